"""Batched physics for many small disc robots among static walls, compiled with numba.

The pymunk world (:mod:`stcvision.sim_camera.world`) with the Buffon explorer's six IR ray casts runs
~4,200 robot-steps/s here; a Buffon reproduction is ~10^9 robot-steps (the
Buffon's needle paper of Girgin & Sahin, sec. 4-5: 100 trials x 2 visits x 50,000 steps per nest,
and more), so the Monte-Carlo path needs compiled per-step loops. numba compiles the plain Python
below to machine code (``cache=True`` keeps the compiled code between runs): 4.4-4.9 million
robot-steps per CPU-second on one core in a 30 body-length circle (``stcvision bench``).

What it models, and how it matches the pymunk path:

* **Solids** are *capsules* (a segment with a radius): the arena's outer polygon edges with radius
  0 (pymunk's outer walls are built outward, so their inner face is the polygon edge), barriers
  with half their thickness (pymunk ``Segment(radius=thickness/2)``), obstacle edges with radius 0.
  :class:`StaticGeometry` holds them with a uniform *near grid*: each cell lists the capsules that
  can be within ``reach_m`` of any point of the cell, so a robot far from every wall looks at none.
* **Ray casts** (:func:`ray_fan`): the distance along a ray to the first capsule surface, like
  pymunk's ``segment_query_first`` with radius 0.
* **Contact** (:func:`push_out`): the disc's centre is moved out of every capsule it overlaps,
  along the normal, a few passes: a frictionless slide, like pymunk's contact with friction 0 and
  elasticity 0. Robots move at most a few mm per step against a radius of 27.5 mm, so the
  centre can never pass a wall's centre line in one step (no tunnelling; tested).
* **Pheromone raster** (:func:`deposit_segment`, :func:`read_cell`): the same grid convention as
  :class:`stcvision.sim_camera.layers.PheromoneLayer` (row 0 = south; a cell is marked when its centre is
  within half the trail width of the path).
* **Containment** (:func:`inside_polygon`): the outer polygon test, used as a guard.

There are no robot-robot contacts: each robot of a batch lives in its own copy of the world
(the trials of an experiment are independent).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from stcvision.errors import BadInputError

__all__ = [
    "StaticGeometry",
    "cell_span",
    "deposit_segment",
    "inside_polygon",
    "loop_jit",
    "push_out",
    "ray_fan",
    "read_cell",
    "stamp_segment",
    "step_jit",
]

_MAX_GRID_CELLS = 4_000_000
#: relative slack of the tests that skip what is surely out of reach (a capsule the disc cannot
#: touch, a raster cell the trail cannot cover): a billionth, far above the rounding of the few
#: products and quotients they compare (~1e-16), far below any distance that matters
_SLACK = 1e-9


@dataclass(frozen=True, eq=False)
class StaticGeometry:
    """Capsules of an arena with a near grid (build once with :meth:`from_arena`).

    caps : (K, 5) float64 rows [ax, ay, bx, by, radius] (m).
    origin_m, cell_m, shape : the near grid (row 0 = south).
    offsets : (ny * nx + 1,) int64; cell c lists ``index[offsets[c]:offsets[c + 1]]``.
    outer : (V, 2) float64, the outer polygon (counter-clockwise).
    """

    caps: np.ndarray
    origin_m: tuple[float, float]
    cell_m: float
    shape: tuple[int, int]
    offsets: np.ndarray
    index: np.ndarray
    outer: np.ndarray

    @classmethod
    def from_arena(cls, arena, reach_m: float) -> StaticGeometry:
        """Capsules of ``arena`` and a near grid whose cells list every capsule that comes within
        ``reach_m`` of some point of the cell (``reach_m`` >= robot radius + sensor range)."""
        if not reach_m > 0:
            raise BadInputError(f"reach_m must be > 0; got {reach_m!r}")
        # Arena.boundary_segments lists the outer edges, then the barriers' centre lines, then
        # the obstacles' edges; only barriers are thick (pymunk Segment radius = thickness / 2)
        segs = arena.boundary_segments()
        v = arena.outer_vertices()
        rad = np.zeros(len(segs))
        rad[len(v) : len(v) + len(arena.barriers)] = [0.5 * b.thickness_m for b in arena.barriers]
        caps = np.ascontiguousarray(np.c_[segs.reshape(-1, 4), rad], dtype=np.float64)

        xmin, ymin, xmax, ymax = arena.bounds_m
        # small cells keep each cell's list short (a cell lists what is within reach of any of its
        # points), bounded so that the grid stays within _MAX_GRID_CELLS
        extent = max(xmax - xmin, ymax - ymin) + 4 * reach_m
        cell = max(0.25 * float(reach_m), extent / math.sqrt(_MAX_GRID_CELLS))
        pad = 2 * reach_m
        ox, oy = xmin - pad, ymin - pad
        nx = math.ceil((xmax - xmin + 2 * pad) / cell)
        ny = math.ceil((ymax - ymin + 2 * pad) / cell)
        if nx * ny > _MAX_GRID_CELLS:
            raise BadInputError(f"arena too large for the batched path: {ny}x{nx} near-grid cells")
        half_diag = cell * math.sqrt(0.5)
        # (cell, capsule) pairs, capsule by capsule; a stable sort by cell then lists each cell's
        # capsules in capsule order (a list of lists appended to in Python cost most of a
        # Buffon batch's set-up: ~20 ms for a 30 u circle, a fifth of four paper-length trials)
        cells, ks = [], []
        for k, (ax, ay, bx, by, rad) in enumerate(caps):
            lim = rad + reach_m + half_diag
            j0 = max(0, int((min(ax, bx) - lim - ox) / cell))
            j1 = min(nx - 1, int((max(ax, bx) + lim - ox) / cell))
            i0 = max(0, int((min(ay, by) - lim - oy) / cell))
            i1 = min(ny - 1, int((max(ay, by) + lim - oy) / cell))
            jj, ii = np.arange(j0, j1 + 1), np.arange(i0, i1 + 1)[:, None]  # the box's cells, row by row
            cx = ox + (jj + 0.5) * cell
            cy = oy + (ii + 0.5) * cell
            d = _point_segment_distance_np(cx, cy, ax, ay, bx, by)
            near = (ii * nx + jj)[d <= lim]
            cells.append(near)
            ks.append(np.full(len(near), k, dtype=np.int64))
        cell_of = np.concatenate(cells).astype(np.int64) if cells else np.zeros(0, np.int64)
        cap_of = np.concatenate(ks) if ks else np.zeros(0, np.int64)
        offsets = np.zeros(nx * ny + 1, dtype=np.int64)
        np.cumsum(np.bincount(cell_of, minlength=nx * ny), out=offsets[1:])
        index = np.ascontiguousarray(cap_of[np.argsort(cell_of, kind="stable")], dtype=np.int64)
        return cls(caps, (ox, oy), cell, (ny, nx), offsets, index, np.ascontiguousarray(v, dtype=np.float64))

    @property
    def arrays(self) -> tuple:
        """The arguments the kernels take: (caps, ox, oy, cell, ny, nx, offsets, index)."""
        return (self.caps, self.origin_m[0], self.origin_m[1], self.cell_m, *self.shape, self.offsets, self.index)


def _point_segment_distance_np(px, py, ax, ay, bx, by):
    dx, dy = bx - ax, by - ay
    ll = dx * dx + dy * dy
    t = np.clip(((px - ax) * dx + (py - ay) * dy) / ll, 0.0, 1.0) if ll > 0 else 0.0
    return np.hypot(px - (ax + t * dx), py - (ay + t * dy))


# ------------------------------------------------------------------------------ kernels
#: how the per-step kernels are compiled: without numba's reference counting of arrays (``_nrt``
#: off, as numba's own ``register_jitable`` documents for code that allocates nothing). Its atomic
#: increments and decrements around every call that takes an array were half of a robot-step
#: (measured with perf on the Buffon explorer); these kernels only read and write arrays their
#: caller owns, so no count is needed. numpy's error model: a division by zero gives inf or nan
#: instead of a test before every division (a branch that keeps a loop out of vector registers;
#: the one division that can meet a zero, a ray parallel to a wall, discards its quotient). No
#: fastmath: results stay the same to the last digit.
loop_jit = numba.njit(cache=True, fastmath=False, nogil=True, _nrt=False, error_model="numpy")
#: the same for the pieces of one step (a fan of rays, the contact, the trail stamp): numba
#: inlines them into the loop that calls them, so that no call passes its arrays on the stack
#: (~40 words a call; inlined: +10 % robot-steps per second, measured, and no longer to compile)
step_jit = numba.njit(cache=True, fastmath=False, nogil=True, _nrt=False, error_model="numpy", inline="always")


@loop_jit
def cell_span(x, y, ox, oy, cell, ny, nx, offsets):
    """The slice of ``index`` listing the capsules near (x, y) (empty off the grid)."""
    j = int(math.floor((x - ox) / cell))
    i = int(math.floor((y - oy) / cell))
    if i < 0 or j < 0 or i >= ny or j >= nx:
        return 0, 0
    c = i * nx + j
    return offsets[c], offsets[c + 1]


@loop_jit
def _ray_segment(px, py, dx, dy, ax, ay, bx, by):
    """Ray parameter t >= 0 (unit direction) where the ray meets segment a-b, or inf."""
    ex, ey = bx - ax, by - ay
    den = dx * ey - dy * ex
    qx, qy = ax - px, ay - py
    t = (qx * ey - qy * ex) / den
    u = (qx * dy - qy * dx) / den
    # one select, no branch, so that a fan of rays runs side by side in vector registers (a
    # parallel ray, den = 0, gives inf or nan here, and inf)
    return t if (den != 0.0) & (t >= 0.0) & (u >= 0.0) & (u <= 1.0) else np.inf


@loop_jit
def _ray_circle(px, py, dx, dy, cx, cy, r):
    qx, qy = px - cx, py - cy
    b = qx * dx + qy * dy
    c = qx * qx + qy * qy - r * r
    if c <= 0.0:
        return 0.0  # starts inside
    disc = b * b - c
    if disc < 0.0 or b > 0.0:
        return np.inf
    return -b - math.sqrt(disc)


@loop_jit
def _ray_capsule(px, py, dx, dy, ax, ay, bx, by, rad):
    if rad == 0.0:
        return _ray_segment(px, py, dx, dy, ax, ay, bx, by)
    ex, ey = bx - ax, by - ay
    ln = math.hypot(ex, ey)
    nx_, ny_ = -ey / ln * rad, ex / ln * rad
    t = _ray_segment(px, py, dx, dy, ax + nx_, ay + ny_, bx + nx_, by + ny_)
    t = min(t, _ray_segment(px, py, dx, dy, ax - nx_, ay - ny_, bx - nx_, by - ny_))
    t = min(t, _ray_circle(px, py, dx, dy, ax, ay, rad))
    return min(t, _ray_circle(px, py, dx, dy, bx, by, rad))


@step_jit
def ray_fan(caps, ox, oy, cell, ny, nx, offsets, index, qx, qy, rays, max_len):
    """Cast a fan of rays: for each column q of ``rays`` (5, n): origin (rays[0, q], rays[1, q]),
    unit direction (rays[2, q], rays[3, q]), the distance to the first capsule, or inf if none
    within ``max_len``, into rays[4, q]. The capsules are those listed in the near cell of
    (qx, qy) (the robot's centre: the grid was built with a reach covering every ray of the
    robot). The rays of one capsule are cast side by side (columns: one vector lane each)."""
    n = rays.shape[1]
    for q in range(n):
        rays[4, q] = np.inf
    lo, hi = cell_span(qx, qy, ox, oy, cell, ny, nx, offsets)
    for m in range(lo, hi):
        k = index[m]
        ax, ay, bx, by, rad = caps[k, 0], caps[k, 1], caps[k, 2], caps[k, 3], caps[k, 4]
        if rad == 0.0:
            for q in range(n):
                t = _ray_segment(rays[0, q], rays[1, q], rays[2, q], rays[3, q], ax, ay, bx, by)
                rays[4, q] = min(rays[4, q], t)
        else:
            for q in range(n):
                t = _ray_capsule(rays[0, q], rays[1, q], rays[2, q], rays[3, q], ax, ay, bx, by, rad)
                rays[4, q] = min(rays[4, q], t)
    for q in range(n):
        rays[4, q] = rays[4, q] if rays[4, q] <= max_len else np.inf


@loop_jit
def _closest_on_segment(x, y, ax, ay, bx, by):
    ex, ey = bx - ax, by - ay
    ll = ex * ex + ey * ey
    t = 0.0
    if ll > 0.0:
        t = min(1.0, max(0.0, ((x - ax) * ex + (y - ay) * ey) / ll))
    return ax + t * ex, ay + t * ey


@loop_jit
def _surely_apart(x, y, ax, ay, bx, by, need):
    """Whether (x, y) is surely farther than ``need`` from segment a-b, told without a division
    or a root: its distance to the segment's line, or beyond an end along the segment, is."""
    ex, ey = bx - ax, by - ay
    ll = ex * ex + ey * ey
    px, py = x - ax, y - ay
    cr = px * ey - py * ex  # |e| times the distance to the line
    dot = px * ex + py * ey  # |e| times the position along the segment
    beyond = min(dot, 0.0) + max(dot - ll, 0.0)  # |e| times the distance beyond an end
    return max(cr * cr, beyond * beyond) > need * need * ll * (1.0 + _SLACK)


