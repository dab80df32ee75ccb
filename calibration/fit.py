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

__all__ = ["FitReport", "FitSetup", "fit_profile"]

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


@dataclass(frozen=True, kw_only=True)
class FitSetup:
    """What a fit frees and where it starts: the image, the rim (its radius scales the image
    radius theta is a polynomial of), the centre (initial, or fixed with ``fix_center``), the
    degree of theta's polynomial, the viewpoint height, and whether the rim ellipse and the
    mirror axis's tilt are fitted."""

    image_size_px: tuple[int, int]
    rim_radius_px: float
    center_px: tuple[float, float] | None = None
    fix_center: bool = False
    degree: int = 6
    viewpoint_height_m: float = DEFAULT_VIEWPOINT_M
    fit_ellipse: bool = True
    fit_tilt: bool = True


#: the largest axis tilt a fit may find (either axis): a mirror leaning more is a broken mount
TILT_LIMIT_RAD = math.radians(10.0)


def _tilt_rotation(tx: float, ty: float) -> np.ndarray:
    """The mirror axis's tilt (about x, then y) as a 3x3 rotation."""
    cx, sx, cy, sy = math.cos(tx), math.sin(tx), math.cos(ty), math.sin(ty)
    return np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]]) @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])


def _image_angles(uv: np.ndarray, setup: FitSetup, sign: float, c, fwd, k, ang, poly):
    """Depression theta and azimuth psi (mirror-axis frame) of image points ``uv``."""
    dd = uv - c
    if setup.fit_ellipse:
        cs, sn = math.cos(ang), math.sin(ang)
        rot = np.array([[cs, -sn], [sn, cs]])
        dd = dd @ (rot @ np.diag([1.0, 1.0 / k]) @ rot.T).T
    r = np.hypot(dd[:, 0], dd[:, 1]) / setup.rim_radius_px
    th = np.polynomial.polynomial.polyval(r, poly)
    return th, sign * (np.arctan2(dd[:, 1], dd[:, 0]) - fwd)


class _Layout:
    """Where each free parameter sits in the solver's vector, its start and its bounds."""

    def __init__(self, setup: FitSetup, c0, fwd0, e0, t0, poly0):
        self.setup, self.c0 = setup, c0
        free_c = not setup.fix_center
        self.p0 = (list(c0) if free_c else []) + [fwd0] + (list(e0) if setup.fit_ellipse else [])
        self.p0 += list(t0) if setup.fit_tilt else []
        self.p0 += list(poly0[1:])
        lim = TILT_LIMIT_RAD
        self.lo = ([-np.inf, -np.inf] if free_c else []) + [-np.inf] + ([0.9, -np.pi] if setup.fit_ellipse else [])
        self.hi = ([np.inf, np.inf] if free_c else []) + [np.inf] + ([1.1, np.pi] if setup.fit_ellipse else [])
        self.lo += [-lim, -lim] if setup.fit_tilt else []
        self.hi += [lim, lim] if setup.fit_tilt else []
        self.lo += [-np.inf] * (len(poly0) - 1)
        self.hi += [np.inf] * (len(poly0) - 1)

    def unpack(self, p):
        """(centre, forward angle, ellipse ratio, ellipse angle, tilt, theta polynomial)."""
        i = 0
        if self.setup.fix_center:
            c = self.c0
        else:
            c, i = p[0:2], 2
        fwd, i = p[i], i + 1
        if self.setup.fit_ellipse:
            k, ang, i = p[i], p[i + 1], i + 2
        else:
            k, ang = 1.0, 0.0
        if self.setup.fit_tilt:
            tilt, i = (p[i], p[i + 1]), i + 2
        else:
            tilt = (0.0, 0.0)
        # theta(0) = pi/2: the mirror's axis looks straight down in its own frame (the axis tilt
        # carries any lean); with no data under the robot's body the constant would float
        return c, fwd, k, ang, tilt, np.concatenate([[math.pi / 2], p[i:]])


def _initial_guess(uv, theta_t, psi_t, c0, setup: FitSetup, init: Profile | None):
    """(centre, mirrored, forward angle, theta polynomial, ellipse, tilt) to start from: the
    ``init`` profile's, else the flip and forward angle from the azimuths and theta from a
    polynomial through the targets' depressions."""
    degree = setup.degree
    if init is not None:
        poly0 = np.zeros(degree + 1)
        m = min(len(init.theta_poly), degree + 1)
        poly0[:m] = init.theta_poly[:m]
        e0, t0 = [init.ellipse_ratio, init.ellipse_angle_rad], list(init.axis_tilt_rad)
        return np.array(init.center_px, float), init.mirrored, init.forward_angle_rad, poly0, e0, t0
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
    x0n = np.hypot(d[:, 0], d[:, 1]) / setup.rim_radius_px
    # least squares for the non-constant terms with theta(0) = pi/2
    V = np.vander(x0n, degree + 1, increasing=True)[:, 1:]
    coef = np.linalg.lstsq(V, theta_t - math.pi / 2, rcond=None)[0]
    return c0, mirrored, fwd0, np.concatenate([[math.pi / 2], coef]), [1.0, 0.0], [0.0, 0.0]


def _line_residuals(lines, setup: FitSetup, sign: float, c, fwd, k, ang, tilt, poly):
    """Signed floor distance of each line point from its known line, over its distance from the
    viewpoint (an angle, like the point residuals), weighted by the lines' weight."""
    l_uv = np.asarray(lines[0], float).reshape(-1, 2)
    l_axis = np.asarray(lines[1], int)
    l_off = np.asarray(lines[2], float)
    l_w = float(lines[3]) if len(lines) > 3 else 1.0
    th, psi = _image_angles(l_uv, setup, sign, c, fwd, k, ang, poly)
    d = np.column_stack([np.cos(th) * np.cos(psi), np.cos(th) * np.sin(psi), -np.sin(th)])
    d = d @ _tilt_rotation(*tilt).T
    H = setup.viewpoint_height_m
    t = H / np.maximum(-d[:, 2], 1e-3)
    xy = d[:, :2] * t[:, None]
    coord = np.where(l_axis == 0, xy[:, 0], xy[:, 1])
    return l_w * (coord - l_off) / np.hypot(np.hypot(xy[:, 0], xy[:, 1]), H)


