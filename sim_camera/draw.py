"""Top-down drawing of a world into a BGR uint8 image (OpenCV), north up, fixed px per metre.

Draws, back to front: pheromone trail (light blue) and chemical patches (yellow shade), the board
grid (sub-cells thin, cells thicker) and blocked cells with the red dots of their red lights,
obstacles (grey), outer walls and barriers (black, true thickness), robot trails (blue), the
odometry estimate (magenta cross), and each robot (green circle with a heading line).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from stcvision.errors import BadInputError
from stcvision.sim_camera.arenas import BoardArena, CircleObstacle

__all__ = ["draw_world", "world_to_px"]

MAX_SIDE_PX = 4096


class _Frame:
    def __init__(self, bounds, px_per_m, margin_px):
        self.xmin, self.ymin, self.xmax, self.ymax = bounds
        self.s = float(px_per_m)
        self.m = int(margin_px)
        self.w = int(math.ceil((self.xmax - self.xmin) * self.s)) + 2 * self.m
        self.h = int(math.ceil((self.ymax - self.ymin) * self.s)) + 2 * self.m

    def px(self, pts) -> np.ndarray:
        p = np.asarray(pts, dtype=float).reshape(-1, 2)
        u = (p[:, 0] - self.xmin) * self.s + self.m
        v = (self.ymax - p[:, 1]) * self.s + self.m
        return np.round(np.c_[u, v]).astype(np.int32)

    def world(self, u, v):
        return (self.xmin + (u + 0.5 - self.m) / self.s, self.ymax - (v + 0.5 - self.m) / self.s)


def world_to_px(world, px_per_m: float = 200.0, margin_px: int = 20):
    """Function mapping world (N, 2) m to image (N, 2) int px for :func:`draw_world`'s frame."""
    return _Frame(_bounds(world), px_per_m, margin_px).px


def _bounds(world):
    xmin, ymin, xmax, ymax = world.arena.bounds_m
    pad = 0.5 * world.arena.wall_thickness_m + 0.01
    return (xmin - pad, ymin - pad, xmax + pad, ymax + pad)


def draw_world(
    world,
    *,
    px_per_m: float = 200.0,
    margin_px: int = 20,
    trails: bool = True,
    odometry: bool = True,
) -> np.ndarray:
    """Draw ``world`` top-down. Returns (H, W, 3) uint8 BGR."""
    f = _Frame(_bounds(world), px_per_m, margin_px)
    if f.w > MAX_SIDE_PX or f.h > MAX_SIDE_PX:
        raise BadInputError(
            f"drawing would be {f.w}x{f.h} px (> {MAX_SIDE_PX}); use a smaller px_per_m than {px_per_m}"
        )
    img = np.full((f.h, f.w, 3), 255, np.uint8)
    arena = world.arena
    # outer walls are built outward from the boundary: draw a line twice the wall thickness
    # centred on the boundary, then clear the inside, so only the outer half shows
    verts = f.px(arena.outer_vertices())
    cv2.polylines(img, [verts], True, (0, 0, 0), max(1, int(round(2 * arena.wall_thickness_m * f.s))), cv2.LINE_AA)
    cv2.fillPoly(img, [verts], (255, 255, 255), cv2.LINE_AA)
    _draw_floor(img, f, world)
    if isinstance(arena, BoardArena):
        _draw_board(img, f, arena)
    else:
        _draw_obstacles(img, f, arena)
    cv2.polylines(img, [verts], True, (0, 0, 0), 1, cv2.LINE_AA)
    for b in arena.barriers:
        p = f.px([b.start_m, b.end_m])
        width = max(1, int(round(b.thickness_m * f.s)))
        cv2.line(img, tuple(map(int, p[0])), tuple(map(int, p[1])), (0, 0, 0), width, cv2.LINE_AA)
    _draw_robots(img, f, world.robots, trails=trails, odometry=odometry)
    return img


