"""Stage times of two pipelines side by side in one process, taking turns frame by frame: this
checkout's ``Pipeline`` and another checkout's ``stcvision/pipeline.py`` loaded beside it (its
stages come from this checkout's ``stcvision.stages``, so use it for front-end changes that keep
the stages' functions). On ``stcvision bench``'s scene and frames (one thread), so a busy
machine slows both alike and the ratios hold. Run it with its own ``NUMBA_CACHE_DIR`` when the
other checkout has a ``kernels.py``: numba caches its loops under this script's module names.

    python docs/pipeline_side_by_side.py --other /path/to/other/checkout [--frames 400]

Prints the median ms per stage of each, the front end's sum (dark, window, unwarp, channels)
and the CPU ms per frame of each (thread time). Used for the front end's speed-ups.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

FRONT = ("dark", "window", "unwarp", "channels")


def _module(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def _load(root: Path):
    """The other checkout's ``stcvision/pipeline.py``; from a checkout before the stages became
    a package (one module per stage), with its own ``kernels.py`` for its front end's loops
    (this checkout has none: its loops live with their stages)."""
    kernels = root / "stcvision" / "kernels.py"
    if not kernels.exists():
        return _module("other_pipeline", root / "stcvision" / "pipeline.py")
    sys.modules["stcvision.kernels"] = _module("other_kernels", kernels)
    try:
        return _module("other_pipeline", root / "stcvision" / "pipeline.py")
    finally:
        del sys.modules["stcvision.kernels"]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--other", required=True, metavar="CHECKOUT", help="the other checkout's root")
    p.add_argument("--frames", type=int, default=400, help="frames each (default 400)")
    p.add_argument("--seed", type=int, default=0, help="the bench scene's seed (default 0)")
    a = p.parse_args(argv)
    import cv2
    import numpy as np

    from calibration.profiles import default_profile
    from sim_camera.camera import SyntheticCamera
    from sim_camera.scenarios import benchmark_scene
    from stcvision.pipeline import Pipeline

    cv2.setNumThreads(1)
    other = _load(Path(a.other).resolve())
    board, layer, pose = benchmark_scene(a.seed)
    cam = SyntheticCamera()
    rng = np.random.default_rng(a.seed)
    dark = cam.median_dark(8, rng=rng)
    lights = board.red_lights_m()
    imgs = [cam.render(pose, rng=rng, phosphor=layer, red_lights_m=lights).image for _ in range(8)]
    prof = default_profile()
    pipes = {"other": other.Pipeline(prof, dark=dark), "this": Pipeline(prof, dark=dark)}
    stages = {k: {} for k in pipes}
    cpu = dict.fromkeys(pipes, 0)
    for pipe in pipes.values():
        pipe.process(imgs[0])  # warm up (compiles)
    for i in range(a.frames):
        order = list(pipes.items()) if i % 2 else list(pipes.items())[::-1]  # no first-mover bias
        for name, pipe in order:
            c0 = time.thread_time_ns()
            r = pipe.process(imgs[i % len(imgs)])
            cpu[name] += time.thread_time_ns() - c0
            for k, v in r.stage_ms.items():
                stages[name].setdefault(k, []).append(v)
    print(f"{'stage (ms, median)':<20s} {'other':>8s} {'this':>8s}")
    for k in stages["this"]:
        print(f"{k:<20s} {np.median(stages['other'][k]):8.3f} {np.median(stages['this'][k]):8.3f}")
    for name in ("front end", "total"):
        keys = FRONT if name == "front end" else tuple(stages["this"])
        v = {n: np.median([sum(x) for x in zip(*(stages[n][k] for k in keys), strict=True)]) for n in pipes}
        print(f"{name + ' (per frame)':<20s} {v['other']:8.3f} {v['this']:8.3f}   ratio {v['other'] / v['this']:.2f}x")
    print(f"{'cpu ms per frame':<20s} {cpu['other'] / 1e6 / a.frames:8.3f} {cpu['this'] / 1e6 / a.frames:8.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
