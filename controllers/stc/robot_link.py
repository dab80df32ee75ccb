"""``stcvision robot run``: the ant-like STC robot driven over a serial link.

The link speaks the protocol of :mod:`stcvision.controllers.stc.link`, through pyserial. The
controller (Python, the host-built C or the firmware in its emulator) decides on this computer;
the robot reads its floor where its camera is and carries out the commands: a row and one
sub-cell forward, a quarter turn by the profile's turn time, the LEDs on for the profile's
time.

Any failure of the link (a lost byte, a bad checksum, a reply that never comes, a port that
disappears) ends the run with one line (``abort_reason``) after a safe stop: no command is sent
again, so none is carried out twice.
"""

from __future__ import annotations

import struct
import time

from stcvision.controllers.stc import wire
from stcvision.controllers.stc.choose import make_controller
from stcvision.controllers.stc.fsm import Action, StcPhase, initial_state
from stcvision.controllers.stc.link import Link, LinkError
from stcvision.errors import BadInputError

__all__ = ["BAUD", "CAMERAS", "LinkRecorder", "run_robot"]

#: the link's speed (bits/s): what an Arduino-class board's USB serial runs at
BAUD = 115_200
#: where the readings come from: the robot's own camera (it answers READ)
CAMERAS = ("robot",)
#: how long one read of the port waits (s): short, so Ctrl-C and SIGTERM stop the run at once
READ_POLL_S = 0.05


def _command(link: Link, action: Action, profile) -> None:
    """Send the robot's command(s) for a controller action (LOOK and DONE send none)."""
    if action is Action.FORWARD:
        link.request("DRIVE", struct.pack(">H", 0))  # 0: one sub-cell, the robot's own
    elif action in (Action.TURN_LEFT, Action.TURN_RIGHT):
        ms = round(profile.turn_90_s * 1000)
        link.request("TURN", struct.pack(">h", ms if action is Action.TURN_LEFT else -ms))
    elif action is Action.MARK:
        link.request("LEDS", struct.pack(">H", round(profile.led_on_s * 1000)))


class LinkRecorder:
    """A rerun recording of a robot run.

    Every request on the link with its reply (or how it failed) on the ``request`` timeline,
    and every controller tick (the state, the reading, the action, the decision) on the
    ``tick`` timeline. Committed by :meth:`close`, removed by :meth:`abort`
    (:class:`stcvision.rr.Recordings`).
    """

    def __init__(self, path):
        import rerun.blueprint as rrb

        from stcvision.rr import open_recording

        bp = rrb.Blueprint(rrb.Horizontal(rrb.TextLogView(origin="link", name="link"),
                                          rrb.TextDocumentView(origin="tick", name="tick")))  # fmt: skip
        self.path = path
        self.rec, self.tmp = open_recording(path, app_id="stcvision-robot", default_blueprint=bp)
        self.requests = self.ticks = 0

    def on_request(self, name: str, payload: bytes, reply) -> None:
        """Log request ``name`` with ``payload`` and its reply (a LinkError when it failed)."""
        import rerun as rr

        self.requests += 1
        self.rec.set_time("request", sequence=self.requests)
        failed = isinstance(reply, Exception)
        said = f"failed: {reply}" if failed else f"-> {bytes(reply).hex(' ')}"
        self.rec.log("link", rr.TextLog(f"{name} {payload.hex(' ')} {said}", level="ERROR" if failed else "INFO"))

    def on_tick(self, state, obs, action, decision) -> None:
        """Log one controller tick: the state before, the reading, the action, the decision."""
        import rerun as rr

        self.ticks += 1
        self.rec.set_time("tick", sequence=self.ticks)
        self.rec.set_time("request", sequence=self.requests)
        text = f"state: {state}\n\nreading: {obs}\n\naction: {action.name}\n\ndecision: {decision}"
        self.rec.log("tick", rr.TextDocument(text))

    def close(self) -> None:
        """Commit the recording."""
        from stcvision.rr import finish_recording

        finish_recording(self.rec, self.tmp, self.path)

    def abort(self) -> None:
        """Remove the recording."""
        from stcvision.rr import abort_recording

        abort_recording(self.rec, self.tmp)


