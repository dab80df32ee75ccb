"""The portable C controller as firmware on a microcontroller, asked over the serial protocol.

It is built for the chip by its cross compiler, run in an emulator of that chip, and asked over
the serial protocol (:mod:`stcvision.controllers.stc.link`), so that every decision of a
closed-loop run can be the firmware's (:class:`FirmwareController`, ``stcvision cover --fsm
firmware``); and measured (:func:`stcvision.controllers.stc.firmware_report.build_firmware`,
``stcvision firmware build``): flash and static RAM from the ELF's sections, the stack's
high-water mark from the firmware itself after it has run tours in the emulator (it paints its
free RAM at start and reports how deep the stack reached).

The chips (:data:`MCUS`): the ATmega328P of the Arduino Uno (avr-gcc, QEMU's ``uno`` machine)
and ``host``: the same firmware built for this machine by ``cc``, its serial line the process's
standard input and output (no emulator, so the protocol's firmware side is tested where only a
C compiler is installed).
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stcvision.controllers.stc import wire
from stcvision.controllers.stc.controller import C_FLAGS, OUT_BYTES, compile_cached, decode_out
from stcvision.controllers.stc.fsm import StcState, Step
from stcvision.controllers.stc.link import FdPort, Link, LinkError
from stcvision.errors import BadInputError

__all__ = [
    "APT_PACKAGES",
    "DEFAULT_MCU",
    "MCUS",
    "FirmwareController",
    "Mcu",
    "compile_firmware",
    "mcu_named",
    "need_tool",
]

#: the protocol and the controller, built for every chip; each adds its own main
FIRMWARE_SOURCES = ("stc_fsm.c", "stc_link.c")
#: the Debian packages of the cross compiler and the emulator (``make cross-tools``)
APT_PACKAGES = ("gcc-avr", "avr-libc", "binutils-avr", "qemu-system-misc")
#: the first reply may wait for the emulator to start (s)
BOOT_S = 20.0
#: each later reply (s): the emulator answers in well under a millisecond
REPLY_S = 5.0


@dataclass(frozen=True)
class Mcu:
    """A chip the firmware is built for.

    Its compiler and flags, its main, its size tool, its flash and RAM (bytes; None on the host)
    and how its emulator runs an ELF (the command before the ELF's path; empty: the ELF runs
    itself).
    """

    name: str
    cc: str
    flags: tuple[str, ...]
    main: str
    size_tool: str | None
    objcopy: str | None
    flash_bytes: int | None
    ram_bytes: int | None
    emulator: tuple[str, ...]


MCUS = {
    "atmega328p": Mcu(
        "atmega328p", "avr-gcc", ("-mmcu=atmega328p", "-DF_CPU=16000000UL", "-Os"), "main_avr.c",
        "avr-size", "avr-objcopy", 32 * 1024, 2 * 1024,
        ("qemu-system-avr", "-M", "uno", "-display", "none", "-monitor", "none", "-serial", "stdio", "-bios"),
    ),
    "host": Mcu("host", "cc", ("-O2",), "main_host.c", None, None, None, None, ()),
}  # fmt: skip
DEFAULT_MCU = "atmega328p"
_PORTABLE_FLAGS = tuple(f for f in C_FLAGS if f != "-O2")  # each chip sets its own optimisation


#: prctl(2)'s "signal me when my parent dies" (<linux/prctl.h>)
_PR_SET_PDEATHSIG = 1


def _die_with_parent() -> None:
    """Have the Linux kernel kill the emulator's process when its parent dies.

    Runs in the emulator's process before it starts (elsewhere than Linux nothing happens;
    close() and the process group still end it).
    """
    import ctypes
    import signal
    import sys

    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None).prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):
            pass


def mcu_named(name: str | None) -> Mcu:
    """Return the chip named ``name`` (:data:`MCUS`; None: :data:`DEFAULT_MCU`).

    An unknown name raises BadInputError naming the chips there are.
    """
    name = name or DEFAULT_MCU
    if name not in MCUS:
        raise BadInputError(f"unknown microcontroller '{name}': one of {', '.join(MCUS)}")
    return MCUS[name]


def need_tool(tool: str) -> str:
    """Return the path of ``tool`` on PATH.

    A tool that is not installed raises BadInputError saying that ``make cross-tools`` installs
    the cross compiler and the emulator (:data:`APT_PACKAGES`).
    """
    exe = shutil.which(tool)
    if exe is None:
        raise BadInputError(
            f"'{tool}' is not installed: 'make cross-tools' installs the cross compiler and the emulator "
            f"(apt: {' '.join(APT_PACKAGES)})"
        )
    return exe


def compile_firmware(mcu: str | None = None) -> Path:
    """Return the firmware's ELF for ``mcu``.

    It is built once and cached (:func:`stcvision.controllers.stc.controller.compile_cached`).
    """
    m = mcu_named(mcu)
    need_tool(m.cc)
    return compile_cached(m.cc, (*_PORTABLE_FLAGS, *m.flags), (*FIRMWARE_SOURCES, m.main),
                          name=f"stc_firmware-{m.name}", suffix=".elf", what=f"the firmware for {m.name}")  # fmt: skip


class _PipePort:
    """An emulator's standard input and output as a serial port."""

    def __init__(self, proc: subprocess.Popen):
        self.proc, self._in = proc, FdPort(proc.stdout.fileno())

    def read(self, n: int) -> bytes:
        return self._in.read(n)

    def write(self, data: bytes) -> None:
        self.proc.stdin.write(data)

    def flush(self) -> None:
        self.proc.stdin.flush()


