"""The heading stage: a line through the newest mark row, and the turn-time recalibration.

The heading: a line through the newest mark row's dots (the ant-like STC paper of Srour &
Abboud, "Angle Detection"), and the turn-time recalibration from a measured turn ("Rotation and
Calibration").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np

from stcvision.errors import BadInputError
from stcvision.stages.dots import Dots


@dataclass(frozen=True, kw_only=True, slots=True)
class HeadingParams:
    """Parameters of the heading fit.

    Heading fit (ant-like STC paper, "Angle Detection": the newest three dots, a line through
    them).

    The newest mark is the brightest; its dots are the brightest dot and its lit neighbours
    within ``row_radius_m`` (a row of four UV dots spans 9 cm) that lie on one line with it
    (within ``max_residual_m``). ``max_residual_m`` is also the RMS distance of the dots from
    the fitted line above which the fit is refused.
    """

    n_dots: int = 3
    row_radius_m: float = 0.10
    max_residual_m: float = 0.004
    min_span_m: float = 0.02


@dataclass(frozen=True)
class HeadingFit:
    """Result of :func:`fit_heading`. Falsy when the fit failed (``reason`` says why).

    ``line_angle_rad``: direction of the mark row in the robot frame (x forward, y left),
    folded into [-pi/4, pi/4) around the nearest grid axis. ``heading_error_rad``: how far the
    robot's heading is off the grid (counter-clockwise positive) = ``-line_angle_rad``.
    """

    ok: bool
    line_angle_rad: float = math.nan
    heading_error_rad: float = math.nan
    residual_m: float = math.nan
    points_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    reason: str = ""

    def __bool__(self) -> bool:
        return self.ok


def fit_heading(dots: Dots, params: HeadingParams = HeadingParams()) -> HeadingFit:
    """Fit a total-least-squares line through the newest (brightest) dots of the last mark row.

    Parameters
    ----------
    dots : Dots
        The dots found (robot-frame positions and strengths of the lit ones are read).
    params : HeadingParams
        How many dots make the row, the row's radius, the largest residual and the least span.

    Returns
    -------
    HeadingFit
        The line and the heading error; ``ok=False`` with a reason when no row fits.
    """
    lit = np.flatnonzero(dots.lit)
    if len(lit) < params.n_dots:
        return HeadingFit(False, reason=f"fewer than {params.n_dots} dots ({len(lit)} lit)")
    xy = np.ascontiguousarray(dots.xy_m[lit], np.float64)
    # the row through the brightest dot: of the lines from it to each neighbour within the row
    # radius, the one most other neighbours lie on (another mark can sit within the row radius,
    # across the row), then the brightest; its n_dots brightest dots (heading_row)
    status, count, pick = heading_row(
        xy,
        np.ascontiguousarray(dots.strength[lit], np.float64),
        params.n_dots,
        float(params.row_radius_m),
        float(params.max_residual_m),
    )
    if status == 1:
        return HeadingFit(
            False, reason=f"the brightest dot has only {count - 1} lit neighbours within {params.row_radius_m} m"
        )
    if status == 2:
        return HeadingFit(False, reason=f"no row of {params.n_dots} collinear dots at the brightest dot")
    pts = xy[pick]
    # the line's direction, and the spread along and across it (tls_line: closed form)
    ang, span, resid = tls_line(pts)
    if span * 2 < params.min_span_m:
        return HeadingFit(False, points_m=pts, reason="dots too close together to define a line")
    if resid > params.max_residual_m:
        return HeadingFit(
            False, residual_m=float(resid), points_m=pts, reason=f"dots not on a line (residual {resid * 1000:.1f} mm)"
        )
    folded = (ang + math.pi / 4) % (math.pi / 2) - math.pi / 4
    return HeadingFit(True, float(folded), float(-folded), float(resid), pts)


@numba.njit(cache=True, error_model="numpy")
def heading_row(xy, s, n_dots, radius, max_residual):
    """Pick the dots the heading fit goes through.

    The dots :func:`stcvision.stages.fit_heading` fits, among lit dots at ``xy`` (robot
    frame, m) of strengths ``s``: the brightest, and of the lines from it to each neighbour
    within ``radius`` the one most neighbours lie on (within ``max_residual``; then the
    brightest in sum; then the first), its ``n_dots`` brightest dots (stable order). Returns
    (status, value, picks): status 0 with the picked indices; 1 with the neighbours' count
    (too few); 2 (no row of ``n_dots``).
    """
    first = 0
    for i in range(1, len(s)):
        if s[i] > s[first]:
            first = i
    fx, fy = xy[first, 0], xy[first, 1]
    near = np.empty(len(s), np.int64)
    k = 0
    for i in range(len(s)):
        if np.hypot(xy[i, 0] - fx, xy[i, 1] - fy) <= radius:
            near[k] = i
            k += 1
    near = near[:k]
    if k < n_dots:
        return 1, k, np.zeros(0, np.int64)
    best_c, best_count, best_total = -1, -1, -np.inf
    for ci in range(k):
        j = near[ci]
        if j == first:
            continue
        rx, ry = xy[j, 0] - fx, xy[j, 1] - fy
        norm = np.hypot(rx, ry)
        dx, dy = rx / norm, ry / norm
        count = 0
        total = 0.0
        for t in range(k):  # the neighbours on this line, in order
            i = near[t]
            if abs((xy[i, 0] - fx) * -dy + (xy[i, 1] - fy) * dx) <= max_residual:
                total = s[i] if count == 0 else total + s[i]
                count += 1
        if count > best_count or (count == best_count and total > best_total):
            best_c, best_count, best_total = ci, count, total
    j = near[best_c]
    rx, ry = xy[j, 0] - fx, xy[j, 1] - fy
    norm = np.hypot(rx, ry)
    dx, dy = rx / norm, ry / norm
    row = np.empty(k, np.int64)
    m = 0
    for t in range(k):
        i = near[t]
        if abs((xy[i, 0] - fx) * -dy + (xy[i, 1] - fy) * dx) <= max_residual:
            row[m] = i
            m += 1
    if m < n_dots:
        return 2, m, np.zeros(0, np.int64)
    row = row[:m]
    order = np.argsort(-s[row], kind="mergesort")
    return 0, m, row[order[:n_dots]]


@numba.njit(cache=True)
def tls_line(pts):
    """Fit a total-least-squares line through points, in closed form.

    Total-least-squares line through the points ``pts`` ((n, 2), n >= 2): (angle of its
    direction in (-pi/2, pi/2], RMS spread along it, RMS distance from it), in closed form --
    the principal axis of the points' 2 x 2 scatter matrix, and the RMS of the centred points'
    projections on it and across it: the singular values :func:`numpy.linalg.svd` of the
    centred points gave, divided by sqrt(n), without the LAPACK call and its wrapper (which
    cost ~40 us a frame in the pipeline here).
    """
    n = len(pts)
    cx = 0.0
    cy = 0.0
    for i in range(n):
        cx += pts[i, 0]
        cy += pts[i, 1]
    cx /= n
    cy /= n
    sxx = 0.0
    syy = 0.0
    sxy = 0.0
    for i in range(n):
        dx, dy = pts[i, 0] - cx, pts[i, 1] - cy
        sxx += dx * dx
        syy += dy * dy
        sxy += dx * dy
    ang = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
    c, s = math.cos(ang), math.sin(ang)
    along = 0.0
    across = 0.0
    for i in range(n):  # the spreads from the projections (no cancellation for a thin row)
        dx, dy = pts[i, 0] - cx, pts[i, 1] - cy
        along += (dx * c + dy * s) ** 2
        across += (dy * c - dx * s) ** 2
    return ang, math.sqrt(along / n), math.sqrt(across / n)


@dataclass(frozen=True)
class Recalibration:
    """New rotation time and the correction to finish the current turn.

    ``turn_time_s``: time to command for the next 90-degree turn; ``correction_s``: signed
    extra rotation time (negative = rotate back) to complete this one; ``accepted``: the
    measurement was used; ``reason``: why not, or what bound applied; ``clipped``: the ratio
    was bounded (the measurement is more likely a misreading than the robot).
    """

    turn_time_s: float
    correction_s: float
    accepted: bool
    reason: str = ""
    clipped: bool = False


def recalibrate_turn(
    turn_time_s: float,
    measured_turn_rad: float,
    *,
    target_rad: float = math.pi / 2,
    max_ratio: float = 1.25,
    tolerance_rad: float = math.radians(1.0),
) -> Recalibration:
    """Recalibrate the turn time from a measured turn.

    The ant-like STC paper, "Rotation and Calibration": in time T the robot turned d instead of
    90 degrees, so the next turn gets ``T' = 90/d * T``, and a correction finishes this one.

    Robust to a wild measurement: a non-positive or non-finite ``d`` is rejected (T kept), and
    ``T'/T`` is bounded to ``[1/max_ratio, max_ratio]`` (a Lego robot's rate drifts by a few
    per cent per turn, so a larger jump is a misreading, not the robot). Within
    ``tolerance_rad`` no calibration is needed (the paper: "If the robot has done the rotation
    accurate enough, no calibration is needed").

    Parameters
    ----------
    turn_time_s : float
        T, the time the turn took (s).
    measured_turn_rad : float
        d, the angle the robot turned (rad).
    target_rad : float
        The turn asked for (90 degrees).
    max_ratio : float
        The bound on ``T'/T``.
    tolerance_rad : float
        Within this of the target no calibration is needed.

    Returns
    -------
    Recalibration
        The next turn's time, the correction for this one, and whether the measurement was
        accepted (with the reason when not, or when clipped).

    Raises
    ------
    BadInputError
        When ``turn_time_s`` is not a positive finite time.
    """
    if not (turn_time_s > 0 and math.isfinite(turn_time_s)):
        raise BadInputError(f"turn_time_s must be > 0, got {turn_time_s}")
    d = measured_turn_rad
    if not math.isfinite(d) or d <= 0:
        return Recalibration(turn_time_s, 0.0, False, f"measured turn {d!r} rad is not a positive angle")
    if abs(d - target_rad) <= tolerance_rad:
        return Recalibration(turn_time_s, 0.0, True, "within tolerance")
    ratio = target_rad / d
    reason = ""
    clipped = ratio > max_ratio or ratio < 1 / max_ratio
    if clipped:
        reason = f"ratio {ratio:.2f} clipped to the +-{(max_ratio - 1) * 100:.0f} % bound"
        ratio = min(max(ratio, 1 / max_ratio), max_ratio)
    # finishing this turn takes (target - d) / (d / T) = T (ratio - 1): bounded with the ratio
    return Recalibration(turn_time_s * ratio, float(turn_time_s * (ratio - 1.0)), True, reason, clipped)
