"""Compile, once, the numba kernels a first run would otherwise compile in front of the user.

numba compiles a kernel on its first call and keeps the machine code in ``__pycache__``
(``cache=True``); every later process loads it in milliseconds. On a fresh install the first
``stcvision demo`` would spend ~30 s compiling in silence, so ``make``'s install step runs
``python -m stcvision.warm``: it does, small, what the demo and the pipeline do -- the demo's
closed loop itself (render, 8-bit pipeline, world, recording) into a temporary folder, and a
16-bit frame of the cooled camera through the pipeline -- so that each of their kernels is
compiled with the argument types they will meet. Buffon's and the other rooms' kernels compile
on their first use instead (only what runs).

:func:`stcvision.compiles.announce_compiles` (the CLI installs it) says on stderr, once per
process, when a kernel is compiled rather than loaded from the cache, so a slow first run is
never a silent one.
"""

from __future__ import annotations

import sys
import time


def warm(*, verbose: bool = True) -> dict:
    """Run the small workloads that compile the demo's and the pipeline's kernels; returns the
    wall time of each (seconds)."""
    import json
    import tempfile
    from pathlib import Path

    from stcvision.cli import main

    times = {}
    with tempfile.TemporaryDirectory(prefix="stcvision-warm-") as tmp:
        steps = [
            ("demo (closed loop, 8-bit pipeline, recording)", ["demo", "--out", f"{tmp}/demo"]),
        ]
        from stcvision.sim_camera.scene import EXAMPLE_SCENE

        scene = Path(tmp) / "scene.json"
        scene.write_text(json.dumps(EXAMPLE_SCENE))
        for cam in ("cooled", "webcam"):
            steps.append(
                (f"render, {cam}", ["render", "--scene", str(scene), "--camera", cam, "--out", f"{tmp}/{cam}"])
            )
            steps.append(
                (
                    f"pipeline, {cam} frame",
                    ["pipeline", f"{tmp}/{cam}/frame.png", "--dark", f"{tmp}/{cam}/dark.png", "--json"],
                )
            )
        import contextlib
        import io

        for name, argv in steps:
            t0 = time.perf_counter()
            with contextlib.redirect_stdout(io.StringIO()):
                code = main(argv)
            times[name] = round(time.perf_counter() - t0, 2)
            if verbose:
                print(f"stcvision warm: {name}: {times[name]:.1f} s", file=sys.stderr, flush=True)
            if code not in (0, 3):  # 3: the robot did not complete, which still compiled everything
                raise SystemExit(f"stcvision warm: {' '.join(argv)} failed with exit code {code}")
    return times


def main() -> int:
    t0 = time.perf_counter()
    warm()
    print(f"stcvision warm: numba kernels compiled and cached in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
