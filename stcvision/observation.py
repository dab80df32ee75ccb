"""The per-cell observation the ant-like STC controller consumes.

Geometry: :mod:`stcvision.stc_geometry` (the entry frame, sub-cells 0..3, the five boxes, the
start mark; shared with the controller).

Where the cells are in the ground view comes from the profile's neighbours calibration (the 12
corners of the five cells), through a homography to *cell units* (the entry frame in units of
the sub-cell side, origin at the current cell's centre). A mark lies a few centimetres inside
one edge of its sub-cell, so each dot is assigned to the sub-cell it falls in and that
sub-cell's nearest edge. The measured heading error (from the heading fit) rotates the dots
back into the entry frame about the robot before they are assigned. The robot's pose from the
red lights (landmarks at cell centres) is fitted by :mod:`stcvision.localisation`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numba
import numpy as np

from stcvision.localisation import landmark_pose, rotate_about_robot
from stcvision.profile import CORNER_ORDER
from stcvision.stages.compiled import fma64
from stcvision.stc_geometry import BOXES, DIRECTIONS, NEIGHBOURS, START_MARKS, SUBCELLS, VISITED_BY

__all__ = [
    "BOXES",
    "NEIGHBOURS",
    "CellGeometry",
    "CellObservation",
    "NeighbourReading",
    "ObservationParams",
    "LANDING_DOTS",
    "marks_ahead",
    "marks_landing_ahead",
    "observe_cell",
    "rotate_about_robot",
]

#: a landing sub-cell counts as marked with a whole row inside it: this many of its four dots,
#: within this half-width (cell units) of its centre, 1 cm clear of its borders (a row of the
#: next sub-cell lies 2 cm beyond the edge and must not count)
LANDING_DOTS = 3
_LANDING_HALF = 0.44

# sub-cell of a point by its quadrant: [right, up] -> index (from stc_geometry.SUBCELLS, built once)
_SUB_OF_QUADRANT = np.full((2, 2), -1, np.int64)
for _k, (_sr, _su) in SUBCELLS.items():
    _SUB_OF_QUADRANT[int(_sr > 0), int(_su > 0)] = _k
# box of a dot by [sub-cell, edge right + 1, edge up + 1] (stc_geometry.BOXES; the start marks, box
# -m, along sub-cell m's exterior edge m), built once: one look-up per dot instead of a mask per box
_BOX_OF = np.zeros((4, 3, 3), np.int64)
for _b, (_k, (_er, _eu)) in BOXES.items():
    _BOX_OF[_k, _er + 1, _eu + 1] = _b
for _m in (1, 2, 3):
    _er, _eu = DIRECTIONS[START_MARKS[_m]]
    _BOX_OF[_m, _er + 1, _eu + 1] = -_m
_NEIGHBOUR_DIRS = np.array(list(NEIGHBOURS.values()), np.int64)
#: centres (cell units) of the sub-cell of each neighbour (NEIGHBOURS order) next to ours
_LANDING = np.array(
    [(0.5 * SUBCELLS[d][0] + dr, 0.5 * SUBCELLS[d][1] + du) for d, (dr, du) in enumerate(NEIGHBOURS.values())]
)


def _apply(H: np.ndarray, xy) -> np.ndarray:
    """Map (N, 2) points through the homography ``H``.

    Homogeneous coordinates (the points and a column of ones) times ``H.T``, then divided.
    """
    p = np.asarray(xy, float).reshape(-1, 2)
    if len(p) >= 2:  # compiled, bit for bit numpy's product (homography)
        return homography(H, np.ascontiguousarray(p))
    q = np.empty((len(p), 3))
    q[:, :2] = p
    q[:, 2] = 1.0
    q = q @ H.T
    return q[:, :2] / q[:, 2:3]


@dataclass(frozen=True, eq=False)
class CellGeometry:
    """Homography from ground-view pixels to cell units, built once from a profile."""

    H: np.ndarray  # (3, 3) ground px -> cell units
    H_inv: np.ndarray

    @classmethod
    def from_profile(cls, profile) -> CellGeometry:
        """Fit the ground-view-to-cell homography to the profile's 12 neighbour corners."""
        src = profile.corners_px().astype(np.float64)
        dst = np.array(CORNER_ORDER, np.float64)
        H, _ = cv2.findHomography(src, dst, 0)
        if H is None or not np.isfinite(H).all() or np.linalg.cond(H) > 1e12:
            from stcvision.errors import ProfileError

            raise ProfileError(
                "the profile's 12 neighbour corners do not span a grid (coincident or collinear points); "
                "expected corners from 'stcvision calibrate neighbors'"
            )
        return cls(H, np.linalg.inv(H))

    def to_cell(self, xy_px: np.ndarray) -> np.ndarray:
        """Map ground-view pixels to cell units."""
        return _apply(self.H, xy_px)

    def to_ground(self, cell_pts: np.ndarray) -> np.ndarray:
        """Map cell units to ground-view pixels."""
        return _apply(self.H_inv, cell_pts)

    def outline_px(self, heading_error_rad: float = 0.0) -> dict[str, np.ndarray]:
        """Return the ground-view polygons of the cell and its neighbours, for drawing.

        Ground-view polygons of the cell, its sub-cells, the five boxes and the four
        neighbours (for drawing), rotated by the heading error.
        """
        polys = {"cell": _sq((0, 0), 1)}
        for k, (sr, su) in SUBCELLS.items():
            polys[f"subcell{k}"] = _sq((0.5 * sr, 0.5 * su), 0.5)
        for b, (k, (er, eu)) in BOXES.items():
            sr, su = SUBCELLS[k]
            c = np.array([0.5 * sr, 0.5 * su])
            e = np.array([er, eu], float)
            t = np.array([e[1], -e[0]])
            polys[f"box{b}"] = np.array([c, c + 0.5 * (e + t), c + 0.5 * (e - t)])
        for name, (dr, du) in NEIGHBOURS.items():
            polys[name] = _sq((2 * dr, 2 * du), 1)
        return {k: self.to_ground(rotate_about_robot(v, heading_error_rad)) for k, v in polys.items()}


