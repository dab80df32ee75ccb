"""The controller as a part of the closed loop, chosen as the loop's other parts are.

Anything with :meth:`Controller.step` ``(StcState, reading) -> Step`` and
:meth:`Controller.close` will do:

* :class:`PythonController`: :func:`stcvision.controllers.stc.fsm.step` itself;
* :class:`HostC`: the portable C controller (``firmware/stc_fsm.c``) built for this machine by
  its C compiler (``cc``) and called through :mod:`ctypes`;
* :class:`stcvision.controllers.stc.mcu.FirmwareController`: the same C built for a
  microcontroller, running in its emulator, asked over the serial protocol.

:func:`stcvision.controllers.stc.choose.make_controller` makes the one a run names.

Each returns the state as :class:`~stcvision.controllers.stc.fsm.StcState` (the C state's three
bytes read back, :mod:`stcvision.controllers.stc.wire`), so the loop, the referee and the
observers see one kind of state whichever controller decides.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Protocol

import numpy as np

from stcvision.controllers.stc import wire
from stcvision.controllers.stc.fsm import LookObs, StcObservation, StcState, Step, step
from stcvision.errors import BadInputError, OutputError

__all__ = [
    "CONTROLLERS",
    "FIRMWARE_DIR",
    "HOST_SOURCES",
    "OUT_BYTES",
    "PORTABLE_SOURCES",
    "Controller",
    "HostC",
    "PythonController",
    "build_host_library",
    "compile_cached",
]

#: the portable C controller's folder (installed with the package)
FIRMWARE_DIR = Path(__file__).resolve().parent / "firmware"
#: the sources every build compiles (host and microcontroller)
PORTABLE_SOURCES = ("stc_fsm.c",)
#: the host build adds the batch entry point
HOST_SOURCES = (*PORTABLE_SOURCES, "stc_host.c")
#: the C flags: the language the sources keep to, every warning an error
C_FLAGS = ("-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-O2")
#: bytes per tick of the C batch's output: status, action, state, decision
OUT_BYTES = 2 + wire.STATE_BYTES + wire.DECISION_BYTES
#: the ``--fsm`` names: Python, the host-built C, the firmware in its emulator
CONTROLLERS = ("python", "c", "firmware")


class Controller(Protocol):
    """What the loop asks of its controller."""

    name: str

    def step(self, state: StcState, obs: StcObservation | LookObs | None) -> Step:
        """Make one tick (:func:`stcvision.controllers.stc.fsm.step`'s contract).

        Parameters
        ----------
        state : StcState
            The controller's state before the tick.
        obs : StcObservation or LookObs or None
            The reading the state asks for: a cell's at a decision, a neighbour's at a look,
            None where the state reads nothing.

        Returns
        -------
        Step
            The state after the tick, the action and the decision taken.
        """

    def close(self) -> None:
        """Release what the controller holds (a library, an emulator)."""


class PythonController:
    """:func:`stcvision.controllers.stc.fsm.step`, the reference."""

    name = "python"

    def step(self, state: StcState, obs) -> Step:
        """Make one tick: :func:`stcvision.controllers.stc.fsm.step` itself."""
        return step(state, obs)

    def close(self) -> None:
        """Release nothing: the Python step holds nothing."""


def _cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "stcvision"


def compile_cached(cc: str, flags, sources, *, name: str, suffix: str, what: str) -> Path:
    """Compile ``sources`` with ``cc`` and ``flags`` once into the user's cache folder.

    ``sources`` are file names in :data:`FIRMWARE_DIR`. The build is cached under ``name``, the
    hash of the compiler, the flags and every source and header, and ``suffix``: an edited
    source builds anew, an unchanged one is reused. ``what`` names the build in the messages.
    Raises BadInputError when there is no such compiler or it rejects the sources.
    """
    from stcvision.fileio import commit_temp, discard_temp, temp_sibling

    exe = shutil.which(cc)
    if exe is None:
        raise BadInputError(f"no C compiler '{cc}' on PATH: {what} is built by one")
    h = hashlib.sha256(" ".join((cc, *flags, *sources)).encode())
    for f in sorted(FIRMWARE_DIR.glob("*.[ch]")):
        h.update(f.name.encode() + f.read_bytes())
    out = _cache_dir() / f"{name}-{h.hexdigest()[:16]}{suffix}"
    if out.exists():
        return out
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = temp_sibling(out)
    except OSError as e:
        raise OutputError(f"cannot write the build cache {out.parent} ({e.strerror}): set XDG_CACHE_HOME") from None
    try:
        srcs = [str(FIRMWARE_DIR / s) for s in sources]
        r = subprocess.run([exe, *flags, "-o", str(tmp), *srcs], capture_output=True, text=True)
        if r.returncode != 0:
            first = (r.stderr.strip().splitlines() or ["(no message)"])[0]
            raise BadInputError(f"{cc} could not build {what}: {first}")
        commit_temp(tmp, out)
    finally:
        discard_temp(tmp if tmp.exists() else None)
    return out


def build_host_library(cc: str | None = None) -> Path:
    """Return the host's shared library of the C controller.

    It is built by ``cc`` (or ``$CC``) once (:func:`compile_cached`).
    """
    cc = cc or os.environ.get("CC") or "cc"
    suffix = ".dll" if sys.platform == "win32" else ".so"
    return compile_cached(cc, (*C_FLAGS, "-shared", "-fPIC"), HOST_SOURCES, name="stc_fsm", suffix=suffix,
                          what="the C controller (set CC or install cc)")  # fmt: skip


class HostC:
    """The portable C controller built for this machine (:func:`build_host_library`).

    One tick per :meth:`step` or many per :meth:`step_batch`.

    Parameters
    ----------
    cc : str or None
        The C compiler that builds it (None: ``$CC``, else ``cc``).
    """

    name = "c"

    def __init__(self, cc: str | None = None):
        self._lib = ctypes.CDLL(str(build_host_library(cc)))
        u8p = ctypes.POINTER(ctypes.c_uint8)
        self._lib.stc_step_batch.argtypes = (ctypes.c_uint32, u8p, u8p, u8p)
        self._lib.stc_step_batch.restype = None
        self._lib.stc_state_size.restype = ctypes.c_uint32
        #: sizeof the C state struct, as the compiler laid it out
        self.state_bytes = int(self._lib.stc_state_size())

    def step_batch(self, states: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """Make ticks of independent (state, reading) pairs.

        Parameters
        ----------
        states : numpy.ndarray
            The states before, (n, 3) uint8 in the :mod:`~stcvision.controllers.stc.wire`
            layout.
        obs : numpy.ndarray
            The readings, (n, 5) uint8 in the :mod:`~stcvision.controllers.stc.wire` layout.

        Returns
        -------
        numpy.ndarray
            (n, 8) uint8: status, action, the state after, the decision.
        """
        states = np.ascontiguousarray(states, np.uint8)
        obs = np.ascontiguousarray(obs, np.uint8)
        n = len(states)
        if states.shape != (n, wire.STATE_BYTES) or obs.shape != (n, wire.OBS_BYTES):
            raise ValueError(f"need ({n}, {wire.STATE_BYTES}) states and ({n}, {wire.OBS_BYTES}) readings")
        out = np.zeros((n, OUT_BYTES), np.uint8)
        u8p = ctypes.POINTER(ctypes.c_uint8)
        self._lib.stc_step_batch(n, states.ctypes.data_as(u8p), obs.ctypes.data_as(u8p), out.ctypes.data_as(u8p))
        return out

    def step(self, state: StcState, obs) -> Step:
        """Make one tick in the C controller.

        Parameters
        ----------
        state : StcState
            The controller's state before the tick.
        obs : StcObservation or LookObs or None
            The reading the state asks for (None where it reads nothing).

        Returns
        -------
        Step
            The state after the tick (read back from the C state's bytes), the action and the
            decision; a status other than 0 raises ValueError, as the Python step does.
        """
        s = np.frombuffer(wire.encode_state(state), np.uint8)[None]
        o = np.frombuffer(wire.encode_obs(obs), np.uint8)[None]
        return decode_out(self.step_batch(s, o)[0].tobytes())

    def close(self) -> None:
        """Release nothing: the library stays loaded for the process."""


def decode_out(out: bytes) -> Step:
    """Read a C tick's output bytes (status, action, state, decision) as the Python step's result.

    A status other than 0 raises ValueError, as the Python step does.
    """
    status = out[0]
    if status:
        raise ValueError(wire.STATUS_ERRORS.get(status, f"status {status}"))
    s = wire.decode_state(out[2 : 2 + wire.STATE_BYTES])
    return Step(s, wire.decode_action(out[1]), wire.decode_decision(out[2 + wire.STATE_BYTES :]))