@step_jit
def push_out(caps, ox, oy, cell, ny, nx, offsets, index, x, y, radius):
    """Move a disc of ``radius`` centred at (x, y) out of every capsule it overlaps (frictionless
    contact: only the normal component is removed). Returns (x, y, touched)."""
    touched = False
    for _ in range(4):
        moved = False
        lo, hi = cell_span(x, y, ox, oy, cell, ny, nx, offsets)
        for m in range(lo, hi):
            k = index[m]
            need = radius + caps[k, 4]
            if _surely_apart(x, y, caps[k, 0], caps[k, 1], caps[k, 2], caps[k, 3], need):
                continue
            cx, cy = _closest_on_segment(x, y, caps[k, 0], caps[k, 1], caps[k, 2], caps[k, 3])
            ddx, ddy = x - cx, y - cy
            d = math.hypot(ddx, ddy)
            if d < need and d > 0.0:
                s = (need - d) / d
                x += ddx * s
                y += ddy * s
                moved = True
        if not moved:
            break
        touched = True
    return x, y, touched


@loop_jit
def inside_polygon(poly, x, y):
    """Even-odd point-in-polygon test; poly (V, 2)."""
    inside = False
    n = poly.shape[0]
    j = n - 1
    for i in range(n):
        xi, yi = poly[i, 0], poly[i, 1]
        xj, yj = poly[j, 0], poly[j, 1]
        if (yi > y) != (yj > y):
            if x < (xj - xi) * (y - yi) / (yj - yi) + xi:
                inside = not inside
        j = i
    return inside


