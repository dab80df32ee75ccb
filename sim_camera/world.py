"""The physical world: a pymunk 7 space holding an arena's walls and the robots.

Units are SI: metres, seconds, kilograms, radians. pymunk's defaults assume pixels, so the
tolerances are set for metres: ``collision_slop`` 0.1 mm (pymunk's default 0.1 would be 10 cm).
Gravity is zero (a top-down floor). One thread, fixed time step ``dt_s``, split into substeps
``space.step(dt_s / n)``: the run is deterministic for a given seed.

Walls:

* outer boundary: segments built *outward* from the boundary polygon (inner face on the
  boundary), radius ``wall_thickness_m / 2``, each extended past convex corners so no gap opens;
* barriers: segments of radius ``thickness_m / 2`` on their centre lines;
* obstacles: static circles and (convex-decomposed) polygons.

No tunnelling: a robot pushed by a velocity controller moves at most
``max_substep_travel_m`` per substep (default a quarter of the thinnest wall's half-thickness);
the number of substeps of each step grows with the fastest robot's speed to keep that bound. As a
last line, after every step a guard checks each robot centre against ``arena.contains_xy``; a
robot found outside is put back to its last inside pose and counted in
:attr:`World.containment_events` (tests assert it stays 0).

Randomness: ``World(arena, seed=S)`` owns a ``SeedSequence(S)``; each robot gets a child stream
(in the order robots are added), and each robot splits its own into parameter draws, slip noise
and one stream per sensor. No global RNG.
"""

from __future__ import annotations

import math

import numpy as np
import pymunk

from stcvision.errors import BadInputError
from stcvision.sim_camera.arenas import Arena, CircleObstacle, PolygonObstacle
from stcvision.sim_camera.robot import DiffDriveParams, DiffDriveRobot, MotionResult

__all__ = ["WALL_CATEGORY", "ROBOT_CATEGORY", "World"]

WALL_CATEGORY = 0b01
ROBOT_CATEGORY = 0b10
COLLISION_SLOP_M = 1e-4


