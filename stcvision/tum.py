"""Poses on the floor as TUM trajectory lines, the format ``evo`` reads.

The TUM RGB-D benchmark's trajectory format (Sturm, Engelhard, Endres, Burgard and Cremers, "A
Benchmark for the Evaluation of RGB-D SLAM Systems"): one pose a line, ``timestamp x y z qx qy
qz qw``. Every robot's ``--trajectory`` files are written with :func:`tum_line` and
:func:`write_tum_files`; a robot that believes a pose (the STC robot, the search robot's
odometry) writes :data:`TUM_FILES` with :func:`tum_files`.
"""

from __future__ import annotations

import math
from pathlib import Path

__all__ = ["TUM_DECIMALS", "TUM_FILES", "tum_files", "tum_line", "write_tum_files"]

#: decimals of times and positions in the TUM files: a nanometre, far below any error they show
TUM_DECIMALS = 9
#: the two files of ``--trajectory DIR``: the path the robot truly drove, and the one it believed
TUM_FILES = ("true.tum", "believed.tum")


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


def tum_files(true, believed) -> dict[str, str]:
    """Return the TUM files' text of two paths sampled at the same times.

    Parameters
    ----------
    true, believed : sequence of tuple
        (t_s, x_m, y_m, heading_rad) each, the same times in both.

    Returns
    -------
    dict of str to str
        By file name (:data:`TUM_FILES`): the true path's, then the believed path's.
    """
    return {
        name: "".join(tum_line(*p) + "\n" for p in poses)
        for name, poses in zip(TUM_FILES, (true, believed), strict=True)
    }


def write_tum_files(folder: str | Path, files: dict[str, str], *, overwrite: bool = False) -> list[Path]:
    """Write TUM files' text into a folder as one set (:func:`stcvision.fileio.write_set`): all or none.

    Parameters
    ----------
    folder : str or Path
        Where the files go (made if missing).
    files : dict of str to str
        The files' text by name.
    overwrite : bool
        Replace existing files; else they are refused.

    Returns
    -------
    list of Path
        The files written.
    """
    from stcvision.fileio import write_set

    return write_set(folder, {k: v.encode() for k, v in files.items()}, overwrite=overwrite)