def _draw_floor(img: np.ndarray, f: _Frame, world) -> None:
    """The floor layers (chemical patches, pheromone), sampled at pixel centres."""
    if world.pheromone is None and world.chemical is None:
        return
    vv, uu = np.mgrid[0 : f.h, 0 : f.w]
    x, y = f.world(uu.ravel(), vv.ravel())
    pts = np.c_[x, y]
    if world.chemical is not None and world.chemical.patches:
        c = world.chemical.concentration(pts).reshape(f.h, f.w)
        c = np.clip(c / max(1e-12, float(c.max())), 0, 1)
        img[c > 0] = (255 - 120 * c[c > 0, None] * np.array([1.0, 0.0, 0.0])).astype(np.uint8)
    if world.pheromone is not None:
        m = world.pheromone.read(pts).reshape(f.h, f.w)
        img[m] = (235, 190, 120)


def _draw_board(img: np.ndarray, f: _Frame, arena) -> None:
    """A board's blocked sub-cells, its grid (cell lines darker than sub-cell lines) and red lights."""
    d = arena.subcell_m
    rows, cols = arena.blocked.shape
    top = arena.size_m[1]
    for i, j in np.argwhere(arena.blocked):
        p = f.px([[j * d, top - i * d], [(j + 1) * d, top - (i + 1) * d]])
        cv2.rectangle(img, tuple(map(int, p[0])), tuple(map(int, p[1])), (90, 90, 90), -1)
    lines = [([j * d, 0], [j * d, top], j) for j in range(cols + 1)]
    lines += [([0, i * d], [cols * d, i * d], i) for i in range(rows + 1)]
    for a, b, k in lines:
        p = f.px([a, b])
        colour = (150, 150, 150) if k % 2 == 0 else (215, 215, 215)  # cell lines, sub-cell lines
        cv2.line(img, tuple(map(int, p[0])), tuple(map(int, p[1])), colour, 1)
    if len(arena.red_lights):
        xy = arena.red_lights
        inside = (xy[:, 0] > 0) & (xy[:, 0] < arena.size_m[0]) & (xy[:, 1] > 0) & (xy[:, 1] < top)
        for u, v in f.px(xy[inside]):
            cv2.circle(img, (int(u), int(v)), max(2, int(0.02 * f.s)), (0, 0, 255), -1, cv2.LINE_AA)


def _draw_obstacles(img: np.ndarray, f: _Frame, arena) -> None:
    """An open arena's circle and polygon obstacles."""
    for o in arena.obstacles:
        if isinstance(o, CircleObstacle):
            c = f.px([o.center_m])[0]
            rad = max(1, int(round(o.radius_m * f.s)))
            cv2.circle(img, (int(c[0]), int(c[1])), rad, (120, 120, 120), -1, cv2.LINE_AA)
        else:
            cv2.fillPoly(img, [f.px(o.vertices_m)], (120, 120, 120), cv2.LINE_AA)


def _draw_robots(img: np.ndarray, f: _Frame, robots, *, trails: bool, odometry: bool) -> None:
    """Every robot's trail (all trails first, under every robot), body, heading and odometry."""
    for r in robots:
        if trails and len(r.trail) > 1:
            tr = np.asarray(r.trail)
            stride = max(1, len(tr) // 20000)
            cv2.polylines(img, [f.px(tr[::stride])], False, (200, 80, 0), 1, cv2.LINE_AA)
    for r in robots:
        x, y, th = r.pose
        c = f.px([[x, y]])[0]
        rad = max(2, int(round(r.params.radius_m * f.s)))
        cv2.circle(img, (int(c[0]), int(c[1])), rad, (0, 160, 0), 2, cv2.LINE_AA)
        tip = f.px([[x + r.params.radius_m * math.cos(th), y + r.params.radius_m * math.sin(th)]])
        cv2.line(img, (int(c[0]), int(c[1])), (int(tip[0][0]), int(tip[0][1])), (0, 160, 0), 2, cv2.LINE_AA)
        if odometry:
            o = f.px([[r.odometry.x, r.odometry.y]])[0]
            cv2.drawMarker(img, (int(o[0]), int(o[1])), (200, 0, 200), cv2.MARKER_CROSS, max(6, rad), 1)