def _sq(c, h):
    c = np.asarray(c, float)
    return np.array([c + (h, -h), c + (h, h), c + (-h, h), c + (-h, -h)])


#: Half-width (cell units, i.e. fractions of D) of the band a row's dots share across the row
#: (1 cm at D = 16 cm); rows are found among dots within ROW_SPAN along it.
ROW_TOL = 0.06
ROW_SPAN = 0.6


def row_orientation(cell_pts: np.ndarray) -> np.ndarray:
    """Tell, per dot, which way its row runs.

    For each dot: 1 if it lies in a row running along 'up' (a mark on a right/left edge),
    0 if along 'right' (top/bottom edge), -1 if it has no row-mate (an isolated dot).

    A mark is a row of four dots parallel to one edge of its sub-cell; near a corner the end
    dots of two marks on perpendicular edges can be closer to each other than to their own
    row-mates, so a dot's edge is decided by the row it belongs to, not by the nearest edge.
    """
    if len(cell_pts) == 0:
        return np.zeros(0, int)
    return row_orientation_loop(np.ascontiguousarray(cell_pts, np.float64), ROW_TOL, ROW_SPAN)


def assign_boxes(cell_pts: np.ndarray, orient: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Assign each dot (cell units) its sub-cell, box and neighbour.

    For dots in cell units: sub-cell index (-1 outside the cell), box (0 = none) and
    neighbour index (0..3 in :data:`NEIGHBOURS` order, -1 = none).

    The edge of a dot is the nearer of its sub-cell's two edges across its row (see
    :func:`row_orientation`); an isolated dot takes the nearest edge.
    """
    if orient is None:
        orient = row_orientation(cell_pts)
    # the box of the sub-cell's edge; the start mark, sub-cell m along its exterior edge in
    # direction m, is coded as box -m (m = 1, 2, 3; sub-cell 0's is under the robot)
    return assign_boxes_loop(
        np.ascontiguousarray(cell_pts, np.float64),
        np.asarray(orient, np.int64),
        _SUB_OF_QUADRANT,
        _BOX_OF,
        _NEIGHBOUR_DIRS,
    )


#: a mark's dots lie this far (cell units) inside its sub-cell's edge; :func:`mark_offset` needs
#: this many dots of rows along an axis before it measures the offset across them
MARK_INSET = 0.125
MARK_MIN_DOTS = 4


def mark_offset(cell_pts: np.ndarray, orient: np.ndarray, *, inset: float = MARK_INSET, min_dots: int = MARK_MIN_DOTS):
    """Measure the robot's offset from its sub-cell centre from the marks in view.

    The robot's offset from its sub-cell centre (right, up; cell units) from the marks in
    view: every mark lies ``inset`` inside one edge of its sub-cell, so across its row a dot's
    coordinate should be an integer (an edge) +- ``inset``; the median residual of the rows
    running along 'up' gives the offset to the right, of those along 'right' the offset up.
    Unambiguous while the robot is less than ``inset`` off (the residual would flip sides).
    """
    if not len(cell_pts):
        return None
    lit = np.ones(len(cell_pts), np.bool_)
    have, off = mark_offset_loop(
        np.ascontiguousarray(cell_pts, np.float64), np.asarray(orient, np.int64), lit, inset, min_dots
    )
    return _offset_of(have, off)


def _offset_of(have: np.ndarray, off: np.ndarray):
    """(right, up) from :func:`mark_offset`'s answer; None where neither axis had rows."""
    if not have.any():
        return None
    return (float(off[0]) or 0.0, float(off[1]) or 0.0)


