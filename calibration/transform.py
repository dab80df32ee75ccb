"""Transformation and neighbours calibration from a lights-on frame.

The robot stands on the board as it does when it enters a cell: at the centre of a sub-cell,
facing along the grid (docs/explanation/stc-geometry.md: "in the entry frame ... it stands in the
lower-right sub-cell"). In its frame (x forward, y left) the cell boundaries -- dark tape lines --
are then the lines ``x = -D/2 + 2kD`` and ``y = -D/2 + 2kD``, and their crossings are known floor
points.

1. :func:`stcvision.calibration.rim.detect_rim` finds the mirror's rim (centre and radius), unless a
   person gives the centre.
2. A coarse search fits the grid: for each of the four ways the robot can face in the image
   and a grid of radial shapes, the known grid lines are projected and scored by how many land
   on the dark-line mask (a chamfer score on its distance transform). A mirror view is always
   mirrored (one reflection), which removes the grid's diagonal symmetry.
3. Grid crossings are predicted with the best model, refined to sub-pixel with
   :func:`cv2.cornerSubPix`, and the profile is fitted to them (:func:`stcvision.calibration.fit.fit_profile`);
   predict-refine-fit repeats so farther crossings join as the model improves.
4. Neighbours calibration: the 12 corners of the five cells are found in the unwarped ground
   view the same way (straight lines there) and stored in the profile.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

import cv2
import numpy as np

from stcvision.calibration.fit import DEFAULT_VIEWPOINT_M, FitSetup, fit_profile
from stcvision.calibration.frames import geometry_frame
from stcvision.calibration.rim import RimFit, detect_rim
from stcvision.errors import BadInputError
from stcvision.profile import CORNER_ORDER, Profile, nominal_corners_px
from stcvision.stc_geometry import DEFAULT_SUBCELL_M

__all__ = [
    "TransformReport",
    "calibrate_neighbors",
    "calibrate_transform",
    "draw_preview",
    "grid_corners_m",
    "mount_uncertainty",
]


def grid_lines_m(subcell_m: float, reach_m: float = 1.2) -> tuple[np.ndarray, np.ndarray]:
    """Offsets of the cell-boundary lines ``x = a`` and ``y = b`` in the robot frame."""
    k = np.arange(-8, 9)
    v = -subcell_m / 2 + 2 * k * subcell_m
    v = v[np.abs(v) <= reach_m]
    return v, v


def grid_corners_m(subcell_m: float, *, rho_min_m: float = 0.12, rho_max_m: float = 1.0) -> np.ndarray:
    """Grid crossings (robot frame) between ``rho_min_m`` and ``rho_max_m`` from the robot."""
    xs, ys = grid_lines_m(subcell_m)
    pts = np.array([(x, y) for x in xs for y in ys])
    rho = np.hypot(pts[:, 0], pts[:, 1])
    return pts[(rho >= rho_min_m) & (rho <= rho_max_m)]


def _line_samples(subcell_m: float) -> np.ndarray:
    """Points every centimetre along the grid lines (for the chamfer score and fit)."""
    return _line_points(subcell_m, step_m=0.01, rho_min_m=0.1, skip_crossings=False)[0]


def _line_points(subcell_m: float, step_m: float = 0.005, *, rho_min_m: float = 0.12, skip_crossings: bool = True):
    """Points along every grid line (robot frame) out to 1 m, with the line's axis (0: a line
    ``x = offset``, 1: ``y = offset``) and offset; by default away from the crossings, where the
    profile across one line meets the other line."""
    xs, ys = grid_lines_m(subcell_m)
    t = np.arange(-1.2, 1.2, step_m)
    pts, axis, off = [], [], []
    for ax, offsets in ((0, xs), (1, ys)):
        for v in offsets:
            line = np.column_stack([np.full_like(t, v), t])
            pts.append(line if ax == 0 else line[:, ::-1])
            axis.append(np.full(len(t), ax))
            off.append(np.full(len(t), v))
    pts, axis, off = np.vstack(pts), np.concatenate(axis), np.concatenate(off)
    rho = np.hypot(pts[:, 0], pts[:, 1])
    keep = (rho > rho_min_m) & (rho < 1.0)
    if skip_crossings:
        other = np.where(axis == 0, pts[:, 1], pts[:, 0])
        phase = (other + subcell_m / 2) % (2 * subcell_m)  # 0 at a crossing line
        keep &= (phase > 0.03) & (phase < 2 * subcell_m - 0.03)
    return pts[keep], axis[keep], off[keep]


def _measure_line_centres(prof, bh: np.ndarray, pts: np.ndarray, axis: np.ndarray, centre, rim_r: float):
    """Image points of the dark line's centre across each predicted line point: the centroid
    of the black-hat response along the image normal of the projected line (+-5 px)."""
    along = np.where(axis[:, None] == 0, [[0.0, 0.002]], [[0.002, 0.0]])  # the line's direction
    uv = prof.robot_to_image(pts)
    uv2 = prof.robot_to_image(pts + along)
    d = uv2 - uv
    n = np.column_stack([-d[:, 1], d[:, 0]])
    n /= np.maximum(np.hypot(n[:, 0], n[:, 1]), 1e-9)[:, None]
    ts = np.arange(-5.0, 5.01, 0.5)
    su = (uv[:, 0, None] + ts[None, :] * n[:, 0, None]).astype(np.float32)
    sv = (uv[:, 1, None] + ts[None, :] * n[:, 1, None]).astype(np.float32)
    prof_vals = cv2.remap(bh, su, sv, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    base = np.minimum(prof_vals[:, 0], prof_vals[:, -1])[:, None]
    wts = np.maximum(prof_vals - base, 0)
    tot = wts.sum(1)
    t_star = (wts * ts[None, :]).sum(1) / np.maximum(tot, 1e-9)
    peak = prof_vals.max(1)
    r_img = np.hypot(uv[:, 0] - centre[0], uv[:, 1] - centre[1])
    keep = np.isfinite(uv).all(1) & np.isfinite(uv2).all(1) & (r_img < 0.93 * rim_r)
    keep &= (peak > 8.0) & (np.abs(t_star) < 3.5) & (tot > 0)
    return (uv + t_star[:, None] * n)[keep], keep


def _line_residuals_m(prof, uv, axis, off) -> np.ndarray:
    xy = prof.image_to_robot(uv)
    return np.where(axis == 0, xy[:, 0], xy[:, 1]) - off


def _chamfer_residuals(prof, dist: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """Distance (px, capped at 6) from each floor sample's image point to the nearest line pixel."""
    uv = prof.robot_to_image(samples)
    ok = np.isfinite(uv).all(1)
    out = np.full(len(samples), 6.0)
    if ok.any():
        d = cv2.remap(
            dist,
            uv[ok, 0].astype(np.float32).reshape(-1, 1),
            uv[ok, 1].astype(np.float32).reshape(-1, 1),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=6.0,
        ).ravel()
        out[ok] = np.minimum(d, 6.0)
    return out


