"""One search run: the world moves TASTI 2 truly, the controller navigates by dead reckoning.

The world is pymunk's (:class:`stcvision.sim_camera.world.World` +
:data:`stcvision.sim_camera.robot.TASTI2`); the controller is
:mod:`stcvision.controllers.search.controller`.

Executor of a :class:`Move` (TASTI 2's motion layer, the TASTI 2 paper by Russell):
turn on the spot to the move's heading by the odometry (``rotate_by``), drive the step with the
capacitive ring watching (``run_until_done(stop_when=...)``: halted when the ring's one signal is
at its stop threshold and has risen 5 noise sigmas since the move began -- the electrodes are in
parallel over the front half, so next to an obstacle the signal can be above the threshold for a
move that leads along or away from it), and if the ring halts the drive or the motor stalls,
drive back the odometric distance covered -- the move is "blocked" and the robot is back at the
point it left (sec. V: it "must return to a previous point"). With policy
``none`` the robot stays where the ring stopped it. Then the tongue is read.

Coordinates: metres, the start at the origin, heading 0 along +x. The arena is an open square
around the whole pattern (1 m beyond its planned extent and every obstacle), so its walls never
matter.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from stcvision.angles import wrap_angle
from stcvision.controllers.search.controller import (
    Move,
    Phase,
    Policy,
    SearchConfig,
    SearchObs,
    Stop,
    initial_state,
    step,
)
from stcvision.controllers.search.patterns import planned_points
from stcvision.errors import BadInputError
from stcvision.sim_camera.arenas import CircleObstacle, SquareArena
from stcvision.sim_camera.layers import ChemicalLayer, ChemicalPatch
from stcvision.sim_camera.robot import TASTI2
from stcvision.sim_camera.world import World

__all__ = ["MoveRecord", "SearchRun", "SearchScene", "check_reach", "execute_move", "run_search", "robot_params"]

MOVE_TIMEOUT_S = 60.0
RING_RISE_SIGMAS = 5.0  # the ring must rise this many noise sigmas above its start to halt a drive


@dataclass(frozen=True, kw_only=True, slots=True)
class SearchScene:
    """The search's world: obstacles and the chemical patch, relative to the start (heading 0 = +x).

    Attributes
    ----------
    obstacles : tuple of (float, float, float)
        Circular obstacles, (x, y, radius) in metres; none may overlap the robot at the start.
    patch : (float, float, float) or None
        The chemical patch the robot searches for, (x, y, radius) in metres; its centre outside
        every obstacle. None: no patch.

    Raises
    ------
    BadInputError
        For more obstacles than :data:`stcvision.limits.MAX_SEARCH_OBSTACLES`, a value that is
        not three finite numbers, anything reaching beyond
        :data:`stcvision.limits.MAX_SEARCH_REACH_M` from the start, a radius that is not
        positive, an obstacle over the start, or the patch's centre inside an obstacle.
    """

    obstacles: tuple[tuple[float, float, float], ...] = ()
    patch: tuple[float, float, float] | None = None

    def __post_init__(self):
        from stcvision.limits import MAX_SEARCH_OBSTACLES, MAX_SEARCH_REACH_M

        rr = TASTI2.radius_m
        if len(self.obstacles) > MAX_SEARCH_OBSTACLES:
            raise BadInputError(
                f"{len(self.obstacles)} obstacles is over the cap of {MAX_SEARCH_OBSTACLES} "
                "(stcvision.limits.MAX_SEARCH_OBSTACLES)"
            )
        for what, v in [("obstacle", o) for o in self.obstacles] + [("patch", self.patch)] * (self.patch is not None):
            if len(v) != 3 or not all(isinstance(c, int | float) and math.isfinite(c) for c in v):
                raise BadInputError(f"{what} {v}: expected three finite numbers x, y, radius (metres)")
        for what, v in [("obstacle", o) for o in self.obstacles] + [("patch", self.patch)] * (self.patch is not None):
            if math.hypot(v[0], v[1]) + abs(v[2]) > MAX_SEARCH_REACH_M:
                raise BadInputError(
                    f"{what} {tuple(v)} reaches beyond {MAX_SEARCH_REACH_M:g} m from the start, the cap "
                    "(stcvision.limits.MAX_SEARCH_REACH_M)"
                )
        for o in self.obstacles:
            x, y, r = o
            if not r > 0:
                raise BadInputError(f"obstacle {o}: radius must be > 0")
            if math.hypot(x, y) < r + rr:
                raise BadInputError(
                    f"obstacle at ({x}, {y}) radius {r} m overlaps the start: TASTI 2 (radius {rr} m) "
                    "stands at the origin"
                )
        if self.patch is not None:
            px, py, pr = self.patch
            if not pr > 0:
                raise BadInputError(f"patch {self.patch}: radius must be > 0")
            for x, y, r in self.obstacles:
                if math.hypot(px - x, py - y) < r:
                    raise BadInputError(f"the patch centre ({px}, {py}) lies inside the obstacle at ({x}, {y})")

    def circle_obstacles(self) -> tuple[CircleObstacle, ...]:
        """Return the obstacles as the simulator's circles.

        Returns
        -------
        tuple of CircleObstacle
            One :class:`stcvision.sim_camera.arenas.CircleObstacle` per obstacle.
        """
        return tuple(CircleObstacle(center_m=(float(x), float(y)), radius_m=float(r)) for x, y, r in self.obstacles)


def robot_params(odometry_noise: bool):
    """Return TASTI 2's parameters, with or without the odometry's errors.

    TASTI 2 as in :mod:`stcvision.sim_camera.robot`, or with exact wheels (no Ed, Eb, slip;
    encoder quantisation stays) for ``odometry_noise=False``.
    """
    if odometry_noise:
        return TASTI2
    return dataclasses.replace(TASTI2, ed=1.0, eb=1.0, slip_k=0.0)


@dataclass(frozen=True, slots=True)
class MoveRecord:
    """One move and the sensing after it."""

    index: int
    t_s: float
    kind: str  # search / avoid / unavoid
    phase: int  # 1..4 (Fig. 5)
    heading_rad: float  # commanded, odometric frame
    distance_m: float  # commanded
    result: str  # done / blocked
    true_pose: tuple[float, float, float]
    odo_pose: tuple[float, float, float]  # after the beacon fix, if any
    odo_pose_before_fix: tuple[float, float, float]
    tongue: float
    search_steps: int  # search-path steps taken after this move
    fix: tuple[float, float, float] | None = None  # beacon fix (x, y, heading or nan)


@dataclass(frozen=True, slots=True)
class SearchRun:
    """Everything a run produced.

    The metrics are computed from it by :func:`stcvision.controllers.search.metrics.summarise`.
    """

    scene: SearchScene
    config: SearchConfig
    moves: tuple[MoveRecord, ...]
    start_tongue: float
    reason: str
    search_steps: int
    true_trail: np.ndarray = field(repr=False)  # (T, 2) true centre every world step
    sim_time_s: float = 0.0
    path_length_m: float = 0.0
    containment_events: int = 0
    beacon: object = None  # the beacon used (None without)
    ring_stop_gap_m: float = 0.015

    @property
    def found(self) -> bool:
        """The search stopped because it found the patch."""
        return self.reason == "found"

    def planned(self) -> np.ndarray:
        """Return the undisturbed pattern's sampling points up to the steps taken (equation (5))."""
        return planned_points(self.config.pattern, self.search_steps)


