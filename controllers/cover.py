"""Closed-loop ant-like STC coverage: camera -> pipeline -> finite-state controller -> robot.

The controller (:mod:`controllers.stc`) decides from one observation per cell entry; this module
runs it on a board with honest time and honest marks:

* **Robot** (a small Lego robot like the seed's; ``sim_camera.robot.LEGO_STC``): drives one
  sub-cell (16 cm) at 8 cm/s (2 s), turns 90 degrees by a timed command (nominal 1.5 s) at a rate
  that is off nominal by up to +-10 % per robot and fades 20 %/h with the battery, and keeps its
  rear UV LEDs on for 3 s before every forward move (seed 003: "for a few seconds"). Moves are
  kinematic on the floor plane: the robot drives straight along its *true* heading, with 2 mm
  (1 sigma) of distance error per move; the pymunk world is not needed for these straight moves
  between free cells.
* **Rotation-time recalibration** (seed 003): after every turn the robot takes a frame, fits the
  newest mark row (heading fit), turns the rest of the way (the correction command) and updates
  its turn time ``T' = 90/d * T`` (bounded, :func:`stcvision.stages.recalibrate_turn`).
* **Marks** are laid in the phosphor layer at the true LED positions, at the true time; they fade
  by the afterglow law and are read back through the synthetic camera.
* **Perception**: ``camera`` (render -> pipeline -> observation) or ``oracle`` (ground truth from
  the floor's record of marks). In camera mode every decision is also compared with the oracle's
  decision in the same state (``decision_errors``).
* **Exposure**: ``webcam`` (1/30 s, gain 16: the seed's camera), a fixed ``exposure_s``, or
  ``auto``: every observation takes a short webcam frame (red lights without bloom, fresh marks,
  the pose) and, where old marks may matter (returns to a parent, the looks), a long one whose
  length follows the robot's clock (:data:`AUTO_LONG`: 2-30 s at gain 4, then 2 to 64 30 s
  frames stacked: the issue's "frame stacking"), sized for what the frame must read
  (``CoverConfig.decision_reach_m``, ``look_reach_m``, ``sizing_snr``); a mark counts if either
  frame sees it -- the seed's proposal, "a camera with a fully controlled integration time".
  After each turn a 2 s frame gives the lean of all rows (the heading consensus). Dark frames
  are taken once per setting, at the matching exposure (a master dark of 8n frames for a stack
  of n). A decision or look whose frames the red lights show were taken more than a degree
  askew is observed again. Past the longest frame's horizon the robot stops ("out of sight").
* **Perception** ``ideal``: the physics-limited camera (:class:`_Ideal`), the same frames and
  time, but it sees exactly the marks within the frames' visibility horizon.
* **Looks**: before entering a child the robot looks at it from the sub-cell next to it
  (:data:`controllers.stc.Action.LOOK`); a marked child moves the exit on.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from controllers.stc import (
    COMPASS_VEC,
    Action,
    LookObs,
    MarkFloor,
    NeighbourObs,
    StcObservation,
    StcPhase,
    decide,
    initial_state,
    look_oracle,
    observe_oracle,
    start_heading,
    step,
)

__all__ = ["CoverConfig", "RobotTiming", "draw_floor", "is_complete", "run_cover"]

#: the short frame of every observation: the seed's webcam (red lights, fresh marks, the pose):
#: (exposure_s, gain, frames averaged)
WEBCAM = (1 / 30, 16.0, 1)
#: ``--exposure auto``, long frames: (exposure_s, gain, frames averaged), shortest first. Each is
#: used while the robot's clock (the oldest age any mark can have) is within its visibility
#: horizon at the distance the frame must read (``CoverConfig.decision_reach_m``,
#: ``look_reach_m``; ``sim_camera.camera.visibility_horizon_s``: the camera's calibration of the
#: phosphor, measured once per robot); gain 4 keeps the 8-bit quantisation below the dark
#: current's noise at every length. 60 s frames were tried and read fewer boxes than 30 s ones
#: (the fresh mark's bloom), so beyond 30 s the ladder stacks 30 s frames (issue 6: "frame
#: stacking"): averaging n frames divides the noise variance by n.
AUTO_LONG = (
    (2.0, 4.0, 1),
    (4.0, 4.0, 1),
    (8.0, 4.0, 1),
    (16.0, 4.0, 1),
    (30.0, 4.0, 1),
    *((30.0, 4.0, n) for n in (2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 24, 32, 40, 48, 64)),
)
#: the far side of the cell ahead (its near sub-cells' marks are 0.1-0.25 m away, its far
#: ones' up to 0.45 m): the default distance for :meth:`_Exposures.horizons`
AUTO_REACH_M = 0.45


@dataclass(frozen=True, kw_only=True, slots=True)
class RobotTiming:
    """The Lego robot's defaults (see the module docstring); fixed across exposure settings."""

    drive_speed_m_s: float = 0.08
    nominal_turn_s: float = 1.5
    led_on_s: float = 3.0
    rate_spread: float = 0.10
    fade_per_h: float = 0.20
    drive_sigma_m: float = 0.002
    initial_turn_error: float = 0.01
    #: time to stop, take a frame and decide (a webcam frame plus processing)
    settle_s: float = 0.3


