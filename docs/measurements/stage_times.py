"""Per-stage pipeline times on ``stcvision bench``'s frames: the median ms of each stage and of
the whole over ``--frames`` frames (after a warm-up), ``--repeats`` times. Run it for another
checkout with that checkout on the path, alternating with this one so a busy host slows both:

    python docs/measurements/stage_times.py [--frames 1000] [--repeats 2] [--seed 0]
    PYTHONPATH=/path/to/other python /path/to/other/docs/measurements/stage_times.py   # or this file

Used for the per-stage table (docs/results/pipeline.md, "Speed"); ``stcvision bench`` is the benchmark.
"""

from __future__ import annotations

import argparse


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--frames", type=int, default=1000)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    import cv2
    import numpy as np

    from stcvision.calibration.profiles import default_profile
    from stcvision.pipeline import STAGES, Pipeline
    from stcvision.sim_camera.scenarios import benchmark_frames

    cv2.setNumThreads(1)
    dark, imgs = benchmark_frames(a.seed)
    pipe = Pipeline(default_profile(), dark=dark)
    for i in range(30):
        pipe.process(imgs[i % len(imgs)])
    for _ in range(a.repeats):
        per = {s: [] for s in STAGES}
        total = []
        for i in range(a.frames):
            r = pipe.process(imgs[i % len(imgs)])
            for k, v in r.stage_ms.items():
                per[k].append(v)
            total.append(r.total_ms)
        stages = " ".join(f"{k} {np.median(v):.3f}" for k, v in per.items())
        print(f"total {np.median(total):.3f} {stages}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
