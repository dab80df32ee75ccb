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


@pytest.mark.slow
def test_warm_runs_and_then_the_demo_loads_every_kernel_from_the_cache(tmp_path):
    stc = str(Path(sys.executable).with_name("stcvision"))
    r = subprocess.run([sys.executable, "-m", "stcvision.warm"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0 and "numba kernels compiled and cached" in r.stderr, r.stderr
    r = subprocess.run([stc, "demo", "--out", str(tmp_path / "d")], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0 and NOTICE not in r.stderr, r.stderr  # nothing left to compile


def test_the_suite_warms_the_cache_and_the_demo_compiles_only_its_own():
    make = (ROOT / "Makefile").read_text()
    warmed = make.split("$(WARMED): $(STAMP)")[1].split("\n\n")[0]
    assert "-m stcvision.warm" in warmed
    assert "\ntest: $(WARMED)" in make and "\ndemo: $(STAMP)" in make
    install = make.split("$(STAMP): pyproject.toml")[1].split("\n\n")[0]
    assert "stcvision.warm" not in install  # the demo's first run compiles what it uses, no more


def _processes_with(env_value: str) -> list[int]:
    """PIDs of this user's processes whose environment holds ``env_value``."""
    found = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if env_value.encode() in (d / "environ").read_bytes():
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
    p.send_signal(signal.SIGTERM)
    t0 = time.monotonic()
    p.wait(timeout=60)
    err = p.stderr.read()
    assert p.returncode == 128 + signal.SIGTERM and "interrupted" in err and "Traceback" not in err, err
    assert time.monotonic() - t0 < 8  # a function's compile at most, under the suite's load


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
