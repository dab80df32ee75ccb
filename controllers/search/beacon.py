"""Beyond the paper (the TASTI 2 paper by Russell, sec. VI: "drop off one or more beacons at the
start of the search and ... use this/them to correct subsequent odometry errors"), with this
toolkit's own means.

TASTI 2 carries the catadioptric camera of :mod:`sim_camera` and drops at the start a flat bar
with two red LEDs ``separation_m`` apart, centred on the start point and lying along the start
heading (the same red lights the STC robot's camera reads). After a move, when the robot
*believes* it is within ``max_range_m`` of the beacon, it takes one frame: the frame is rendered
at the robot's **true** pose (:meth:`stcvision.sim_camera.camera.SyntheticCamera.render`, noise, dark
frame) and read by the vision pipeline (:class:`stcvision.pipeline.Pipeline`, its red-light
search ``find_red`` on the ground view); the two lights' robot-frame positions and their known
places give the robot's position and heading (which light is which: the assignment nearer the
odometric heading). A fix is used only if exactly two lights are seen, their distance apart is
the bar's within ``separation_tol_m``, and it moves the estimate by less than ``max_jump_m`` and
``max_turn_rad``; otherwise the robot keeps dead reckoning (a frame it cannot trust is ignored).

Measured on rendered frames: both lights are found from 0.1 to about 0.5 m (none under the
camera, one of two beyond), each within ~1-5 mm. With 0.2 m between the lights one frame's
heading is good to about a degree, against TASTI 2's odometry losing ~1 % of every turn (Eb).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stcvision.angles import wrap_angle

__all__ = ["Beacon", "BeaconFix", "BeaconFixer", "pose_from_two_lights"]


@dataclass(frozen=True, slots=True)
class BeaconFix:
    x_m: float
    y_m: float
    heading_rad: float

    def as_tuple(self) -> tuple[float, float, float]:
        return (self.x_m, self.y_m, self.heading_rad)


@dataclass(frozen=True, kw_only=True, slots=True)
class Beacon:
    """The two-light bar at ``center_m`` along ``heading_rad`` (start frame)."""

    center_m: tuple[float, float] = (0.0, 0.0)
    heading_rad: float = 0.0
    separation_m: float = 0.20
    min_range_m: float = 0.12  # the camera does not see the floor under itself
    max_range_m: float = 0.45  # both lights found out to ~0.5 m (measured, module doc)
    separation_tol_m: float = 0.015
    max_jump_m: float = 0.30
    max_turn_rad: float = math.radians(20.0)

    def lights_m(self) -> np.ndarray:
        """(2, 2) world positions of the two LEDs."""
        h = 0.5 * self.separation_m * np.array([math.cos(self.heading_rad), math.sin(self.heading_rad)])
        c = np.asarray(self.center_m, float)
        return np.array([c - h, c + h])

    def fixer(self, world, robot, seed: np.random.SeedSequence) -> BeaconFixer:
        return BeaconFixer(self, world, robot, seed)


def pose_from_two_lights(seen_robot_m: np.ndarray, lights_m: np.ndarray, heading_hint_rad: float):
    """Robot pose (x, y, heading) from two lights seen at ``seen_robot_m`` (2, 2) in the robot
    frame (x forward, y left) whose world places are ``lights_m`` (2, 2); of the two ways to
    pair them the one whose heading is nearer ``heading_hint_rad``."""
    best = None
    for o in (seen_robot_m, seen_robot_m[::-1]):
        dw, do = lights_m[1] - lights_m[0], o[1] - o[0]
        th = math.atan2(dw[1], dw[0]) - math.atan2(do[1], do[0])
        off = abs(wrap_angle(th - heading_hint_rad))
        if best is None or off < best[0]:
            c, s = math.cos(th), math.sin(th)
            mo = o.mean(axis=0)
            pos = lights_m.mean(axis=0) - np.array([c * mo[0] - s * mo[1], s * mo[0] + c * mo[1]])
            th_w = heading_hint_rad + wrap_angle(th - heading_hint_rad)
            best = (off, (float(pos[0]), float(pos[1]), th_w))
    return best[1]


class BeaconFixer:
    """The camera, its dark frame and the pipeline of one run (built once, applied per move)."""

    def __init__(self, beacon: Beacon, world, robot, seed: np.random.SeedSequence):
        from stcvision.calibration.profiles import default_profile
        from stcvision.pipeline import Pipeline
        from stcvision.sim_camera.camera import SyntheticCamera

        ss_pattern, ss_noise = seed.spawn(2)
        self.beacon, self.world, self.robot = beacon, world, robot
        self.lights = beacon.lights_m()
        self.camera = SyntheticCamera(pattern_seed=int(ss_pattern.generate_state(1)[0]))
        self.rng = np.random.default_rng(ss_noise)
        self.profile = default_profile()
        self.pipeline = Pipeline(self.profile, dark=self.camera.median_dark(8, rng=self.rng))
        self.last_result = None  # the pipeline's last result (for a recorder)

    def fix(self) -> BeaconFix | None:
        from stcvision.sim_camera.camera import Pose

        b = self.beacon
        x, y, th = self.robot.odometry.pose
        d = math.hypot(x - b.center_m[0], y - b.center_m[1])
        if not b.min_range_m <= d <= b.max_range_m:
            return None
        frame = self.camera.render(Pose(*self.robot.pose), rng=self.rng, red_lights_m=self.lights)
        res = self.pipeline.process(frame.image)
        self.last_result = res
        if len(res.red) != 2:
            return None
        seen = self.profile.ground_to_robot(res.red.xy_px)
        if abs(float(np.hypot(*(seen[1] - seen[0]))) - b.separation_m) > b.separation_tol_m:
            return None
        fx, fy, fth = pose_from_two_lights(seen, self.lights, th)
        if math.hypot(fx - x, fy - y) > b.max_jump_m or abs(fth - th) > b.max_turn_rad:
            return None
        return BeaconFix(fx, fy, fth)
