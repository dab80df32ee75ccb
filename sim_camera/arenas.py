"""Arena geometry: the closed regions robots live in, as frozen dataclasses.

An arena is an outer shape (circle, square, ellipse, polygon, or an STC board's rectangle) plus
optional straight barriers (the ``|`` and ``+`` partial barriers of the Buffon's needle paper,
Girgin & Sahin, sec. 3.1 / 5.3) and obstacles (circles, polygons; for a board, its
blocked sub-cells). Everything is in metres, world frame (x east, y north).

The *free region* is inside the outer shape, outside every obstacle and farther than half a
barrier's thickness from every barrier. :meth:`Arena.contains` tests points against it
(vectorised); :meth:`Arena.contains_xy` is the scalar fast path the world's containment guard
calls every step; :meth:`Arena.clearance_m` is the signed distance to the nearest solid.

Curved outer shapes are turned into *inscribed* polygons for the physics walls
(:meth:`Arena.outer_vertices`, sagitta at most ``curve_tolerance_m``), so a robot held by the
walls stays inside the exact curve. ``clearance_m`` of an ellipse uses that polygon too (error at
most the sagitta).

JSON form (``Arena.from_dict`` / ``Arena.from_file``; every length in metres)::

    {"schema_version": 1, "kind": "circle", "center_m": [0, 0], "radius_m": 1.0,
     "wall_thickness_m": 0.05,
     "barriers": [{"type": "|", "length_fraction": 0.5, "thickness_m": 0.01},
                  {"type": "+", "length_fraction": 0.3},
                  {"start_m": [0, 0], "end_m": [0.2, 0]}],
     "obstacles": [{"kind": "circle", "center_m": [0.3, 0], "radius_m": 0.05},
                   {"kind": "polygon", "vertices_m": [[0, 0], [0.1, 0], [0, 0.1]]}]}

``kind`` is one of ``circle`` (``center_m``, ``radius_m``), ``square`` (``center_m``,
``side_m``), ``ellipse`` (``center_m``, ``semi_axes_m`` = [along x, along y]) and ``polygon``
(``vertices_m``: at least 3 [x, y] pairs). A ``|`` barrier is vertical, a ``+`` barrier is a
vertical and a horizontal one; both are centred on the arena's centre and their length is
``length_fraction`` times the arena's diameter (its extent along the barrier), as in the paper.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from stcvision.errors import BadInputError
from stcvision.stc_geometry import DEFAULT_SUBCELL_M

__all__ = [
    "Arena",
    "Barrier",
    "BoardArena",
    "CircleArena",
    "CircleObstacle",
    "EllipseArena",
    "PolygonArena",
    "PolygonObstacle",
    "SquareArena",
    "arena_from_board",
    "as_points",
]

SCHEMA_VERSION = 1
DEFAULT_WALL_THICKNESS_M = 0.05  # outer walls: built outward, so thickness costs no floor area
DEFAULT_BARRIER_THICKNESS_M = 0.01  # Buffon barriers: not given in the paper; thin vs. 55 mm robot
DEFAULT_CURVE_TOLERANCE_M = 0.0005  # max sagitta of the inscribed polygon of a curved arena
#: the largest length or coordinate an arena file may give: 10 km, far beyond any arena a robot
#: explores; it keeps areas finite (a radius of 1e300 m overflowed pi r^2, found by fuzzing)
MAX_LENGTH_M = 1e4
_SHAPE_KEYS = {
    "circle": {"center_m", "radius_m"},
    "square": {"center_m", "side_m"},
    "ellipse": {"center_m", "semi_axes_m"},
    "polygon": {"vertices_m"},
}
_COMMON_KEYS = {"schema_version", "kind", "wall_thickness_m", "barriers", "obstacles"}


# --------------------------------------------------------------------------- geometry helpers


def as_points(points: Any) -> np.ndarray:
    """``points`` as an (N, 2) float array of floor points (m); one point (2,) becomes (1, 2).

    Parameters
    ----------
    points : array_like, (N, 2) or (2,)

    Returns
    -------
    (N, 2) float ndarray

    Raises
    ------
    BadInputError
        If they are not points on the floor.
    """
    p = np.asarray(points, dtype=float)
    if p.ndim == 1 and p.shape[0] == 2:
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] != 2:
        raise BadInputError(f"points must have shape (N, 2) in metres; got {p.shape}")
    return p


def points_in_polygon(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Even-odd point-in-polygon test. ``points`` (N, 2), ``poly`` (V, 2) -> (N,) bool."""
    px = points[:, 0:1]
    py = points[:, 1:2]
    a = poly
    b = np.roll(poly, -1, axis=0)
    ay, by = a[None, :, 1], b[None, :, 1]
    cond = (ay > py) != (by > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        xint = a[None, :, 0] + (py - ay) * (b[None, :, 0] - a[None, :, 0]) / (by - ay)
    crossings = cond & (px < xint)
    return (np.count_nonzero(crossings, axis=1) % 2) == 1


def _point_in_polygon_xy(x: float, y: float, poly: tuple[tuple[float, float], ...]) -> bool:
    inside = False
    n = len(poly)
    ax, ay = poly[n - 1]
    for bx, by in poly:
        if (ay > y) != (by > y) and x < ax + (y - ay) * (bx - ax) / (by - ay):
            inside = not inside
        ax, ay = bx, by
    return inside


def segment_distances(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Point-to-segment distances: ``points`` (N, 2), ``a``, ``b`` (E, 2) -> (N, E)."""
    ab = b - a
    len2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300)
    ap = points[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("nej,ej->ne", ap, ab) / len2, 0.0, 1.0)
    d = ap - t[..., None] * ab[None]
    return np.sqrt(np.einsum("nej,nej->ne", d, d))


def _min_segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Minimum distance from each point to a set of segments, in chunks (bounded memory)."""
    out = np.empty(len(points))
    chunk = max(1, 2_000_000 // max(1, len(a)))
    for s in range(0, len(points), chunk):
        out[s : s + chunk] = segment_distances(points[s : s + chunk], a, b).min(axis=1)
    return out


def _seg_dist_xy(x: float, y: float, ax: float, ay: float, bx: float, by: float) -> float:
    dx, dy = bx - ax, by - ay
    l2 = dx * dx + dy * dy
    t = 0.0 if l2 <= 0 else min(1.0, max(0.0, ((x - ax) * dx + (y - ay) * dy) / l2))
    ex, ey = x - ax - t * dx, y - ay - t * dy
    return math.sqrt(ex * ex + ey * ey)


def polygon_area(poly: np.ndarray) -> float:
    """Signed shoelace area (positive when counter-clockwise)."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _ccw(poly: np.ndarray) -> np.ndarray:
    return poly if polygon_area(poly) > 0 else poly[::-1].copy()


# --------------------------------------------------------------------------- parsing helpers


def _vec2(d: dict, key: str, where: str) -> tuple[float, float]:
    if key not in d:
        raise BadInputError(f"{where}: missing key {key!r} (expected [x, y] in metres)")
    v = d[key]
    try:
        x, y = (float(c) for c in v)
    except (TypeError, ValueError):
        raise BadInputError(f"{where}: key {key!r} must be [x, y] in metres; got {v!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)) or max(abs(x), abs(y)) > MAX_LENGTH_M:
        raise BadInputError(f"{where}: key {key!r} must be finite, within {MAX_LENGTH_M:g} m; got {v!r}")
    return (x, y)


def _pos(d: dict, key: str, where: str, default: float | None = None) -> float:
    if key not in d:
        if default is not None:
            return default
        raise BadInputError(f"{where}: missing key {key!r} (expected a positive number, metres)")
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, int | float) or not 0 < v <= MAX_LENGTH_M:
        raise BadInputError(f"{where}: key {key!r} must be a positive number up to {MAX_LENGTH_M:g} m; got {v!r}")
    return float(v)


def _vertices(d: dict, key: str, where: str) -> tuple[tuple[float, float], ...]:
    if key not in d:
        raise BadInputError(f"{where}: missing key {key!r} (expected a list of [x, y] in metres)")
    v = d[key]
    try:
        arr = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        raise BadInputError(f"{where}: key {key!r} must be a list of [x, y] pairs") from None
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] < 3:
        raise BadInputError(f"{where}: key {key!r} must be at least 3 [x, y] pairs; got {v!r}")
    if not np.all(np.abs(arr) <= MAX_LENGTH_M):  # NaN fails too
        raise BadInputError(f"{where}: key {key!r} has coordinates that are not finite or beyond {MAX_LENGTH_M:g} m")
    if abs(polygon_area(arr)) < 1e-12:
        raise BadInputError(f"{where}: key {key!r} encloses no area")
    return tuple((float(x), float(y)) for x, y in _ccw(arr))


# --------------------------------------------------------------------------- parts


@dataclass(frozen=True, kw_only=True, slots=True)
class Barrier:
    """A straight wall segment inside the arena (a partial barrier); solid within
    ``thickness_m / 2`` of the segment."""

    start_m: tuple[float, float]
    end_m: tuple[float, float]
    thickness_m: float = DEFAULT_BARRIER_THICKNESS_M

    @property
    def length_m(self) -> float:
        return math.dist(self.start_m, self.end_m)

    def to_dict(self) -> dict:
        return {
            "start_m": list(self.start_m),
            "end_m": list(self.end_m),
            "thickness_m": self.thickness_m,
        }


@dataclass(frozen=True, kw_only=True, slots=True)
class CircleObstacle:
    """A solid disc (e.g. TASTI 2's steel can, or a pillar)."""

    center_m: tuple[float, float]
    radius_m: float

    @property
    def area_m2(self) -> float:
        return math.pi * self.radius_m**2

    def contains(self, p: np.ndarray) -> np.ndarray:
        return np.hypot(p[:, 0] - self.center_m[0], p[:, 1] - self.center_m[1]) < self.radius_m

    def contains_xy(self, x: float, y: float) -> bool:
        dx, dy = x - self.center_m[0], y - self.center_m[1]
        return dx * dx + dy * dy < self.radius_m * self.radius_m

    def signed_distance(self, p: np.ndarray) -> np.ndarray:
        return np.hypot(p[:, 0] - self.center_m[0], p[:, 1] - self.center_m[1]) - self.radius_m

    def to_dict(self) -> dict:
        return {"kind": "circle", "center_m": list(self.center_m), "radius_m": self.radius_m}


@dataclass(frozen=True, kw_only=True, slots=True)
class PolygonObstacle:
    """A solid simple polygon (vertices counter-clockwise after loading)."""

    vertices_m: tuple[tuple[float, float], ...]

    @property
    def array(self) -> np.ndarray:
        return np.asarray(self.vertices_m, dtype=float)

    @property
    def area_m2(self) -> float:
        return abs(polygon_area(self.array))

    def contains(self, p: np.ndarray) -> np.ndarray:
        return points_in_polygon(p, self.array)

    def contains_xy(self, x: float, y: float) -> bool:
        return _point_in_polygon_xy(x, y, self.vertices_m)

    def signed_distance(self, p: np.ndarray) -> np.ndarray:
        v = self.array
        d = _min_segment_distance(p, v, np.roll(v, -1, axis=0))
        return np.where(self.contains(p), -d, d)

    def is_convex(self) -> bool:
        v = self.array
        e = np.roll(v, -1, axis=0) - v
        cross = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
        return bool(np.all(cross >= -1e-12) or np.all(cross <= 1e-12))

    def to_dict(self) -> dict:
        return {"kind": "polygon", "vertices_m": [list(v) for v in self.vertices_m]}


Obstacle = CircleObstacle | PolygonObstacle


def _obstacle_from_dict(d: Any, where: str) -> Obstacle:
    if not isinstance(d, dict):
        raise BadInputError(f"{where}: must be a JSON object; got {d!r}")
    kind = d.get("kind")
    kind = kind if isinstance(kind, str) else repr(kind)
    unknown = set(d) - {"kind"} - _SHAPE_KEYS.get(kind, set())
    if kind in ("circle", "polygon") and unknown:
        raise BadInputError(f"{where}: unknown key(s) {sorted(unknown)} for a {kind} obstacle")
    if kind == "circle":
        return CircleObstacle(center_m=_vec2(d, "center_m", where), radius_m=_pos(d, "radius_m", where))
    if kind == "polygon":
        return PolygonObstacle(vertices_m=_vertices(d, "vertices_m", where))
    raise BadInputError(f"{where}: key 'kind' must be 'circle' or 'polygon'; got {kind!r}")


# --------------------------------------------------------------------------- arenas


@dataclass(frozen=True, kw_only=True, slots=True)
class Arena:
    """Base class: barriers, obstacles and wall thickness shared by every outer shape."""

    barriers: tuple[Barrier, ...] = ()
    obstacles: tuple[Obstacle, ...] = ()
    wall_thickness_m: float = DEFAULT_WALL_THICKNESS_M
    curve_tolerance_m: float = DEFAULT_CURVE_TOLERANCE_M

    kind: ClassVar[str] = "abstract"

    # -- outer shape: subclasses implement these -------------------------------------------
    def _outer_contains(self, p: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _outer_contains_xy(self, x: float, y: float) -> bool:
        raise NotImplementedError

    def outer_vertices(self) -> np.ndarray:
        """(V, 2) counter-clockwise polygon of the outer boundary (inscribed if curved)."""
        raise NotImplementedError

    @property
    def outer_area_m2(self) -> float:
        raise NotImplementedError

    @property
    def center_m(self) -> tuple[float, float]:
        raise NotImplementedError

    def extent_m(self, axis: int) -> float:
        """Extent of the outer shape along x (``axis=0``) or y (``axis=1``) through the centre."""
        raise NotImplementedError

    def _shape_dict(self) -> dict:
        raise NotImplementedError

    def _outer_signed_distance(self, p: np.ndarray) -> np.ndarray:
        v = self.outer_vertices()
        d = _min_segment_distance(p, v, np.roll(v, -1, axis=0))
        return np.where(self._outer_contains(p), d, -d)

    # -- shared API -------------------------------------------------------------------------
    @property
    def diameter_m(self) -> float:
        """The arena's diameter (largest extent along x or y), used for barrier lengths."""
        return max(self.extent_m(0), self.extent_m(1))

    @property
    def bounds_m(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of the outer boundary."""
        v = self.outer_vertices()
        return (
            float(v[:, 0].min()),
            float(v[:, 1].min()),
            float(v[:, 0].max()),
            float(v[:, 1].max()),
        )

    @property
    def area_m2(self) -> float:
        """Free floor area: outer area minus obstacles and barrier footprints (obstacles are
        assumed inside the arena and not overlapping each other)."""
        a = self.outer_area_m2
        a -= sum(o.area_m2 for o in self.obstacles)
        a -= sum(b.length_m * b.thickness_m for b in self.barriers)
        return a

    def contains(self, points: Any, margin_m: float = 0.0) -> np.ndarray:
        """Which points lie in the free region (``margin_m`` > 0: at least that far inside).

        points : (N, 2) or (2,) float, metres. Returns (N,) bool.
        """
        p = as_points(points)
        if margin_m > 0:
            return self.clearance_m(p) > margin_m
        ok = self._outer_contains(p)
        for o in self.obstacles:
            ok &= ~o.contains(p)
        if self.barriers:
            a, b, half = self._barrier_arrays()
            ok &= np.all(segment_distances(p, a, b) >= half[None, :], axis=1)
        return ok

    def contains_xy(self, x: float, y: float) -> bool:
        """Scalar :meth:`contains` (pure Python, for the per-step guard)."""
        if not self._outer_contains_xy(x, y):
            return False
        for o in self.obstacles:
            if o.contains_xy(x, y):
                return False
        for b in self.barriers:
            if _seg_dist_xy(x, y, *b.start_m, *b.end_m) < 0.5 * b.thickness_m:
                return False
        return True

    def clearance_m(self, points: Any) -> np.ndarray:
        """Signed distance (m) to the nearest solid: positive in the free region."""
        p = as_points(points)
        c = self._outer_signed_distance(p)
        for o in self.obstacles:
            c = np.minimum(c, o.signed_distance(p))
        if self.barriers:
            a, b, half = self._barrier_arrays()
            c = np.minimum(c, (segment_distances(p, a, b) - half[None, :]).min(axis=1))
        return c

    def _barrier_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        a = np.array([b.start_m for b in self.barriers], dtype=float)
        b = np.array([b.end_m for b in self.barriers], dtype=float)
        half = np.array([0.5 * b.thickness_m for b in self.barriers])
        return a, b, half

    def boundary_segments(self) -> np.ndarray:
        """Every boundary as line segments, (K, 2, 2): outer polygon edges, barrier centre lines,
        obstacle edges (circles as 64-gons)."""
        segs = []
        v = self.outer_vertices()
        segs.append(np.stack([v, np.roll(v, -1, axis=0)], axis=1))
        for b in self.barriers:
            segs.append(np.array([[b.start_m, b.end_m]], dtype=float))
        for o in self.obstacles:
            ov = _obstacle_polygon(o, 64)
            segs.append(np.stack([ov, np.roll(ov, -1, axis=0)], axis=1))
        return np.concatenate(segs, axis=0)

    def sample_free_points(self, n: int, rng: np.random.Generator, margin_m: float = 0.0) -> np.ndarray:
        """``n`` points uniform over the free region (shrunk by ``margin_m``), by rejection."""
        xmin, ymin, xmax, ymax = self.bounds_m
        if min(xmax - xmin, ymax - ymin) <= 2 * margin_m:  # no point is that far from the walls: say so at once
            raise BadInputError(f"arena has no free point {margin_m} m away from its walls")
        out: list[np.ndarray] = []
        got = 0
        for _ in range(1000):
            cand = rng.uniform((xmin, ymin), (xmax, ymax), size=(max(64, 2 * n), 2))
            cand = cand[self.contains(cand, margin_m)]
            out.append(cand)
            got += len(cand)
            if got >= n:
                return np.concatenate(out)[:n]
        raise BadInputError(f"arena has no free point {margin_m} m away from its walls")

    def start_pose(self, clearance_m: float) -> tuple[float, float, float]:
        """A start pose at the central bottom of the arena, heading north (Buffon's needle paper
        sec. 3.1: "the robot began its exploration from the central bottom part of the nest")."""
        cx, cy = self.center_m
        ymin = self.bounds_m[1]
        # candidates bottom-up, each row centre first; the first free one (one vectorised test:
        # a nest with no room was 1,400 scalar tests, 35 s for a thin ellipse, found by fuzzing)
        ys = np.repeat(np.linspace(ymin, cy, 200), 7)
        xs = cx + np.tile([0.0, 0.5, -0.5, 1.0, -1.0, 2.0, -2.0], 200) * clearance_m
        ok = np.flatnonzero(self.contains(np.column_stack([xs, ys]), margin_m=clearance_m))
        if len(ok):
            return (float(xs[ok[0]]), float(ys[ok[0]]), math.pi / 2)
        p = self.sample_free_points(1, np.random.default_rng(0), clearance_m)[0]
        return (float(p[0]), float(p[1]), math.pi / 2)

    # -- serialisation ----------------------------------------------------------------------
    def to_dict(self) -> dict:
        d = {"schema_version": SCHEMA_VERSION, "kind": self.kind}
        d.update(self._shape_dict())
        d["wall_thickness_m"] = self.wall_thickness_m
        d["barriers"] = [b.to_dict() for b in self.barriers]
        d["obstacles"] = [o.to_dict() for o in self.obstacles]
        return d

    @staticmethod
    def from_dict(d: Any) -> Arena:
        """Build an arena from its JSON dict; bad input raises a one-line BadInputError that
        names the offending key."""
        if not isinstance(d, dict):
            raise BadInputError(f"arena must be a JSON object; got {type(d).__name__}")
        ver = d.get("schema_version", SCHEMA_VERSION)
        if ver != SCHEMA_VERSION:
            raise BadInputError(f"arena: key 'schema_version' is {ver!r}; this version reads {SCHEMA_VERSION}")
        kind = d.get("kind")
        kind = kind if isinstance(kind, str) else repr(kind)
        where = f"arena ({kind})"
        unknown = set(d) - _COMMON_KEYS - _SHAPE_KEYS.get(kind, set())
        if kind in _SHAPE_KEYS and unknown:
            raise BadInputError(
                f"{where}: unknown key(s) {sorted(unknown)}; "
                f"expected some of {sorted(_COMMON_KEYS | _SHAPE_KEYS[kind])}"
            )
        common: dict[str, Any] = {"wall_thickness_m": _pos(d, "wall_thickness_m", where, DEFAULT_WALL_THICKNESS_M)}
        if kind == "circle":
            shape: Arena = CircleArena(
                center_m=_vec2(d, "center_m", where), radius_m=_pos(d, "radius_m", where), **common
            )
        elif kind == "square":
            shape = SquareArena(center_m=_vec2(d, "center_m", where), side_m=_pos(d, "side_m", where), **common)
        elif kind == "ellipse":
            ax = d.get("semi_axes_m")
            if not (
                isinstance(ax, list)
                and len(ax) == 2
                and all(isinstance(a, int | float) and not isinstance(a, bool) and 0 < a <= MAX_LENGTH_M for a in ax)
            ):
                raise BadInputError(
                    f"{where}: key 'semi_axes_m' must be [a, b], two positive numbers "
                    f"up to {MAX_LENGTH_M:g} m; got {ax!r}"
                )
            shape = EllipseArena(
                center_m=_vec2(d, "center_m", where),
                semi_axes_m=(float(ax[0]), float(ax[1])),
                **common,
            )
        elif kind == "polygon":
            shape = PolygonArena(vertices_m=_vertices(d, "vertices_m", where), **common)
        else:
            raise BadInputError(
                f"arena: key 'kind' must be one of 'circle', 'square', 'ellipse', 'polygon'; got {kind!r}"
            )
        barriers = _barriers_from_list(d.get("barriers", []), shape)
        obstacles_raw = d.get("obstacles", [])
        if not isinstance(obstacles_raw, list):
            raise BadInputError(f"arena: key 'obstacles' must be a list; got {obstacles_raw!r}")
        obstacles = tuple(_obstacle_from_dict(o, f"arena: obstacles[{i}]") for i, o in enumerate(obstacles_raw))
        arena = shape.with_parts(barriers=barriers, obstacles=obstacles)
        if not arena.area_m2 > 0:  # found by fuzzing: obstacles larger than the arena gave a negative area
            raise BadInputError(
                f"{where}: its obstacles and barriers cover more than its {shape.area_m2:.4g} m^2; "
                "expected obstacles inside the arena, not overlapping"
            )
        return arena

    @staticmethod
    def from_file(path: str | os.PathLike) -> Arena:
        from stcvision.fileio import read_json

        return Arena.from_dict(read_json(path, what="arena file"))

    def with_parts(self, *, barriers: tuple[Barrier, ...] = (), obstacles: tuple[Obstacle, ...] = ()) -> Arena:
        """A copy with extra barriers and obstacles appended."""
        import dataclasses

        return dataclasses.replace(
            self,
            barriers=self.barriers + tuple(barriers),
            obstacles=self.obstacles + tuple(obstacles),
        )

    def centred_barriers(
        self, kind: str, length_fraction: float, thickness_m: float = DEFAULT_BARRIER_THICKNESS_M
    ) -> tuple[Barrier, ...]:
        """The Buffon paper's ``|`` or ``+`` barrier(s), centred, length a fraction of the
        arena's extent along the barrier (sec. 5.3)."""
        cx, cy = self.center_m
        out = []
        if kind in ("|", "+"):
            h = 0.5 * length_fraction * self.extent_m(1)
            out.append(Barrier(start_m=(cx, cy - h), end_m=(cx, cy + h), thickness_m=thickness_m))
        if kind == "+":
            h = 0.5 * length_fraction * self.extent_m(0)
            out.append(Barrier(start_m=(cx - h, cy), end_m=(cx + h, cy), thickness_m=thickness_m))
        if kind not in ("|", "+"):
            raise BadInputError(f"barrier type must be '|' or '+'; got {kind!r}")
        return tuple(out)


def _barriers_from_list(raw: Any, shape: Arena) -> tuple[Barrier, ...]:
    if not isinstance(raw, list):
        raise BadInputError(f"arena: key 'barriers' must be a list; got {raw!r}")
    out: list[Barrier] = []
    for i, b in enumerate(raw):
        where = f"arena: barriers[{i}]"
        if not isinstance(b, dict):
            raise BadInputError(f"{where}: must be a JSON object; got {b!r}")
        unknown = set(b) - (
            {"type", "length_fraction", "thickness_m"} if "type" in b else {"start_m", "end_m", "thickness_m"}
        )
        if unknown:
            raise BadInputError(f"{where}: unknown key(s) {sorted(unknown)}")
        thick = _pos(b, "thickness_m", where, DEFAULT_BARRIER_THICKNESS_M)
        if "type" in b:
            frac = b.get("length_fraction")
            if isinstance(frac, bool) or not isinstance(frac, int | float) or not 0 < frac <= 1:
                raise BadInputError(f"{where}: key 'length_fraction' must be a number in (0, 1]; got {frac!r}")
            if b["type"] not in ("|", "+"):
                raise BadInputError(f"{where}: key 'type' must be '|' or '+'; got {b['type']!r}")
            out.extend(shape.centred_barriers(b["type"], float(frac), thick))
        else:
            s, e = _vec2(b, "start_m", where), _vec2(b, "end_m", where)
            if s == e:
                raise BadInputError(f"{where}: keys 'start_m' and 'end_m' are the same point")
            out.append(Barrier(start_m=s, end_m=e, thickness_m=thick))
    return tuple(out)


def _obstacle_polygon(o: Obstacle, n: int) -> np.ndarray:
    if isinstance(o, CircleObstacle):
        t = np.linspace(0, 2 * np.pi, n, endpoint=False)
        return np.c_[o.center_m[0] + o.radius_m * np.cos(t), o.center_m[1] + o.radius_m * np.sin(t)]
    return o.array


def _n_segments_for(radius_m: float, tol_m: float) -> int:
    # sagitta of a chord of an inscribed N-gon: R (1 - cos(pi/N)) ~ R pi^2 / (2 N^2) <= tol
    return int(np.clip(math.ceil(math.pi * math.sqrt(radius_m / (2 * tol_m))), 32, 4096))


@dataclass(frozen=True, kw_only=True, slots=True)
class CircleArena(Arena):
    center_m: tuple[float, float] = (0.0, 0.0)
    radius_m: float = 1.0
    kind: ClassVar[str] = "circle"

    def _outer_contains(self, p):
        return np.hypot(p[:, 0] - self.center_m[0], p[:, 1] - self.center_m[1]) < self.radius_m

    def _outer_contains_xy(self, x, y):
        dx, dy = x - self.center_m[0], y - self.center_m[1]
        return dx * dx + dy * dy < self.radius_m * self.radius_m

    def _outer_signed_distance(self, p):
        return self.radius_m - np.hypot(p[:, 0] - self.center_m[0], p[:, 1] - self.center_m[1])

    def outer_vertices(self):
        n = _n_segments_for(self.radius_m, self.curve_tolerance_m)
        t = np.linspace(0, 2 * np.pi, n, endpoint=False)
        return np.c_[
            self.center_m[0] + self.radius_m * np.cos(t),
            self.center_m[1] + self.radius_m * np.sin(t),
        ]

    @property
    def bounds_m(self):
        cx, cy = self.center_m
        r = self.radius_m
        return (cx - r, cy - r, cx + r, cy + r)

    @property
    def outer_area_m2(self):
        return math.pi * self.radius_m**2

    def extent_m(self, axis):
        return 2 * self.radius_m

    def _shape_dict(self):
        return {"center_m": list(self.center_m), "radius_m": self.radius_m}


@dataclass(frozen=True, kw_only=True, slots=True)
class SquareArena(Arena):
    center_m: tuple[float, float] = (0.0, 0.0)
    side_m: float = 1.0
    kind: ClassVar[str] = "square"

    def _outer_contains(self, p):
        h = 0.5 * self.side_m
        return (np.abs(p[:, 0] - self.center_m[0]) < h) & (np.abs(p[:, 1] - self.center_m[1]) < h)

    def _outer_contains_xy(self, x, y):
        h = 0.5 * self.side_m
        return abs(x - self.center_m[0]) < h and abs(y - self.center_m[1]) < h

    def _outer_signed_distance(self, p):
        h = 0.5 * self.side_m
        dx = h - np.abs(p[:, 0] - self.center_m[0])
        dy = h - np.abs(p[:, 1] - self.center_m[1])
        inside = np.minimum(dx, dy)
        outside = -np.hypot(np.minimum(dx, 0), np.minimum(dy, 0))
        return np.where((dx >= 0) & (dy >= 0), inside, np.minimum(outside, inside))

    def outer_vertices(self):
        cx, cy = self.center_m
        h = 0.5 * self.side_m
        return np.array([[cx - h, cy - h], [cx + h, cy - h], [cx + h, cy + h], [cx - h, cy + h]])

    @property
    def outer_area_m2(self):
        return self.side_m**2

    def extent_m(self, axis):
        return self.side_m

    def _shape_dict(self):
        return {"center_m": list(self.center_m), "side_m": self.side_m}


@dataclass(frozen=True, kw_only=True, slots=True)
class EllipseArena(Arena):
    center_m: tuple[float, float] = (0.0, 0.0)
    semi_axes_m: tuple[float, float] = (1.0, 0.5)  # (a along x, b along y)
    kind: ClassVar[str] = "ellipse"

    def _outer_contains(self, p):
        a, b = self.semi_axes_m
        return ((p[:, 0] - self.center_m[0]) / a) ** 2 + ((p[:, 1] - self.center_m[1]) / b) ** 2 < 1

    def _outer_contains_xy(self, x, y):
        a, b = self.semi_axes_m
        return ((x - self.center_m[0]) / a) ** 2 + ((y - self.center_m[1]) / b) ** 2 < 1.0

    def outer_vertices(self):
        a, b = self.semi_axes_m
        # parametric spacing; the tightest curvature radius is min(a, b)^2 / max(a, b), but the
        # parametric chords there are short too, so size N by the larger curvature radius a^2/b.
        rho = max(a, b) ** 2 / min(a, b)
        n = _n_segments_for(rho, self.curve_tolerance_m)
        t = np.linspace(0, 2 * np.pi, n, endpoint=False)
        return np.c_[self.center_m[0] + a * np.cos(t), self.center_m[1] + b * np.sin(t)]

    @property
    def bounds_m(self):
        cx, cy = self.center_m
        a, b = self.semi_axes_m
        return (cx - a, cy - b, cx + a, cy + b)

    @property
    def outer_area_m2(self):
        return math.pi * self.semi_axes_m[0] * self.semi_axes_m[1]

    def extent_m(self, axis):
        return 2 * self.semi_axes_m[axis]

    def _shape_dict(self):
        return {"center_m": list(self.center_m), "semi_axes_m": list(self.semi_axes_m)}


@dataclass(frozen=True, kw_only=True, slots=True)
class PolygonArena(Arena):
    vertices_m: tuple[tuple[float, float], ...] = ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0))
    kind: ClassVar[str] = "polygon"

    def _outer_contains(self, p):
        return points_in_polygon(p, self.outer_vertices())

    def _outer_contains_xy(self, x, y):
        return _point_in_polygon_xy(x, y, self.vertices_m)

    def outer_vertices(self):
        return _ccw(np.asarray(self.vertices_m, dtype=float))

    @property
    def outer_area_m2(self):
        return abs(polygon_area(self.outer_vertices()))

    @property
    def center_m(self):
        xmin, ymin, xmax, ymax = self.bounds_m
        return (0.5 * (xmin + xmax), 0.5 * (ymin + ymax))

    def extent_m(self, axis):
        v = self.outer_vertices()[:, axis]
        return float(v.max() - v.min())

    def _shape_dict(self):
        return {"vertices_m": [list(v) for v in self.vertices_m]}


@dataclass(frozen=True, kw_only=True, slots=True)
class BoardArena(Arena):
    """An STC board: its outer rectangle as walls and every blocked sub-cell as a static square
    obstacle (horizontal runs of blocked sub-cells merged into one rectangle each).

    ``blocked`` row 0 is the north (top) row; the board spans x in [0, W], y in [0, H].
    """

    blocked: np.ndarray = field(default_factory=lambda: np.zeros((2, 2), bool), compare=False)
    subcell_m: float = DEFAULT_SUBCELL_M
    red_lights: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)), compare=False)
    start_xy_m: tuple[float, float] | None = None  # centre of the board's start sub-cell
    kind: ClassVar[str] = "board"

    def start_pose(self, clearance_m: float) -> tuple[float, float, float]:
        """The start sub-cell's centre, heading north (if free enough), else the generic one."""
        if self.start_xy_m is not None and self.contains(self.start_xy_m, clearance_m)[0]:
            return (self.start_xy_m[0], self.start_xy_m[1], math.pi / 2)
        return Arena.start_pose(self, clearance_m)

    @property
    def size_m(self) -> tuple[float, float]:
        rows, cols = self.blocked.shape
        return (cols * self.subcell_m, rows * self.subcell_m)

    @property
    def center_m(self):
        w, h = self.size_m
        return (0.5 * w, 0.5 * h)

    def extent_m(self, axis):
        return self.size_m[axis]

    def outer_vertices(self):
        w, h = self.size_m
        return np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])

    @property
    def outer_area_m2(self):
        w, h = self.size_m
        return w * h

    @property
    def area_m2(self):
        return float((~self.blocked).sum()) * self.subcell_m**2

    def _outer_contains(self, p):
        w, h = self.size_m
        return (p[:, 0] > 0) & (p[:, 0] < w) & (p[:, 1] > 0) & (p[:, 1] < h)

    def _outer_contains_xy(self, x, y):
        w, h = self.size_m
        return 0.0 < x < w and 0.0 < y < h

    def contains(self, points, margin_m=0.0):
        p = as_points(points)
        if margin_m > 0:
            return self.clearance_m(p) > margin_m
        ok = self._outer_contains(p)
        rows, cols = self.blocked.shape
        h = rows * self.subcell_m
        j = np.clip((p[:, 0] / self.subcell_m).astype(int), 0, cols - 1)
        i = np.clip(((h - p[:, 1]) / self.subcell_m).astype(int), 0, rows - 1)
        return ok & ~self.blocked[i, j]

    def contains_xy(self, x, y):
        if not self._outer_contains_xy(x, y):
            return False
        rows, cols = self.blocked.shape
        j = min(int(x / self.subcell_m), cols - 1)
        i = min(int((rows * self.subcell_m - y) / self.subcell_m), rows - 1)
        return not self.blocked[i, j]

    def _shape_dict(self):
        return {
            "subcell_m": self.subcell_m,
            "blocked": ["".join("#" if c else "." for c in row) for row in self.blocked],
        }


