"""Measure how fast a command stops on a signal, and whether any of its processes outlive it.

    python docs/measurements/signal_latency.py WAIT_FILE MIN_LINES SIGNAL -- COMMAND...

Starts COMMAND in its own session, waits (polling) until WAIT_FILE has MIN_LINES lines (e.g. a
sweep store with a finished task: header + 1), sends SIGNAL (SIGINT, SIGTERM, or SIGKILL to the
parent alone), and prints the exit status, the seconds it took, the lines of WAIT_FILE then (the
finished tasks kept) and the processes of the session still alive a moment later. E.g.

    python docs/measurements/signal_latency.py D/sweep.jsonl 2 SIGINT -- \\
        stcvision cover sweep --sizes 3,4 --runs 2 --out D --workers 2
"""

import os
import signal
import subprocess
import sys
import time

from stcvision.sweep import session_processes as session


def main() -> int:
    wait_file, min_lines, sig = sys.argv[1], int(sys.argv[2]), getattr(signal, sys.argv[3])
    cmd = sys.argv[sys.argv.index("--") + 1 :]
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    t0 = time.monotonic()
    while p.poll() is None and time.monotonic() - t0 < 600:
        if os.path.exists(wait_file) and len(open(wait_file, "rb").read().splitlines()) >= min_lines:
            break
        time.sleep(0.05)
    before = session(p.pid)
    t1 = time.monotonic()
    p.send_signal(sig)
    p.communicate()
    took = time.monotonic() - t1
    lines = len(open(wait_file, "rb").read().splitlines())
    deadline = time.monotonic() + 10
    while session(p.pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    print(
        f"{sys.argv[3]} after {t1 - t0:.1f} s: exit {p.returncode} in {took:.2f} s; {wait_file}: {lines} lines; "
        f"processes {len(before)} before, {len(session(p.pid))} left "
        f"{time.monotonic() - t1 - took:.1f} s later"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
