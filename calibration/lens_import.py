"""A profile from another tool's lens model, and a lens model from a profile.

Import: the floor is the plane perpendicular to the model's axis (the centre pixel's ray), at
``viewpoint_height_m`` from its viewpoint, on the side that ray points to. The model is radial
about its principal point in the coordinates its linear part (camera matrix, OCamCalib's affine)
makes; the profile takes

* the centre = the principal point; the rim ellipse = the symmetric factor of that linear part
  (polar decomposition), so the profile's radius is the model's normalised radius times a scale;
* the elevation ``theta(r)``: a polynomial fitted (least squares, ``theta(0) = pi/2``) to the
  model's own ray angles over the image, of the lowest degree that meets
  :data:`FIT_TOL_RAD`;
* azimuth: the model's, up to a constant and a sense, both read off the model; robot-forward at
  the image angle the user gives; ``mirrored`` when the user says the model's frame is the mirror
  image of the world (a camera looking at a mirror, calibrated on planar targets, which cannot
  tell); otherwise the model's frame is taken as the world's;
* Brown's decentering for a radial-tangential model, fitted with the polynomial.

Then the profile is checked against the model over every pixel whose ray meets the floor within
:data:`DOMAIN_DEG` of the axis: the elevation the profile's floor distance implies against the
model's ray, and the azimuth; an import whose worst error exceeds :data:`MAX_ERR_DEG` is refused.

Export fits the target format's model to the profile's rays the same way and checks it likewise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from stcvision.angles import wrap_angle
from stcvision.calibration.lens_models import CentralModel, OcamModel
from stcvision.errors import BadInputError
from stcvision.profile import MAX_DECENTERING, MAX_DECENTERING_RADIAL, Profile

__all__ = ["Fidelity", "axis_basis", "fidelity", "model_from_profile", "profile_from_model"]

#: the part of the image the profile must match the model on: rays within this angle of the axis
#: (beyond, the floor is more than 3.7 viewpoint heights away and the dots too small to read)
DOMAIN_DEG = 75.0
#: what an import or export may differ from the source model by, anywhere in that domain
MAX_ERR_DEG = 0.05
#: the polynomial fits stop at the lowest degree whose worst elevation error is under this
FIT_TOL_RAD = math.radians(0.001)
#: the rays the fits use reach this far from the axis (a margin beyond the checked domain, and
#: still below the horizon, where the profile's floor ends)
FIT_DEG = 85.0
#: pixels sampled along the longer image side for the fits and the checks
GRID = 240


@dataclass(frozen=True)
class Fidelity:
    """Worst and median differences between a profile and a lens model over the domain."""

    n_pixels: int
    elevation_err_deg_max: float
    elevation_err_deg_median: float
    azimuth_err_deg_max: float

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def _grid(w: int, h: int, n: int = GRID) -> np.ndarray:
    step = max(w, h) / n
    u = np.arange(step / 2, w, step)
    v = np.arange(step / 2, h, step)
    uu, vv = np.meshgrid(u, v)
    return np.column_stack([uu.ravel(), vv.ravel()]) - 0.5  # pixel centres, 0-based


def axis_basis(model) -> np.ndarray:
    """Rows e1, e2, e3: e3 = the centre pixel's ray (down to the floor), e1 along the image's u."""
    d0, ok = model.unproject(np.array([model.center_px]))
    if not ok[0]:
        raise BadInputError("the lens model gives the centre pixel no ray; expected a central camera model")
    e3 = d0[0]
    x = np.array([1.0, 0.0, 0.0])
    e1 = x - e3 * (x @ e3)
    e1 /= np.linalg.norm(e1)
    return np.vstack([e1, np.cross(e3, e1), e3])


def _angles(rays: np.ndarray, basis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Angle from the axis and azimuth (about e3, from e1 towards e2) of unit rays."""
    c = rays @ basis.T
    return np.arccos(np.clip(c[:, 2], -1, 1)), np.arctan2(c[:, 1], c[:, 0])


def _ellipse_of(A: np.ndarray) -> tuple[float, float, np.ndarray]:
    """The profile's rim ellipse (ratio, angle) and matrix M for a model's linear part ``A``:
    ``A = s M R`` with M symmetric (first axis 1) and R orthogonal."""
    U, S, _ = np.linalg.svd(A)
    ratio = float(S[1] / S[0])
    angle = float(math.atan2(U[1, 0], U[0, 0]))
    angle = (angle + math.pi / 2) % math.pi - math.pi / 2
    return ratio, angle, _ellipse_matrix(ratio, angle)


