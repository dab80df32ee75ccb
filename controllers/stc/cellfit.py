"""Localisation against the cell's own marks: where the robot stands relative to the rows of the
cell it decides in, from the box and start-mark lines those rows must lie on.

The pipeline reads the boxes relative to the offset the marks *in view* give
(:func:`stcvision.observation.mark_offset`: the median residual of every row from the nearest
edge +- the rows' inset). That offset is ambiguous beyond the inset (2 cm: the residual flips
sides), and it mixes rows laid at different times, each where the robot then stood: on open
floor, far from any red light, a robot 1.8 cm behind its sub-cell (the drift of ~80 moves, which
nothing absolute measured) read its cell's rows of an hour before against its neighbour's rows
of five minutes before, took the median (~0), and read boxes 2 and 4 as marks at no box at all.

At a decision, though, the cell's marks can lie only on the box and start-mark lines
(:data:`stcvision.stc_geometry.BOX_EDGES`, :data:`~stcvision.stc_geometry.START_MARKS`; the oracle's
``box_table_violations`` is zero on every tour), and along each axis those lines stand 0.75 of a
sub-cell apart within a half of the cell (a row's extent says which half). So the offset that
puts the cell's rows on those lines is found well beyond the rows' inset (the search keeps to
+-0.3 of a sub-cell, 4.8 cm; a neighbour's row just beyond the cell's edge lies 0.25 from its
outermost lines, which is why an offset two ways as good is not taken), and it is
the offset that matters for reading the boxes: the robot relative to the marks it reads.
:func:`fit_cell_offset` finds it; :class:`stcvision.controllers.stc.frames.RobotCamera` reads a frame again
with it when the pipeline's offset leaves rows of the cell on no line, and a reading whose rows
no offset puts on the lines is not decided on (``StcObservation.misread``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from stcvision.observation import LANDING_DOTS, MARK_INSET, ROW_TOL, rotate_about_robot, row_orientation
from stcvision.stc_geometry import BOX_EDGES, DIRECTIONS, START_MARKS, SUBCELLS

__all__ = ["CellFit", "fit_cell_offset", "mark_lines", "shows_row", "shows_tour_row", "tour_lines"]

#: how far (sub-cell sides) the fit searches either side of the pipeline's offset: short of the
#: 0.375 at which a row would meet the next line of its half (half the lines' 0.75 spacing)
SEARCH = 0.3
#: the search's step (sub-cell sides; 1.6 mm at 16 cm sub-cells)
STEP = 0.01
#: a dot counts as the cell's within this of the centre (sub-cell sides): the outermost lines
#: (0.875) and their band, not a neighbour's row just beyond the cell's edge (1.125)
INSIDE = 1.0 - ROW_TOL
#: a row's dot lies on a line within this (sub-cell sides): the row search's band across a row
#: (:data:`stcvision.observation.ROW_TOL`, 1 cm)
ON_LINE = ROW_TOL
#: a dot with no line of its half within this (sub-cell sides) at the pipeline's offset is no
#: row of the cell's displaced by the robot's offset (the search reaches 0.3 either side) but a
#: stray (a noise peak, a neighbour's row seen through the cell's edge, a bloom): half the lines'
#: 0.75 spacing, it is left out of the fit rather than pull it
NEAR_LINE = 0.375


@cache
def mark_lines() -> tuple[tuple[tuple[float, int], ...], tuple[tuple[float, int], ...]]:
    """Per axis (0: across the rows along 'up', the right coordinate; 1: across the rows along
    'right', the up coordinate) the (coordinate, half) of every line a mark of the cell may lie
    on at a decision: the five boxes and the start marks of sub-cells 1-3 (sub-cell 0's is under
    the robot); ``half`` is the sign of the row's other coordinate (the sub-cell's side)."""
    lines: tuple[list, list] = ([], [])
    edges = list(BOX_EDGES.values()) + [(m, START_MARKS[m]) for m in (1, 2, 3)]
    for k, d in edges:
        e = np.asarray(DIRECTIONS[d], float)
        centre = 0.5 * np.asarray(SUBCELLS[k], float)
        axis = 0 if e[0] else 1
        coord = float(centre[axis] + (0.5 - MARK_INSET) * e[axis])
        lines[axis].append((coord, int(SUBCELLS[k][1 - axis])))
    return tuple(lines[0]), tuple(lines[1])


@cache
def tour_lines() -> np.ndarray:
    """Every line an STC tour marks in a cell whose entry frame the reader does not know (a
    neighbour, the cell ahead): (K, 4) rows of (across axis, coordinate across, centre along,
    sub-cell) in cell units from that cell's centre. Sub-cell ``m`` of an entry frame is left
    towards ``m + 1`` (its row on exterior edge ``m + 3``) or out of the cell towards ``m`` (its
    row on interior edge ``m + 2``), and the start mark lies on exterior edge ``m``; entry frames
    turn the sub-cells and the directions together, so the same three edges per sub-cell hold in
    any frame: the eight exterior edges and four of the eight interior ones."""
    rows = []
    for m in range(4):
        centre = 0.5 * np.asarray(SUBCELLS[m], float)
        for d in ((m + 2) % 4, (m + 3) % 4, START_MARKS[m]):
            e = np.asarray(DIRECTIONS[d], float)
            axis = 0 if e[0] else 1
            rows.append((axis, centre[axis] + (0.5 - MARK_INSET) * e[axis], centre[1 - axis], m))
    return np.array(rows, float)


def shows_tour_row(cell_pts: np.ndarray, lit: np.ndarray, centre) -> bool:
    """Whether the lit dots ``cell_pts`` (cell units, rotated and shifted as the pipeline read them)
    show a row an STC tour lays in the cell centred at ``centre``: at least
    :data:`stcvision.observation.LANDING_DOTS` of a row's four dots within :data:`ON_LINE`
    across one of :func:`tour_lines` and inside its sub-cell along it. A noise peak, a bloom or
    another cell's row read across the cell's edge (it lies 0.25 of a sub-cell from the nearest
    such line) shows none; a mark the tour laid there does, once a frame sees most of its dots.
    For a frame registered on the marks (a decision's: :func:`fit_cell_offset`)."""
    p = np.asarray(cell_pts, float)[np.asarray(lit, bool)] - np.asarray(centre, float)
    if len(p) < LANDING_DOTS:
        return False
    lines = tour_lines()
    axis = lines[:, 0].astype(int)
    across = p[:, axis] - lines[:, 1]  # (dots, lines)
    along = p[:, 1 - axis] - lines[:, 2]
    on = (np.abs(across) < ON_LINE) & (np.abs(along) < 0.5)
    return bool((on.sum(axis=0) >= LANDING_DOTS).any())


#: a row of the LEDs' dots spans this along it (sub-cell sides): three of the four LEDs' dots at least
#: (0.375 at 16 cm), all four at most (0.5625), with the dots' read-out error either side
LED_ROW_SPAN = (0.3, 0.7)


def shows_row(cell_pts: np.ndarray, lit: np.ndarray, centre) -> bool:
    """Whether the lit dots ``cell_pts`` (cell units) inside the cell centred at ``centre`` show a row
    of the robot's LEDs, wherever it lies: at least :data:`stcvision.observation.LANDING_DOTS`
    dots within :data:`ON_LINE` of one line along either axis, spanning :data:`LED_ROW_SPAN` along
    it. A noise peak, two dots or a bloom show none. Unlike :func:`shows_tour_row` it asks
    nothing of where the row lies: for a frame read where the robot believes it stands, whose
    rows may lie several centimetres off their lines."""
    p = np.asarray(cell_pts, float)[np.asarray(lit, bool)] - np.asarray(centre, float)
    p = p[(np.abs(p) < 1.0).all(axis=1)]
    for axis in (0, 1):  # the coordinate across the row
        across, along = p[:, axis], p[:, 1 - axis]
        for a in across:
            near = np.sort(along[np.abs(across - a) < ON_LINE])
            for k in range(len(near) - LANDING_DOTS + 1):
                run = near[k:][near[k:] - near[k] <= LED_ROW_SPAN[1]]
                if len(run) >= LANDING_DOTS and run[-1] - run[0] >= LED_ROW_SPAN[0]:
                    return True
    return False


@dataclass(frozen=True, slots=True)
class CellFit:
    offset: tuple[float, float]  # (right, up), sub-cell sides: add to the dots (the pipeline's sense)
    on_line: int  # the cell's row dots on a line at that offset
    off_line: int  # ... and on none
    ambiguous: bool  # another offset as good, far from this one, reads them otherwise


def _line_distance(p: np.ndarray, along_axis: np.ndarray, lines) -> np.ndarray:
    """Per dot (shifted, cell units) the distance to the nearest line of its half, on the axis
    its row is read on."""
    out = np.empty(len(p))
    for i, ((r, u), a) in enumerate(zip(p, along_axis, strict=True)):
        c, other = (r, u) if a == 0 else (u, r)
        half = 1 if other >= 0 else -1
        out[i] = min((abs(c - x) for x, h in lines[a] if h == half), default=1.0)
    return out


def _score(p: np.ndarray, along_axis: np.ndarray, lines) -> tuple[int, float]:
    """(dots on a line less the cell's dots on none, minus the squared distances of those on a
    line) for dots ``p`` (shifted, cell units); ``along_axis``: per dot the axis (0 or 1) its
    row is read on."""
    on = off = 0
    rss = 0.0
    for (r, u), a in zip(p, along_axis, strict=True):
        if not (abs(r) < INSIDE and abs(u) < INSIDE):
            continue
        c, other = (r, u) if a == 0 else (u, r)
        half = 1 if other >= 0 else -1
        d = min((abs(c - x) for x, h in lines[a] if h == half), default=1.0)
        if d < ON_LINE:
            on += 1
            rss += d * d
        else:
            off += 1
    return on - off, -rss


def _counts(p: np.ndarray, along_axis: np.ndarray, lines) -> tuple[int, int]:
    """(the cell's row dots on a line, on none)."""
    on = off = 0
    for (r, u), a in zip(p, along_axis, strict=True):
        if abs(r) < INSIDE and abs(u) < INSIDE:
            c, other = (r, u) if a == 0 else (u, r)
            half = 1 if other >= 0 else -1
            if any(h == half and abs(c - x) < ON_LINE for x, h in lines[a]):
                on += 1
            else:
                off += 1
    return on, off


def fit_cell_offset(
    ru_raw: np.ndarray, lit: np.ndarray, start: tuple[float, float], *, search: bool = True
) -> CellFit | None:
    """The offset (right, up; sub-cell sides, added to the dots) that puts the most lit row dots
    of the cell on :func:`mark_lines` and the fewest on none, searched :data:`SEARCH` either side
    of ``start`` (the pipeline's offset) per axis, the nearest to ``start`` among equals
    (``search`` False: the counts at ``start`` itself).
    ``ru_raw``: the frame's dots in cell units, rotated by the heading fit, not shifted. None
    when the frame shows no row of the cell."""
    lit = np.asarray(lit, bool)
    p0 = np.asarray(ru_raw, float)[lit]
    if not len(p0):
        return None
    orient = row_orientation(p0)
    rows = orient >= 0
    # a row along 'up' (orient 1) is read on the right coordinate (axis 0), one along 'right' on up
    p0, axis_of = p0[rows], np.where(orient[rows] == 1, 0, 1)
    if not len(p0):
        return None
    lines = mark_lines()
    off = np.asarray(start, float).copy()
    near = _line_distance(p0 + off, axis_of, lines) <= NEAR_LINE
    p0, axis_of = p0[near], axis_of[near]
    if not len(p0):
        return None
    ambiguous = False
    steps = np.round(np.arange(-SEARCH, SEARCH + STEP / 2, STEP), 4)
    for a in (0, 1) if search else ():
        sel = axis_of == a
        if not sel.any():
            continue
        scored = []
        for d in steps:
            shift = off.copy()
            shift[a] += d
            scored.append((_score(p0[sel] + shift, axis_of[sel], lines), -abs(d), d))
        (best, _), _, best_d = max(scored)
        if best <= 0:  # no row of the cell on a line anywhere in reach: the start stands
            continue
        # another offset as good, beyond the band the best one's lines allow, reads the rows
        # on other lines: the cell's rows cannot say where the robot stands
        ambiguous |= any(sc[0] == best and abs(d - best_d) > 3 * ON_LINE for sc, _, d in scored)
        off[a] += best_d
    on, bad = _counts(p0 + off, axis_of, lines)
    return CellFit((float(off[0]), float(off[1])), on, bad, ambiguous)


def frame_dots(res, geometry) -> tuple[np.ndarray, np.ndarray]:
    """A pipeline result's dots in cell units, rotated back by the heading it was read with (not
    shifted by any offset), and which are lit."""
    dots = res.dots
    if not len(dots):
        return np.zeros((0, 2)), np.zeros(0, bool)
    cell_pts = rotate_about_robot(geometry.to_cell(dots.xy_px), res.observation.heading_error_rad)
    return cell_pts, np.asarray(dots.lit, bool)
