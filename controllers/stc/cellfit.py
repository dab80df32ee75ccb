"""Localisation against the cell's own marks: where the robot stands relative to the rows of the
cell it decides in, from the box and start-mark lines those rows must lie on.

The pipeline reads the boxes relative to the offset the marks *in view* give
(:func:`stcvision.observation.mark_offset`: the median residual of every row from the nearest
edge +- the rows' inset). That offset is ambiguous beyond the inset (2 cm: the residual flips
sides), and it mixes rows laid at different times, each where the robot then stood: on open
floor, far from any red light, a robot 1.8 cm behind its sub-cell (the drift of ~80 moves, which
nothing absolute measured) read its cell's rows of an hour before against its neighbour's rows
of five minutes before, took the median (~0), and read boxes 2 and 4 as marks at no box at all.

At a decision, though, the cell's marks can lie only on the box and start-mark lines
(:data:`stcvision.stcgrid.BOX_EDGES`, :data:`~stcvision.stcgrid.START_MARKS`; the oracle's
``box_table_violations`` is zero on every tour), and along each axis those lines stand 0.75 of a
sub-cell apart within a half of the cell (a row's extent says which half). So the offset that
puts the cell's rows on those lines is unambiguous far beyond the rows' inset (the search keeps
to +-2.9 cm, :data:`SEARCH`, where no neighbour's row can be pulled onto a line), and it is
the offset that matters for reading the boxes: the robot relative to the marks it reads.
:func:`fit_cell_offset` finds it; :class:`controllers.stc.frames.RobotCamera` reads a frame again
with it when the pipeline's offset leaves rows of the cell on no line, and a reading whose rows
no offset puts on the lines is not decided on (``StcObservation.misread``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from stcvision.observation import MARK_INSET, ROW_TOL, _rotate, row_orientation
from stcvision.stcgrid import BOX_EDGES, DIRECTIONS, START_MARKS, SUBCELLS

__all__ = ["CellFit", "fit_cell_offset", "mark_lines"]

#: how far (sub-cell sides) the fit searches either side of the pipeline's offset: 2.9 cm,
#: short of pulling a neighbour's row (0.125 beyond the cell's edge) onto the cell's outermost
#: line (0.125 inside it) within :data:`ON_LINE` and across :data:`INSIDE`
SEARCH = 0.18
#: the search's step (sub-cell sides; 1.6 mm at 16 cm sub-cells)
STEP = 0.01
#: a dot counts as the cell's within this of the centre (sub-cell sides): the outermost lines
#: (0.875) and their band, not a neighbour's row just beyond the cell's edge (1.125)
INSIDE = 1.0 - ROW_TOL
#: a row's dot lies on a line within this (sub-cell sides): the row search's band across a row
#: (:data:`stcvision.observation.ROW_TOL`, 1 cm)
ON_LINE = ROW_TOL


@cache
def mark_lines() -> tuple[tuple[tuple[float, int], ...], tuple[tuple[float, int], ...]]:
    """Per axis (0: across the rows along 'up', the right coordinate; 1: across the rows along
    'right', the up coordinate) the (coordinate, half) of every line a mark of the cell may lie
    on at a decision: the five boxes and the start marks (sub-cell 0's, under the robot at the
    first decision and the last, where an edge of it may show); ``half`` is the sign of the
    row's other coordinate (the sub-cell's side)."""
    lines: tuple[list, list] = ([], [])
    edges = list(BOX_EDGES.values()) + [(m, START_MARKS[m]) for m in range(4)]
    for k, d in edges:
        e = np.asarray(DIRECTIONS[d], float)
        centre = 0.5 * np.asarray(SUBCELLS[k], float)
        axis = 0 if e[0] else 1
        coord = float(centre[axis] + (0.5 - MARK_INSET) * e[axis])
        lines[axis].append((coord, int(SUBCELLS[k][1 - axis])))
    return tuple(lines[0]), tuple(lines[1])


@dataclass(frozen=True, slots=True)
class CellFit:
    offset: tuple[float, float]  # (right, up), sub-cell sides: add to the dots (the pipeline's sense)
    on_line: int  # the cell's row dots on a line at that offset
    off_line: int  # ... and on none
    ambiguous: bool  # another offset as good, far from this one, reads them otherwise


def _line_distance(p: np.ndarray, along_axis: np.ndarray, lines) -> tuple[np.ndarray, np.ndarray]:
    """For dots ``p`` (..., N, 2; shifted, cell units) whose rows are read on axis
    ``along_axis`` (N: 0 or 1): which are the cell's (inside :data:`INSIDE`), and each one's
    distance to the nearest line of its axis and its half (numpy: a frame's few hundred dots at
    every step of the search at once)."""
    inside = (np.abs(p[..., 0]) < INSIDE) & (np.abs(p[..., 1]) < INSIDE)
    n = np.arange(p.shape[-2])
    c = p[..., n, along_axis]
    half = np.where(p[..., n, 1 - along_axis] >= 0, 1, -1)
    d = np.full(c.shape, np.inf)
    for a in (0, 1):
        for x, h in lines[a]:
            m = (along_axis == a) & (half == h)
            d = np.where(m, np.minimum(d, np.abs(c - x)), d)
    return inside, d


def _score(p: np.ndarray, along_axis: np.ndarray, lines) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per shift (``p``: S, N, 2): the cell's dots on no line, on one, and the mean squared
    distance of those on one to their line (0 when none)."""
    inside, d = _line_distance(p, along_axis, lines)
    on = inside & (d < ON_LINE)
    n_on = on.sum(-1)
    msd = np.where(on, d * d, 0.0).sum(-1) / np.maximum(n_on, 1)
    return (inside & ~on).sum(-1), n_on, msd


