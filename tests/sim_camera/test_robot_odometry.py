"""Motion primitives and the dead-reckoning error model (Borenstein & Feng 1996)."""

import dataclasses
import math

import numpy as np
import pytest

from stcvision.sim_camera.arenas import SquareArena
from stcvision.sim_camera.odometry import (
    straight_heading_error_rad,
    straight_heading_sigma_rad,
    turn_heading_error_rad,
)
from stcvision.sim_camera.robot import KHEPERA, LEGO_STC, TASTI2
from stcvision.sim_camera.world import World

OPEN = SquareArena(side_m=4.0)


def test_drive_distance_done_and_blocked():
    world = World(OPEN, seed=0)
    r = world.add_robot(LEGO_STC, pose=(0.0, 0.0, 0.0), sensors=False)
    r.drive_distance(0.5)
    res = world.run_until_done(r)
    assert res.status == "done"
    assert res.odometric_distance_m == pytest.approx(0.5, abs=0.002)
    assert r.pose[0] == pytest.approx(0.5, abs=0.02)  # truth: slip/Ed errors only
    r.drive_distance(5.0)  # into the east wall at x = 2
    res = world.run_until_done(r, timeout_s=100)
    assert res.status == "blocked"
    assert r.pose[0] == pytest.approx(2.0 - LEGO_STC.radius_m, abs=0.002)
    r.drive_distance(-0.3)
    assert world.run_until_done(r).ok


def test_rotate_for_is_off_nominal_per_robot_and_drifts_with_battery():
    """The 90-degree timed turn of the ant-like STC paper: the angle turned is the robot's true
    rate x duration; rates differ per robot by up to +-10 % and fade with the battery."""
    turn_s = (math.pi / 2) / LEGO_STC.nominal_turn_rate_rad_s
    assert 1.0 <= turn_s <= 2.0
    angles = []
    for seed in range(8):
        world = World(OPEN, seed=seed)
        r = world.add_robot(LEGO_STC, pose=(0.0, 0.0, 0.0), sensors=False)
        expected = r.true_turn_rate_rad_s(0.0) * turn_s
        r.rotate_for(turn_s, +1)
        assert world.run_until_done(r).ok
        assert r.pose[2] == pytest.approx(expected, abs=0.035)  # slip: sigma ~0.007 rad
        angles.append(r.pose[2])
        assert 0.85 < r.pose[2] / (math.pi / 2) < 1.15
        r.rotate_for(turn_s, -1)
        world.run_until_done(r)
        assert abs(r.pose[2]) < 0.05  # back where it started (same gain both ways)
        # an hour later, the battery has faded 20 %: the same timed turn falls short
        assert r.true_turn_rate_rad_s(3600.0) == pytest.approx(0.8 * r.true_turn_rate_rad_s(0.0))
    assert np.std(angles) > 0.01  # robots differ


def test_leds_and_nozzle_state():
    world = World(OPEN, seed=0)
    r = world.add_robot(LEGO_STC, pose=(0.0, 0.0, 0.0), sensors=False)
    assert not r.leds_lit
    r.leds_on()
    assert r.leds_lit
    r.leds_off()
    assert not r.leds_lit
    r.nozzle_on()
    assert r.nozzle_open


def test_encoder_counts_match_wheel_rotation():
    ideal = dataclasses.replace(KHEPERA, slip_k=0.0)
    world = World(OPEN, seed=0)
    r = world.add_robot(ideal, pose=(0.0, 0.0, 0.0), sensors=False)
    r.drive_distance(0.2)
    world.run_until_done(r)
    # Khepera: 600 counts per revolution of a 15.6 mm wheel, about 12 counts per mm
    per_mm = 600 / (math.pi * 15.6)
    assert r.encoders.counts_per_rev == 600
    assert r.encoders.counts[0] == pytest.approx(200 * per_mm, abs=2)
    assert r.encoders.counts == (r.encoders.counts[0], r.encoders.counts[1])


def _runs(params, n, body):
    out = []
    for seed in range(n):
        world = World(SquareArena(side_m=6.0), seed=seed)
        r = world.add_robot(params, pose=(-1.5, 0.0, 0.0), sensors=False)
        out.append(body(world, r))
    return np.array(out)


def test_straight_run_heading_drift_matches_ed_model():
    """1 m commanded straight, 40 seeded runs: mean (true - odometric) heading vs. the closed
    form 2 d (Ed - 1) / ((Ed + 1) b) within 3 standard errors + 2 %; spread vs. the slip model
    sqrt(2 d) k / b within 30 %."""
    p = dataclasses.replace(TASTI2, ed=1.01, eb=1.0, slip_k=0.002, cruise_speed_m_s=0.1)

    def body(world, r):
        r.drive_distance(1.0)
        assert world.run_until_done(r).ok
        return r.pose[2] - r.odometry.theta

    err = _runs(p, 40, body)
    b_true = p.wheelbase_m * p.eb
    mean_pred = straight_heading_error_rad(1.0, p.ed, b_true)
    sd_pred = straight_heading_sigma_rad(1.0, p.slip_k, b_true)
    assert mean_pred == pytest.approx(0.0452, abs=1e-3)
    assert abs(err.mean() - mean_pred) < 3 * sd_pred / math.sqrt(len(err)) + 0.02 * mean_pred
    assert err.std(ddof=1) == pytest.approx(sd_pred, rel=0.3)


def test_full_turn_error_matches_eb_model():
    """A 360-degree turn in place by the odometry, 30 runs: true - odometric heading vs.
    2 pi (1/Eb - 1) within 3 standard errors + 2 %."""
    p = dataclasses.replace(TASTI2, ed=1.0, eb=1.03, slip_k=0.001)

    def body(world, r):
        v = p.turn_wheel_speed_m_s
        r.set_wheel_speeds(-v, v)
        while r.odometry.turned_rad < 2 * math.pi:
            world.step()
        r.stop()
        return r.pose[2] - r.odometry.theta, r.odometry.turned_rad

    res = _runs(p, 30, body)
    err, odo = res[:, 0], res[:, 1]
    pred = np.array([turn_heading_error_rad(a, p.eb) for a in odo])
    assert pred.mean() == pytest.approx(2 * math.pi * (1 / 1.03 - 1), rel=0.02)
    wheel_d = math.pi * p.wheelbase_m  # each wheel rolls half the turn circle's circumference
    sd = straight_heading_sigma_rad(wheel_d, p.slip_k, p.wheelbase_m * p.eb)
    assert abs((err - pred).mean()) < 3 * sd / math.sqrt(len(err)) + 0.02 * abs(pred.mean())
    assert (err - pred).std(ddof=1) == pytest.approx(sd, rel=0.35)


def test_no_error_configured_means_exact_dead_reckoning():
    p = dataclasses.replace(LEGO_STC, ed=1.0, eb=1.0, slip_k=0.0)
    world = World(OPEN, seed=0)
    r = world.add_robot(p, pose=(0.0, 0.0, 0.0), sensors=False)
    r.drive_distance(1.0)
    world.run_until_done(r)
    r.rotate_for(1.5, 1)
    world.run_until_done(r)
    r.drive_distance(0.5)
    world.run_until_done(r)
    pos_err, head_err = r.odometry.error_to(r.pose)
    assert pos_err < 0.001 and abs(head_err) < 0.002  # encoder quantisation only