def _ellipse_matrix(ratio: float, angle: float) -> np.ndarray:
    """R(angle) diag(1, ratio) R(angle)^T, as :class:`~stcvision.profile.Profile` builds it."""
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    return rot @ np.diag([1.0, ratio]) @ rot.T


def _reach(model, basis, M, r_max: float):
    """The model's radial function along the major axis out to ``r_max`` (profile px), and the
    radius where its angle from the axis stops growing: beyond, a polynomial model's rays fold
    back and mean nothing."""
    c = np.asarray(model.center_px, float)
    rr = np.linspace(0.0, r_max * 1.05, 4096)
    rays_r, ok_r = model.unproject(c + np.column_stack([rr, np.zeros_like(rr)]) @ M.T)
    al_r = _angles(rays_r, basis)[0]
    good = ok_r & np.isfinite(al_r) & np.concatenate([[True], np.diff(al_r) > 0])
    good &= np.cumprod(good).astype(bool)
    r_mono = float(rr[np.argmin(good)] if not good.all() else rr[-1])
    return rr, al_r, good, r_mono


def fidelity(
    profile: Profile, model, *, domain_deg: float = DOMAIN_DEG, grid: int = GRID, inside_rim: bool = False
) -> Fidelity:
    """Compare ``profile`` (tilt set aside: the model knows no floor) with ``model`` over the
    image pixels whose model rays lie within ``domain_deg`` of the axis (and, with
    ``inside_rim``, inside the profile's rim: where a profile made from frames holds)."""
    prof = profile.replace(axis_tilt_rad=(0.0, 0.0))
    w, h = model.image_size_px
    uv = _grid(w, h, grid)
    rays, ok = model.unproject(uv)
    basis = axis_basis(model)
    alpha, beta = _angles(rays, basis)
    _, _, M = _ellipse_of(model.linear_part())
    q = (uv - np.asarray(model.center_px)) @ np.linalg.inv(M).T
    rq = np.hypot(q[:, 0], q[:, 1])
    sel = ok & (alpha <= math.radians(domain_deg)) & (rq <= _reach(model, basis, M, float(rq.max()))[3])
    if inside_rim:
        d = prof._ellipse(uv - np.asarray(prof.center_px), inverse=True)
        sel &= np.hypot(d[:, 0], d[:, 1]) <= prof.rim_radius_px
    uv, alpha, beta = uv[sel], alpha[sel], beta[sel]
    if not len(uv):
        raise BadInputError(f"no pixel of the model's image sees within {domain_deg:g} degrees of its axis")
    xy = prof.image_to_robot(uv)
    H = prof.viewpoint_height_m
    elev = np.arctan2(H, np.hypot(xy[:, 0], xy[:, 1]))
    e_err = np.abs(np.where(np.isfinite(elev), elev - (math.pi / 2 - alpha), np.pi))
    psi = np.arctan2(xy[:, 1], xy[:, 0])
    # the azimuth's offset is the forward angle the user chose and its sense the mirror flip: the
    # model cannot know them, so the check is up to a constant and a sense (the better of the two)
    far = alpha > math.radians(2.0)
    a_err = np.zeros(0)
    for s in (1.0, -1.0):
        d = wrap_angle(psi - s * beta)[far]
        off = np.angle(np.mean(np.exp(1j * d))) if len(d) else 0.0
        err = np.abs(wrap_angle(d - off)) * np.sin(alpha[far])  # as an angle between rays
        if not len(a_err) or (len(err) and err.max() < a_err.max()):
            a_err = err
    return Fidelity(
        n_pixels=int(len(uv)),
        elevation_err_deg_max=float(np.degrees(e_err.max())),
        elevation_err_deg_median=float(np.degrees(np.median(e_err))),
        azimuth_err_deg_max=float(np.degrees(a_err.max())) if len(a_err) else 0.0,
    )


