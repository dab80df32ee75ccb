"""Dark frames: check that a frame is one (lens capped or room dark) and median-stack several.

A dark frame holds the sensor's offset, dark current and hot pixels, nothing of the scene. Three
things betray a frame that is not dark: a high typical level (the lights are on, the lens is
open; an all-white frame); structure over areas larger than a pixel (a room, lit dimly enough
that its median stays low: :func:`stcvision.stages.frame_structure`); and bright *spots* --
connected groups of pixels far above the typical level (phosphor marks, a red light, a lamp in
view). Hot pixels are far above the level too, but one by one: isolated pixels are allowed,
spots are not. The frames stacked must be of one kind: one size, one depth, one typical level
(frames of other exposures or gains differ in it).
"""

from __future__ import annotations

import cv2
import numpy as np

from stcvision.errors import BadInputError
from stcvision.stages import DARK_ROOM_MAX_STRUCTURE, frame_structure

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
    structure = frame_structure(img)
    if structure > DARK_ROOM_MAX_STRUCTURE:
        return (
            f"it shows a scene ({100 * structure:.1f} % of full scale of structure over blocks of pixels; "
            f"a dark frame shows under {100 * DARK_ROOM_MAX_STRUCTURE:g} %): the lights are on or the lens is open"
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
    levels = [_typical_level(img) for img in frames]
    lo, hi = int(np.argmin([lv[0] for lv in levels])), int(np.argmax([lv[0] for lv in levels]))
    spread = max(SAME_KIND_K_SIGMA * max(levels[lo][1], levels[hi][1]), 1.0)
    if levels[hi][0] - levels[lo][0] > spread:
        raise BadInputError(
            f"dark frames {names[lo]} and {names[hi]} sit at typical levels {levels[lo][0]:.1f} and "
            f"{levels[hi][0]:.1f}: frames of other exposures, gains or cameras; expected dark frames of one setting"
        )
    return np.median(np.stack(frames), axis=0).round().astype(first.dtype)


#: two dark frames of one setting differ in their typical level by at most this many of their
#: pixels' robust sigmas (the level of a frame's median moves by far less than one sigma between
#: frames of one setting: the median averages hundreds of thousands of pixels)
SAME_KIND_K_SIGMA = 2.0


def _typical_level(img: np.ndarray) -> tuple[float, float]:
    """(median, robust sigma) of a frame's brightest channel, on every 7th pixel."""
    v = (img.max(axis=2) if img.ndim == 3 else img).reshape(-1)[::7].astype(np.float32)
    med = float(np.median(v))
    return med, 1.4826 * float(np.median(np.abs(v - med)))
