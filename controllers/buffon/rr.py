"""One Buffon trial in rerun: an observer of a recorded trial, never inside the simulation.

Entity paths (world coordinates in body lengths, y flipped so north is up in the 2-D view)::

    nest              the nest outline and barriers (static)
    first_visit/trail the pheromone trail of the first visit (static)
    second_visit/path the second visit's path so far
    second_visit/robot the robot now
    crossings         every crossing counted so far, as points
    nbc               crossings so far / second-visit length so far (a time series)

Timeline ``step`` (the second visit's step), one frame per ``every`` steps.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from stcvision.controllers.buffon.nests import BODY_LENGTH_M

__all__ = ["blueprint", "record_trial"]


def blueprint() -> rrb.Blueprint:
    """The layout a trial's recording opens with: the nest with the first visit's trail and
    the second visit's path, nBC over the second visit, on the ``step`` timeline."""
    from stcvision.rr import layout

    return layout(
        rrb.Horizontal(
            rrb.Spatial2DView(
                origin="/",
                contents=["nest/**", "first_visit/**", "second_visit/**", "crossings/**"],
                name="nest (north up)",
            ),
            rrb.TimeSeriesView(origin="nbc", name="nBC over the second visit"),
            column_shares=[3, 2],
        ),
        timeline="step",
    )


def _xy(p) -> np.ndarray:
    p = np.asarray(p, float).reshape(-1, 2) / BODY_LENGTH_M
    return np.column_stack([p[:, 0], -p[:, 1]])


def record_trial(path: str | Path, nest, visit1: np.ndarray, visit2: np.ndarray, *, frames: int = 250) -> Path:
    """Write ``path`` (.rrd, streamed as it is logged: :class:`stcvision.rr.RecordingFile`).

    The trial whose paths are ``visit1``, ``visit2`` ((S, 3) arrays x m, y m, crossed), as
    recorded by :func:`stcvision.controllers.buffon.batched.run_trials`.
    """
    from stcvision.rr import RecordingFile, Recordings

    path = Path(path)
    with Recordings() as recs:
        rec = recs.add(RecordingFile(path, app_id="stcvision-buffon", default_blueprint=blueprint())).rec
        _log(rec, nest, visit1, visit2, frames)
    return path


def _log(rec, nest, visit1, visit2, frames: int) -> None:
    arena = nest.arena
    outline = arena.outer_vertices()
    rec.log("nest/outline", rr.LineStrips2D([_xy(np.vstack([outline, outline[:1]]))], colors=[0, 0, 0]), static=True)
    if arena.barriers:
        bars = [_xy([b.start_m, b.end_m]) for b in arena.barriers]
        rec.log("nest/barriers", rr.LineStrips2D(bars, colors=[90, 90, 90], radii=0.1), static=True)
    rec.log("first_visit/trail", rr.LineStrips2D([_xy(visit1[:, :2])], colors=[60, 120, 255]), static=True)
    steps = len(visit2)
    every = max(1, steps // frames)
    stride = max(1, every // 20)  # the path so far, thinned to ~20 points per frame
    seg = np.hypot(*np.diff(visit2[:, :2], axis=0, prepend=visit2[:1, :2]).T) / BODY_LENGTH_M
    length = np.cumsum(seg)
    count = np.cumsum(visit2[:, 2])
    for s in range(every - 1, steps, every):
        rec.set_time("step", sequence=s)
        rec.log("second_visit/path", rr.LineStrips2D([_xy(visit2[: s + 1 : stride, :2])], colors=[220, 60, 60]))
        rec.log("second_visit/robot", rr.Points2D(_xy(visit2[s, :2]), radii=0.5, colors=[220, 60, 60]))
        hits = visit2[: s + 1][visit2[: s + 1, 2] > 0]
        rec.log("crossings", rr.Points2D(_xy(hits[:, :2]), radii=0.4, colors=[0, 0, 0]))
        if length[s] > 0:
            rec.log("nbc", rr.Scalars(count[s] / length[s]))
