"""Intrinsics from views of a planar target, with their uncertainty and a held-out test.

Two central models, nine intrinsic parameters each, fitted by bundle adjustment (every view's
pose with the intrinsics, the reprojection error in pixels minimised with
``scipy.optimize.least_squares``):

* ``mei``: the unified model of Mei & Rives, "Single View Point Omnidirectional Camera
  Calibration from Planar Grids" (ICRA 2007), as OpenCV's ``omnidir`` module fits it with the
  skew fixed at 0: ``xi``, ``fu, fv, pu, pv``, radial ``k1, k2`` and tangential ``p1, p2``;
* ``poly``: the polynomial model of Scaramuzza, Martinelli & Siegwart, "A Toolbox for Easily
  Calibrating Omnidirectional Cameras" (IROS 2006; the OCamCalib toolbox): the ray of a pixel is
  ``(x, y, -f(rho))`` with ``f(rho) = a0 + a2 rho^2 + a3 rho^3 + a4 rho^4`` after the affine
  ``[1 e; d c]`` about the centre. Its elevation is a free function of the radius, which is what
  a webcam behind a curved mirror needs: the mirror's profile, not a conic's, sets it.

OpenCV's own fit of the unified model (``cv2.omnidir.calibrate``) lives in opencv-contrib, not in
the opencv-python-headless the toolkit depends on (the two wheels install the same ``cv2`` and
cannot be installed side by side), and it does not return the Jacobian at its optimum, which the
covariance needs; the second model and the held-out refits need the same machinery. So the fit
is made here, and tested against OpenCV's on OpenCV's own sample (the same RMS to 0.0005 px).

The uncertainty is the covariance of the parameters at the optimum, ``s^2 (J^T J)^-1`` with ``J``
the Jacobian of the residuals and ``s^2`` their measured variance (the sum of squares over the
degrees of freedom), marginalised over the poses. It is chosen over a bootstrap over views
because a bootstrap needs dozens of views to resample (a typical calibration has 10-20, and
resampling 15 views leaves several parameters barely fixed in many draws) and as many refits;
the Jacobian's covariance is exact to first order for independent corner noise, and whether it
is honest is tested rather than assumed: by the coverage of its intervals on simulated views
with a known truth, and on real views by a cross-validation diff between two calibrations on
disjoint halves of the views, beside what the two covariances predict for it (the test of
Kogan's mrcal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares

from stcvision.calibration.lens_models import CentralModel
from stcvision.calibration.target_options import MODELS
from stcvision.calibration.target_views import TargetViews
from stcvision.errors import BadInputError

__all__ = ["TargetFit", "fit_target", "heldout_rms", "project_points", "ray_to_pixel_jacobian"]

#: polynomial coefficients are fitted in units of this many pixels of radius, so that the four
#: are of one size (a4 rho^4 in raw pixels is ~1e-10 rho^4, beyond a finite difference's reach)
POLY_RADIUS_UNIT_PX = 100.0
#: the projection's table for the polynomial model: radii sampled from the centre to the far
#: corner, then refined by Newton steps to ~1e-10 px
POLY_TABLE = 2048
POLY_NEWTON_STEPS = 4
#: a converged fit: the relative change of the cost and of the parameters
FIT_TOL = 1e-10
#: the fit's iterations at most (a converged fit takes 10-50)
MAX_ITERATIONS = 200
#: initial focal lengths tried for the unified model, as fractions of the image's shorter side
#: (xi = 1 fixed for the search: a parabolic mirror's, the middle of the range of real ones)
INIT_FOCAL_FRACTIONS = np.geomspace(0.1, 2.0, 24)


# ---------------------------------------------------------------------------- models
def _mei_model(p, size) -> CentralModel:
    xi, fu, fv, pu, pv, k1, k2, p1, p2 = map(float, p)
    return CentralModel("omni", (xi,), "radtan", (k1, k2, p1, p2), fu, fv, pu, pv, int(size[0]), int(size[1]))


def _decenter(XY: np.ndarray, p1: float, p2: float) -> np.ndarray:
    """Brown's decentering (the tangential terms of OpenCV's radial-tangential model)."""
    x, y = XY[:, 0], XY[:, 1]
    r2 = x * x + y * y
    return np.column_stack([x + 2 * p1 * x * y + p2 * (r2 + 2 * x * x), y + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y])


#: fixed-point iterations of the decentering's inverse (its terms are a few per cent of the
#: radius: each iteration gains two digits)
UNDECENTER_ITERATIONS = 20


def _poly_parts(p):
    pu, pv, c, e, a0, a2, a3, a4, p1, p2 = map(float, p)
    # a symmetric affine: a stretch, no rotation (a rotation about the axis is the poses')
    A = np.array([[1.0, e], [e, c]])
    return (pu, pv), A, np.array([a0, 0.0, a2, a3, a4]), (p1, p2)


def _poly_project(p, pc: np.ndarray, size) -> np.ndarray:
    """Camera-frame points (N, 3) -> pixels under the polynomial model (NaN outside its reach)."""
    centre, A, ss, (p1, p2) = _poly_parts(p)
    w, h = size
    rho_max = math.hypot(w, h) / POLY_RADIUS_UNIT_PX
    rr = np.linspace(0.0, rho_max, POLY_TABLE)
    al = np.arctan2(rr, -np.polynomial.polynomial.polyval(rr, ss))  # angle from the axis
    good = np.concatenate([[True], np.diff(al) > 0])
    stop = len(rr) if good.all() else int(np.argmin(good))
    rr, al = rr[:stop], al[:stop]
    x, y, z = pc[:, 0], pc[:, 1], pc[:, 2]
    n = np.hypot(x, y)
    target = np.arctan2(n, z)
    rho = np.interp(target, al, rr, left=np.nan, right=np.nan)
    ds = np.polynomial.polynomial.polyder(ss)
    for _ in range(POLY_NEWTON_STEPS):
        q = -np.polynomial.polynomial.polyval(rho, ss)
        dq = -np.polynomial.polynomial.polyval(rho, ds)
        f = np.arctan2(rho, q) - target
        df = (q - rho * dq) / (rho * rho + q * q)
        rho = rho - f / df
    safe = np.where(n > 0, n, 1.0)
    XY = np.column_stack([np.where(n > 0, x / safe, 0.0) * rho, np.where(n > 0, y / safe, 0.0) * rho])
    return _decenter(XY, p1, p2) * POLY_RADIUS_UNIT_PX @ A.T + centre


def project_points(model: str, p, pc: np.ndarray, size) -> np.ndarray:
    """Camera-frame points (N, 3) -> pixels (N, 2) under ``model`` with parameters ``p``."""
    if model == "mei":
        return _mei_model(p, size).project(pc)
    return _poly_project(p, pc, size)


def unproject_pixels(model: str, p, uv: np.ndarray, size) -> np.ndarray:
    """Pixels (N, 2) -> unit rays (N, 3) in the camera frame (NaN where undefined)."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    if model == "mei":
        rays, ok = _mei_model(p, size).unproject(uv)
        rays[~ok] = np.nan
        return rays
    centre, A, ss, (p1, p2) = _poly_parts(p)
    XYd = (uv - centre) @ np.linalg.inv(A).T / POLY_RADIUS_UNIT_PX
    XY = XYd.copy()
    with np.errstate(over="ignore", invalid="ignore"):  # where it diverges: NaN, no ray
        for _ in range(UNDECENTER_ITERATIONS):
            XY = XYd - (_decenter(XY, p1, p2) - XY)
    rho = np.hypot(XY[:, 0], XY[:, 1])
    r = np.column_stack([XY, -np.polynomial.polynomial.polyval(rho, ss)])
    return r / np.linalg.norm(r, axis=1, keepdims=True)


