"""Score pipeline results against ground truth (``stcvision.sim_camera`` truth dicts).

Used by the tests and by ``stcvision eval``. Only what the camera can see is held against the
pipeline: a truth dot "should be found" if it is visible and its expected SNR is at least
``snr_visible`` (8: the detection threshold is 5, and the expected SNR assumes a perfectly
centred window and a noiseless dark frame). A box counts as marked if ``min_dots`` of its dots
should be found (the observation needs that many), and is left out (ambiguous) if its
``min_dots``-th brightest dot lies between ``snr_ambiguous`` and ``snr_visible`` -- at the edge
of the visibility horizon. ``snr_ambiguous`` is 1.5: the faint-row search reads a row of four
dots whose SNRs average 3 (sum / 2 >= 6), or, through one found dot, 2.5 for the other three,
and noise lets it read some a little fainter; such a box is really marked, so reading it either
way is not held against the pipeline.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["DotMatch", "FrameScore", "match_dots", "score_frame", "summarize"]


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


def match_dots(xy_m, truth: dict, profile, *, match_m: float = 0.01) -> DotMatch:
    """Match detections to the visible truth dots.

    Match detections ``xy_m`` ((N, 2) robot frame, strongest first) to the visible truth
    dots: greedily, each detection to its nearest truth dot if within ``match_m`` and not taken
    already (else it is a false detection). The image error is that of the detection mapped
    through ``profile.robot_to_image`` (none without a profile). Any detector's dots can be scored this way (the
    pipeline's, the plain-OpenCV baseline's).
    """
    tdots = [d for d in truth["dots"] if d["visible"] and d["age_s"] >= 0]
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


def score_frame(
    result,
    truth: dict,
    profile,
    *,
    snr_visible: float = 8.0,
    snr_ambiguous: float = 1.5,
    match_m: float = 0.01,
    min_dots: int = 2,
) -> FrameScore:
    """Score one frame's pipeline result against its ground truth.

    The module docstring gives the rules: only what the camera can see is held against the
    pipeline.

    Parameters
    ----------
    result : PipelineResult
        The pipeline's reading of the frame (its dots, heading and observation are scored).
    truth : dict
        The frame's truth (``stcvision.sim_camera`` truth dict: dots, pose, cell).
    profile : Profile or None
        The camera's profile: the matched dots' image errors go through
        ``profile.robot_to_image`` (none without a profile).
    snr_visible : float
        A truth dot of at least this expected SNR should be found.
    snr_ambiguous : float
        A box whose ``min_dots``-th brightest dot lies between this and ``snr_visible`` is left
        out.
    match_m : float
        A found dot matches a truth dot within this distance (m).
    min_dots : int
        Dots that make a box marked, as the observation needs them.

    Returns
    -------
    FrameScore
        The dots, heading, boxes and obstacles held against the truth.
    """
    sc = FrameScore()
    d = result.dots
    m = match_dots(d.xy_m[np.flatnonzero(d.lit)], truth, profile, match_m=match_m)
    tdots = m.truth
    should = np.array([t["snr"] >= snr_visible for t in tdots], bool)
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
            (sc.dot_ages_found if m.found[j] >= 0 else sc.dot_ages_missed).append(t["age_s"])
    cell = truth.get("cell")
    if cell is not None:
        true_err = truth["pose"]["heading_rad"] - cell["entry_heading_rad"]
        if result.heading.ok:
            sc.heading_err_deg = math.degrees(result.heading.heading_error_rad - true_err)

        def status(sel):
            snrs = sorted((t["snr"] for t in tdots if sel(t)), reverse=True)
            m = snrs[min_dots - 1] if len(snrs) >= min_dots else 0.0
            return None if snr_ambiguous <= m < snr_visible else m >= snr_visible

        obs = result.observation
        for b in obs.boxes:
            st = status(lambda t, b=b: t.get("box") == b.box)
            if st is None:
                continue
            sc.boxes_total += 1
            if b.lit == st:
                sc.boxes_correct += 1
            else:
                sc.errors.append(f"box {b.box}: read {'lit' if b.lit else 'unlit'}")
        tn = {n["direction"]: n for n in cell["neighbours"]}
        for name, n in obs.neighbours.items():
            sc.obstacles_total += 1
            if n.has_red == tn[name]["has_red"]:
                sc.obstacles_correct += 1
            else:
                sc.errors.append(f"{name}: red read {n.has_red}")
    return sc


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
    }
