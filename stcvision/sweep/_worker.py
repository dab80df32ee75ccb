"""What a local pool worker does before its first task: one thread, no Ctrl-C, die with the parent.

A worker of :class:`concurrent.futures.ProcessPoolExecutor` waits on a pipe that its siblings also
hold open, so when the parent is killed outright (``kill -9``, the OOM killer) nothing ever tells
it to stop: it would finish its task and then wait forever, holding its memory. Two guards:

* Linux: ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` (prctl(2)) makes the kernel kill the worker the
  moment the thread that started it exits; the pool starts its workers from the caller's thread,
  which lives until the sweep is over. It works while the worker is inside a compiled loop that
  holds the GIL, which no Python-level watcher can.
* Everywhere: a daemon thread that checks every :data:`WATCH_PERIOD_S` whether the parent is still
  the process that started the worker (``os.getppid()`` changes when the parent dies) and ends
  the worker if not (on systems without prctl, or if the parent died before prctl ran).

Ctrl-C in a terminal goes to the whole process group; a worker ignores it so that the parent
alone decides, stops the pool at once and keeps the finished tasks (see ``_run._stop_pool``).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time

#: how often the fallback watcher looks at the parent: a worker outlives a killed parent by at
#: most this long (plus the end of a GIL-holding compiled call where prctl is not available)
WATCH_PERIOD_S = 0.5

_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def _set_pdeathsig(signum: int) -> bool:
    """Ask the Linux kernel to send ``signum`` to this process when its parent dies."""
    if not sys.platform.startswith("linux"):
        return False
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, int(signum), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _watch_parent(parent_pid: int) -> None:
    while True:
        time.sleep(WATCH_PERIOD_S)
        if os.getppid() != parent_pid:
            os._exit(128 + signal.SIGKILL)  # as if killed: no cleanup can matter to a dead parent


def die_with_parent(parent_pid: int) -> None:
    """Make this process end when ``parent_pid`` (its parent) dies: prctl on Linux and a
    watcher thread everywhere; ends it now if the parent is already gone."""
    _set_pdeathsig(signal.SIGKILL)
    if os.getppid() != parent_pid:  # died before prctl took effect
        os._exit(128 + signal.SIGKILL)
    threading.Thread(target=_watch_parent, args=(parent_pid,), name="stcvision-parent-watch", daemon=True).start()


def init_worker(parent_pid: int, env: dict[str, str]) -> None:
    """The pool's initializer: runs in each new worker before any task (so before numpy or
    OpenCV is imported there)."""
    os.environ.update(env)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(parent_pid)


def session_processes(sid: int) -> set[int]:
    """The live processes of the session ``sid`` (a command started with ``start_new_session``
    and the pool workers it started), read from /proc: how a test or a measurement sees that no
    worker outlived its parent. Empty where there is no /proc."""
    out = set()
    if not os.path.isdir("/proc"):
        return out
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                if os.getsid(int(d)) == sid:
                    out.add(int(d))
            except OSError:  # the process ended while being listed
                pass
    return out