@dataclass(frozen=True)
class PolyModel:
    """The polynomial model with its decentering, as a lens model a profile can be made from
    (the interface of :mod:`stcvision.calibration.lens_models`: pixels <-> rays in the
    image-aligned camera frame)."""

    params: tuple[float, ...]
    width: int
    height: int

    kind = "poly"

    @property
    def image_size_px(self) -> tuple[int, int]:
        return (self.width, self.height)

    @property
    def center_px(self) -> tuple[float, float]:
        return (self.params[0], self.params[1])

    def linear_part(self) -> np.ndarray:
        return _poly_parts(self.params)[1]

    def tangential(self) -> bool:
        return any(self.params[8:])

    def radial(self) -> PolyModel:
        """The same model without its tangential (decentering) terms."""
        return PolyModel((*self.params[:8], 0.0, 0.0), self.width, self.height)

    def unproject(self, uv) -> tuple[np.ndarray, np.ndarray]:
        rays = unproject_pixels("poly", self.params, uv, self.image_size_px)
        return rays, np.isfinite(rays).all(axis=1)

    def project(self, rays) -> np.ndarray:
        return _poly_project(self.params, np.asarray(rays, float).reshape(-1, 3), self.image_size_px)


def lens_model(model: str, p, size):
    """The fit as a lens model (for a profile): a Kalibr/OpenCV-style :class:`CentralModel` for
    the unified model, a :class:`PolyModel` for the polynomial."""
    if model == "mei":
        return _mei_model(p, size)
    return PolyModel(tuple(map(float, p)), int(size[0]), int(size[1]))


