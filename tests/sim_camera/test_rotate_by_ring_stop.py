"""Substrate additions for the TASTI 2 search robot (usable by every robot): a turn closed on the
odometry (``rotate_by``), a drive stopped by a sensor condition (``run_until_done(stop_when=)``)
and an external pose fix (``Odometry.correct``)."""

import dataclasses
import math

import numpy as np
import pytest

from stcvision.sim_camera.arenas import CircleObstacle, SquareArena
from stcvision.sim_camera.odometry import turn_heading_error_rad
from stcvision.sim_camera.robot import LEGO_STC, TASTI2
from stcvision.sim_camera.world import World

OPEN = SquareArena(side_m=4.0)


@pytest.mark.parametrize("params", [TASTI2, LEGO_STC])
@pytest.mark.parametrize("angle_deg", [90.0, -37.0, 180.0, 3.0])
def test_rotate_by_lands_on_the_odometric_angle_and_the_true_one_is_off_by_eb(params, angle_deg):
    """The odometry turns by the angle within one encoder count's heading step; the true turn is
    off by B&F's wheelbase error (true/odometric = 1/Eb) -- not by the motor gain (LEGO_STC's
    +-10 % gain would make a timed turn miss by up to 9 degrees)."""
    world = World(OPEN, seed=3)
    r = world.add_robot(dataclasses.replace(params, slip_k=0.0), pose=(0.0, 0.0, 0.0), sensors=False)
    a = math.radians(angle_deg)
    r.rotate_by(a)
    assert world.run_until_done(r).ok
    count_rad = math.pi * params.wheel_diameter_m / params.counts_per_rev / params.wheelbase_m
    assert r.odometry.theta == pytest.approx(a, abs=2 * count_rad)
    expected_true = r.odometry.theta + turn_heading_error_rad(r.odometry.theta, params.eb)
    assert r.pose[2] == pytest.approx(expected_true, abs=2 * count_rad + 1e-3)
    assert math.hypot(r.pose[0], r.pose[1]) < 1e-3  # in place


def test_ring_stops_a_drive_about_1_5_cm_from_a_can():
    """TASTI 2 drives at a steel can (radius 36.5 mm): ``stop_when`` = the capacitive ring's
    threshold halts it ~15 mm away (TASTI 2 paper sec. IV), status "stopped", no contact; without
    the condition the same drive ends "blocked" against the can."""
    can = CircleObstacle(center_m=(1.0, 0.0), radius_m=0.0365)
    arena = SquareArena(side_m=4.0, obstacles=(can,))
    for seed in range(3):
        world = World(arena, seed=seed)
        r = world.add_robot(TASTI2, pose=(0.0, 0.0, 0.0))
        r.drive_distance(1.5)
        res = world.run_until_done(r, stop_when=lambda w, r=r: r.sensors.capacitive.obstacle_ahead())
        assert res.status == "stopped" and not res.ok
        gap = 1.0 - 0.0365 - r.pose[0] - TASTI2.radius_m
        assert gap == pytest.approx(0.015, abs=0.004)
        assert 0.70 < res.odometric_distance_m < 0.85
    world = World(arena, seed=0)
    r = world.add_robot(TASTI2, pose=(0.0, 0.0, 0.0))
    r.drive_distance(1.5)
    assert world.run_until_done(r).status == "blocked"
    assert 1.0 - 0.0365 - r.pose[0] - TASTI2.radius_m < 0.002


def test_stop_when_already_true_does_not_move():
    world = World(OPEN, seed=0)
    r = world.add_robot(TASTI2, pose=(0.0, 0.0, 0.0))
    r.drive_distance(0.5)
    res = world.run_until_done(r, stop_when=lambda w: True)
    assert res.status == "stopped" and res.odometric_distance_m == 0.0
    assert r.pose[0] == 0.0 and not r.busy


def test_odometry_correct_keeps_the_counters_running():
    world = World(OPEN, seed=0)
    r = world.add_robot(TASTI2, pose=(0.0, 0.0, 0.0), sensors=False)
    r.drive_distance(0.3)
    world.run_until_done(r)
    d = r.odometry.distance_m
    r.odometry.correct((0.5, -0.2, 1.0))
    assert r.odometry.pose == (0.5, -0.2, 1.0) and r.odometry.distance_m == d
    r.drive_distance(0.1)
    assert world.run_until_done(r).ok
    assert np.allclose(r.odometry.pose[:2], (0.5 + 0.1 * math.cos(1.0), -0.2 + 0.1 * math.sin(1.0)), atol=2e-3)
