"""The robot's checks of its own hardware: what it does when it cannot trust what it sees or
where it stands, rather than decide on garbage.

* :func:`frame_fault`: a frame that never arrived or arrived black (below the dark frame's black
  level) is not read; :class:`stcvision.controllers.stc.frames.RobotCamera` takes it again, up to
  :data:`FRAME_RETRIES` times, and then stops.
* :class:`NoiseCheck`: every frame's noise floor against the camera's own figures; a camera
  much noisier than its calibration stops the robot (its frames no longer see as far as the
  exposure ladder assumes).
* The robot's count of its moves, and what the tour takes from it, is
  :class:`stcvision.controllers.stc.movecount.MoveCount`.
* :class:`RobotStop`: raised by a part of the loop that finds the robot cannot go on; the loop
  ends the run with its message as the ``abort_reason``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "FRAME_RETRIES",
    "NOISE_CHECK",
    "NoiseCheck",
    "RobotStop",
    "frame_fault",
    "noise_floor_dn",
    "sampled_level",
]

#: a lost or black frame is taken again this many times before the robot stops: at 5 % lost
#: frames, four in a row happen once in 160,000 frames; a dead camera stops it at once
FRAME_RETRIES = 3


#: a frame's measured noise floor this many times what the camera's figures give
#: (:func:`noise_floor_dn`) means the camera is not the one its horizons were computed for:
#: measured on the webcam's ladder, healthy frames read 1.05-1.28x, a noise floor x3 2.4-3.2x
NOISE_CHECK = 1.6
#: ... in this many frames in a row (one frame full of glare or marks is not a faulty camera)
NOISE_CHECK_FRAMES = 3


class RobotStop(Exception):
    """The robot stops: its message is the run's ``abort_reason``."""


def frame_fault(image: np.ndarray | None, dark: np.ndarray | None, *, dark_level: float | None = None) -> str | None:
    """Why ``image`` (H, W, 3) uint8 cannot be read, or None: it never arrived, or it is black --
    its mean below half the dark frame's (a real frame of the dark room is never darker than
    the camera's black level and dark signal, which the dark frame holds). Sampled on every
    8th pixel (~0.1 ms); ``dark_level``: the dark frame's :func:`sampled_level`, when the caller
    keeps it from frame to frame."""
    if image is None:
        return "dropped (no frame arrived)"
    if dark is not None and image.shape == dark.shape:
        level = sampled_level(image)
        floor = sampled_level(dark) if dark_level is None else dark_level
        if level < 0.5 * floor:
            return f"black (mean {level:.1f} DN against the dark frame's {floor:.1f})"
    return None


def sampled_level(image: np.ndarray) -> float:
    """The mean of every 8th pixel of every 8th row: a frame's level as :func:`frame_fault` reads it."""
    return float(image[::8, ::8].mean())


def noise_floor_dn(sensor, *, n_avg: int = 1, n_dark: int = 8) -> float:
    """The noise (DN, 1 sigma) a dark pixel of a dark-subtracted frame should show by the
    camera's own figures (``sensor``: its preset at the frame's exposure and gain): read noise and
    dark-current shot noise, averaged over ``n_avg`` frames, the dark frame's own noise (a median
    or mean of ``n_dark`` frames, ~1.25^2 / n_dark of a frame's variance) and the 8-bit rounding
    of both."""
    e_var = (sensor.read_noise_e**2 + sensor.dark_current_e_s * sensor.exposure_s) / n_avg
    dn_var = e_var * sensor.dn_per_e**2 * (1.0 + 1.25**2 / n_dark)
    return float(np.sqrt(dn_var + 2 / 12))


class NoiseCheck:
    """Counts frames whose measured noise floor exceeds :data:`NOISE_CHECK` times
    :func:`noise_floor_dn`; :data:`NOISE_CHECK_FRAMES` in a row stop the robot."""

    def __init__(self):
        self.over = 0
        self.worst = 0.0

    def check(self, measured_dn: float, expected_dn: float) -> None:
        ratio = measured_dn / expected_dn
        self.worst = max(self.worst, ratio)
        self.over = self.over + 1 if ratio > NOISE_CHECK else 0
        if self.over >= NOISE_CHECK_FRAMES:
            raise RobotStop(
                f"camera: noise floor {ratio:.1f}x its calibration in {self.over} frames in a row "
                f"(over {NOISE_CHECK}x): its frames no longer see the marks the exposure ladder counts on"
            )
