"""Poses on the floor as TUM trajectory lines, the format ``evo`` reads.

The TUM RGB-D benchmark's trajectory format (Sturm, Engelhard, Endres, Burgard and Cremers, "A
Benchmark for the Evaluation of RGB-D SLAM Systems"): one pose a line, ``timestamp x y z qx qy
qz qw``. Every robot's ``--trajectory`` files are written with :func:`tum_line`.
"""

from __future__ import annotations

import math

__all__ = ["TUM_DECIMALS", "tum_line"]

#: decimals of times and positions in the TUM files: a nanometre, far below any error they show
TUM_DECIMALS = 9


def tum_line(t_s: float, x_m: float, y_m: float, yaw_rad: float) -> str:
    """One TUM trajectory line of a pose on the floor.

    Parameters
    ----------
    t_s : float
        The robot's clock (s).
    x_m, y_m : float
        The position on the floor (world, m); z is 0.
    yaw_rad : float
        The heading (counter-clockwise from the world's x axis), written as a unit quaternion
        about z.

    Returns
    -------
    str
        ``timestamp x y z qx qy qz qw``, space-separated, no newline.
    """
    qz, qw = math.sin(yaw_rad / 2), math.cos(yaw_rad / 2)
    return " ".join(f"{v:.{TUM_DECIMALS}f}" for v in (t_s, x_m, y_m, 0.0, 0.0, 0.0, qz, qw))