def _report(prof: Profile, uv, xy, res_points, res_lines, weight: float) -> FitReport:
    """Floor and image reprojection errors of the fitted profile (lines only: the floor
    distance of each line point from its line, in metres at the typical 0.5 m)."""
    if len(uv):
        ferr = np.hypot(*(prof.image_to_robot(uv) - xy).T)
        ierr = np.hypot(*(prof.robot_to_image(xy) - uv).T)
        inl = int(np.sum(np.hypot(res_points[: len(uv)], res_points[len(uv) : 2 * len(uv)]) < 5e-3))
    else:
        res = res_lines / weight
        ferr = np.abs(res) * 0.5
        ierr = None
        inl = int(np.sum(np.abs(res) < 5e-3))
    return FitReport(
        n_points=len(uv),
        floor_err_m_median=float(np.nanmedian(ferr)),
        floor_err_m_max=float(np.nanmax(ferr)),
        image_err_px_median=None if ierr is None else float(np.nanmedian(ierr)),
        image_err_px_max=None if ierr is None else float(np.nanmax(ierr)),
        inliers=inl,
    )


def fit_profile(
    uv_px, xy_robot_m, setup: FitSetup, *, lines: tuple | None = None, base: Profile | None = None, init=None
) -> tuple[Profile, FitReport]:
    """Fit a profile to ``uv_px`` (N, 2) image points of floor points ``xy_robot_m`` (N, 2).

    Parameters
    ----------
    setup : :class:`FitSetup`, what is fitted and where it starts.
    lines : optional ``(uv (M, 2), axis (M,), offset_m (M,)[, weight])``: image points known
        to lie on the floor line ``x = offset`` (axis 0) or ``y = offset`` (axis 1) of the
        robot frame (points along the calibration grid's tape lines).
    base : profile whose ground-view and board fields are kept.
    init : profile to start from (default: a guess from the points).
    """
    uv = np.asarray(uv_px, float).reshape(-1, 2)
    xy = np.asarray(xy_robot_m, float).reshape(-1, 2)
    if len(uv) != len(xy):
        raise BadInputError(f"fit_profile: {len(uv)} image points but {len(xy)} floor points")
    n_lines = 0 if lines is None else len(lines[0])
    if len(uv) + n_lines // 4 < setup.degree + 6:
        raise BadInputError(f"fit_profile: need at least {setup.degree + 6} correspondences, got {len(uv)}")
    w, h = setup.image_size_px
    c0 = np.array(setup.center_px if setup.center_px is not None else ((w - 1) / 2, (h - 1) / 2), float)
    H = setup.viewpoint_height_m
    floor_dirs = np.column_stack([xy, np.full(len(xy), -H)])
    floor_dirs /= np.linalg.norm(floor_dirs, axis=1, keepdims=True)
    theta_t, psi_t = np.arctan2(H, np.hypot(xy[:, 0], xy[:, 1])), np.arctan2(xy[:, 1], xy[:, 0])
    c0, mirrored, fwd0, poly0, e0, t0 = _initial_guess(uv, theta_t, psi_t, c0, setup, init)
    sign = 1.0 if mirrored else -1.0
    layout = _Layout(setup, c0, fwd0, e0, t0, poly0)

    def point_residuals(p):
        c, fwd, k, ang, tilt, poly = layout.unpack(p)
        d = floor_dirs @ _tilt_rotation(*tilt)  # the targets in the mirror-axis frame
        theta_t, psi_t = np.arcsin(np.clip(-d[:, 2], -1, 1)), np.arctan2(d[:, 1], d[:, 0])
        th, psi = _image_angles(uv, setup, sign, c, fwd, k, ang, poly)
        # azimuth error matters in proportion to how far the point is seen off the nadir
        res = [th - theta_t, wrap_angle(psi - psi_t) * np.cos(theta_t)]
        if lines is not None:
            res.append(_line_residuals(lines, setup, sign, c, fwd, k, ang, tilt, poly))
        return np.concatenate(res)

    sol = least_squares(
        point_residuals,
        np.array(layout.p0),
        bounds=(layout.lo, layout.hi),
        loss="soft_l1",
        f_scale=2e-3,
        x_scale="jac",
    )
    c, fwd, k, ang, tilt, poly = layout.unpack(sol.x)
    fields = dict(
        image_size_px=(int(w), int(h)),
        center_px=(float(c[0]), float(c[1])),
        rim_radius_px=float(setup.rim_radius_px),
        forward_angle_rad=wrap_angle(float(fwd)),
        mirrored=bool(mirrored),
        ellipse_ratio=float(k),
        ellipse_angle_rad=float(ang),
        axis_tilt_rad=(float(tilt[0]), float(tilt[1])),
        viewpoint_height_m=float(H),
        theta_poly=tuple(float(v) for v in poly),
    )
    prof = base.replace(**fields) if base is not None else Profile(**fields)
    res_lines = _line_residuals(lines, setup, sign, c, fwd, k, ang, tilt, poly) if not len(uv) else None
    weight = float(lines[3]) if lines is not None and len(lines) > 3 else 1.0
    return prof, _report(prof, uv, xy, point_residuals(sol.x) if len(uv) else None, res_lines, weight)
