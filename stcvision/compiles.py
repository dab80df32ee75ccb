"""Say when numba compiles: a first run that compiles kernels (~30 s in all, then cached in
``__pycache__``) says so once on stderr instead of sitting silent. The CLI installs
:func:`announce_compiles` for every command; :mod:`stcvision.warm` compiles ahead of time.
"""

from __future__ import annotations

import sys

__all__ = ["NOTICE", "announce_compiles"]

_ANNOUNCED = False
_LISTENING = False

NOTICE = (
    "stcvision: compiling numba kernels on first use (once: ~30 s in all, then cached in __pycache__; "
    "'make' or 'python -m stcvision.warm' does it ahead)"
)


def announce_compiles(stream=None) -> None:
    """Print :data:`NOTICE` on stderr the first time this process compiles a numba kernel (a
    cache miss; a kernel loaded from the cache says nothing). Idempotent."""
    global _LISTENING
    if _LISTENING:
        return
    from numba.core import event

    class _Notice(event.Listener):
        def on_start(self, ev) -> None:
            global _ANNOUNCED
            if not _ANNOUNCED:
                _ANNOUNCED = True
                out = stream or sys.stderr
                print(NOTICE, file=out, flush=True)

        def on_end(self, ev) -> None:
            pass

    event.register("numba:compile", _Notice())
    _LISTENING = True
