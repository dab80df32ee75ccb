"""Find the mirror's rim in a catadioptric image (the first step of the transformation
calibration, and useful on any catadioptric image).

Edges (Canny on a smoothed grey image) vote for circles: RANSAC draws three edge points at a
time, and a candidate circle scores by *coverage* -- the fraction of its visible circumference
(in one-degree bins) that has an edge point within ``tol_px`` -- so the long, complete rim beats
the arcs of the scene inside the mirror. The winner is refined by least squares on its inliers
(geometric distance), and an ellipse is fitted to the same points (a tilted mirror's rim is an
ellipse).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stcvision.errors import BadInputError

__all__ = ["RimFit", "check_rim_matches", "detect_rim"]


@dataclass(frozen=True)
class RimFit:
    """The rim circle: ``center_px`` (u, v), ``radius_px``, RMS distance of the inlier edge
    points from it (``residual_px``), ``coverage`` of the visible circumference, and the ellipse
    fitted to the same points (``ellipse_center_px``, ``ellipse_axes_px`` (full lengths),
    ``ellipse_angle_deg``)."""

    center_px: tuple[float, float]
    radius_px: float
    residual_px: float
    coverage: float
    n_points: int
    ellipse_center_px: tuple[float, float]
    ellipse_axes_px: tuple[float, float]
    ellipse_angle_deg: float

    def to_dict(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}


def _coverage(pts, c, r, shape, tol):
    h, w = shape
    d = np.abs(np.hypot(pts[:, 0] - c[0], pts[:, 1] - c[1]) - r)
    inl = d < tol
    ang = np.degrees(np.arctan2(pts[inl, 1] - c[1], pts[inl, 0] - c[0])).astype(int) % 360
    hit = np.zeros(360, bool)
    hit[ang] = True
    a = np.radians(np.arange(360) + 0.5)
    visible = (
        (c[0] + r * np.cos(a) >= 2)
        & (c[0] + r * np.cos(a) <= w - 3)
        & (c[1] + r * np.sin(a) >= 2)
        & (c[1] + r * np.sin(a) <= h - 3)
    )
    if visible.sum() < 90:
        return 0.0, inl
    return float((hit & visible).sum() / visible.sum()), inl


#: what makes a circle of edge points a rim, not texture (docs/explanation/calibration.md, "Rim"):
#: it covers at least this share of its visible circumference...
MIN_COVERAGE = 0.5
#: ...its edge points lie within this share of the inlier band's half-width (points drawn at random
#: in the band have an RMS distance of tol/sqrt(3) = 0.58 tol; a real rim's sit within ~0.2 tol)...
MAX_RESIDUAL_FRAC = 0.45
#: ...and edge points are this many times denser on the circle than in the quieter of the two bands
#: beside it (in random noise or a busy texture, edges are as dense everywhere)
MIN_EDGE_CONTRAST = 3.0


def _check_real_rim(pts, c, r, coverage: float, residual_px: float, tol_px: float) -> None:
    """Refuse, with the reason, a best circle that is not a real rim (noise, a checkerboard)."""
    d = np.hypot(pts[:, 0] - c[0], pts[:, 1] - c[1]) - r
    on = np.count_nonzero(np.abs(d) < tol_px) / (2 * tol_px)  # edge points per px of band width
    inside = np.count_nonzero((d <= -3 * tol_px) & (d > -5 * tol_px)) / (2 * tol_px)
    outside = np.count_nonzero((d >= 3 * tol_px) & (d < 5 * tol_px)) / (2 * tol_px)
    contrast = on / max(min(inside, outside), 0.5 / tol_px)  # the rim has a quiet side (the floor image
    # is busy just inside it, the housing quiet outside; a tilted mirror may swap them)
    why = None
    if coverage < MIN_COVERAGE:
        why = (
            f"the best circle has edges along only {100 * coverage:.0f} % of it "
            f"(expected >= {100 * MIN_COVERAGE:.0f} %)"
        )
    elif residual_px > MAX_RESIDUAL_FRAC * tol_px:
        why = f"its edge points scatter by {residual_px:.2f} px RMS (expected <= {MAX_RESIDUAL_FRAC * tol_px:.2f} px)"
    elif contrast < MIN_EDGE_CONTRAST:
        why = (
            f"edges are only {contrast:.1f}x denser on the circle than beside it (expected >= {MIN_EDGE_CONTRAST:g}x: "
            "this looks like texture or noise)"
        )
    if why:
        raise BadInputError(f"no mirror rim found: {why}; expected a lights-on catadioptric frame showing the rim")


def detect_rim(
    image: np.ndarray,
    *,
    rng: np.random.Generator | None = None,
    min_radius_frac: float = 0.3,
    max_radius_frac: float = 0.75,
    iterations: int = 3000,
    tol_px: float = 2.0,
) -> RimFit:
    """Find the rim circle of a catadioptric image ((H, W, 3) or (H, W), uint8 or uint16: see
    :func:`stcvision.calibration.frames.geometry_frame`).

    Radii are searched between ``min_radius_frac`` and ``max_radius_frac`` of the image's
    smaller side times 1... of the larger side's half-diagonal; the centre must lie in the
    middle half of the image.
    """
    from stcvision.calibration.frames import geometry_frame

    if not isinstance(image, np.ndarray) or image.dtype not in (np.uint8, np.uint16) or image.ndim not in (2, 3):
        raise BadInputError("rim detection needs an (H, W) or (H, W, 3) uint8 or uint16 image")
    image = geometry_frame(image, "rim frame")
    rng = rng or np.random.default_rng(0)
    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    h, w = grey.shape
    blur = cv2.GaussianBlur(grey, (0, 0), 1.5)
    med = float(np.median(blur))
    edges = cv2.Canny(blur, max(5.0, 0.33 * med), max(15.0, 0.66 * med) + 10)
    ys, xs = np.nonzero(edges)
    if len(xs) < 50:
        raise BadInputError("no edges found: is this a lights-on catadioptric image with the mirror's rim visible?")
    pts = np.column_stack([xs, ys]).astype(float)
    side = min(h, w)
    rmin, rmax = min_radius_frac * side, max_radius_frac * side
    best = (0.0, None)
    sample = pts if len(pts) <= 4000 else pts[rng.choice(len(pts), 4000, replace=False)]
    for _ in range(iterations):
        p = sample[rng.choice(len(sample), 3, replace=False)]
        A = np.column_stack(
            [
                2 * (p[1:] - p[0]),
            ]
        )
        b = (p[1:] ** 2).sum(1) - (p[0] ** 2).sum()
        det = np.linalg.det(A)
        if abs(det) < 1e-6:
            continue
        c = np.linalg.solve(A, b)
        r = float(np.hypot(*(p[0] - c)))
        if not (rmin <= r <= rmax and w * 0.25 <= c[0] <= w * 0.75 and h * 0.25 <= c[1] <= h * 0.75):
            continue
        cov, _ = _coverage(sample, c, r, (h, w), tol_px)
        if cov > best[0]:
            best = (cov, (c, r))
    if best[1] is None:
        raise BadInputError("no circular rim found: expected the mirror's rim as a circle in the middle of the image")
    c, r = best[1]
    from scipy.optimize import least_squares  # here: a frame with no rim (most) costs no import of it

    for _ in range(3):  # refine on all edge points near the circle
        _, inl = _coverage(pts, c, r, (h, w), tol_px * 1.5)
        q = pts[inl]
        sol = least_squares(lambda x, q=q: np.hypot(q[:, 0] - x[0], q[:, 1] - x[1]) - x[2], [c[0], c[1], r])
        c, r = sol.x[:2], float(sol.x[2])
    cov, inl = _coverage(pts, c, r, (h, w), tol_px)
    q = pts[inl]
    resid = float(np.sqrt(np.mean((np.hypot(q[:, 0] - c[0], q[:, 1] - c[1]) - r) ** 2)))
    _check_real_rim(pts, c, r, cov, resid, tol_px)
    (ex, ey), (ea, eb), eang = (
        cv2.fitEllipse(q.astype(np.float32)) if len(q) >= 5 else ((c[0], c[1]), (2 * r, 2 * r), 0.0)
    )
    return RimFit(
        (float(c[0]), float(c[1])),
        r,
        resid,
        cov,
        int(len(q)),
        (float(ex), float(ey)),
        (float(ea), float(eb)),
        float(eang),
    )


#: a frame's rim matches a profile's when its centre is within this share of the profile's rim
#: radius and its radius within this share of it (the same camera refitted moves by < 1 %)
RIM_MATCH_FRAC = 0.04


def check_rim_matches(frame: np.ndarray, profile, *, frame_name: str, profile_name: str) -> RimFit | None:
    """Refuse a frame whose mirror rim is clearly not where ``profile`` has it (a frame from another
    camera, or a mirror that moved): one line naming both. A frame without a visible rim (a dark-room
    frame) cannot be checked; returns the frame's rim, or None then."""
    try:
        rim = detect_rim(frame, iterations=1000)
    except BadInputError:
        try:  # a short RANSAC can miss a real rim (seen on a 16-bit frame): the full search decides
            rim = detect_rim(frame)
        except BadInputError:
            return None
    r0 = float(profile.rim_radius_px)
    off = float(np.hypot(rim.center_px[0] - profile.center_px[0], rim.center_px[1] - profile.center_px[1]))
    # a profile imported from a lens model alone does not know where the mirror ends: its radius is
    # the model's field of view, so only the centre can be checked
    radius_off = abs(rim.radius_px - r0) if getattr(profile, "rim_measured", True) else 0.0
    if off > RIM_MATCH_FRAC * r0 or radius_off > RIM_MATCH_FRAC * r0:
        raise BadInputError(
            f"{frame_name} shows the mirror's rim at ({rim.center_px[0]:.0f}, {rim.center_px[1]:.0f}) px, radius "
            f"{rim.radius_px:.0f} px, but {profile_name} has it at ({profile.center_px[0]:.0f}, "
            f"{profile.center_px[1]:.0f}) px, radius {r0:.0f} px: a frame from another camera? expected a profile "
            "calibrated for this camera"
        )
    return rim