def _counts(p: np.ndarray, along_axis: np.ndarray, lines) -> tuple[int, int]:
    """(the cell's row dots on a line, on none)."""
    inside, d = _line_distance(p, along_axis, lines)
    on = inside & (d < ON_LINE)
    return int(on.sum()), int((inside & ~on).sum())


def fit_cell_offset(
    ru_raw: np.ndarray, lit: np.ndarray, start: tuple[float, float], *, search: bool = True
) -> CellFit | None:
    """The offset (right, up; sub-cell sides, added to the dots) that puts the most lit row dots
    of the cell on :func:`mark_lines` and the fewest on none, searched :data:`SEARCH` either side
    of ``start`` (the pipeline's offset) per axis, the nearest to ``start`` among equals
    (``search`` False: the counts at ``start`` itself).
    ``ru_raw``: the frame's dots in cell units, rotated by the heading fit, not shifted. None
    when the frame shows no row of the cell."""
    lit = np.asarray(lit, bool)
    p0 = np.asarray(ru_raw, float)[lit]
    if not len(p0):
        return None
    orient = row_orientation(p0)
    rows = orient >= 0
    # a row along 'up' (orient 1) is read on the right coordinate (axis 0), one along 'right' on up
    p0, axis_of = p0[rows], np.where(orient[rows] == 1, 0, 1)
    if not len(p0):
        return None
    lines = mark_lines()
    off = np.asarray(start, float).copy()
    ambiguous = False
    steps = np.round(np.arange(-SEARCH, SEARCH + STEP / 2, STEP), 4)
    for a in (0, 1) if search else ():
        sel = axis_of == a
        if not sel.any():
            continue
        shifts = np.repeat(off[None, :], len(steps), 0)
        shifts[:, a] += steps
        n_off, n_on, msd = _score(p0[sel][None, :, :] + shifts[:, None, :], axis_of[sel], lines)
        if not (n_off + n_on).any():  # no row of the cell at any shift: the start stands
            continue
        # the fewest of the cell's dots on no line, then the best-centred on their lines, then
        # the nearest to the start (more dots on lines is no merit: a shift that pulls a
        # neighbour's row in over the cell's edge would win by it)
        best = min(range(len(steps)), key=lambda i: (n_off[i], round(float(msd[i]), 6), abs(steps[i])))
        # two separate runs of shifts that leave none on no line: two readings of the rows
        fits = np.flatnonzero(n_off == n_off[best]) if n_off[best] == 0 else np.zeros(0, int)
        ambiguous |= bool(len(fits) and np.diff(fits).max(initial=1) > 1)
        off[a] += steps[best]
    on, bad = _counts(p0 + off, axis_of, lines)
    return CellFit((float(off[0]), float(off[1])), on, bad, ambiguous)


def frame_dots(res, geometry) -> tuple[np.ndarray, np.ndarray]:
    """A pipeline result's dots in cell units, rotated back by the heading it was read with (not
    shifted by any offset), and which are lit."""
    dots = res.dots
    if not len(dots):
        return np.zeros((0, 2)), np.zeros(0, bool)
    ru = _rotate(geometry.to_cell(dots.xy_px), res.observation.heading_error_rad)
    return ru, np.asarray(dots.lit, bool)