# ---------------------------------------------------------------------------- poses
def _pose_from_rays(obj: np.ndarray, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The plane's pose from unit rays to its points (any direction, beyond 90 degrees too):
    rays x (H [X Y 1]) = 0, linear in the homography H = [r1 r2 t] (a DLT on the sphere)."""
    X, Y = obj[:, 0], obj[:, 1]
    P = np.column_stack([X, Y, np.ones_like(X)])
    rows = []
    dx, dy, dz = rays[:, 0:1], rays[:, 1:2], rays[:, 2:3]
    zero = np.zeros_like(P)
    rows.append(np.hstack([zero, -dz * P, dy * P]))
    rows.append(np.hstack([dz * P, zero, -dx * P]))
    rows.append(np.hstack([-dy * P, dx * P, zero]))
    A = np.vstack(rows)
    if not np.isfinite(A).all():
        return None
    Hm = np.linalg.svd(A, full_matrices=False)[2][-1].reshape(3, 3)
    if np.einsum("ij,ij->i", (P @ Hm.T), rays).mean() < 0:
        Hm = -Hm
    s = 2.0 / (np.linalg.norm(Hm[:, 0]) + np.linalg.norm(Hm[:, 1]))
    r1, r2, t = Hm[:, 0] * s, Hm[:, 1] * s, Hm[:, 2] * s
    U, _, Vt = np.linalg.svd(np.column_stack([r1, r2, np.cross(r1, r2)]))
    R = U @ Vt
    if np.linalg.det(R) < 0:
        return None
    return cv2.Rodrigues(R)[0].ravel(), t


def _transform(pose: np.ndarray, obj: np.ndarray) -> np.ndarray:
    R = cv2.Rodrigues(np.asarray(pose[:3], float))[0]
    return obj @ R.T + pose[3:6]


# ---------------------------------------------------------------------------- the fit
@dataclass(frozen=True)
class TargetFit:
    """A fitted model: its parameters, their covariance (marginal over the poses), the poses,
    the residuals, and what the residuals say about the noise."""

    model: str
    params: np.ndarray
    cov: np.ndarray
    poses: np.ndarray
    residuals: np.ndarray  # (n_points, 2), all views in order
    view_rms_px: np.ndarray
    image_size_px: tuple[int, int]
    sigma_px: float  # the residuals' measured noise per coordinate, over the degrees of freedom
    #: the joint covariance of the intrinsics and the first view's pose (that view can stand for a
    #: plane of the world, such as the floor, whose uncertainty then includes its pose's)
    cov_first_view: np.ndarray | None = None

    @property
    def rms_px(self) -> float:
        """The root mean square of the points' reprojection errors (the 2-D distance), as
        OpenCV's calibrations report it."""
        return float(np.sqrt(np.mean(np.sum(self.residuals**2, axis=1))))

    @property
    def names(self) -> tuple[str, ...]:
        return MODELS[self.model]

    @property
    def center_px(self) -> tuple[float, float]:
        i = self.names.index("pu")
        return float(self.params[i]), float(self.params[i + 1])

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.diag(self.cov))

    def lens_model(self):
        return lens_model(self.model, self.params, self.image_size_px)

    def project(self, pc: np.ndarray, params=None) -> np.ndarray:
        return project_points(self.model, self.params if params is None else params, pc, self.image_size_px)

    def unproject(self, uv: np.ndarray) -> np.ndarray:
        return unproject_pixels(self.model, self.params, uv, self.image_size_px)


