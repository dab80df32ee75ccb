"""``stcvision cover plan``: "what camera do I need?" answered by the physics-limited camera.

It runs the tour with ``perception="ideal"`` (the camera's frames and time, exactly the marks
within their visibility horizon; no rendering, no pipeline: seconds), at the given camera and
robot profiles with exposure control, and reports whether the tour converges (complete: every
reachable sub-cell once, back at the start) or runs past the longest frame ("out of sight"), how
long it takes, the oldest mark a decision had to read, and the frames it takes (length x count).
It is an upper bound: a real pipeline does no better than the physics
(docs/explanation/stc-robot.md, "The physics-limited camera"). It counts a stack's noise as
idealised (over the square root of its frames); the camera-mode robot sizes its frames by the noise
the stack will have, digitised (``CoverConfig.size_by_frame_noise``), so the plan also gives that
robot's limit: on 8-bit frames its longest frame sees about half as far back.
"""

from __future__ import annotations

import dataclasses
import math

from stcvision.controllers.stc.claims import distance_m
from stcvision.controllers.stc.config import CoverConfig
from stcvision.controllers.stc.frames import Exposures
from stcvision.controllers.stc.loop import is_complete, run_cover
from stcvision.controllers.stc.perception import IdealPerception

__all__ = ["plan"]


def plan(board, cfg: CoverConfig | None = None) -> dict:
    """The physics-limited tour of ``board`` with ``cfg``'s camera and robot (exposure auto)."""
    cfg = dataclasses.replace(cfg or CoverConfig(), perception="ideal", exposure="auto")
    seen: list[IdealPerception] = []
    r = run_cover(board, cfg, perception_hook=seen.append)
    cam = seen[0].cam
    # the farthest claim a reading must make: no mark in the cell ahead, at a look
    reach = distance_m("cell ahead", board.subcell_m, cfg.position_margin_m)
    limit = cam.horizon(len(cam.ladder) - 1, reach)
    camera_limit = Exposures(cfg, board.subcell_m, frame_noise=True).horizon(len(cam.ladder) - 1, reach)
    frames = [
        {"exposure_s": e, "gain": g, "stack": cam.stack(k), "frame_s": e * cam.stack(k), "count": n}
        for k, ((e, g, _), n) in enumerate(zip(cam.ladder, cam.per_rung, strict=True))
        if n
    ]
    return {
        "camera": cfg.camera.name,
        "robot": cfg.robot.name,
        "board_cells": r["board_cells"],
        "subcells_reachable": r["subcells_reachable"],
        "subcells_covered": r["subcells_covered"],
        "converges": is_complete(r),
        "abort_reason": r["abort_reason"],
        "tour_s": r["sim_time_s"],
        "oldest_mark_read_s": r["max_mark_age_read_s"],
        "longest_frame_s": max(f["frame_s"] for f in frames),
        # how old a mark the longest frame still sees at the farthest claim (None: any age)
        "horizon_limit_s": limit if math.isfinite(limit) else None,
        "horizon_limit_reach_m": round(reach, 3),
        # the same for the camera-mode robot, whose frames are sized by the noise they will have
        "camera_horizon_limit_s": camera_limit if math.isfinite(camera_limit) else None,
        "frames": frames,
        "wall_s": r["wall_s"],
    }