def pattern_rotation(
    cell_pts: np.ndarray, orient: np.ndarray, *, min_rows: int = 2, max_rad: float = 0.06
) -> float | None:
    """Measure the median lean of the mark rows in view.

    Median lean (rad, counter-clockwise) of the mark rows in view. Dots are grouped into rows
    (same coordinate across the row within ``ROW_TOL``, no gap over 0.35 along it); each row of
    3+ dots spanning 0.3..0.7 sub-cells and fitting a line within 0.02 gives one angle. ``None``
    unless ``min_rows`` rows agree (within 1 degree of their median) and the lean is under
    ``max_rad`` (a larger one is a misgrouping, not the floor). Plain Python: rows hold four
    dots, where numpy's per-call cost would dominate.
    """
    angles = []
    for along, across in ((1, 0), (0, 1)):  # rows along 'up' (vary in u), along 'right'
        pts = sorted((float(p[across]), float(p[along])) for p in cell_pts[orient == along])
        band: list[tuple[float, float]] = []
        for k, pt in enumerate(pts + [(math.inf, 0.0)]):
            if band and pt[0] - band[-1][0] > ROW_TOL:
                angles.extend(_row_angles(band, along))
                band = []
            if k < len(pts):
                band.append(pt)
    if len(angles) < min_rows:
        return None
    med = float(np.median(angles))
    agree = [a for a in angles if abs(a - med) < math.radians(1.0)]
    if len(agree) < min_rows or abs(med) > max_rad:
        return None
    return float(np.median(agree))


def _row_angles(band: list[tuple[float, float]], along: int) -> list[float]:
    """Split a band of (across, along) points at gaps along it; one angle per straight row."""
    out = []
    pts = sorted(band, key=lambda p: p[1])
    start = 0
    for k in range(1, len(pts) + 1):
        if k == len(pts) or pts[k][1] - pts[k - 1][1] > 0.35:
            row = pts[start:k]
            start = k
            n = len(row)
            if n < 3:
                continue
            xs = [p[1] for p in row]
            ys = [p[0] for p in row]
            span = xs[-1] - xs[0]
            if not 0.3 <= span <= 0.7:
                continue
            mx, my = sum(xs) / n, sum(ys) / n
            sxx = sum((x - mx) ** 2 for x in xs)
            slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys, strict=True)) / sxx
            if max(abs(my + slope * (x - mx) - y) for x, y in zip(xs, ys, strict=True)) > 0.02:
                continue
            out.append(-math.atan(slope) if along == 1 else math.atan(slope))
    return out


