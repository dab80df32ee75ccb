"""What a target calibration's covariance says about the image and the floor, and whether the
STC robot can work with it.

* Projection uncertainty: a fixed camera-frame ray's pixel moves with the intrinsics; its 2x2
  covariance is ``J C J^T`` (``J`` the pixel's derivative by the intrinsics, ``C`` their
  covariance). The map gives the ellipse's major semi-axis at 1 sigma, and the radius that holds
  95 % of a 2-D normal error (``sqrt(chi2_2(0.95))`` sigmas along the major axis).
* Floor uncertainty: a pixel's ray meets the floor, the plane perpendicular to the model's axis
  at the viewpoint's height; the floor point moves with the intrinsics likewise (in mm), at each
  distance the robot reads and every azimuth, the worst azimuth reported.
* Cross-validation diff: two calibrations on disjoint halves of the views project the same rays
  to pixels that differ by about their two uncertainties combined when those are honest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from stcvision.calibration.target_fit import TargetFit, fit_target, params_jacobian, ray_to_pixel_jacobian
from stcvision.calibration.target_views import TargetViews

__all__ = [
    "CONFIDENCE",
    "FLOOR_DISTANCES_M",
    "cross_validation_diff",
    "draw_floor_uncertainty",
    "floor_uncertainty",
    "projection_uncertainty",
    "verdict",
]

#: the level of the reported intervals
CONFIDENCE = 0.95
#: a 2-D normal error's radius holding CONFIDENCE of it, in sigmas (2.448 for 95 %)
K95 = math.sqrt(chi2.ppf(CONFIDENCE, 2))
#: distances on the floor at which the floor uncertainty is reported (m): what the robot reads
FLOOR_DISTANCES_M = tuple(round(0.1 * k, 1) for k in range(1, 10))
#: azimuths sampled around the robot at each distance
FLOOR_AZIMUTHS = 72
#: the uncertainty map's samples along the image's longer side
MAP_GRID = 64


def pixel_covariances(fit: TargetFit, rays: np.ndarray) -> np.ndarray:
    """(N, 2, 2) covariance of the pixels that fixed rays project to."""
    J = ray_to_pixel_jacobian(fit, rays)
    return np.einsum("nij,jk,nlk->nil", J, fit.cov, J)


def _major_sigma(S: np.ndarray) -> np.ndarray:
    return np.sqrt(np.maximum(np.linalg.eigvalsh(S)[:, -1], 0.0))


@dataclass(frozen=True)
class ProjectionMap:
    """The projection uncertainty over a grid of pixels (NaN where the model gives no ray)."""

    u: np.ndarray
    v: np.ndarray
    sigma_px: np.ndarray  # (len(v), len(u)): the 1-sigma ellipse's major semi-axis
    observed: np.ndarray  # (N, 2): the target points the fit saw

    @property
    def r95_px(self) -> np.ndarray:
        return K95 * self.sigma_px

    def summary(self) -> dict:
        s = self.sigma_px[np.isfinite(self.sigma_px)]
        inside = observed_mask(self)
        si = self.sigma_px[inside & np.isfinite(self.sigma_px)]
        return {
            "sigma_px_median": float(np.median(s)),
            "sigma_px_max": float(s.max()),
            "r95_px_median": float(K95 * np.median(s)),
            "r95_px_max": float(K95 * s.max()),
            "sigma_px_median_where_observed": float(np.median(si)) if len(si) else None,
            "r95_px_max_where_observed": float(K95 * si.max()) if len(si) else None,
        }


def observed_mask(m: ProjectionMap) -> np.ndarray:
    import cv2

    hull = cv2.convexHull(m.observed.astype(np.float32))
    uu, vv = np.meshgrid(m.u, m.v)
    pts = np.column_stack([uu.ravel(), vv.ravel()])
    inside = np.array([cv2.pointPolygonTest(hull, (float(x), float(y)), False) >= 0 for x, y in pts])
    return inside.reshape(uu.shape)


def projection_uncertainty(fit: TargetFit, views: TargetViews, grid: int = MAP_GRID) -> ProjectionMap:
    w, h = fit.image_size_px
    step = max(w, h) / grid
    u = np.arange(step / 2, w, step) - 0.5
    v = np.arange(step / 2, h, step) - 0.5
    uu, vv = np.meshgrid(u, v)
    uv = np.column_stack([uu.ravel(), vv.ravel()])
    rays = fit.unproject(uv)
    ok = np.isfinite(rays).all(axis=1)
    back = fit.project(np.where(ok[:, None], rays, [0.0, 0.0, 1.0]))
    ok &= np.linalg.norm(back - uv, axis=1) < 0.01  # where the model's inverse holds
    sig = np.full(len(uv), np.nan)
    if ok.any():
        sig[ok] = _major_sigma(pixel_covariances(fit, rays[ok]))
    return ProjectionMap(u, v, sig.reshape(uu.shape), np.vstack(views.image_points))


def draw_uncertainty(m: ProjectionMap, fit: TargetFit, title: str):
    """A matplotlib figure of the map: 1 sigma in colour, 95 % contours, the observed points."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    w, h = fit.image_size_px
    fig, ax = plt.subplots(figsize=(7.5, 7.5 * h / w + 0.6))
    vmax = float(np.nanpercentile(m.sigma_px, 95)) if np.isfinite(m.sigma_px).any() else 1.0
    im = ax.imshow(
        m.sigma_px, extent=(-0.5, w - 0.5, h - 0.5, -0.5), cmap="viridis", vmin=0, vmax=vmax, interpolation="nearest"
    )
    levels = sorted({round(x, 2) for x in np.nanpercentile(m.r95_px, [25, 50, 75]) if np.isfinite(x) and x > 0})
    if len(levels) >= 1:
        cs = ax.contour(m.u, m.v, m.r95_px, levels=levels, colors="white", linewidths=0.8)
        ax.clabel(cs, fmt="%.2f px (95 %%)", fontsize=7)
    ax.plot(m.observed[:, 0], m.observed[:, 1], ".", color="red", markersize=1.5, alpha=0.7)
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_title(title, fontsize=9)
    fig.colorbar(im, ax=ax, shrink=0.8, label="projection uncertainty, 1 sigma (px, major semi-axis)")
    fig.tight_layout()
    return fig


