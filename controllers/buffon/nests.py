"""Nests of the Buffon experiments (the Buffon's needle paper of Girgin & Sahin, sec. 3.1 and 5),
in body lengths, and their parsing from the command line.

Unit: one *body length* u = the Khepera's diameter, 55 mm (``2 * KHEPERA.radius_m``; the paper
measures nests in "units (robot diameters)").

**One consistent scale.** The paper's numbers cannot all hold: "the diameter of the smallest
circular nest is approximately ten times the body length", "the largest nest is ten times wider
than the smallest one", "circular nest with diameter 100 units ... is taken as the standard size
nest", yet sec. 5.1 gives the two smallest nests' areas as 348 and 1392 unit^2 (diameters 21 and
42 u). We keep the stated diameters and the stated ratio between the two smallest areas (4, i.e.
diameters d and 2d): ten circles of diameter 10, 20, ..., 100 u (areas 78.5 to 7,854 u^2); the
standard nest is the largest, diameter 100 u, area 7,854 u^2. Every other set is built from it.

Spec strings (the CLI's ``--nest``): ``circle:DIAMETER``, ``square:SIDE``,
``ellipse:AREA:RATIO`` (RATIO = r1/r2 >= 1, major axis horizontal), ``polygon:FILE`` (a JSON
list of [x, y] vertices in body lengths: a simple polygon, convex or not). Barriers (``--barrier``):
``bar:FRACTION`` (the paper's ``|``, vertical) or ``plus:FRACTION`` (``+``), centred, their length
a fraction of the nest's extent (sec. 5.3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stcvision.errors import BadInputError
from stcvision.sim_camera.arenas import (
    DEFAULT_BARRIER_THICKNESS_M,
    Arena,
    CircleArena,
    EllipseArena,
    PolygonArena,
    SquareArena,
)
from stcvision.sim_camera.robot import KHEPERA

__all__ = [
    "BODY_LENGTH_M",
    "STANDARD_AREA_U2",
    "STANDARD_DIAMETER_U",
    "Nest",
    "eccentricity_to_ratio",
    "parse_barrier",
    "parse_nest",
]

BODY_LENGTH_M = 2 * KHEPERA.radius_m  # the paper's unit: the robot's diameter (55 mm)
STANDARD_DIAMETER_U = 100.0  # sec. 3.1: "Circular nest with diameter 100 units ... standard size"
STANDARD_AREA_U2 = math.pi * (STANDARD_DIAMETER_U / 2) ** 2
START_CLEARANCE_BODY_LENGTHS = 1.0  # the start's centre is one body length above the bottom wall
_MAX_EXTENT_U = 2000.0  # the batched path's near grid and trail raster must fit in memory
_MAX_VERTICES = 1000  # a polygon nest's vertices: its self-intersection test is O(n^2)


def eccentricity_to_ratio(e: float) -> float:
    """r1/r2 of an ellipse of eccentricity ``e`` (sec. 5.2's compactness)."""
    return 1.0 / math.sqrt(1.0 - e * e)


@dataclass(frozen=True, kw_only=True, slots=True)
class Nest:
    """A nest: its spec, the arena in metres, and its true floor area in u^2."""

    spec: str
    barrier: str | None
    arena: Arena

    @property
    def area_u2(self) -> float:
        """True free floor area (outer area minus barrier footprints), body lengths squared."""
        return self.arena.area_m2 / BODY_LENGTH_M**2

    @property
    def start_xy(self) -> tuple[float, float]:
        """Where both visits start (m): the central bottom of the nest (sec. 3.1: "the robot began
        its exploration from the central bottom part of the nest"), one body length above the wall."""
        x, y, _ = self.arena.start_pose(START_CLEARANCE_BODY_LENGTHS * BODY_LENGTH_M)
        return x, y

    @property
    def label(self) -> str:
        return self.spec + (f" {self.barrier}" if self.barrier else "")


def _positive(text: str, what: str, spec: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise BadInputError(f"nest {spec!r}: {what} must be a number; got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise BadInputError(f"nest {spec!r}: {what} must be a positive number; got {text!r}")
    return v


def _polygon_from_file(path: str, spec: str) -> np.ndarray:
    from stcvision.fileio import read_json

    raw = read_json(path, what="polygon file")
    try:
        v = np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        raise BadInputError(f"polygon file {path}: expected a JSON list of [x, y] numbers") from None
    if v.ndim != 2 or v.shape[1] != 2:
        raise BadInputError(f"polygon file {path}: expected a JSON list of [x, y] pairs; got shape {v.shape}")
    if not (np.abs(v) <= _MAX_EXTENT_U).all():  # NaN fails too; bounded before any arithmetic (fuzzing: overflow)
        raise BadInputError(
            f"polygon file {path}: vertices must be finite numbers within {_MAX_EXTENT_U:g} body lengths"
        )
    if len(v) > _MAX_VERTICES:  # the self-intersection test is quadratic
        raise BadInputError(f"polygon file {path}: {len(v):,} vertices; expected at most {_MAX_VERTICES:,}")
    if len(v) >= 2 and np.allclose(v[0], v[-1]):
        v = v[:-1]  # a closed ring: drop the repeated vertex
    if len(v) < 3:
        raise BadInputError(f"polygon file {path}: needs at least 3 vertices; got {len(v)}")
    if _self_intersects(v):
        raise BadInputError(f"polygon file {path}: the polygon intersects itself; expected a simple polygon")
    a = 0.5 * abs(np.dot(v[:, 0], np.roll(v[:, 1], -1)) - np.dot(v[:, 1], np.roll(v[:, 0], -1)))
    if not a > 0:
        raise BadInputError(f"polygon file {path}: the polygon has zero area")
    return v


def _self_intersects(v: np.ndarray) -> bool:
    """True if two non-adjacent edges of the closed polygon ``v`` meet (or adjacent ones overlap)."""
    n = len(v)
    a, b = v, np.roll(v, -1, axis=0)

    def orient(p, q, r):
        return np.sign(
            (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])
        )

    for i in range(n):
        j = np.arange(i + 1, n)
        adjacent = (j == i + 1) | ((i == 0) & (j == n - 1))
        pa, pb = a[i], b[i]
        qa, qb = a[j], b[j]
        o1, o2 = orient(pa, pb, qa), orient(pa, pb, qb)
        o3, o4 = orient(qa, qb, pa), orient(qa, qb, pb)
        proper = (o1 * o2 < 0) & (o3 * o4 < 0)
        touching = ((o1 == 0) | (o2 == 0) | (o3 == 0) | (o4 == 0)) & _boxes_overlap(pa, pb, qa, qb)
        collinear_overlap = adjacent & (o1 == 0) & (o2 == 0) & _overlap_beyond_vertex(pa, pb, qa, qb)
        if np.any(proper & ~adjacent) or np.any(touching & ~adjacent) or np.any(collinear_overlap):
            return True
    return False


def _boxes_overlap(pa, pb, qa, qb):
    lo = np.minimum(qa, qb)
    hi = np.maximum(qa, qb)
    return np.all((np.maximum(np.minimum(pa, pb), lo) <= np.minimum(np.maximum(pa, pb), hi) + 1e-12), axis=-1)


def _overlap_beyond_vertex(pa, pb, qa, qb):
    """Adjacent collinear edges that fold back over each other (a spike)."""
    d1 = pb - pa
    d2 = qb - qa
    return (d1 * d2).sum(axis=-1) < 0


def _outer(kind: str, args: list[str], spec: str) -> Arena:
    u = BODY_LENGTH_M
    if kind == "circle" and len(args) == 1:
        return CircleArena(radius_m=0.5 * _positive(args[0], "DIAMETER", spec) * u)
    if kind == "square" and len(args) == 1:
        return SquareArena(side_m=_positive(args[0], "SIDE", spec) * u)
    if kind == "ellipse" and len(args) == 2:
        area = _positive(args[0], "AREA", spec)
        ratio = _positive(args[1], "RATIO", spec)
        if ratio < 1:
            raise BadInputError(f"nest {spec!r}: RATIO = r1/r2 must be >= 1; got {args[1]!r}")
        b = math.sqrt(area / (math.pi * ratio))
        return EllipseArena(semi_axes_m=(ratio * b * u, b * u))
    if kind == "polygon" and len(args) >= 1:
        v = _polygon_from_file(":".join(args), spec) * u
        return PolygonArena(vertices_m=tuple((float(x), float(y)) for x, y in v))
    raise BadInputError(
        f"nest {spec!r}: expected circle:DIAMETER, square:SIDE, ellipse:AREA:RATIO or polygon:FILE "
        "(lengths in body lengths)"
    )


def parse_barrier(text: str) -> tuple[str, float]:
    """``bar:F`` -> ("|", F); ``plus:F`` -> ("+", F); F in (0, 1)."""
    kind, _, frac = text.partition(":")
    kinds = {"bar": "|", "|": "|", "plus": "+", "+": "+"}
    if kind not in kinds or not frac:
        raise BadInputError(f"barrier {text!r}: expected bar:FRACTION or plus:FRACTION")
    try:
        f = float(frac)
    except ValueError:
        raise BadInputError(f"barrier {text!r}: FRACTION must be a number in (0, 1); got {frac!r}") from None
    if not 0 < f < 1:
        raise BadInputError(f"barrier {text!r}: FRACTION must be in (0, 1); got {frac!r}")
    return kinds[kind], f


def parse_nest(spec: str, barrier: str | None = None, *, robot_radius_m: float = KHEPERA.radius_m) -> Nest:
    """The nest of ``spec`` (and ``barrier``), checked: not larger than the batched path can
    hold, wide enough for the robot, and not cut in two by its barrier."""
    if not isinstance(spec, str) or ":" not in spec:
        raise BadInputError(f"nest {spec!r}: expected KIND:ARGS, e.g. circle:100 or ellipse:7854:4")
    kind, *args = spec.split(":")
    arena = _outer(kind, args, spec)
    xmin, ymin, xmax, ymax = arena.bounds_m
    if max(xmax - xmin, ymax - ymin) > _MAX_EXTENT_U * BODY_LENGTH_M:
        raise BadInputError(f"nest {spec!r}: larger than {_MAX_EXTENT_U:g} body lengths across")
    if barrier:
        btype, frac = parse_barrier(barrier)
        arena = arena.with_parts(barriers=arena.centred_barriers(btype, frac, DEFAULT_BARRIER_THICKNESS_M))
        _check_not_cut(arena, spec, barrier, robot_radius_m)
    nest = Nest(spec=spec, barrier=barrier, arena=arena)
    try:
        start = nest.start_xy
    except BadInputError:
        start = None
    if start is None or not arena.contains([start], margin_m=START_CLEARANCE_BODY_LENGTHS * BODY_LENGTH_M * 0.99)[0]:
        raise BadInputError(
            f"nest {spec!r}: too small: the robot starts {START_CLEARANCE_BODY_LENGTHS:g} body length from every wall"
        )
    return nest


def _check_not_cut(arena: Arena, spec: str, barrier: str, robot_radius_m: float) -> None:
    """Each barrier end must leave a gap the robot fits through, to the outer wall and to every
    other barrier's body (else the barrier cuts the nest)."""
    outer_only = type(arena)(**{k: getattr(arena, k) for k in _shape_fields(arena)})
    for b in arena.barriers:
        for end in (b.start_m, b.end_m):
            gap = float(outer_only.clearance_m([end])[0]) - 0.5 * b.thickness_m
            if gap < 2 * robot_radius_m:
                raise BadInputError(
                    f"barrier {barrier!r} cuts nest {spec!r} in two: a gap of {gap / BODY_LENGTH_M:.2f} body lengths "
                    "is left at its end; the robot needs 1"
                )


def _shape_fields(arena: Arena) -> list[str]:
    import dataclasses

    return [f.name for f in dataclasses.fields(arena) if f.name not in ("barriers", "obstacles")]
