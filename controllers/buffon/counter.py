"""The crossing counter of Buffon's method (the Buffon's needle paper of Girgin & Sahin, sec. 4).

"The output of the pheromone sensor (a binary value) is first filtered by a leaky integrator to
remove any artefacts that may have occurred due to a pixellized implementation of the pheromone
trail and then thresholded. *Buffon's count* is defined as the number of crossings counted
during the second visit."

    level <- level + rate * (x - level)

A crossing is counted when the level rises through ``threshold``; it must fall below
``threshold - hysteresis`` before the next one counts. The constants are not in the paper:
rate 0.3 per step and threshold 0.5 need two consecutive steps on the trail (0.3, then 0.51),
so a one-cell artefact of the raster is not a crossing, while a real crossing (a 0.1 body-length
trail is ~2.3 steps wide at full speed, more at a slant) counts once, however long the path then
runs along the trail.

One source: :func:`integrate` is plain Python; numba compiles the same function for the batched
path (:mod:`stcvision.controllers.buffon.batched`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

__all__ = ["CounterParams", "LeakyIntegrator", "count_crossings", "integrate"]


@dataclass(frozen=True, kw_only=True, slots=True)
class CounterParams:
    rate: float = 0.3
    threshold: float = 0.5
    hysteresis: float = 0.2


def integrate(level, above, x, rate, threshold, hysteresis):
    """One step of the leaky integrator and threshold: returns (level, above, crossed)."""
    level = level + rate * (x - level)
    if not above and level >= threshold:
        return level, True, True
    if above and level < threshold - hysteresis:
        return level, False, False
    return level, above, False


integrate_nb = numba.njit(cache=True)(integrate)


@dataclass(kw_only=True, slots=True)
class LeakyIntegrator:
    """Stateful counter for one robot (the pymunk path): feed one binary reading per step."""

    params: CounterParams = CounterParams()
    level: float = 0.0
    above: bool = False
    crossings: int = 0

    def update(self, x: float | bool) -> bool:
        """Feed one reading; return True if this step completed a new crossing."""
        p = self.params
        self.level, self.above, crossed = integrate(self.level, self.above, float(x), p.rate, p.threshold, p.hysteresis)
        self.crossings += crossed
        return crossed


def count_crossings(readings, params: CounterParams = CounterParams()) -> int:
    """Crossings counted on a sequence of binary readings (one per step)."""
    c = LeakyIntegrator(params=params)
    for x in np.asarray(readings, dtype=float):
        c.update(x)
    return c.crossings
