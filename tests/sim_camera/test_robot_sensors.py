"""IR, capacitive ring, tongue, pheromone detector + leaky integrator, floor layers."""

import dataclasses
import math

import numpy as np
import pytest

from stcvision.controllers.buffon.counter import LeakyIntegrator
from stcvision.sim_camera.arenas import CircleObstacle, SquareArena
from stcvision.sim_camera.layers import ChemicalLayer, ChemicalPatch, PheromoneLayer, PolygonPatch
from stcvision.sim_camera.robot import KHEPERA, TASTI2
from stcvision.sim_camera.robot_sensors import (
    CapacitiveRingParams,
    IrParams,
    IrSensors,
    capacitive_signal_for_can,
    ir_response,
)
from stcvision.sim_camera.world import World


def test_ir_response_curve():
    p = IrParams()
    assert ir_response([0.0, 0.005, 0.05, 0.2, np.inf], p) == pytest.approx([1, 1, 0, 0, 0])
    mid = ir_response(0.0275, p)
    assert mid == pytest.approx(0.25)
    d = np.linspace(0, 0.06, 50)
    assert np.all(np.diff(ir_response(d, p)) <= 0)  # monotone


def test_ir_sees_wall_at_the_right_distance_and_side():
    """Khepera 20 mm from the east wall, facing it: the two front sensors read I(20 mm), the
    90-degree side sensors see nothing; turned so the wall is on the left, sensor 0 reads it."""
    world = World(SquareArena(side_m=1.0), seed=0)
    x = 0.5 - 0.02 - KHEPERA.radius_m
    r = world.add_robot(KHEPERA, pose=(x, 0.0, 0.0))
    ir = IrSensors(world, r, dataclasses.replace(IrParams(), noise_sigma=0.0), np.random.default_rng(0))
    d = ir.distances_m()
    assert d[2] == pytest.approx(d[3], abs=1e-9)
    assert d[2] == pytest.approx(0.02 + KHEPERA.radius_m * (1 - math.cos(math.radians(10))), abs=3e-3)
    reading = ir.read()
    assert reading[2] == pytest.approx(ir_response(d[2]), abs=1e-12)
    assert reading[0] == 0 and reading[5] == 0
    r.body.angle = -math.pi / 2  # heading south: the east wall is on the left
    assert ir.read()[0] == pytest.approx(ir_response(0.02), abs=1e-6)
    # noisy sensor: zero-mean noise of the configured sigma, clipped to [0, 1]
    r.body.angle = 0.0
    noisy = np.array([r.sensors.ir.read() for _ in range(400)])
    assert noisy.min() >= 0 and noisy.max() <= 1
    assert noisy[:, 2].std() == pytest.approx(IrParams().noise_sigma, rel=0.2)
    assert noisy[:, 2].mean() == pytest.approx(ir_response(d[2]), abs=0.006)


def test_capacitive_ring_stops_tasti2_15mm_from_a_can():
    """TASTI 2 drives at a steel can and halts when the ring's signal crosses its threshold:
    the gap between ring (radius 153 mm) and can is 1.5 cm (TASTI 2 paper sec. IV) within 3 mm."""
    can = CircleObstacle(center_m=(0.5, 0.0), radius_m=CapacitiveRingParams().reference_can_radius_m)
    world = World(SquareArena(side_m=2.0).with_parts(obstacles=(can,)), seed=0)
    r = world.add_robot(TASTI2, pose=(-0.4, 0.0, 0.0))
    ring = r.sensors.capacitive
    assert ring.params.ring_radius_m == pytest.approx(0.153)
    assert ring.params.n_electrodes == 9
    assert math.degrees(ring.params.electrode_span_rad * ring.params.n_electrodes) == pytest.approx(180)
    assert ring.read() < 0.1 * ring.stop_threshold  # far away: nothing
    r.set_wheel_speeds(0.05, 0.05)
    for _ in range(2000):
        if ring.obstacle_ahead():
            r.stop()
            break
        world.step()
    gap = math.dist(r.pose[:2], can.center_m) - can.radius_m - 0.153
    assert gap == pytest.approx(0.015, abs=0.003)
    # the pure-geometry signal and the (noise-free) ray-cast signal agree
    from stcvision.sim_camera.robot_sensors import _signal_from_gaps

    geo = capacitive_signal_for_can(gap, ring.params)
    # (TASTI 2 has Ed = 1.002, so it arrives slightly off-axis: 5 %)
    assert geo == pytest.approx(_signal_from_gaps(ring.gaps_m(), ring.params), rel=0.05)


