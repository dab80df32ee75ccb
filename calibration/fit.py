"""Fit the pipeline's mirror model (a :class:`stcvision.profile.Profile`) to correspondences
between image points and known floor points.

The model is central and radial (see :mod:`stcvision.profile`): image centre, forward angle,
mirror flip, rim ellipse, and the depression angle ``theta`` as a polynomial of the image radius.
Residuals are angular -- ``theta`` (elevation) and ``phi`` (azimuth) -- so near and far points
weigh alike; :func:`scipy.optimize.least_squares` with a soft-L1 loss keeps a few bad
correspondences (a misdetected grid corner) from pulling the fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from stcvision.angles import wrap_angle
from stcvision.errors import BadInputError
from stcvision.profile import Profile

__all__ = ["FitReport", "fit_profile"]

#: Effective viewpoint height used by default: the mirror's height above the floor on the
#: default robot (camera at 15 cm, mirror vertex 10 cm above it), measured with a ruler. Any
#: value of that order works: theta's polynomial absorbs the rest.
DEFAULT_VIEWPOINT_M = 0.25


@dataclass(frozen=True)
class FitReport:
    """Residuals of a fit: floor reprojection error (m) and image reprojection error (px)."""

    n_points: int
    floor_err_m_median: float
    floor_err_m_max: float
    image_err_px_median: float | None
    image_err_px_max: float | None
    inliers: int

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def fit_profile(
    uv_px,
    xy_robot_m,
    *,
    image_size_px: tuple[int, int],
    rim_radius_px: float,
    center_px: tuple[float, float] | None = None,
    fix_center: bool = False,
    degree: int = 6,
    viewpoint_height_m: float = DEFAULT_VIEWPOINT_M,
    fit_ellipse: bool = True,
    fit_tilt: bool = True,
    base: Profile | None = None,
    lines: tuple | None = None,
    init: Profile | None = None,
) -> tuple[Profile, FitReport]:
    """Fit a profile to ``uv_px`` (N, 2) image points of floor points ``xy_robot_m`` (N, 2).

    Parameters
    ----------
    center_px : initial (or, with ``fix_center``, fixed) image centre; default: image centre.
    degree : degree of the theta polynomial.
    base : profile whose ground-view and board fields are kept.
    lines : optional ``(uv (M, 2), axis (M,), offset_m (M,)[, weight])``: image points known
        to lie on the floor line ``x = offset`` (axis 0) or ``y = offset`` (axis 1) of the
        robot frame (points along the calibration grid's tape lines).
    """
    uv = np.asarray(uv_px, float).reshape(-1, 2)
    xy = np.asarray(xy_robot_m, float).reshape(-1, 2)
    if len(uv) != len(xy):
        raise BadInputError(f"fit_profile: {len(uv)} image points but {len(xy)} floor points")
    n_lines = 0 if lines is None else len(lines[0])
    if len(uv) + n_lines // 4 < degree + 6:
        raise BadInputError(f"fit_profile: need at least {degree + 6} correspondences, got {len(uv)}")
    w, h = image_size_px
    c0 = np.array(center_px if center_px is not None else ((w - 1) / 2, (h - 1) / 2), float)
    H = viewpoint_height_m
    rho = np.hypot(xy[:, 0], xy[:, 1])
    theta_t = np.arctan2(H, rho)
    psi_t = np.arctan2(xy[:, 1], xy[:, 0])
    floor_dirs = np.column_stack([xy, np.full(len(xy), -H)])
    floor_dirs /= np.linalg.norm(floor_dirs, axis=1, keepdims=True)

    def target_angles(tx, ty):
        """Depression and azimuth of the targets in the mirror-axis frame."""
        cx, sx, cy, sy = math.cos(tx), math.sin(tx), math.cos(ty), math.sin(ty)
        rot = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]]) @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
        d = floor_dirs @ rot
        return np.arcsin(np.clip(-d[:, 2], -1, 1)), np.arctan2(d[:, 1], d[:, 0])

    # initial guesses: flip and forward angle from the azimuths, theta from a polynomial
    if init is not None:
        c0 = np.array(init.center_px, float)
        mirrored, fwd0 = init.mirrored, init.forward_angle_rad
        poly0 = np.zeros(degree + 1)
        m = min(len(init.theta_poly), degree + 1)
        poly0[:m] = init.theta_poly[:m]
        e0 = [init.ellipse_ratio, init.ellipse_angle_rad]
        t0 = list(init.axis_tilt_rad)
    else:
        d = uv - c0
        a = np.arctan2(d[:, 1], d[:, 0])
        best = None
        for mirrored in (True, False):
            s = 1.0 if mirrored else -1.0
            fwd = np.angle(np.mean(np.exp(1j * (a - s * psi_t))))
            spread = np.abs(wrap_angle(a - s * psi_t - fwd)).mean()
            if best is None or spread < best[0]:
                best = (spread, mirrored, fwd)
        _, mirrored, fwd0 = best
        x0n = np.hypot(d[:, 0], d[:, 1]) / rim_radius_px
        # least squares for the non-constant terms with theta(0) = pi/2
        V = np.vander(x0n, degree + 1, increasing=True)[:, 1:]
        coef = np.linalg.lstsq(V, theta_t - math.pi / 2, rcond=None)[0]
        poly0 = np.concatenate([[math.pi / 2], coef])
        e0, t0 = [1.0, 0.0], [0.0, 0.0]
    sign = 1.0 if mirrored else -1.0

    def unpack(p):
        i = 0
        if fix_center:
            c = c0
        else:
            c, i = p[0:2], 2
        fwd, i = p[i], i + 1
        if fit_ellipse:
            k, ang, i = p[i], p[i + 1], i + 2
        else:
            k, ang = 1.0, 0.0
        if fit_tilt:
            tilt, i = (p[i], p[i + 1]), i + 2
        else:
            tilt = (0.0, 0.0)
        # theta(0) = pi/2: the mirror's axis looks straight down in its own frame (the axis tilt
        # carries any lean); with no data under the robot's body the constant would float
        return c, fwd, k, ang, tilt, np.concatenate([[math.pi / 2], p[i:]])

    if lines is not None:
        l_uv = np.asarray(lines[0], float).reshape(-1, 2)
        l_axis = np.asarray(lines[1], int)
        l_off = np.asarray(lines[2], float)
        l_w = float(lines[3]) if len(lines) > 3 else 1.0

    def line_residuals(c, fwd, k, ang, tilt, poly):
        """Signed floor distance of each line point from its known line, over its distance
        from the viewpoint (an angle, like the point residuals)."""
        dd = l_uv - c
        if fit_ellipse:
            cs, sn = math.cos(ang), math.sin(ang)
            rot = np.array([[cs, -sn], [sn, cs]])
            dd = dd @ (rot @ np.diag([1.0, 1.0 / k]) @ rot.T).T
        r = np.hypot(dd[:, 0], dd[:, 1]) / rim_radius_px
        th = np.polynomial.polynomial.polyval(r, poly)
        psi = sign * (np.arctan2(dd[:, 1], dd[:, 0]) - fwd)
        d = np.column_stack([np.cos(th) * np.cos(psi), np.cos(th) * np.sin(psi), -np.sin(th)])
        tx, ty = tilt
        cx, sx, cy, sy = math.cos(tx), math.sin(tx), math.cos(ty), math.sin(ty)
        rot3 = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]]) @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
        d = d @ rot3.T
        t = H / np.maximum(-d[:, 2], 1e-3)
        xy = d[:, :2] * t[:, None]
        coord = np.where(l_axis == 0, xy[:, 0], xy[:, 1])
        return l_w * (coord - l_off) / np.hypot(np.hypot(xy[:, 0], xy[:, 1]), H)

    def residuals(p):
        c, fwd, k, ang, tilt, poly = unpack(p)
        theta_t, psi_t = target_angles(*tilt)
        dd = uv - c
        if fit_ellipse:
            cs, sn = math.cos(ang), math.sin(ang)
            rot = np.array([[cs, -sn], [sn, cs]])
            m = rot @ np.diag([1.0, 1.0 / k]) @ rot.T
            dd = dd @ m.T
        r = np.hypot(dd[:, 0], dd[:, 1]) / rim_radius_px
        th = np.polynomial.polynomial.polyval(r, poly)
        az = np.arctan2(dd[:, 1], dd[:, 0])
        psi = sign * (az - fwd)
        dpsi = wrap_angle(psi - psi_t)
        # azimuth error matters in proportion to how far the point is seen off the nadir
        res = [th - theta_t, dpsi * np.cos(theta_t)]
        if lines is not None:
            res.append(line_residuals(c, fwd, k, ang, tilt, poly))
        return np.concatenate(res)

    tilt_lim = np.radians(10.0)
    p0 = ([] if fix_center else list(c0)) + [fwd0] + (list(e0) if fit_ellipse else [])
    p0 += list(t0) if fit_tilt else []
    p0 += list(poly0[1:])
    lo = ([-np.inf, -np.inf] if not fix_center else []) + [-np.inf] + ([0.9, -np.pi] if fit_ellipse else [])
    hi = ([np.inf, np.inf] if not fix_center else []) + [np.inf] + ([1.1, np.pi] if fit_ellipse else [])
    lo += [-tilt_lim, -tilt_lim] if fit_tilt else []
    hi += [tilt_lim, tilt_lim] if fit_tilt else []
    lo += [-np.inf] * (len(poly0) - 1)
    hi += [np.inf] * (len(poly0) - 1)
    sol = least_squares(residuals, np.array(p0), bounds=(lo, hi), loss="soft_l1", f_scale=2e-3, x_scale="jac")
    c, fwd, k, ang, tilt, poly = unpack(sol.x)
    fields = dict(
        image_size_px=(int(w), int(h)),
        center_px=(float(c[0]), float(c[1])),
        rim_radius_px=float(rim_radius_px),
        forward_angle_rad=wrap_angle(float(fwd)),
        mirrored=bool(mirrored),
        ellipse_ratio=float(k),
        ellipse_angle_rad=float(ang),
        axis_tilt_rad=(float(tilt[0]), float(tilt[1])),
        viewpoint_height_m=float(viewpoint_height_m),
        theta_poly=tuple(float(v) for v in poly),
    )
    if base is not None:
        prof = base.replace(**fields)
    else:
        prof = Profile(**fields)
    if len(uv):
        back = prof.image_to_robot(uv)
        ferr = np.hypot(*(back - xy).T)
        ierr = np.hypot(*(prof.robot_to_image(xy) - uv).T)
        res = residuals(sol.x)
        inl = int(np.sum(np.hypot(res[: len(uv)], res[len(uv) : 2 * len(uv)]) < 5e-3))
    else:  # lines only: the floor distance of each line point from its line
        res = line_residuals(*unpack(sol.x)) / l_w
        ferr = np.abs(res) * 0.5  # ~ metres at the typical 0.5 m (reported only)
        ierr = None
        inl = int(np.sum(np.abs(res) < 5e-3))
    report = FitReport(
        n_points=len(uv),
        floor_err_m_median=float(np.nanmedian(ferr)),
        floor_err_m_max=float(np.nanmax(ferr)),
        image_err_px_median=None if ierr is None else float(np.nanmedian(ierr)),
        image_err_px_max=None if ierr is None else float(np.nanmax(ierr)),
        inliers=inl,
    )
    return prof, report
