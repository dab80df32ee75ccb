"""Time this checkout's camera render beside another checkout's, in one process (for the camera's speed-ups).

    python docs/render_side_by_side.py --reference /path/to/other/checkout [--frames 40] [--repeats 5] [--clock thread]

The reference's ``sim_camera/optics.py``, ``sensor.py`` and ``camera.py`` are loaded under other
module names (the phosphor layer and bench scene are this checkout's), both cameras render the
``stcvision bench`` scene in interleaved blocks, at one pose and from a new pose every frame,
and the medians, their ratio and whether the frames are bit for bit the same are printed.
``--clock thread`` (default) times this thread's CPU time, which other processes on a busy
machine do not inflate; ``--clock wall`` the wall clock, as ``stcvision bench`` does.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
import types
from pathlib import Path


def _load(name: str, path: Path, replace: tuple = ()) -> types.ModuleType:
    """``path`` run as module ``name``, with numba's on-disk cache off: a cached function of
    the reference would be stored beside its file under this module name, and the reference
    checkout's own runs would then fail to load it."""
    src = path.read_text().replace("cache=True", "cache=False")
    for a, b in replace:
        src = src.replace(a, b)
    mod = types.ModuleType(name)
    mod.__file__ = str(path)
    sys.modules[name] = mod
    exec(compile(src, str(path), "exec"), mod.__dict__)
    return mod


def main(argv=None) -> None:
    import cv2
    import numpy as np

    from sim_camera.camera import Pose, SyntheticCamera
    from sim_camera.scenarios import benchmark_scene

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reference", required=True, type=Path, help="a checkout to compare with (its sim_camera/)")
    ap.add_argument("--frames", type=int, default=40, help="frames per block (default 40)")
    ap.add_argument("--repeats", type=int, default=5, help="interleaved blocks per variant (default 5)")
    ap.add_argument("--clock", choices=("thread", "wall"), default="thread")
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    ref = args.reference / "sim_camera"
    _load("reference_optics", ref / "optics.py")
    _load("reference_sensor", ref / "sensor.py")
    old_cam = _load(
        "reference_camera",
        ref / "camera.py",
        (
            ("from sim_camera.sensor import", "from reference_sensor import"),
            ("from sim_camera.optics import", "from reference_optics import"),
        ),
    )
    board, layer, pose = benchmark_scene(0)
    lights = board.red_lights_m()
    cams = {"reference": old_cam.SyntheticCamera(), "this": SyntheticCamera()}
    clock = time.thread_time_ns if args.clock == "thread" else time.perf_counter_ns

    def poses(kind):
        if kind == "one pose":
            return itertools.repeat(pose)
        return (Pose(pose.x_m + 1e-3 * k, pose.y_m, pose.heading_rad) for k in itertools.count())

    def block(cam, it) -> list[float]:
        rng = np.random.default_rng(0)
        cam.render(next(it), rng=rng, phosphor=layer, red_lights_m=lights)  # warm up
        out = []
        for _ in range(args.frames):
            p = next(it)
            t0 = clock()
            cam.render(p, rng=rng, phosphor=layer, red_lights_m=lights)
            out.append((clock() - t0) / 1e6)
        return out

    times: dict[tuple[str, str], list[float]] = {}
    for _ in range(args.repeats):
        for kind in ("one pose", "new pose every frame"):
            for name, cam in cams.items():
                times.setdefault((kind, name), []).extend(block(cam, poses(kind)))
    for kind in ("one pose", "new pose every frame"):
        ref_ms, new_ms = (float(np.median(times[(kind, n)])) for n in ("reference", "this"))
        print(f"{kind:22s} reference {ref_ms:6.2f} ms   this {new_ms:6.2f} ms   ratio {new_ms / ref_ms:.2f}")
    same = differ = 0
    for k, p in enumerate(itertools.islice(poses("new pose every frame"), 0, 20 * args.frames, 20)):
        a, b = (
            c.render(p, rng=np.random.default_rng(k), phosphor=layer, red_lights_m=lights).image for c in cams.values()
        )
        same += np.array_equal(a, b)
        differ += int(np.count_nonzero(a != b))
    print(
        f"{args.clock} clock, {args.repeats} x {args.frames} frames each; frames bit for bit the same: "
        f"{same} of {args.frames} poses ({differ} differing pixel values in all)"
    )


if __name__ == "__main__":
    main()
