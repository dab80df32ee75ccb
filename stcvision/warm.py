"""Compile, once and in parallel, the numba kernels the commands would otherwise compile on first use.

numba compiles a kernel on its first call and keeps the machine code in ``__pycache__``
(``cache=True``); every later process loads it in milliseconds. ``make demo`` does not wait for
this: the demo compiles the kernels it uses itself, on its first run, and says so on stderr
(:func:`stcvision.compiles.announce_compiles`). ``make test`` runs ``python -m stcvision.warm``
first, so that the suite's parallel workers do not each compile the same kernels: it does, small,
what the demo and the pipeline do -- the demo's closed loop (render, 8-bit pipeline, world,
recording), an 8-bit and a 16-bit frame through render and the pipeline, and a short Buffon trial
-- each in a process of its own, as many at a time as the machine has cores, so that each kernel
is compiled with the argument types it will meet. The other rooms' kernels compile on first use.

A line on stderr as each part starts and ends; Ctrl-C or SIGTERM ends the parts at once (each is
a ``stcvision`` command, which stops within a second of a signal).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time

_STOPS = {signal.SIGINT, signal.SIGTERM}
# how long a part may take to stop on SIGTERM before it is killed (a command stops within a second
# or two of a signal)
_PART_GRACE_S = 1.5


def warm_steps(tmp: str) -> list[tuple[str, list[list[str]]]]:
    """The parts of the warm-up: (name, the ``stcvision`` commands one process runs in turn)."""
    import json
    from pathlib import Path

    from stcvision.sim_camera.scene import EXAMPLE_SCENE

    scene = Path(tmp) / "scene.json"
    scene.write_text(json.dumps(EXAMPLE_SCENE))
    steps = [("demo (closed loop, 8-bit pipeline, recording)", [["demo", "--out", f"{tmp}/demo"]])]
    for cam in ("cooled", "webcam"):
        out = f"{tmp}/{cam}"
        render = ["render", "--scene", str(scene), "--camera", cam, "--out", out]
        pipeline = ["pipeline", f"{out}/frame.png", "--dark", f"{out}/dark.png", "--json"]
        steps.append((f"render and pipeline, {cam} frame", [render, pipeline]))
    # Buffon's visit loop: one compile here rather than one in each of the suite's workers
    buffon = ["buffon", "--nest", "circle:30", "--trials", "2", "--visit-steps", "2000", "--threads", "1"]
    steps.append(("Buffon's explorer", [buffon]))
    return steps


@contextlib.contextmanager
def _signals_deferred():
    """Hold Ctrl-C and SIGTERM for the duration of the block, then act on the first one that came
    as the handler in place would have. Python runs signal handlers in the main thread whichever
    thread the signal reached, so a handler swapped in for the block defers it where blocking the
    signal in this thread would not (another thread may take it). Outside the main thread, where
    handlers cannot be set, the block runs as it is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[tuple[int, object]] = []
    previous: dict[int, object] = {}
    try:
        for s in _STOPS:
            if signal.getsignal(s) is not signal.SIG_IGN:  # an ignored signal stays ignored, in the parts too
                previous[s] = signal.signal(s, lambda signum, frame: caught.append((signum, frame)))
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        for signum, frame in dict(caught).items():  # each signal once, in the order they came
            handler = previous[signum]
            if callable(handler):
                handler(signum, frame)  # the usual handlers raise: the rest wait for the next check
            elif handler == signal.SIG_DFL:
                signal.raise_signal(signum)


def _run_part(commands: list[list[str]]) -> int:
    """Run ``stcvision`` commands in turn in this process (one part of the warm-up)."""
    import io

    from stcvision.cli import main

    for argv in commands:
        with contextlib.redirect_stdout(io.StringIO()):
            code = main(argv)
        if code not in (0, 3):
            return code
    return 0


def warm(*, verbose: bool = True, processes: int | None = None) -> dict:
    """Run the warm-up's parts, ``processes`` at a time (default: the machine's cores); returns
    the wall time of each part (seconds).

    Raises
    ------
    SystemExit
        When a part fails (its exit code is neither 0 nor 3, the robot not completing).
    """
    import json
    import tempfile
    from pathlib import Path

    processes = max(1, processes or os.cpu_count() or 1)
    times: dict[str, float] = {}
    with tempfile.TemporaryDirectory(prefix="stcvision-warm-") as tmp:
        pending = list(enumerate(warm_steps(tmp)))
        running: list[tuple[str, subprocess.Popen, float, Path]] = []
        try:
            while pending or running:
                while pending and len(running) < processes:
                    k, (name, argv) = pending.pop(0)
                    if verbose:
                        print(f"stcvision warm: compiling for {name} ...", file=sys.stderr, flush=True)
                    # a part's stderr (progress, the compile notice) goes to a file: a pipe no one
                    # reads until the part ends would stall a part that writes more than it holds
                    log = Path(tmp) / f"part{k}.log"
                    # a signal that landed inside Popen (after the fork, before the part is in
                    # ``running``) would leave that part compiling on its own: it waits until
                    # the part is known
                    with _signals_deferred(), log.open("w") as err:
                        proc = subprocess.Popen(
                            [sys.executable, "-m", "stcvision.warm", "--part", json.dumps(argv)],
                            stdout=subprocess.DEVNULL,
                            stderr=err,
                        )
                        running.append((name, proc, time.perf_counter(), log))
                time.sleep(0.05)
                for item in list(running):
                    name, proc, t0, log = item
                    code = proc.poll()
                    if code is None:
                        continue
                    running.remove(item)
                    times[name] = round(time.perf_counter() - t0, 2)
                    if code not in (0, 3):  # 3: the robot did not complete, which still compiled everything
                        lines = log.read_text(errors="replace").strip().splitlines()
                        last = lines[-1] if lines else ""
                        raise SystemExit(f"stcvision warm: {name} failed with exit code {code}: {last}")
                    if verbose:
                        print(f"stcvision warm: {name}: {times[name]:.1f} s", file=sys.stderr, flush=True)
        finally:
            for _, proc, _, _ in running:  # a signal or a failure: the other parts end now
                proc.terminate()
            for _, proc, _, _ in running:
                try:  # a part inside a long LLVM pass answers its SIGTERM late: it is killed
                    proc.wait(timeout=_PART_GRACE_S)
                except subprocess.TimeoutExpired:
                    proc.kill()  # numba writes its cache files whole (a temporary file, renamed)
                    proc.wait()
    return times


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--part"]:
        import json

        return _run_part(json.loads(argv[1]))

    from stcvision.errors import Terminated

    def on_term(signum, frame):
        raise Terminated(signum)

    signal.signal(signal.SIGTERM, on_term)
    t0 = time.perf_counter()
    try:
        warm()
    except KeyboardInterrupt as exc:
        print("stcvision warm: interrupted", file=sys.stderr)
        return 128 + (exc.signum if isinstance(exc, Terminated) else signal.SIGINT)
    print(f"stcvision warm: numba kernels compiled and cached in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