def profile_from_model(
    model,
    *,
    viewpoint_height_m: float,
    forward_angle_rad: float = -math.pi / 2,
    mirrored: bool = False,
    rim_radius_px: float | None = None,
    axis_tilt_rad: tuple[float, float] = (0.0, 0.0),
    base: Profile | None = None,
    provenance: dict | None = None,
    max_err_deg: float | None = MAX_ERR_DEG,
) -> tuple[Profile, Fidelity]:
    """The profile of ``model`` (see the module docstring); ``forward_angle_rad`` is the raw image
    angle ``atan2(v - pv, u - pu)`` at which robot-forward appears. Refused when it differs from
    the model by more than ``max_err_deg`` anywhere in the domain (None: not checked)."""
    if not (viewpoint_height_m > 0 and math.isfinite(viewpoint_height_m)):
        raise BadInputError(f"--viewpoint-height-m must be > 0, got {viewpoint_height_m}")
    w, h = model.image_size_px
    c = np.asarray(model.center_px, float)
    basis = axis_basis(model)
    ratio, ell_angle, M = _ellipse_of(model.linear_part())
    if not 0.8 <= ratio <= 1.25:
        raise BadInputError(f"the model's pixels are {1 / ratio:.3f}:1 non-square; expected within 0.8..1.25")
    Minv = np.linalg.inv(M)
    uv = _grid(w, h)
    rays, ok = model.unproject(uv)
    alpha, beta = _angles(rays, basis)
    q = (uv - c) @ Minv.T
    r = np.hypot(q[:, 0], q[:, 1])
    a = np.arctan2(q[:, 1], q[:, 0])
    rr, al_r, good, r_mono = _reach(model, basis, M, float(r.max()))
    fit = ok & (alpha <= math.radians(FIT_DEG)) & (r <= r_mono)
    dom = ok & (alpha <= math.radians(DOMAIN_DEG)) & (r <= r_mono)
    if dom.sum() < 50:
        raise BadInputError(
            f"the model's image has only {int(dom.sum())} sampled pixels seeing within {DOMAIN_DEG:g} degrees of its "
            "axis; expected a camera that sees the floor around it"
        )
    if rim_radius_px is None:
        below = good & (al_r < math.pi / 2)
        r_fov = float(rr[below][-1]) if below.any() else r_mono
        rim = min(r_fov, float(r[ok].max()))
        rim_measured = False
    else:
        if not (rim_radius_px > 0 and math.isfinite(rim_radius_px)):
            raise BadInputError(f"--rim-px must be > 0, got {rim_radius_px}")
        rim, rim_measured = float(rim_radius_px), True
    # the azimuth: a = sense * beta + offset
    far = fit & (alpha > math.radians(1.0))
    best = None
    for sense in (1.0, -1.0):
        off = np.angle(np.mean(np.exp(1j * (a[far] - sense * beta[far]))))
        spread = float(np.abs(wrap_angle(a[far] - sense * beta[far] - off)).max())
        if best is None or spread < best[0]:
            best = (spread, sense, off)
    _, sense, _ = best
    # robot azimuth psi = -(beta - beta_f) in a world-handed model frame (e1, e2, e3 = down):
    # robot-left is up x forward; psi = +(beta - beta_f) when the frame is the world's mirror image
    prof_mirrored = (sense > 0) == mirrored
    fwd = float(math.atan2(*(Minv @ [math.cos(forward_angle_rad), math.sin(forward_angle_rad)])[::-1]))
    theta_t = math.pi / 2 - alpha
    fields = dict(
        image_size_px=(int(w), int(h)),
        center_px=(float(c[0]), float(c[1])),
        rim_radius_px=rim,
        rim_measured=rim_measured,
        forward_angle_rad=fwd,
        mirrored=bool(prof_mirrored),
        ellipse_ratio=ratio,
        ellipse_angle_rad=ell_angle,
        axis_tilt_rad=(0.0, 0.0),
        viewpoint_height_m=float(viewpoint_height_m),
    )
    prov = dict(provenance or {})
    non_radial = _radial_part(model) is not None
    if non_radial:  # the polynomial's degree from the model without its tangential terms
        radial = _radial_part(model)
        r_al = _angles(radial.unproject(uv[fit])[0], basis)[0]
        prof = _fit_theta(fields, base, prov, r[fit], math.pi / 2 - r_al, rim)
    else:
        prof = _fit_theta(fields, base, prov, r[fit], theta_t[fit], rim)
    if non_radial:
        prof = _fit_decentering(prof, uv[fit], theta_t[fit], sense * beta[fit], a[fit])
    fid = fidelity(prof, model)
    if max_err_deg is not None and max(fid.elevation_err_deg_max, fid.azimuth_err_deg_max) > max_err_deg:
        raise BadInputError(
            f"the profile cannot follow this lens model to {max_err_deg} degrees: worst elevation error "
            f"{fid.elevation_err_deg_max:.3f}, azimuth {fid.azimuth_err_deg_max:.3f} degrees"
        )
    return prof.replace(axis_tilt_rad=tuple(float(t) for t in axis_tilt_rad)), fid


