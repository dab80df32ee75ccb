"""Perception: what the robot reads at a decision, at a look and after a turn, behind one small
interface (:class:`Perception`), three ways:

* :class:`OraclePerception` -- the floor's record of marks (no camera); the pose read-out has
  the pipeline's measured noise;
* :class:`IdealPerception` -- the physics-limited camera (:class:`stcvision.controllers.stc.frames.IdealCamera`):
  the camera's frames and time, exactly the marks within their visibility horizon;
* :class:`CameraPerception` -- rendered frames read by the vision pipeline, and the robot's
  localisation from them: where it stands (red lights and its own marks, each weighed against
  what it believes: :mod:`stcvision.controllers.stc.localise`), its heading error
  (the newest row's fit less the lean the red lights or all rows show), frames taken again when
  the red lights show them askew.

A perception may spend the robot's time (``plant.wait``) and, with the red lights, correct a
drift it sees (``plant.rotate_by``) or drive back to the sub-cell centre
(:func:`stcvision.controllers.stc.belief.recentre`); what it measures of where the robot stands updates
the robot's belief (``belief.offset_m``), never the plant. It never moves the robot to another
sub-cell and never decides.
"""

from __future__ import annotations

import math
from functools import partial
from typing import Protocol

import numpy as np

from stcvision.controllers.stc.belief import Belief, realign, recentre
from stcvision.controllers.stc.config import (
    LANDMARK_OFFSET_SIGMA,
    LANDMARK_TURN_SIGMA_RAD,
    RECENTRE_M,
    REOBSERVE_RAD,
    CoverConfig,
)
from stcvision.controllers.stc.frames import IdealCamera, RobotCamera
from stcvision.controllers.stc.fsm import StcObservation
from stcvision.controllers.stc.health import RobotStop
from stcvision.controllers.stc.localise import LIGHTS_WIDE_SIGMA_M, LIGHTS_WIDE_SPREAD, MARKS_SIGMA_M
from stcvision.controllers.stc.oracle import landing_oracle, look_oracle, observe_oracle
from stcvision.controllers.stc.plant import Floor, Plant
from stcvision.stc_geometry import entry_axes

#: the newest row's lean at a decision or a look beyond which the robot turned on its own since
#: it laid the row (a turn's recalibration leaves ~0.25 degrees): it is turned back
HEADING_CHECK_RAD = math.radians(2.0)
#: a long frame's lean of all rows beyond which the heading is trimmed by it: the lean of two
#: or more rows agreeing within a degree (:func:`stcvision.observation.pattern_rotation`) is
#: good to ~0.18 degrees (the newest row's 0.25 over the square root of two); a bias left
#: below this drifts the robot sideways by under 0.5 mm a sub-cell
LEAN_TRIM_RAD = math.radians(0.15)
#: a white light this close (m) blinds the decision's reading: the cell and its neighbours'
#: near halves lie within 0.45 m (frames.AUTO_REACH_M)
WHITE_BLIND_M = 0.45

__all__ = ["CameraPerception", "IdealPerception", "OraclePerception", "Perception", "make_perception"]


class Perception(Protocol):
    """The interface the loop sees."""

    #: its decisions are compared with the oracle's (the referee), as the oracle's own are not
    refereed: bool
    #: the frame a decision or a look was read from, for the observers: (pipeline result,
    #: pipeline), or None when there is no rendered frame
    last_frame: tuple | None
    frames: int
    long_frames: int
    #: decisions and looks observed again because their frames were read askew (camera only)
    reobserved: int

    def observe(
        self, plant: Plant, belief: Belief, floor: Floor, *, fresh: bool, at_start: bool, start_cell: bool
    ) -> StcObservation:
        """The decision's reading; may raise :class:`stcvision.controllers.stc.claims.OutOfSight`.
        ``start_cell``: the robot's count of its moves puts it in its start cell."""

    def look(self, plant: Plant, belief: Belief, floor: Floor, *, landing: bool) -> bool:
        """The look ahead (``landing``: at the sub-cell ahead, before a return to the parent);
        may raise :class:`stcvision.controllers.stc.claims.OutOfSight`."""

    def heading_after_turn(self, plant: Plant, belief: Belief, floor: Floor) -> float | None: ...


