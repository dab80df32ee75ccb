"""How fast the closed loop runs against its frames: the loop's overhead ratio.

A camera tour's time is its frames' rendering and reading plus everything else the loop does
(the robot's motion and clock, the readings' checks, the claims, the referee, the observers, the
dark frames, the set-up). The ratio says how much that everything else costs::

    loop_overhead_ratio = wall time of the tour / (frames x (median render + median pipeline))

* **wall time**: :func:`stcvision.controllers.stc.loop.run_cover`'s own ``wall_s``, from the
  parts' construction (camera, pipelines, dark frames) to the summary; the compiled kernels are
  loaded (or compiled) before, by a small tour of the same camera, so the figure is the loop's
  and not the compiler's.
* **frames**: every frame the tour rendered (the summary's ``frames``: short, long and stacked
  frames, and frames taken again).
* **median render, median pipeline**: of the same tour's frames, each timed where the loop takes
  it (:class:`FrameTimes`: ``SyntheticCamera.render`` and the ``Pipeline.process`` that reads the
  frame; a frame read again against the cell's own marks counts that second reading to the loop).

``loop_overhead_ratio_cpu`` is the same ratio on this thread's CPU time (the tour's and each
frame's): on a machine whose other processes take turns on the core, the wall time's figures
include their turns, the CPU time's do not.

A ratio of 1 is a loop that costs nothing beyond its frames. Medians make the denominator what a
typical frame costs, so frames that cost more than the typical one (long frames' many dots) count
to the loop's overhead too; the means' ratio (``loop_frame_share``: the frames' own time over the
wall time) is given beside it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

__all__ = ["LOOP_WARM_CELLS", "FrameTimes", "bench_loop", "profile_loop"]

#: the board of the small tour that loads the compiled kernels before the timed one (cells a side)
LOOP_WARM_CELLS = 3


@dataclass(slots=True)
class FrameTimes:
    """The render and pipeline time of every frame a tour takes (seconds), in order.

    A :class:`stcvision.controllers.stc.frames.RobotCamera` given one (its ``times``) adds to it.
    """

    render_s: list[float] = field(default_factory=list)
    pipeline_s: list[float] = field(default_factory=list)
    render_cpu_s: list[float] = field(default_factory=list)
    pipeline_cpu_s: list[float] = field(default_factory=list)
    stage_ms: list[dict] = field(default_factory=list)

    @staticmethod
    def now() -> tuple[float, float]:
        """The clocks a frame is timed by: (wall, this thread's CPU time), seconds."""
        return time.perf_counter(), time.thread_time()

    def add_render(self, since: tuple[float, float]) -> None:
        """Count one rendered frame, begun at ``since`` (:meth:`now`)."""
        wall, cpu = self.now()
        self.render_s.append(wall - since[0])
        self.render_cpu_s.append(cpu - since[1])

    def add_pipeline(self, since: tuple[float, float], stage_ms: dict) -> None:
        """Count one frame's reading, begun at ``since`` (:meth:`now`), and the pipeline's own
        per-stage times (ms)."""
        wall, cpu = self.now()
        self.pipeline_s.append(wall - since[0])
        self.pipeline_cpu_s.append(cpu - since[1])
        self.stage_ms.append(stage_ms)


def _timed_tour(board, cfg) -> tuple[dict, float, FrameTimes | None]:
    """Run one tour with its frames timed: (summary, its CPU seconds, frame times; None without a camera)."""
    from stcvision.controllers.stc.loop import run_cover

    times = FrameTimes()
    seen: list = []

    def attach(perception) -> None:
        cam = getattr(perception, "cam", None)
        if cam is not None and hasattr(cam, "times"):
            cam.times = times
            seen.append(cam)

    cpu0 = time.thread_time()
    summary = run_cover(board, cfg, perception_hook=attach)
    return summary, time.thread_time() - cpu0, (times if seen else None)


def _warm(cfg) -> None:
    """Load the compiled kernels the tour uses: a small tour of the same camera and perception."""
    from dataclasses import replace

    from stcvision.controllers.stc.experiments import random_board
    from stcvision.controllers.stc.loop import run_cover

    board = random_board(LOOP_WARM_CELLS, LOOP_WARM_CELLS, 0.0, cfg.seed, None)
    run_cover(board, replace(cfg, trace=False))


def bench_loop(board, cfg) -> dict:
    """Time one tour of ``board`` and its frames: the loop's overhead ratio (module docstring).

    Parameters
    ----------
    board : Board
        The board to cover.
    cfg : CoverConfig
        The run's settings (its perception should be the camera's: the others take no frames).

    Returns
    -------
    dict
        ``loop_overhead_ratio``, ``loop_wall_s``, ``loop_frames``, the medians and means of the
        frames' render and pipeline times (ms), the pipeline's per-stage medians (ms), the frames'
        share of the wall time, and the tour's outcome (complete, decisions).
    """
    _warm(cfg)
    summary, cpu_s, times = _timed_tour(board, cfg)
    out = {
        "loop_board_cells": summary["board_cells"],
        "loop_camera": summary["camera"],
        "loop_seed": cfg.seed,
        "loop_complete": summary["complete"],
        "loop_decisions": summary["decisions"],
        "loop_frames": summary["frames"],
        "loop_wall_s": summary["wall_s"],
        "loop_cpu_s": cpu_s,
    }
    if times is None or not times.render_s or not times.pipeline_s:
        out["loop_overhead_ratio"] = out["loop_overhead_ratio_cpu"] = None  # no frames: nothing to measure against
        return out
    render, pipe = np.asarray(times.render_s), np.asarray(times.pipeline_s)
    med_render, med_pipe = float(np.median(render)), float(np.median(pipe))
    stages = times.stage_ms[0].keys()
    out |= {
        "loop_render_ms_median": 1e3 * med_render,
        "loop_pipeline_ms_median": 1e3 * med_pipe,
        "loop_render_ms_mean": 1e3 * float(render.mean()),
        "loop_pipeline_ms_mean": 1e3 * float(pipe.mean()),
        "loop_stage_ms_median": {k: float(np.median([s[k] for s in times.stage_ms])) for k in stages},
        "loop_timed_frames": len(render),
        "loop_overhead_ratio": summary["wall_s"] / (summary["frames"] * (med_render + med_pipe)),
        "loop_frame_share": float(render.sum() + pipe.sum()) / summary["wall_s"],
        "loop_frame_cpu_share": float(np.sum(times.render_cpu_s) + np.sum(times.pipeline_cpu_s)) / cpu_s,
        # the same on this thread's CPU time (tour and frames): what other processes sharing the
        # core do not change
        "loop_overhead_ratio_cpu": cpu_s
        / (summary["frames"] * float(np.median(times.render_cpu_s) + np.median(times.pipeline_cpu_s))),
    }
    return out


def profile_loop(board, cfg, *, top: int) -> str:
    """Profile one tour (cProfile): the ``top`` functions by their own time, as pstats prints them.

    The kernels are loaded first (:func:`bench_loop`'s small tour), so the table is the loop's.

    Parameters
    ----------
    board : Board
        The board to cover.
    cfg : CoverConfig
        The run's settings.
    top : int
        How many functions the table lists.

    Returns
    -------
    str
        The table (``pstats.Stats.print_stats`` sorted by ``tottime``).
    """
    import cProfile
    import io
    import pstats

    from stcvision.controllers.stc.loop import run_cover

    _warm(cfg)
    prof = cProfile.Profile()
    t0 = time.perf_counter()
    prof.runcall(run_cover, board, cfg)
    wall = time.perf_counter() - t0
    buf = io.StringIO()
    pstats.Stats(prof, stream=buf).strip_dirs().sort_stats("tottime").print_stats(top)
    return f"cProfile of the tour ({wall:.1f} s under the profiler), top {top} by own time:\n{buf.getvalue().strip()}"