def execute_move(world: World, robot, move: Move, *, back_off: bool = True) -> str:
    """Execute one move: turn by the odometry, then drive while the capacitive ring watches.

    Turn to ``move.heading_rad`` by the odometry, drive ``move.distance_m`` while the ring
    watches; "done", or "blocked" (and, with ``back_off``, back at the move's start point).
    """
    turn = wrap_angle(move.heading_rad - robot.odometry.theta)
    if abs(turn) > 1e-4:
        robot.rotate_by(turn)
        world.run_until_done(robot, timeout_s=MOVE_TIMEOUT_S)
    ring = robot.sensors.capacitive
    start = ring.read()
    margin = RING_RISE_SIGMAS * ring.params.noise_sigma

    def approaching(_w) -> bool:
        # at the threshold *and* risen since the move began: the nine electrodes are wired in
        # parallel over the front half (TASTI 2 paper sec. IV), so beside an obstacle the signal can
        # sit above the threshold while the move leads along it or away from it
        v = ring.read()
        return v >= ring.stop_threshold and v > start + margin

    robot.drive_distance(move.distance_m)
    res = world.run_until_done(robot, timeout_s=MOVE_TIMEOUT_S, stop_when=approaching)
    if res.ok:
        return "done"
    if back_off and res.odometric_distance_m > 0:
        robot.drive_distance(-res.odometric_distance_m)
        world.run_until_done(robot, timeout_s=MOVE_TIMEOUT_S)
    return "blocked"


def check_reach(pattern) -> None:
    """Refuse a pattern whose planned sampling points go beyond the search's reach cap."""
    from stcvision.limits import MAX_SEARCH_REACH_M

    reach = float(np.hypot(*planned_points(pattern).T).max())
    if reach > MAX_SEARCH_REACH_M:
        raise BadInputError(
            f"the {pattern.describe()} pattern reaches {reach:.3g} m from the start, beyond the cap of "
            f"{MAX_SEARCH_REACH_M:g} m (stcvision.limits.MAX_SEARCH_REACH_M); fewer or shorter steps"
        )


