"""Simulated target calibrations with a known truth: does a reported interval hold the truth as
often as it says?

A camera with known intrinsics (by default near the unified-model fit of OpenCV's omnidirectional
sample: 1280x960, xi 1.05) sees a 9x6 checkerboard (0.2 units a square) in random poses
around it; the corners get Gaussian noise. Each simulated calibration is fitted and its 95 %
bounds are checked against the truth, in the image (a fixed ray's pixel) and on the floor (the
plane perpendicular to the axis at a height, where a pixel's ray meets it).

    python -m stcvision.calibration.target_sim --seeds 200
    python -m stcvision.calibration.target_sim --simulator --seeds 40

print the share of points whose true error lies within the 95 % bounds; the second calibrates
the simulator's ray-traced spherical-mirror camera (whose true projection the renderer knows
independently of any lens model) from boards laid on the floor and raised on blocks.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from stcvision.calibration.target_fit import derivative_steps, fit_target, project_points
from stcvision.calibration.target_uncertainty import (
    K95,
    floor_covariances,
    floor_points,
    observed_mask,
    pixel_covariances,
    projection_uncertainty,
    remove_similarity,
)
from stcvision.calibration.target_views import TargetViews, board_points

__all__ = ["TRUE_MEI", "coverage", "simulated_views"]

#: the simulated camera: the unified model's (xi, fu, fv, pu, pv, k1, k2, p1, p2)
TRUE_MEI = (1.05, 407.0, 409.0, 630.0, 431.0, -0.01, 0.012, 0.002, -0.001)
IMAGE_SIZE = (1280, 960)
#: the simulated board: inner corners and spacing (the sample's)
BOARD = (9, 6)
SPACING = 0.2
#: the corners' noise (px, each coordinate)
NOISE_PX = 0.5
#: the floor's height below the viewpoint, in the board's units, and the distances checked
FLOOR_HEIGHT = 1.0
FLOOR_DISTANCES = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)


def simulated_views(seed: int, n_views: int = 8, *, params=TRUE_MEI, noise_px: float = NOISE_PX) -> TargetViews:
    """``n_views`` views of the board in random poses that the camera sees whole: the board's
    centre 1-2.5 units away at up to 100 degrees from the axis, tilted up to 50 degrees."""
    import cv2

    rng = np.random.default_rng(seed)
    obj = board_points("chessboard", *BOARD, SPACING)
    centre = obj.mean(axis=0)
    objs, imgs = [], []
    w, h = IMAGE_SIZE
    while len(objs) < n_views:
        al, az = math.radians(rng.uniform(10, 100)), rng.uniform(-math.pi, math.pi)
        direction = np.array([math.sin(al) * math.cos(az), math.sin(al) * math.sin(az), math.cos(al)])
        dist = rng.uniform(1.0, 2.5)
        # the board faces the camera, then tilts
        z = -direction
        x = np.cross([0.0, 0.0, 1.0] if abs(z[2]) < 0.9 else [1.0, 0.0, 0.0], z)
        x /= np.linalg.norm(x)
        R = np.column_stack([x, np.cross(z, x), z])
        tilt = cv2.Rodrigues(rng.normal(0, 1, 3) * math.radians(25))[0]
        R = R @ tilt
        pc = (obj - centre) @ R.T + direction * dist
        uv = project_points("mei", params, pc, IMAGE_SIZE)
        if not np.isfinite(uv).all() or (uv < 5).any() or (uv[:, 0] > w - 6).any() or (uv[:, 1] > h - 6).any():
            continue
        objs.append(obj)
        imgs.append(uv + rng.normal(0, noise_px, uv.shape))
    return TargetViews(tuple(objs), tuple(imgs), IMAGE_SIZE, tuple(f"view {i}" for i in range(n_views)))


def coverage(seeds, *, n_views: int = 8, model: str = "mei") -> dict:
    """Over the simulated calibrations of ``seeds``: the share of image points (fixed rays where
    the board was seen) and of floor points whose true error lies within the 95 % bounds."""
    img_in, img_n, floor_in, floor_n, mount_in = 0, 0, 0, 0, 0
    psi = np.linspace(-math.pi, math.pi, 12, endpoint=False)
    for seed in seeds:
        views = simulated_views(seed, n_views)
        fit = _as_reported(views, fit_target(views, model))
        m = projection_uncertainty(fit, views, grid=16)
        uu, vv = np.meshgrid(m.u, m.v)
        inside = observed_mask(m)
        uv = np.column_stack([uu[inside], vv[inside]])
        rays = _true_rays(uv)
        err = fit.project(rays) - project_points("mei", TRUE_MEI, rays, IMAGE_SIZE)
        S = pixel_covariances(fit, rays)
        ok = np.isfinite(err).all(axis=1)
        d2 = np.einsum("ni,nij,nj->n", err[ok], np.linalg.inv(S[ok]), err[ok])
        img_in += int((d2 <= K95**2).sum())
        img_n += int(ok.sum())
        rho = np.repeat(FLOOR_DISTANCES, len(psi))
        ps = np.tile(psi, len(FLOOR_DISTANCES))
        P = np.column_stack([rho * np.cos(ps), rho * np.sin(ps), np.full(len(rho), FLOOR_HEIGHT)])
        uvf = project_points("mei", TRUE_MEI, P, IMAGE_SIZE)  # the true model's axis is z
        ok = np.isfinite(uvf).all(axis=1)
        e = floor_points(fit, uvf[ok], FLOOR_HEIGHT) - P[ok, :2]
        Sf = floor_covariances(fit, uvf[ok], FLOOR_HEIGHT)
        d2 = np.einsum("ni,nij,nj->n", e, np.linalg.inv(Sf), e)
        floor_in += int((d2 <= K95**2).sum())
        floor_n += int(ok.sum())
        # with the mount fitted to the floor (height and forward angle): what it leaves
        e = remove_similarity(e, P[ok, :2])
        Sf = floor_covariances(fit, uvf[ok], FLOOR_HEIGHT, mount_fitted=True)
        d2 = np.einsum("ni,nij,nj->n", e, np.linalg.inv(Sf), e)
        mount_in += int((d2 <= K95**2).sum())
    return {
        "seeds": len(list(seeds)),
        "image_points": img_n,
        "image_coverage": img_in / img_n,
        "floor_points": floor_n,
        "floor_coverage": floor_in / floor_n,
        "floor_coverage_mount_fitted": mount_in / floor_n,
    }


def _as_reported(views, fit):
    """The fit with the uncertainty ``calibrate target`` reports for it: widened by the model
    error its halves measure (:func:`stcvision.calibration.target.model_error_inflation`)."""
    from stcvision.calibration.target import inflate, model_error_inflation
    from stcvision.calibration.target_uncertainty import cross_validation_diff

    try:
        cv = cross_validation_diff(views, fit)
    except (np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:  # a half too weak to fit, as there
        cv = {"failed": str(exc)}
    return inflate(fit, model_error_inflation(cv))


def _true_rays(uv: np.ndarray) -> np.ndarray:
    from stcvision.calibration.target_fit import unproject_pixels

    return unproject_pixels("mei", TRUE_MEI, uv, IMAGE_SIZE)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=200)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument("--model", default="mei")
    ap.add_argument(
        "--simulator", action="store_true", help="views of the simulator's spherical-mirror camera (12 a calibration)"
    )
    ap.add_argument(
        "--write-points",
        metavar="FILE.xml",
        help="write one calibration's views of the simulator's camera (seed --first-seed) as a points file",
    )
    ap.add_argument("--force", action="store_true", help="overwrite --write-points")
    a = ap.parse_args(argv)
    if a.write_points:
        from stcvision.calibration.target_views import write_points_file

        views, _ = simulator_views(a.first_seed)
        write_points_file(a.write_points, views, overwrite=a.force)
        print(f"wrote {a.write_points}: {len(views)} views, {views.n_points} points of the simulator's camera")
        return
    if a.simulator:
        r = simulator_coverage(range(a.first_seed, a.first_seed + a.seeds), model=a.model)
        print(
            f"{a.seeds} calibrations of the simulator's camera ({a.model}, 12 views each, median RMS "
            f"{r['rms_px_median']:.3f} px): the 95 % floor bound holds the truth at "
            f"{100 * r['floor_coverage']:.1f} % (binomial 95 % interval {100 * r['floor_coverage_ci95'][0]:.1f}-"
            f"{100 * r['floor_coverage_ci95'][1]:.1f} %) of {r['floor_points']:,} floor points (0.1-0.9 m); "
            f"median floor error {r['error_mm_median']:.2f} mm; models used {r['models']}"
        )
        return
    r = coverage(range(a.first_seed, a.first_seed + a.seeds), n_views=a.views, model=a.model)
    print(
        f"{r['seeds']} simulated calibrations ({a.model}, {a.views} views each): the 95 % bound holds the truth at "
        f"{100 * r['image_coverage']:.1f} % of {r['image_points']:,} image points and "
        f"{100 * r['floor_coverage']:.1f} % of {r['floor_points']:,} floor points ("
        f"{100 * r['floor_coverage_mount_fitted']:.1f} % with the mount fitted to the floor)"
    )


# ---------------------------------------------------------------------------- the simulator's camera
#: target views of the simulator's camera: a 9x6 board of 5 cm squares laid flat, on the floor
#: and raised on blocks up to 4 cm (the heights alternate), anywhere 0.15-0.6 m from the robot
SIM_BOARD_SPACING_M = 0.05
SIM_HEIGHTS_M = (0.0, 0.02, 0.04)
SIM_NOISE_PX = 0.3


def simulator_views(seed: int, n_views: int = 12, *, noise_px: float = SIM_NOISE_PX):
    """Views of a flat board seen by the simulator's ray-traced spherical-mirror camera (a
    webcam looking up into the mirror: not a central camera). A board raised by z is the floor
    of the same camera z lower (its body as much lower), which the simulator projects exactly.
    The first view lies on the floor; returned with its placement (board centre in the robot
    frame (m) and turn (rad)), which ties the fit's frame to the floor."""
    from stcvision.calibration.target_views import MIN_POINTS_PER_VIEW
    from stcvision.sim_camera.optics import MirrorCameraParams, project_floor_points

    rng = np.random.default_rng(seed)
    base = MirrorCameraParams()
    obj = board_points("chessboard", *BOARD, SIM_BOARD_SPACING_M)
    mid = obj[:, :2].mean(axis=0)
    objs, imgs, first = [], [], None
    while len(objs) < n_views:
        z = SIM_HEIGHTS_M[len(objs) % len(SIM_HEIGHTS_M)]
        turn, az, dist = rng.uniform(-math.pi, math.pi), rng.uniform(-math.pi, math.pi), rng.uniform(0.15, 0.6)
        c = np.array([dist * math.cos(az), dist * math.sin(az)])
        rot = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
        xy = (obj[:, :2] - mid) @ rot.T + c
        p = base.replace(camera_height_m=base.camera_height_m - z, body_height_m=base.body_height_m - z)
        uv, ok = project_floor_points(p, xy)
        if ok.sum() < max(MIN_POINTS_PER_VIEW, len(obj) // 2):
            continue
        if first is None:
            first = (c, turn)
        objs.append(obj[ok])
        imgs.append(uv[ok] + rng.normal(0, noise_px, (int(ok.sum()), 2)))
    size = (base.width_px, base.height_px)
    return TargetViews(tuple(objs), tuple(imgs), size, tuple(f"view {i}" for i in range(n_views))), first


def _floor_of_first_view(fit, x: np.ndarray, uv: np.ndarray, placement) -> np.ndarray:
    """Pixels -> robot-frame floor points through the plane of the first view (its pose in
    ``x[n:n + 6]`` with the intrinsics ``x[:n]``), placed on the floor as ``placement`` says."""
    import cv2

    from stcvision.calibration.target_fit import unproject_pixels

    n = len(fit.params)
    d = unproject_pixels(fit.model, x[:n], uv, fit.image_size_px)
    R = cv2.Rodrigues(np.asarray(x[n : n + 3], float))[0]
    t = np.asarray(x[n + 3 : n + 6], float)
    nrm = R[:, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        s = (nrm @ t) / (d @ nrm)
    b = (s[:, None] * d - t) @ R  # board coordinates
    mid = board_points("chessboard", *BOARD, SIM_BOARD_SPACING_M)[:, :2].mean(axis=0)
    c, turn = placement
    rot = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
    return (b[:, :2] - mid) @ rot.T + c


def _chosen_fit(views, model: str):
    """The fit of ``model``, or with ``"chosen"`` the model ``calibrate target`` picks
    (:func:`~stcvision.calibration.target.choose_model` on the
    :data:`~stcvision.calibration.target_options.DEFAULT_FOLDS`-fold held-out errors); with its name."""
    from stcvision.calibration.target import choose_model
    from stcvision.calibration.target_fit import heldout_rms
    from stcvision.calibration.target_options import DEFAULT_FOLDS, MODELS

    if model != CHOSEN:
        return fit_target(views, model), model
    fits = {m: fit_target(views, m) for m in MODELS}
    best = choose_model({m: heldout_rms(views, f, DEFAULT_FOLDS)[1] for m, f in fits.items()}, views)
    return fits[best], best


#: ``--model`` of the simulator's coverage for the model ``calibrate target`` would choose
CHOSEN = "chosen"


def _floor_check(seed: int, model: str, xy: np.ndarray, uv: np.ndarray, n_views: int) -> dict:
    """One calibration of the simulator's camera: its floor points inside their 95 % bound."""
    views, placement = simulator_views(seed, n_views)
    fit, name = _chosen_fit(views, model)
    fit = _as_reported(views, fit)
    x0 = np.concatenate([fit.params, fit.poses[0]])
    e = _floor_of_first_view(fit, x0, uv, placement) - xy
    J = np.empty((len(uv), 2, len(x0)))
    steps = derivative_steps(x0, np.sqrt(np.diag(fit.cov_first_view)))
    for j in range(len(x0)):
        xp, xm = x0.copy(), x0.copy()
        xp[j] += steps[j]
        xm[j] -= steps[j]
        fp, fm = (_floor_of_first_view(fit, x, uv, placement) for x in (xp, xm))
        J[:, :, j] = (fp - fm) / (2 * steps[j])
    S = np.einsum("nij,jk,nlk->nil", J, fit.cov_first_view, J)
    good = np.isfinite(e).all(axis=1)
    # a point the fit gives no floor point for, or whose bound is degenerate (a flat or
    # undefined covariance), holds no error: it counts, outside the bound
    bounded = good & np.isfinite(S).all(axis=(1, 2))
    bounded[bounded] &= np.linalg.det(S[bounded]) > 0
    d2 = np.einsum("ni,nij,nj->n", e[bounded], np.linalg.inv(S[bounded]), e[bounded])
    return {
        "model": name,
        "inside": int((d2 <= K95**2).sum()),
        "points": len(uv),
        "errors_mm": 1000 * np.hypot(*e[good].T),
        "rms_px": fit.rms_px,
    }


def simulator_coverage(seeds, *, model: str = "mei", n_views: int = 12) -> dict:
    """Over calibrations of the simulator's camera from ``simulator_views``: the share of floor
    points (0.1-0.9 m, every 30 degrees) whose true error lies within the 95 % floor bound (the
    intrinsics' and the floor view's pose's joint covariance, widened as ``calibrate target``
    reports it), with its exact binomial 95 % interval (the points of one calibration share its
    errors, so the interval is narrower than the calibrations alone would give), the errors'
    median (mm), and which model each calibration used (``model`` ``"chosen"``: the one
    ``calibrate target`` picks by held-out RMS)."""
    from scipy.stats import binomtest

    from stcvision.calibration.target_uncertainty import FLOOR_DISTANCES_M
    from stcvision.sim_camera.optics import MirrorCameraParams, project_floor_points

    base = MirrorCameraParams()
    psi = np.linspace(-math.pi, math.pi, 12, endpoint=False)
    rho = np.repeat(FLOOR_DISTANCES_M, len(psi))
    ps = np.tile(psi, len(FLOOR_DISTANCES_M))
    xy = np.column_stack([rho * np.cos(ps), rho * np.sin(ps)])
    uv, ok = project_floor_points(base, xy)
    xy, uv = xy[ok], uv[ok]
    runs = [_floor_check(seed, model, xy, uv, n_views) for seed in seeds]
    inside, n = sum(r["inside"] for r in runs), sum(r["points"] for r in runs)
    ci = binomtest(inside, n).proportion_ci(0.95)
    errs = np.concatenate([r["errors_mm"] for r in runs])
    return {
        "calibrations": len(runs),
        "floor_points": n,
        "floor_coverage": inside / n,
        "floor_coverage_ci95": [float(ci.low), float(ci.high)],
        "per_calibration_coverage": [round(r["inside"] / r["points"], 4) for r in runs],
        "models": {m: sum(r["model"] == m for r in runs) for m in sorted({r["model"] for r in runs})},
        "error_mm_median": float(np.median(errs)) if len(errs) else float("nan"),
        "rms_px_median": float(np.median([r["rms_px"] for r in runs])),
    }


if __name__ == "__main__":
    main()