# ---------------------------------------------------------------------------- the floor
def _floor_basis(fit: TargetFit) -> np.ndarray:
    """Rows e1, e2, e3 of the floor frame: e3 the centre pixel's ray (the model's axis), as an
    imported lens model's profile takes it; held fixed while the intrinsics vary."""
    from types import SimpleNamespace

    from stcvision.calibration.lens_import import axis_basis

    def unproject(uv):
        rays = fit.unproject(uv)
        return rays, np.isfinite(rays).all(axis=1)

    return axis_basis(SimpleNamespace(center_px=fit.center_px, unproject=unproject))


def floor_points(fit: TargetFit, uv: np.ndarray, height_m: float, params=None) -> np.ndarray:
    """Pixels -> floor points (N, 2) in m, in the floor frame of the (given or fitted) model."""
    from dataclasses import replace

    f = fit if params is None else replace(fit, params=np.asarray(params, float))
    B = _floor_basis(fit)
    d = f.unproject(uv) @ B.T
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(d[:, 2] > 1e-9, height_m / d[:, 2], np.nan)
    return d[:, :2] * t[:, None]


def floor_jacobian(fit: TargetFit, uv: np.ndarray, height_m: float) -> np.ndarray:
    """(N, 2, n) derivative of fixed pixels' floor points (m) by the intrinsics."""
    return params_jacobian(fit, lambda p: floor_points(fit, uv, height_m, p))


