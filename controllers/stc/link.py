"""The serial protocol between a robot and the computer (or chip) that decides for it.

Framing, a checksum and a version, carrying the controller's readings and actions and the
robot's own commands, so that either half can live on the robot
(docs/reference/serial-protocol.md).

A frame::

    0xA5 | version | type | seq | length | payload (length bytes, at most 64) | CRC-16 (2 bytes)

The CRC is CRC-16/CCITT-FALSE (polynomial 0x1021, start 0xFFFF, most significant byte first)
over version to payload: :func:`binascii.crc_hqx`. Each request gets exactly one reply: its own
type with the high bit set, the same sequence number, or a :data:`NAK`. A lost byte, a bad
checksum, a reply that never comes or a port that disappears is a :class:`LinkError` whose text
is one line; the caller stops the robot safely (:meth:`Link.safe_stop`) and never retries a
move, so no command is carried out twice.
"""

from __future__ import annotations

import binascii
import os
import select
import struct
import time

from stcvision.errors import StcVisionError

__all__ = [
    "MAX_PAYLOAD",
    "POLL_S",
    "RESYNC_BYTES",
    "NAK",
    "NAK_CODES",
    "REQUESTS",
    "SYNC",
    "VERSION",
    "FdPort",
    "Link",
    "LinkError",
    "crc16",
    "frame",
    "nak",
    "read_frame",
    "request_name",
]

SYNC = 0xA5
#: the protocol's version: a frame of another version is refused (NAK)
VERSION = 1
#: the longest payload (a reason for a stop is cut to it)
MAX_PAYLOAD = 64
#: header bytes after the sync byte (version, type, seq, length) and the checksum's
HEADER, CRC_BYTES = 4, 2
#: zero bytes that fill any frame a reader may be in the middle of (:meth:`Link.resync`), and
#: how long (s) the line must then stay quiet
RESYNC_BYTES = 1 + HEADER + MAX_PAYLOAD + CRC_BYTES
RESYNC_QUIET_S = 0.2
#: reply type = request type | REPLY
REPLY = 0x80
#: the requests (name -> type): the controller's (HELLO, STEP, STEP_FROM, RESET) and the robot's
REQUESTS = {
    "HELLO": 0x01,  # -> version, state bytes, name
    "STEP": 0x02,  # reading (5) -> status, action, state (3), decision (3), from the held state
    "STEP_FROM": 0x03,  # state (3) + reading (5) -> the same, from the given state
    "RESET": 0x04,  # -> the initial state (3)
    "READ": 0x10,  # controller state (3) -> the reading (5) for it
    "DRIVE": 0x11,  # uint16 mm: lay a row on the rear edge, then drive one sub-cell -> ack
    "TURN": 0x12,  # int16 ms, > 0 counter-clockwise: a quarter turn by time -> ack
    "LEDS": 0x13,  # uint16 ms: rear UV LEDs on without moving -> ack
    "ODOM": 0x14,  # -> moves, turns (uint16 each), clock (uint32 ms)
    "REPORT": 0x15,  # -> reachable, covered, covered twice (uint16 each), flags (finished, back)
    "STATS": 0x05,  # -> the stack's high-water mark (uint16 bytes; 0: not measured)
    "STOP": 0x1F,  # motors off, LEDs off -> ack
}
_NAMES = {t: n for n, t in REQUESTS.items()}
#: the reply to a request that cannot be carried out: code (1 byte) + one line of text
NAK = 0x7F
#: how often (s) a wait on a port looks up (Ctrl-C, SIGTERM)
POLL_S = 0.1
NAK_CODES = {1: "bad checksum", 2: "unknown request", 3: "bad length", 4: "wrong version", 5: "robot stopped"}


try:  # a terminal's drain fails with termios.error (not an OSError) when the far side hangs up
    from termios import error as _TermiosError
except ImportError:  # no terminals on this platform
    _TermiosError = OSError


class LinkError(StcVisionError):
    """The link failed: one line saying how (the robot is then stopped)."""


def crc16(data: bytes) -> int:
    """Return the CRC-16/CCITT-FALSE of ``data`` (polynomial 0x1021, start 0xFFFF)."""
    return binascii.crc_hqx(data, 0xFFFF)


