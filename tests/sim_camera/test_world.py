"""World physics: SI tolerances, no tunnelling, containment (acceptance criterion)."""

import dataclasses
import math

import numpy as np
import pytest

from stcvision.sim_camera.arenas import Barrier, CircleObstacle, SquareArena
from stcvision.sim_camera.robot import KHEPERA, LEGO_STC
from stcvision.sim_camera.world import World


def random_drive(world, robot, n_steps, rng, *, hold=(5, 60)):
    """Random wheel speeds (a third of the time at +-max) held for a random number of steps;
    returns the (n_steps, 2) true centre positions."""
    vmax = robot.params.max_wheel_speed_m_s
    pos = np.empty((n_steps, 2))
    left = 0
    for i in range(n_steps):
        if left == 0:
            if rng.random() < 1 / 3:
                wheels = rng.choice([-vmax, vmax], size=2)
            else:
                wheels = rng.uniform(-vmax, vmax, size=2)
            if rng.random() < 0.3:
                wheels = np.array([vmax, vmax])  # full speed ahead, into whatever is there
            robot.set_wheel_speeds(*wheels)
            left = int(rng.integers(*hold))
        left -= 1
        world.step()
        p = robot.body.position
        pos[i] = (p.x, p.y)
    return pos


def test_units_are_metres():
    w = World(SquareArena(side_m=1.0))
    assert w.space.collision_slop <= 1e-3  # pymunk's pixel default 0.1 would be 10 cm
    assert w.space.gravity == (0, 0)
    assert w.max_substep_travel_m <= 0.25 * 0.5 * w.arena.wall_thickness_m


@pytest.mark.slow
@pytest.mark.parametrize("name", ["circle", "square", "ellipse", "polygon", "board"])
def test_random_drive_never_leaves_arena(name, arenas):
    """Acceptance: 100,000 steps of random driving (at max speed a good part of the time) in
    each arena kind; the centre is inside ``arena.contains`` at every step, the guard never
    fires, and the body never sinks more than 2 mm into a wall."""
    arena = arenas[name]
    world = World(arena, seed=11)
    robot = world.add_robot(LEGO_STC, record_trail=False, sensors=False)
    pos = random_drive(world, robot, 100_000, np.random.default_rng(5))
    assert world.containment_events == 0
    assert arena.contains(pos).all()
    clearance = arena.clearance_m(pos[::7]) if name in ("ellipse", "polygon") else arena.clearance_m(pos)
    assert clearance.min() > LEGO_STC.radius_m - 0.002
    assert robot.distance_travelled_m > 100  # it really drove around


def test_wedged_between_obstacle_and_wall():
    """The only way north is a gap narrower than the robot between an obstacle and the east
    wall (a barrier closes the rest). Steered into the gap at full speed with random twists for
    20,000 steps, the robot neither squeezes through nor leaves the arena."""
    arena = SquareArena(side_m=1.0).with_parts(
        obstacles=(CircleObstacle(center_m=(0.36, 0.0), radius_m=0.1),),
        barriers=(Barrier(start_m=(-0.5, 0.0), end_m=(0.36, 0.0), thickness_m=0.02),),
    )
    gap = 0.5 - 0.46
    assert gap < 2 * LEGO_STC.radius_m
    world = World(arena, seed=2)
    robot = world.add_robot(LEGO_STC, pose=(0.0, -0.3, math.radians(30)), sensors=False)
    rng = np.random.default_rng(0)
    vmax = LEGO_STC.max_wheel_speed_m_s
    ys = np.empty(20_000)
    twist = 0.0
    for i in range(len(ys)):
        if i % 25 == 0:
            twist = rng.choice([0.0, 0.0, 0.5, -0.5, 1.0, -1.0])
        x, y, th = robot.pose
        err = (math.atan2(0.02 - y, 0.49 - x) - th + math.pi) % (2 * math.pi) - math.pi
        turn = float(np.clip(2.0 * err + twist, -1, 1)) * vmax
        robot.set_wheel_speeds(vmax - turn, vmax + turn)
        world.step()
        p = robot.body.position
        assert arena.contains_xy(p.x, p.y)
        ys[i] = p.y
    assert world.containment_events == 0
    assert ys.max() < 0.0  # never squeezed through to the north side of the gap
    # ... but it was pressed into the gap: touching wall and obstacle, the centre is at
    # x = 0.5 - r, y = -sqrt((0.1 + r)^2 - (0.5 - r - 0.36)^2) = -0.155
    wedged_y = -math.sqrt(0.17**2 - 0.07**2)
    assert ys[-5000:].max() == pytest.approx(wedged_y, abs=0.003)