@dataclass(frozen=True, kw_only=True)
class CoverConfig:
    perception: str = "camera"  # "camera" or "oracle"
    exposure: str | float = "webcam"  # "webcam", "auto" or an exposure in seconds
    gain: float | None = None
    n_stack: int = 1
    seed: int = 0
    timing: RobotTiming = field(default_factory=RobotTiming)
    max_decisions: int = 20000
    heading_sigma_oracle_rad: float = math.radians(0.25)  # the pipeline's measured heading RMS
    position_sigma_oracle_m: float = 0.001  # the marks' position read-out (measured: ~1 mm)
    use_mark_consensus: bool = True
    #: red lights as absolute references, near and far (offset, heading, with their
    #: uncertainties; README "Red lights as landmarks")
    use_landmarks: bool = True
    #: with exposure control, after each turn also a frame at the shortest long rung (2 s) for the
    #: lean of all rows: it sees the rows of many minutes, the webcam frame the last one or two
    consensus_frame: bool = True
    #: with exposure control, the long frame's rung is the shortest whose visibility horizon at
    #: this distance (m) covers the robot's clock: for a decision, its boxes (box 2 is 0.27 m
    #: away; a neighbour's marks it misses, the look before entering finds), and for a look, the
    #: cell ahead (its near sub-cells' marks 0.1-0.25 m, its far ones' from 0.3 m)
    decision_reach_m: float = 0.30
    look_reach_m: float = 0.35
    #: a long frame is sized so that a dot at the reach, as old as the clock, still has this SNR:
    #: Rose's 5 (what a lone dot needs); the row search accepts a row of four at a mean of 3
    #: (:data:`ROW_EQUIVALENT_STACK`), but at its threshold it finds a row only half the time
    sizing_snr: float = 5.0
    #: ``perception="ideal"``: every visibility horizon times this (``inf``: it sees every mark,
    #: so a run measures how long the tour takes with the frames it needs)
    ideal_horizon_factor: float = 1.0
    #: with exposure control, stop (``abort_reason`` "out of sight") once the clock is past the
    #: longest frame's horizon at ``decision_reach_m``: the robot knows its camera's limit
    stop_out_of_sight: bool = True
    trace: bool = False  # heading from the lean of all rows in view, not the newest only


#: the red lights' estimates are used as long as they are this sure (1 sigma): the offset within
#: 0.03 sub-cell sides (5 mm), the heading within 0.3 degrees for the turn-time recalibration
#: (the newest row's fit is 0.25 deg); a drift correction needs 2.5 sigma whatever the spread
LANDMARK_OFFSET_SIGMA = 0.03
LANDMARK_TURN_SIGMA_RAD = math.radians(0.3)
#: a heading correction this large at a decision or a look means its frames were read askew (box
#: 2, 0.27 m away, moves 0.5 cm per degree): they are taken again
REOBSERVE_RAD = math.radians(1.0)


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _compass_to_rad(h: int) -> float:
    """Compass (0 N, 1 E, 2 S, 3 W) -> world heading (0 = east, counter-clockwise)."""
    return math.pi / 2 - h * math.pi / 2


def _to_stc_obs(cell_obs) -> StcObservation:
    order = ("right", "forward", "left", "back")
    neigh = tuple(NeighbourObs(cell_obs.neighbours[d].has_marks, cell_obs.neighbours[d].has_red) for d in order)
    return StcObservation(
        boxes=tuple(b.lit for b in cell_obs.boxes),
        neighbours=neigh,
        start_mark=cell_obs.start_mark,
        landing_marked=tuple(cell_obs.landing_marked),
    )


def _merge(a: StcObservation, b: StcObservation) -> StcObservation:
    """What two exposures of one scene show together: a mark either one sees is there; the red
    lights come from the first (short) frame, which does not saturate them."""
    return StcObservation(
        boxes=tuple(x or y for x, y in zip(a.boxes, b.boxes, strict=True)),
        neighbours=tuple(
            NeighbourObs(x.has_marks or y.has_marks, x.has_red) for x, y in zip(a.neighbours, b.neighbours, strict=True)
        ),
        start_mark=a.start_mark if a.start_mark is not None else b.start_mark,
        landing_marked=tuple(x or y for x, y in zip(a.landing_marked, b.landing_marked, strict=True)),
    )


#: a row of four dots is accepted at a mean dot SNR of 3 (the row search's 6 sigma on the sum of
#: four, halved) where a lone dot needs Rose's 5; in the horizon that is as if (5/3)^2 frames
#: were stacked
ROW_EQUIVALENT_STACK = (5.0 / 3.0) ** 2