def _radial_part(model):
    """The model without its tangential terms, or None when it has none (a radial-tangential
    central model's p1, p2; a model that says so itself with ``tangential()`` and ``radial()``)."""
    from dataclasses import replace

    if isinstance(model, CentralModel):
        if model.distortion == "radtan" and any(model.coeffs[2:]):
            return replace(model, coeffs=(*model.coeffs[:2], 0.0, 0.0))
        return None
    if hasattr(model, "tangential") and model.tangential():
        return model.radial()
    return None


def _fit_theta(fields, base, prov, r, theta_t, rim) -> Profile:
    """theta(r) = pi/2 + sum c_i (r / rim)^i, least squares, lowest degree meeting FIT_TOL_RAD."""
    x = r / rim
    y = theta_t - math.pi / 2
    best = None
    for deg in range(3, 12):
        V = np.vander(x, deg + 1, increasing=True)[:, 1:]
        coef = np.linalg.lstsq(V, y, rcond=None)[0]
        err = float(np.abs(V @ coef - y).max())
        if best is None or err < best[0]:
            best = (err, coef)
        if err <= FIT_TOL_RAD:
            break
    poly = (math.pi / 2, *map(float, best[1]))
    kw = dict(fields, theta_poly=poly, provenance=prov)
    return base.replace(**kw) if base is not None else Profile(**kw)


#: bounds of the decentering fit: the profile's own limits
_DEC_BOUNDS = (MAX_DECENTERING, MAX_DECENTERING, *[MAX_DECENTERING_RADIAL] * 3)


def _fit_decentering(prof: Profile, uv, theta_t, beta_s, a) -> Profile:
    """Decentering (p1, p2) with the polynomial and the azimuth offset, on the rays themselves."""
    rng = np.random.default_rng(0)
    idx = rng.choice(len(uv), min(len(uv), 600), replace=False)
    uv, theta_t, beta_s = uv[idx], theta_t[idx], beta_s[idx]
    n = len(prof.theta_poly) - 1
    off0 = float(np.angle(np.mean(np.exp(1j * (a[idx] - beta_s)))))

    def make(p):
        return prof.replace(theta_poly=(math.pi / 2, *p[:n]), decentering=tuple(map(float, p[n : n + 5])))

    def residuals(p):
        pr = make(p)
        d = pr._ellipse(uv - np.asarray(pr.center_px), inverse=True)
        qu = pr._undecenter(d)
        th = pr.theta_of_r(np.hypot(qu[:, 0], qu[:, 1]))
        az = np.arctan2(qu[:, 1], qu[:, 0])
        return np.concatenate([th - theta_t, wrap_angle(az - beta_s - p[n + 5]) * np.cos(theta_t)])

    x0 = np.array([*prof.theta_poly[1:], 0.0, 0.0, 0.0, 0.0, 0.0, off0])
    hi = np.array([np.inf] * n + list(_DEC_BOUNDS) + [np.inf])
    sol = least_squares(residuals, x0, bounds=(-hi, hi), x_scale="jac", xtol=1e-14, ftol=1e-14, gtol=1e-14)
    return make(sol.x)


# ---------------------------------------------------------------------------- export
def _profile_rays(prof: Profile, *, grid: int = GRID):
    """Pixels inside the profile's rim (and image) below :data:`FIT_DEG`, with their rays in the
    profile's own image-aligned axis frame (e3 down, azimuth = the ellipse-corrected image angle)."""
    w, h = prof.image_size_px
    uv = _grid(w, h, grid)
    d = prof._ellipse(uv - np.asarray(prof.center_px), inverse=True)
    if any(prof.decentering):
        d = prof._undecenter(d)
    r = np.hypot(d[:, 0], d[:, 1])
    r_tab, th_tab = prof._theta_table()
    r_max = min(float(r_tab[-1]), prof.rim_radius_px)
    th = prof.theta_of_r(r)
    sel = (r <= r_max) & (th >= math.radians(90 - FIT_DEG))
    uv, r, th, a = uv[sel], r[sel], th[sel], np.arctan2(d[sel, 1], d[sel, 0])
    rays = np.column_stack([np.cos(th) * np.cos(a), np.cos(th) * np.sin(a), np.sin(th)])
    return uv, r, th, rays


