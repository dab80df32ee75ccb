"""The first run is never a silent compile: a numba compile (a cache miss) is announced once on
stderr, a kernel loaded from the cache says nothing, and the install step's warm-up compiles what
the demo and the pipeline use."""

import subprocess
import sys
from pathlib import Path

import pytest

from stcvision.compiles import NOTICE

ROOT = Path(__file__).resolve().parents[2]

TWO_COMPILES = """
from stcvision.compiles import announce_compiles
announce_compiles(); announce_compiles()  # idempotent
import sys
assert "numba" not in sys.modules  # listening costs no compiler's import
import numba
f = numba.njit(lambda x: x + 1)
g = numba.njit(lambda x: x * 2)
print(f(1) + g(2))
"""


def test_a_compile_is_announced_once_on_stderr():
    r = subprocess.run([sys.executable, "-c", TWO_COMPILES], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "6"
    assert r.stderr.count(NOTICE) == 1 and r.stdout.count(NOTICE) == 0


#: the demo run in a process of its own, then the kernels it called from Python, with their
#: argument types, one repr'd tuple a line: loaded from the cache, a kernel's callees are part of
#: its machine code, so the loaded signatures are those the demo called
DEMO_THEN_ITS_KERNELS = """
import contextlib, io, sys
from numba.core.registry import CPUDispatcher
from stcvision.cli import main
from stcvision.warm import kernel_entry
with contextlib.redirect_stdout(io.StringIO()):
    code = main(["demo", "--out", sys.argv[1]])
for name, mod in list(sys.modules.items()):
    if name.startswith("stcvision"):
        for d in set(v for v in vars(mod).values() if isinstance(v, CPUDispatcher) and v.py_func.__module__ == name):
            for sig in d.signatures:
                print(repr(kernel_entry(d, sig)))
sys.exit(code)
"""


@pytest.mark.slow
def test_warm_runs_and_then_the_demo_loads_every_kernel_from_the_cache(tmp_path):
    """... and the kernels it loads are those stcvision.demo_kernels lists, with the same
    argument types (the table the first run's second process compiles from the end)."""
    from stcvision.demo_kernels import DEMO_KERNELS

    r = subprocess.run([sys.executable, "-m", "stcvision.warm"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0 and "numba kernels compiled and cached" in r.stderr, r.stderr
    r = subprocess.run(
        [sys.executable, "-c", DEMO_THEN_ITS_KERNELS, str(tmp_path / "d")], capture_output=True, text=True, timeout=600
    )
    assert r.returncode == 0 and NOTICE not in r.stderr, r.stderr  # nothing left to compile
    loaded = set(r.stdout.splitlines())
    listed = {repr(entry) for entry in DEMO_KERNELS}
    again = "python -m stcvision.warm --record-demo > stcvision/demo_kernels.py"
    assert loaded <= listed, f"the demo's kernels changed, run {again}: {loaded - listed}"
    # the rest are kernels those call, compiled as they are: each names a cached kernel and
    # types numba reads back
    import importlib

    from stcvision.warm import _argument_types

    for module, name, args in DEMO_KERNELS:
        kernel = getattr(importlib.import_module(module), name)
        assert kernel.stats.cache_path is not None and repr(_argument_types(args)) == args, (module, name)


def test_the_process_compiling_from_the_end_fills_the_cache_for_the_demo(tmp_path):
    """The second process of a first demo compiles the table's kernels, last first, into numba's
    cache, where the demo finds them (here: the last one, into an empty cache)."""
    import os

    from stcvision.demo_kernels import DEMO_KERNELS

    module, name, _ = DEMO_KERNELS[-1]
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    r = subprocess.run(
        [sys.executable, "-m", "stcvision.warm", "--from-the-end", str(os.getpid()), "1"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    function = getattr(__import__(module, fromlist=[name]), name).py_func.__name__
    assert [p.name for p in (tmp_path / "cache").rglob(f"*.{function}-*.nbi")], list((tmp_path / "cache").rglob("*"))
    # a parent that is gone already: nothing is compiled
    r = subprocess.run(
        [sys.executable, "-m", "stcvision.warm", "--from-the-end", "1", "1"],
        env={**env, "NUMBA_CACHE_DIR": str(tmp_path / "other")},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0 and not (tmp_path / "other").exists(), r.stderr


def test_the_suite_warms_the_cache_and_the_demo_compiles_only_its_own():
    make = (ROOT / "Makefile").read_text()
    warmed = make.split("$(WARMED): $(STAMP)")[1].split("\n\n")[0]
    assert "-m stcvision.warm" in warmed
    assert "\ntest: $(WARMED)" in make and "\ndemo: $(STAMP)" in make
    install = make.split("$(STAMP): pyproject.toml")[1].split("\n\n")[0]
    assert "stcvision.warm" not in install  # the demo's first run compiles what it uses, no more


def _processes_with(text: str, where: str = "environ") -> list[int]:
    """PIDs of this user's processes whose environment (or ``where``: their command line,
    ``cmdline``) holds ``text``."""
    found = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if text.encode() in (d / where).read_bytes():
                    found.append(int(d.name))
            except OSError:
                continue
    return found


def test_a_signal_during_the_warm_up_ends_it_and_its_parts(tmp_path):
    """The parts compile in child processes; SIGTERM to the warm-up ends them all, at once."""
    import os
    import signal
    import time

    cache = str(tmp_path / "numba-cache")  # an empty cache: the parts are compiling when it lands
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
    p = subprocess.Popen([sys.executable, "-m", "stcvision.warm"], env=env, stderr=subprocess.PIPE, text=True)
    line = p.stderr.readline()
    assert "compiling for" in line, line
    deadline = time.monotonic() + 60
    while len(_processes_with(cache)) < 2 and time.monotonic() < deadline:  # a part has started
        time.sleep(0.05)
    p.send_signal(signal.SIGTERM)
    t0 = time.monotonic()
    p.wait(timeout=30)
    waited = time.monotonic() - t0
    assert p.returncode == 128 + signal.SIGTERM and "interrupted" in p.stderr.read()
    assert waited < 10  # within a second or two on a quiet machine; the bound allows for load
    deadline = time.monotonic() + 10
    while _processes_with(cache) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _processes_with(cache) == []


def test_a_signal_as_a_part_starts_still_ends_that_part(monkeypatch):
    """A signal that lands while a part is being started (after its fork, before the warm-up knows
    it) waits until the part is known, so that the part is ended with the others, not orphaned."""
    import os
    import signal

    import pytest

    from stcvision import warm as warm_module
    from stcvision.errors import Terminated

    started = []
    real_popen = subprocess.Popen

    def popen(*args, **kwargs):
        proc = real_popen(*args, **kwargs)
        started.append(proc)
        os.kill(os.getpid(), signal.SIGTERM)  # the signal lands inside the start of the part
        return proc

    def on_term(signum, frame):
        raise Terminated(signum)

    monkeypatch.setattr(warm_module.subprocess, "Popen", popen)
    previous = signal.signal(signal.SIGTERM, on_term)
    try:
        with pytest.raises(Terminated):
            warm_module.warm(verbose=False, processes=1)
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert len(started) == 1 and started[0].poll() is not None  # the part was ended and reaped


LOST_SIGNALS = """
import numba
from numba.core import event
from stcvision.compiles import announce_compiles
from stcvision.fileio import interrupt_received, new_run, signal_received
announce_compiles()
import numba  # the listener is registered as numba loads
new_run()
signal_received(15)  # as the SIGTERM handler does before raising: its exception then lost
try:
    numba.njit(lambda x: x + 1)(1)
    print("compiled")
except KeyboardInterrupt as exc:
    print("stopped", getattr(exc, "signum", None))
new_run()

class CtrlC(event.Listener):  # a Ctrl-C that lands while the next function compiles
    def on_start(self, ev):
        interrupt_received()
    def on_end(self, ev):
        pass

ctrl_c = CtrlC()
event.register("numba:compile", ctrl_c)
try:
    numba.njit(lambda x: x * 2)(1)
    print("compiled")
except KeyboardInterrupt as exc:
    print("stopped", type(exc).__name__)
event.unregister("numba:compile", ctrl_c)
new_run()
print(numba.njit(lambda x: x * 3)(1))  # a compile with no signal in it runs to its end
"""


def test_a_signal_lost_inside_a_compile_still_ends_it():
    """ctypes drops an exception raised inside a callback from C (llvmlite's, while LLVM
    finalises code), so a signal landing there was lost and the compile ran on for tens of
    seconds; the compile listener raises it again as the function's compile ends."""
    r = subprocess.run([sys.executable, "-c", LOST_SIGNALS], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split("\n")[:3] == ["stopped 15", "stopped KeyboardInterrupt", "3"], r.stdout


@pytest.mark.slow
def test_sigterm_during_the_demos_first_compile_stops_it(tmp_path):
    """Measured before the listener: SIGTERM 6 and 15 s into a cold demo took 33 and 23 s to end it."""
    import os
    import signal
    import time

    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    stc = str(Path(sys.executable).with_name("stcvision"))
    p = subprocess.Popen(
        [stc, "demo", "--out", str(tmp_path / "d")],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert NOTICE in p.stderr.readline()  # compiling now
    time.sleep(2.0)
    compilers = _compiling_from_the_end(p.pid)
    assert compilers  # the second process, compiling from the last kernel
    p.send_signal(signal.SIGTERM)
    t0 = time.monotonic()
    p.wait(timeout=60)
    err = p.stderr.read()
    assert p.returncode == 128 + signal.SIGTERM and "interrupted" in err and "Traceback" not in err, err
    assert time.monotonic() - t0 < 8  # a function's compile at most, under the suite's load
    assert _gone(compilers, within=3.0)  # it ends with the demo
    # killed outright, the demo leaves no second process behind either (it dies with its parent)
    p = subprocess.Popen(
        [stc, "demo", "--out", str(tmp_path / "e")], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    p.stderr.readline()
    deadline = time.monotonic() + 10
    while not (compilers := _compiling_from_the_end(p.pid)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert compilers
    p.kill()
    p.wait(timeout=10)
    assert _gone(compilers, within=3.0)


def _compiling_from_the_end(parent: int) -> list[int]:
    """PIDs of the processes compiling the demo's kernels from the end for ``parent``."""
    return _processes_with(f"--from-the-end\0{parent}\0", "cmdline")


def _gone(pids: list[int], *, within: float) -> bool:
    """Whether every one of ``pids`` has ended (or is a zombie, ended but not yet reaped) within
    ``within`` seconds."""
    import time

    deadline = time.monotonic() + within
    while any(_state(pid) != b"Z" for pid in pids):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def _state(pid: int) -> bytes:
    """The process's state letter (``/proc/PID/stat``); ``Z`` for one that is gone."""
    try:
        return Path(f"/proc/{pid}/stat").read_bytes().rsplit(b")", 1)[1].split()[0]
    except (OSError, IndexError):
        return b"Z"


def test_an_ignored_ctrl_c_stays_ignored_in_a_part_started_while_signals_wait():
    """A warm-up whose Ctrl-C is ignored (started in the background by a script) starts parts
    that ignore it too: waiting signals leave an ignored one alone."""
    import signal

    from stcvision import warm as warm_module

    probe = "import signal; print(signal.getsignal(signal.SIGINT) is signal.SIG_IGN)"
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with warm_module._signals_deferred():
            r = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)
    assert r.stdout.strip() == "True", r.stderr