def test_fast_robot_does_not_tunnel_through_thin_barrier():
    """Khepera at its 1 m/s limit (5 cm per step, 5x the barrier thickness) against a 1 cm
    barrier: the substeps keep every substep's travel under a quarter of the half-thickness."""
    arena = SquareArena(side_m=1.0).with_parts(
        barriers=(Barrier(start_m=(0.0, -0.45), end_m=(0.0, 0.45), thickness_m=0.01),)
    )
    world = World(arena, seed=0)
    robot = world.add_robot(KHEPERA, pose=(-0.3, 0.0, 0.0), sensors=False)
    robot.set_wheel_speeds(1.0, 1.0)
    for _ in range(200):
        world.step()
        assert robot.body.position.x < -0.005 - KHEPERA.radius_m + 2e-3
    assert world.containment_events == 0
    assert robot.body.position.x == pytest.approx(-0.005 - KHEPERA.radius_m, abs=1e-3)
    assert world.substeps_taken / world.step_count >= 0.05 / world.max_substep_travel_m


def test_guard_detects_and_repairs_an_escape():
    """The containment check can fail: teleport the body out and the guard counts and undoes it."""
    world = World(SquareArena(side_m=1.0), seed=0)
    robot = world.add_robot(LEGO_STC, pose=(0.0, 0.0, 0.0), sensors=False)
    world.step()
    robot.body.position = (3.0, 0.0)
    world.step()
    assert world.containment_events == 1
    assert world.arena.contains_xy(*robot.pose[:2])


def test_robots_collide_with_each_other():
    world = World(SquareArena(side_m=1.0), seed=0)
    a = world.add_robot(LEGO_STC, pose=(-0.2, 0.0, 0.0), sensors=False)
    b = world.add_robot(LEGO_STC, pose=(0.2, 0.0, math.pi), sensors=False)
    a.set_wheel_speeds(0.1, 0.1)
    b.set_wheel_speeds(0.1, 0.1)
    for _ in range(100):
        world.step()
        d = math.dist(a.pose[:2], b.pose[:2])
        assert d > 2 * LEGO_STC.radius_m - 0.006  # both approach: 2 substeps' travel


def test_add_robot_rejects_pose_in_wall():
    from stcvision.errors import BadInputError

    world = World(SquareArena(side_m=1.0))
    with pytest.raises(BadInputError, match="not a free spot"):
        world.add_robot(LEGO_STC, pose=(0.48, 0.0, 0.0))


def test_ideal_robot_follows_kinematics():
    """No errors configured: straight line and in-place turn match the unicycle model."""
    ideal = dataclasses.replace(LEGO_STC, ed=1.0, eb=1.0, slip_k=0.0, speed_gain_spread=0.0, battery_fade_per_h=0.0)
    world = World(SquareArena(side_m=3.0), seed=0)
    r = world.add_robot(ideal, pose=(0.0, 0.0, 0.0), sensors=False)
    r.set_wheel_speeds(0.1, 0.1)
    world.run(100)  # 5 s at 0.1 m/s
    assert r.pose[0] == pytest.approx(0.5, abs=1e-6) and abs(r.pose[1]) < 1e-9
    r.set_wheel_speeds(-0.06, 0.06)
    world.run(20)  # 1 s at 2 * 0.06 / 0.12 = 1 rad/s
    assert r.pose[2] == pytest.approx(1.0, abs=1e-6)