def model_from_profile(prof: Profile, fmt: str, *, max_err_deg: float = MAX_ERR_DEG):
    """A lens model of ``fmt`` (``ocamcalib``; ``omnidir`` or ``kalibr``: Mei's model with radtan;
    ``ds``, ``eucm``) fitted to the profile's rays in its axis frame inside its rim, its
    fidelity there, and the import flags that give the profile back. Refused when the model
    cannot follow the profile to ``max_err_deg``."""
    if fmt == "ocamcalib":
        model = _fit_ocam(prof)
    elif fmt in ("omnidir", "kalibr"):
        model = _fit_mei(prof, skew=fmt == "omnidir")
    elif fmt in ("ds", "eucm"):
        model = _fit_central(prof, fmt)
    else:
        raise BadInputError(f"export format {fmt!r}: expected ocamcalib, omnidir, kalibr, ds or eucm")
    fid = fidelity(prof, model, inside_rim=True)
    if max(fid.elevation_err_deg_max, fid.azimuth_err_deg_max) > max_err_deg:
        raise BadInputError(
            f"the {fmt} model cannot follow this profile to {max_err_deg} degrees inside its rim (worst elevation "
            f"error {fid.elevation_err_deg_max:.3f} degrees); raise --max-error-deg to accept it, or try "
            "another --format"
        )
    back, _ = profile_from_model(
        model,
        viewpoint_height_m=prof.viewpoint_height_m,
        forward_angle_rad=import_forward_angle(prof),
        max_err_deg=None,
    )
    flags = {
        "viewpoint_height_m": prof.viewpoint_height_m,
        "forward_angle_deg": math.degrees(import_forward_angle(prof)),
        "mirrored": bool(back.mirrored != prof.mirrored),  # the exported frame's sense against the profile's
        "rim_px": prof.rim_radius_px,
        "axis_tilt_deg": [math.degrees(t) for t in prof.axis_tilt_rad],
    }
    return model, fid, flags


def import_forward_angle(prof: Profile) -> float:
    """The raw image angle at which the profile has robot-forward (``--forward-angle-deg``)."""
    v = _prof_M(prof) @ [math.cos(prof.forward_angle_rad), math.sin(prof.forward_angle_rad)]
    return float(math.atan2(v[1], v[0]))


def _prof_M(prof: Profile) -> np.ndarray:
    """The profile's rim-ellipse matrix (image offsets = M times ellipse-corrected ones)."""
    return _ellipse_matrix(prof.ellipse_ratio, prof.ellipse_angle_rad)


def _fit_ocam(prof: Profile) -> OcamModel:
    if any(prof.decentering):
        raise BadInputError("OCamCalib's model has no decentering term; export this profile with --format omnidir")
    uv, r, th, _ = _profile_rays(prof)
    M = _prof_M(prof)
    A = M / M[0, 0]  # OCamCalib's affine has its last entry 1: [c d; e 1] in (row, col)
    rho = r * M[0, 0]  # |A^-1 d| = |M^-1 d| * M[0, 0]
    z = -rho * np.tan(th)  # ss(rho): the ray (x, y, ss) has angle atan2(rho, -ss) from the axis
    wgt = rho / (rho**2 + z**2)  # d(angle)/d(ss): fit in angle
    wgt = np.where(rho > 0, wgt, 1.0 / np.abs(z))
    alpha_t = np.arctan2(rho, -z)
    best = None
    scale = float(rho.max())  # fit in rho / scale: powers of pixels up to the 12th are ill-conditioned
    for deg in range(2, 13):
        V = np.vander(rho / scale, deg + 1, increasing=True)
        ss = np.linalg.lstsq(V * wgt[:, None], z * wgt, rcond=None)[0] / scale ** np.arange(deg + 1)
        err = float(np.abs(np.arctan2(rho, -np.polynomial.polynomial.polyval(rho, ss)) - alpha_t).max())
        if best is None or err < best[0]:
            best = (err, ss)
        if err <= FIT_TOL_RAD:
            break
    ss = best[1]
    # the inverse polynomial, world2cam's: rho as a polynomial of theta = atan(z / rho)
    t = np.arctan2(np.polynomial.polynomial.polyval(rho, ss), rho)
    inv = None
    for deg in range(3, 30):
        coef = np.polynomial.polynomial.Polynomial.fit(t, rho, deg).convert().coef
        if float(np.abs(np.polynomial.polynomial.polyval(t, coef) - rho).max()) < 0.01:
            inv = coef
            break
    inv = coef if inv is None else inv
    w, h = prof.image_size_px
    cu, cv = prof.center_px
    return OcamModel(
        ss=tuple(map(float, ss)),
        invpol=tuple(map(float, inv)),
        xc=float(cv),
        yc=float(cu),
        c=float(A[1, 1]),
        d=float(A[1, 0]),
        e=float(A[0, 1]),
        width=int(w),
        height=int(h),
    )


