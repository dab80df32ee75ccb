"""The local pool under signals: Ctrl-C/SIGTERM stop a sweep within 2 s keeping the finished
tasks, and no worker outlives a parent killed with SIGKILL (the sweep's own tasks and a real
command). Each waits by polling the store or /proc, never by a fixed sleep, so a busy machine
only makes it slower, not wrong."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from stcvision.sweep import read_store

ROOT = Path(__file__).resolve().parents[2]
STCVISION = str(Path(sys.executable).with_name("stcvision"))


def wait_for(cond, timeout_s: float, what: str):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if cond():
            return
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")


def lines(path: Path) -> int:
    return len(path.read_bytes().splitlines()) if path.exists() else 0


def start(argv, tmp_path):
    return subprocess.Popen(
        argv, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True
    )


def reap(proc, session_pids) -> None:
    """Kill whatever of the command's session is left (a failing test leaves no process)."""
    for pid in session_pids(proc.pid):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    proc.poll()


def selftest(store: Path, tmp_path):
    # 2 quick tasks, then 4 that sleep a minute: the interrupt lands while both workers are busy
    argv = [sys.executable, "-m", "stcvision.sweep.selftest", str(store), "6", "--workers", "2"]
    return start(argv + ["--sleep-s", "60", "--fast", "2"], tmp_path)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_stops_a_pool_sweep_within_2_s_and_keeps_the_finished_tasks(tmp_path, sig, session_pids):
    store = tmp_path / "s.jsonl"
    proc = selftest(store, tmp_path)
    try:
        wait_for(lambda: lines(store) >= 3, 120, "the two quick tasks")
        wait_for(lambda: len(session_pids(proc.pid)) >= 3, 60, "the pool's workers")
        t0 = time.monotonic()
        proc.send_signal(sig)
        proc.wait(timeout=30)
        took = time.monotonic() - t0
    finally:
        reap(proc, session_pids)
    assert took < 2.0, f"took {took:.2f} s to stop"
    assert proc.returncode in (128 + sig, -sig)
    done = [r for r in read_store(store) if r["status"] == "ok"]
    assert sorted(r["params"]["x"] for r in done) == [0, 1]  # the finished tasks are kept
    wait_for(lambda: not session_pids(proc.pid), 10, "the workers to end")


def test_pool_workers_die_with_a_sigkilled_parent(tmp_path, session_pids):
    store = tmp_path / "s.jsonl"
    proc = selftest(store, tmp_path)
    try:
        wait_for(lambda: lines(store) >= 3, 120, "the two quick tasks")  # the workers are initialised
        assert len(session_pids(proc.pid)) >= 3
        os.kill(proc.pid, signal.SIGKILL)  # the parent alone, as the OOM killer would
        proc.wait()
        wait_for(lambda: not session_pids(proc.pid), 10, "the orphaned workers to end")
    finally:
        reap(proc, session_pids)


def test_dataset_generate_workers_die_with_a_sigkilled_parent(tmp_path, session_pids):
    out = tmp_path / "D"
    recipe = ROOT / "datasets" / "recipes" / "ages.json"
    proc = start([STCVISION, "dataset", "generate", str(recipe), "--out", str(out), "--workers", "2"], tmp_path)
    try:
        # the parent plus two workers that have started (they import the renderer: a few seconds)
        wait_for(lambda: len(session_pids(proc.pid)) >= 3, 120, "the pool's workers")
        time.sleep(1.0)  # let the workers reach their tasks (any moment works; this is the common one)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        wait_for(lambda: not session_pids(proc.pid), 10, "the orphaned workers to end")
    finally:
        reap(proc, session_pids)


def test_a_worker_whose_parent_is_already_gone_ends_itself():
    # die_with_parent given a parent that is not this process's parent (it died before the
    # worker got to run) ends the process at once
    code = (
        "import os; from stcvision.sweep._worker import die_with_parent; "
        "die_with_parent(os.getppid() + 10**6); print('alive')"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 128 + signal.SIGKILL and "alive" not in r.stdout
