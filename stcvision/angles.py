"""Angle wrapping, the one helper every package uses (the pipeline, the simulator's odometry,
the robots and the calibration fits): an angle, or an array of them, wrapped to [-pi, pi).

It holds no model of the camera or the world, so the simulator may import it without sharing
the pipeline's model (the rule that keeps the renderer's errors from cancelling the pipeline's).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["wrap_angle"]


def wrap_angle(a):
    """``a`` (radians) wrapped to [-pi, pi): a float for a Python or NumPy scalar, else an array."""
    if isinstance(a, int | float | np.floating | np.integer):
        return (float(a) + math.pi) % (2 * math.pi) - math.pi
    return (np.asarray(a, dtype=float) + np.pi) % (2 * np.pi) - np.pi