def _chamfer_refine(prof, dist: np.ndarray, samples: np.ndarray):
    from scipy.optimize import least_squares

    h, w = dist.shape
    poly0 = np.zeros(4)
    poly0[: min(4, len(prof.theta_poly))] = prof.theta_poly[:4]
    x0 = np.concatenate([prof.center_px, [prof.forward_angle_rad, 0.0, 0.0], poly0[1:]])

    def make(x):
        return prof.replace(
            center_px=(float(x[0]), float(x[1])),
            forward_angle_rad=float(x[2]),
            axis_tilt_rad=(float(x[3]), float(x[4])),
            theta_poly=(math.pi / 2, *map(float, x[5:])),
        )

    def res(x):
        return _chamfer_residuals(make(x), dist, samples)

    sol = least_squares(res, x0, loss="soft_l1", f_scale=2.0, diff_step=1e-4, max_nfev=200)
    return make(sol.x)


def _line_mask(grey: np.ndarray, rim: RimFit) -> np.ndarray:
    bh = cv2.morphologyEx(grey, cv2.MORPH_BLACKHAT, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (9, 9)))
    h, w = grey.shape
    vv, uu = np.mgrid[0:h, 0:w]
    inside = np.hypot(uu - rim.center_px[0], vv - rim.center_px[1]) < 0.97 * rim.radius_px
    vals = bh[inside]
    thr, _ = cv2.threshold(vals.reshape(-1, 1), 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    return ((bh > thr) & inside).astype(np.uint8)


def _theta_poly(rho_mid: float, rho_far: float, H: float) -> tuple[float, ...]:
    """Quadratic theta(x), x = r / rim, through (0, pi/2), (0.45, atan H/rho_mid), (0.85, ...)."""
    x = np.array([0.0, 0.45, 0.85])
    th = np.array([math.pi / 2, math.atan2(H, rho_mid), math.atan2(H, rho_far)])
    return tuple(np.polynomial.polynomial.polyfit(x, th, 2))


@dataclass(frozen=True)
class TransformReport:
    """``line_points``: points measured on the tape lines; ``line_err_mm_*``: their floor
    distance from their lines after the fit."""

    rim: RimFit
    forward_angle_deg: float
    line_points: int
    line_err_mm_median: float
    line_err_mm_max: float

    def to_dict(self) -> dict:
        d = dict(self.__dict__)
        d["rim"] = self.rim.to_dict()
        return d


def _grid_distance(grey: np.ndarray, rim, refusal: str) -> np.ndarray:
    """Each pixel's distance (px) to the nearest grid-line pixel of the lights-on frame; refused
    when the frame shows (almost) no line."""
    mask = _line_mask(grey, rim)
    if mask.sum() < 200:
        raise BadInputError(refusal)
    return cv2.distanceTransform((1 - mask).astype(np.uint8), cv2.DIST_L2, 3)


def _line_image(grey: np.ndarray) -> np.ndarray:
    """The dark tape lines as a bright, slightly smoothed image, where their centres are measured."""
    bh = cv2.morphologyEx(grey, cv2.MORPH_BLACKHAT, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (9, 9)))
    return cv2.GaussianBlur(bh.astype(np.float32), (0, 0), 0.7)