class OraclePerception:
    """The floor's record, read as the camera would see it (no start mark under the robot)."""

    refereed = False
    last_frame = None
    frames = long_frames = reobserved = 0

    def __init__(self, cfg: CoverConfig, board, rng: np.random.Generator):
        self.cfg = cfg
        self.board = board
        self.rng = rng  # the read-out noise of the pose

    def _offset(self, plant: Plant, belief: Belief) -> np.ndarray:
        """The truth with the marks' read-out noise."""
        return plant.true_offset(belief.sub) + self.rng.normal(0, self.cfg.position_sigma_oracle_m, 2)

    def _heading(self, plant: Plant, belief: Belief) -> float:
        """The truth with the pipeline's measured heading noise."""
        return plant.heading_error(belief.hc) + self.rng.normal(0, self.cfg.heading_sigma_oracle_rad)

    def observe(self, plant, belief, floor, *, fresh, at_start=False, start_cell=True):
        plant.wait(self.cfg.robot.settle_s)
        obs = observe_oracle(floor.record, self.board, belief.sub, belief.hc, camera_view=True)
        belief.offset_m = self._offset(plant, belief)
        return obs

    def look(self, plant, belief, floor, *, landing=False):
        plant.wait(self.cfg.robot.settle_s)
        return (landing_oracle if landing else look_oracle)(floor.record, belief.sub, belief.hc).marked

    def heading_after_turn(self, plant, belief, floor):
        plant.wait(self.cfg.robot.settle_s)
        belief.offset_m = self._offset(plant, belief)
        return self._heading(plant, belief)


class _TakesFrames:
    """What a perception with a camera (``self.cam``: :class:`stcvision.controllers.stc.frames.Exposures`)
    reports of its frames."""

    @property
    def frames(self) -> int:
        return self.cam.frames

    @property
    def long_frames(self) -> int:
        return self.cam.long_frames


class IdealPerception(_TakesFrames, OraclePerception):
    """The physics-limited camera: its frames' time, the marks within their horizon, the pose
    as the oracle reads it."""

    refereed = True

    def __init__(self, cfg: CoverConfig, board, rng: np.random.Generator):
        super().__init__(cfg, board, rng)
        self.cam = IdealCamera(cfg, board)

    def observe(self, plant, belief, floor, *, fresh, at_start=False, start_cell=True):
        obs, dt = self.cam.observe(
            (plant.x, plant.y), plant.t, floor.phosphor, floor.laid, belief.sub, belief.hc, fresh=fresh,
            at_start=at_start, dot_mark=floor.dot_mark, start_cell=start_cell,
        )  # fmt: skip
        plant.wait(self.cfg.robot.settle_s + dt)
        belief.offset_m = self._offset(plant, belief)
        return obs

    def look(self, plant, belief, floor, *, landing=False):
        xy = (plant.x, plant.y)
        marked, dt = self.cam.look(
            xy, plant.t, floor.phosphor, floor.laid, belief.sub, belief.hc, landing=landing, dot_mark=floor.dot_mark
        )
        plant.wait(self.cfg.robot.settle_s + dt)
        belief.offset_m = self._offset(plant, belief)
        return marked

    def heading_after_turn(self, plant, belief, floor):
        # the frames' time: the newest row and the consensus frame
        cam = self.cam
        plant.wait(self.cfg.robot.settle_s)
        plant.wait(cam.frame_s(0))
        if self.cfg.consensus_frame and cam.controlled and self._short_rows(plant, floor) < self.cfg.consensus_rows:
            plant.wait(cam.frame_s(1))
        belief.offset_m = self._offset(plant, belief)
        return self._heading(plant, belief)

    def _short_rows(self, plant, floor) -> int:
        """The marks a short frame sees from here (the camera counts the lit dots in its ground
        view, :meth:`CameraPerception.heading_after_turn`)."""
        seen = self.cam.floor_seen((plant.x, plant.y), plant.t, floor.phosphor, floor.laid, [0])
        return sum(len(e) for e in seen.edges.values())