class _Exposures:
    """The frames a robot's camera takes: the ladder of (exposure_s, gain) settings, the short
    webcam frame first, and which long rung the robot's clock asks for."""

    def __init__(self, cfg: CoverConfig):
        from sim_camera.camera import SyntheticCamera

        self.cam = SyntheticCamera()
        self.cfg = cfg
        self._horizons: dict[float, tuple[float, ...]] = {}
        if cfg.exposure == "auto":
            self.ladder = (WEBCAM, *AUTO_LONG)
        elif cfg.exposure == "webcam":
            self.ladder = (WEBCAM,)
        else:
            e = float(cfg.exposure)
            self.ladder = ((e, cfg.gain if cfg.gain is not None else max(1.0, min(16.0, 16.0 * (1 / 30) / e * 4)), 1),)
        self.frames = 0
        self.long_frames = 0

    def horizons(self, reach_m: float = AUTO_REACH_M) -> tuple[float, ...]:
        """The long rungs' visibility horizons (s) for a dot ``reach_m`` from the robot."""
        if reach_m not in self._horizons:
            from sim_camera.camera import ROSE_SNR, visibility_horizon_s

            eq = (ROSE_SNR / self.cfg.sizing_snr) ** 2  # as if that many more frames were stacked
            self._horizons[reach_m] = tuple(
                visibility_horizon_s(self.cam, sensor=self._sensor(k), rho_m=reach_m, n_stack=eq * self.stack(k))
                for k in range(1, len(self.ladder))
            )
        return self._horizons[reach_m]

    @property
    def controlled(self) -> bool:
        """Exposure control: long frames besides the short one."""
        return len(self.ladder) > 1

    def long_rung(self, t_s: float, reach_m: float = AUTO_REACH_M) -> int | None:
        """The ladder rung for old marks up to ``reach_m`` away at clock ``t_s``: the shortest
        whose horizon covers the oldest mark there can be (the last one beyond them all); None
        without exposure control."""
        if not self.controlled:
            return None
        hs = self.horizons(reach_m)
        return 1 + next((k for k, h in enumerate(hs) if h >= t_s), len(hs) - 1)

    def out_of_sight(self, t_s: float) -> str | None:
        """Why the robot stops at clock ``t_s``, or None: with exposure control it knows its
        camera, and once the clock is past the longest frame's horizon at the decision's reach
        even that frame may miss the marks it must read: every decision would be a guess."""
        if not self.controlled:
            return None
        reach = self.cfg.decision_reach_m
        limit = self.horizons(reach)[-1]
        if t_s <= limit:
            return None
        return (
            f"out of sight: at {t_s:.0f} s the marks may be older than the longest frame sees "
            f"{reach:.2f} m away ({limit:.0f} s)"
        )

    def _sensor(self, k: int):
        e, g, _ = self.ladder[k]
        return self.cam.sensor.replace(exposure_s=e, gain=g)

    def stack(self, k: int) -> int:
        """How many frames rung ``k`` averages."""
        return self.ladder[k][2] * self.cfg.n_stack

    def frame_s(self, k: int) -> float:
        """Counts a frame at rung ``k``; returns the seconds it takes (all its exposures)."""
        self.frames += 1
        self.long_frames += k > 0
        return self.ladder[k][0] * self.stack(k)


class _Ideal(_Exposures):
    """The physics-limited camera (``--perception ideal``): it takes the same frames as the
    camera and spends the same time, but instead of rendering and reading them it sees exactly
    the marks with a dot whose age is within the frame's visibility horizon at its distance
    (:func:`sim_camera.camera.visibility_horizon_s`, the Rose criterion on the camera model; for
    a row of four dots with ``rows``), and nothing else. No pipeline error and no drift beyond
    the oracle's: what it cannot do, no pipeline on this camera can."""

    RHO = np.arange(0.05, 1.0, 0.01)

    def __init__(self, cfg: CoverConfig, board, *, rows: bool = True):
        super().__init__(cfg)
        from sim_camera.camera import visibility_horizon_s

        self.board = board
        n = ROW_EQUIVALENT_STACK if rows else 1.0
        self.curves = [
            visibility_horizon_s(self.cam, sensor=self._sensor(k), rho_m=self.RHO, n_stack=n * self.stack(k))
            for k in range(len(self.ladder))
        ]
        if cfg.ideal_horizon_factor != 1.0:
            for c in self.curves:
                c[c > 0] *= cfg.ideal_horizon_factor

    def floor_seen(self, xy, t_s: float, phosphor, marks: list, rungs) -> MarkFloor:
        """The marks (``marks``: the (sub-cell, edge) of every four dots laid, in order) that
        frames at ``rungs`` taken from ``xy`` at ``t_s`` see."""
        seen = MarkFloor(self.board.shape_subcells)
        if not marks:
            return seen
        d = np.hypot(*(phosphor.xy_m - np.asarray(xy)).T)
        h = np.max([np.interp(d, self.RHO, self.curves[k], left=0.0, right=0.0) for k in rungs], axis=0)
        vis = (phosphor.ages_s(t_s) <= h).reshape(-1, 4).any(axis=1)
        for (sub, edge), v in zip(marks, vis, strict=True):
            if v:
                seen.mark(sub, edge)
        return seen

    def _rungs(self, t_s: float, reach_m: float, short_only: bool = False) -> list[int]:
        k = self.long_rung(t_s, reach_m)
        return [0] if k is None or short_only else [0, k]

    def observe(self, xy, t_s, phosphor, marks, sub, hc, *, fresh: bool = False):
        """(StcObservation, seconds spent): the frames :meth:`_Camera.observe` takes."""
        rungs = self._rungs(t_s, self.cfg.decision_reach_m, fresh)
        dt = sum(self.frame_s(r) for r in rungs)
        seen = self.floor_seen(xy, t_s, phosphor, marks, rungs)
        return observe_oracle(seen, self.board, sub, hc, camera_view=True), dt

    def look(self, xy, t_s, phosphor, marks, sub, hc):
        """(marked, seconds spent): the frames :meth:`_Camera.look` takes."""
        rungs = self._rungs(t_s, self.cfg.look_reach_m)
        dt = sum(self.frame_s(r) for r in rungs)
        return look_oracle(self.floor_seen(xy, t_s, phosphor, marks, rungs), sub, hc).marked, dt