def _fit_mei(prof: Profile, *, skew: bool) -> CentralModel:
    """Mei's model with radtan distortion: camera matrix shaped by the profile's ellipse (with the
    skew for omnidir; diagonal for Kalibr), xi, k1, k2, p1, p2 by least squares on the rays."""
    from scipy.linalg import rq

    U, _ = rq(_prof_M(prof))  # M = U Q: U upper triangular, the camera matrix's shape
    U = U @ np.diag(np.sign(np.diag(U)))
    shape = U / U[0, 0] if skew else np.diag([1.0, U[1, 1] / U[0, 0]])
    return _fit_central(prof, "omni", shape=shape)


def _fit_central(prof: Profile, projection: str, *, shape: np.ndarray | None = None) -> CentralModel:
    """A Kalibr-style central model (``omni`` with radtan, ``ds``, ``eucm``) with the profile's
    centre and the camera matrix's ``shape`` (the focal length fitted), its other parameters by
    least squares on the reprojection of the profile's rays; starts at typical values."""
    uv, _, th, rays = _profile_rays(prof)
    rng = np.random.default_rng(0)
    idx = rng.choice(len(uv), min(len(uv), 3000), replace=False)
    uv, th, rays = uv[idx], th[idx], rays[idx]
    w, h = prof.image_size_px
    cu, cv = prof.center_px
    if shape is None:  # Kalibr's ds and eucm have no skew
        shape = np.diag([1.0, prof.ellipse_ratio])
    slope = -float(prof.theta_poly[1]) / prof.rim_radius_px  # d(angle)/d(r) at the centre, rad/px
    if projection == "omni":
        x0 = [1.0 + 0.8, 0.8, 0.0, 0.0, 0.0, 0.0]  # f * slope, xi, k1, k2, p1, p2
    elif projection == "ds":
        x0 = [1.0 - 0.2, -0.2, 0.6]
    else:
        x0 = [1.0, 0.6, 1.0]

    def make(p):
        f = p[0] / slope
        fu, fv, s = f * shape[0, 0], f * shape[1, 1], f * shape[0, 1]
        if projection == "omni":
            return CentralModel("omni", (p[1],), "radtan", tuple(p[2:6]), fu, fv, cu, cv, w, h, s)
        return CentralModel(projection, tuple(p[1:3]), "none", (), fu, fv, cu, cv, w, h, s)

    def residuals(p):
        """Reprojection error (px) of the profile's rays, as the calibration tools minimise."""
        try:
            m = make(p)
        except BadInputError:
            return np.full(2 * len(uv), 1e3)
        res = m.project(rays_model) - uv
        return np.where(np.isfinite(res), res, 1e3).ravel()

    # the model's azimuth runs with the camera matrix's rotation away from the profile's ellipse
    Minv = np.linalg.inv(_prof_M(prof))
    n_model = (uv - [cu, cv]) @ np.linalg.inv(shape).T
    n_prof = (uv - [cu, cv]) @ Minv.T
    rot = np.angle(
        np.mean(np.exp(1j * (np.arctan2(n_model[:, 1], n_model[:, 0]) - np.arctan2(n_prof[:, 1], n_prof[:, 0]))))
    )
    az = np.arctan2(rays[:, 1], rays[:, 0]) + rot
    rays_model = np.column_stack([np.cos(th) * np.cos(az), np.cos(th) * np.sin(az), np.sin(th)])
    sol = least_squares(
        residuals, np.array(x0, float), x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000
    )
    return make(sol.x)
