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

__all__ = ["BAUD", "CAMERAS", "CameraStop", "LinkRecorder", "PcCamera", "blueprint", "run_robot"]

#: the link's speed (bits/s): what an Arduino-class board's USB serial runs at
BAUD = 115_200
#: where the readings come from: the robot's own camera (it answers READ); else a camera on this
#: computer (a device number) or a recorded video, read by the pipeline here (:class:`PcCamera`)
CAMERAS = ("robot",)
#: how long one read of the port waits (s): short, so Ctrl-C and SIGTERM stop the run at once
READ_POLL_S = 0.05


class CameraStop(Exception):
    """Stop the robot before it decides: the camera here gave no frame, or one not to trust."""


class PcCamera:
    """Read the floor with a camera on this computer (or a recorded video of one).

    Each frame goes through the vision pipeline; a decision's reading is the cell's observation,
    a look's the marks ahead counted as the closed loop's camera counts them.

    Parameters
    ----------
    source : stcvision.video.VideoSource
        The open camera or video.
    pipeline : stcvision.pipeline.Pipeline
        The pipeline with the camera's calibration profile and its dark frame.
    """

    def __init__(self, source, pipeline) -> None:
        self.source, self.pipeline = source, pipeline
        self.frames = source.frames()
        self.read_frames = 0

    def read(self, state):
        """Take the next frame and read it for the controller in ``state``.

        Parameters
        ----------
        state : StcState
            The controller's state: a DECIDE reads the cell, a LOOK the marks ahead (the cell
            ahead before entering a child, the sub-cell ahead before a return to the parent).

        Returns
        -------
        StcObservation or LookObs
            The controller's reading of the frame (for a decision:
            :func:`stcvision.controllers.stc.frames.stc_observation`).

        Raises
        ------
        CameraStop
            No frame came (the camera stopped, the video ended), or the pipeline does not trust
            the frame (a lit room, a dark frame of another camera, ...): the robot never decides
            on a reading it cannot trust.
        """
        from stcvision.controllers.stc.frames import LOOK_AHEAD_DOTS, stc_observation
        from stcvision.controllers.stc.fsm import LookObs
        from stcvision.observation import LANDING_DOTS, marks_ahead, marks_landing_ahead

        frame = next(self.frames, None)
        if frame is None:
            raise CameraStop(f"camera: {self.source.name} gave no frame after {self.read_frames}")
        self.read_frames += 1
        res = self.pipeline.process(frame[1])
        if res.untrusted:
            raise CameraStop(f"camera: frame {self.read_frames} cannot be trusted ({res.untrusted})")
        if state.phase is not StcPhase.LOOK:
            return stc_observation(res.observation)
        landing = not state.child
        count, need = (marks_landing_ahead, LANDING_DOTS) if landing else (marks_ahead, LOOK_AHEAD_DOTS)
        herr = res.heading.heading_error_rad if res.heading.ok else 0.0
        return LookObs(count(res.dots, self.pipeline.geometry, heading_error_rad=herr) >= need)

    def close(self) -> None:
        """Release the camera."""
        self.source.close()


def open_pc_camera(camera: str, calibration, dark):
    """Open ``--camera N`` (a device number) or ``--camera VIDEO`` (a file) as a :class:`PcCamera`.

    Parameters
    ----------
    camera : str
        A device number, or a video file's path.
    calibration : stcvision.profile.Profile
        The camera's calibration profile.
    dark : numpy.ndarray or None
        The dark frame at the camera's exposure (None: read without one).

    Returns
    -------
    PcCamera
        The open camera with its pipeline.
    """
    from stcvision.pipeline import Pipeline
    from stcvision.video import open_device, open_video

    source = open_device(int(camera)) if camera.isdigit() else open_video(camera)
    return PcCamera(source, Pipeline(calibration, dark=dark))


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
    ``tick`` timeline. Streamed as it is logged and ended as the run ends
    (:class:`stcvision.rr.RecordingFile`, :class:`stcvision.rr.Recordings`).
    """

    def __init__(self, path):
        from stcvision.rr import RecordingFile

        self.path = path
        self.file = RecordingFile(path, app_id="stcvision-robot", default_blueprint=blueprint())
        self.rec = self.file.rec
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

    def end(self, exc) -> None:
        """End the recording as :meth:`stcvision.rr.RecordingFile.end` says."""
        self.file.end(exc)


def blueprint():
    """Return the layout a robot run's recording opens with.

    The link's requests as a log, the controller's tick as text, the request and tick
    timelines below.
    """
    import rerun.blueprint as rrb

    from stcvision.rr import layout

    return layout(
        rrb.Horizontal(rrb.TextLogView(origin="link", name="link"), rrb.TextDocumentView(origin="tick", name="tick")),
        timeline="tick",
    )


def run_robot(port: str, *, camera: str, profile, fsm: str = "python", mcu: str | None = None,
              timeout_s: float = 10.0, max_decisions: int = 20_000, rrd=None, calibration=None,
              dark=None) -> dict:  # fmt: skip
    """Drive the robot on ``port`` with controller ``fsm`` until it is done, it stops, or the link fails.

    Parameters
    ----------
    port : str
        The serial port, or a pyserial URL (``serial.serial_for_url``).
    camera : str
        Where the readings come from: "robot", its own camera (it answers READ); a device
        number, a camera on this computer; or a video file recorded by one (a replay): frames
        read here by the pipeline (:class:`PcCamera`).
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
    calibration : stcvision.profile.Profile or None
        A camera on this computer: its calibration profile (required then).
    dark : numpy.ndarray or None
        A camera on this computer: its dark frame at its exposure (None: read without one).

    Returns
    -------
    dict
        What happened (finished, ``abort_reason``, decisions, looks, commands, wall time) and
        the robot's own report of its cover and its odometry.
    """
    from stcvision.rr import Recordings

    with Recordings() as recs:
        recorder = recs.add(LinkRecorder(rrd)) if rrd else None
        eye = None
        if camera not in CAMERAS:
            if calibration is None:
                raise BadInputError(f"--camera {camera}: a camera on this computer needs its calibration --profile")
            eye = open_pc_camera(camera, calibration, dark)
        try:
            return _run(port, camera, profile, fsm, mcu, timeout_s, max_decisions, recorder, eye)
        finally:
            if eye is not None:
                eye.close()


def _run(port, camera, profile, fsm, mcu, timeout_s, max_decisions, recorder, eye=None) -> dict:
    import serial

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
                if eye is None:  # the robot reads its floor with its own camera
                    obs = wire.decode_obs(link.request("READ", wire.encode_state(state)))
                else:
                    obs = eye.read(state)
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
    except (LinkError, CameraStop) as e:
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
