"""Differential-drive robot body: a dynamic pymunk circle driven by two wheels.

Commands are *nominal* wheel surface speeds in m/s (what the robot's motor controller is asked
for). The wheels actually turn at ``command * motor_gain(t)``, where the motor gain is drawn once
per robot (``speed_gain_spread``, e.g. +-10 %) and fades with battery charge
(``battery_fade_per_h``) -- the ant-like STC paper (Srour & Abboud): "Because of the battery
decay, and the fact that the robot is built from Lego, a 90 degree turn, wasn't actually 90
degree". Each wheel rolls ``rotation * true_radius`` plus slip noise; the body's velocity follows
from the true wheelbase (see :mod:`stcvision.sim_camera.odometry` for the error model).

Motion primitives are small state machines advanced by :meth:`World.step`:
``drive_distance`` (done when the odometry says so, or "blocked" when the motor stalls against
something), ``rotate_for`` (open loop: a timed turn, so its angle is off by the motor gain),
``rotate_by`` (closed loop on the odometry: done when the *odometric* heading has turned by the
angle, so the true angle is off only by what the odometry gets wrong, 1/Eb) and raw
``set_wheel_speeds``. ``World.run_until_done(robot, stop_when=...)`` steps until the primitive
ends, or until a sensor condition (e.g. the capacitive ring firing) stops it: status "stopped".

Presets (every number with its source; "assumed" means the papers give none):

* :data:`KHEPERA` -- the Buffon explorer (Buffon's needle paper, Girgin & Sahin, sec. 3). Diameter
  55 mm and wheelbase 53 mm (K-Team Khepera user manual); wheel diameter 15.6 mm and 150 encoder
  lines x 4 = 600 counts per revolution give the manual's ~12 counts per mm; top speed 1 m/s (K-Team
  spec).
* :data:`TASTI2` -- the chemical-search robot (the TASTI 2 paper by Russell, sec. IV). Body radius
  153 mm = the radius of its front capacitive ring; wheelbase 0.22 m, wheel diameter 65 mm, 128-line
  quadrature encoders, cruise speed 0.05 m/s: assumed. Ed = 1.002 and Eb = 1.01: assumed, the order
  of the uncalibrated errors Borenstein & Feng 1996 report for their platforms.
* :data:`LEGO_STC` -- the ant-like STC robot (the ant-like STC paper, Srour & Abboud). Radius 70 mm
  so it fits a 0.16 m sub-cell (the default board); LEGO 56 mm tyres; wheelbase 0.12 m; NXT-style
  motor encoders at 360 counts/rev; cruise 0.08 m/s; turn wheel speed 0.0628 m/s so a nominal
  90-degree turn takes 1.5 s (exactly: the wheel speed is derived from it); motor gain +-10 % per
  robot and 20 %/h battery fade (assumed; the paper gives only the qualitative statement above);
  Ed = 1.005, Eb = 1.03 (assumed: a flexible Lego frame).
* :data:`LEGO_STC_ROBOT` -- the same robot as the coverage loop's kinematic plant sees it
  (:class:`MarkingRobot`): motion from :data:`LEGO_STC`, LED-on time and timing cited there.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np
import pymunk

from stcvision.errors import BadInputError
from stcvision.sim_camera.odometry import Odometry, OdometryParams, WheelEncoders, true_wheel_diameters_m

__all__ = [
    "KHEPERA",
    "LEGO_STC",
    "LEGO_STC_ROBOT",
    "TASTI2",
    "DiffDriveParams",
    "DiffDriveRobot",
    "MarkingRobot",
    "MotionMode",
    "MotionResult",
]


@dataclass(frozen=True, kw_only=True, slots=True)
class DiffDriveParams:
    """Geometry, limits and error model of a differential-drive robot (SI units)."""

    name: str = "robot"
    radius_m: float  # collision radius of the body
    wheelbase_m: float  # nominal distance between the wheel contact points (odometry uses it)
    wheel_diameter_m: float  # nominal wheel diameter (odometry uses it)
    max_wheel_speed_m_s: float  # commands are clipped to +- this
    cruise_speed_m_s: float  # default speed of drive_distance
    turn_wheel_speed_m_s: float  # wheel speed of rotate_for (left -v, right +v for a left turn)
    encoder_lines_per_rev: int  # quadrature: 4 counts per line
    mass_kg: float = 0.5
    # true-vs-nominal (systematic) and random error, see stcvision.sim_camera.odometry
    ed: float = 1.0  # D_R / D_L (true)
    eb: float = 1.0  # b_true / b_nominal
    slip_k: float = 0.0  # m / sqrt(m): per-wheel travel noise std = slip_k * sqrt(|d|)
    speed_gain_spread: float = 0.0  # motor gain drawn once per robot from U(1 - s, 1 + s)
    battery_fade_per_h: float = 0.0  # motor gain loses this fraction per hour (floor 0.5)
    stall_time_s: float = 0.3  # drive_distance reports "blocked" after this long without progress

    def __post_init__(self):
        for k in (
            "radius_m",
            "wheelbase_m",
            "wheel_diameter_m",
            "max_wheel_speed_m_s",
            "cruise_speed_m_s",
            "turn_wheel_speed_m_s",
            "mass_kg",
            "ed",
            "eb",
        ):
            v = getattr(self, k)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise BadInputError(f"DiffDriveParams.{k} must be a positive number; got {v!r}")
        if not 0 <= self.speed_gain_spread < 1:
            raise BadInputError("DiffDriveParams.speed_gain_spread must be in [0, 1)")

    @property
    def nominal_turn_rate_rad_s(self) -> float:
        """Turn rate of rotate_for if the robot were exactly nominal: 2 v_turn / b."""
        return 2.0 * self.turn_wheel_speed_m_s / self.wheelbase_m

    @property
    def counts_per_rev(self) -> int:
        return 4 * self.encoder_lines_per_rev

    def odometry_params(self) -> OdometryParams:
        return OdometryParams(
            wheel_diameter_m=self.wheel_diameter_m,
            wheelbase_m=self.wheelbase_m,
            counts_per_rev=self.counts_per_rev,
        )


KHEPERA = DiffDriveParams(
    name="khepera",
    radius_m=0.0275,
    wheelbase_m=0.053,
    wheel_diameter_m=0.0156,
    max_wheel_speed_m_s=1.0,
    cruise_speed_m_s=0.1,
    turn_wheel_speed_m_s=0.05,
    encoder_lines_per_rev=150,
    mass_kg=0.08,
    slip_k=0.0005,
)
TASTI2 = DiffDriveParams(
    name="tasti2",
    radius_m=0.153,
    wheelbase_m=0.22,
    wheel_diameter_m=0.065,
    max_wheel_speed_m_s=0.15,
    cruise_speed_m_s=0.05,
    turn_wheel_speed_m_s=0.05,
    encoder_lines_per_rev=128,
    mass_kg=3.0,
    ed=1.002,
    eb=1.01,
    slip_k=0.001,
)
LEGO_STC = DiffDriveParams(
    name="lego_stc",
    radius_m=0.07,
    wheelbase_m=0.12,
    wheel_diameter_m=0.056,
    max_wheel_speed_m_s=0.15,
    cruise_speed_m_s=0.08,
    turn_wheel_speed_m_s=0.12 * (math.pi / 2) / (2 * 1.5),  # b x 90 deg / (2 x 1.5 s): 0.0628 m/s
    encoder_lines_per_rev=90,
    mass_kg=0.8,
    ed=1.005,
    eb=1.03,
    slip_k=0.002,
    speed_gain_spread=0.10,
    battery_fade_per_h=0.2,
)


class MotionMode(enum.Enum):
    IDLE = "idle"
    WHEELS = "wheels"  # raw wheel speeds until changed
    DRIVE = "drive"  # drive_distance in progress
    ROTATE = "rotate"  # rotate_for in progress


@dataclass(frozen=True, slots=True)
class MotionResult:
    """How a primitive ended: ``status`` is "done", "blocked" or "timeout"."""

    status: str
    odometric_distance_m: float
    duration_s: float

    @property
    def ok(self) -> bool:
        return self.status == "done"


class DiffDriveRobot:
    """A robot in a :class:`stcvision.sim_camera.world.World` (create it with ``world.add_robot``).

    State the rest of the sim reads: :attr:`pose` (true x, y, heading), :attr:`leds_lit` (the UV
    LEDs, read by the phosphor layer), :attr:`nozzle_open` (pheromone nozzle), :attr:`encoders`,
    :attr:`odometry` (the robot's own dead-reckoning estimate), :attr:`trail` (true positions).
    """

    def __init__(
        self,
        params: DiffDriveParams,
        pose: tuple[float, float, float],
        *,
        seed: np.random.SeedSequence,
        robot_id: int,
        record_trail: bool = True,
    ):
        self.params = params
        self.id = robot_id
        ss_params, ss_slip, self.sensor_seed = seed.spawn(3)
        prng = np.random.default_rng(ss_params)
        s = params.speed_gain_spread
        self.speed_gain = float(prng.uniform(1 - s, 1 + s)) if s > 0 else 1.0
        self._slip_rng = np.random.default_rng(ss_slip)
        self.wheel_diameters_m = true_wheel_diameters_m(params.wheel_diameter_m, params.ed)
        self.wheelbase_true_m = params.wheelbase_m * params.eb

        self.body = pymunk.Body(params.mass_kg, pymunk.moment_for_circle(params.mass_kg, 0, params.radius_m))
        self.body.position = (float(pose[0]), float(pose[1]))
        self.body.angle = float(pose[2])
        self.shape = pymunk.Circle(self.body, params.radius_m)
        self.shape.friction = 0.0
        self.shape.elasticity = 0.0
        self.shape.filter = pymunk.ShapeFilter(group=robot_id + 1)
        self.body.velocity_func = self._velocity_func

        self.encoders = WheelEncoders(params.encoder_lines_per_rev)
        self.odometry = Odometry(params.odometry_params(), pose)
        self.wheel_angles_rad = [0.0, 0.0]
        self.leds_lit = False  # UV LEDs state, read by the phosphor layer
        self.nozzle_open = False  # pheromone nozzle state
        self.record_trail = record_trail
        self.trail: list[tuple[float, float]] = [(float(pose[0]), float(pose[1]))]
        self.distance_travelled_m = 0.0  # true path length of the centre
        self.sensors = None  # set by World.add_robot (stcvision.sim_camera.robot_sensors.SensorSuite)

        self.mode = MotionMode.IDLE
        self._cmd = (0.0, 0.0)
        self._v = 0.0
        self._w = 0.0
        self._last_inside = (float(pose[0]), float(pose[1]), float(pose[2]))
        self._prim: dict = {}
        self.last_result: MotionResult | None = None
        # heading change of one encoder count on one wheel (what rotate_by can resolve)
        self._rad_per_count = math.pi * params.wheel_diameter_m / params.counts_per_rev / params.wheelbase_m

    # -- state -----------------------------------------------------------------------------
    @property
    def pose(self) -> tuple[float, float, float]:
        """True pose (x m, y m, heading rad) in the world frame."""
        p = self.body.position
        return (p.x, p.y, self.body.angle)

    @property
    def position(self) -> np.ndarray:
        p = self.body.position
        return np.array([p.x, p.y])

    @property
    def busy(self) -> bool:
        return self.mode in (MotionMode.DRIVE, MotionMode.ROTATE)

    def motor_gain(self, t_s: float) -> float:
        """Actual/commanded wheel speed at time ``t_s``: the per-robot gain times battery fade."""
        fade = max(0.5, 1.0 - self.params.battery_fade_per_h * t_s / 3600.0)
        return self.speed_gain * fade

    def true_turn_rate_rad_s(self, t_s: float) -> float:
        """The rate rotate_for really turns at time ``t_s`` (vs. ``params.nominal_turn_rate``)."""
        dl, dr = self.wheel_diameters_m
        dn = self.params.wheel_diameter_m
        v = self.params.turn_wheel_speed_m_s * self.motor_gain(t_s)
        return v * (dl + dr) / dn / self.wheelbase_true_m

    # -- commands --------------------------------------------------------------------------
    def set_wheel_speeds(self, left_m_s: float, right_m_s: float) -> None:
        """Command nominal wheel speeds (m/s, clipped to the limit); cancels any primitive."""
        m = self.params.max_wheel_speed_m_s
        self._cmd = (min(m, max(-m, float(left_m_s))), min(m, max(-m, float(right_m_s))))
        self.mode = MotionMode.WHEELS
        self._prim = {}

    def stop(self) -> None:
        self._cmd = (0.0, 0.0)
        self.mode = MotionMode.IDLE
        self._prim = {}

    def drive_distance(self, d_m: float, speed_m_s: float | None = None) -> None:
        """Start driving ``d_m`` metres straight (negative = backwards) by the odometry.
        Ends "done" when the odometric distance is reached or "blocked" on a motor stall."""
        v = self.params.cruise_speed_m_s if speed_m_s is None else float(speed_m_s)
        if not v > 0:
            raise BadInputError(f"drive_distance speed must be > 0; got {speed_m_s!r}")
        self.mode = MotionMode.DRIVE
        self.last_result = None
        self._prim = {
            "target": abs(float(d_m)),
            "sign": 1.0 if d_m >= 0 else -1.0,
            "speed": min(v, self.params.max_wheel_speed_m_s),
            "start_dist": self.odometry.distance_m,
            "t": 0.0,
            "stall": 0.0,
        }

    def rotate_for(self, duration_s: float, direction: int) -> None:
        """Start turning in place for ``duration_s`` (``direction`` +1 = left/counter-clockwise,
        -1 = right). Open loop: the angle is nominal_turn_rate * duration only for a nominal
        robot; this one turns at :meth:`true_turn_rate_rad_s`."""
        if direction not in (1, -1):
            raise BadInputError(f"rotate_for direction must be +1 or -1; got {direction!r}")
        if not duration_s >= 0:
            raise BadInputError(f"rotate_for duration must be >= 0; got {duration_s!r}")
        self.mode = MotionMode.ROTATE
        self.last_result = None
        self._prim = {
            "duration": float(duration_s),
            "dir": direction,
            "t": 0.0,
            "start_dist": self.odometry.distance_m,
        }

    def rotate_by(self, angle_rad: float) -> None:
        """Start turning in place until the *odometry* has turned by ``angle_rad`` (positive =
        left/counter-clockwise). Closed loop on the encoders: a motor gain error does not matter,
        a wheelbase error (Eb) and slip do -- the true turn is about ``angle_rad / Eb``."""
        a = float(angle_rad)
        if not math.isfinite(a):
            raise BadInputError(f"rotate_by angle must be a finite number; got {angle_rad!r}")
        self.mode = MotionMode.ROTATE
        self.last_result = None
        self._prim = {
            "target_rad": abs(a),
            "dir": 1 if a >= 0 else -1,
            "start_turned": self.odometry.turned_rad,
            "t": 0.0,
            "start_dist": self.odometry.distance_m,
        }

    def leds_on(self) -> None:
        """Switch the rear UV LEDs on (:attr:`leds_lit` is what the phosphor layer reads)."""
        self.leds_lit = True

    def leds_off(self) -> None:
        self.leds_lit = False

    def nozzle_on(self) -> None:
        """Open the pheromone nozzle: the world's pheromone layer records the trail."""
        self.nozzle_open = True

    def nozzle_off(self) -> None:
        self.nozzle_open = False

    # -- advanced by World.step ---------------------------------------------------------------
    def _finish(self, status: str) -> None:
        p = self._prim
        self.last_result = MotionResult(status, self.odometry.distance_m - p.get("start_dist", 0), p.get("t", 0.0))
        self.stop()

    def _pre_step(self, t_s: float, dt_s: float) -> float:
        """Work out this step's wheel motion; return the centre speed bound (m/s) for substeps."""
        p = self._prim
        if self.mode is MotionMode.DRIVE:
            remaining = p["target"] - (self.odometry.distance_m - p["start_dist"])
            # slow down on the last step so the odometric distance lands on the target
            v = p["sign"] * min(p["speed"], max(0.0, remaining) / dt_s)
            cmd = (v, v)
        elif self.mode is MotionMode.ROTATE:
            v_turn = self.params.turn_wheel_speed_m_s
            if "target_rad" in p:  # rotate_by: slow down on the last step to land on the angle
                left = p["target_rad"] - p["dir"] * (self.odometry.turned_rad - p["start_turned"])
                # (at least 10 % of the turn speed, so the encoders keep counting to the end)
                frac = min(1.0, max(0.1, left * 0.5 * self.params.wheelbase_m / (v_turn * dt_s)))
            else:
                frac = min(1.0, max(0.0, p["duration"] - p["t"]) / dt_s)
            w = p["dir"] * v_turn * frac
            cmd = (-w, w)
        else:
            cmd = self._cmd
        self._step_cmd = cmd
        g = self.motor_gain(t_s)
        half_dn = 0.5 * self.params.wheel_diameter_m
        dphi_l = cmd[0] / half_dn * g * dt_s
        dphi_r = cmd[1] / half_dn * g * dt_s
        self.wheel_angles_rad[0] += dphi_l
        self.wheel_angles_rad[1] += dphi_r
        dl = dphi_l * 0.5 * self.wheel_diameters_m[0]
        dr = dphi_r * 0.5 * self.wheel_diameters_m[1]
        k = self.params.slip_k
        if k > 0 and (dl != 0 or dr != 0):
            n = self._slip_rng.standard_normal(2)
            dl += k * math.sqrt(abs(dl)) * n[0]
            dr += k * math.sqrt(abs(dr)) * n[1]
        self._v = 0.5 * (dl + dr) / dt_s
        self._w = (dr - dl) / (self.wheelbase_true_m * dt_s)
        self._pos_before = self.body.position
        # Without contacts, start the step at the commanded velocity (no one-substep lag); in
        # contact, keep the solver's corrected velocity from the last substep.
        touching = []
        self.body.each_arbiter(touching.append)
        if not touching:
            self._velocity_func(self.body, None, 1.0, dt_s)
        return abs(self._v)

    def _velocity_func(self, body, gravity, damping, dt) -> None:
        """pymunk velocity callback, run inside every substep *before* the contact solver: the
        wheels set the velocity, contacts then correct it, and the corrected velocity moves the
        body in the next substep (so a wall is never driven into; cf. Chipmunk's step order:
        integrate positions, collide, integrate velocities, solve)."""
        a = body.angle
        body.velocity = (self._v * math.cos(a), self._v * math.sin(a))
        body.angular_velocity = self._w

    def _post_step(self, dt_s: float) -> None:
        pos = self.body.position
        moved = math.hypot(pos.x - self._pos_before.x, pos.y - self._pos_before.y)
        self.distance_travelled_m += moved
        if self.record_trail:
            self.trail.append((pos.x, pos.y))
        self.odometry.update(self.encoders.update(*self.wheel_angles_rad))
        p = self._prim
        if self.mode is MotionMode.DRIVE:
            p["t"] += dt_s
            expected = abs(self._step_cmd[0]) * dt_s
            # motor stall (current sensing on a real robot): the body barely moves
            p["stall"] = p["stall"] + dt_s if expected > 0 and moved < 0.3 * expected else 0.0
            if self.odometry.distance_m - p["start_dist"] >= p["target"] - 1e-9:
                self._finish("done")
            elif p["stall"] >= self.params.stall_time_s:
                self._finish("blocked")
        elif self.mode is MotionMode.ROTATE:
            p["t"] += dt_s
            if "target_rad" in p:
                turned = p["dir"] * (self.odometry.turned_rad - p["start_turned"])
                # within one encoder count's heading step of the target: done
                if turned >= p["target_rad"] - self._rad_per_count:
                    self._finish("done")
            elif p["t"] >= p["duration"] - 1e-12:
                self._finish("done")


@dataclass(frozen=True, kw_only=True, slots=True)
class MarkingRobot:
    """A robot that marks the floor as it covers it (the ant-like STC robot), as the coverage
    loop's kinematic plant sees it: one sub-cell per forward move, timed 90-degree turns.

    :meth:`from_body` takes the motion figures from a :class:`DiffDriveParams` preset (one source
    for every number); a JSON profile gives them directly (:mod:`stcvision.sim_camera.hardware`)."""

    name: str
    drive_speed_m_s: float  # cruise speed of a forward move
    turn_90_s: float  # a nominal robot's 90-degree timed turn
    rate_spread: float  # turn rate off nominal by U(-s, s) per robot (motor gain)
    fade_per_h: float  # the turn rate fades by this fraction per hour (battery; floor 0.5)
    led_on_s: float  # rear UV LEDs on before every forward move
    drive_sigma_m: float  # distance error of one forward move (1 sigma)
    initial_turn_error: float  # the turn time T set before the run is off by this (1 sigma, relative)
    settle_s: float  # stop, take a webcam frame and decide
    #: where each figure comes from (figure name -> citation)
    sources: tuple[tuple[str, str], ...] = ()

    def __post_init__(self):
        for k in ("drive_speed_m_s", "turn_90_s", "led_on_s"):
            v = getattr(self, k)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise BadInputError(f"robot {self.name!r}: {k} must be a positive number; got {v!r}")
        for k in ("rate_spread", "fade_per_h", "drive_sigma_m", "initial_turn_error", "settle_s"):
            v = getattr(self, k)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise BadInputError(f"robot {self.name!r}: {k} must be a number >= 0; got {v!r}")
        if self.rate_spread >= 1:
            raise BadInputError(f"robot {self.name!r}: rate_spread must be below 1; got {self.rate_spread}")

    @classmethod
    def from_body(cls, body: DiffDriveParams, **kw) -> MarkingRobot:
        """The cruise speed, the nominal 90-degree turn (``pi / 2`` over
        :attr:`DiffDriveParams.nominal_turn_rate_rad_s`), the motor gain spread and the battery
        fade from ``body``; the rest from ``kw``."""
        return cls(
            name=kw.pop("name", body.name),
            drive_speed_m_s=body.cruise_speed_m_s,
            turn_90_s=(math.pi / 2) / body.nominal_turn_rate_rad_s,
            rate_spread=body.speed_gain_spread,
            fade_per_h=body.battery_fade_per_h,
            **kw,
        )


#: The Lego robot of the ant-like STC paper (Srour & Abboud) for the coverage loop: motion from
#: :data:`LEGO_STC` (see the module docstring for its sources), marking and timing figures cited
#: below.
LEGO_STC_ROBOT = MarkingRobot.from_body(
    LEGO_STC,
    name="lego",
    led_on_s=3.0,
    drive_sigma_m=0.002,
    initial_turn_error=0.01,
    settle_s=0.3,
    sources=(
        ("drive_speed_m_s", "LEGO_STC.cruise_speed_m_s (assumed: a slow Lego robot, 2 s per 16 cm sub-cell)"),
        ("turn_90_s", "LEGO_STC: 1.5 s (assumed), its turn wheel speed over its 0.12 m wheelbase"),
        (
            "rate_spread",
            "LEGO_STC.speed_gain_spread (assumed; Srour & Abboud: 'a 90 degree turn, wasn't actually 90 degree')",
        ),
        ("fade_per_h", "LEGO_STC.battery_fade_per_h (assumed; Srour & Abboud: 'Because of the battery decay')"),
        ("led_on_s", "Srour & Abboud: the rear UV LEDs are switched on 'for a few seconds'"),
        ("drive_sigma_m", "assumed: 2 mm per 16 cm move (a Lego frame on wheels, no encoder feedback)"),
        (
            "initial_turn_error",
            "Srour & Abboud: 'We initially set T to a time that let's the robot do the first rotation accurate "
            "enough' -- 1 % assumed",
        ),
        ("settle_s", "assumed: stop, one webcam frame (1/30 s) and the pipeline"),
    ),
)
