"""Say when numba compiles: a first run that compiles kernels (~30 s in all, then cached in
``__pycache__``) says so once on stderr instead of sitting silent. The CLI installs
:func:`announce_compiles` for every command; :mod:`stcvision.warm` compiles ahead of time.
"""

from __future__ import annotations

import importlib.abc
import importlib.util
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
    cache miss; a kernel loaded from the cache says nothing). Idempotent.

    A command that never loads numba does not import it for this: the listener is registered
    when numba is first imported (a finder on ``sys.meta_path`` that waits for it), so that
    ``calibrate rescale`` or ``--help`` cost no compiler's import."""
    global _LISTENING
    if _LISTENING:
        return
    _LISTENING = True
    if "numba" in sys.modules:
        _listen(stream)
    else:
        sys.meta_path.insert(0, _WhenNumbaLoads(lambda: _listen(stream)))


def _listen(stream) -> None:
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


class _WhenNumbaLoads(importlib.abc.MetaPathFinder):
    """Calls ``then`` once, right after the ``numba`` package has been imported; finds nothing
    itself (the other finders import numba as usual)."""

    def __init__(self, then) -> None:
        self._then = then

    def find_spec(self, fullname, path, target=None):
        if fullname != "numba":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(fullname)
        if spec is None or spec.loader is None:
            return spec
        loader, then = spec.loader, self._then

        class _ThenLoader(importlib.abc.Loader):
            def create_module(self, spec):
                return loader.create_module(spec)

            def exec_module(self, module):
                module.__spec__.loader = module.__loader__ = loader  # numba sees its own loader
                loader.exec_module(module)
                then()

        spec.loader = _ThenLoader()
        return spec
