"""The reference path: Buffon's two visits on the pymunk world, one Python call per step.

The same trial as :mod:`stcvision.controllers.buffon.batched`, built from the substrate's parts: the
:class:`stcvision.sim_camera.world.World` with real contacts, a :data:`~stcvision.sim_camera.robot.KHEPERA` body, its
pymunk IR ray casts (:class:`stcvision.sim_camera.robot_sensors.IrSensors`), the raster
:class:`stcvision.sim_camera.layers.PheromoneLayer` and
:class:`stcvision.sim_camera.robot_sensors.PheromoneDetector`, and
the scalar controller :class:`stcvision.controllers.buffon.behaviour.Explorer`. It is ~100x slower; it is
what the batched path is a model of (``stcvision buffon compare`` tests them against each other).

Streams: trial i takes the same four seed streams as the batched path
(:func:`stcvision.controllers.buffon.batched.trial_seeds`): the same start headings; the behaviour's
draws from its own stream; the world (wheel slip, IR noise) from the fourth.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from stcvision.controllers.buffon.batched import TrialSet, VisitConfig, start_headings, trial_seeds
from stcvision.controllers.buffon.behaviour import Explorer
from stcvision.controllers.buffon.counter import LeakyIntegrator
from stcvision.controllers.buffon.nests import BODY_LENGTH_M, Nest
from stcvision.sim_camera.layers import PheromoneLayer
from stcvision.sim_camera.robot_sensors import SensorSuite
from stcvision.sim_camera.world import World

__all__ = ["run_trial_pymunk", "run_trials_pymunk"]


def _visit(nest, config, layer, pose, ss_world, beh_rng, *, lay: bool, progress=None):
    world = World(nest.arena, seed=ss_world, dt_s=config.dt_s, pheromone=layer)
    robot = world.add_robot(config.robot, pose=pose, sensors=False, record_trail=False)
    robot.sensors = SensorSuite(world, robot, ir=config.ir)
    explorer = Explorer(robot, beh_rng, config.behaviour)
    counter = LeakyIntegrator(params=config.counter)
    blind = 0
    if lay:
        robot.nozzle_on()
    for _ in range(config.visit_steps):
        explorer(world)
        world.step()
        if not lay:
            counter.update(robot.sensors.pheromone.read())
            blind += counter.above
    if progress is not None:
        progress(config.visit_steps)
    return robot.distance_travelled_m / BODY_LENGTH_M, counter.crossings, blind, world.containment_events


def run_trial_pymunk(nest: Nest, config: VisitConfig, seeds, *, progress=None) -> tuple[float, float, int, float, int]:
    """One trial with the four seed streams ``seeds``: (L1 u, L2 u, crossings, blind fraction,
    containment events)."""
    ss_start, ss_beh, _, ss_world = seeds
    h1, h2 = start_headings(np.random.default_rng(ss_start))
    beh = np.random.default_rng(ss_beh)
    w1, w2 = ss_world.spawn(2)
    layer = PheromoneLayer(nest.arena.bounds_m, width_m=config.trail_width_m)
    x, y = nest.start_xy
    l1, _, _, e1 = _visit(nest, config, layer, (x, y, h1), w1, beh, lay=True, progress=progress)
    l2, n, blind, e2 = _visit(nest, config, layer, (x, y, h2), w2, beh, lay=False, progress=progress)
    return l1, l2, n, blind / config.visit_steps, e1 + e2


def run_trials_pymunk(
    nest: Nest,
    config: VisitConfig | None = None,
    *,
    trials: int = 100,
    seed: int | np.random.SeedSequence = 0,
    progress: Callable[[int], None] | None = None,
) -> TrialSet:
    """``trials`` trials on the pymunk world (same result type as the batched path)."""
    config = config or VisitConfig()
    t0 = time.perf_counter()
    rows = [run_trial_pymunk(nest, config, s, progress=progress) for s in trial_seeds(seed, trials)]
    l1, l2, n, blind, esc = (np.array(c) for c in zip(*rows, strict=True))
    return TrialSet(
        l1, l2, n.astype(np.int64), blind, int(esc.sum()), 2 * trials * config.visit_steps, time.perf_counter() - t0
    )
