"""The compiled world's shortcuts against the rules they shortcut, to the last digit."""

import math

import numpy as np

from stcvision.controllers.buffon.nests import parse_nest
from stcvision.sim_camera.fastworld import StaticGeometry, ray_fan, stamp_segment

CELL = 0.00275  # the paper's 0.1 u trail's raster cell (half the trail width)
HALF = 0.00275


def _stamp_everywhere(grid, ox, oy, cell, half, x0, y0, x1, y1, value):
    """The rule over the whole raster: every empty cell whose centre is within ``half`` of the
    segment gets ``value`` (the same float64 operations, in numpy)."""
    ny, nx = grid.shape
    cy, cx = np.meshgrid(oy + (np.arange(ny) + 0.5) * cell, ox + (np.arange(nx) + 0.5) * cell, indexing="ij")
    ex, ey = x1 - x0, y1 - y0
    ll = ex * ex + ey * ey
    t = np.minimum(1.0, np.maximum(0.0, ((cx - x0) * ex + (cy - y0) * ey) / ll)) if ll > 0.0 else 0.0
    qx, qy = x0 + t * ex, y0 + t * ey
    hit = ((cx - qx) ** 2 + (cy - qy) ** 2 <= half * half) & (grid == 0)
    grid[hit] = value


def test_stamp_marks_exactly_the_cells_within_half_of_the_path():
    """A random walk of robot-sized steps (and some long and zero ones), stamped step by step:
    the raster is the rule's, cell for cell, first values kept."""
    rng = np.random.default_rng(3)
    shape = (64, 80)
    got = np.zeros(shape, dtype=np.uint32)
    want = np.zeros(shape, dtype=np.uint32)
    x, y = 0.11, 0.09
    for k in range(1, 400):
        step = rng.choice([0.0, 0.0019, 0.004, 0.03])
        a = rng.uniform(-math.pi, math.pi)
        nx_ = min(max(x + step * math.cos(a), -0.01), 0.23)  # the walk may leave the raster a little
        ny_ = min(max(y + step * math.sin(a), -0.01), 0.19)
        stamp_segment(got, 0.0, 0.0, CELL, HALF, x, y, nx_, ny_, np.uint32(k))
        _stamp_everywhere(want, 0.0, 0.0, CELL, HALF, x, y, nx_, ny_, np.uint32(k))
        x, y = nx_, ny_
    assert np.array_equal(got, want)
    assert 300 < np.count_nonzero(got) < got.size


def test_a_fan_of_rays_gives_each_ray_its_own_distance():
    """Six rays cast as one fan and one by one, in a nest with a thick barrier (capsules of
    radius > 0) and plain walls: the same distances."""
    geo = StaticGeometry.from_arena(parse_nest("circle:20", "plus:0.5").arena, reach_m=0.0825)
    rng = np.random.default_rng(5)
    cx, cy = geo.outer.mean(axis=0)
    met = 0
    for _ in range(300):
        x, y = cx + rng.uniform(-0.5, 0.5), cy + rng.uniform(-0.5, 0.5)
        ang = rng.uniform(-math.pi, math.pi) + np.radians([90, 45, 10, -10, -45, -90])
        fan = np.array([x + 0.0275 * np.cos(ang), y + 0.0275 * np.sin(ang), np.cos(ang), np.sin(ang), np.zeros(6)])
        ray_fan(*geo.arrays, x, y, fan, 0.05)
        for q in range(6):
            one = fan[:, q : q + 1].copy()
            ray_fan(*geo.arrays, x, y, one, 0.05)
            assert one[4, 0] == fan[4, q]
        met += int(np.isfinite(fan[4]).sum())
    assert met > 50