def build_world(scene: SearchScene, pattern, *, seed: np.random.SeedSequence, odometry_noise: bool = True):
    """Build the world (open square arena, obstacles, chemical layer) and TASTI 2 at the origin."""
    pts = planned_points(pattern)
    reach = float(np.abs(pts).max()) + 1.0
    for x, y, r in scene.obstacles:
        reach = max(reach, abs(x) + r + 1.0, abs(y) + r + 1.0)
    if scene.patch is not None:
        reach = max(reach, abs(scene.patch[0]) + scene.patch[2] + 0.5, abs(scene.patch[1]) + scene.patch[2] + 0.5)
    arena = SquareArena(side_m=2.0 * reach, obstacles=scene.circle_obstacles())
    chem = ChemicalLayer()
    if scene.patch is not None:
        chem.add(ChemicalPatch(center_m=(scene.patch[0], scene.patch[1]), radius_m=scene.patch[2]))
    world = World(arena, seed=seed, chemical=chem)
    robot = world.add_robot(robot_params(odometry_noise), pose=(0.0, 0.0, 0.0))
    return world, robot


def run_search(
    scene: SearchScene,
    config: SearchConfig,
    *,
    seed: np.random.SeedSequence,
    odometry_noise: bool = True,
    beacon=None,
    observer=None,
    progress=None,
) -> SearchRun:
    """Run the TASTI 2 search until the controller stops.

    Parameters
    ----------
    scene : SearchScene
        The obstacles and the chemical patch.
    config : SearchConfig
        The search pattern, the obstacle policy and the stop rule.
    seed : numpy.random.SeedSequence
        Split into the world's stream and the beacon camera's.
    odometry_noise : bool
        TASTI 2's odometry errors; False: exact wheels (encoder quantisation stays).
    beacon : Beacon, optional
        A :class:`stcvision.controllers.search.beacon.Beacon` fixing the odometry after each
        move (None: dead reckoning alone).
    observer : object, optional
        An object with ``on_move(record, world, robot, fixer=)`` (e.g. the rerun recorder).
    progress : callable, optional
        ``progress(search_steps)`` after each move (a progress bar).

    Returns
    -------
    SearchRun
        Every move and the sensing after it, why the search stopped, the true trail and the
        run's times and distances.

    Raises
    ------
    BadInputError
        When the pattern's planned points reach beyond the search's cap.
    """
    check_reach(config.pattern)
    ss_world, ss_beacon = seed.spawn(2)
    world, robot = build_world(scene, config.pattern, seed=ss_world, odometry_noise=odometry_noise)
    fixer = beacon.fixer(world, robot, ss_beacon) if beacon is not None else None
    sensors = robot.sensors
    state = initial_state(config)
    start_tongue = sensors.tongue.read()
    obs = SearchObs(robot.odometry.pose, sensors.capacitive.obstacle_ahead(), start_tongue, None)
    records: list[MoveRecord] = []
    back_off = config.policy is not Policy.NONE
    while True:
        state, action = step(state, obs)
        if isinstance(action, Stop):
            break
        result = execute_move(world, robot, action, back_off=back_off)
        before = robot.odometry.pose
        fix = fixer.fix() if fixer is not None else None
        if fix is not None:
            robot.odometry.correct(fix.as_tuple())
        tongue = sensors.tongue.read()
        ring = sensors.capacitive.obstacle_ahead()
        st = state.i + (1 if (result == "done" and action.kind.value == "search") else 0)
        rec = MoveRecord(
            index=len(records),
            t_s=world.time_s,
            kind=action.kind.value,
            phase=action.phase.value,
            heading_rad=action.heading_rad,
            distance_m=action.distance_m,
            result=result,
            true_pose=robot.pose,
            odo_pose=robot.odometry.pose,
            odo_pose_before_fix=before,
            tongue=tongue,
            search_steps=st,
            fix=None if fix is None else fix.as_tuple(),
        )
        records.append(rec)
        if observer is not None:
            observer.on_move(rec, world, robot, fixer=fixer)
        if progress is not None:
            progress(st)
        obs = SearchObs(robot.odometry.pose, ring, tongue, result)
    assert state.phase is Phase.DONE
    return SearchRun(
        scene=scene,
        config=config,
        moves=tuple(records),
        start_tongue=start_tongue,
        reason=state.reason,
        search_steps=state.i,
        true_trail=np.asarray(robot.trail, dtype=float),
        sim_time_s=world.time_s,
        path_length_m=robot.distance_travelled_m,
        containment_events=world.containment_events,
        beacon=beacon,
        ring_stop_gap_m=sensors.capacitive.params.stop_gap_m,
    )