def remove_mount(J: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """What of the floor displacements ``J`` (N, 2, n) at floor points ``xy`` (N, 2) the mount's
    fit to a lights-on frame leaves: that fit sets the viewpoint's height (which scales every
    floor distance alike, rho = H tan(angle)) and the forward angle (a turn about the robot), so
    each parameter's displacement field loses its least-squares scale and turn."""
    perp = np.column_stack([-xy[:, 1], xy[:, 0]])
    A = np.column_stack([xy.ravel(), perp.ravel()])  # (2N, 2): scale, turn
    D = J.transpose(0, 1, 2).reshape(2 * len(xy), -1)  # (2N, n)
    coef = np.linalg.lstsq(A, D, rcond=None)[0]
    return (D - A @ coef).reshape(J.shape)


def remove_similarity(err: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """The floor errors (N, 2) at ``xy`` after the least-squares scale and turn (as the mount's
    fit removes them)."""
    return remove_mount(err[:, :, None], xy)[:, :, 0]


def floor_covariances(fit: TargetFit, uv: np.ndarray, height_m: float, *, mount_fitted: bool = False) -> np.ndarray:
    """(N, 2, 2) covariance (m^2) of the floor points of fixed pixels; with ``mount_fitted``, of
    what is left after the mount's fit (see :func:`remove_mount`)."""
    J = floor_jacobian(fit, uv, height_m)
    if mount_fitted:
        J = remove_mount(J, floor_points(fit, uv, height_m))
    return np.einsum("nij,jk,nlk->nil", J, fit.cov, J)


def floor_pixels(fit: TargetFit, rho_m: np.ndarray, psi: np.ndarray, height_m: float) -> np.ndarray:
    """Where floor points at distance ``rho_m`` and azimuth ``psi`` appear (NaN off the image)."""
    B = _floor_basis(fit)
    P = np.column_stack([rho_m * np.cos(psi), rho_m * np.sin(psi), np.full(len(rho_m), height_m)])
    uv = fit.project(P @ B)
    w, h = fit.image_size_px
    off = ~((uv[:, 0] >= -0.5) & (uv[:, 0] <= w - 0.5) & (uv[:, 1] >= -0.5) & (uv[:, 1] <= h - 0.5))
    uv[off] = np.nan
    return uv


def floor_uncertainty(
    fit: TargetFit, height_m: float, distances_m=FLOOR_DISTANCES_M, *, mount_fitted: bool = True
) -> list[dict]:
    """At each distance: the worst azimuth's 1-sigma (major semi-axis) and 95 % radius in mm, and
    the share of azimuths the image sees there. With ``mount_fitted`` (a profile whose height and
    forward angle were fitted to a lights-on frame), what that fit absorbs is left out."""
    psi = np.linspace(-math.pi, math.pi, FLOOR_AZIMUTHS, endpoint=False)
    rho = np.repeat(np.asarray(distances_m, float), len(psi))
    uv = floor_pixels(fit, rho, np.tile(psi, len(distances_m)), height_m)
    ok = np.isfinite(uv).all(axis=1)
    sig = np.full(len(rho), np.nan)
    if ok.any():
        sig[ok] = 1000 * _major_sigma(floor_covariances(fit, uv[ok], height_m, mount_fitted=mount_fitted))
    out = []
    for k, d in enumerate(distances_m):
        s = sig[k * len(psi) : (k + 1) * len(psi)]
        seen = np.isfinite(s)
        row = {"distance_m": float(d), "seen_fraction": float(seen.mean())}
        if seen.any():
            row.update(sigma_mm=float(s[seen].max()), r95_mm=float(K95 * s[seen].max()))
        else:
            row.update(sigma_mm=None, r95_mm=None)
        out.append(row)
    return out


def draw_floor_uncertainty(floor: list[dict], verdict_: dict, title: str):
    """A matplotlib figure of the floor bound against the distance from the robot: the worst
    azimuth's 1 sigma and 95 % radius (mm) at each distance, the row band the verdict holds them
    to, and the farthest distance the robot reads."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = np.array([r["distance_m"] for r in floor], float)
    sig = np.array([np.nan if r["sigma_mm"] is None else r["sigma_mm"] for r in floor], float)
    r95 = np.array([np.nan if r["r95_mm"] is None else r["r95_mm"] for r in floor], float)
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot(d, r95, "o-", color="C3", label=f"{100 * CONFIDENCE:.0f} % radius (worst azimuth)")
    ax.plot(d, sig, "s--", color="C0", label="1 sigma (worst azimuth)")
    ax.axhline(verdict_["limit_mm"], color="k", linestyle=":", label=f"row band: {verdict_['limit_mm']:.1f} mm")
    ax.axvline(verdict_["reach_m"], color="grey", linestyle="-.", label=f"farthest read: {verdict_['reach_m']:.2f} m")
    unseen = [r["distance_m"] for r in floor if r["seen_fraction"] < 1.0]
    if unseen:
        ax.axvspan(min(unseen) - 0.05, max(unseen) + 0.05, color="grey", alpha=0.15, label="not seen all round")
    ax.set_xlabel("distance on the floor from the viewpoint (m)")
    ax.set_ylabel("floor uncertainty (mm)")
    ax.set_ylim(bottom=0)
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    return fig


# ---------------------------------------------------------------------------- tests of it
def cross_validation_diff(views: TargetViews, fit: TargetFit, grid: int = 24, should_stop=None) -> dict:
    """Two calibrations on the even and the odd views; their projections of the same rays over
    the observed part of the image, beside the two covariances combined."""
    a = fit_target(views.subset(range(0, len(views), 2)), fit.model, should_stop=should_stop)
    b = fit_target(views.subset(range(1, len(views), 2)), fit.model, should_stop=should_stop)
    m = projection_uncertainty(fit, views, grid)
    inside = observed_mask(m)
    uu, vv = np.meshgrid(m.u, m.v)
    uv = np.column_stack([uu[inside], vv[inside]])
    rays = fit.unproject(uv)
    rays = rays[np.isfinite(rays).all(axis=1)]
    d = b.project(rays) - a.project(rays)
    S = pixel_covariances(a, rays) + pixel_covariances(b, rays)
    ok = np.isfinite(d).all(axis=1)
    d, S = d[ok], S[ok]
    m2 = np.einsum("ni,nij,nj->n", d, np.linalg.inv(S), d)
    pred = np.sqrt(np.trace(S, axis1=1, axis2=2))
    return {
        "views": [len(views.subset(range(0, len(views), 2))), len(views.subset(range(1, len(views), 2)))],
        "diff_px_median": float(np.median(np.linalg.norm(d, axis=1))),
        "diff_px_max": float(np.linalg.norm(d, axis=1).max()),
        "predicted_px_median": float(np.median(pred)),
        "within_95_fraction": float(np.mean(m2 <= K95**2)),
        "diff_over_predicted": float(np.median(np.linalg.norm(d, axis=1)) / np.median(pred)),
        "n_rays": int(len(d)),
    }


def verdict(
    floor: list[dict],
    *,
    subcell_m: float,
    reach_m: float,
    n_views: int,
    heldout_ratio: float,
    cv_ratio: float,
    mount_line_err_mm: float | None = None,
) -> dict:
    """Whether the floor uncertainty lets the STC robot place marks in their rows: the 95 % floor
    bound must stay inside the row band (a row's dots share a band ROW_TOL sub-cells wide on each
    side) at every distance up to the farthest neighbour corner it reads; and the held-out error
    must not say the model overfits. When two calibrations on halves of the views differ by more
    than their covariances predict (``cv_ratio`` > 1: model error, not the corners' noise,
    dominates), the floor bounds passed in already carry that ratio (the fit's covariance was
    widened by it: :func:`stcvision.calibration.target.model_error_inflation`), and above
    :data:`CV_RATIO_MAX` the verdict says so. The mount's fit to the lights-on frame is a test of
    its own: the grid's tape lines must land on the model's lines to within half the band
    (``mount_line_err_mm``, the median). If not good enough, what to add."""
    from stcvision.observation import ROW_TOL

    limit_mm = 1000 * ROW_TOL * subcell_m
    scale = 1.0  # the model error is in the covariance already
    rows = [r for r in floor if r["distance_m"] <= reach_m + 1e-9]
    unseen = [r["distance_m"] for r in rows if r["r95_mm"] is None or r["seen_fraction"] < 1.0]
    worst = scale * max((r["r95_mm"] for r in rows if r["r95_mm"] is not None), default=math.inf)
    advice = []
    if cv_ratio > CV_RATIO_MAX:
        advice.append(
            f"two calibrations on halves of the views differ by {cv_ratio:.1f}x what the views' noise predicts: "
            "the model does not follow this camera to its noise (every uncertainty is widened by that ratio)"
        )
    if unseen:
        advice.append(f"the image does not see all around at {', '.join(f'{d:g}' for d in unseen)} m")
    if worst > limit_mm:
        far = [r["distance_m"] for r in rows if r["r95_mm"] is not None and scale * r["r95_mm"] > limit_mm]
        need = math.ceil(n_views * (worst / limit_mm) ** 2)
        span = f"{min(far):g}" if min(far) == max(far) else f"{min(far):g}-{max(far):g}"
        advice.append(
            f"the 95 % floor bound reaches {worst:.1f} mm (over {limit_mm:.1f} mm) at {span} m: "
            f"add views with the target near the image's rim, where those distances appear, or about {need} views "
            "in all (the bound shrinks as one over the square root of the views)"
        )
    if mount_line_err_mm is not None and mount_line_err_mm > limit_mm / 2:
        advice.append(
            f"the lights-on frame's grid lines lie {mount_line_err_mm:.1f} mm (median) off the calibrated model "
            f"(over {limit_mm / 2:.1f} mm): the intrinsics do not hold on the floor; add views tilted every way "
            "(views all parallel to the floor leave the axis's tilt and the mirror's scale unresolved), check that "
            "the robot stood at the calibration pose, or fit the mount to a second lights-on frame"
        )
    if heldout_ratio > HELDOUT_RATIO_MAX:
        advice.append(
            f"the held-out error is {heldout_ratio:.2f}x the in-sample one (over {HELDOUT_RATIO_MAX}): "
            "the model follows the views' noise; add views or take the simpler model"
        )
    return {
        "ok": not advice,
        "limit_mm": limit_mm,
        "reach_m": reach_m,
        "worst_r95_mm": None if math.isinf(worst) else worst,
        "model_error_ratio": cv_ratio,
        "advice": advice,
    }


#: the held-out RMS over the in-sample RMS above which a fit is said to overfit
HELDOUT_RATIO_MAX = 1.3
#: the cross-validation diff over its prediction above which the uncertainty is said to flatter
CV_RATIO_MAX = 2.0
