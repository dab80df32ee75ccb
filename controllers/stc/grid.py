"""The STC grid on the board: compass headings, the entry frame of a cell, sub-cell indices.

Geometry (``docs/explanation/stc-geometry.md``)
---------------------------------------------------------------
The robot occupies one sub-cell; a cell is 2x2 sub-cells. Every decision is taken on entering a
cell, in the **entry frame** (robot heading "up"), where the robot stands in sub-cell 0 =
lower-right; sub-cells are numbered counter-clockwise 0 (lower-right), 1 (upper-right),
2 (upper-left), 3 (lower-left). Directions in the entry frame are numbered counter-clockwise too:
``0`` right, ``1`` forward, ``2`` left, ``3`` back. Sub-cell ``m`` is left either towards the
next sub-cell ``m + 1`` (direction ``m + 1``) or out of the cell (direction ``m``), so the exit
to the neighbour in direction ``d`` is always from sub-cell ``d`` and lands in the neighbour's
sub-cell 0 of its own entry frame (the right-hand side of the spanning-tree edge).

On the board the robot's heading is a **compass** heading, clockwise: 0 N, 1 E, 2 S, 3 W, with
(row, column) steps :data:`COMPASS_VEC` (row 0 is the north edge). World angles (radians, 0 =
east, counter-clockwise) only at the plant's edge: :func:`compass_to_rad`.

The tables themselves (the five boxes, the sub-cells' and neighbours' (right, up) signs, the
start mark, the compass) are :mod:`stcvision.stc_geometry`'s, shared with the vision; this module maps
them onto board indices.
"""

from __future__ import annotations

from stcvision.stc_geometry import BOX_EDGES, COMPASS_VEC, SUBCELLS, compass_to_rad

__all__ = [
    "BOXES",
    "COMPASS_NAMES",
    "COMPASS_VEC",
    "behind",
    "cell_of",
    "compass_to_rad",
    "frame_compass",
    "frame_step",
    "frame_subcells",
    "start_heading",
    "step_from",
    "turned",
]

COMPASS_NAMES = "NESW"
#: The five boxes in order as (sub-cell, entry-frame edge direction)
BOXES = tuple(BOX_EDGES[b] for b in sorted(BOX_EDGES))


def turned(hc: int, left: bool) -> int:
    """The compass heading after a quarter turn from ``hc``: left is counter-clockwise (compass
    headings run clockwise)."""
    return (hc + (3 if left else 1)) % 4


def behind(hc: int) -> int:
    """The compass direction behind a robot heading ``hc`` (where its rear LEDs lay a row)."""
    return (hc + 2) % 4


def step_from(sub: tuple[int, int], hc: int) -> tuple[int, int]:
    """The sub-cell one forward move from ``sub`` heading compass ``hc``."""
    di, dj = COMPASS_VEC[hc]
    return sub[0] + di, sub[1] + dj


def frame_compass(hc: int, d: int) -> int:
    """Compass direction of entry-frame direction ``d`` when the robot heads ``hc``."""
    return (hc + 1 - d) % 4


def frame_step(hc: int, right_up: tuple[int, int]) -> tuple[int, int]:
    """(row, column) step of an entry-frame step ``right_up`` = (right, up) for a robot heading ``hc``."""
    up, right = COMPASS_VEC[hc], COMPASS_VEC[(hc + 1) % 4]
    return right_up[0] * right[0] + right_up[1] * up[0], right_up[0] * right[1] + right_up[1] * up[1]


def frame_subcells(sub: tuple[int, int], hc: int) -> list[tuple[int, int]]:
    """Board indices of entry-frame sub-cells 0..3 for a robot in ``sub`` (sub-cell 0) heading ``hc``."""
    r0, u0 = SUBCELLS[0]
    steps = [frame_step(hc, ((sr - r0) // 2, (su - u0) // 2)) for sr, su in (SUBCELLS[k] for k in range(4))]
    return [(sub[0] + di, sub[1] + dj) for di, dj in steps]


def cell_of(sub: tuple[int, int]) -> tuple[int, int]:
    """The cell (row, column) holding sub-cell ``sub``."""
    return sub[0] // 2, sub[1] // 2


def start_heading(board) -> int:
    """Compass heading in which the board's start sub-cell is the lower-right one of its cell."""
    i, j = board.start_subcell
    for hc in range(4):
        if all(cell_of(s) == cell_of((i, j)) for s in frame_subcells((i, j), hc)):
            return hc
    raise AssertionError("unreachable")  # pragma: no cover
