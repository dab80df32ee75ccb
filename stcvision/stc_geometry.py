"""The one STC geometry (docs/explanation/stc-geometry.md), used by the
vision (:mod:`stcvision.observation`) and the controller (:mod:`stcvision.controllers.stc`).

**Entry frame** (the robot's heading rounded to a multiple of 90 degrees points "up"): the robot
stands in sub-cell 0 of its cell; sub-cells are numbered counter-clockwise 0 lower-right,
1 upper-right, 2 upper-left, 3 lower-left. Directions are numbered counter-clockwise from
"right": 0 right, 1 forward (up), 2 left, 3 back (down). Sub-cell ``m`` is left towards ``m + 1``
(direction ``m + 1``) or out of the cell (direction ``m``).

==== ========== ===================== =========================
box  sub-cell   edge                   laid when
==== ========== ===================== =========================
1    1          right (exterior)       1 was left going left
2    2          top (exterior)         2 was left going down
3    2          right (shared with 1)  2 was left going left
4    3          top (shared with 2)    3 was left going down
5    1          bottom (shared with 0) 1 was left going up
==== ========== ===================== =========================

Sub-cell 1 is visited iff box 1 or 5 is lit, 2 iff box 2 or 3, 3 iff box 4 (:data:`VISITED_BY`).
The start mark: sub-cell ``m`` along its exterior edge in direction ``m`` (:data:`START_MARKS`).

**Board headings** are compass headings, clockwise: 0 N, 1 E, 2 S, 3 W (:data:`COMPASS_VEC`:
(row, column) steps, row 0 at the north edge); world angles (radians, 0 east,
counter-clockwise) only through :func:`compass_to_rad` and :func:`entry_axes`.

``sim_camera/truth.py`` keeps its own copy on purpose: it is the oracle, and an error here must
not cancel there.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # numpy is imported where it is used: the command line's help shows these numbers
    import numpy as np

#: Default sub-cell side D (m): the footprint of the default STC robot, a small Lego Mindstorms
#: robot about 16 cm across (ant-like STC paper: "the robot divides the floor virtually into
#: sub-cells of its size"; the footprint itself is this project's choice). The board, the
#: calibration profile and the calibration fits all default to it.
DEFAULT_SUBCELL_M = 0.16

__all__ = [
    "BOXES",
    "BOX_EDGES",
    "COMPASS_VEC",
    "DIRECTIONS",
    "NEIGHBOURS",
    "START_MARKS",
    "SUBCELLS",
    "VISITED_BY",
    "compass_to_rad",
    "entry_axes",
]

#: entry-frame direction d -> unit step (right, up): 0 right, 1 forward, 2 left, 3 back
DIRECTIONS = ((1, 0), (0, 1), (-1, 0), (0, -1))
#: neighbour name -> direction (right, up), in direction order (counter-clockwise from "right")
NEIGHBOURS = dict(zip(("right", "forward", "left", "back"), DIRECTIONS, strict=True))
#: sub-cell -> sign (right, up) of its centre relative to the cell centre
SUBCELLS = {0: (1, -1), 1: (1, 1), 2: (-1, 1), 3: (-1, -1)}
#: box -> (sub-cell, direction index of its edge)
BOX_EDGES = {1: (1, 0), 2: (2, 1), 3: (2, 0), 4: (3, 1), 5: (1, 3)}
#: box -> (sub-cell, edge direction (right, up))
BOXES = {b: (k, DIRECTIONS[d]) for b, (k, d) in BOX_EDGES.items()}
#: sub-cell -> the boxes any one of which shows it was visited (sub-cell 0 is the entry)
VISITED_BY = {1: (1, 5), 2: (2, 3), 3: (4,)}
#: sub-cell m -> direction index of the edge its start mark lies along (its exterior edge m)
START_MARKS = {m: m for m in range(4)}

#: compass heading (0 N, 1 E, 2 S, 3 W) -> (row, column) step on the board
COMPASS_VEC = ((-1, 0), (0, 1), (1, 0), (0, -1))


def compass_to_rad(h: int) -> float:
    """Compass heading (0 N, 1 E, 2 S, 3 W) -> world angle (0 = east, counter-clockwise)."""
    return math.pi / 2 - h * math.pi / 2


def entry_axes(h: int) -> tuple[np.ndarray, np.ndarray]:
    """World unit vectors (right, up) of the entry frame of a robot heading compass ``h``."""
    import numpy as np

    a = compass_to_rad(h)
    up = np.array([math.cos(a), math.sin(a)])
    return np.array([up[1], -up[0]]), up