def arena_from_board(board: Any, *, wall_thickness_m: float = DEFAULT_WALL_THICKNESS_M) -> BoardArena:
    """Arena of a :class:`stcvision.sim_camera.board.Board` (anything with ``blocked``, ``subcell_m``)."""
    blocked = np.asarray(board.blocked, dtype=bool).copy()
    blocked.setflags(write=False)
    d = float(board.subcell_m)
    rows, cols = blocked.shape
    h = rows * d
    obstacles: list[Obstacle] = []
    for i in range(rows):
        j = 0
        while j < cols:
            if blocked[i, j]:
                k = j
                while k + 1 < cols and blocked[i, k + 1]:
                    k += 1
                x0, x1 = j * d, (k + 1) * d
                y1, y0 = h - i * d, h - (i + 1) * d
                obstacles.append(PolygonObstacle(vertices_m=((x0, y0), (x1, y0), (x1, y1), (x0, y1))))
                j = k + 1
            else:
                j += 1
    red = getattr(board, "red_lights_m", None)
    red_lights = np.asarray(red(), dtype=float) if callable(red) else np.zeros((0, 2))
    start = getattr(board, "start_subcell", None)
    start_xy = None
    if start is not None:
        start_xy = ((start[1] + 0.5) * d, h - (start[0] + 0.5) * d)
    return BoardArena(
        blocked=blocked,
        subcell_m=d,
        obstacles=tuple(obstacles),
        red_lights=red_lights,
        wall_thickness_m=wall_thickness_m,
        start_xy_m=start_xy,
    )