class CameraPerception(_TakesFrames):
    """Rendered frames read by the pipeline; the robot's localisation from them."""

    refereed = True

    def __init__(self, cfg: CoverConfig, board, rng: np.random.Generator, *, camera_wrap=None):
        self.cfg = cfg
        self.board = board
        self.cam = RobotCamera(board, cfg, rng, camera_wrap=camera_wrap)
        self.last_frame = None
        self.reobserved = 0

    # ------------------------------------------------------------------ the loop's three readings
    def observe(self, plant, belief, floor, *, fresh, at_start=False, start_cell=True):
        take = partial(self.cam.observe, phosphor=floor.phosphor, fresh=fresh, at_start=at_start, start_cell=start_cell)
        obs, res = self._read(plant, belief, take)
        self.last_frame = (res, self.cam.pipe)
        return obs

    def look(self, plant, belief, floor, *, landing=False):
        # a look stands beside the exit, where the rows in view were laid at many other times
        # (each where the robot then stood): only the red lights say where it stands there
        look = partial(self.cam.look, phosphor=floor.phosphor, landing=landing)
        marked, res = self._read(plant, belief, look, lights_only=True)
        self.last_frame = (res, self.cam.pipe)
        return marked

    def heading_after_turn(self, plant, belief, floor):
        """The heading fit on the newest row; the marks in view also say where the robot stands."""
        cam, cfg = self.cam, self.cfg
        res, dt = cam.shoot(plant.pose, plant.t, floor.phosphor)
        plant.wait(cfg.robot.settle_s + dt)
        belief.offset_m, _ = self._where(res.observation, belief)
        lights = self._lights_rotation(res.observation)
        if lights is not None:  # the heading's absolute reference, as sure as their spread
            belief.bearing.lights(res.observation.landmark_rotation_sigma_rad)
            belief.unmeasured_turns = 0  # (measured against the grid, any turn's error included)
        if not res.heading.ok:
            # no newest row to fit: the red lights, when they are sure enough, else the newest
            # row of a 2 s frame (a turn left uncorrected leaves the next cell read askew)
            if lights is not None:
                return -lights
            if not cam.controlled:
                return None
            res, dt = cam.shoot(plant.pose, plant.t, floor.phosphor, 1)
            plant.wait(dt)
            return res.heading.heading_error_rad - belief.realigned_rad if res.heading.ok else None
        rows = None
        # the lean of all rows is wanted only where the red lights do not say it (_heading)
        few_rows = int(res.dots.lit.sum()) < 4 * cfg.consensus_rows  # (four dots a row)
        if cfg.consensus_frame and cam.controlled and few_rows and lights is None:
            rows, dt = cam.shoot(
                plant.pose, plant.t, floor.phosphor, 1, heading_error_rad=res.heading.heading_error_rad
            )
            plant.wait(dt)
        # the newest row carries the heading error the robot had when laying it; the lean of
        # all the rows in view (the consensus of older marks) or the red lights take that out
        return self._heading(res, belief, rows, taken=True)

    # ------------------------------------------------------------------ localisation
    def _read(self, plant, belief, take, *, lights_only: bool = False):
        """A decision's or a look's frames: ``take(pose, t) -> (reading, short frame's result,
        long frame's result or None, seconds)``. The short frame says where the robot stands
        and, with the red lights, how far its heading has drifted; a drift over
        :data:`REOBSERVE_RAD` means the frames were read askew, so they are taken once more; so
        are they when the robot finds itself over :data:`RECENTRE_M` off its sub-cell centre
        (it drives back first) or its newest row leaning (:meth:`_check_heading`), and when the
        red lights disagreed with the belief beyond what either could be off by
        (:meth:`_where`): the second frame says which of them to believe.
        Where no lights are in view, a long frame's rows say it: they were laid square to the
        grid, so their lean is the heading's drift (a robot 7.7 degrees askew read the rows of
        the cell behind as a start mark and stopped a 12x12 tour half-way). Returns (reading,
        the frame that read the old marks)."""
        for attempt in range(2):
            reading, short, long, dt = take(plant.pose, plant.t)
            plant.wait(self.cfg.robot.settle_s + dt)
            self._check_lights(short, belief)
            belief.offset_m, doubted = self._where(short.observation, belief, lights_only=lights_only)
            turned = self._correct_heading(short, plant, belief)
            if turned == 0.0:
                turned = self._check_heading(short, plant, belief)
            if turned == 0.0 and long is not None:  # (the lights, absolute, outrank the rows)
                turned = self._correct_lean(long, plant, belief)
            moved = np.hypot(*belief.offset_m) > RECENTRE_M
            if moved:  # read the cell from where the robot should stand
                recentre(plant, belief)
            if abs(turned) < REOBSERVE_RAD and not moved and not doubted:
                break
            self.reobserved += attempt == 0  # (a second askew reading is kept)
        return reading, long or short

    def _correct_lean(self, long, plant, belief) -> float:
        """A long frame's rows, read with the short frame's heading, still lean by more than
        :data:`LEAN_TRIM_RAD` once weighed against how sure the heading is (:func:`_weigh_lean`):
        the heading has drifted that far; take it out. Returns the rotation made (rad)."""
        lean = long.observation.pattern_rotation_rad if self.cfg.use_mark_consensus else None
        if lean is None:
            return 0.0
        e, k = _weigh_lean(long.observation.heading_error_rad, lean, belief)
        if abs(e) <= LEAN_TRIM_RAD:
            return 0.0
        realign(plant, belief, -e)
        belief.bearing.took_rows(k)
        # a small lean is a heading bias the newest row shares (it was laid with it), which
        # no turn's recalibration sees: taken out, the reading itself stands (0.3 degrees moves
        # box 2 by 1.4 mm); only a large one means the frames were read askew
        return -e if abs(e) > REOBSERVE_RAD else 0.0

    def _where(self, observation, belief, *, lights_only: bool = False) -> tuple[np.ndarray, bool]:
        """The robot's offset from its sub-cell centre (world, m), from the red lights in view
        and its own marks (``lights_only``: not from them), each weighted by its uncertainty
        against the belief so far (:class:`stcvision.controllers.stc.localise.Fix`): sure red lights
        (absolute: they stand at cell centres) replace it; less sure ones, and the marks, are
        fused into it unless they disagree with it beyond what either could be off by.
        Returns (the offset, whether the gate left the red lights out).

        Why the second: along its track the robot's marks say only where its own newest rows
        lie, and those were laid where it then stood, so the belief they keep can walk away
        from the truth by a move's error at a time (2 mm, 1 sigma) while its variance stays
        small; the red lights are the only absolute reference and may be in view for one
        reading only. Left out once, the gate has made the belief as unsure as that reading
        needs, and a second frame's lights that agree are taken (spiral_stc_test_3, lowlight,
        seed 821: lights 2.1 cm from a belief of 0, right to 0.8 mm, left out; the robot, 2 cm
        off, later read an old row as a start mark and stopped)."""
        fix, sm = belief.fix, self.board.subcell_m
        off = belief.offset_m
        lights = observation.landmark_offset if self.cfg.use_landmarks else None
        doubted = False
        if _believable(lights):
            spread = observation.landmark_offset_sigma
            if spread <= LANDMARK_OFFSET_SIGMA:
                return fix.lights(entry_offset_to_world(lights, belief.hc, sm)), False
            if spread <= LIGHTS_WIDE_SPREAD:
                left_out = fix.rejected
                off = fix.fuse(off, entry_offset_to_world(lights, belief.hc, sm), LIGHTS_WIDE_SIGMA_M)
                doubted = fix.rejected > left_out
        marks = observation.position_offset
        if not lights_only and not doubted and _believable(marks):  # (doubted: the re-look says)
            # only the axes the marks measured: rows across one axis say nothing of the other
            axes = np.abs(entry_offset_to_world(observation.position_offset_axes, belief.hc, 1.0)) > 0.5
            off = fix.fuse(off, entry_offset_to_world(marks, belief.hc, sm), MARKS_SIGMA_M, axes)
        return off, doubted

    def _heading(self, res, belief, rows=None, *, taken: bool = False) -> float | None:
        """The heading error: the newest row's, less what the red lights (absolute, when in view)
        or the lean of all rows (the consensus of older marks; from ``rows``, a long frame read
        with the same heading, when given: it sees many more of them) say is left over -- the
        rows' lean weighed against how sure the heading is (:func:`_weigh_lean`); ``taken``:
        the caller turns by the result, so the heading's variance becomes the fused one."""
        if not res.heading.ok:
            return None
        cfg, o = self.cfg, res.observation
        newest = res.heading.heading_error_rad
        lights = self._lights_rotation(o)
        if lights is not None:
            return newest - lights
        lean = o.pattern_rotation_rad if cfg.use_mark_consensus else None
        if lean is not None and rows is not None and rows.observation.pattern_rotation_rad is not None:
            lean = rows.observation.pattern_rotation_rad
        if lean is None:
            return newest - belief.realigned_rad
        e, k = _weigh_lean(newest, lean, belief)
        if taken:
            belief.bearing.took_rows(k)
        return e

    def _check_heading(self, res, plant, belief) -> float:
        """Without the red lights: a heading error over :data:`HEADING_CHECK_RAD` (the newest
        row's lean less the lean of all rows in view, :meth:`_heading`) means the robot turned
        during a move (a wheel slipped): turn back by it. Returns the rotation made (rad)."""
        e = self._heading(res, belief)
        if e is not None and abs(e) > HEADING_CHECK_RAD:
            plant.rotate_by(-e, belief.turn_s)
            return -e
        return 0.0

    def _check_lights(self, short, belief) -> None:
        """A white light (a lamp, not a red obstacle light) in the short frame ``short`` within
        :data:`WHITE_BLIND_M` of the robot: its glare hides the marks around it, so the cell
        cannot be read: stop rather than decide on it."""
        xy = short.white_lights_m
        if len(xy):
            d = float(np.hypot(*xy.T).min())
            if d < WHITE_BLIND_M:
                raise RobotStop(
                    f"a white light (not a red obstacle light) {d:.2f} m from the robot at sub-cell "
                    f"{tuple(int(v) for v in belief.sub)}: its glare hides the marks there"
                )

    def _lights_rotation(self, o) -> float | None:
        """How far the red lights in view are still turned (rad), when they are sure enough to
        be the heading's reference (:data:`LANDMARK_TURN_SIGMA_RAD`); None otherwise (then the
        consensus of the marks is)."""
        if not self.cfg.use_landmarks or o.landmark_rotation_rad is None:
            return None
        return o.landmark_rotation_rad if o.landmark_rotation_sigma_rad <= LANDMARK_TURN_SIGMA_RAD else None

    def _correct_heading(self, res, plant, belief) -> float:
        """Two or more red lights in view say how far the heading has drifted: take it out.
        Returns the rotation made (rad)."""
        if self.cfg.use_landmarks and res.observation.landmark_rotation_rad is not None:
            e = self._heading(res, belief)
            sig = res.observation.landmark_rotation_sigma_rad
            sure = self._lights_rotation(res.observation) is not None
            # only a drift the lights show clearly (2.5 sigma), and never by a hair
            if e is not None and abs(e) > max(math.radians(0.5), 2.5 * sig):
                realign(plant, belief, -e)
                if sure:
                    belief.bearing.lights(sig)
                return -e
            if e is not None and sure:
                belief.bearing.lights(sig, e)  # a drift too small to turn out
        return 0.0


