"""The red lights: blobs of the obstacle image (red-light pixels after the channel separation),
their centroids, areas and peaks."""

from __future__ import annotations

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
    """Blobs of the (already thresholded) obstacle image: outer contours and their moments.
    ``peak_dn`` is per pixel (window sums are divided by ``window_area``)."""
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
    """``out`` (uint8, ``img``'s shape) 255 where ``img`` is above 0, else 0 (``cv2.compare(img,
    0, CMP_GT)``); returns how many (``cv2.countNonZero``), in one pass."""
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
    """:func:`stcvision.stages.find_red`'s blobs from their contours (contour ``k``: the points
    ``pts[starts[k]:starts[k + 1]]``, (T, 2) integers, as ``cv2.findContours`` gives them):
    the area ``m00`` and first moments of each (``cv2.moments`` of the polygon: OpenCV's
    contour sums, exact in float64 for integer points, then scaled by +-1/2 and +-1/6 by the
    sign of the area; zero for an area within ``FLT_EPSILON`` of 0); a blob's area is the
    larger of that and its number of points (a thin blob has none), and those under
    ``min_area`` are dropped; its position the centroid, or the mean of its points where the
    area is 0; its peak the largest value of ``obstacle`` in its bounding box
    (``cv2.boundingRect``) over ``window_area``. Returns (xy (M, 2), peak (M,), area (M,))."""
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