def _chamfer_score(prof: Profile, dist: np.ndarray, samples: np.ndarray, sigma_px: float, *, inside: bool) -> float:
    """How well the profile's projected grid-line samples land on the line mask (0..1). With
    ``inside`` only samples that fall inside the image count (at least 20 % of them); otherwise
    every finite one, clipped to the image (at least 30 %)."""
    h, w = dist.shape
    uv = prof.robot_to_image(samples)
    ok = np.isfinite(uv).all(1)
    if inside:
        ok &= (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
    if ok.sum() < (0.2 if inside else 0.3) * len(samples):
        return 0.0 if inside else -1.0
    iu = np.clip(np.rint(uv[ok, 0]).astype(int), 0, w - 1)
    iv = np.clip(np.rint(uv[ok, 1]).astype(int), 0, h - 1)
    return float(np.exp(-0.5 * (dist[iv, iu] / sigma_px) ** 2).sum()) / len(samples)


def _coarse_transform(base: Profile, dist: np.ndarray, samples: np.ndarray) -> Profile | None:
    """The best of a grid of forward angles (quarter turns) and radial shapes, by chamfer score;
    None when no candidate projects enough of the grid into the image."""
    H = base.viewpoint_height_m
    best = (-1.0, None)
    for fwd in (-math.pi / 2, 0.0, math.pi / 2, math.pi):
        for rho_mid in np.geomspace(0.08, 0.6, 14):
            for rho_far in np.geomspace(0.3, 3.0, 16):
                if rho_far < 1.3 * rho_mid:
                    continue
                prof = base.replace(forward_angle_rad=fwd, mirrored=True, theta_poly=_theta_poly(rho_mid, rho_far, H))
                score = _chamfer_score(prof, dist, samples, 2.0, inside=False)
                if score > best[0]:
                    best = (score, prof)
    return best[1]


def calibrate_transform(
    frame: np.ndarray,
    *,
    subcell_m: float = DEFAULT_SUBCELL_M,
    center_px: tuple[float, float] | None = None,
    viewpoint_height_m: float = DEFAULT_VIEWPOINT_M,
    base: Profile | None = None,
    iterations: int = 3,
) -> tuple[Profile, TransformReport]:
    """Fit a profile to a lights-on frame of the board grid (see the module docstring)."""
    if not isinstance(frame, np.ndarray) or frame.dtype not in (np.uint8, np.uint16) or frame.ndim != 3:
        raise BadInputError("transformation calibration needs an (H, W, 3) uint8 or uint16 lights-on frame")
    source_sha256 = hashlib.sha256(frame.tobytes()).hexdigest()  # of the frame as given
    frame = geometry_frame(frame)
    h, w = frame.shape[:2]
    grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    rim = detect_rim(frame)
    centre = tuple(center_px) if center_px is not None else rim.center_px
    dist = _grid_distance(
        grey,
        rim,
        "no grid lines found in the frame: expected a lights-on frame of the board with its cell grid visible",
    )
    samples = _line_samples(subcell_m)
    H = viewpoint_height_m
    base = base or Profile(
        image_size_px=(w, h),
        center_px=centre,
        rim_radius_px=rim.radius_px,
        viewpoint_height_m=H,
        theta_poly=(math.pi / 2, -1.0),
        subcell_m=subcell_m,
    )

    # 1) coarse search over orientation and radial shape (chamfer score)
    prof = _coarse_transform(base.replace(center_px=tuple(centre), rim_radius_px=rim.radius_px), dist, samples)
    if prof is None:
        raise BadInputError(
            "could not fit the grid: is the robot on the board, at a sub-cell centre, facing along the grid?"
        )

    # 2) continuous chamfer refinement (centre, forward angle, axis tilt, a cubic theta): the
    # projected grid lines slide onto the line mask
    prof = _chamfer_refine(prof, dist, samples)

    # 3) dense fit along the tape lines: every 5 mm of every line the dark line's centre is
    # measured across the predicted image line, and the profile is fitted so that each
    # measured point maps onto its known floor line; measure again with the new profile
    bh = _line_image(grey)
    lpts, laxis, loff = _line_points(subcell_m)
    empty = np.zeros((0, 2))
    for it in range(iterations):
        l_uv, keep = _measure_line_centres(prof, bh, lpts, laxis, centre, rim.radius_px)
        if len(l_uv) < 100:
            raise BadInputError(f"only {len(l_uv)} points on the grid lines found; expected hundreds")
        degree = 3 if it == 0 else 6
        setup = FitSetup(image_size_px=(w, h), rim_radius_px=rim.radius_px, viewpoint_height_m=H, degree=degree)
        prof, _ = fit_profile(empty, empty, setup, base=prof, init=prof, lines=(l_uv, laxis[keep], loff[keep]))
    ferr = 1000 * np.abs(_line_residuals_m(prof, l_uv, laxis[keep], loff[keep]))
    report = TransformReport(
        rim, math.degrees(prof.forward_angle_rad), int(len(l_uv)), float(np.median(ferr)), float(ferr.max())
    )
    prov = {
        "method": "transformation calibration: rim + grid crossings of a lights-on frame",
        "frame_sha256": source_sha256,
        "subcell_m": subcell_m,
        "report": report.to_dict(),
    }
    return prof.replace(subcell_m=subcell_m, neighbour_corners_px=None, provenance=prov), report


def calibrate_neighbors(frame: np.ndarray, profile: Profile) -> tuple[Profile, np.ndarray]:
    """Find the 12 corners of the five cells in the lights-on frame's ground view and store them
    in the profile. Returns (profile, corners (12, 2) ground px)."""
    from stcvision.pipeline import Pipeline

    profile.check_frame(frame.shape)
    ground = Pipeline(profile).ground_view(geometry_frame(frame))
    grey = cv2.cvtColor(ground, cv2.COLOR_BGR2GRAY)
    nominal = nominal_corners_px(profile.subcell_m, profile.ground_px_per_m, profile.ground_size_px)
    pts = nominal.astype(np.float32).reshape(-1, 1, 2).copy()
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.01)
    found = cv2.cornerSubPix(grey, pts, (6, 6), (-1, -1), crit).reshape(-1, 2)
    moved = np.hypot(*(found - nominal).T)
    if (moved > 8).any():
        bad = [i for i in range(12) if moved[i] > 8]
        raise BadInputError(
            f"corner(s) {bad} of the 12 not found near where the transformation puts them; "
            "check the robot's pose, or give the corners with --points"
        )
    return with_corners(profile, found, method="neighbours calibration: ground-view grid corners", frame=frame), found