def frame(kind: int, seq: int, payload: bytes = b"") -> bytes:
    """One frame of ``kind`` (a request or reply type) with ``payload``."""
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"payload of {len(payload)} bytes, at most {MAX_PAYLOAD}")
    body = bytes((VERSION, kind, seq & 0xFF, len(payload))) + payload
    return bytes((SYNC,)) + body + struct.pack(">H", crc16(body))


def _read_exact(port, n: int, deadline: float) -> bytes:
    """Read ``n`` bytes from ``port`` before ``deadline``; fewer if it passes.

    ``port`` is a pyserial port or anything with ``read(n)`` returning what arrived within its
    own short timeout.
    """
    got = b""
    while len(got) < n and time.monotonic() < deadline:
        got += port.read(n - len(got))
    return got


def read_frame(port, timeout_s: float, *, what: str = "a frame", synced: bool = False) -> tuple[int, int, bytes]:
    """Read the next frame on ``port``: (type, seq, payload).

    Raises :class:`LinkError` when none starts within ``timeout_s``, when it is cut short, out
    of frame, of another version or its checksum is wrong. ``what`` names the frame in those
    messages. ``synced``: the sync byte has been read already.
    """
    deadline = time.monotonic() + timeout_s
    first = bytes((SYNC,)) if synced else _read_exact(port, 1, deadline)
    if not first:
        raise LinkError(f"no {what} within {timeout_s:g} s (a reply that never came)")
    if first[0] != SYNC:
        raise LinkError(f"lost framing: byte 0x{first[0]:02x} where {what} starts (a byte lost or garbled)")
    head = _read_exact(port, HEADER, deadline)
    if len(head) == HEADER and head[0] != VERSION:
        raise LinkError(f"{what} of protocol version {head[0]}, this side speaks {VERSION}")
    n = head[3] if len(head) == HEADER else 0
    rest = _read_exact(port, n + CRC_BYTES, deadline) if len(head) == HEADER else b""
    if len(head) < HEADER or len(rest) < n + CRC_BYTES:
        got = 1 + len(head) + len(rest)
        raise LinkError(f"{what} cut short ({got} bytes within {timeout_s:g} s): a byte was lost")
    body, (crc,) = head + rest[:n], struct.unpack(">H", rest[n:])
    if crc16(body) != crc:
        raise LinkError(f"bad checksum in {what} (0x{crc:04x}, computed 0x{crc16(body):04x}): noise on the line")
    return head[1], head[2], rest[:n]


