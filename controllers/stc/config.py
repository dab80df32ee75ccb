"""The coverage run's settings (:class:`CoverConfig`) and the localisation limits."""

from __future__ import annotations

import math
from dataclasses import dataclass

from stcvision.sim_camera.hardware import WEBCAM, CameraProfile
from stcvision.sim_camera.robot import LEGO_STC_ROBOT, MarkingRobot
from stcvision.stages import DotParams

__all__ = [
    "ALIGN_MARK_M",
    "LANDMARK_OFFSET_SIGMA",
    "LANDMARK_TURN_SIGMA_RAD",
    "RECENTRE_M",
    "REOBSERVE_RAD",
    "CoverConfig",
]

#: the frames' sizing SNR (``CoverConfig.sizing_snr``): one sigma above the dot threshold
_SIZING_SNR = DotParams().k_sigma + 1.0


@dataclass(frozen=True, kw_only=True)
class CoverConfig:
    """Everything a coverage run (:func:`stcvision.controllers.stc.loop.run_cover`) is set by.

    Attributes
    ----------
    perception : str
        "camera", "ideal" or "oracle".
    exposure : str or float
        "auto" (the short webcam frame, then longer ones while a reading relies on an absence no
        frame so far could have seen), "webcam" (the STC paper's camera alone) or an exposure in
        seconds. The one default: ``stcvision cover`` with no options takes it from here.
    gain : float or None
        The sensor gain of a fixed exposure (None: the camera's own for that exposure).
    n_stack : int
        Frames stacked into each reading.
    seed : int
        The run's seed (every random stream is drawn from it).
    robot : MarkingRobot
        The robot (motion, timing, marking): :data:`stcvision.sim_camera.robot.LEGO_STC_ROBOT`
        by default.
    camera : CameraProfile
        The camera's sensor physics (:mod:`stcvision.sim_camera.hardware`): the STC paper's
        webcam by default.
    max_decisions : int
        The run stops after this many decisions.
    heading_sigma_oracle_rad : float
        The oracle's heading noise: the pipeline's measured heading RMS.
    position_sigma_oracle_m : float
        The oracle's position noise: the marks' position read-out (measured: ~1 mm).
    use_mark_consensus : bool
        Heading from the lean of all rows in view, not the newest only.
    use_landmarks : bool
        Red lights as absolute references, near and far (offset, heading, with their
        uncertainties; docs/explanation/stc-robot.md, "Red lights as landmarks").
    consensus_frame : bool
        With exposure control, after each turn also a frame at the shortest long rung (2 s) for
        the lean of all rows: it sees the rows of many minutes, the webcam frame the last one or
        two; taken only where the red lights do not give the heading's reference and the short
        frame shows fewer than ``consensus_rows`` rows (a low-noise camera's short frame sees
        minutes).
    consensus_rows : int
        See ``consensus_frame``.
    position_margin_m : float
        With exposure control, a reading takes longer frames until every absence it relies on
        is covered: a frame whose horizon at the deciding dot's distance reaches the clock
        (:mod:`stcvision.controllers.stc.claims`: box 2 0.26 m away, the start mark 0.16-0.26 m,
        the cell ahead at a look 0.41 m, the sub-cell ahead before a return 0.23 m); the
        distances are taken this much farther, for the robot's own offset from its sub-cell
        centre (it stays within 1.3-2.9 cm: docs/explanation/stc-robot.md, "Each reading
        weighted by how sure it is").
    sizing_snr : float
        A frame covers a claim while the deciding dot, as old as the clock, still has this
        expected SNR: one noise sigma above the dot search's threshold (``DotParams.k_sigma``,
        5.5), so each dot is found ~84 % of the time and two of a row's four (what a box needs)
        > 97 %; at Rose's 5 (the earlier sizing) a dot at the horizon is found less than half
        the time (the row search accepts a row of four at a mean of 3,
        :data:`ROW_EQUIVALENT_STACK`, but at its threshold it too finds a row only half the
        time).
    size_by_frame_noise : bool
        Size the camera's frames by the noise they will have, the stack's and the dark frame's
        rounding included (:meth:`stcvision.controllers.stc.frames.Exposures.stack_equivalent`),
        not the idealised noise over the square root of the frames stacked: on the webcam's
        8-bit frames a 32 x 30 s stack is worth 12 frames and the longest frame's reach halves.
        On by default (never decide on a frame sized for noise it will not have): measured (the
        results page's "Coverage per camera preset") it turns webcam 12x12 seed 11's wrong
        decision into a safe stop, and half of the webcam's 10x10 tours into safe stops too;
        off, those tours complete on frames whose real reach is shorter than the robot assumed
        (a study of the risk).
    ideal_horizon_factor : float
        ``perception="ideal"``: every visibility horizon times this (``inf``: it sees every
        mark, so a run measures how long the tour takes with the frames it needs).
    stop_out_of_sight : bool
        With exposure control, stop (``abort_reason`` "out of sight: ...") when not even the
        longest frame can rule out what a reading must: the robot knows its camera's limit;
        off, it reads the longest frame and decides anyway (a study of what the guess costs).
    check_returns : bool
        With exposure control, cross-check a return's reading against the tour: a cell
        re-entered from a child shows box 4 and one of
        :data:`stcvision.controllers.stc.fsm.REENTRY_BOXES`; a reading that does not is read
        again with a longer frame, and still wrong the robot stops ("misread: ...") rather than
        decide on a mark missed within its frames' reach; off, it decides on what it read (a
        study of what the misread costs).
    return_snr : float
        At a return, an unlit box's frames must reach the clock at this SNR of its deciding dot,
        else the cell is read again with the next longer frame
        (:meth:`stcvision.controllers.stc.frames.Exposures._check_old_boxes`): two noise sigmas
        above the dot search's threshold, so each dot is found ~98 % of the time and two of a
        row's four > 99.99 % (at ``sizing_snr`` 98.6 %: over a long tour's returns, now and
        then a miss).
    move_log : bool
        A study switch, off in the ant-like robot: keep beside the count of moves a map of where
        the robot has been (every cell entered, every row laid: it grows with the board) and
        check the camera's readings against it
        (:class:`stcvision.controllers.stc.movecount.MoveLog`); on, the cost of deciding from
        the floor and a constant memory alone is measured.
    trace : bool
        Print one line per controller step, per turn measurement and per referee finding
        (:class:`stcvision.controllers.stc.observers.Trace`).
    faults : tuple of (str, float)
        Hardware faults injected into the run: (name, level) pairs
        (:mod:`stcvision.controllers.stc.faults`).
    fsm : str
        The controller that decides (:data:`stcvision.controllers.stc.controller.CONTROLLERS`):
        "python", the Python step; "c", the portable C built for this machine; or "firmware",
        that C as firmware in an emulator.
    mcu : str or None
        ``fsm="firmware"``: the microcontroller it is built for (None: the default,
        :data:`stcvision.controllers.stc.mcu.DEFAULT_MCU`).
    """

    perception: str = "camera"
    exposure: str | float = "auto"
    gain: float | None = None
    n_stack: int = 1
    seed: int = 0
    robot: MarkingRobot = LEGO_STC_ROBOT
    camera: CameraProfile = WEBCAM
    max_decisions: int = 20000
    heading_sigma_oracle_rad: float = math.radians(0.25)
    position_sigma_oracle_m: float = 0.001
    use_mark_consensus: bool = True
    use_landmarks: bool = True
    consensus_frame: bool = True
    consensus_rows: int = 8
    position_margin_m: float = 0.02
    sizing_snr: float = _SIZING_SNR
    size_by_frame_noise: bool = True
    ideal_horizon_factor: float = 1.0
    stop_out_of_sight: bool = True
    check_returns: bool = True
    return_snr: float = _SIZING_SNR + 1.0
    move_log: bool = False
    trace: bool = False
    faults: tuple[tuple[str, float], ...] = ()
    fsm: str = "python"
    mcu: str | None = None