#: the 12 corners must be the nominal ones moved by a near-rigid map: scale within this factor of
#: the ground view's (either way), not mirrored, and off that map by at most this share of a sub-cell
CORNER_MAX_SCALE = 2.0
CORNER_MAX_RESIDUAL_SUBCELLS = 0.25


def corners_problem(profile: Profile, c: np.ndarray) -> str | None:
    """Why the (12, 2) ground-view points ``c`` cannot be the neighbour corners (coincident,
    collinear, mirrored, scaled, scrambled), or None: the affine map from the nominal corners
    must be well-conditioned and fit them."""
    from stcvision.profile import nominal_corners_px

    nominal = nominal_corners_px(profile.subcell_m, profile.ground_px_per_m, profile.ground_size_px)
    X = np.column_stack([nominal, np.ones(12)])
    A, *_ = np.linalg.lstsq(X, c, rcond=None)
    lin = A[:2].T
    sv = np.linalg.svd(lin, compute_uv=False)
    subcell_px = profile.subcell_m * profile.ground_px_per_m
    resid = float(np.sqrt(np.mean(np.sum((X @ A - c) ** 2, axis=1))))
    if sv[-1] < 1 / CORNER_MAX_SCALE or sv[0] > CORNER_MAX_SCALE:
        return (
            f"they span the grid at {sv[-1]:.2f}..{sv[0]:.2f} times its size "
            f"(coincident or collinear points?); expected within {1 / CORNER_MAX_SCALE:g}..{CORNER_MAX_SCALE:g}"
        )
    if np.linalg.det(lin) < 0:
        return "they are mirrored against the grid's corner order"
    if resid > CORNER_MAX_RESIDUAL_SUBCELLS * subcell_px:
        return (
            f"they are {resid:.1f} px RMS off the grid's shape (expected <= "
            f"{CORNER_MAX_RESIDUAL_SUBCELLS * subcell_px:.1f} px; order: {', '.join(map(str, CORNER_ORDER))})"
        )
    return None


