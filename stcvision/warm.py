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


# ------------------------------------------------------------------ the demo's first run, on two cores
#: run with an empty numba cache by ``--record-demo``: the demo, in process, with each cached
#: kernel numba starts compiling for it noted (those it calls from Python and those they call),
#: in the order the compiles start
_RECORDER = """
import io, contextlib, sys
from numba.core import event
seen = []
class Note(event.Listener):
    def on_start(self, ev):
        d = ev.data["dispatcher"]
        if d.py_func.__module__.startswith("stcvision") and d.stats.cache_path is not None:
            entry = stcvision.warm.kernel_entry(d, ev.data["args"])
            if entry and entry not in seen:
                seen.append(entry)
    def on_end(self, ev):
        pass
event.register("numba:compile", Note())
import stcvision.warm
stcvision.warm.start_compiling_from_the_end = lambda: None  # every compile here, in this process
from stcvision.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    code = main(["demo", "--out", sys.argv[1], "--force"])
for entry in seen:
    print(repr(entry))
sys.exit(code)
"""


def kernel_entry(dispatcher, args) -> tuple[str, str, str] | None:
    """A line of :data:`stcvision.demo_kernels.DEMO_KERNELS`: the kernel's module, the name it has
    there, and its argument types as numba writes them; None for a kernel no module names."""
    module = dispatcher.py_func.__module__
    names = [k for k, v in vars(sys.modules[module]).items() if v is dispatcher]
    return (module, names[0], repr(tuple(args))) if names else None


def record_demo_kernels() -> str:
    """The text of :mod:`stcvision.demo_kernels`: the demo run once on an empty numba cache, each
    cached kernel it compiles with its argument types, in the order the compiles start."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="stcvision-record-") as tmp:
        env = {**os.environ, "NUMBA_CACHE_DIR": f"{tmp}/cache"}
        done = subprocess.run(
            [sys.executable, "-c", _RECORDER, f"{tmp}/demo"], env=env, capture_output=True, text=True, check=False
        )
    if done.returncode not in (0, 3):
        raise SystemExit(f"stcvision warm: the demo failed while recording: {done.stderr.strip()[-500:]}")
    lines = "".join(f"    {line},\n" for line in done.stdout.splitlines() if line.startswith("("))
    return (
        "# ruff: noqa: E501 (numba's argument types, one kernel a line)\n"
        '"""The numba kernels the demo compiles on its first run (those it calls from Python and\n'
        "those they call), with their argument types as numba writes them, in the order their\n"
        "compiles start: written by ``python -m stcvision.warm --record-demo``, checked against what\n"
        "the demo loads by ``tests/stcvision/test_warm.py``. On the demo's first run a second process\n"
        "compiles them from the last (:func:`stcvision.warm.compile_from_the_end`) while the demo\n"
        'compiles them from the first."""\n\n'
        "#: (module, the name the kernel has there, its argument types), one kernel a line, as the\n"
        "#: recording writes it\n"
        "# fmt: off\n"
        f"DEMO_KERNELS = (\n{lines})\n"
        "# fmt: on\n"
    )


def _argument_types(text: str) -> tuple:
    """Argument types written as numba's ``repr`` writes them, as numba types."""
    from numba.core import types

    class _Literal:  # ``Literal[int](5)``: a constant a kernel passes to the kernels it calls
        def __getitem__(self, kind):
            return lambda value: types.literal(kind(value))

    names = {**vars(types), "bool": types.boolean, "int": int, "Literal": _Literal()}
    return eval(text, {"__builtins__": {}}, names)  # noqa: S307 (the table is ours, and checked)


def compile_from_the_end(parent: int, count: int | None = None) -> int:
    """Compile the demo's kernels from the last (``count`` of them; all by default), each unless
    numba's cache has it already (the demo, compiling from the first, wrote it); end with
    ``parent``, the demo's process."""
    import importlib

    _die_with(parent)
    from stcvision.demo_kernels import DEMO_KERNELS

    for module, name, args in list(reversed(DEMO_KERNELS))[:count]:
        try:
            getattr(importlib.import_module(module), name).compile(_argument_types(args))
        except Exception:  # noqa: BLE001 (a kernel that no longer takes these types: the demo compiles its own)
            continue
    return 0


def _die_with(parent: int) -> None:
    """End this process with SIGTERM when ``parent`` ends, however it ends (Linux's
    ``PR_SET_PDEATHSIG``; elsewhere the parent's exit ends it); and now if it has ended already."""
    import ctypes

    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # 1: PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent:
        sys.exit(0)


_FROM_THE_END: list[subprocess.Popen] = []


def start_compiling_from_the_end() -> None:
    """Start the process of :func:`compile_from_the_end` beside this one, which is about to compile
    the demo's kernels from the first: the two meet halfway, and the first run's compile takes
    the two cores. It ends when this process exits (or is killed), or when it is done."""
    import atexit

    if _FROM_THE_END:
        return
    with _signals_deferred():
        proc = subprocess.Popen(
            [sys.executable, "-m", "stcvision.warm", "--from-the-end", str(os.getpid())],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        _FROM_THE_END.append(proc)
        atexit.register(_end_from_the_end)


def _end_from_the_end() -> None:
    _end(_FROM_THE_END)


def _end(procs: list[subprocess.Popen]) -> None:
    """End compiling processes: SIGTERM to all, then each is waited for and killed if it has not
    ended within :data:`_PART_GRACE_S` (one inside a long LLVM pass answers late; numba writes
    its cache files whole, a temporary file renamed, so a kill leaves no half file)."""
    for proc in procs:
        if proc.poll() is None:
            proc.terminate()
    for proc in procs:
        try:
            proc.wait(timeout=_PART_GRACE_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


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
            _end([proc for _, proc, _, _ in running])  # a signal or a failure: the other parts end now
    return times


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--part"]:
        import json

        return _run_part(json.loads(argv[1]))
    if argv[:1] == ["--from-the-end"]:
        return compile_from_the_end(int(argv[1]), int(argv[2]) if len(argv) > 2 else None)
    if argv[:1] == ["--record-demo"]:
        sys.stdout.write(record_demo_kernels())
        return 0

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
