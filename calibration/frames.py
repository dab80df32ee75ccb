"""Frames of any depth into the calibration's geometry.

The rim, the grid lines and the corners are found from contrast, not from a camera's DN, so a
12- or 16-bit lights-on frame (uint16 holding the ADC's counts LSB-aligned, 0..4095 for 12 bits,
or MSB-aligned, steps of 16 for 12 bits, as the pipeline takes them) is brought to 8 bits by its
own brightness: its 99.9th percentile to 250 -- where a webcam's auto-exposed lights-on frame
puts its lit floor's brightest pixels -- whatever the alignment or the exposure. 8-bit frames
pass unchanged (bit for bit the results they always gave).
"""

from __future__ import annotations

import numpy as np

from stcvision.errors import BadInputError

__all__ = ["geometry_frame"]

#: the 8-bit level the frame's 99.9th percentile is scaled to (a little under full scale, so the
#: brightest 0.1 % clip instead of the whole floor darkening to make room for a hot pixel)
BRIGHT_LEVEL = 250.0
BRIGHT_PERCENTILE = 99.9


def geometry_frame(frame: np.ndarray, what: str = "lights-on frame") -> np.ndarray:
    """``frame`` ((H, W) or (H, W, 3), uint8 or uint16) as uint8 for the geometric calibration."""
    if not isinstance(frame, np.ndarray) or frame.ndim not in (2, 3) or frame.size == 0:
        raise BadInputError(f"{what} must be an (H, W) or (H, W, 3) image")
    if frame.dtype == np.uint8:
        return frame
    if frame.dtype != np.uint16:
        raise BadInputError(f"{what} has dtype {frame.dtype}; expected uint8 or uint16 (12- or 16-bit counts)")
    top = float(np.percentile(frame[::2, ::2], BRIGHT_PERCENTILE))
    if top <= 0:
        raise BadInputError(f"{what} is black; expected a lights-on frame")
    scaled = frame.astype(np.float32) * np.float32(BRIGHT_LEVEL / top)
    return np.clip(np.rint(scaled), 0, 255).astype(np.uint8)
