"""The simulated robot behind a serial link: the simulator's plant, floor and camera (or oracle)
answer the protocol's robot requests (:mod:`stcvision.controllers.stc.link`) on a
pseudo-terminal, as a real robot answers them on its serial port, so that ``stcvision robot
run`` is tested end to end without hardware.

The robot reads its floor where its camera is (``READ`` carries the controller's state and
returns the reading), lays a row and drives one sub-cell (``DRIVE``), turns a quarter turn
(``TURN``), lays the start mark (``LEDS``), counts its moves (``ODOM``), says what it covered
(``REPORT``) and stops (``STOP``). Faults of the link itself can be injected (:data:`LINK_FAULTS`)
to test that the other side stops safely.
"""

from __future__ import annotations

import os
import struct
import time
import tty

from stcvision.controllers.stc import link, wire
from stcvision.controllers.stc.link import POLL_S, FdPort
from stcvision.controllers.stc.loop import LoopEnd, build_parts, read_tick
from stcvision.controllers.stc.oracle import coverage
from stcvision.errors import BadInputError

__all__ = ["LINK_FAULTS", "SimRobot", "parse_link_fault", "serve_pty"]

#: faults of the link, injected at the Nth request: a byte of the reply dropped, the reply's
#: checksum flipped, no reply at all, the port closed (a robot unplugged)
LINK_FAULTS = ("drop", "corrupt", "mute", "hangup")
#: a frame that has started must be whole within this (s): else it is dropped
FRAME_S = 0.5
#: the robot waits this long (s) between requests before it stops by itself (a host that is gone)
IDLE_S = 60.0


def parse_link_fault(text: str | None) -> tuple[str, int] | None:
    """``KIND@N`` (:data:`LINK_FAULTS`, N >= 1: the Nth request) or None."""
    if not text:
        return None
    kind, _, n = text.partition("@")
    if kind not in LINK_FAULTS or not n.isdigit() or int(n) < 1:
        raise BadInputError(f"--link-fault {text!r}: expected KIND@N, KIND one of {', '.join(LINK_FAULTS)}, N >= 1")
    return kind, int(n)


class SimRobot:
    """The simulator's robot answering requests: :meth:`handle` (type, payload) -> reply frame."""

    def __init__(self, board, cfg):
        self.board = board
        self.robot, self.referee, self.watch, self.faults = build_parts(board, cfg)
        self.end = LoopEnd()
        self.stopped = False
        self.requests = 0
        self.log: list[str] = []  # the requests carried out, in order

    def handle(self, kind: int, seq: int, payload: bytes) -> bytes:
        name = link.request_name(kind)
        try:
            body = self._carry_out(name, payload)
        except _Refused as e:
            return link.nak(seq, e.code, str(e))
        self.log.append(name)
        return link.frame(kind | link.REPLY, seq, body)

    def _carry_out(self, name: str, payload: bytes) -> bytes:
        robot = self.robot
        want = {"READ": wire.STATE_BYTES, "DRIVE": 2, "TURN": 2, "LEDS": 2, "REPORT": 1}.get(name, 0)
        if name not in link.REQUESTS or name in ("STEP", "STEP_FROM", "RESET"):
            raise _Refused(2, f"this robot has no controller: {name}")
        if len(payload) != want:
            raise _Refused(3, f"{name} takes {want} bytes, got {len(payload)}")
        if self.stopped and name not in ("REPORT", "STOP", "ODOM", "HELLO"):
            raise _Refused(5, "stopped")
        if name == "HELLO":
            return bytes((link.VERSION, 0)) + b"simulated robot"
        if name == "READ":
            obs, why = read_tick(robot, wire.decode_state(payload), self.end)
            if why is not None:
                self.stopped = True
                raise _Refused(5, why)
            return wire.encode_obs(obs)
        if name == "DRIVE":
            why = robot.forward()
            if why is not None:
                self.stopped = True
                raise _Refused(5, why)
            return b""
        if name == "TURN":
            (ms,) = struct.unpack(">h", payload)
            robot.turn(ms > 0)
            return b""
        if name == "LEDS":
            robot.mark()
            return b""
        if name == "ODOM":
            p = robot.plant
            return struct.pack(">HHI", p.moves, p.turns, int(p.t * 1000))
        if name == "REPORT":
            finished = bool(payload[0])
            cov = coverage(self.board, robot.plant.visits, robot.belief.sub, finished=finished, moves=robot.plant.moves)
            away = robot.count.done_away() if finished else "not finished"
            complete = (
                finished
                and away is None
                and cov["returned_to_start"]
                and cov["subcells_covered"] == cov["subcells_reachable"]
                and cov["subcells_covered_more_than_once"] == 0
            )
            flags = int(cov["returned_to_start"]) | int(complete) << 1
            return struct.pack(">HHHB", cov["subcells_reachable"], cov["subcells_covered"],
                               cov["subcells_covered_more_than_once"], flags)  # fmt: skip
        self.stopped = True  # STOP
        return b""


class _Refused(Exception):
    def __init__(self, code: int, text: str):
        super().__init__(text)
        self.code = code


def serve_pty(board, cfg, *, ready=None, link_fault: tuple[str, int] | None = None, idle_s: float = IDLE_S) -> dict:
    """Serve the simulated robot on a new pseudo-terminal until a ``STOP`` is answered, the port
    is idle for ``idle_s`` or a ``hangup`` fault; ``ready(path)`` is told the terminal's path
    before the first request. Returns what the robot did."""
    sim = SimRobot(board, cfg)
    master, slave = os.openpty()
    tty.setraw(slave)  # bytes as they are: no echo, no line editing
    path = os.ttyname(slave)
    port = FdPort(master)
    ended = "stopped"
    try:
        if ready is not None:
            ready(path)
        while True:
            if not _wait(port, idle_s):
                ended = f"no request for {idle_s:g} s"
                break
            if port.read(1) != bytes((link.SYNC,)):  # between frames: anything but a sync byte is skipped
                continue
            try:
                kind, seq, payload = link.read_frame(port, FRAME_S, what="a request", synced=True)
            except link.LinkError as e:  # a garbled request: refused, nothing carried out
                sim.log.append(f"refused: {e}")
                if "checksum" in str(e):
                    port.write(link.nak(0, 1, str(e)))
                continue
            sim.requests += 1
            reply = sim.handle(kind, seq, payload)
            if link_fault is not None and sim.requests == link_fault[1]:
                fault = link_fault[0]
                if fault == "hangup":
                    ended = "hung up"
                    break
                if fault == "mute":
                    continue
                reply = reply[:3] + reply[4:] if fault == "drop" else reply[:-1] + bytes((reply[-1] ^ 1,))
            port.write(reply)
            if kind == link.REQUESTS["STOP"]:
                time.sleep(FRAME_S)  # the reply is read before the terminal goes
                break
    finally:
        os.close(master)
        os.close(slave)
    p = sim.robot.plant
    return {"port": path, "ended": ended, "requests": sim.requests, "moves": p.moves, "turns": p.turns,
            "decisions": sim.end.decisions, "looks": sim.end.looks, "carried_out": sim.log}  # fmt: skip


def _wait(port: FdPort, idle_s: float) -> bool:
    """Wait for the next request's first byte, looking up every :data:`POLL_S` (so a signal
    stops the wait at once); False after ``idle_s`` with nothing."""
    waited = 0.0
    while waited < idle_s:
        if port.readable(POLL_S):
            return True
        waited += POLL_S
    return False