@loop_jit
def deposit_segment(grid, ox, oy, cell, half, x0, y0, x1, y1):
    """Mark the cells of ``grid`` (uint8, row 0 = south) whose centre lies within ``half`` of the
    segment (x0, y0)-(x1, y1) (the rule of :class:`stcvision.sim_camera.layers.PheromoneLayer`)."""
    stamp_segment(grid, ox, oy, cell, half, x0, y0, x1, y1, 1)


@step_jit
def stamp_segment(grid, ox, oy, cell, half, x0, y0, x1, y1, value):
    """As :func:`deposit_segment`, but an empty cell (0) gets ``value`` and a marked one keeps
    what it holds: a raster of when (how far along its path) the trail was first laid, which a
    robot reading its own trail needs to tell an old strand from the stripe it is laying."""
    ny, nx = grid.shape
    # the cells whose centres lie within the segment's box grown by half (and a margin, so that
    # no cell the test below could mark is left out by rounding): ~6 cells a robot-step
    reach = half * (1.0 + _SLACK)
    j0 = max(0, int(math.ceil((min(x0, x1) - reach - ox) / cell - 0.5)))
    j1 = min(nx - 1, int(math.floor((max(x0, x1) + reach - ox) / cell - 0.5)))
    i0 = max(0, int(math.ceil((min(y0, y1) - reach - oy) / cell - 0.5)))
    i1 = min(ny - 1, int(math.floor((max(y0, y1) + reach - oy) / cell - 0.5)))
    h2 = half * half
    ex, ey = x1 - x0, y1 - y0
    ll = ex * ex + ey * ey
    moving = ll > 0.0
    for i in range(i0, i1 + 1):
        cy = oy + (i + 0.5) * cell
        for j in range(j0, j1 + 1):
            # _closest_on_segment, and a store whatever the outcome: no branch in the loop (which
            # cells a step reaches, and which were laid, are a coin toss to the branch predictor)
            cx = ox + (j + 0.5) * cell
            t = min(1.0, max(0.0, ((cx - x0) * ex + (cy - y0) * ey) / ll)) if moving else 0.0
            qx, qy = x0 + t * ex, y0 + t * ey
            g = grid[i, j]
            grid[i, j] = value if ((cx - qx) ** 2 + (cy - qy) ** 2 <= h2) & (g == 0) else g


@loop_jit
def read_cell(grid, ox, oy, cell, x, y):
    """The raster's value (0 or 1) under the point (x, y); 0 off the grid."""
    j = int(math.floor((x - ox) / cell))
    i = int(math.floor((y - oy) / cell))
    if 0 <= i < grid.shape[0] and 0 <= j < grid.shape[1]:
        return grid[i, j]
    return 0
