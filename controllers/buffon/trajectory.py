"""The recorded Buffon trial's paths as TUM trajectory files (what ``evo`` reads).

Buffon's explorer keeps no estimate of its pose: its behaviour reads its six IR rays and its
pheromone detector, its stopping rule its path length and its count of crossings (Girgin and
Sahin's robot, as :mod:`stcvision.controllers.buffon.batched` simulates it); nothing in it
dead-reckons a position. So it has no believed path, and ``buffon --trajectory DIR`` writes the
true one only, one file per visit (each visit starts at the nest's start, so one file would
hold a jump between them): ``visit1.true.tum`` and ``visit2.true.tum``.

Each file holds the visit's start and the robot's position after every step, on the visit's
own clock (0 at its start, one world step apart). The record holds positions only, so the
heading column is the direction of travel: of the step that leaves a sample (the last
sample: of the step that reached it; a sample where the robot did not move keeps the
heading before it). Evo's path length of a visit's file is the visit's length the trial
reports (``L1``, ``L2``), to the files' decimals.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["VISIT_FILES", "visit_tum", "write_trajectory"]

#: the files of ``buffon --trajectory DIR``: the true path of the first visit and of the second
VISIT_FILES = ("visit1.true.tum", "visit2.true.tum")


def visit_tum(start_xy, path: np.ndarray, dt_s: float) -> str:
    """Return one visit's true path as TUM text.

    Parameters
    ----------
    start_xy : (2,) array_like
        Where the visit started (m).
    path : (S, 3) ndarray
        The position after each step (x m, y m, crossed), as the trial recorded it.
    dt_s : float
        The world step (s).

    Returns
    -------
    str
        ``S + 1`` TUM lines (:func:`stcvision.tum.tum_line`).
    """
    from stcvision.tum import tum_line

    pts = np.vstack([np.asarray(start_xy, float).reshape(1, 2), np.asarray(path, float)[:, :2]])
    steps = np.diff(pts, axis=0)
    yaw, lines = 0.0, []
    for k, (x, y) in enumerate(pts):
        dx, dy = steps[min(k, len(steps) - 1)] if len(steps) else (0.0, 0.0)
        if dx or dy:
            yaw = float(np.arctan2(dy, dx))
        lines.append(tum_line(k * dt_s, float(x), float(y), yaw) + "\n")
    return "".join(lines)


def write_trajectory(folder: str | Path, start_xy, trails: dict, dt_s: float, *, overwrite: bool = False) -> list[Path]:
    """Write the two visits' true paths into ``folder`` as one set (:data:`VISIT_FILES`,
    :func:`stcvision.tum.write_tum_files`).

    Parameters
    ----------
    folder : str or Path
        Where the files go (made if missing).
    start_xy : (2,) array_like
        The nest's start (m), where both visits begin.
    trails : dict
        The recorded trial's ``visit1`` and ``visit2`` (``TrialSet.trails``).
    dt_s : float
        The world step (s).
    overwrite : bool
        Replace existing files; else they are refused.

    Returns
    -------
    list of Path
        The files written.
    """
    from stcvision.tum import write_tum_files

    files = {name: visit_tum(start_xy, trails[f"visit{k}"], dt_s) for k, name in enumerate(VISIT_FILES, 1)}
    return write_tum_files(folder, files, overwrite=overwrite)