class World:
    """An arena, its static walls and the robots in one pymunk space.

    Parameters
    ----------
    arena : Arena
    dt_s : fixed time step (s); default 0.05 s.
    min_substeps : substeps per step at least; more when robots are fast.
    seed : int or SeedSequence; everything random in this world derives from it.
    max_substep_travel_m : bound on a robot centre's travel per substep (default: a quarter of
        the thinnest wall's half-thickness, at most 2 mm).
    pheromone, chemical : optional floor layers (see :mod:`stcvision.sim_camera.layers`).
    """

    def __init__(
        self,
        arena: Arena,
        *,
        dt_s: float = 0.05,
        min_substeps: int = 2,
        seed: int | np.random.SeedSequence = 0,
        max_substep_travel_m: float | None = None,
        pheromone=None,
        chemical=None,
    ):
        if not dt_s > 0:
            raise BadInputError(f"dt_s must be > 0; got {dt_s!r}")
        self.arena = arena
        self.dt_s = float(dt_s)
        self.min_substeps = max(1, int(min_substeps))
        self._ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        self.pheromone = pheromone
        self.chemical = chemical
        self.layers: list = []
        self.robots: list[DiffDriveRobot] = []
        self.time_s = 0.0
        self.step_count = 0
        self.containment_events = 0
        self.substeps_taken = 0

        space = pymunk.Space(threaded=False)
        space.gravity = (0.0, 0.0)
        space.damping = 1.0
        space.collision_slop = COLLISION_SLOP_M
        space.iterations = 20
        self.space = space
        self._thinnest_m = self._build_walls()
        self.max_substep_travel_m = (
            float(max_substep_travel_m) if max_substep_travel_m else min(0.002, 0.25 * self._thinnest_m)
        )

    # -- construction ----------------------------------------------------------------------
    def _add_static(self, shape: pymunk.Shape) -> None:
        shape.friction = 0.0
        shape.elasticity = 0.0
        shape.filter = pymunk.ShapeFilter(categories=WALL_CATEGORY)
        self.space.add(shape)

    def _build_walls(self) -> float:
        """Create the static shapes; return the thinnest half-thickness (m)."""
        sb = self.space.static_body
        arena = self.arena
        w = 0.5 * arena.wall_thickness_m
        thinnest = w
        v = arena.outer_vertices()  # counter-clockwise
        n = len(v)
        nxt = np.roll(v, -1, axis=0)
        t = nxt - v
        t /= np.linalg.norm(t, axis=1)[:, None]
        normal_out = np.c_[t[:, 1], -t[:, 0]]
        turn = t[:, 0] * np.roll(t, -1, axis=0)[:, 1] - t[:, 1] * np.roll(t, -1, axis=0)[:, 0]
        convex_end = turn > 1e-12  # vertex at the end of edge k is convex
        convex_start = np.roll(convex_end, 1)
        for k in range(n):
            a = v[k] + normal_out[k] * w - (t[k] * w if convex_start[k] else 0.0)
            b = nxt[k] + normal_out[k] * w + (t[k] * w if convex_end[k] else 0.0)
            self._add_static(pymunk.Segment(sb, tuple(a), tuple(b), w))
        for bar in arena.barriers:
            r = 0.5 * bar.thickness_m
            thinnest = min(thinnest, r)
            self._add_static(pymunk.Segment(sb, bar.start_m, bar.end_m, r))
        for o in arena.obstacles:
            if isinstance(o, CircleObstacle):
                thinnest = min(thinnest, o.radius_m)
                self._add_static(pymunk.Circle(sb, o.radius_m, offset=o.center_m))
            elif isinstance(o, PolygonObstacle):
                verts = o.vertices_m
                ext = o.array.max(axis=0) - o.array.min(axis=0)
                thinnest = min(thinnest, 0.5 * float(ext.min()))
                if o.is_convex():
                    self._add_static(pymunk.Poly(sb, verts))
                else:
                    import pymunk.autogeometry as ag

                    loop = list(verts) + [verts[0]]
                    for part in ag.convex_decomposition(loop, 1e-6):
                        self._add_static(pymunk.Poly(sb, [tuple(p) for p in part]))
        return thinnest

    def spawn_seed(self) -> np.random.SeedSequence:
        """A fresh child seed stream of this world (deterministic order)."""
        return self._ss.spawn(1)[0]

    def add_robot(
        self,
        params: DiffDriveParams,
        pose: tuple[float, float, float] | None = None,
        *,
        record_trail: bool = True,
        sensors: bool = True,
    ) -> DiffDriveRobot:
        """Add a robot at ``pose`` (default: the arena's central-bottom start pose)."""
        if pose is None:
            pose = self.arena.start_pose(params.radius_m * 1.2)
        if not self.arena.contains([pose[0], pose[1]], margin_m=params.radius_m * 0.999)[0]:
            raise BadInputError(
                f"robot pose {tuple(round(p, 4) for p in pose)} is not a free spot {params.radius_m} m from the walls"
            )
        robot = DiffDriveRobot(
            params,
            pose,
            seed=self.spawn_seed(),
            robot_id=len(self.robots),
            record_trail=record_trail,
        )
        robot.shape.filter = pymunk.ShapeFilter(group=robot.id + 1, categories=ROBOT_CATEGORY)
        self.space.add(robot.body, robot.shape)
        self.robots.append(robot)
        if sensors:
            from stcvision.sim_camera.robot_sensors import SensorSuite

            robot.sensors = SensorSuite(self, robot)
        return robot

    def add_layer(self, layer) -> None:
        """Add a floor layer whose ``on_step(world)`` is called after every step."""
        self.layers.append(layer)

    def rng(self) -> np.random.Generator:
        """A Generator on a fresh child stream (e.g. for a controller's noise)."""
        return np.random.default_rng(self.spawn_seed())

    # -- stepping --------------------------------------------------------------------------
    def step(self) -> None:
        """Advance robots, physics, encoders/odometry and floor layers by ``dt_s``."""
        dt = self.dt_s
        vmax = 0.0
        for r in self.robots:
            vmax = max(vmax, r._pre_step(self.time_s, dt))
        n = max(self.min_substeps, math.ceil(vmax * dt / self.max_substep_travel_m))
        h = dt / n
        space = self.space
        robots = self.robots
        for _ in range(n):
            space.step(h)  # robots' velocity_func applies the wheel velocities each substep
        self.substeps_taken += n
        arena = self.arena
        for r in robots:
            b = r.body
            p = b.position
            if arena.contains_xy(p.x, p.y):
                r._last_inside = (p.x, p.y, b.angle)
            else:  # should never happen: count it and put the robot back
                self.containment_events += 1
                x, y, a = r._last_inside
                b.position = (x, y)
                b.angle = a
                space.reindex_shapes_for_body(b)
            r._post_step(dt)
            if r.nozzle_open and self.pheromone is not None:
                self.pheromone.deposit_segment(r._pos_before, (b.position.x, b.position.y))
        self.time_s += dt
        self.step_count += 1
        for layer in self.layers:
            layer.on_step(self)

    def run(self, n_steps: int, controller=None) -> None:
        """Step ``n_steps`` times, calling ``controller(world)`` before each step if given."""
        for _ in range(int(n_steps)):
            if controller is not None:
                controller(self)
            self.step()

    def run_until_done(self, robot: DiffDriveRobot, timeout_s: float = 120.0, stop_when=None) -> MotionResult:
        """Step until ``robot``'s current primitive ends (or ``timeout_s`` of sim time).

        ``stop_when``: optional ``callable(world) -> bool`` checked before every step (so a
        primitive never starts into a condition that already holds) and after it; when it
        returns True the robot stops where it is and the result's status is "stopped" (e.g. a
        drive halted by TASTI 2's capacitive ring, ``robot.sensors.capacitive.obstacle_ahead``).
        """
        t_end = self.time_s + timeout_s
        while robot.busy:
            if stop_when is not None and stop_when(self):
                return self._interrupt(robot, "stopped")
            if self.time_s >= t_end:
                return self._interrupt(robot, "timeout")
            self.step()
        return robot.last_result or MotionResult("done", 0.0, 0.0)

    @staticmethod
    def _interrupt(robot: DiffDriveRobot, status: str) -> MotionResult:
        """Stop ``robot``'s primitive where it is; the result says how far it got."""
        res = MotionResult(
            status,
            robot.odometry.distance_m - robot._prim.get("start_dist", 0.0),
            robot._prim.get("t", 0.0),
        )
        robot.stop()
        robot.last_result = res
        return res

    # -- queries ---------------------------------------------------------------------------
    def ray_distance(self, start, end, robot: DiffDriveRobot | None = None) -> float | None:
        """Distance (m) from ``start`` along to ``end`` to the first solid (walls, obstacles and
        other robots; ``robot`` itself excluded), or None if nothing is hit."""
        flt = pymunk.ShapeFilter(group=robot.id + 1) if robot is not None else pymunk.ShapeFilter()
        info = self.space.segment_query_first(tuple(start), tuple(end), 0.0, flt)
        if info is None:
            return None
        return info.alpha * math.dist(start, end)