def group_stats(code: np.ndarray, n: int, lit: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Count lit dots per code and take each code's largest value.

    For codes 0..n-1 (one per dot): how many of the lit dots have each code, and the largest
    ``value`` among all dots of each code (0.0 where none has it).
    """
    return group_stats_loop(np.asarray(code, np.int64), n, np.asarray(lit, np.bool_), np.asarray(value, float))


def _confidence(value: float, threshold: float, noise: float) -> float:
    """Say how sure a threshold decision is.

    Logistic in the margin, in units of the noise (0.5 at the threshold, ~0.99 five noise units
    away).
    """
    return float(1.0 / (1.0 + math.exp(-abs(value - threshold) / max(noise, 1e-9))))


@dataclass(frozen=True)
class BoxReading:
    box: int
    lit: bool
    confidence: float
    n_dots: int


@dataclass(frozen=True)
class NeighbourReading:
    """What the camera says about one neighbour cell: marked, red, and how sure of each."""

    direction: str
    has_marks: bool
    has_red: bool
    marks_confidence: float
    red_confidence: float


@dataclass(frozen=True)
class CellObservation:
    """What the camera says about the current cell and its neighbours (entry frame).

    Attributes
    ----------
    boxes : tuple of BoxReading
        The five mark boxes.
    visited : dict of int to bool
        Sub-cells 1-3 from the box rule.
    neighbours : dict of str to NeighbourReading
        Right, forward, left, back.
    heading_error_rad : float
        The rotation applied.
    stray_dots : int
        Lit dots in the current cell outside any box (a sign of a bad pose).
    start_mark : int or None
        The sub-cell (1-3) holding the STC start mark, if this is the start cell.
    landing_marked : tuple of bool
        Per neighbour direction (right, forward, left, back), whether the sub-cell the robot
        would land on when leaving that way already carries a mark.
    position_offset : tuple of float or None
        Where the marks say the robot stands, off its sub-cell centre, in the entry frame (right,
        up; cell units = sub-cell sides); None with too few rows in view. An axis with no rows
        across it reads 0 here (the boxes are read unshifted along it): which axes the marks did
        measure is ``position_offset_axes``.
    pattern_rotation_rad : float or None
        How far all the rows in view still lean (counter-clockwise, rad) after the rotation by
        ``heading_error_rad``: the consensus of every mark, not just the newest row.
    landmark_offset : tuple of float or None
        The robot's offset (right, up; cell units) from the red lights in view, which stand at
        cell centres: an absolute reference, unlike the marks it laid itself; None unless two or
        more lights at distinct cells are well in view (one light cannot tell an offset from a
        turn).
    landmark_rotation_rad : float or None
        How far those lights are still turned about their centroid (rad, counter-clockwise)
        after the rotation by ``heading_error_rad`` (2-D Procrustes); None when
        ``landmark_offset`` is.
    landmark_rotation_sigma_rad, landmark_offset_sigma : float or None
        1-sigma uncertainties of ``landmark_rotation_rad`` (rad) and ``landmark_offset`` (cell
        units), from the lights' centroid-error model and their spread.
    untrusted : str
        Why this reading cannot be trusted ("" when it can): the dot search hit a cap
        (:attr:`stcvision.stages.Dots.untrusted`); a controller must not decide on it.
    position_offset_axes : tuple of bool
        Which axes of ``position_offset`` (right, up) this frame's marks measured; both False
        when the caller gave the offset (it is then no reading of the marks).
    """

    boxes: tuple[BoxReading, ...]
    visited: dict[int, bool]
    neighbours: dict[str, NeighbourReading]
    heading_error_rad: float
    stray_dots: int
    start_mark: int | None = None
    landing_marked: tuple[bool, bool, bool, bool] = (False, False, False, False)
    position_offset: tuple[float, float] | None = None
    pattern_rotation_rad: float | None = None
    landmark_offset: tuple[float, float] | None = None
    landmark_rotation_rad: float | None = None
    landmark_rotation_sigma_rad: float | None = None
    landmark_offset_sigma: float | None = None
    untrusted: str = ""
    position_offset_axes: tuple[bool, bool] = (False, False)

    def lit(self, box: int) -> bool:
        """Say whether a box is lit (marked).

        Parameters
        ----------
        box : int
            The box, 1-5.

        Returns
        -------
        bool
            Whether the box reads as marked.
        """
        return self.boxes[box - 1].lit

    def to_dict(self) -> dict:
        """Return the reading as plain JSON-ready values.

        Returns
        -------
        dict
            The boxes, the visited sub-cells, the neighbours, the heading error (deg), the start
            mark, the landing marks, the stray dots and the untrusted reason.
        """
        return {
            "boxes": {
                b.box: {"lit": b.lit, "confidence": round(b.confidence, 4), "n_dots": b.n_dots} for b in self.boxes
            },
            "visited": {str(k): v for k, v in self.visited.items()},
            "neighbours": {
                n.direction: {
                    "has_marks": n.has_marks,
                    "has_red": n.has_red,
                    "marks_confidence": round(n.marks_confidence, 4),
                    "red_confidence": round(n.red_confidence, 4),
                }
                for n in self.neighbours.values()
            },
            "heading_error_deg": math.degrees(self.heading_error_rad),
            "start_mark": self.start_mark,
            "landing_marked": list(self.landing_marked),
            "stray_dots": self.stray_dots,
            "untrusted": self.untrusted,
        }


@dataclass(frozen=True, kw_only=True, slots=True)
class ObservationParams:
    """Parameters of the cell observation.

    ``min_dots``: lit dots needed before a box (or a neighbour) counts as marked. A mark is
    a row of four dots, so two agreeing dots reject a lone noise peak (measured: one lone 5.6-
    sigma false dot in 300 rendered frames) at the cost of marks with three of four dots lost.
    """

    min_dots: int = 2
    #: shift the cell regions by the robot's offset as the marks show it (within 2 cm)
    use_offset: bool = True
    #: also estimate the rows' lean and the red-light landmarks (for a controller correcting its
    #: pose; costs ~0.4 ms with many dots in view, so off for plain frame reading)
    pose_estimates: bool = False
    #: how far out (m, from the robot) red lights serve as landmarks: the pipeline finds them
    #: in a wide, coarse ground view of the red channel (the main view reaches ~0.55 m); far
    #: lights pin the robot down where no light is near (open floor)
    landmark_range_m: float = 1.25
    #: report the lights' rotation (and offset) only when their spread fixes the rotation to
    #: this (1 sigma, from the centroid errors' model): two lights close together far away do not
    landmark_max_sigma_rad: float = math.radians(1.0)


def observe_cell(
    dots,
    red_px: np.ndarray,
    red_strength: np.ndarray,
    geometry: CellGeometry,
    *,
    red_threshold_dn: float,
    heading_error_rad: float = 0.0,
    params: ObservationParams = ObservationParams(),
    landmark_px: np.ndarray | None = None,
    subcell_m: float | None = None,
    position_offset: tuple[float, float] | None = None,
) -> CellObservation:
    """Classify the five boxes and the four neighbours.

    Parameters
    ----------
    dots : stcvision.stages.Dots -- all candidates (lit and not) in the ground view.
    red_px, red_strength : (M, 2) ground-view centroids and peak values of red blobs.
    heading_error_rad : rotate the ground view back by this much (from the heading fit).
    landmark_px : (L, 2) red-light centroids for the landmark fit, in the ground view's pixel
        coordinates (may lie beyond its edges: from a wider view); default ``red_px``, within
        2.6 sub-cells of the robot.
    subcell_m : the sub-cell side, to turn ``params.landmark_range_m`` into cell units.
    position_offset : read the boxes with the robot standing this far off its sub-cell centre
        (right, up; cell units) instead of where this frame's marks say (e.g. the red lights'
        offset from a short frame at the same pose: a long frame's marks may mislead it).
    """
    cell_pts, orient, offset, axes = _cell_dots(dots, geometry, heading_error_rad, params, position_offset)
    sub, box, nb = assign_boxes(cell_pts, orient) if len(cell_pts) else (np.zeros(0, np.int64),) * 3
    thr = dots.threshold_snr
    boxes, visited, stray, start_mark, nb_stats = _read_boxes(dots, sub, box, nb, params)
    # neighbour d's sub-cell next to our sub-cell d holds a whole row (LANDING_DOTS of its 4
    # dots, clear of the borders)
    inside = landing_counts(cell_pts, np.asarray(dots.lit, np.bool_), _LANDING, _LANDING_HALF)
    landing = tuple(bool(c >= max(params.min_dots, LANDING_DOTS)) for c in inside)
    rru = rotate_about_robot(geometry.to_cell(red_px), heading_error_rad) if len(red_px) else np.zeros((0, 2))
    landmark = (None,) * 4
    if params.pose_estimates:
        landmark = _landmarks(rru, landmark_px, geometry, heading_error_rad, params, subcell_m)
    neighbours = _read_neighbours(nb_stats, rru, red_strength, red_threshold_dn, thr, params)
    lean = pattern_rotation(cell_pts[dots.lit], orient[dots.lit]) if (len(cell_pts) and params.pose_estimates) else None
    return CellObservation(
        tuple(boxes),
        visited,
        neighbours,
        float(heading_error_rad),
        stray,
        start_mark,
        landing,
        offset,
        lean,
        *landmark,
        getattr(dots, "untrusted", ""),
        axes,
    )


def _cell_dots(dots, geometry: CellGeometry, heading_error_rad: float, params: ObservationParams, position_offset):
    """Return the dots in cell units, their row orientation and the robot's offset.

    The dots in cell units, rotated back by the heading error and shifted by the robot's
    offset (``position_offset``, else where the marks say it stands); their row orientation
    (:func:`row_orientation`, lit dots only: rows are made of lit dots; -1 for the rest); and
    that offset (None: too few rows); and which of its axes the marks measured.
    """
    if not len(dots):
        return np.zeros((0, 2)), np.zeros(0, np.int64), None, (False, False)
    cell_pts = rotate_about_robot(geometry.to_cell(dots.xy_px), heading_error_rad)
    lit = np.asarray(dots.lit, np.bool_)
    orient, have, off = cell_dots(cell_pts, lit, ROW_TOL, ROW_SPAN, MARK_INSET, MARK_MIN_DOTS)
    # where the robot really stands, from the marks: read the boxes relative to that
    offset = _offset_of(have, off) if position_offset is None else tuple(position_offset)
    axes = (bool(have[0]), bool(have[1])) if position_offset is None else (False, False)
    if offset is not None and params.use_offset:
        cell_pts = cell_pts + np.asarray(offset)
    return cell_pts, orient, offset, axes


def _read_boxes(dots, sub: np.ndarray, box: np.ndarray, nb: np.ndarray, params: ObservationParams):
    """Read the five boxes, the visited sub-cells, the stray dots and the start mark.

    The five boxes (lit with ``params.min_dots`` lit dots; confidence from the best
    candidate's SNR), the visited sub-cells, the stray lit dots (in the cell, in no box), the
    start mark's sub-cell (or None), and per neighbour code (``nb + 1``) the lit dots and the
    best SNR (:func:`box_counts`).
    """
    thr = dots.threshold_snr
    # per box code (-3..5, offset by 3): lit dots and the best candidate's SNR
    n_box, best_box, n_nb, best_nb, stray = box_counts(
        box, nb, sub, np.asarray(dots.lit, np.bool_), np.asarray(dots.snr, float)
    )
    n_lit_box, best_box = n_box.tolist(), best_box.tolist()
    boxes = []
    for b in BOXES:
        n_lit = n_lit_box[b + 3]
        boxes.append(BoxReading(b, bool(n_lit >= params.min_dots), _confidence(best_box[b + 3], thr, 1.0), n_lit))
    lit_b = {b.box: b.lit for b in boxes}
    visited = {m: any(lit_b[b] for b in boxes_) for m, boxes_ in VISITED_BY.items()}
    start_mark = next((m for m in (1, 2, 3) if n_lit_box[3 - m] >= params.min_dots), None)
    return boxes, visited, int(stray), start_mark, (n_nb.tolist(), best_nb.tolist())


def _read_neighbours(nb_stats, rru, red_strength, red_threshold_dn: float, thr: float, params: ObservationParams):
    """Read the four neighbours: marked, red, each with a confidence.

    The four neighbours: marked (``params.min_dots`` lit dots in the cell: ``nb_stats`` from
    :func:`_read_boxes`), red (a red light ``rru`` in it), each with a confidence.
    """
    _, _, rnb = assign_boxes(rru, np.full(len(rru), -1)) if len(rru) else (None, None, np.zeros(0, np.int64))
    neighbours = {}
    n_lit_nb, best_nb = nb_stats
    n_red_nb, best_red = group_stats(rnb + 1, 5, np.ones(len(rnb), bool), np.asarray(red_strength, float))
    n_red_nb, best_red = n_red_nb.tolist(), best_red.tolist()
    for i, name in enumerate(NEIGHBOURS):
        has_red = bool(n_red_nb[i + 1])
        neighbours[name] = NeighbourReading(
            name,
            bool(n_lit_nb[i + 1] >= params.min_dots),
            has_red,
            _confidence(best_nb[i + 1], thr, 1.0),
            _confidence(best_red[i + 1], red_threshold_dn, red_threshold_dn / 5.0) if has_red else 1.0,
        )
    return neighbours


def _landmarks(
    rru, landmark_px, geometry: CellGeometry, heading_error_rad: float, params: ObservationParams, subcell_m
):
    """Fit the robot's pose to the red lights in view, which stand at cell centres.

    Red lights stand at cell centres (even coordinates in cell units): absolute landmarks.
    (offset, rotation, rotation sigma, offset sigma) of the landmark pose fit
    (:func:`stcvision.localisation.landmark_pose`) over the lights near a cell centre within
    reach (``landmark_px`` out to ``params.landmark_range_m``, else the view's lights ``rru``
    within 2.6 sub-cells), each None where not fixed.
    """
    if landmark_px is not None and subcell_m:
        lru = (
            rotate_about_robot(geometry.to_cell(landmark_px), heading_error_rad)
            if len(landmark_px)
            else np.zeros((0, 2))
        )
        reach = params.landmark_range_m / subcell_m
    else:
        lru, reach = rru, 2.6  # well inside the ground view (a blob cut by its border is biased)
    return landmark_pose(lru, reach, subcell_m, max_sigma_rad=params.landmark_max_sigma_rad)


def marks_ahead(
    dots, geometry: CellGeometry, *, heading_error_rad: float = 0.0, offset: tuple[float, float] | None = None
) -> int:
    """Count the lit dots in the cell just ahead of the robot.

    The cell whose lower-right sub-cell is the one in front of the robot's (where an STC robot
    lands when it leaves into a child). The robot stands in the front-right sub-cell of its own
    cell as it leaves, so that cell is ``[-1, 1] x [0, 2]`` in cell units and its own cell lies
    wholly behind ``up = 0``. ``offset``: the robot's offset from its sub-cell centre
    (``CellObservation.position_offset``).
    """
    if not len(dots):
        return 0
    cell_pts = rotate_about_robot(geometry.to_cell(dots.xy_px[dots.lit]), heading_error_rad)
    if offset is not None:
        cell_pts = cell_pts + np.asarray(offset)
    return int(((np.abs(cell_pts[:, 0]) < 1) & (cell_pts[:, 1] > 0) & (cell_pts[:, 1] < 2)).sum())


def marks_landing_ahead(
    dots, geometry: CellGeometry, *, heading_error_rad: float = 0.0, offset: tuple[float, float] | None = None
) -> int:
    """Count the lit dots in the sub-cell just ahead of the robot.

    Lit dots in the sub-cell just ahead of the robot (where it lands when it drives on; the
    lower-right sub-cell of :func:`marks_ahead`'s cell ahead), 1 cm clear of its borders as
    :func:`observe_cell`'s landing rule: a row of the next sub-cell must not count.
    """
    if not len(dots):
        return 0
    cell_pts = rotate_about_robot(geometry.to_cell(dots.xy_px[dots.lit]), heading_error_rad)
    if offset is not None:
        cell_pts = cell_pts + np.asarray(offset)
    return int(((np.abs(cell_pts[:, 0] - 0.5) < _LANDING_HALF) & (np.abs(cell_pts[:, 1] - 0.5) < _LANDING_HALF)).sum())


# --------------------------------------------------------------------------- compiled loops
@numba.njit(cache=True)
def row_orientation_loop(cell_pts, tol, span):
    """Tell, per dot, which way its row runs (the compiled loop).

    Per dot (cell units): 1 if it has more row-mates along 'up' than along 'right', 0 if
    fewer, -1 if as many (:func:`stcvision.observation.row_orientation`).
    """
    n = len(cell_pts)
    out = np.empty(n, np.int64)
    for i in range(n):
        vertical = 0
        horizontal = 0
        for j in range(n):
            if j == i:
                continue
            dr = abs(cell_pts[i, 0] - cell_pts[j, 0])
            du = abs(cell_pts[i, 1] - cell_pts[j, 1])
            if dr < tol and du < span:
                vertical += 1
            if du < tol and dr < span:
                horizontal += 1
        out[i] = 1 if vertical > horizontal else (0 if horizontal > vertical else -1)
    return out


@numba.njit(cache=True)
def assign_boxes_loop(cell_pts, orient, sub_of_quadrant, box_of, neighbours):
    """Sub-cell, box and neighbour of each dot (:func:`stcvision.observation.assign_boxes`)."""
    n = len(cell_pts)
    sub = np.full(n, -1, np.int64)
    box = np.zeros(n, np.int64)
    nb = np.full(n, -1, np.int64)
    for i in range(n):
        r, u = cell_pts[i, 0], cell_pts[i, 1]
        right, up = r >= 0, u >= 0
        if abs(r) < 1 and abs(u) < 1:
            sub[i] = sub_of_quadrant[int(right), int(up)]
        lr = r - (0.5 if right else -0.5)
        lu = u - (0.5 if up else -0.5)
        horiz = True if orient[i] == 1 else (False if orient[i] == 0 else abs(lr) > abs(lu))
        er = int(np.sign(lr)) if horiz else 0
        eu = 0 if horiz else int(np.sign(lu))
        if sub[i] >= 0:
            box[i] = box_of[sub[i], er + 1, eu + 1]
        for k in range(len(neighbours)):
            if abs(r - 2 * neighbours[k, 0]) < 1 and abs(u - 2 * neighbours[k, 1]) < 1:
                nb[i] = k
    return sub, box, nb


@numba.njit(cache=True)
def mark_offset_loop(cell_pts, orient, lit, inset, min_dots):
    """Return the median residuals of the marks' rows (the compiled loop of the mark offset).

    The median residuals of :func:`stcvision.observation.mark_offset` over the lit dots:
    per axis (0: right, from the rows along 'up'; 1: up, from those along 'right'), whether
    ``min_dots`` rows' dots were there, and minus the median of each dot's coordinate less its
    nominal one (the nearest integer, half to even, +- ``inset``).
    """
    have = np.zeros(2, np.bool_)
    out = np.zeros(2)
    for axis in range(2):
        along = 1 - axis
        r = np.empty(len(cell_pts))
        k = 0
        for i in range(len(cell_pts)):
            if lit[i] and orient[i] == along:
                p = cell_pts[i, axis]
                q = np.round(p)
                r[k] = p - (q + (inset if p >= q else -inset))
                k += 1
        if k >= min_dots:
            have[axis] = True
            out[axis] = -np.median(r[:k])
    return have, out


@numba.njit(cache=True)
def group_stats_loop(code, n, lit, value):
    """Count lit dots per code and take each code's largest value (the compiled loop).

    Per code 0..n-1: lit dots with it, and the largest ``value`` of any dot with it (0.0
    where none has it): the compiled loop of :func:`group_stats`, on arrays of its types.
    """
    counts = np.zeros(n, np.int64)
    best = np.full(n, -np.inf)
    seen = np.zeros(n, np.bool_)
    for i in range(len(code)):
        c = code[i]
        seen[c] = True
        if lit[i]:
            counts[c] += 1
        if value[i] > best[c]:
            best[c] = value[i]
    for c in range(n):
        if not seen[c]:
            best[c] = 0.0
    return counts, best


@numba.njit(cache=True)
def cell_dots(cell_pts, lit, tol, span, inset, min_dots):
    """Return the row orientation and mark offset of the dots in one call.

    Row orientation and mark offset of the dots ``cell_pts`` (cell units, already rotated), in
    one call (:func:`stcvision.observation._cell_dots`): per dot, :func:`row_orientation` among
    the lit dots (-1 for the rest), then :func:`mark_offset` over the lit dots. Returns
    (orient, have, offset).
    """
    idx = np.flatnonzero(lit)
    sub = np.empty((len(idx), 2))
    for k in range(len(idx)):
        sub[k, 0] = cell_pts[idx[k], 0]
        sub[k, 1] = cell_pts[idx[k], 1]
    orient = np.full(len(cell_pts), -1, np.int64)
    o = row_orientation_loop(sub, tol, span)
    for k in range(len(idx)):
        orient[idx[k]] = o[k]
    have, off = mark_offset_loop(cell_pts, orient, lit, inset, min_dots)
    return orient, have, off


@numba.njit(cache=True)
def box_counts(box, nb, sub, lit, snr):
    """Count lit dots and the best SNR per box and neighbour code, and the stray lit dots.

    Per box code (box + 3: -3..5) and neighbour code (nb + 1: -1..3): the lit dots and the
    best SNR of any dot (:func:`group_stats_loop`), and the stray lit dots (in a sub-cell, in no
    box) (:func:`stcvision.observation._read_boxes`).
    """
    n_box, best_box = group_stats_loop(box + 3, 9, lit, snr)
    n_nb, best_nb = group_stats_loop(nb + 1, 5, lit, snr)
    stray = 0
    for i in range(len(box)):
        if sub[i] >= 0 and box[i] == 0 and lit[i]:
            stray += 1
    return n_box, best_box, n_nb, best_nb, stray


@numba.njit(cache=True)
def landing_counts(cell_pts, lit, centres, half):
    """Per landing centre, the lit dots within ``half`` of it along both axes."""
    out = np.zeros(len(centres), np.int64)
    for i in range(len(cell_pts)):
        if not lit[i]:
            continue
        for k in range(len(centres)):
            if abs(cell_pts[i, 0] - centres[k, 0]) < half and abs(cell_pts[i, 1] - centres[k, 1]) < half:
                out[k] += 1
    return out


@numba.njit(cache=True)
def homography(H, p):
    """Map (N, 2) points through a homography, bit for bit as the matrix product does.

    (N, 2) points ``p`` through the homography ``H`` ((3, 3)): ``[p, 1] @ H.T`` then divided
    by the third coordinate, each row of the product as OpenBLAS's dgemm computes it on this
    machine for N >= 2 (``fma(y, h1, x * h0) + h2``: bit for bit on 100,000 points; numpy takes
    another path for N = 1, which :func:`stcvision.observation._apply` keeps).
    """
    n = len(p)
    out = np.empty((n, 2))
    for i in range(n):
        x, y = p[i, 0], p[i, 1]
        a = fma64(y, H[0, 1], x * H[0, 0]) + H[0, 2]
        b = fma64(y, H[1, 1], x * H[1, 0]) + H[1, 2]
        c = fma64(y, H[2, 1], x * H[2, 0]) + H[2, 2]
        out[i, 0] = a / c
        out[i, 1] = b / c
    return out
