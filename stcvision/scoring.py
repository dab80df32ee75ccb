"""Score pipeline results against ground truth (``sim_camera`` truth dicts).

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

__all__ = ["FrameScore", "score_frame", "summarize"]


@dataclass
class FrameScore:
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
    sc = FrameScore()
    tdots = [d for d in truth["dots"] if d["visible"] and d["age_s"] >= 0]
    txy = np.array([d["xy_robot_m"] for d in tdots]).reshape(-1, 2)
    tsnr = np.array([d["snr"] for d in tdots])
    should = tsnr >= snr_visible
    sc.dots_expected = int(should.sum())
    d = result.dots
    found = np.flatnonzero(d.lit)
    sc.dots_found = len(found)
    matched_truth = np.zeros(len(tdots), bool)
    for k in found:
        if len(txy) == 0:
            break
        dist = np.hypot(*(txy - d.xy_m[k]).T)
        j = int(np.argmin(dist))
        if dist[j] <= match_m and not matched_truth[j]:
            matched_truth[j] = True
            sc.dots_true_positive += 1
            sc.dot_err_mm.append(1000 * float(dist[j]))
            if tdots[j]["uv_px"] is not None:
                uv = profile.robot_to_image(d.xy_m[k][None])[0]
                sc.dot_err_px.append(float(np.hypot(*(uv - tdots[j]["uv_px"]))))
    for j, t in enumerate(tdots):
        if should[j]:
            (sc.dot_ages_found if matched_truth[j] else sc.dot_ages_missed).append(t["age_s"])
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