class FirmwareController:
    """The firmware in its emulator as the loop's controller.

    It keeps its own state: a tick from the state it returned last sends the reading alone
    (``STEP``), any other sends the state too (``STEP_FROM``).

    Parameters
    ----------
    mcu : str or None
        The chip (:data:`MCUS`; None: :data:`DEFAULT_MCU`).
    elf : pathlib.Path or None
        The firmware to run (None: built for ``mcu`` by :func:`compile_firmware`).
    """

    name = "firmware"

    def __init__(self, mcu: str | None = None, elf: Path | None = None):
        self.mcu = mcu_named(mcu)
        elf = elf or compile_firmware(self.mcu.name)
        cmd = [need_tool(self.mcu.emulator[0]), *self.mcu.emulator[1:], str(elf)] if self.mcu.emulator else [str(elf)]
        self._err = tempfile.TemporaryFile()
        # the emulator stays in this process group: a Ctrl-C reaches it too; close() ends it, and
        # the kernel ends it if this process is killed (an emulator reading a closed input runs on)
        self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._err,
                                     preexec_fn=_die_with_parent)  # fmt: skip
        #: ticks sent with their state (STEP_FROM): none in a run, where the firmware keeps its own
        self.sent_state = 0
        where = f"the firmware in {self.mcu.emulator[0]}" if self.mcu.emulator else "the host-built firmware"
        self.link = Link(_PipePort(self.proc), timeout_s=REPLY_S, name=where)
        try:
            hello = self.link.request("HELLO", timeout_s=BOOT_S)
            #: sizeof the state struct as the chip's compiler laid it out
            self.state_bytes = hello[1]
            self.held = self.link.request("RESET")
        except LinkError as e:
            self.close()
            raise BadInputError(f"{e}{self._stderr()}") from None
        except BaseException:
            self.close()
            raise

    def _stderr(self) -> str:
        self._err.seek(0)
        lines = self._err.read().decode(errors="replace").strip().splitlines()
        return f" ({lines[0]})" if lines else ""

    def _tick(self, state_bytes: bytes, obs_bytes: bytes) -> bytes:
        if state_bytes == self.held:
            out = self.link.request("STEP", obs_bytes)
        else:
            self.sent_state += 1
            out = self.link.request("STEP_FROM", state_bytes + obs_bytes)
        if len(out) != OUT_BYTES:
            raise LinkError(f"the firmware's step reply has {len(out)} bytes, expected {OUT_BYTES}")
        self.held = out[2 : 2 + wire.STATE_BYTES]
        return out

    def step(self, state: StcState, obs) -> Step:
        """Make one tick in the firmware.

        Parameters
        ----------
        state : StcState
            The controller's state before the tick: the one the firmware returned last sends
            the reading alone (``STEP``), any other the state too (``STEP_FROM``).
        obs : StcObservation or LookObs or None
            The reading the state asks for (None where it reads nothing).

        Returns
        -------
        Step
            The state after the tick, the action and the decision. A link that fails raises
            :class:`LinkError`.
        """
        return decode_out(self._tick(wire.encode_state(state), wire.encode_obs(obs)))

    def step_batch(self, states: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """Make one tick per pair, each from its own state (``STEP_FROM``).

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
        out = np.zeros((len(states), OUT_BYTES), np.uint8)
        for i in range(len(states)):
            self.held = None
            out[i] = np.frombuffer(self._tick(states[i].tobytes(), obs[i].tobytes()), np.uint8)
        return out

    def stack_bytes(self) -> int:
        """Ask the firmware for its stack's high-water mark so far (``STATS``).

        Returns
        -------
        int
            The mark in bytes; 0 where the chip does not measure it.
        """
        b = self.link.request("STATS")
        return b[0] << 8 | b[1]

    def close(self) -> None:
        """End the emulator and close its pipes."""
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        for f in (self.proc.stdin, self.proc.stdout, self._err):
            try:
                f.close()
            except OSError:
                pass