class _Camera(_Exposures):
    """Camera + pipeline at the robot: one pipeline per exposure setting, each holding the dark
    frame taken at its exposure (so no dark frame is re-prepared between the short and the long
    frame of a decision)."""

    def __init__(self, board, cfg: CoverConfig, rng: np.random.Generator):
        super().__init__(cfg)
        self.board = board
        self.lights = board.red_lights_m()
        self.rng = rng
        self.pipes: dict = {}
        self.darks: dict = {}
        self.pipe = None  # the pipeline that read the last frame (for the recording)

    def _pipeline(self, k: int):
        """The pipeline of rung ``k``'s exposure and gain (stacked rungs share it), holding the
        dark frame of rung ``k``: for a stack of n frames a master dark of 8n frames at the same
        exposure (taken once, before the run, lens capped), so that its own noise stays well
        below the stack's."""
        e, g, _ = self.ladder[k]
        n = self.stack(k)
        if (e, g) not in self.pipes:
            from calibration.profiles import default_profile
            from stcvision.observation import ObservationParams
            from stcvision.pipeline import Pipeline, PipelineParams

            # the pose comes from the short frame: a long one needs no far red lights (two more
            # remaps and the refinement per frame), only its rows and their lean
            obs = ObservationParams(pose_estimates=True)
            if k > 0:
                obs = dataclasses.replace(obs, landmark_range_m=0.0)
            self.pipes[(e, g)] = Pipeline(default_profile(), PipelineParams(observation=obs))
        if (e, g, n) not in self.darks:
            s = self._sensor(k)
            self.darks[(e, g, n)] = (
                self.cam.median_dark(8, rng=self.rng, sensor=s)
                if n == 1
                else self.cam.dark_frame(rng=self.rng, sensor=s, n_avg=8 * n)
            )
        pipe = self.pipes[(e, g)]
        if pipe.dark is not self.darks[(e, g, n)]:
            pipe.set_dark(self.darks[(e, g, n)])
        return pipe

    def shoot(self, pose, t_s: float, phosphor, k: int = 0, *, heading_error_rad: float | None = None):
        """Returns (pipeline result, capture seconds). A stacked rung is the average of its
        frames (:meth:`sim_camera.camera.SyntheticCamera.render`, ``n_avg``)."""
        from sim_camera.camera import Pose

        img = self.cam.render(
            Pose(*pose), rng=self.rng, t_s=t_s, phosphor=phosphor, red_lights_m=self.lights, sensor=self._sensor(k),
            n_avg=self.stack(k),
        ).image  # fmt: skip
        self.pipe = self._pipeline(k)
        res = self.pipe.process(img, heading_error_rad=heading_error_rad)
        return res, self.frame_s(k)

    def observe(self, pose, t_s, phosphor, *, fresh: bool = False):
        """One observation: (StcObservation, the short frame's result, the long frame's result
        or None, seconds spent): the short frame, and with exposure
        control a long one at the rung the clock asks for, what either sees of the marks
        merged. The pose comes from the short frame, whose red lights do not saturate.
        ``fresh``: the cell was entered as a child the look found unmarked, so no old mark can
        be in it and the short frame (red lights, the neighbours' recent marks) is enough; the
        looks check the rest."""
        res, dt = self.shoot(pose, t_s, phosphor, 0)
        obs = _to_stc_obs(res.observation)
        k = self.long_rung(t_s, self.cfg.decision_reach_m)
        if k is None or fresh:
            return obs, res, None, dt
        long, dt_k = self.shoot(pose, t_s + dt, phosphor, k, heading_error_rad=_fit(res))
        return _merge(obs, _to_stc_obs(long.observation)), res, long, dt + dt_k

    def look(self, pose, t_s, phosphor):
        """The look at the cell ahead: (marked, the short frame's result (for the pose), the
        long frame's result or None, seconds spent), the long frame at the rung the clock asks
        for (the short frame alone without exposure control)."""
        from stcvision.observation import marks_ahead

        short, dt = self.shoot(pose, t_s, phosphor, 0)
        k = self.long_rung(t_s, self.cfg.look_reach_m)
        long = None
        herr = _fit(short)  # the long frame's recent rows all saturate: its own fit is unsure
        if k is not None:
            long, dt_k = self.shoot(pose, t_s + dt, phosphor, k, heading_error_rad=herr)
            dt += dt_k
        res = long if long is not None else short
        geo = self.pipe.geometry  # one profile: every rung's pipeline has the same geometry
        n = marks_ahead(res.dots, geo, heading_error_rad=herr or 0.0, offset=res.observation.position_offset)
        if long is not None:  # what the short frame sees counts too (it is never less right)
            n = max(n, marks_ahead(short.dots, geo, heading_error_rad=herr or 0.0))
        return n >= 2, short, long, dt


def _fit(res) -> float | None:
    """A frame's heading fit (None if it failed)."""
    return res.heading.heading_error_rad if res.heading.ok else None


def is_complete(summary: dict) -> bool:
    """A run of :func:`run_cover` is complete when every reachable sub-cell was covered exactly
    once, the robot finished back in its start cell, and (camera mode) made no decision the
    oracle would not have made."""
    return bool(
        summary["finished"]
        and summary["returned_to_start"]
        and summary["abort_reason"] is None
        and summary["subcells_covered"] == summary["subcells_reachable"]
        and summary["subcells_covered_more_than_once"] == 0
        and summary["decision_errors"] == 0
    )


