"""Search patterns of TASTI 2 (the TASTI 2 paper by Russell, sec. II): a repeated sequence of a
straight step of fixed length ``step_m``, an on-the-spot turn and a sensing operation.

A pattern is its list of headings: step ``i`` moves ``step_m`` along ``headings_rad[i]`` (in the
robot's start frame, heading 0 = the start heading), so the planned sampling points are
equations (4)-(5): ``p_{i+1} = p_i + step_m (cos theta_i, sin theta_i)``, ``theta_{i+1} =
theta_i + dtheta_i``.

Radial "flower" (equations (1)-(2))::

    dtheta_i = 4 pi / n * sin(2 pi (i + n/4) / n)^2
    if rem(i, n) == n/4:  dtheta_i += 2 pi / petals

The sin^2 term sums to 2 pi over one petal (``n >= 3``), so each petal is one loop out and back
and the extra ``2 pi / petals`` turns the next petal; after ``n * petals`` steps the heading has
turned ``2 pi (petals + 1)`` and the petals' displacements, rotated copies of one another, sum to
zero: the flower closes on itself. The paper says ``n`` "should be divisible by 4" but its Fig. 1
uses n = 30. **Reading for n not divisible by 4**: the kick is applied at ``rem(i, n) == n // 4``
(the step where ``i`` first passes ``n/4``), the sin^2 term is used as written (``n/4``
fractional). Without that reading the kick would never fire and all petals would lie on top of
one another; with it the flower closes just the same (the closing argument does not need n/4 to
be whole) and Fig. 1's 12 x 30 flower is drawn.

**Where the flower starts.** Counted from ``i = 0`` the petals' common point (the flower's
centre) is ``p_{n//4 + 1}``, the point reached by the step after which the kick turns (the
sin^2 term turns fastest at ``i = 0`` and ``n/2``, the petals' outer and inner bends, and the
kick falls on the straight leg between them). Starting at ``i = 0`` would put the robot on the
rim of its own flower, about one petal length from the centre. The search starts at its best
guess and extends outwards (TASTI 2 paper sec. II), so step ``j`` of the search uses
``i = j + n//4 + 1``:
the robot starts at the centre, every petal comes back through it, and the flower (``n *
petals`` steps) ends there.

Archimedes spiral: ``r = b phi`` with equal spacing ``2 pi b = spacing_m`` between turns
(counter-clockwise), sampled by chords of length ``step_m`` (each step's end lies on the spiral),
rotated so that the first step goes along heading 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq

from stcvision.errors import BadInputError

__all__ = ["RadialPattern", "SpiralPattern", "planned_points", "radial_turn_rad"]

# the TASTI 2 paper (Russell), sec. V: "The step size of the robot search path was 141mm"
DEFAULT_STEP_M = 0.141
DEFAULT_SPIRAL_MAX_STEPS = 150  # ~1.3 m radius at the default step and spacing
# The TASTI 2 paper gives no spacing between the spiral's turns. 0.25 m (our choice) is below 0.35 /
# sqrt(2): with chords of 0.141 m along turns 0.25 m apart every 350 mm patch (sec. V) holds a
# sampling point.
DEFAULT_SPIRAL_SPACING_M = 0.25


def _positive_int(name: str, v) -> int:
    if isinstance(v, bool) or not isinstance(v, int | np.integer) or v <= 0:
        raise BadInputError(f"{name} must be a positive integer; got {v!r}")
    return int(v)


def _positive(name: str, v) -> float:
    if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
        raise BadInputError(f"{name} must be a positive number; got {v!r}")
    return float(v)


def _check_steps(n: int, what: str) -> None:
    from stcvision.limits import MAX_SEARCH_STEPS

    if n > MAX_SEARCH_STEPS:
        raise BadInputError(
            f"{what}: {n:,} search steps is over the cap of {MAX_SEARCH_STEPS:,} (stcvision.limits.MAX_SEARCH_STEPS)"
        )


def radial_turn_rad(i: int, n: int, petals: int) -> float:
    """Equations (1)-(2): the turn after step ``i`` of a flower of ``petals`` petals of ``n``
    steps (``rem(i, n) == n // 4`` for the petal kick; see the module docstring)."""
    d = 4.0 * math.pi / n * math.sin(2.0 * math.pi * (i + n / 4.0) / n) ** 2
    if i % n == n // 4:
        d += 2.0 * math.pi / petals
    return d


@dataclass(frozen=True, kw_only=True, slots=True)
class RadialPattern:
    """The looping radial search: ``petals`` petals of ``steps_per_petal`` steps; ``max_steps``
    (default: one whole flower) cuts it short."""

    petals: int = 12
    steps_per_petal: int = 32
    step_m: float = DEFAULT_STEP_M
    max_steps: int | None = None
    headings_rad: tuple[float, ...] = field(init=False, repr=False)

    kind = "radial"

    def __post_init__(self):
        n = _positive_int("steps per petal", self.steps_per_petal)
        petals = _positive_int("petals", self.petals)
        _positive("step length (m)", self.step_m)
        if n < 3:
            raise BadInputError(f"steps per petal must be at least 3 (a petal is a loop); got {n}")
        total = n * petals
        if self.max_steps is not None:
            total = min(total, _positive_int("max steps", self.max_steps))
        _check_steps(total, f"{petals} petals x {n} steps per petal" if total == n * petals else "--max-steps")
        th, out = 0.0, []
        i0 = n // 4 + 1  # the flower's centre (module docstring)
        for j in range(total):
            out.append(th)
            th += radial_turn_rad(j + i0, n, petals)
        object.__setattr__(self, "headings_rad", tuple(out))

    @property
    def n_steps(self) -> int:
        return len(self.headings_rad)

    def describe(self) -> str:
        return f"radial {self.petals} petals x {self.steps_per_petal} steps of {self.step_m * 1000:.0f} mm"


@dataclass(frozen=True, kw_only=True, slots=True)
class SpiralPattern:
    """Archimedes spiral, equal ``spacing_m`` between turns (default 0.25 m), ``max_steps``
    chords of ``step_m``."""

    step_m: float = DEFAULT_STEP_M
    spacing_m: float | None = None
    max_steps: int = DEFAULT_SPIRAL_MAX_STEPS
    headings_rad: tuple[float, ...] = field(init=False, repr=False)

    kind = "spiral"

    def __post_init__(self):
        s = _positive("step length (m)", self.step_m)
        spacing = (
            DEFAULT_SPIRAL_SPACING_M if self.spacing_m is None else _positive("spiral spacing (m)", self.spacing_m)
        )
        from stcvision.limits import MIN_SEARCH_SPIRAL_SPACING_M

        if spacing < MIN_SEARCH_SPIRAL_SPACING_M:
            raise BadInputError(
                f"spiral spacing {spacing:g} m is under the minimum of {MIN_SEARCH_SPIRAL_SPACING_M:g} m "
                "(stcvision.limits.MIN_SEARCH_SPIRAL_SPACING_M)"
            )
        n = _positive_int("max steps", self.max_steps)
        _check_steps(n, "max steps")
        b = spacing / (2.0 * math.pi)

        def pt(phi):
            return np.array([b * phi * math.cos(phi), b * phi * math.sin(phi)])

        phis = [0.0]
        for _ in range(n):
            p0, phi0 = pt(phis[-1]), phis[-1]

            def chord(phi, p0=p0):
                return float(np.hypot(*(pt(phi) - p0))) - s

            hi = phi0 + max(0.1, s / max(b * phi0, 1e-9))
            while chord(hi) < 0:
                hi += 0.5 * (hi - phi0)
            phis.append(brentq(chord, phi0 + 1e-12, hi, xtol=1e-12))
        pts = np.array([pt(p) for p in phis])
        d = np.diff(pts, axis=0)
        th = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
        object.__setattr__(self, "headings_rad", tuple(float(t) for t in th - th[0]))
        object.__setattr__(self, "spacing_m", spacing)

    @property
    def n_steps(self) -> int:
        return len(self.headings_rad)

    def describe(self) -> str:
        return (
            f"spiral {self.n_steps} steps of {self.step_m * 1000:.0f} mm, {self.spacing_m * 1000:.0f} mm between turns"
        )


def planned_points(pattern, n: int | None = None) -> np.ndarray:
    """(n + 1, 2) planned sampling points p_0 .. p_n of equations (4)-(5), start at the origin
    (default ``n``: the whole pattern)."""
    th = np.asarray(pattern.headings_rad[: pattern.n_steps if n is None else n])
    steps = pattern.step_m * np.c_[np.cos(th), np.sin(th)]
    return np.vstack([[0.0, 0.0], np.cumsum(steps, axis=0)])