def _weigh_lean(newest: float, lean: float, belief) -> tuple[float, float]:
    """The heading error (rad) from the newest row's fit ``newest`` and the lean of all rows
    ``lean``, weighed by the robot's heading variance
    (:meth:`stcvision.controllers.stc.localise.Bearing.rows_gain`), and the gain used. Against the newest
    row alone, the turns towards the grid made since it was laid come off (it lies that much
    askew of the heading they gave)."""
    k = belief.bearing.rows_gain(newest - lean, HEADING_CHECK_RAD)
    return (1 - k) * (newest - belief.realigned_rad) + k * (newest - lean), k


def _believable(off) -> bool:
    """An offset reading (entry frame, sub-cell sides) that is there and within 0.3 of a
    sub-cell (5 cm): further, the robot would stand in another sub-cell's marks."""
    return off is not None and max(abs(off[0]), abs(off[1])) <= 0.3


def entry_offset_to_world(off_ru, hc: int, subcell_m: float) -> np.ndarray:
    """Entry-frame (right, up) offset in sub-cell sides -> world metres for compass heading ``hc``."""
    right, up = entry_axes(hc)
    return subcell_m * (off_ru[0] * right + off_ru[1] * up)


def check_profile_fits(board) -> None:
    """Refuse a board whose sub-cell is not the one the camera's profile reads: the profile's
    five boxes and neighbour corners are calibrated for its own sub-cell side, and read on a
    board of another they land off the marks (a 0.20 m board read with the 0.16 m profile was
    lost after 21 decisions)."""
    from stcvision.calibration.profiles import default_profile
    from stcvision.errors import BadInputError

    prof = default_profile().subcell_m
    if abs(board.subcell_m - prof) > 1e-9 * prof:
        raise BadInputError(
            f"the board's sub-cell is {board.subcell_m:g} m but the camera's profile reads {prof:g} m sub-cells; "
            f"expected --subcell-m {prof:g}, or a profile calibrated for this robot's footprint"
        )


def make_perception(
    cfg: CoverConfig, board, *, camera_rng: np.random.Generator, oracle_rng: np.random.Generator, camera_wrap=None
) -> Perception:
    """The perception ``cfg.perception`` names: the camera draws its noise from ``camera_rng``,
    the oracle and the physics-limited camera their read-out noise from ``oracle_rng``;
    ``camera_wrap`` (the camera's faults) puts the rendering camera inside another."""
    if cfg.perception == "camera":
        check_profile_fits(board)
        return CameraPerception(cfg, board, camera_rng, camera_wrap=camera_wrap)
    if cfg.perception == "ideal":
        return IdealPerception(cfg, board, oracle_rng)
    if cfg.perception == "oracle":
        return OraclePerception(cfg, board, oracle_rng)
    from stcvision.errors import BadInputError

    raise BadInputError(f"perception must be camera, ideal or oracle; got {cfg.perception!r}")
