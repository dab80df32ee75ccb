"""``calibrate target``: a camera's intrinsics from planar targets, each model fitted and tested
(in-sample and held-out reprojection error, a cross-validation diff between two halves of the
views), the chosen model's uncertainty over the image, and -- for a profile -- the mount from a
lights-on frame, the uncertainty on the floor and a verdict for the STC robot.

The model chosen (unless asked for one) is the simpler one unless the richer one's held-out error
is lower by more than its standard error (:func:`choose_model`): a model with more freedom that
only follows the views' noise does worse on views it has not seen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stcvision.calibration.target_fit import TargetFit, fit_target, heldout_rms
from stcvision.calibration.target_options import DEFAULT_FOLDS, MODELS
from stcvision.calibration.target_uncertainty import (
    CONFIDENCE,
    cross_validation_diff,
    draw_floor_uncertainty,
    draw_uncertainty,
    floor_uncertainty,
    projection_uncertainty,
    verdict,
)
from stcvision.calibration.target_views import TargetViews, detect_views, read_points_file
from stcvision.errors import BadInputError

__all__ = ["TargetResult", "calibrate_target", "choose_model", "load_views", "target_profile"]


@dataclass(frozen=True)
class TargetResult:
    """The report (JSON-ready), the chosen fit, and the uncertainty map as PNG bytes."""

    report: dict
    fit: TargetFit
    fits: dict
    views: TargetViews
    png: bytes


def load_views(source, *, camera=None, image_size=None, pattern=None, board=None, spacing=None, should_stop=None):
    """A points file, or a folder of target images (then ``pattern``, ``board`` (cols, rows) and
    ``spacing`` say what to look for)."""
    src = Path(source)
    if src.is_dir():
        if pattern is None or board is None or spacing is None:
            raise BadInputError(
                f"{src} is a folder of images: say what the target is with --pattern, --board COLSxROWS and --spacing"
            )
        return detect_views(
            src, pattern=pattern, cols=board[0], rows=board[1], spacing=spacing, should_stop=should_stop
        ), "images"
    return read_points_file(src, camera=camera, image_size=image_size), "points file"


def _params(fit: TargetFit) -> dict:
    return {n: {"value": float(v), "std": float(s)} for n, v, s in zip(fit.names, fit.params, fit.std, strict=True)}


def choose_model(per_view_heldout: dict, views: TargetViews) -> str:
    """The model to report: the simplest unless a richer one is better on views it has not seen.

    The one-standard-error rule (Breiman, Friedman, Olshen & Stone, "Classification and
    Regression Trees"; Hastie, Tibshirani & Friedman, "The Elements of Statistical Learning"): a
    model with more parameters replaces a simpler one only when its held-out mean squared error
    is lower by more than the standard error of the two's difference, paired view by view (the
    views are the units the k-fold leaves out). Two models equal to within that error are not
    told apart by these views, and the simpler one's covariance is the better conditioned (the
    polynomial's ten parameters are nearly dependent over an annulus of views, and its 95 %
    floor bound held the truth less often on simulated calibrations).

    Parameters
    ----------
    per_view_heldout : dict of str to numpy.ndarray
        Each fitted model's held-out RMS per view (px), by name.
    views : TargetViews
        The views (their point counts weigh the views).

    Returns
    -------
    str
        The chosen model's name.
    """
    w = np.array([len(p) for p in views.image_points], float)
    order = sorted(per_view_heldout, key=lambda n: (len(MODELS[n]), n))
    best = order[0]
    for name in order[1:]:
        d = np.asarray(per_view_heldout[name]) ** 2 - np.asarray(per_view_heldout[best]) ** 2
        ok = np.isfinite(d)
        if not ok.any():
            continue
        wk, dk = w[ok], d[ok]
        mean = float(np.sum(wk * dk) / wk.sum())
        se = float(np.sqrt(np.sum((wk * (dk - mean)) ** 2)) / wk.sum())
        if mean < -se:
            best = name
    return best


def model_error_inflation(cv: dict) -> float:
    """How much to widen a fit's covariance so that it accounts for what the views' noise does not.

    The covariance from the Jacobian holds the corners' noise only. When two calibrations on
    disjoint halves of the views differ by more than their covariances predict, the model does
    not follow the camera down to that noise, and the covariance alone would flatter the
    calibration (OpenCV's real omnidirectional sample: halves 8.6-9.1 px apart where 2.1 px was
    predicted). Above :data:`~stcvision.calibration.target_uncertainty.CV_RATIO_MAX` (where the
    verdict says the model does not follow the camera; below it the ratio is within what the
    halves' own sampling gives an adequate model) the measured ratio widens every standard
    deviation alike, as a Birge ratio does; otherwise nothing changes.

    Parameters
    ----------
    cv : dict
        The cross-validation of :func:`stcvision.calibration.target_uncertainty.cross_validation_diff`
        (or ``{"failed": ...}`` when a half could not be fitted: then no widening).

    Returns
    -------
    float
        The factor on the standard deviations, at least 1.
    """
    from stcvision.calibration.target_uncertainty import CV_RATIO_MAX

    ratio = cv.get("diff_over_predicted")
    ok = ratio is not None and np.isfinite(ratio) and ratio > CV_RATIO_MAX
    return float(ratio) if ok else 1.0


def inflate(fit: TargetFit, factor: float) -> TargetFit:
    """Return ``fit`` with its covariances widened by ``factor`` on the standard deviations."""
    import dataclasses

    if factor == 1.0:
        return fit
    first = None if fit.cov_first_view is None else fit.cov_first_view * factor**2
    return dataclasses.replace(fit, cov=fit.cov * factor**2, cov_first_view=first)


def calibrate_target(
    views: TargetViews, *, model: str | None = None, folds: int = DEFAULT_FOLDS, should_stop=None
) -> TargetResult:
    """Fit every model (or only ``model``), test each by k-fold over the views, take the one with
    the better held-out error by :func:`choose_model` (or ``model``), and measure its uncertainty."""
    from stcvision.fileio import figure_png

    if model is not None and model not in MODELS:
        raise BadInputError(f"--model {model!r}: expected one of {', '.join(MODELS)}")
    k = min(folds, len(views))
    if k < 2:
        raise BadInputError(f"--folds {folds}: expected at least 2")
    fits, rows = {}, {}
    for name in MODELS if model is None else (model,):
        start = fits["mei"][0] if "mei" in fits else None
        try:
            f = fit_target(views, name, start=start, should_stop=should_stop)
            held, per_view = heldout_rms(views, f, k, should_stop)
        except (np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:
            if model is not None or not fits:  # the one asked for, or the first: the user must know
                raise BadInputError(f"the {name} model could not be fitted to these views: {exc}") from None
            rows[name] = {"failed": str(exc)}  # the others are compared without it
            continue
        fits[name] = (f, held, per_view)
        rows[name] = {
            "rms_px": f.rms_px,
            "heldout_rms_px": held,
            "heldout_ratio": held / max(f.rms_px, 1e-12),
            "n_params": len(f.params),
            "params": _params(f),
        }
    for name, (f, _, _) in fits.items():
        try:
            rows[name]["cross_validation"] = cross_validation_diff(views, f, should_stop=should_stop)
        except (np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:  # a half too weak to fit
            rows[name]["cross_validation"] = {"failed": str(exc)}
    chosen = model or choose_model({n: v[2] for n, v in fits.items()}, views)
    fit, held, per_view = fits[chosen]
    cv = rows[chosen]["cross_validation"]
    inflation = model_error_inflation(cv)
    fit = inflate(fit, inflation)
    pmap = projection_uncertainty(fit, views)
    title = (
        f"{chosen} model, {len(views)} views: projection uncertainty (colour: 1 sigma; contours: "
        f"{100 * CONFIDENCE:.0f} % radius)\nin-sample RMS {fit.rms_px:.3f} px, held-out {held:.3f} px ({k}-fold)"
    )
    fig = draw_uncertainty(pmap, fit, title)
    png = figure_png(fig)
    import matplotlib.pyplot as plt

    plt.close(fig)
    report = {
        "views": len(views),
        "points": views.n_points,
        "refused_views": [{"view": n, "reason": r} for n, r in views.refused],
        "image_size_px": list(views.image_size_px),
        "model": chosen,
        "rms_px": fit.rms_px,
        "heldout_rms_px": held,
        "folds": k,
        "noise_px": fit.sigma_px,
        "params": _params(fit),
        "view_rms_px": [float(x) for x in fit.view_rms_px],
        "heldout_view_rms_px": [float(x) for x in per_view],
        "models": rows,
        "cross_validation": cv,
        "uncertainty": {
            "method": "Jacobian at the optimum, scaled by the residuals' noise"
            + (", then by the halves' measured diff over its prediction (model error)" if inflation > 1 else ""),
            "inflation": inflation,
            **pmap.summary(),
        },
    }
    return TargetResult(report, fit, {n: v[0] for n, v in fits.items()}, views, png)


def target_profile(
    fit: TargetFit,
    *,
    viewpoint_height_m: float,
    forward_angle_rad: float,
    mirrored: bool,
    rim_px: float | None,
    subcell_m: float,
    lights_on: np.ndarray | None,
    provenance: dict,
    n_views: int,
    heldout_ratio: float,
    cv_ratio: float,
):
    """The profile of the fit (as ``calibrate import`` makes one), its mount from a lights-on
    frame when given (the intrinsics kept), the floor uncertainty at the distances the robot reads,
    and the verdict; with the floor bound drawn against the distance as PNG bytes."""
    from stcvision.calibration.lens_import import profile_from_model
    from stcvision.fileio import figure_png

    prof, fid = profile_from_model(
        fit.lens_model(),
        viewpoint_height_m=viewpoint_height_m,
        forward_angle_rad=forward_angle_rad,
        mirrored=mirrored,
        rim_radius_px=rim_px,
        provenance=provenance,
    )
    prof = prof.replace(subcell_m=subcell_m)
    mount = None
    if lights_on is not None:
        from stcvision.calibration.transform import calibrate_mount, mount_uncertainty

        prof, rep = calibrate_mount(lights_on, prof, subcell_m=subcell_m)
        mount = {
            **mount_uncertainty(lights_on, prof),
            "forward_angle_deg": math.degrees(prof.forward_angle_rad),
            "viewpoint_height_m": prof.viewpoint_height_m,
            "mirrored": prof.mirrored,
            "line_points": rep.line_points,
            "line_err_mm_median": rep.line_err_mm_median,
            "line_err_mm_max": rep.line_err_mm_max,
        }
    floor = floor_uncertainty(fit, prof.viewpoint_height_m, mount_fitted=lights_on is not None)
    corners = prof.ground_to_robot(prof.corners_px())
    reach = float(np.hypot(corners[:, 0], corners[:, 1]).max())
    v = verdict(
        floor,
        subcell_m=subcell_m,
        reach_m=reach,
        n_views=n_views,
        heldout_ratio=heldout_ratio,
        cv_ratio=cv_ratio,
        mount_line_err_mm=mount["line_err_mm_median"] if mount else None,
    )
    if mount is None:
        v["advice"].append("no lights-on frame: the mount (forward angle, mirror flip, height) is as given, not fitted")
        v["ok"] = False
    import matplotlib.pyplot as plt

    fig = draw_floor_uncertainty(
        floor,
        v,
        f"floor uncertainty of the profile ({'mount fitted to a lights-on frame' if mount else 'mount as given'}): "
        f"{'good enough' if v['ok'] else 'not good enough'} for the STC robot",
    )
    floor_png = figure_png(fig)
    plt.close(fig)
    return prof, {"fidelity": fid.to_dict(), "mount": mount, "floor": floor, "verdict": v}, floor_png
