"""The robot's checks of its own hardware: what it does when it cannot trust what it sees or
where it stands, rather than decide on garbage.

* :func:`frame_fault`: a frame that never arrived or arrived black (below the dark frame's black
  level) is not read; :class:`controllers.stc.frames.RobotCamera` takes it again, up to
  :data:`FRAME_RETRIES` times, and then stops.
* :class:`RobotStop`: raised by a part of the loop that finds the robot cannot go on; the loop
  ends the run with its message as the ``abort_reason``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["FRAME_RETRIES", "RobotStop", "frame_fault"]

#: a lost or black frame is taken again this many times before the robot stops: at 5 % lost
#: frames, four in a row happen once in 160,000 frames; a dead camera stops it at once
FRAME_RETRIES = 3


class RobotStop(Exception):
    """The robot stops: its message is the run's ``abort_reason``."""


def frame_fault(image: np.ndarray | None, dark: np.ndarray | None) -> str | None:
    """Why ``image`` (H, W, 3) uint8 cannot be read, or None: it never arrived, or it is black --
    its mean below half the dark frame's (a real frame of the dark room is never darker than
    the camera's black level and dark signal, which the dark frame holds). Sampled on every
    8th pixel (~0.1 ms)."""
    if image is None:
        return "dropped (no frame arrived)"
    if dark is not None and image.shape == dark.shape:
        level, floor = float(image[::8, ::8].mean()), float(dark[::8, ::8].mean())
        if level < 0.5 * floor:
            return f"black (mean {level:.1f} DN against the dark frame's {floor:.1f})"
    return None
