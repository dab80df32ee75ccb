"""Wheel encoders and dead reckoning with systematic and random error.

Error model (Borenstein & Feng 1996, "Measurement and correction of systematic odometry errors in
mobile robots", IEEE T-RA 12(6), ref. [10] of the TASTI 2 paper by Russell):

* **Ed** = D_R / D_L, the ratio of the *true* right and left wheel diameters. Their mean equals
  the nominal diameter D_n that the odometry assumes, so D_L = 2 D_n / (Ed + 1) and
  D_R = 2 D_n Ed / (Ed + 1) (B&F eq. 3).
* **Eb** = b_true / b_nominal, the ratio of the true (effective) wheelbase to the one the odometry
  assumes.
* **random error**: each wheel's ground travel in a step differs from its rotation times its true
  radius by a zero-mean Gaussian with variance ``slip_k^2 |d|`` (non-systematic slip; variance
  growing linearly with distance, the usual model of Chong & Kleeman 1997), plus encoder
  quantisation (whole counts only).

The robot's encoders count true wheel *rotation* (what the shaft does); the odometry turns counts
into distances with the nominal diameter and into heading with the nominal wheelbase. So it
drifts: a commanded straight run curves by :func:`straight_heading_error_rad` and a turn in
place is off by :func:`turn_heading_error_rad`. Collisions add error too: when a robot pushes
against a wall its wheels keep turning (slip) while the body stays, which is how the TASTI 2 seed
sec. V describes it ("collisions introduce significant inaccuracy").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from stcvision.angles import wrap_angle

__all__ = [
    "Odometry",
    "OdometryParams",
    "WheelEncoders",
    "straight_heading_error_rad",
    "straight_heading_sigma_rad",
    "true_wheel_diameters_m",
    "turn_heading_error_rad",
]


def true_wheel_diameters_m(nominal_m: float, ed: float) -> tuple[float, float]:
    """(D_L, D_R) for a diameter ratio ``ed`` = D_R/D_L whose mean is ``nominal_m`` (B&F eq. 3)."""
    return (2.0 * nominal_m / (ed + 1.0), 2.0 * nominal_m * ed / (ed + 1.0))


def straight_heading_error_rad(distance_m: float, ed: float, wheelbase_true_m: float) -> float:
    """True minus odometric heading after a straight run of odometric length ``distance_m``.

    Both wheels turn by the same angle phi = d / (D_n/2) (the odometry sees equal counts and
    reports heading 0), but they roll different distances: (D_R - D_L) phi / 2 over the true
    wheelbase gives the true heading change 2 d (Ed - 1) / ((Ed + 1) b_true).
    """
    return 2.0 * distance_m * (ed - 1.0) / ((ed + 1.0) * wheelbase_true_m)


def straight_heading_sigma_rad(distance_m: float, slip_k: float, wheelbase_true_m: float) -> float:
    """Standard deviation of the heading error of a straight run caused by slip alone:
    delta_theta = (delta_d_R - delta_d_L) / b with each variance ``slip_k^2 d``."""
    return math.sqrt(2.0 * distance_m) * slip_k / wheelbase_true_m


def turn_heading_error_rad(odometric_angle_rad: float, eb: float) -> float:
    """True minus odometric heading change of an in-place turn the odometry measures as
    ``odometric_angle_rad`` (wheels turning equal and opposite): true/odometric = 1/Eb."""
    return odometric_angle_rad * (1.0 / eb - 1.0)


@dataclass(frozen=True, kw_only=True, slots=True)
class OdometryParams:
    """What the robot *believes* about itself (the nominal geometry)."""

    wheel_diameter_m: float
    wheelbase_m: float
    counts_per_rev: int


class WheelEncoders:
    """Quadrature wheel encoders: ``lines_per_rev`` slots, 4 counts per slot (both edges of both
    phases, as TASTI 2's two-phase quadrature encoder, TASTI 2 paper sec. IV).

    Counts are whole numbers of the true wheel rotation (quantisation is the encoder's random
    error); the robot advances the wheel angles, this class only reads them.
    """

    def __init__(self, lines_per_rev: int):
        if lines_per_rev <= 0:
            raise ValueError("lines_per_rev must be > 0")
        self.counts_per_rev = 4 * int(lines_per_rev)
        self._k = self.counts_per_rev / (2.0 * math.pi)
        self.counts = (0, 0)

    def update(self, wheel_angle_left_rad: float, wheel_angle_right_rad: float) -> tuple[int, int]:
        """Return the cumulative (left, right) counts for the given true wheel angles."""
        self.counts = (
            math.floor(wheel_angle_left_rad * self._k),
            math.floor(wheel_angle_right_rad * self._k),
        )
        return self.counts


class Odometry:
    """Dead reckoning from cumulative encoder counts with the nominal geometry.

    Midpoint (second-order Runge-Kutta) integration of each count increment:
    ds = (d_L + d_R)/2, dtheta = (d_R - d_L)/b_n, x += ds cos(theta + dtheta/2), ...
    """

    def __init__(self, params: OdometryParams, pose: tuple[float, float, float]):
        self.params = params
        self._m_per_count = math.pi * params.wheel_diameter_m / params.counts_per_rev
        self.reset(pose)

    def reset(self, pose: tuple[float, float, float], counts: tuple[int, int] = (0, 0)) -> None:
        self.x, self.y, self.theta = (float(v) for v in pose)
        self._last = counts
        self.distance_m = 0.0  # path length of the centre (sum of |ds|)
        self.turned_rad = 0.0  # sum of dtheta (signed)

    @property
    def pose(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.theta)

    def correct(self, pose: tuple[float, float, float]) -> None:
        """Replace the estimated pose by an external fix (e.g. a beacon seen by a camera); the
        counters (path length, turned angle) that running primitives measure against are kept."""
        self.x, self.y, self.theta = (float(v) for v in pose)

    def update(self, counts: tuple[int, int]) -> tuple[float, float, float]:
        dl = (counts[0] - self._last[0]) * self._m_per_count
        dr = (counts[1] - self._last[1]) * self._m_per_count
        self._last = counts
        if dl == 0 and dr == 0:
            return self.pose
        ds = 0.5 * (dl + dr)
        dth = (dr - dl) / self.params.wheelbase_m
        mid = self.theta + 0.5 * dth
        self.x += ds * math.cos(mid)
        self.y += ds * math.sin(mid)
        self.theta += dth
        self.distance_m += abs(ds)
        self.turned_rad += dth
        return self.pose

    def error_to(self, true_pose: tuple[float, float, float]) -> tuple[float, float]:
        """(position error m, heading error rad wrapped to [-pi, pi)) of the estimate vs truth."""
        dpos = math.hypot(self.x - true_pose[0], self.y - true_pose[1])
        dth = wrap_angle(true_pose[2] - self.theta)
        return dpos, dth