def run_robot(port: str, *, camera: str, profile, fsm: str = "python", mcu: str | None = None,
              timeout_s: float = 10.0, max_decisions: int = 20_000, rrd=None) -> dict:  # fmt: skip
    """Drive the robot on ``port`` with controller ``fsm`` until it is done, it stops, or the link fails.

    Parameters
    ----------
    port : str
        The serial port, or a pyserial URL (``serial.serial_for_url``).
    camera : str
        Where the readings come from (:data:`CAMERAS`): "robot", its own camera.
    profile : MarkingRobot
        The robot's figures: its quarter turn's time (``turn_90_s``) and its LEDs' time on
        (``led_on_s``) set the TURN and LEDS commands.
    fsm : str
        The controller that decides on this computer
        (:func:`stcvision.controllers.stc.choose.make_controller`): "python", "c" or
        "firmware".
    mcu : str or None
        ``fsm="firmware"``: its chip (None: the default).
    timeout_s : float
        How long (s) each reply may take, and each write.
    max_decisions : int
        The run gives up after this many decisions.
    rrd : str or pathlib.Path or None
        A rerun recording of every request and tick (:class:`LinkRecorder`; None: none).

    Returns
    -------
    dict
        What happened (finished, ``abort_reason``, decisions, looks, commands, wall time) and
        the robot's own report of its cover and its odometry.
    """
    from stcvision.rr import Recordings

    with Recordings() as recs:
        recorder = recs.add(LinkRecorder(rrd)) if rrd else None
        return _run(port, camera, profile, fsm, mcu, timeout_s, max_decisions, recorder)


def _run(port, camera, profile, fsm, mcu, timeout_s, max_decisions, recorder) -> dict:
    import serial

    if camera not in CAMERAS:
        raise BadInputError(f"--camera {camera!r}: this version reads the robot's own camera only (--camera robot)")
    try:
        ser = serial.serial_for_url(port, baudrate=BAUD, timeout=READ_POLL_S, write_timeout=timeout_s)
    except (serial.SerialException, ValueError) as e:
        raise BadInputError(f"cannot open the port {port}: {' '.join(str(e).split())}") from None
    wall0 = time.perf_counter()
    link = Link(ser, timeout_s=timeout_s, name=f"the port {port}",
                listener=recorder.on_request if recorder else None)  # fmt: skip
    out = {"port": port, "fsm": fsm, "camera": camera, "profile": profile.name, "finished": False,
           "abort_reason": None, "decisions": 0, "looks": 0, "commands": 0}  # fmt: skip
    controller = None
    try:
        link.resync()  # a robot left in the middle of a frame by an earlier run waits for a frame again
        out["robot_says"] = link.request("HELLO")[2:].decode(errors="replace")
        controller = make_controller(fsm, mcu=mcu)
        state = initial_state()
        while out["decisions"] < max_decisions:
            obs = None
            if state.phase is StcPhase.LOOK or (state.phase is StcPhase.DECIDE and not state.closing):
                obs = wire.decode_obs(link.request("READ", wire.encode_state(state)))
                out["decisions" if state.phase is StcPhase.DECIDE else "looks"] += 1
            prev = state
            state, action, decision = controller.step(state, obs)
            if recorder is not None:
                recorder.on_tick(prev, obs, action, decision)
            if action is Action.DONE:
                out["finished"] = True
                break
            _command(link, action, profile)
            out["commands"] += action is not Action.LOOK
        else:
            out["abort_reason"] = f"gave up after {max_decisions} decisions"
    except LinkError as e:
        out["abort_reason"] = str(e)
    except BaseException:  # Ctrl-C, SIGTERM: the robot stops too
        link.safe_stop()
        ser.close()
        raise
    finally:
        if controller is not None:
            controller.close()
    abort = out["abort_reason"]
    if abort is None or "refused: robot stopped" in abort:  # the link works: the robot's own count
        try:
            reach, covered, twice, flags = struct.unpack(">HHHB", link.request("REPORT", bytes((out["finished"],))))
            out |= {"subcells_reachable": reach, "subcells_covered": covered, "subcells_covered_more_than_once": twice,
                    "returned_to_start": bool(flags & 1), "robot_complete": bool(flags & 2)}  # fmt: skip
            moves, turns, clock_ms = struct.unpack(">HHI", link.request("ODOM"))
            out |= {"moves": moves, "turns": turns, "robot_clock_s": clock_ms / 1000}
        except LinkError as e:
            out["report_failed"] = str(e)
    stop_failed = link.safe_stop()  # whatever happened: motors off, LEDs off
    if stop_failed is not None:
        out["safe_stop_failed"] = stop_failed
    ser.close()
    out["complete"] = bool(out["finished"] and out.get("robot_complete") and out["abort_reason"] is None)
    out["wall_s"] = time.perf_counter() - wall0
    return out