def test_tongue_reads_salt_patch():
    world = World(
        SquareArena(side_m=2.0),
        seed=0,
        chemical=ChemicalLayer([ChemicalPatch(center_m=(0.5, 0.0), concentration=1.0)]),
    )
    r = world.add_robot(TASTI2, pose=(0.0, 0.0, 0.0))
    off = np.mean([r.sensors.tongue.read() for _ in range(50)])
    r.body.position = (0.6, 0.1)  # inside the 350 mm patch
    on = np.mean([r.sensors.tongue.read() for _ in range(50)])
    assert off == pytest.approx(0.0, abs=0.01) and on == pytest.approx(1.0, abs=0.01)


def test_chemical_layer_shapes():
    layer = ChemicalLayer(
        [
            ChemicalPatch(center_m=(0, 0), radius_m=0.175, edge_m=0.1),
            PolygonPatch(vertices_m=((1, 0), (2, 0), (2, 1), (1, 1)), concentration=2.0),
        ]
    )
    c = layer.concentration([[0, 0], [0.225, 0], [0.3, 0], [1.5, 0.5], [3, 3]])
    assert c == pytest.approx([1.0, 0.5, 0.0, 2.0, 0.0])


def test_pheromone_trail_width_and_area():
    layer = PheromoneLayer((0, 0, 1, 1), width_m=0.0055)  # 0.1 Khepera body length
    layer.deposit_segment((0.1, 0.5), (0.9, 0.5))
    assert layer.marked_area_m2 == pytest.approx(0.8 * 0.0055, rel=0.15)
    half, c = 0.5 * layer.width_m, layer.cell_m
    ys = np.array([0.5, 0.5 + half - c, 0.5 + half + c, 0.5 - half - c])
    got = layer.read(np.c_[np.full(4, 0.5), ys])
    assert list(got) == [True, True, False, False]
    assert not layer.read([[2.0, 2.0]])[0]  # off the grid


def test_leaky_integrator_counts_crossings_not_blips():
    li = LeakyIntegrator()
    seq = [0] * 10 + [1] + [0] * 10 + [1] * 5 + [0] * 20 + [1] * 4 + [0] * 10
    hits = [li.update(x) for x in seq]
    assert li.crossings == 2 and sum(hits) == 2


def test_pheromone_detector_counts_trail_crossings():
    """Lay a north-south trail, then drive east across it twice: two crossings counted."""
    ph = PheromoneLayer((-1, -1, 1, 1), width_m=0.0055)
    world = World(SquareArena(side_m=2.0), seed=0, pheromone=ph)
    r = world.add_robot(KHEPERA, pose=(0.0, -0.5, math.pi / 2))
    r.nozzle_on()
    r.drive_distance(1.0)
    world.run_until_done(r)
    r.nozzle_off()
    assert ph.marked_area_m2 == pytest.approx(1.0 * 0.0055, rel=0.2)
    li = LeakyIntegrator()
    for y in (-0.2, 0.3):
        r.body.position, r.body.angle = (-0.3, y), 0.0
        r.odometry.reset(r.pose, r.encoders.counts)
        r.drive_distance(0.6, speed_m_s=0.02)  # 1 mm per step across a 5.5 mm trail
        while r.busy:
            world.step()
            li.update(r.sensors.pheromone.read())
    assert li.crossings == 2