#: the red lights' estimates are used as long as they are this sure (1 sigma): the offset within
#: 0.03 sub-cell sides (5 mm) replaces the robot's belief (less sure, it is weighed against it:
#: :mod:`stcvision.controllers.stc.localise`), the heading within 0.3 degrees for the turn-time recalibration
#: (the newest row's fit is 0.25 deg); a drift correction needs 2.5 sigma whatever the spread
LANDMARK_OFFSET_SIGMA = 0.03
LANDMARK_TURN_SIGMA_RAD = math.radians(0.3)
#: a heading correction this large at a decision or a look means its frames were read askew (box
#: 2, 0.27 m away, moves 0.5 cm per degree): they are taken again
REOBSERVE_RAD = math.radians(1.0)
#: a robot that measures itself this far off its sub-cell centre (pushed, slipped) drives back
#: to it (:meth:`stcvision.controllers.stc.plant.Plant.recentre`) before it marks, and before it decides
#: (the boxes are read from where it should stand): healthy runs stay within 1.3 cm (6x6 board,
#: seed 0); a mark 2.5 cm off lies half-way to the next box
RECENTRE_M = 0.025
#: a robot that measures itself this far (m) ahead of or behind its sub-cell centre, along its
#: heading, drives to the centre along its heading before it lays a row: the row lies across the
#: heading, so that offset is the row's own distance off its box line (a row laid 1-2 cm off
#: by a robot 1-2 cm behind its centre was read in the neighbouring box region); 0.8 cm is the
#: row search's half band (ROW_TOL, 1 cm) less the marks' read-out (~2 mm)
ALIGN_MARK_M = 0.008
