"""Dark frames: check that a frame is one (lens capped or room dark) and median-stack several.

A dark frame holds the sensor's offset, dark current and hot pixels, nothing of the scene. Two
things betray a frame that is not dark: a high typical level (the lights are on, the lens is
open; an all-white frame) and bright *spots* -- connected groups of pixels far above the typical
level (phosphor marks, a red light, a lamp in view). Hot pixels are far above the level too,
but one by one: isolated pixels are allowed, spots are not.
"""

from __future__ import annotations

import cv2
import numpy as np

from stcvision.errors import BadInputError

__all__ = ["dark_frame_problem", "median_dark"]

#: the typical (median) level of a dark frame is at most this share of full scale
MAX_MEDIAN_FRAC = 0.25
#: a pixel is bright when it is this many robust sigmas above the median, and at least
#: MIN_EXCESS_FRAC of full scale above it (the hot-pixel rule of stcvision.stages.hot_pixels)
K_SIGMA = 8.0
MIN_EXCESS_FRAC = 6.0 / 255.0
#: a spot is a connected group of at least this many bright pixels (a hot pixel is one)
MIN_SPOT_PX = 4
#: a dark frame may hold at most this share of its pixels in spots (clusters of hot pixels)
MAX_SPOT_FRAC = 5e-4


def dark_frame_problem(img: np.ndarray) -> str | None:
    """Why ``img`` ((H, W, 3) or (H, W), uint8 or uint16) is not a dark frame, or None if it is one."""
    full = float(np.iinfo(img.dtype).max)
    level = img.max(axis=2) if img.ndim == 3 else img
    v = level.reshape(-1)[::7].astype(np.float32)
    med = float(np.median(v))
    if med > MAX_MEDIAN_FRAC * full:
        return (
            f"its typical level is {med:.0f} of {full:.0f} (over {100 * MAX_MEDIAN_FRAC:.0f} % of full scale): "
            "the lights are on or the lens is open"
        )
    sigma = 1.4826 * float(np.median(np.abs(v - med)))
    bright = (level > med + max(K_SIGMA * sigma, MIN_EXCESS_FRAC * full)).astype(np.uint8)
    n, _, stats, _ = cv2.connectedComponentsWithStats(bright, connectivity=8)
    areas = stats[1:, cv2.CC_STAT_AREA]
    in_spots = int(areas[areas >= MIN_SPOT_PX].sum())
    if in_spots > MAX_SPOT_FRAC * level.size:
        spots = int((areas >= MIN_SPOT_PX).sum())
        return (
            f"it has {spots} bright spots ({in_spots} px, over {100 * MAX_SPOT_FRAC:.2f} % of the image): "
            "marks or a light are in view"
        )
    return None


def median_dark(frames: list[np.ndarray], names: list[str]) -> np.ndarray:
    """The per-pixel median of dark ``frames`` (one size and depth; ``names`` for the messages),
    each checked with :func:`dark_frame_problem`; the result keeps the frames' depth."""
    from stcvision.fileio import check_same_depth

    first = frames[0]
    for img, name in zip(frames, names, strict=True):
        if img.shape != first.shape:
            raise BadInputError(
                f"dark frame {name} is {img.shape[1]}x{img.shape[0]}, the first is "
                f"{first.shape[1]}x{first.shape[0]}; expected one size"
            )
        check_same_depth(first, img, name, frame_path=names[0])
        why = dark_frame_problem(img)
        if why:
            raise BadInputError(
                f"{name} is not a dark frame: {why}; expected a frame with the lens capped or the room dark"
            )
    return np.median(np.stack(frames), axis=0).round().astype(first.dtype)