class Link:
    """The requesting side: one request, one reply, each within ``timeout_s``.

    Parameters
    ----------
    port : serial.Serial
        A pyserial port (``serial.Serial`` or ``serial.serial_for_url``) with a short read
        timeout, or anything with its ``read``, ``write`` and ``flush``
        (:class:`FdPort`).
    timeout_s : float
        How long (s) a reply may take.
    name : str
        What the link is, for its messages ("the port /dev/ttyACM0": "... is gone").
    listener : callable or None
        Told of every request: ``listener(name, payload, reply)``, the reply a
        :class:`LinkError` when it failed (None: no one is told).
    """

    def __init__(self, port, *, timeout_s: float = 5.0, name: str = "the link", listener=None):
        self.port, self.timeout_s, self.name = port, timeout_s, name
        self.seq = 0
        #: told of every request: ``listener(name, payload, reply)``, the reply a LinkError when
        #: it failed
        self.listener = listener

    def request(self, name: str, payload: bytes = b"", *, timeout_s: float | None = None) -> bytes:
        """Send request ``name`` and return its reply's payload.

        Parameters
        ----------
        name : str
            The request (:data:`REQUESTS`).
        payload : bytes
            Its payload (at most :data:`MAX_PAYLOAD` bytes).
        timeout_s : float or None
            How long (s) its reply may take (None: the link's own).

        Returns
        -------
        bytes
            The reply's payload. Any failure, including a NAK (its code and text), raises
            :class:`LinkError`.
        """
        try:
            reply = self._request(name, payload, timeout_s)
        except LinkError as e:
            if self.listener is not None:
                self.listener(name, payload, e)
            raise
        if self.listener is not None:
            self.listener(name, payload, reply)
        return reply

    def _request(self, name: str, payload: bytes, timeout_s: float | None) -> bytes:
        import serial

        kind = REQUESTS[name]
        self.seq = (self.seq + 1) & 0xFF
        try:
            self.port.write(frame(kind, self.seq, payload))
            try:
                self.port.flush()  # waits for the bytes to leave; a port that is gone shows at the read
            except (serial.SerialException, OSError, _TermiosError):
                pass
            rtype, rseq, body = read_frame(self.port, timeout_s or self.timeout_s, what=f"the reply to {name}")
        except (serial.SerialException, OSError) as e:
            raise LinkError(f"{self.name} is gone ({' '.join(str(e).split())})") from None
        if rtype == NAK:
            code = body[0] if body else 0
            text = body[1:].decode(errors="replace")
            raise LinkError(f"{name} refused: {NAK_CODES.get(code, f'code {code}')}" + (f": {text}" if text else ""))
        if rtype != kind | REPLY or rseq != self.seq:
            raise LinkError(f"the reply to {name} is 0x{rtype:02x} #{rseq}, expected 0x{kind | REPLY:02x} #{self.seq}")
        return body

    def resync(self) -> None:
        """Bring the far side's frame reader back to waiting for a frame.

        Whatever the reader was in the middle of (a frame cut short by a lost byte, noise on the
        line), zero bytes enough to fill any frame end it, its checksum then failing; what it
        answered is read and dropped. A reader waiting for a frame skips the zeros (none is a
        sync byte).
        """
        import serial

        try:
            self.port.write(bytes(RESYNC_BYTES))
            self.port.flush()
            quiet_until = time.monotonic() + RESYNC_QUIET_S
            while time.monotonic() < quiet_until:
                if self.port.read(MAX_PAYLOAD):
                    quiet_until = time.monotonic() + RESYNC_QUIET_S
        except (serial.SerialException, OSError, _TermiosError) as e:
            raise LinkError(f"{self.name} is gone ({' '.join(str(e).split())})") from None

    def safe_stop(self) -> str | None:
        """Ask the robot to stop (motors off, LEDs off) once, briefly.

        A robot that hears nothing more stops by itself (its own watchdog).

        Returns
        -------
        str or None
            Why the stop failed too, or None.
        """
        try:
            self.request("STOP", timeout_s=min(self.timeout_s, 1.0))
        except LinkError as e:
            return str(e)
        return None


def nak(seq: int, code: int, text: str = "") -> bytes:
    """Make a NAK frame: ``code`` (:data:`NAK_CODES`) and one line of text, cut to fit."""
    return frame(NAK, seq, bytes((code,)) + " ".join(text.split()).encode()[: MAX_PAYLOAD - 1])


def request_name(kind: int) -> str:
    """Return the name of request type ``kind`` (its hex for a type no request has)."""
    return _NAMES.get(kind, f"0x{kind:02x}")


class FdPort:
    """A file descriptor as a port.

    ``read(n)`` returns what arrives within :data:`POLL_S`, and raises OSError once the other
    side has closed (a process that died, a terminal hung up).
    """

    def __init__(self, fd: int):
        self.fd = fd

    def read(self, n: int) -> bytes:
        """Return up to ``n`` bytes that arrive within :data:`POLL_S` (none: empty)."""
        r, _, _ = select.select([self.fd], [], [], POLL_S)
        if not r:
            return b""
        got = os.read(self.fd, n)
        if not got:  # readable, yet nothing: the other side has closed
            raise ConnectionResetError("the other side closed the line")
        return got

    def readable(self, timeout_s: float) -> bool:
        """Say whether there is something to read within ``timeout_s`` (s)."""
        return bool(select.select([self.fd], [], [], timeout_s)[0])

    def write(self, data: bytes) -> None:
        """Write ``data`` to the descriptor."""
        os.write(self.fd, data)

    def flush(self) -> None:
        """Do nothing: a write reaches the descriptor at once."""
