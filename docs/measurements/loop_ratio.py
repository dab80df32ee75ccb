"""The closed loop's overhead ratio of one cooled-camera tour, measured from outside the loop, so
that it runs on a checkout without ``stcvision.controllers.stc.timing`` too: every
``SyntheticCamera.render`` and every ``Pipeline.process`` is timed (wall and this thread's CPU
time) by wrapping the two methods, after a 3x3 tour has loaded the compiled kernels (a frame read
again against the cell's own marks adds a pipeline time here, where the bench counts it to the
loop; the 22x22 tours measured read none again). Prints one JSON line: frames, wall and CPU seconds, the medians,
the ratio on wall time and on CPU time, the frames' share of the CPU time. Run it for another
checkout with that checkout installed, alternating with this one so that a busy host slows both:

    python docs/measurements/loop_ratio.py [--cells 22] [--seed 0]

Used for the table of docs/results/stc.md ("The loop against its frames"); ``stcvision bench
--loop-only`` is the benchmark.
"""

from __future__ import annotations

import argparse
import json
import time


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cells", type=int, default=22)
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    import numpy as np

    from stcvision.calibration.profiles import default_profile
    from stcvision.controllers.stc.experiments import OBSTACLE_FRACTION, random_board
    from stcvision.controllers.stc.loop import CoverConfig, run_cover
    from stcvision.pipeline import Pipeline
    from stcvision.sim_camera import hardware
    from stcvision.sim_camera.camera import SyntheticCamera

    times = {"render": [], "pipeline": [], "render_cpu": [], "pipeline_cpu": []}

    def timed(real, name):
        def run(self, *args, **kw):
            t, c = time.perf_counter(), time.thread_time()
            out = real(self, *args, **kw)
            times[name].append(time.perf_counter() - t)
            times[f"{name}_cpu"].append(time.thread_time() - c)
            return out

        return run

    SyntheticCamera.render = timed(SyntheticCamera.render, "render")
    Pipeline.process = timed(Pipeline.process, "pipeline")
    cfg = CoverConfig(seed=a.seed, camera=hardware.load_camera("cooled"))
    run_cover(random_board(3, 3, 0.0, a.seed, None), cfg)  # the compiled kernels, loaded
    for v in times.values():
        v.clear()
    board = random_board(a.cells, a.cells, OBSTACLE_FRACTION, a.seed, default_profile().subcell_m)
    cpu0 = time.thread_time()
    out = run_cover(board, cfg)
    cpu = time.thread_time() - cpu0
    n, med = out["frames"], {k: float(np.median(v)) for k, v in times.items()}
    print(
        json.dumps(
            {
                "cells": a.cells,
                "seed": a.seed,
                "frames": n,
                "timed": [len(times["render"]), len(times["pipeline"])],
                "complete": out["complete"],
                "wall_s": round(out["wall_s"], 2),
                "cpu_s": round(cpu, 2),
                "render_ms_median": round(1e3 * med["render"], 3),
                "pipeline_ms_median": round(1e3 * med["pipeline"], 3),
                "ratio": round(out["wall_s"] / (n * (med["render"] + med["pipeline"])), 3),
                "ratio_cpu": round(cpu / (n * (med["render_cpu"] + med["pipeline_cpu"])), 3),
                "frame_cpu_share": round((sum(times["render_cpu"]) + sum(times["pipeline_cpu"])) / cpu, 3),
            }
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
