"""Say when numba compiles: a first run that compiles kernels (~25-50 s for the demo's, then cached in
``__pycache__``) says so once on stderr instead of sitting silent. The CLI installs
:func:`announce_compiles` for every command; :mod:`stcvision.warm` compiles ahead of time.
"""

from __future__ import annotations

import importlib.abc
import importlib.util
import sys

__all__ = ["NOTICE", "announce_compiles", "at_first_compile"]

_ANNOUNCED = False
_LISTENING = False
#: what runs when this process first compiles (after the notice): a command that knows which
#: kernels it will need can start compiling some of them elsewhere
_AT_FIRST: list = []


def at_first_compile(action) -> None:
    """Call ``action()`` once, when this process first compiles a numba kernel (a cache miss;
    nothing if every kernel loads from the cache). Needs :func:`announce_compiles`'s listener."""
    _AT_FIRST.append(action)


NOTICE = (
    "stcvision: compiling numba kernels on first use (once, ~20-50 s; then they load from __pycache__; "
    "'python -m stcvision.warm' compiles the demo's and the pipeline's ahead, in parallel)"
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
    import threading
    import time

    from numba.core import event

    from stcvision.fileio import interrupted_since, raise_if_signalled

    class _Notice(event.Listener):
        """Says the first compile, and ends a compile a signal asked to stop: a signal's exception
        raised inside a callback from C (llvmlite calls back into Python while LLVM finalises
        code) is printed and dropped by ctypes, and the compile would run on for tens of
        seconds; at the end of each function's compile (a second or two at most) the signal
        that came meanwhile is raised again."""

        def __init__(self) -> None:
            self._starts: list[float] = []

        def on_start(self, ev) -> None:
            global _ANNOUNCED
            if not _ANNOUNCED:
                _ANNOUNCED = True
                out = stream or sys.stderr
                print(NOTICE, file=out, flush=True)
                while _AT_FIRST:
                    _AT_FIRST.pop(0)()
            if threading.current_thread() is threading.main_thread():
                self._starts.append(time.monotonic())

        def on_end(self, ev) -> None:
            if threading.current_thread() is not threading.main_thread() or not self._starts:
                return  # signals are handled in the main thread: only its compiles can lose one
            t0 = self._starts.pop()
            # raised even when the signal's own exception is ending the compile: it is the same one
            raise_if_signalled()
            if interrupted_since(t0):
                raise KeyboardInterrupt

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
