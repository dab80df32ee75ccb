"""When a visit ends: the robot's own online rule (``--visit-steps auto``), from what it senses.

The Buffon's needle paper (Girgin & Sahin, sec. 6) asks how long the first visit should be and
whether that can be decided during the visit. The rule here needs no knowledge of the nest: it
reads only the robot's odometry (its path length) and its pheromone detector.

**First visit: stop at a fixed trail coverage.** While laying, the robot also reads the detector
and counts, with the same leaky-integrator counter as the second visit, every encounter with
trail it laid more than ``recent_u`` body lengths of path ago (its own fresh stripe is always
under it). For a curve of length L spread uniformly and isotropically over an area A, the
expected number of self-crossings is L^2 / (pi A) (Poincare's formula for two curves,
2 L1 L2 / (pi A), halved for the pairs of one curve), so after path L with n self-encounters

    coverage  rho = w L / A  ~  pi w n / L                                   (1)

(w the trail width). The visit may stop when rho reaches ``coverage`` (and at least ``min_self``
encounters were counted, so that (1) is not a guess from a handful), once its trail is mixed
(1b). Why a coverage removes the size bias of a fixed visit length: the trail's density, hence
how often strands merge under the counter (blending, dead time), is set by rho alone; and the
trail's path measured in mixing lengths of the nest, L / (A / l_p) = rho l_p / w for an explorer
of persistence length l_p, is the same at every size. A fixed length gives a dense, blended trail in a small nest and a
trail that has not left the start's neighbourhood in a large one; a fixed rho gives the same
trail, scaled, in both.

**First visit, and mixed: its self-encounters come at a steady rate (1b).** Formula (1)
assumes a trail spread evenly over the nest. A trail that lies unevenly (most of it in some
compartments of a nest split by long barriers) meets itself more, so (1) stops early and the
first visit's self-crossing estimate reads the area low. The robot cannot see the compartments,
but it senses their effect on its own encounters: for an even trail the encounter rate per unit
path at path l is proportional to the trail laid so far (its density l / A is the same
everywhere), so it grows smoothly with l; a robot that moves between a compartment where it has
laid much and one where it has laid little meets its trail at a rate that swings up and down
about that smooth growth. The visit keeps its self-encounters in the batch-means bins of the
second visit (:func:`batch_add`: bins of equal step count, merged in pairs as they fill, between
``batches`` and ``2 batches`` full ones). Over the later half of its full bins, i = h..k-1
(h = floor(k / 2)), with n_i encounters on the path from l_i to l_{i+1} and u = l / l_k, the
smooth growth is fitted by weighted least squares (weights 1 / max(n_i, 1)):

    E_i = a (u_{i+1} - u_i) + b (u_{i+1}^2 - u_i^2)
    X^2 = sum_i (n_i - E_i)^2 / E_i,   N = sum_i n_i,   m = k - h
    s   = sqrt( max(0, X^2 - (m - 2)) / N )                                  (1b)

For encounters that are Poisson about E_i, X^2 is chi-square with m - 2 degrees of freedom
(mean m - 2), so s estimates the relative spread of the encounter rate about its smooth growth
beyond counting noise, a number that does not grow with the count. The visit stops at
rho >= ``coverage`` once s <= ``mix_tol``, and in any case at rho >= ``max_coverage``: a longer
trail blends (the dead-time-corrected self-crossing estimate runs high where the counted coverage
reaches 0.2), so waiting for ever would trade one bias for another.

Why not a test of significance, and why the term a: the robot's encounters are not Poisson about
any smooth rate even in an open nest (the path lingers along its own trail and comes back to its
recent loops). Measured on the calibration family at rho = 0.13 (8 trials a nest,
``docs/measurements/buffon_mixing_choice.py``): the Poisson dispersion X^2 / (m - 1) about a rate proportional
to l alone (b only, all bins) had medians of 2.9-42 over the 16 nests without compartments, so a
chi-square test rejects mixing in every nest at any level, and more often the larger the nest
(more encounters). The spread s is the size of the swings, not their significance. The rate is
not proportional to l alone either: in the first tenth of the path it is 1.3-3.5 times that (the
start's neighbourhood and the path's own recent loops: a term per unit path, a), and in the last
tenth 0.76-0.90 times (blending); hence the term a, and only the later half of the bins. What it
cannot see: a robot shut in one compartment for the whole later half meets its trail at a rate
that grows smoothly too (as in a smaller nest), and passes.

The two constants were chosen on the calibration family (8 trials a nest, seeds 9100 + i, the same
script): the spread (log) of the nests' median A1 was 0.053 at the coverage alone, 0.023 with
``mix_tol`` 0.10 and ``max_coverage`` 0.18 (0.027 with 0.12, 0.014 with 0.08, 0.037 with a cap of
0.16), the single trials' A1 spread about their nest's median 0.063 and 0.050; the first visits'
paths were a median 1.08 times longer (1.04 with 0.12, 1.18 with 0.08, which also reads the
compartment nests 1-7 % high). Within a nest, trials whose spread
(1b) was larger at the coverage read A1 lower (rank correlation -0.48 over the 160 trials, about
their nests' medians).

**Second visit: stop when the crossing rate is pinned down and the path has mixed.** The second
visit counts crossings N over path L2. The rate N / L2 is an average of a correlated series (the
path lingers where the trail is dense), so its standard error is measured the way simulation
output is: *batch means* (Law, *Simulation Modeling and Analysis*, 5th ed., sec. 9.5.3). The
visit keeps ``2 batches`` bins of equal step count; when they fill, neighbours are merged and
the bin width doubles, so there are always between ``batches`` and ``2 batches`` full bins of
width growing with the visit, and the correlation within a bin is soon short against its width.
The relative standard error of the ratio estimate N / L2 from k bins (n_i crossings, l_i path):

    se_rel^2 = sum_i (n_i - R l_i)^2 / (k (k - 1) lbar^2 R^2),   R = N / L2   (2)

The visit stops when (a) L2 >= ``second_ratio`` * L1 (the path had the time to leave the start,
where the first visit's trail is densest: a length tied to the first visit's, hence to the
area the robot measured, not to a number of steps), (b) N >= ``min_crossings`` and (c)
se_rel <= ``rel_se``, with at least ``batches`` full bins; or at L2 = ``max_ratio`` * L1.

**What the scaling does not remove.** Wall-following packs both paths along the periphery
(more crossings than uniform curves), an effect of perimeter / area that still grows in small
nests, while the dead-time correction over-restores a denser trail. The coverage 0.13 is where
the two cancel across 700-31,000 u^2 (measured: 0.07 and 0.15 leave opposite trends;
docs/results/buffon.md, "Online visit lengths", measured with the second visit's estimate alone): a
tuned constant of the robot, balanced rather than removed (the estimate of both visits,
:func:`stcvision.controllers.buffon.estimate.online_area`, leaves less to balance: its factor is
:data:`stcvision.controllers.buffon.estimate.ONLINE_CORRECTION`). In a nest a few body lengths across
the first visit is on its own trail most of the time and rule (1) cannot be met; it gives up
(:func:`first_visit_hopeless`) and the trial is untrusted.

The rules are compiled functions (numba) that the visit loop (:mod:`stcvision.controllers.buffon.batched`)
calls every 64 steps (the batch means of both visits every step), and the synthetic-stream
tests call from Python: one code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stcvision.errors import BadInputError
from stcvision.sim_camera.fastworld import loop_jit

__all__ = [
    "StopParams",
    "batch_add",
    "batch_rel_se",
    "first_visit_done",
    "mixing_spread",
    "new_batch_state",
    "second_visit_done",
]


@dataclass(frozen=True, kw_only=True, slots=True)
class StopParams:
    """Constants of the online rule (the robot's, not the world's; chosen on the calibration
    nests, docs/results/buffon.md, "Online visit lengths").

    coverage : trail coverage w L1 / A at which the first visit may stop (once mixed).
    mix_tol : the largest spread (1b) of the first visit's self-encounter rate about its smooth
        growth at which its trail counts as mixed.
    max_coverage : the coverage at which the first visit stops, mixed or not.
    min_self : self-encounters needed before (1) is trusted.
    recent_u : trail younger than this much path (body lengths) is the robot's own fresh stripe.
    second_ratio : the second visit lasts at least this share of the first visit's path.
    max_ratio : ... and at most this multiple of it: where the crossing rate's error will not come
        down (a corridor, in which the path lingers for long stretches), the visit ends there and
        reports the error it reached (the per-trial interval uses it).
    min_crossings : crossings the second visit needs at least.
    rel_se : the relative standard error (2) of the crossing rate at which it may stop.
    batches : bins of the batch-means estimate (between this and twice this are full).
    """

    coverage: float = 0.13
    mix_tol: float = 0.10
    max_coverage: float = 0.18
    min_self: int = 40
    recent_u: float = 2.0
    second_ratio: float = 0.4
    max_ratio: float = 3.0
    min_crossings: int = 200
    rel_se: float = 0.05
    batches: int = 16

    def __post_init__(self):
        for name in ("coverage", "mix_tol", "max_coverage", "recent_u", "second_ratio", "max_ratio", "rel_se"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise BadInputError(f"stopping rule: {name} must be a positive number; got {v!r}")
        for name in ("min_self", "min_crossings", "batches"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= 2):
                raise BadInputError(f"stopping rule: {name} must be an integer >= 2; got {v!r}")
        if self.max_coverage < self.coverage:
            raise BadInputError(
                f"stopping rule: max_coverage ({self.max_coverage}) must be at least coverage ({self.coverage})"
            )

    def array(self, trail_width_u: float) -> np.ndarray:
        """The constants the compiled loop reads: coverage, min_self, pi w, second_ratio,
        min_crossings, rel_se, batches, max_ratio, mix_tol, max_coverage."""
        return np.array(
            [
                self.coverage,
                self.min_self,
                math.pi * trail_width_u,
                self.second_ratio,
                self.min_crossings,
                self.rel_se,
                self.batches,
                self.max_ratio,
                self.mix_tol,
                self.max_coverage,
            ],
            dtype=np.float64,
        )


@loop_jit
def first_visit_done(path_u, n_self, coverage, min_self, pi_w, st, batches, mix_tol, max_coverage):
    """Rules (1) and (1b): has the trail of ``path_u`` body lengths, with ``n_self``
    self-encounters, reached the target coverage with its encounter rate steady (``st``: the
    batch-means state of its encounters, :func:`batch_add`), or the largest coverage in any case?"""
    if n_self < min_self or pi_w * n_self < coverage * path_u:
        return False
    if pi_w * n_self >= max_coverage * path_u:
        return True
    return mixing_spread(st, batches) <= mix_tol


@loop_jit
def first_visit_hopeless(steps, blind_steps, n_self, min_self):
    """The first visit gives up (the measurement is then untrusted) once, after ``min_self``
    encounters, its counter has been blind for more than :data:`MAX_FIRST_BLIND` of its steps:
    in a nest a few body lengths across the robot is on its own trail most of the time, the
    counter merges encounters, and rule (1) could never be met (measured: a 10 u circle's
    first visit ran to the cap of 10^8 steps)."""
    return n_self >= min_self and blind_steps > MAX_FIRST_BLIND * steps


#: the first visit's blind share beyond which it gives up (0.1-0.35 in nests of 700 u^2 and more)
MAX_FIRST_BLIND = 0.6

# batch-means state: [bin width (steps), steps in the current bin, full bins, then 2B crossings, then 2B paths]
_W, _IN, _FULL, _BINS = 0, 1, 2, 3


def new_batch_state(batches: int, first_width: int = 64) -> np.ndarray:
    """An empty batch-means state for ``batches`` (2 * batches bins), bins ``first_width`` steps wide."""
    st = np.zeros(_BINS + 4 * batches)
    st[_W] = first_width
    return st


@loop_jit
def batch_add(st, crossed, dl_u, batches):
    """Add one step (``crossed`` 0 or 1, path ``dl_u``) to the batch-means state ``st``."""
    b2 = 2 * batches
    k = int(st[_FULL])
    st[_BINS + k] += crossed
    st[_BINS + b2 + k] += dl_u
    st[_IN] += 1
    if st[_IN] >= st[_W]:
        st[_IN] = 0
        k += 1
        if k == b2:  # all bins full: merge neighbours, the width doubles
            for i in range(batches):
                st[_BINS + i] = st[_BINS + 2 * i] + st[_BINS + 2 * i + 1]
                st[_BINS + b2 + i] = st[_BINS + b2 + 2 * i] + st[_BINS + b2 + 2 * i + 1]
            for i in range(batches, b2):
                st[_BINS + i] = 0.0
                st[_BINS + b2 + i] = 0.0
            st[_W] *= 2
            k = batches
        st[_FULL] = k


@loop_jit
def batch_rel_se(st, batches):
    """Rule (2): the relative standard error of crossings per path over the full bins (inf with
    fewer than two full bins or no crossing)."""
    b2 = 2 * batches
    k = int(st[_FULL])
    if k < 2:
        return math.inf
    n = 0.0
    length = 0.0
    for i in range(k):
        n += st[_BINS + i]
        length += st[_BINS + b2 + i]
    if n <= 0.0 or length <= 0.0:
        return math.inf
    rate = n / length
    lbar = length / k
    ss = 0.0
    for i in range(k):
        d = st[_BINS + i] - rate * st[_BINS + b2 + i]
        ss += d * d
    return math.sqrt(ss / (k * (k - 1))) / (lbar * rate)


@loop_jit
def mixing_spread(st, batches):
    """Rule (1b): the relative spread, beyond counting noise, of the self-encounters in the later
    half of the full bins of ``st`` about a rate growing smoothly with the path (a + b l per unit
    path); inf with fewer than ``batches`` full bins or no encounter there."""
    b2 = 2 * batches
    k = int(st[_FULL])
    if k < batches:
        return math.inf
    h = k // 2
    total = 0.0
    for i in range(k):
        total += st[_BINS + b2 + i]
    if total <= 0.0:
        return math.inf
    # the weighted normal equations of n_i ~ a x_i + b y_i, u = l / l_k
    sxx = sxy = syy = sxn = syn = 0.0
    u0 = 0.0
    for i in range(h):
        u0 += st[_BINS + b2 + i] / total
    u = u0
    for i in range(h, k):
        u1 = u + st[_BINS + b2 + i] / total
        x, y, n = u1 - u, u1 * u1 - u * u, st[_BINS + i]
        v = max(n, 1.0)
        sxx += x * x / v
        sxy += x * y / v
        syy += y * y / v
        sxn += x * n / v
        syn += y * n / v
        u = u1
    det = sxx * syy - sxy * sxy
    if det <= 0.0:
        return math.inf
    a = (syy * sxn - sxy * syn) / det
    b = (sxx * syn - sxy * sxn) / det
    x2 = 0.0
    count = 0.0
    u = u0
    for i in range(h, k):
        u1 = u + st[_BINS + b2 + i] / total
        e = max(a * (u1 - u) + b * (u1 * u1 - u * u), 1e-9)
        n = st[_BINS + i]
        x2 += (n - e) * (n - e) / e
        count += n
        u = u1
    if count <= 0.0:
        return math.inf
    return math.sqrt(max(0.0, x2 - (k - h - 2)) / count)


@loop_jit
def second_visit_done(st, path_u, n, l1_u, second_ratio, min_crossings, rel_se, batches, max_ratio):
    """The second visit's rule: mixed (path >= second_ratio * L1), enough crossings, and the
    rate's relative standard error (2) at most ``rel_se`` over at least ``batches`` full bins;
    or a path of ``max_ratio`` * L1 in any case."""
    if path_u >= max_ratio * l1_u and st[_FULL] >= batches:
        return True
    if path_u < second_ratio * l1_u or n < min_crossings or st[_FULL] < batches:
        return False
    return batch_rel_se(st, batches) <= rel_se
