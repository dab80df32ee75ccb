"""`stcvision buffon` stops within about a second on SIGTERM and Ctrl-C, even inside one
visit of 10^8 steps (the compiled loop returns to Python every chunk of steps), with the
usual status and nothing written."""

import os
import signal
import subprocess
import sys
import time

import pytest


def _cli(tmp_path, *argv):
    # (SIGINT reaches the command at its default whatever the session inherited: tests/conftest.py)
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.Popen(
        [sys.executable, "-m", "stcvision", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
        env=env,
    )


@pytest.mark.slow
@pytest.mark.parametrize("sig,status,threads", [(signal.SIGTERM, 143, 1), (signal.SIGINT, 130, 2)])
def test_a_huge_visit_stops_within_a_second(tmp_path, sig, status, threads):
    argv = ["buffon", "--nest", "circle:30", "--trials", "2", "--visit-steps", "100000000"]
    p = _cli(tmp_path, *argv, "--threads", str(threads))
    time.sleep(5)  # imports, the compile cache, and well into the first visit
    assert p.poll() is None, p.communicate()
    t0 = time.perf_counter()
    p.send_signal(sig)
    out, err = p.communicate(timeout=30)
    elapsed = time.perf_counter() - t0
    assert p.returncode == status, err
    assert elapsed < 1.5, f"took {elapsed:.2f} s to stop"
    assert "interrupted" in err and "Traceback" not in err and out == ""
    assert os.listdir(tmp_path) == []  # no temporary file