def with_corners(profile: Profile, corners, *, method: str, frame: np.ndarray | None = None) -> Profile:
    try:
        c = np.asarray(corners, float)
    except (TypeError, ValueError):
        c = np.empty((0,))
    if c.shape != (12, 2) or not np.isfinite(c).all():
        raise BadInputError(
            "neighbours calibration needs 12 [x, y] ground-view points (finite numbers), got "
            + (f"shape {c.shape}" if c.size else "something else")
        )
    why = corners_problem(profile, c)
    if why:
        raise BadInputError(f"these 12 points are not the neighbour corners: {why}")
    prov = dict(profile.provenance)
    prov["neighbours"] = {"method": method, "corner_order": [list(p) for p in CORNER_ORDER]}
    if frame is not None:
        prov["neighbours"]["frame_sha256"] = hashlib.sha256(frame.tobytes()).hexdigest()
    return profile.replace(neighbour_corners_px=tuple(tuple(map(float, p)) for p in c), provenance=prov)


def draw_preview(frame: np.ndarray, profile: Profile) -> np.ndarray:
    """The unwarped ground view with the expected grid (cell boundaries) and the 12 corners
    drawn over it: a person checks that the drawn grid sits on the tape lines."""
    from stcvision.pipeline import Pipeline

    ground = Pipeline(profile).ground_view(geometry_frame(frame)).copy()
    xs, ys = grid_lines_m(profile.subcell_m)
    for x in xs:
        a, b = profile.robot_to_ground(np.array([[x, -1.2], [x, 1.2]]))
        cv2.line(ground, tuple(np.rint(a).astype(int)), tuple(np.rint(b).astype(int)), (0, 200, 255), 1, cv2.LINE_AA)
    for y in ys:
        a, b = profile.robot_to_ground(np.array([[-1.2, y], [1.2, y]]))
        cv2.line(ground, tuple(np.rint(a).astype(int)), tuple(np.rint(b).astype(int)), (0, 200, 255), 1, cv2.LINE_AA)
    for i, p in enumerate(profile.corners_px()):
        c = tuple(np.rint(p).astype(int))
        cv2.circle(ground, c, 4, (255, 80, 0), 1, cv2.LINE_AA)
        cv2.putText(ground, str(i), (c[0] + 4, c[1] - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (255, 80, 0), 1, cv2.LINE_AA)
    return ground


#: the chamfer score's width in the mount's coarse search (px): wide enough that a step of 4
#: degrees or 6 % of height still finds the basin
COARSE_SIGMA_PX = 6.0


def with_rim(profile: Profile, rim_radius_px: float) -> Profile:
    """The same mapping with a measured rim radius: the theta polynomial and the decentering are in
    units of the rim radius, so their coefficients are rescaled with it."""
    k = rim_radius_px / profile.rim_radius_px
    poly = tuple(c * k**i for i, c in enumerate(profile.theta_poly))
    p1, p2, *g = profile.decentering
    dec = (p1 * k, p2 * k, *(gi * k ** (2 * (i + 1)) for i, gi in enumerate(g)))
    return profile.replace(rim_radius_px=rim_radius_px, rim_measured=True, theta_poly=poly, decentering=dec)


def _mount_rim(frame: np.ndarray, profile: Profile, subcell_m: float):
    """The rim of the lights-on frame (the profile's own when the frame shows none), refused when
    it is not the model's camera's; and the profile with that rim and the board's sub-cell."""
    try:
        rim = detect_rim(frame)
        if np.hypot(rim.center_px[0] - profile.center_px[0], rim.center_px[1] - profile.center_px[1]) > 0.04 * (
            rim.radius_px
        ):
            raise BadInputError(
                f"the frame's rim centre ({rim.center_px[0]:.0f}, {rim.center_px[1]:.0f}) px is not the model's "
                f"({profile.center_px[0]:.0f}, {profile.center_px[1]:.0f}): a frame of another camera?"
            )
        profile = with_rim(profile, float(rim.radius_px)).replace(subcell_m=subcell_m)
    except BadInputError as exc:
        if "another camera" in str(exc):
            raise
        rim = RimFit(tuple(profile.center_px), profile.rim_radius_px, 0.0, 0.0, 0, tuple(profile.center_px), (0, 0), 0)
    return rim, profile.replace(subcell_m=subcell_m)


def calibrate_mount(
    frame: np.ndarray, profile: Profile, *, subcell_m: float = DEFAULT_SUBCELL_M, forward_hint_rad: float | None = None
) -> tuple[Profile, TransformReport]:
    """Fit only what a lens model cannot know -- forward angle, mirror flip, viewpoint height --
    to a lights-on frame of the grid (the robot at the calibration pose), keeping the profile's
    intrinsics (centre, ellipse, theta polynomial, decentering). The rim is measured from the
    frame when it shows one. The grid is symmetric about its diagonal through the robot (a flip
    and a quarter turn give the same lines), so of the two fits the one whose forward lies nearer
    ``forward_hint_rad`` (default: the profile's) is taken."""
    from scipy.optimize import least_squares

    if not isinstance(frame, np.ndarray) or frame.dtype not in (np.uint8, np.uint16) or frame.ndim != 3:
        raise BadInputError("the lights-on frame must be an (H, W, 3) uint8 or uint16 image")
    profile.check_frame(frame.shape, what="lights-on frame")
    source_sha256 = hashlib.sha256(frame.tobytes()).hexdigest()
    frame = geometry_frame(frame)
    grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    rim, profile = _mount_rim(frame, profile, subcell_m)
    dist = _grid_distance(
        grey, rim, "no grid lines found in the lights-on frame: expected the board's cell grid in view"
    )
    samples = _line_samples(subcell_m)
    H0 = profile.viewpoint_height_m

    def chamfer(prof, sigma_px: float = 2.0) -> float:
        return _chamfer_score(prof, dist, samples, sigma_px, inside=True)

    def refine(prof):
        def res(x):
            p = prof.replace(forward_angle_rad=float(x[0]), viewpoint_height_m=float(np.exp(x[1])))
            return _chamfer_residuals(p, dist, samples)

        x0 = [prof.forward_angle_rad, math.log(prof.viewpoint_height_m)]
        sol = least_squares(res, x0, loss="soft_l1", f_scale=2.0, diff_step=1e-4, max_nfev=200)
        return prof.replace(forward_angle_rad=float(sol.x[0]), viewpoint_height_m=float(np.exp(sol.x[1])))

    # coarse: flip x forward angle (4 degree steps) x height (0.5x..2x the given, 6 % steps: the
    # chamfer peak is ~ +-8 % wide in height, +-3 degrees in angle)
    fits = []
    for mirrored in (True, False):
        best = (0.0, None)
        for fwd in np.radians(np.arange(-180.0, 180.0, 4.0)):
            for H in H0 * np.geomspace(0.5, 2.0, 25):
                p = profile.replace(mirrored=mirrored, forward_angle_rad=float(fwd), viewpoint_height_m=float(H))
                s = chamfer(p, COARSE_SIGMA_PX)  # a wide basin for the coarse steps
                if s > best[0]:
                    best = (s, p)
        if best[1] is not None:
            p = refine(best[1])
            fits.append((chamfer(p), p))
    if not fits or max(f[0] for f in fits) < 0.2:
        raise BadInputError("could not fit the grid: is the robot on the board, at a sub-cell centre, facing along it?")
    top = max(f[0] for f in fits)
    near = [p for s, p in fits if s >= 0.9 * top]  # the diagonal's twin scores alike
    hint = profile.forward_angle_rad if forward_hint_rad is None else forward_hint_rad
    prof = min(near, key=lambda p: abs(math.remainder(p.forward_angle_rad - hint, 2 * math.pi)))
    # dense: the tape lines' centres, and forward angle and height fitted so they land on their lines
    bh = _line_image(grey)
    lpts, laxis, loff = _line_points(subcell_m)
    for _ in range(3):
        l_uv, keep = _measure_line_centres(prof, bh, lpts, laxis, prof.center_px, prof.rim_radius_px)
        if len(l_uv) < 100:
            raise BadInputError(f"only {len(l_uv)} points on the grid lines found; expected hundreds")
        ax, off = laxis[keep], loff[keep]

        def lres(x, base=prof, l_uv=l_uv, ax=ax, off=off):
            p = base.replace(forward_angle_rad=float(x[0]), viewpoint_height_m=float(np.exp(x[1])))
            return _line_residuals_m(p, l_uv, ax, off)

        sol = least_squares(
            lres, [prof.forward_angle_rad, math.log(prof.viewpoint_height_m)], loss="soft_l1", f_scale=0.003
        )
        prof = prof.replace(forward_angle_rad=float(sol.x[0]), viewpoint_height_m=float(np.exp(sol.x[1])))
    ferr = 1000 * np.abs(_line_residuals_m(prof, l_uv, ax, off))
    report = TransformReport(
        rim, math.degrees(prof.forward_angle_rad), int(len(l_uv)), float(np.median(ferr)), float(ferr.max())
    )
    prov = {
        **profile.provenance,
        "mount": {
            "method": "forward angle, mirror flip and height fitted to a lights-on frame's grid lines",
            "frame_sha256": source_sha256,
            "report": report.to_dict(),
        },
    }
    prof = prof.replace(
        forward_angle_rad=math.remainder(prof.forward_angle_rad, 2 * math.pi),
        neighbour_corners_px=None,
        provenance=prov,
    )
    prof, _ = calibrate_neighbors(frame, prof)
    return prof, report


def mount_uncertainty(frame: np.ndarray, profile: Profile) -> dict:
    """The standard deviations of a fitted mount's forward angle (degrees) and viewpoint height
    (mm) from its lights-on frame, at the fit's optimum, from the tape lines' centres measured
    across the model's lines. Points of one tape line share its errors (its width, its straightness,
    the model's error along it), so the covariance is the cluster-robust sandwich with one cluster
    a line, ``(J^T J)^-1 (sum_l J_l^T r_l r_l^T J_l) (J^T J)^-1`` (Liang & Zeger, Biometrika 1986),
    not ``s^2 (J^T J)^-1``, which would count every point as news. The intrinsics' part is in the
    floor bound."""
    frame = geometry_frame(frame)
    grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    bh = _line_image(grey)
    lpts, laxis, loff = _line_points(profile.subcell_m)
    l_uv, keep = _measure_line_centres(profile, bh, lpts, laxis, profile.center_px, profile.rim_radius_px)
    ax, off = laxis[keep], loff[keep]

    def res(x):
        p = profile.replace(forward_angle_rad=float(x[0]), viewpoint_height_m=float(x[1]))
        return _line_residuals_m(p, l_uv, ax, off)

    x0 = np.array([profile.forward_angle_rad, profile.viewpoint_height_m])
    steps = np.array([1e-5, 1e-5 * profile.viewpoint_height_m])
    J = np.column_stack([(res(x0 + e) - res(x0 - e)) / (2 * e[i]) for i, e in enumerate(np.diag(steps))])
    r = res(x0)
    ok = np.isfinite(r) & np.isfinite(J).all(axis=1)
    J, r, line = J[ok], r[ok], np.column_stack([ax[ok], np.round(off[ok], 6)])
    bread = np.linalg.inv(J.T @ J)
    meat = np.zeros((2, 2))
    lines = np.unique(line, axis=0)
    for g in lines:
        sel = (line == g).all(axis=1)
        v = J[sel].T @ r[sel]
        meat += np.outer(v, v)
    sd = np.sqrt(np.diag(bread @ meat @ bread))
    return {
        "forward_angle_deg_std": math.degrees(sd[0]),
        "viewpoint_height_mm_std": 1000 * sd[1],
        "lines": int(len(lines)),
    }
