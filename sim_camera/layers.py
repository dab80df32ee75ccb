"""Floor layers queried by position (vectorised): pheromone trail and chemical patches.

* :class:`PheromoneLayer` -- the Buffon explorer's trail (the Buffon's needle paper of
  Girgin & Sahin, sec. 4): a robot with its nozzle open marks every floor cell whose centre lies
  within half the trail width of its path; the default width is 0.1 body length ("the width of the
  pheromone is taken as 0.1, i.e. one tenth of the body length of the robot"). The trail is a
  raster, like the paper's own "pixellized implementation"; cells default to half the width.
* :class:`ChemicalLayer` -- circular or polygonal patches with a concentration, read by the
  tongue sensor (the TASTI 2 paper by Russell, sec. V: "a circular patch of salt
  crystals 350mm in diameter"). An optional linear edge ramp stands in for scattered crystals.

The phosphor layer lives in :mod:`stcvision.sim_camera.phosphor`. A layer that wants to react to the world
every step (e.g. to robots' LEDs) implements ``on_step(world)`` and is added with
``World.add_layer``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stcvision.errors import BadInputError
from stcvision.sim_camera.arenas import as_points, points_in_polygon

__all__ = [
    "ChemicalLayer",
    "ChemicalPatch",
    "PheromoneLayer",
    "PolygonPatch",
    "TASTI2_SALT_PATCH_DIAMETER_M",
]

TASTI2_SALT_PATCH_DIAMETER_M = 0.350  # the TASTI 2 paper (Russell), sec. V


class PheromoneLayer:
    """Rasterised pheromone trail of width ``width_m`` over ``bounds_m`` = (xmin, ymin, xmax, ymax).

    Grid row 0 is the *south* row (y = ymin); cell (i, j) has centre
    (xmin + (j + 0.5) c, ymin + (i + 0.5) c) with c = ``cell_m``.
    """

    def __init__(
        self,
        bounds_m: tuple[float, float, float, float],
        *,
        width_m: float,
        cell_m: float | None = None,
    ):
        if not width_m > 0:
            raise BadInputError(f"pheromone width_m must be > 0; got {width_m!r}")
        self.width_m = float(width_m)
        self.cell_m = float(cell_m) if cell_m is not None else 0.5 * self.width_m
        xmin, ymin, xmax, ymax = bounds_m
        self.origin_m = (float(xmin), float(ymin))
        self.shape = (
            max(1, math.ceil((ymax - ymin) / self.cell_m)),
            max(1, math.ceil((xmax - xmin) / self.cell_m)),
        )
        if self.shape[0] * self.shape[1] > 100_000_000:
            raise BadInputError(f"pheromone grid {self.shape} too large; use a coarser cell_m than {self.cell_m}")
        self.grid = np.zeros(self.shape, dtype=bool)

    def clear(self) -> None:
        self.grid[:] = False

    @property
    def marked_area_m2(self) -> float:
        return float(self.grid.sum()) * self.cell_m**2

    def deposit_segment(self, p0, p1) -> None:
        """Mark the cells whose centre is within width/2 of the segment p0-p1 (metres)."""
        self.deposit_path(np.array([p0, p1], dtype=float))

    def deposit_path(self, points) -> None:
        """Mark the trail along a polyline ``points`` (N, 2); N = 1 marks a dot."""
        p = as_points(points)
        half = 0.5 * self.width_m
        c = self.cell_m
        ox, oy = self.origin_m
        a = p[:-1] if len(p) > 1 else p
        b = p[1:] if len(p) > 1 else p
        lo = np.minimum(a, b) - half
        hi = np.maximum(a, b) + half
        j0 = max(0, int(math.floor((lo[:, 0].min() - ox) / c - 0.5)))
        j1 = min(self.shape[1] - 1, int(math.ceil((hi[:, 0].max() - ox) / c - 0.5)))
        i0 = max(0, int(math.floor((lo[:, 1].min() - oy) / c - 0.5)))
        i1 = min(self.shape[0] - 1, int(math.ceil((hi[:, 1].max() - oy) / c - 0.5)))
        if j1 < j0 or i1 < i0:
            return
        if (i1 - i0 + 1) * (j1 - j0 + 1) * len(a) > 4_000_000:  # long path: split it
            mid = len(p) // 2
            self.deposit_path(p[: mid + 1])
            self.deposit_path(p[mid:])
            return
        jj, ii = np.meshgrid(np.arange(j0, j1 + 1), np.arange(i0, i1 + 1))
        centres = np.c_[ox + (jj.ravel() + 0.5) * c, oy + (ii.ravel() + 0.5) * c]
        from stcvision.sim_camera.arenas import segment_distances

        hit = (segment_distances(centres, a, b) <= half).any(axis=1)
        self.grid[ii.ravel()[hit], jj.ravel()[hit]] = True

    def read(self, points) -> np.ndarray:
        """Pheromone present (bool) at each point (N, 2); points off the grid read False."""
        p = as_points(points)
        j = np.floor((p[:, 0] - self.origin_m[0]) / self.cell_m).astype(int)
        i = np.floor((p[:, 1] - self.origin_m[1]) / self.cell_m).astype(int)
        ok = (i >= 0) & (i < self.shape[0]) & (j >= 0) & (j < self.shape[1])
        out = np.zeros(len(p), dtype=bool)
        out[ok] = self.grid[i[ok], j[ok]]
        return out

    def read_xy(self, x: float, y: float) -> bool:
        j = math.floor((x - self.origin_m[0]) / self.cell_m)
        i = math.floor((y - self.origin_m[1]) / self.cell_m)
        if 0 <= i < self.shape[0] and 0 <= j < self.shape[1]:
            return bool(self.grid[i, j])
        return False


@dataclass(frozen=True, kw_only=True, slots=True)
class ChemicalPatch:
    """A disc of chemical: ``concentration`` inside ``radius_m``, falling linearly to 0 over
    ``edge_m`` outside it (0 = sharp edge). Concentration is in arbitrary sensor units."""

    center_m: tuple[float, float]
    radius_m: float = 0.5 * TASTI2_SALT_PATCH_DIAMETER_M
    concentration: float = 1.0
    edge_m: float = 0.0

    def value(self, p: np.ndarray) -> np.ndarray:
        d = np.hypot(p[:, 0] - self.center_m[0], p[:, 1] - self.center_m[1]) - self.radius_m
        if self.edge_m > 0:
            return self.concentration * np.clip(1.0 - d / self.edge_m, 0.0, 1.0)
        return np.where(d <= 0, self.concentration, 0.0)


@dataclass(frozen=True, kw_only=True, slots=True)
class PolygonPatch:
    """A polygon of uniform chemical concentration (sharp edge)."""

    vertices_m: tuple[tuple[float, float], ...]
    concentration: float = 1.0

    def value(self, p: np.ndarray) -> np.ndarray:
        inside = points_in_polygon(p, np.asarray(self.vertices_m, dtype=float))
        return np.where(inside, self.concentration, 0.0)


class ChemicalLayer:
    """Sum of chemical patches; :meth:`concentration` is vectorised over positions."""

    def __init__(self, patches=()):
        self.patches: list[ChemicalPatch | PolygonPatch] = list(patches)

    def add(self, patch: ChemicalPatch | PolygonPatch) -> None:
        self.patches.append(patch)

    def concentration(self, points) -> np.ndarray:
        p = as_points(points)
        out = np.zeros(len(p))
        for patch in self.patches:
            out += patch.value(p)
        return out
