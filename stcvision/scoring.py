"""Score pipeline results against a frame's label.

The label is a person's (``labels.jsonl`` of real frames) or the simulator's ground truth
written as one (:func:`stcvision.labels.label_from_truth`).

Used by the tests and by ``stcvision eval``. :func:`score_label` is the one scoring; only what a
label says is held against the pipeline, and what it leaves out (a box at the edge of
visibility, a field a labeller did not fill) is not scored. From the simulator's truth a dot
"should be found" if it is visible and its expected SNR is at least
:data:`stcvision.labels.SNR_VISIBLE`, and a fainter one down to
:data:`~stcvision.labels.SNR_AMBIGUOUS` is "faint": found or not, it counts neither way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["DotMatch", "FrameScore", "match_dots", "score_frame", "score_label", "summarize"]


@dataclass
class FrameScore:
    """One frame's reading held against its truth (:func:`score_frame`).

    Attributes
    ----------
    dots_expected : int
        Truth dots that should be found (visible, expected SNR at least ``snr_visible``).
    dots_found : int
        Lit dots the pipeline found.
    dots_true_positive : int
        Found dots matched to a visible truth dot.
    dot_err_mm, dot_err_px : list of float
        Each matched dot's floor error (mm) and image error (px), in the order matched.
    dot_ages_found, dot_ages_missed : list of float
        Ages (s) of the truth dots that should be found, found or missed.
    heading_err_deg : float or None
        The heading fit's error (deg); None without a fit or a cell in the truth.
    boxes_correct, boxes_total : int
        Boxes read right, of those scored (ambiguous boxes are left out).
    obstacles_correct, obstacles_total : int
        Neighbours whose red light was read right, of those scored.
    neighbour_marks_correct, neighbour_marks_total : int
        The neighbours' marks read right, of those scored (:func:`score_frame` leaves both 0).
    errors : list of str
        What was read wrong, one line each.
    """

    dots_expected: int = 0
    dots_found: int = 0
    dots_true_positive: int = 0
    dot_err_mm: list = field(default_factory=list)
    dot_err_px: list = field(default_factory=list)
    dot_ages_found: list = field(default_factory=list)
    dot_ages_missed: list = field(default_factory=list)
    heading_err_deg: float | None = None
    boxes_correct: int = 0
    boxes_total: int = 0
    obstacles_correct: int = 0
    obstacles_total: int = 0
    neighbour_marks_correct: int = 0
    neighbour_marks_total: int = 0
    errors: list = field(default_factory=list)
    box_pairs: list = field(default_factory=list)  # (label lit, read lit)
    red_pairs: list = field(default_factory=list)  # (label red, read red), per neighbour
    marks_pairs: list = field(default_factory=list)  # (label marked, read marked), per neighbour


@dataclass(frozen=True, eq=False)
class DotMatch:
    """Found dots matched to a frame's visible truth dots (:func:`match_dots`).

    ``truth``: the visible truth dots (age >= 0), in label order; ``found``: (M,) index of the
    found dot matched to each (-1: none); ``err_mm``, ``err_px``: (M,) its floor and image
    error (NaN where unmatched, or the dot has no image position); ``n_found``: detections
    scored; ``n_true_positive``: of those, matched.
    """

    truth: list
    found: np.ndarray
    err_mm: np.ndarray
    err_px: np.ndarray
    n_found: int

    @property
    def matched(self) -> np.ndarray:
        """(M,) bool: which visible truth dots a found dot matched."""
        return self.found >= 0

    @property
    def n_true_positive(self) -> int:
        """How many found dots matched a visible truth dot."""
        return int(self.matched.sum())


def match_dots(xy_m, truth: dict, profile, *, match_m: float = 0.01, visible_only: bool = True) -> DotMatch:
    """Match detections to the visible truth dots.

    Match detections ``xy_m`` ((N, 2) robot frame, strongest first) to the visible truth
    dots (every dot given, with ``visible_only`` False: a label's): greedily, each detection to
    its nearest truth dot if within ``match_m`` and not taken
    already (else it is a false detection). The image error is that of the detection mapped
    through ``profile.robot_to_image`` (none without a profile). Any detector's dots can be scored this way (the
    pipeline's, the plain-OpenCV baseline's).
    """
    tdots = [d for d in truth["dots"] if d["visible"] and d["age_s"] >= 0] if visible_only else list(truth["dots"])
    txy = np.array([d["xy_robot_m"] for d in tdots]).reshape(-1, 2)
    xy = np.asarray(xy_m, float).reshape(-1, 2)
    found = np.full(len(tdots), -1)
    err_mm = np.full(len(tdots), np.nan)
    err_px = np.full(len(tdots), np.nan)
    for k in range(len(xy) if len(txy) else 0):
        dist = np.hypot(*(txy - xy[k]).T)
        j = int(np.argmin(dist))
        if dist[j] <= match_m and found[j] < 0:
            found[j] = k
            err_mm[j] = 1000 * float(dist[j])
            if profile is not None and tdots[j]["uv_px"] is not None:
                uv = profile.robot_to_image(xy[k][None])[0]
                err_px[j] = float(np.hypot(*(uv - tdots[j]["uv_px"])))
    return DotMatch(tdots, found, err_mm, err_px, len(xy))


def _label_dots(label: dict, profile) -> tuple[list, np.ndarray]:
    """Return the label's dots as :func:`match_dots`' truth list.

    Each with its floor position (robot frame, m): a dot given by its image position alone is
    put on the floor through ``profile``.
    """
    tdots = []
    for d in label.get("dots", ()):
        xy = d.get("xy_m")
        if xy is None:
            xy = profile.image_to_robot(np.asarray(d["uv_px"], float)[None])[0].tolist()
        tdots.append(
            {"xy_robot_m": xy, "uv_px": d.get("uv_px"), "faint": d.get("faint", False), "age_s": d.get("age_s")}
        )
    return tdots


def score_label(result, label: dict, profile, *, match_m: float = 0.01) -> FrameScore:
    """Score one frame's pipeline result against its label.

    Parameters
    ----------
    result : stcvision.pipeline.PipelineResult
        What the pipeline read.
    label : dict
        The frame's label (:func:`stcvision.labels.parse_label`'s form); absent fields are not
        scored.
    profile : stcvision.profile.Profile
        The frame's calibration: puts image-labelled dots on the floor and measures the found
        dots' image error.
    match_m : float
        A detection within this distance on the floor of a labelled dot is that dot.

    Returns
    -------
    FrameScore
        Dots expected, found and matched with their errors; the heading error; boxes, neighbour
        red lights and neighbour marks, each as (label, read) pairs and counts of right readings.
    """
    sc = FrameScore()
    d = result.dots
    if "dots" in label:
        tdots = _label_dots(label, profile)
        m = match_dots(d.xy_m[np.flatnonzero(d.lit)], {"dots": tdots}, profile, match_m=match_m, visible_only=False)
        should = np.array([not t["faint"] for t in tdots], bool)
        sc.dots_expected = int(should.sum())
        sc.dots_found = m.n_found
        sc.dots_true_positive = m.n_true_positive
        order = np.argsort(m.found, kind="stable")  # in the order the detections were matched
        for j in order[m.found[order] >= 0]:
            sc.dot_err_mm.append(float(m.err_mm[j]))
            if not np.isnan(m.err_px[j]):
                sc.dot_err_px.append(float(m.err_px[j]))
        for j, t in enumerate(tdots):
            if should[j]:
                # a person's label gives no age (None): its dots count, in no age bin
                (sc.dot_ages_found if m.found[j] >= 0 else sc.dot_ages_missed).append(t["age_s"])
    if label.get("heading_error_deg") is not None and result.heading.ok:
        sc.heading_err_deg = math.degrees(result.heading.heading_error_rad) - label["heading_error_deg"]
    obs = result.observation
    for b in obs.boxes:
        _tally(sc, "box", label.get("boxes", {}).get(b.box), b.lit, f"box {b.box}: read {'lit' if b.lit else 'unlit'}")
    for name, n in obs.neighbours.items():
        want = label.get("neighbours", {}).get(name, {})
        _tally(sc, "red", want.get("red"), n.has_red, f"{name}: red read {n.has_red}")
        _tally(sc, "marks", want.get("marks"), n.has_marks, f"{name}: marks read {n.has_marks}")
    return sc


#: what :func:`_tally` counts per kind of reading: its (label, read) pairs, total and right counts
_TALLIES = {
    "box": ("box_pairs", "boxes_total", "boxes_correct"),
    "red": ("red_pairs", "obstacles_total", "obstacles_correct"),
    "marks": ("marks_pairs", "neighbour_marks_total", "neighbour_marks_correct"),
}


def _tally(sc: FrameScore, kind: str, want: bool | None, read: bool, error: str) -> None:
    """Count one reading against its label (none when the label leaves it out)."""
    if want is None:
        return
    pairs, total, correct = _TALLIES[kind]
    getattr(sc, pairs).append((want, read))
    setattr(sc, total, getattr(sc, total) + 1)
    if read == want:
        setattr(sc, correct, getattr(sc, correct) + 1)
    else:
        sc.errors.append(error)


def score_frame(result, truth: dict, profile, *, match_m: float = 0.01) -> FrameScore:
    """Score one rendered frame against the simulator's truth.

    :func:`score_label` on the label the truth makes (:func:`stcvision.labels.label_from_truth`).

    Parameters
    ----------
    result : stcvision.pipeline.PipelineResult
        What the pipeline read.
    truth : dict
        The frame's ground truth (``stcvision.sim_camera.truth``).
    profile : stcvision.profile.Profile
        The frame's calibration.
    match_m : float
        Match distance on the floor.

    Returns
    -------
    FrameScore
        As :func:`score_label`.
    """
    from stcvision.labels import label_from_truth

    return score_label(result, label_from_truth(truth), profile, match_m=match_m)


def _recall_precision(pairs) -> tuple[float | None, float | None]:
    """Recall and precision of the positive class (lit, red, marked) over (label, read) pairs."""
    tp = sum(1 for t, r in pairs if t and r)
    pos = sum(1 for t, _ in pairs if t)
    said = sum(1 for _, r in pairs if r)
    return (tp / pos if pos else None), (tp / said if said else None)


def summarize(scores: list[FrameScore]) -> dict:
    """Aggregate metrics over frames (the fields ``stcvision eval`` reports)."""
    exp = sum(s.dots_expected for s in scores)
    found = sum(s.dots_found for s in scores)
    tp_exp = sum(len(s.dot_ages_found) for s in scores)
    tp = sum(s.dots_true_positive for s in scores)
    mm = [e for s in scores for e in s.dot_err_mm]
    px = [e for s in scores for e in s.dot_err_px]
    head = [s.heading_err_deg for s in scores if s.heading_err_deg is not None]
    bt = sum(s.boxes_total for s in scores)
    ot = sum(s.obstacles_total for s in scores)
    mt = sum(s.neighbour_marks_total for s in scores)
    box_r, box_p = _recall_precision([p for s in scores for p in s.box_pairs])
    red_r, red_p = _recall_precision([p for s in scores for p in s.red_pairs])
    marks_r, marks_p = _recall_precision([p for s in scores for p in s.marks_pairs])
    return {
        "frames": len(scores),
        "dot_recall": tp_exp / exp if exp else None,
        "dot_precision": tp / found if found else None,
        "dot_loc_err_px_median": float(np.median(px)) if px else None,
        "dot_loc_err_mm_median": float(np.median(mm)) if mm else None,
        "dot_loc_err_mm_p95": float(np.percentile(mm, 95)) if mm else None,
        "heading_err_deg_rms": float(np.sqrt(np.mean(np.square(head)))) if head else None,
        "heading_fits": len(head),
        "box_accuracy": sum(s.boxes_correct for s in scores) / bt if bt else None,
        "boxes_scored": bt,
        "obstacle_accuracy": sum(s.obstacles_correct for s in scores) / ot if ot else None,
        "obstacles_scored": ot,
        "box_recall": box_r,
        "box_precision": box_p,
        "obstacle_recall": red_r,
        "obstacle_precision": red_p,
        "neighbour_marks_accuracy": sum(s.neighbour_marks_correct for s in scores) / mt if mt else None,
        "neighbour_marks_scored": mt,
        "neighbour_marks_recall": marks_r,
        "neighbour_marks_precision": marks_p,
    }