def _rotations(rvecs: np.ndarray) -> np.ndarray:
    """Rodrigues' formula for many rotation vectors at once: (V, 3) -> (V, 3, 3)."""
    th = np.linalg.norm(rvecs, axis=1)
    safe = np.where(th > 1e-12, th, 1.0)
    k = rvecs / safe[:, None]
    K = np.zeros((len(rvecs), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    K = K - K.transpose(0, 2, 1)
    s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
    small = (th <= 1e-12)[:, None, None]
    R = np.eye(3) + s * K + (1 - c) * (K @ K)
    return np.where(small, np.eye(3) + _skew(rvecs), R)


def _skew(v: np.ndarray) -> np.ndarray:
    S = np.zeros((len(v), 3, 3))
    S[:, 0, 1], S[:, 0, 2], S[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    return S - S.transpose(0, 2, 1)


def _residuals(model, size, views: TargetViews, x: np.ndarray, n_intr: int, fixed_intr=None) -> np.ndarray:
    """All views' reprojection errors (u, v interleaved, view by view), in one projection."""
    intr = x[:n_intr] if fixed_intr is None else fixed_intr
    off = 0 if fixed_intr is not None else n_intr
    poses = np.asarray(x[off:], float).reshape(-1, 6)
    key = "_stacked"
    stacked = views.__dict__.get(key)
    if stacked is None:  # the views' points stacked once, with each point's view
        idx = np.concatenate([np.full(len(o), i) for i, o in enumerate(views.object_points)])
        stacked = (np.vstack(views.object_points), np.vstack(views.image_points), idx)
        object.__setattr__(views, key, stacked)
    obj, img, idx = stacked
    R = _rotations(poses[:, :3])
    pc = np.einsum("nij,nj->ni", R[idx], obj) + poses[idx, 3:]
    r = project_points(model, intr, pc, size) - img
    r[~np.isfinite(r)] = 1e3  # a point the model cannot reach: a large, finite residual
    return r.ravel()


#: the Jacobian is held dense (and the trust-region steps solved exactly) up to this many
#: entries (32 MB); beyond, sparse with iterative steps
DENSE_JACOBIAN_ENTRIES = 4_000_000
#: the finite-difference step of the Jacobian, relative to each parameter (the cube root of the
#: machine epsilon: central differences' best)
FD_STEP = 6e-6


def _jacobian(fun, x: np.ndarray, n_intr: int, n_views: int, rows_of_view, dense: bool):
    """Central differences, grouped: the intrinsics one at a time, then each of the six pose
    components of every view at once (a view's residuals depend on its own pose only)."""
    from scipy.sparse import csr_matrix

    cols = []
    for j in range(n_intr):
        h = FD_STEP * max(1.0, abs(x[j]))
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        cols.append(((fun(xp) - fun(xm)) / (2 * h), None, j))
    for k in range(6):
        idx = n_intr + 6 * np.arange(n_views) + k
        h = FD_STEP * np.maximum(1.0, np.abs(x[idx]))
        xp, xm = x.copy(), x.copy()
        xp[idx] += h
        xm[idx] -= h
        d = fun(xp) - fun(xm)
        cols.append((d, h, idx))
    m = len(cols[0][0])
    if dense:
        J = np.zeros((m, len(x)))
    else:
        r_i, c_i, v_i = [], [], []
    for d, h, idx in cols:
        if h is None:
            if dense:
                J[:, idx] = d
            else:
                r_i.append(np.arange(m))
                c_i.append(np.full(m, idx))
                v_i.append(d)
            continue
        for v in range(n_views):
            rows = rows_of_view[v]
            if dense:
                J[rows, idx[v]] = d[rows] / (2 * h[v])
            else:
                r_i.append(np.arange(rows.start, rows.stop))
                c_i.append(np.full(rows.stop - rows.start, idx[v]))
                v_i.append(d[rows] / (2 * h[v]))
    if dense:
        return J
    return csr_matrix((np.concatenate(v_i), (np.concatenate(r_i), np.concatenate(c_i))), shape=(m, len(x)))


def _solve(model, views: TargetViews, intr0, poses0, should_stop=None, fixed_intr=None):
    size = views.image_size_px
    n_intr = 0 if fixed_intr is not None else len(MODELS[model])
    x0 = np.concatenate([[] if fixed_intr is not None else intr0, np.ravel(poses0)])
    rows, k = [], 0
    for img in views.image_points:
        rows.append(slice(k, k + 2 * len(img)))
        k += 2 * len(img)
    dense = k * len(x0) <= DENSE_JACOBIAN_ENTRIES

    def fun(x):
        if should_stop is not None:
            should_stop()
        return _residuals(model, size, views, x, len(MODELS[model]), fixed_intr)

    return least_squares(
        fun,
        x0,
        jac=lambda x: _jacobian(fun, x, n_intr, len(views), rows, dense),
        method="lm" if dense else "trf",
        x_scale="jac",
        **({} if dense else {"tr_solver": "lsmr"}),
        xtol=FIT_TOL,
        ftol=FIT_TOL,
        gtol=FIT_TOL,
        max_nfev=MAX_ITERATIONS,
    )


def _initial_mei(views: TargetViews, should_stop=None):
    """Intrinsics and poses to start from: xi = 1, the centre at the image's, and the focal length
    of a search whose per-view poses (from rays) reproject best."""
    w, h = views.image_size_px
    best = None
    for frac in INIT_FOCAL_FRACTIONS:
        if should_stop is not None:
            should_stop()
        f = frac * min(w, h)
        p = np.array([1.0, f, f, (w - 1) / 2, (h - 1) / 2, 0.0, 0.0, 0.0, 0.0])
        poses, err = [], 0.0
        for obj, img in zip(views.object_points, views.image_points, strict=True):
            rays = unproject_pixels("mei", p, img, views.image_size_px)
            pose = _pose_from_rays(obj, rays) if np.isfinite(rays).all() else None
            if pose is None:
                break
            pose = np.concatenate(pose)
            uv = project_points("mei", p, _transform(pose, obj), views.image_size_px)
            e = np.nan_to_num(uv - img, nan=1e4)
            err += float(np.sum(e * e))
            poses.append(pose)
        else:
            if best is None or err < best[0]:
                best = (err, p, np.array(poses))
    if best is None:
        raise BadInputError("no starting point found for the fit: are the image points those of the object points?")
    return best[1], best[2]


def _initial_poly(views: TargetViews, mei: TargetFit):
    """The polynomial fitted (linear least squares) to the unified model's rays with the same
    poses: at the views' points and over the whole image (a curve that holds beyond them), or at
    the views' points alone, whichever reprojects the views better. Over the whole image the
    conic's rays past its field of view can bend the quartic away from the views (a simulated
    calibration of the spherical mirror started 66 px off, with 586 points unreachable, and the
    fit diverged); at the views alone it follows them."""
    pu, pv = mei.params[3], mei.params[4]
    fu, fv = mei.params[1], mei.params[2]
    c = fv / fu
    w, h = views.image_size_px
    grid = np.stack(np.meshgrid(np.linspace(0, w - 1, 40), np.linspace(0, h - 1, 30)), -1).reshape(-1, 2)
    seen = np.vstack(views.image_points)
    best = None
    for uv in (np.vstack([seen, grid]), seen):
        rays = mei.unproject(uv)
        X, Y = (uv[:, 0] - pu) / POLY_RADIUS_UNIT_PX, (uv[:, 1] - pv) / (c * POLY_RADIUS_UNIT_PX)
        rho = np.hypot(X, Y)
        nrm = np.hypot(rays[:, 0], rays[:, 1])
        ok = np.isfinite(rays).all(axis=1) & (nrm > 1e-6) & (rho > 1e-6)
        # -f(rho) / rho = z / n, so f(rho) = -rho z / n, linear in a0, a2, a3, a4
        t = -rho[ok] * rays[ok, 2] / nrm[ok]
        V = np.column_stack([np.ones(ok.sum()), rho[ok] ** 2, rho[ok] ** 3, rho[ok] ** 4])
        a = np.linalg.lstsq(V, t, rcond=None)[0]
        p = np.array([pu, pv, c, 0.0, *a, 0.0, 0.0])
        err = _start_error(views, p, mei.poses)
        if best is None or err < best[0]:
            best = (err, p)
    return best[1], mei.poses


def _start_error(views: TargetViews, p: np.ndarray, poses: np.ndarray) -> float:
    """The polynomial model's summed squared reprojection error at ``p`` and ``poses`` (a point
    it cannot reach counts 1e4 px off, as in the unified model's start)."""
    err = 0.0
    for pose, obj, img in zip(poses, views.object_points, views.image_points, strict=True):
        e = np.nan_to_num(project_points("poly", p, _transform(pose, obj), views.image_size_px) - img, nan=1e4)
        err += float(np.sum(e * e))
    return err


#: eigenvalues of the scaled normal matrix below this fraction of its largest are the rounding's,
#: not the data's: their directions are taken as fixed only that well (double precision's
#: 1e-16, with room for the products of the Jacobian)
EIGEN_FLOOR = 1e-14


def _psd_inverse(N: np.ndarray) -> np.ndarray:
    """The inverse of a symmetric positive semi-definite matrix, positive semi-definite.

    By its eigen-decomposition, with eigenvalues floored at :data:`EIGEN_FLOOR` of the largest:
    a direction the views barely fix keeps a huge variance. ``numpy.linalg.inv`` of a nearly
    singular normal matrix (the polynomial model's on views of one annulus) gave negative
    variances, and NaN standard deviations and bounds from them.
    """
    lam, V = np.linalg.eigh((N + N.T) / 2)
    lam = np.maximum(lam, EIGEN_FLOOR * max(float(lam[-1]), 1e-300))
    return (V / lam) @ V.T


def _make_fit(model, views, sol, n_intr) -> TargetFit:
    J = sol.jac
    # J^T J only (parameters x parameters): a sparse Jacobian of many views is never made dense
    JtJ = (J.T @ J).toarray() if hasattr(J, "toarray") else J.T @ J
    r = sol.fun
    dof = max(1, len(r) - len(sol.x))
    s2 = float(r @ r) / dof
    # (J^T J)^-1 with the columns scaled to unit length first: the parameters' units differ by
    # many orders (a pixel, a polynomial coefficient), and unscaled the inverse loses them
    scale = np.sqrt(np.diag(JtJ))
    scale[scale == 0] = 1.0
    N = JtJ / np.outer(scale, scale)
    cov_all = _psd_inverse(N) / np.outer(scale, scale) * s2
    res = r.reshape(-1, 2)
    view_rms, k = [], 0
    for img in views.image_points:
        e = res[k : k + len(img)]
        view_rms.append(float(np.sqrt(np.mean(np.sum(e * e, axis=1)))))
        k += len(img)
    return TargetFit(
        model=model,
        params=np.asarray(sol.x[:n_intr], float),
        cov=cov_all[:n_intr, :n_intr],
        cov_first_view=cov_all[: n_intr + 6, : n_intr + 6],
        poses=np.asarray(sol.x[n_intr:], float).reshape(-1, 6),
        residuals=res,
        view_rms_px=np.array(view_rms),
        image_size_px=tuple(views.image_size_px),
        sigma_px=math.sqrt(s2),
    )


def fit_target(
    views: TargetViews, model: str = "mei", *, start: TargetFit | None = None, should_stop=None
) -> TargetFit:
    """Fit ``model`` (``mei`` or ``poly``) to the views; ``start`` (a fit of the same views, or
    of the unified model for ``poly``) is where the search begins."""
    if model not in MODELS:
        raise BadInputError(f"model {model!r}: expected one of {', '.join(MODELS)}")
    n_intr = len(MODELS[model])
    if start is not None and start.model == model and len(start.poses) == len(views):
        intr0, poses0 = start.params, start.poses
    elif model == "mei":
        intr0, poses0 = _initial_mei(views, should_stop)
    else:
        mei = start if start is not None and start.model == "mei" else fit_target(views, "mei", should_stop=should_stop)
        intr0, poses0 = _initial_poly(views, mei)
    sol = _solve(model, views, intr0, poses0, should_stop)
    return _make_fit(model, views, sol, n_intr)


def fit_poses(fit: TargetFit, views: TargetViews, should_stop=None) -> tuple[np.ndarray, np.ndarray]:
    """Each view's pose with ``fit``'s intrinsics held: (poses (V, 6), residuals (N, 2))."""
    poses = []
    for obj, img in zip(views.object_points, views.image_points, strict=True):
        rays = fit.unproject(img)
        pose = _pose_from_rays(obj, rays) if np.isfinite(rays).all() else None
        poses.append(np.concatenate(pose) if pose is not None else np.array([0, 0, 0, 0, 0, 1.0]))
    sol = _solve(fit.model, views, None, np.array(poses), should_stop, fixed_intr=fit.params)
    return sol.x.reshape(-1, 6), sol.fun.reshape(-1, 2)


def fold_indices(n_views: int, folds: int) -> list[np.ndarray]:
    """Views split into ``folds`` groups by position (view i in fold i mod k): neighbouring
    views, often taken one after another, land in different folds."""
    return [np.arange(k, n_views, folds) for k in range(folds)]


def heldout_rms(views: TargetViews, fit: TargetFit, folds: int, should_stop=None) -> tuple[float, np.ndarray]:
    """k-fold cross-validation over views: each fold's views get their poses fitted with the
    intrinsics of the other folds; the RMS of those held-out points' errors, and each view's."""
    if not 2 <= folds <= len(views):
        raise BadInputError(f"--folds {folds}: expected 2..{len(views)} (the number of views)")
    sq = np.zeros(len(views))
    counts = np.array([len(p) for p in views.image_points])
    for idx in fold_indices(len(views), folds):
        train = np.setdiff1d(np.arange(len(views)), idx)
        tv = views.subset(train)
        start = TargetFit(**{**fit.__dict__, "poses": fit.poses[train]})
        f = fit_target(tv, fit.model, start=start, should_stop=should_stop)
        _, res = fit_poses(f, views.subset(idx), should_stop)
        k = 0
        for j in idx:
            e = res[k : k + counts[j]]
            sq[j] = float(np.sum(e * e))
            k += counts[j]
    return float(np.sqrt(sq.sum() / counts.sum())), np.sqrt(sq / counts)


#: finite-difference steps for propagating the covariance: this fraction of each parameter's
#: standard deviation (the model is close to linear over it, and far above rounding)
COV_STEP_OF_STD = 1e-3
#: ... but never more than this fraction of the parameter's own size: a parameter the views
#: barely fix (the polynomial's constant term, where no view reaches the image's centre, had a
#: standard deviation 5000 times its value) would otherwise be stepped to another model, whose
#: elevation curve no longer reaches the rays (NaN: every floor bound of such a fit was lost)
COV_STEP_OF_VALUE = 1e-3


def derivative_steps(params: np.ndarray, std: np.ndarray) -> np.ndarray:
    """The finite-difference step of each parameter for propagating a covariance.

    :data:`COV_STEP_OF_STD` of its standard deviation, at most :data:`COV_STEP_OF_VALUE` of its
    size (a parameter at zero: of its standard deviation alone), never zero.

    Parameters
    ----------
    params, std : numpy.ndarray
        The parameters and their standard deviations.

    Returns
    -------
    numpy.ndarray
        The steps.
    """
    sd = np.where(np.isfinite(std) & (std > 0), std, 1e-9)
    size = np.abs(np.asarray(params, float))
    step = COV_STEP_OF_STD * sd
    return np.where(size > 0, np.minimum(step, COV_STEP_OF_VALUE * size), step)


def params_jacobian(fit: TargetFit, value_of) -> np.ndarray:
    """d(value)/d(intrinsics): (N, 2, n), central differences with the steps of
    :func:`derivative_steps`; ``value_of(params)`` gives the (N, 2) values at a parameter vector."""
    steps = derivative_steps(fit.params, fit.std)
    cols = []
    for j in range(len(fit.params)):
        h = steps[j]
        p1, p0 = fit.params.copy(), fit.params.copy()
        p1[j] += h
        p0[j] -= h
        cols.append((value_of(p1) - value_of(p0)) / (2 * h))
    return np.stack(cols, axis=-1)


def ray_to_pixel_jacobian(fit: TargetFit, rays: np.ndarray) -> np.ndarray:
    """d(pixel)/d(intrinsics) for fixed camera-frame rays (N, 3): (N, 2, n)."""
    return params_jacobian(fit, lambda p: fit.project(rays, p))