def run_cover(board, cfg: CoverConfig = CoverConfig(), *, recorder=None, on_end=None) -> dict:
    """Cover ``board`` from its start sub-cell; returns the summary the CLI prints."""
    from sim_camera.phosphor import PhosphorLayer
    from stcvision.stages import recalibrate_turn

    wall0 = time.perf_counter()
    tm = cfg.timing
    rng = np.random.default_rng(cfg.seed)
    D = board.subcell_m
    rows, cols = board.shape_subcells
    sub = tuple(board.start_subcell)
    hc = start_heading(board)
    c = board.subcell_center_m(*sub)
    x, y, hdg = float(c[0]), float(c[1]), _compass_to_rad(hc)
    rate_gain = 1.0 + rng.uniform(-tm.rate_spread, tm.rate_spread)  # this robot's motors
    nominal_rate = (math.pi / 2) / tm.nominal_turn_s
    # T, the robot's rotation time for 90 degrees: set before the run to what the first rotation
    # needs (seed 003: "We initially set T to a time that let's the robot do the first rotation
    # accurate enough"), to within ``timing.initial_turn_error`` (1 sigma); recalibrated after
    # every turn as the battery fades
    turn_s = (math.pi / 2) / (nominal_rate * rate_gain) * (1 + rng.normal(0, tm.initial_turn_error))
    phosphor = PhosphorLayer()
    floor = MarkFloor((rows, cols))
    laid_at: dict = {}
    visits = np.zeros((rows, cols), int)
    visits[sub] += 1
    camera = _Camera(board, cfg, rng) if cfg.perception == "camera" else None
    phys = _Ideal(cfg, board) if cfg.perception == "ideal" else None
    sees = camera or phys  # what takes frames and spends their time
    marks: list = []  # (sub-cell, edge) of every four dots laid, for the ideal camera
    state = initial_state()
    t = 0.0
    moves = turns = decisions = decision_errors = looks = look_errors = reobserved = 0
    max_age_read = 0.0
    abort = None
    finished = False
    first_error = None
    max_pos_err = 0.0
    est_err = 0.0  # the robot's own estimate of its heading error (0 after each correction)
    offset_est = np.zeros(2)  # its estimate of where it stands off its sub-cell centre (world, m)

    def true_rate(t_s):
        return nominal_rate * rate_gain * max(0.5, 1.0 - tm.fade_per_h * t_s / 3600.0)

    def heading_error():
        return _wrap(hdg - _compass_to_rad(hc))

    def true_offset():
        ideal = board.subcell_center_m(*sub)
        return np.array([x - ideal[0], y - ideal[1]])

    def oracle_offset():
        """Without the camera's marks: the truth with the marks' read-out noise."""
        return true_offset() + rng.normal(0, cfg.position_sigma_oracle_m, 2)

    def offset_to_world(off_ru):
        """Entry-frame (right, up) cell units -> world metres, for the current compass heading."""
        up = np.array([math.cos(_compass_to_rad(hc)), math.sin(_compass_to_rad(hc))])
        right = np.array([up[1], -up[0]])
        return D * (off_ru[0] * right + off_ru[1] * up)

    def where_am_i(observation, current):
        """The robot's offset from its sub-cell centre: from the red lights in view when there
        are any (they stand at cell centres: an absolute reference), else from its own marks."""
        off = observation.landmark_offset if cfg.use_landmarks else None
        if off is not None and observation.landmark_offset_sigma > LANDMARK_OFFSET_SIGMA:
            off = None  # too unsure: the marks say it better
        if off is None:
            off = observation.position_offset
        if off is None or max(abs(off[0]), abs(off[1])) > 0.3:  # 5 cm: not believable
            return current
        return offset_to_world(off)

    def heading_estimate(res, rows=None):
        """The heading error: the newest row's, less what the red lights (absolute, when in view)
        or the lean of all rows (the consensus of older marks; from ``rows``, a long frame read
        with the same heading, when given: it sees many more of them) say is left over."""
        if not res.heading.ok:
            return None
        o = res.observation
        left = o.landmark_rotation_rad if cfg.use_landmarks else None
        if left is not None and o.landmark_rotation_sigma_rad > LANDMARK_TURN_SIGMA_RAD:
            left = None  # too unsure to take over from the consensus of the marks
        if left is None and cfg.use_mark_consensus:
            left = o.pattern_rotation_rad
            if rows is not None and rows.observation.pattern_rotation_rad is not None:
                left = rows.observation.pattern_rotation_rad
        return res.heading.heading_error_rad - (left if left is not None else 0.0)

    def rotate_by(angle):
        """A small correction turn at the robot's estimated rate (true rate applies)."""
        nonlocal hdg, t
        est_rate = (math.pi / 2) / turn_s
        dur = abs(angle) / est_rate
        hdg = _wrap(hdg + math.copysign(1.0, angle) * true_rate(t) * dur)
        t += dur

    def correct_heading(res) -> float:
        """Two or more red lights in view say how far the heading has drifted: take it out.
        Returns the rotation made (rad)."""
        if cfg.use_landmarks and res.observation.landmark_rotation_rad is not None:
            e = heading_estimate(res)
            if cfg.trace and e is not None:
                print(
                    f"   lights: heading error {math.degrees(e):+.2f} (true {math.degrees(heading_error()):+.2f}), "
                    f"offset {res.observation.landmark_offset}"
                )
            sig = res.observation.landmark_rotation_sigma_rad
            # only a drift the lights show clearly (2.5 sigma), and never by a hair
            if e is not None and abs(e) > max(math.radians(0.5), 2.5 * sig):
                rotate_by(-e)
                return -e
        return 0.0

    def measure_heading():
        """The heading fit on the newest row (camera), or the truth with the pipeline's noise;
        the marks in view also say where the robot stands."""
        nonlocal t, offset_est
        if camera is None:
            t += tm.settle_s
            if phys is not None:  # the frames' time: the newest row and the consensus frame
                t += phys.frame_s(0) + (phys.frame_s(1) if cfg.consensus_frame and phys.controlled else 0.0)
            offset_est = oracle_offset()
            return heading_error() + rng.normal(0, cfg.heading_sigma_oracle_rad)
        res, dt = camera.shoot((x, y, hdg), t, phosphor)
        t += tm.settle_s + dt
        offset_est = where_am_i(res.observation, offset_est)
        if not res.heading.ok:
            # no newest row to fit: the red lights, when they are sure enough, else the newest
            # row of a 2 s frame (a turn left uncorrected leaves the next cell read askew)
            o = res.observation
            if cfg.use_landmarks and o.landmark_rotation_rad is not None:
                if o.landmark_rotation_sigma_rad <= LANDMARK_TURN_SIGMA_RAD:
                    return -o.landmark_rotation_rad
            if not camera.controlled:
                return None
            res, dt = camera.shoot((x, y, hdg), t, phosphor, 1)
            t += dt
            return res.heading.heading_error_rad if res.heading.ok else None
        rows = None
        if cfg.consensus_frame and camera.controlled:
            rows, dt = camera.shoot((x, y, hdg), t, phosphor, 1, heading_error_rad=res.heading.heading_error_rad)
            t += dt
        # the newest row carries the heading error the robot had when laying it; the lean of
        # all the rows in view (the consensus of older marks) takes that out
        return heading_estimate(res, rows)

    def read_camera(take):
        """A decision's or a look's frames: ``take(pose, t) -> (reading, short frame's result,
        long frame's result or None, seconds)``. The short frame says where the robot stands
        and, with the red lights, how far its heading has drifted; a drift over
        :data:`REOBSERVE_RAD` means the frames were read askew, so they are taken once more.
        Returns (reading, the frame that read the old marks, for the recording)."""
        nonlocal t, offset_est, reobserved
        for attempt in range(2):
            reading, short, long, dt = take((x, y, hdg), t)
            t += tm.settle_s + dt
            offset_est = where_am_i(short.observation, offset_est)
            if abs(correct_heading(short)) < REOBSERVE_RAD:
                break
            reobserved += attempt == 0  # (a second askew reading is kept)
        return reading, long or short

    def lay_mark():
        nonlocal t
        xy = phosphor.led_positions_m((x, y, hdg))
        phosphor.charge(xy, t_start_s=t, duration_s=tm.led_on_s)
        edge = (hc + 2) % 4
        floor.mark(sub, edge)
        marks.append((sub, edge))
        laid_at[(sub, edge)] = t + tm.led_on_s
        t += tm.led_on_s

    o_dec = None  # what the oracle decided at this cell's decision (camera mode)

    def check_commit(outcome: tuple):
        """A decision is committed when the robot leaves its cell or stops: it is an error if
        the oracle, deciding in the same state, would have done otherwise (the looks before
        entering a child may revise a first reading, as they are meant to)."""
        nonlocal decision_errors, first_error, o_dec
        expected, o_dec = o_dec, None
        if expected is None or expected == outcome:
            return
        decision_errors += 1
        if cfg.trace:
            print(f"decision error at {sub}: the oracle would {expected}, the robot did {outcome}")
        if first_error is None:
            ideal = board.subcell_center_m(*sub)
            first_error = {
                "decision": decisions,
                "t_s": t,
                "subcell": dec_at["subcell"],
                "camera": dec_at["camera"],
                "oracle": dec_at["oracle"],
                "pos_err_m": math.hypot(x - ideal[0], y - ideal[1]),
                "heading_err_deg": math.degrees(heading_error()),
            }

    dec_at: dict = {}
    while decisions < cfg.max_decisions:
        obs = None
        if state.phase is StcPhase.DECIDE and not state.closing:
            abort = sees.out_of_sight(t) if cfg.stop_out_of_sight and sees is not None else None
            if abort is not None:
                break
            decisions += 1
            o_obs = observe_oracle(floor, board, sub, hc, camera_view=True)
            if sees is not None:
                if camera is not None:
                    obs, res = read_camera(partial(camera.observe, phosphor=phosphor, fresh=state.fresh))
                else:
                    obs, dt = phys.observe((x, y), t, phosphor, marks, sub, hc, fresh=state.fresh)
                    t += tm.settle_s + dt
                    offset_est = oracle_offset()
                od = decide(o_obs, at_start=state.at_start)
                dc = decide(obs, at_start=state.at_start)
                if (dc.visited, dc.parent, dc.is_start, dc.done) != (od.visited, od.parent, od.is_start, od.done):
                    # what the cell says of itself (visited sub-cells, parent, start, end) was
                    # misread: no look can mend that
                    o_dec = ("misread",)
                    if cfg.trace:
                        print(f"misread at {sub}: camera {obs}, oracle {o_obs}, fresh {state.fresh}")
                elif od.done:
                    o_dec = ("done",)
                elif od.final:
                    o_dec = ("stop", od.target, od.parent)
                else:
                    o_dec = ("leave", od.target, od.parent, od.child is None and o_obs.landing_marked[od.target])
                dec_at = {"subcell": sub, "camera": obs, "oracle": o_obs}
            else:
                t += tm.settle_s
                obs = o_obs
                dc = decide(obs, at_start=state.at_start)
                offset_est = oracle_offset()
            if recorder is not None:
                text = (
                    f"**decision {decisions}** at sub-cell {sub}, t = {t:.0f} s\n\n"
                    f"visited 1-3: {dc.visited}, parent {dc.parent}, child {dc.child}, "
                    f"target {dc.target}{' (stop there)' if dc.final else ''}\n\n"
                    f"boxes {obs.boxes}, start mark {obs.start_mark}"
                )
                recorder.decision(
                    decisions,
                    t,
                    (x, y, hdg),
                    phosphor,
                    visits,
                    res if camera is not None else None,
                    camera.pipe if camera is not None else None,
                    text,
                )
            # the oldest mark whose box or neighbour the camera had to read
            for (s_, _edge), t_laid in laid_at.items():
                if abs(s_[0] // 2 - sub[0] // 2) + abs(s_[1] // 2 - sub[1] // 2) <= 1:
                    max_age_read = max(max_age_read, t - t_laid)
        elif state.phase is StcPhase.LOOK:
            looks += 1
            if sees is not None:
                if camera is not None:
                    marked, res = read_camera(partial(camera.look, phosphor=phosphor))
                else:
                    marked, dt = phys.look((x, y), t, phosphor, marks, sub, hc)
                    t += tm.settle_s + dt
                    offset_est = oracle_offset()
                obs = LookObs(marked)
                if marked != look_oracle(floor, sub, hc).marked:
                    look_errors += 1
                    if cfg.trace:
                        di, dj = COMPASS_VEC[hc]
                        ahead = ((sub[0] + di) // 2, (sub[1] + dj) // 2)
                        seen = [
                            (s_, e_, round(t - t_l), round(float(np.hypot(*(board.subcell_center_m(*s_) - (x, y)))), 2))
                            for (s_, e_), t_l in laid_at.items()
                            if (s_[0] // 2, s_[1] // 2) == ahead
                        ]
                        print(f"look error at {sub} heading {hc}: camera {marked}, t={t:.0f}, marks ahead {seen}")
                if recorder is not None and camera is not None:
                    recorder.decision(
                        decisions, t, (x, y, hdg), phosphor, visits, res, camera.pipe,
                        f"**look** from sub-cell {sub}: the cell ahead is {'marked' if marked else 'unmarked'}",
                    )  # fmt: skip
            else:
                t += tm.settle_s
                obs = look_oracle(floor, sub, hc)
        prev = state
        state, action = step(state, obs)
        if action is Action.DONE and prev.phase is StcPhase.DECIDE and not prev.closing:
            check_commit(("done",))
        elif action is Action.DONE and prev.phase is not StcPhase.DECIDE:
            check_commit(("stop", prev.target, prev.parent))
        elif action is Action.FORWARD and state.phase is StcPhase.DECIDE:
            check_commit(("leave", prev.target, prev.parent, state.closing))
        if cfg.trace:
            print(
                f"t={t:7.1f} {action.name:10s} sub={sub} hc={hc} {state.phase.name} tgt={state.target} "
                f"par={state.parent} free={state.free:04b} herr={math.degrees(heading_error()):+.2f} "
                f"pos={100 * float(np.hypot(*true_offset())):.2f}cm est={100 * float(np.hypot(*offset_est)):.2f}cm"
            )
        if action is Action.DONE:
            finished = True
            break
        if action is Action.MARK:
            lay_mark()
        elif action is Action.FORWARD:
            lay_mark()
            di, dj = COMPASS_VEC[hc]
            nxt = (sub[0] + di, sub[1] + dj)
            if not (0 <= nxt[0] < rows and 0 <= nxt[1] < cols) or board.blocked[nxt]:
                abort = f"drove into a blocked sub-cell at {nxt} (decision {decisions})"
                break
            # drive to the next sub-cell centre as the robot believes it: aim off its heading by
            # beta to take out its estimated offset, drive, turn back (turns at the true rate)
            ux, uy = math.cos(_compass_to_rad(hc)), math.sin(_compass_to_rad(hc))
            want = np.array([D * ux, D * uy]) - offset_est
            along = want @ (ux, uy)
            lateral = want @ (-uy, ux)
            beta = math.atan2(lateral, along)
            est_rate = (math.pi / 2) / turn_s
            beta_true = math.copysign(true_rate(t) * abs(beta) / est_rate, beta)
            dist = math.hypot(along, lateral) + rng.normal(0, tm.drive_sigma_m)
            x += dist * math.cos(hdg + beta_true)
            y += dist * math.sin(hdg + beta_true)
            t += 2 * abs(beta) / est_rate + dist / tm.drive_speed_m_s
            offset_est = np.zeros(2)
            sub = nxt
            visits[sub] += 1
            moves += 1
            ideal = board.subcell_center_m(*sub)
            max_pos_err = max(max_pos_err, math.hypot(x - ideal[0], y - ideal[1]))
            if math.hypot(x - ideal[0], y - ideal[1]) > 0.45 * D:
                abort = f"lost: {100 * math.hypot(x - ideal[0], y - ideal[1]):.1f} cm off sub-cell {sub}"
                break
        elif action in (Action.TURN_LEFT, Action.TURN_RIGHT):
            sign = 1.0 if action is Action.TURN_LEFT else -1.0
            hdg = _wrap(hdg + sign * true_rate(t) * turn_s)
            t += turn_s
            hc = (hc + (3 if action is Action.TURN_LEFT else 1)) % 4
            turns += 1
            err = measure_heading()  # (takes frames, does not turn)
            if cfg.trace and err is not None:
                print(f"   turn: heading error {math.degrees(heading_error()):+.3f}, measured {math.degrees(err):+.3f}")
            if err is not None:
                turned = math.pi / 2 + sign * (err - est_err)  # what this turn really did
                rec = recalibrate_turn(turn_s, turned)
                if rec.accepted:
                    turn_s = rec.turn_time_s
                # finish the turn: rotate back by the measured error at the estimated rate
                est_rate = (math.pi / 2) / turn_s
                corr_s = abs(err) / est_rate
                hdg = _wrap(hdg - math.copysign(1.0, err) * true_rate(t) * corr_s)
                t += corr_s
                est_err = 0.0
    else:
        abort = abort or f"gave up after {cfg.max_decisions} decisions"
    if on_end is not None:  # e.g. to draw the floor as the run left it
        on_end(phosphor=phosphor, visits=visits, pose=(x, y, hdg), t_s=t)
    reachable = board.reachable_cells()
    start = tuple(board.start_subcell)
    closed = finished and sub == start and moves > 0
    repeat = visits.copy()
    if closed:
        repeat[sub] -= 1
    out = {
        "perception": cfg.perception,
        "exposure": cfg.exposure,
        "board_cells": list(board.shape_cells),
        "subcells_reachable": int(4 * reachable.sum()),
        "subcells_covered": int((visits > 0).sum()),
        "subcells_covered_more_than_once": int((repeat > 1).sum()),
        "returned_to_start": (sub[0] // 2, sub[1] // 2) == board.start_cell,
        "finished": finished,
        "abort_reason": abort,
        "moves": moves,
        "turns": turns,
        "decisions": decisions,
        "looks": looks,
        "look_errors": look_errors,
        "reobserved": reobserved,
        "sim_time_s": t,
        "wall_s": time.perf_counter() - wall0,
        "decision_errors": decision_errors,
        "max_mark_age_read_s": max_age_read,
        "max_position_error_m": max_pos_err,
        "turn_time_s_final": turn_s,
        "turn_rate_error_pct": 100 * (rate_gain - 1),
        "frames": sees.frames if sees is not None else 0,
        "long_exposures": sees.long_frames if sees is not None else 0,
    }
    if first_error is not None:
        fe = first_error
        out["first_decision_error"] = {
            "decision": fe["decision"],
            "t_s": round(fe["t_s"], 1),
            "subcell": list(fe["subcell"]),
            "position_error_m": round(fe["pos_err_m"], 4),
            "heading_error_deg": round(fe["heading_err_deg"], 2),
            "camera_boxes": list(fe["camera"].boxes),
            "oracle_boxes": list(fe["oracle"].boxes),
            "camera_neighbours": [[n.has_marks, n.has_red] for n in fe["camera"].neighbours],
            "oracle_neighbours": [[n.has_marks, n.has_red] for n in fe["oracle"].neighbours],
            "camera_landing": list(fe["camera"].landing_marked),
            "oracle_landing": list(fe["oracle"].landing_marked),
            "camera_start_mark": fe["camera"].start_mark,
            "oracle_start_mark": fe["oracle"].start_mark,
        }
    return out


def draw_floor(board, phosphor, visits, pose, t_s: float, *, px_per_m: float = 400.0) -> np.ndarray:
    """Top view (north up, BGR uint8) of a run: free and obstacle cells, red lights, covered
    sub-cells, every UV dot drawn with its current luminance, and the robot."""
    import cv2

    w, h = board.size_m
    m = 20
    W, H = int(w * px_per_m) + 2 * m, int(h * px_per_m) + 2 * m
    img = np.full((H, W, 3), 255, np.uint8)

    def px(xy):
        return int(round(m + xy[0] * px_per_m)), int(round(m + (h - xy[1]) * px_per_m))

    D = board.subcell_m
    rows, cols = board.shape_subcells
    for i in range(rows):
        for j in range(cols):
            c = board.subcell_center_m(i, j)
            a, b = px(c - D / 2), px(c + D / 2)
            if not board.cell_free[i // 2, j // 2]:
                cv2.rectangle(img, (a[0], b[1]), (b[0], a[1]), (90, 90, 90), -1)
            elif visits[i, j]:
                cv2.rectangle(img, (a[0], b[1]), (b[0], a[1]), (215, 240, 215), -1)
    for k in range(0, cols + 1, 2):
        cv2.line(img, px((k * D, 0)), px((k * D, h)), (150, 150, 150), 1)
    for k in range(0, rows + 1, 2):
        cv2.line(img, px((0, k * D)), px((w, k * D)), (150, 150, 150), 1)
    for xy in board.red_lights_m():
        if 0 <= xy[0] <= w and 0 <= xy[1] <= h:
            cv2.circle(img, px(xy), 5, (0, 0, 230), -1)
    if len(phosphor):
        lum = phosphor.luminance_at(t_s)
        g = np.sqrt(np.clip(lum / phosphor.law.initial_cd_m2(3.0), 0, 1))
        for xy, v in zip(phosphor.xy_m, g, strict=True):
            cv2.circle(img, px(xy), 2, (int(60 * (1 - v)), int(100 + 155 * v), int(60 * (1 - v))), -1)
    x, y, hd = pose
    cv2.circle(img, px((x, y)), int(0.065 * px_per_m), (200, 90, 40), 2)
    cv2.line(img, px((x, y)), px((x + 0.08 * math.cos(hd), y + 0.08 * math.sin(hd))), (200, 90, 40), 2)
    return img
