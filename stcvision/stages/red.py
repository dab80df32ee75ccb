"""The red stage: the red lights, white lights told apart, and the far red lights.

The red lights are blobs of the obstacle image (red-light pixels after the channel
separation), with their centroids, areas and peaks; white lights are told apart from red ones
on the raw frame; the far red lights (landmarks) are found in the wide ground view and refined
on the full-resolution mirror image.

:func:`read_red` is the stage as the pipeline runs it; :func:`find_red` the blob search alone,
its contour moments computed by the compiled :func:`blobs`, bit for bit ``cv2.moments``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numba
import numpy as np

from stcvision.errors import BadInputError
from stcvision.stages.common import SUM_DTYPES, check_image


@dataclass(frozen=True, kw_only=True, slots=True)
class RedParams:
    """Red-light blobs in the obstacle image: connected areas of at least ``min_area_px``."""

    min_area_px: int = 2


@dataclass(frozen=True, eq=False)
class RedLights:
    """Red blobs: ``xy_px`` (M, 2) ground-view centroids, ``peak_dn`` (M,), ``area_px`` (M,)."""

    xy_px: np.ndarray
    peak_dn: np.ndarray
    area_px: np.ndarray

    def __len__(self) -> int:
        return len(self.peak_dn)


def find_red(obstacle: np.ndarray, params: RedParams = RedParams(), *, window_area: int = 1) -> RedLights:
    """Find the blobs of the (already thresholded) obstacle image: outer contours and their moments.

    Parameters
    ----------
    obstacle : numpy.ndarray
        2-D obstacle image, uint8 or window sums, at least 2 x 2.
    params : RedParams
        The least blob area (px).
    window_area : int
        Pixels per sum: ``peak_dn`` is per pixel (window sums are divided by it).

    Returns
    -------
    RedLights
        Each blob's position (px), peak (DN per pixel) and area (px).

    Raises
    ------
    BadInputError
        When ``obstacle`` is not a 2-D uint8 image or window sums of at least 2 x 2.
    """
    check_image(obstacle, "obstacle image (uint8, or window sums)", (np.uint8, *SUM_DTYPES), ndims=(2,))
    if min(obstacle.shape) < 2:  # OpenCV takes a 1 x 1 array for a scalar and fails (fuzzing)
        raise BadInputError(f"obstacle image must be at least 2x2 pixels, got {obstacle.shape}")
    binary = np.empty(obstacle.shape, np.uint8)  # cv2.compare(obstacle, 0, CMP_GT), counted
    if not nonzero_mask(obstacle, binary):  # no red light in view (most frames): no contour pass
        return RedLights(np.zeros((0, 2)), np.zeros(0), np.zeros(0))
    contours, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return RedLights(np.zeros((0, 2)), np.zeros(0), np.zeros(0))
    # every contour's moments, area, position and peak in one call (blobs: cv2.moments'
    # and cv2.boundingRect's own arithmetic)
    starts = np.zeros(len(contours) + 1, np.int64)
    np.cumsum([len(c) for c in contours], out=starts[1:])
    xy, peak, area = blobs(
        obstacle, np.concatenate(contours).reshape(-1, 2), starts, float(params.min_area_px), float(window_area)
    )
    return RedLights(xy, peak, area)


@numba.njit(cache=True)
def nonzero_mask(img, out):
    """Mark the pixels above 0 and count them, in one pass.

    ``out`` (uint8, ``img``'s shape) 255 where ``img`` is above 0, else 0 (``cv2.compare(img,
    0, CMP_GT)``); returns how many (``cv2.countNonZero``), in one pass.
    """
    h, w = img.shape
    n = 0
    for y in range(h):
        row, o = img[y], out[y]
        for x in range(w):
            v = row[x] > 0
            o[x] = 255 if v else 0
            n += v
    return n


@numba.njit(cache=True)
def blobs(obstacle, pts, starts, min_area, window_area):
    """Measure the blobs of :func:`stcvision.stages.find_red` from their contours.

    :func:`stcvision.stages.find_red`'s blobs from their contours (contour ``k``: the points
    ``pts[starts[k]:starts[k + 1]]``, (T, 2) integers, as ``cv2.findContours`` gives them):
    the area ``m00`` and first moments of each (``cv2.moments`` of the polygon: OpenCV's
    contour sums, exact in float64 for integer points, then scaled by +-1/2 and +-1/6 by the
    sign of the area; zero for an area within ``FLT_EPSILON`` of 0); a blob's area is the
    larger of that and its number of points (a thin blob has none), and those under
    ``min_area`` are dropped; its position the centroid, or the mean of its points where the
    area is 0; its peak the largest value of ``obstacle`` in its bounding box
    (``cv2.boundingRect``) over ``window_area``. Returns (xy (M, 2), peak (M,), area (M,)).
    """
    nc = len(starts) - 1
    xy = np.zeros((nc, 2))
    peak = np.zeros(nc)
    area = np.zeros(nc)
    m = 0
    for k in range(nc):
        a, b = starts[k], starts[k + 1]
        xi_1, yi_1 = float(pts[b - 1, 0]), float(pts[b - 1, 1])
        a00 = 0.0
        a10 = 0.0
        a01 = 0.0
        sx = 0.0
        sy = 0.0
        x0 = x1 = pts[a, 0]
        y0 = y1 = pts[a, 1]
        for i in range(a, b):
            xi, yi = float(pts[i, 0]), float(pts[i, 1])
            dxy = xi_1 * yi - xi * yi_1
            a00 += dxy
            a10 += dxy * (xi_1 + xi)
            a01 += dxy * (yi_1 + yi)
            xi_1, yi_1 = xi, yi
            sx += xi
            sy += yi
            x0 = min(x0, pts[i, 0])
            x1 = max(x1, pts[i, 0])
            y0 = min(y0, pts[i, 1])
            y1 = max(y1, pts[i, 1])
        m00 = m10 = m01 = 0.0
        if abs(a00) > 1.1920928955078125e-07:  # FLT_EPSILON
            h, s6 = (0.5, 0.16666666666666666) if a00 > 0 else (-0.5, -0.16666666666666666)
            m00, m10, m01 = a00 * h, a10 * s6, a01 * s6
        ar = max(m00, float(b - a))
        if ar < min_area:
            continue
        if m00 > 0:
            xy[m, 0], xy[m, 1] = m10 / m00, m01 / m00
        else:
            xy[m, 0], xy[m, 1] = sx / (b - a), sy / (b - a)
        best = obstacle[y0, x0]
        for yy in range(y0, y1 + 1):
            for xx in range(x0, x1 + 1):
                if obstacle[yy, xx] > best:
                    best = obstacle[yy, xx]
        peak[m] = float(best) / window_area
        area[m] = ar
        m += 1
    return xy[:m], peak[:m], area[:m]


@dataclass(frozen=True, eq=False)
class RedReading:
    """What the red stage gives the cell observation.

    ``lights``: the red lights of the main ground view (white lights removed); ``white_m``:
    (N, 2) robot-frame positions (m) of the white lights removed; ``landmark_px``: the far red
    lights as pixels of the main ground view (beyond its edges too), None without a wide view.
    """

    lights: RedLights
    white_m: np.ndarray
    landmark_px: np.ndarray | None


def read_red(
    obstacle: np.ndarray,
    frame: np.ndarray,
    params: RedParams,
    *,
    window_area: int,
    profile,
    dark: np.ndarray | None = None,
    pedestal: float = 0.0,
    red_channel: np.ndarray | None = None,
    white_blue_ratio: float | None = None,
    wide: tuple[np.ndarray, Callable] | None = None,
) -> RedReading:
    """Read the red lights of the ground view, white lights removed, and the far ones.

    The red stage: the red lights of the ground view, white lights removed, and the far ones.

    Parameters
    ----------
    obstacle : (S, S) window sums
        The main ground view's obstacle image.
    frame : (H, W, 3) uint8 or uint16
        The raw frame (the white test reads its blue and red).
    params : RedParams
    window_area : int
        Pixels per window sum.
    profile : Profile
        The camera's mirror model (robot frame to image and ground view, and back).
    dark : (H, W, 3), optional
        The dark frame the white test subtracts.
    pedestal : float
        The pedestal kept by the dark subtraction (the far lights' refinement starts above it).
    red_channel : (h, w)
        The dark-subtracted red of the part of the mirror image the stages read (needed with
        ``wide``).
    white_blue_ratio : float, optional
        A light whose blue is at least this fraction of its red is white, not red (None: off).
    wide : (image, callable), optional
        The wide view's obstacle image and its ground pixels to robot frame: search far lights
        there (:func:`far_lights`).

    Returns
    -------
    RedReading
    """
    red = find_red(obstacle, params, window_area=window_area)
    white_m = np.zeros((0, 2))
    if white_blue_ratio is not None:
        xy_m = profile.ground_to_robot(red.xy_px) if len(red) else np.zeros((0, 2))
        white = white_lights(frame, dark, profile.robot_to_image(xy_m), white_blue_ratio)
        white_m = xy_m[white]
        red = RedLights(red.xy_px[~white], red.peak_dn[~white], red.area_px[~white])
    landmark_px = None
    if wide is not None:
        landmark_px = far_lights(
            wide[0],
            wide[1],
            frame,
            params,
            window_area=window_area,
            profile=profile,
            dark=dark,
            pedestal=pedestal,
            red_channel=red_channel,
            white_blue_ratio=white_blue_ratio,
        )
    return RedReading(red, white_m, landmark_px)


def white_lights(
    frame: np.ndarray, dark: np.ndarray | None, uv: np.ndarray, blue_ratio: float, *, half: int = 4
) -> np.ndarray:
    """Tell which lights are white, not red.

    Which lights at image points ``uv`` (N, 2) are white, not red: the blue of the
    (2 ``half`` + 1)-pixel square around each, dark-subtracted, at least ``blue_ratio`` times
    its red (a red LED's blue is a few per cent of its red; a white lamp's is about equal).

    Returns
    -------
    (N,) bool
    """
    h, w = frame.shape[:2]
    out = np.zeros(len(uv), bool)
    for i, (u, v) in enumerate(uv):
        if not (np.isfinite(u) and np.isfinite(v)):
            continue
        u0, v0 = int(round(u)), int(round(v))
        sl = (slice(max(v0 - half, 0), min(v0 + half + 1, h)), slice(max(u0 - half, 0), min(u0 + half + 1, w)))
        patch = frame[sl].astype(np.float32)
        if dark is not None:
            patch -= dark[sl]
        b, r = float(patch[..., 0].sum()), float(patch[..., 2].sum())
        out[i] = r > 0 and b >= blue_ratio * r
    return out


def far_lights(
    wide_obstacle: np.ndarray,
    wide_to_robot: Callable,
    frame: np.ndarray,
    params: RedParams,
    *,
    window_area: int,
    profile,
    dark: np.ndarray | None,
    pedestal: float,
    red_channel: np.ndarray,
    white_blue_ratio: float | None,
) -> np.ndarray:
    """Find the red lights out to the landmark range, for the landmark fit.

    Red lights out to the landmark range, for the landmark fit, as ground-view pixels of the
    main view (beyond its edges too): found in the wide, coarse view's obstacle image
    ``wide_obstacle`` (its pixels to robot frame by ``wide_to_robot``) and refined on the
    dark-subtracted red channel ``red_channel`` (:func:`refine_lights`), white ones removed
    (:func:`white_lights`). Arguments as :func:`read_red`'s.

    Returns
    -------
    (N, 2) float
    """
    far = find_red(wide_obstacle, params, window_area=window_area)
    xy_m = refine_lights(red_channel, pedestal, wide_to_robot(far.xy_px), profile) if len(far) else np.zeros((0, 2))
    if white_blue_ratio is not None and len(xy_m):
        xy_m = xy_m[~white_lights(frame, dark, profile.robot_to_image(xy_m), white_blue_ratio)]
    return profile.robot_to_ground(xy_m)


def refine_lights(red: np.ndarray, pedestal: float, xy_m: np.ndarray, profile, *, half: int = 6) -> np.ndarray:
    """Refine the positions of red lights found in the wide view on the mirror image.

    Robot-frame positions of red lights found in the coarse wide view, refined on the
    full-resolution mirror image ``red`` (dark-subtracted, ``pedestal`` kept): the centroid of
    the pixels above half the peak in a patch around each (a far light covers a few pixels there,
    each ~2 cm of floor at 0.85 m, so the coarse view alone is off by up to a centimetre). Lights
    that cannot be refined (at the image edge, nothing above the pedestal) are dropped.

    Returns
    -------
    (N, 2) float
    """
    uv = profile.robot_to_image(xy_m)
    h, w = red.shape
    ped = float(pedestal)
    out = []
    for u, v in uv:
        if not (np.isfinite(u) and np.isfinite(v)):
            continue
        u0, v0 = int(round(u)), int(round(v))
        if u0 - half < 0 or v0 - half < 0 or u0 + half >= w or v0 + half >= h:
            continue
        patch = red[v0 - half : v0 + half + 1, u0 - half : u0 + half + 1].astype(np.float32) - ped
        top = float(patch.max())
        if top <= 0:
            continue
        wgt = np.maximum(patch - 0.5 * top, 0.0)
        yy, xx = np.mgrid[-half : half + 1, -half : half + 1]
        tot = float(wgt.sum())
        out.append((u0 + float((xx * wgt).sum()) / tot, v0 + float((yy * wgt).sum()) / tot))
    if not out:
        return np.zeros((0, 2))
    xy = profile.image_to_robot(np.array(out))
    return xy[np.isfinite(xy).all(axis=1)]
