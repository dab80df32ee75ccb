"""From crossings to area: nBC, the Buffon/Barbier estimate, its corrections and intervals.

**nBC** (the Buffon's needle paper of Girgin & Sahin, sec. 4): the Buffon count normalised by
the length of the second visit, N / L2 (per body length).

**Absolute area** (Buffon/Barbier; Mallon & Franks 2000, Proc. R. Soc. B 267:765): two
independent random curves of lengths L1 and L2, isotropic and uniform over a region of area A,
cross on average 2 L1 L2 / (pi A) times, so

    A_raw = 2 L1 L2 / (pi N).

Two things bend it on a real explorer, and each gets one correction:

1. **Blending (dead time).** After a crossing the counter is blind until the leaky integrator
   has fallen back below its re-arm level (:mod:`stcvision.controllers.buffon.counter`); a second visit
   that spends a fraction b of its steps blind meets trail only on the other 1 - b. This is the
   dead-time correction of counting statistics (Knoll, *Radiation Detection and Measurement*,
   ch. 4: n = m / (1 - m tau)); the robot measures b itself, no parameter is fitted:
   A_dt = A_raw (1 - b). It is what shrinks the paper's "lower than expected" nBC of small,
   blended nests (sec. 5.1).
2. **What is left: wall following and deeper blending.** The explorer's centre never comes
   within a body radius of the wall and its wall-following packs both paths along the
   periphery (more crossings than uniform curves: the estimate falls short), while at the
   default visit length the trail is dense enough that merged crossings remain beyond what the
   dead-time correction restores (the estimate runs over). One factor, :data:`AREA_CORRECTION`,
   calibrated once on the standard circle (diameter 100 u) at the default settings and held
   fixed (:func:`calibrate_area_correction` recomputes it): A = AREA_CORRECTION * A_dt. Its
   value depends on the visit length it was calibrated at (1.045 at 150,000 steps, 0.935 at
   300,000), so it is for the default settings; `--json` reports the bias before and after.

A trial set whose second visits were blind for more than :data:`MAX_BLIND_FRACTION` of their
steps is blended beyond what the corrections hold (measured: the dead-time corrected estimate is
within ~10 % of the truth up to b ~ 0.3 and runs to 1.3-1.8x at b = 0.5-0.7): its summary
carries ``area_warning`` saying so, and the estimate must not be trusted.

**Online visit lengths** (``--visit-steps auto``, the default; :mod:`stcvision.controllers.buffon.stopping`):
the first visit ends at a fixed trail coverage once its self-encounters come at a steady rate
(its trail has mixed), the second when its crossing rate is known to a set relative error. Each
visit then measures the area on its own:

* the second visit, by Buffon/Barbier as above: A2 = 2 L1 L2 (1 - b2) / (pi N);
* the first visit, by its own self-encounters n1 (which its stopping rule counts): a uniform curve
  of length L1 meets itself L1^2 / (pi A) times (Poincare's formula halved), so
  A1 = L1^2 (1 - b1) / (pi n1), with the same dead-time correction for the share b1 of the first
  visit's steps its counter was blind on its older trail.

The estimate is their weighted geometric mean, log A = w log A2 + (1 - w) log A1 + log K
(:func:`online_area`, w = :data:`ONLINE_SECOND_WEIGHT`). Why: both read the same random first
trail, but differently. A trail that happens to bunch up meets itself more (A1 falls) while an
independent second path meets it about as often as any trail of its length (A2 does not follow),
and A2's error comes mostly from where the second path happened to go. Measured on the
calibration family, the two errors within a nest are nearly independent (correlation -0.03 on
average), the single-trial spread about a nest's median is 0.052 in log for A1 and 0.068 for A2
alone, 0.045 for the mean; the nests' median biases spread 0.018 about one factor (0.031 for
the undead-time-corrected A1 in the mean). A bunched trail biases A1, not only its spread: in
nests split into compartments by long barriers (and in concave nests) a first visit that stops at
its coverage alone has not spread its trail evenly over them, and A1 read 0.87-0.97 of the truth
against 0.96-1.04 in open nests. The first visit therefore also waits until its self-encounters
come at a steady rate (:mod:`stcvision.controllers.buffon.stopping`, rule (1b)); with it A1 reads
0.95-1.05 of the truth over the whole calibration family (the spread of the nests' median A1
0.021 in log, 0.045 before) and is the steadier of the two, so it gets the larger share
(w = 0.3, chosen on the calibration family: the weights' note below).

**Read at one coverage.** Both estimates grow with the coverage rho = pi w_t n1 / L1 (w_t the trail
width) at which the first visit stopped, whatever the nest: the counter loses more of a denser
trail's encounters than its dead-time correction restores (weighting each encounter by the blind
share of the path just before it, over 50-800 steps, did not flatten the curve: a prototype of the
compiled loop measured on the same circles, not kept), and a short
trail's count carries more of the start's neighbourhood and of the path's own recent loops.
Measured with the coverage forced (``coverage = max_coverage``, 32 trials a nest, the calibration
family's circles of 60, 100 and 160 u, before the factor K;
``python docs/measurements/buffon_coverage_response.py``): A1 reads 1.01-1.04 of
the truth at 0.13, 1.11-1.19 at 0.18 and 1.21-1.39 at 0.24, A2 1.09-1.11, 1.14-1.23 and
1.21-1.34; from 0.13 to 0.18 the log of their weighted mean rises 1.6-2.7 per unit of coverage.
The first visit stops at 0.13 once its trail has mixed, later (up to 0.18) when it has not, so
the trials of one nest were read at different points of that curve: within a nest the reading
coverage explained half of the trials' spread (correlation 0.69 over the calibration family's
240 trials), and nests where most trials stop late (long ellipses, nests split by barriers) read
high (5.4-6.0 % median error in three nests of ``stcvision buffon online``'s evaluation family,
all below 3.6 % once read at one coverage). The estimate is therefore brought back to
the rule's own coverage rho0 (:data:`REFERENCE_COVERAGE`, ``StopParams.coverage``):

    log A = w log A2 + (1 - w) log A1 - kappa (rho - rho0) + log K

with kappa (:data:`COVERAGE_SLOPE`) the pooled within-nest least-squares slope of the log estimate
on rho over the calibration family (:func:`stcvision.controllers.buffon.online.calibrate_online` measures
it). The robot knows rho (it stopped by it); the truth is not used.

One factor, :data:`ONLINE_CORRECTION`, is then calibrated on a family of nests
(:func:`stcvision.controllers.buffon.online.calibrate_online`; circles, squares, ellipses, barriers and
concave polygons of 1,300-20,000 u^2, none of them in the evaluation family), with what that
calibration leaves:

* ``ONLINE_CORRECTION_SE``: the standard error of log K (the calibration's own uncertainty);
* ``SHAPE_SIGMA``: the spread of the nests' median log-bias about K (the residual bias of shape
  and size, which no factor removes; its sampling part included, an upper bound);
* ``TRIAL_EXTRA_SIGMA``: the spread of single trials about their nest's median beyond what the
  trial's own batch-means error (w times the second visit's ``rate_rel_se``) says (the first
  visit's trail is itself one random draw, which the second visit cannot see).

**Intervals** (log scale, Student t with the calibration family's degrees of freedom, scipy.stats):

* per trial (``trial_area_ci95``: what one robot can say about its one measurement):
  log A +- t sqrt((w se_rel)^2 + TRIAL_EXTRA_SIGMA^2 + ONLINE_CORRECTION_SE^2 + SHAPE_SIGMA^2
  + (COVERAGE_SLOPE_SE (rho - rho0))^2);
* over trials (``area_ci95``): the percentile bootstrap of the median log estimate
  (:func:`scipy.stats.bootstrap`, 2,000 resamples, seeded; the trial-to-trial spread), its
  half-widths combined in quadrature with t sqrt(ONLINE_CORRECTION_SE^2 + SHAPE_SIGMA^2).

With fixed visit lengths the factor is the one of the standard circle (:data:`AREA_CORRECTION`),
``area_ci95`` is the plain bootstrap interval of the median, and no per-trial interval is given:
neither carries the shape bias, which was measured for the online rule only.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from stcvision.controllers.buffon.batched import VisitConfig
from stcvision.controllers.buffon.defaults import PAPER_TRAIL_WIDTH_U
from stcvision.controllers.buffon.nests import BODY_LENGTH_M
from stcvision.controllers.buffon.stopping import StopParams
from stcvision.errors import BadInputError

__all__ = [
    "AREA_VISIT_STEPS",
    "AREA_CORRECTION",
    "area_estimates",
    "buffon_area",
    "online_area",
    "reading_coverage",
    "self_crossing_area",
    "calibrate_area_correction",
    "median_ci95",
    "summarise",
]

# Visits long enough for the two paths to mix through a nest of the standard area. Measured,
# median |error| of one trial (100 trials per nest, `stcvision buffon reproduce`, table in
# docs/results/buffon.md, "Visit length"): at the paper's 50,000 steps (sec. 4) 19 % (circle) and
# 17 % (square) by the raw formula; at 300,000 steps 2.6-6.1 % over eight standard-area nests and
# 10.1 % in the ellipse of r1/r2 = 15.8 (a 400 u corridor along which the paths mix slowly).
AREA_VISIT_STEPS = 300_000

MAX_BLIND_FRACTION = 0.3
# a visit's path in body lengths per step at cruising speed (m = 0.25 of sec. 3.2, both wheels)
CRUISE_STEP_U = 0.25 * VisitConfig().behaviour.speed_scale_m_s * VisitConfig().dt_s / BODY_LENGTH_M
MIN_PATH_FRACTION = 0.4  # measured ~0.8 of it in open nests; a robot jammed in a corner makes much less

# A_true / median(A_dt) on the standard circle, 100 trials of AREA_VISIT_STEPS, trail 0.1 u,
# seed 0 (`stcvision buffon calibrate`): held fixed.
AREA_CORRECTION = 0.935  # measured 0.9346, 95 % CI 0.928-0.946


# The online estimate's log is this share of the second visit's Buffon estimate and the rest of
# the first visit's self-crossing estimate, both dead-time corrected (module doc). Chosen on the
# calibration family (20 nests x 12 trials, `python docs/measurements/buffon_heldout.py --calibration --seed
# 9100`), with the first visit's mixing test: the RMS log error about the truth was 0.0448 at 0.2,
# 0.0442 at 0.3, 0.0449 at 0.4, 0.0470 at 0.5, 0.0503 at 0.6, 0.072 with the second visit alone;
# at 0.3 the spread of the nests' median biases (the shape bias, which more trials do not remove)
# is also the smallest, 0.018 (0.019-0.021 at 0.2 and 0.4-0.6), and the worst nest's median error
# 6.9 % (6.8-7.5 % at the others). Once the first visit waits for its trail to mix, its estimate
# no longer reads low in nests split into compartments and is the steadier one. Checked again by a
# rule fixed before it was applied (`python docs/measurements/buffon_weight_check.py`: of 0.3-0.5, the weights
# whose per-trial intervals hold >= 95 % in every group of calibration nests at two seed sets, the
# lowest RMS error): none qualifies (the compartment nests hold 94.8 % at each), so 0.3 stays.
ONLINE_SECOND_WEIGHT = 0.3

# The online rule's calibration (stcvision.controllers.buffon.online.calibration_family: CALIBRATION_NESTS,
# CALIBRATION_POLYGONS and CALIBRATION_COMPARTMENTS, 20 nests x 12 trials, nest i with seed 9100 + i,
# the estimate of online_area; `python docs/measurements/buffon_heldout.py --calibration --out DIR --seed 9100`
# prints these; `stcvision buffon online` recomputes them at its own seeds): measured, then held fixed.
# the log estimate's pooled within-nest slope on the first visit's reading coverage (module doc,
# 'Read at one coverage'): measured 1.73, standard error 0.12
COVERAGE_SLOPE = 1.73
COVERAGE_SLOPE_SE = 0.12
#: the coverage every online estimate is brought back to: the one the first visit may stop at
REFERENCE_COVERAGE = StopParams().coverage
ONLINE_CORRECTION = 0.977  # measured 0.9774: exp(-mean of the nests' median log-bias)
ONLINE_CORRECTION_SE = 0.0051  # measured: sd of the nests' median log-bias / sqrt(20)
# the nests' median log-biases' whole spread, measured 0.0226, of which 0.0197 beyond their
# sampling error at 12 trials; the whole spread ships, an upper bound
SHAPE_SIGMA = 0.023
# single trials about their nest's median, beyond their own second-visit error
# (ONLINE_SECOND_WEIGHT * rate_rel_se): measured 0.030
TRIAL_EXTRA_SIGMA = 0.030
CALIBRATION_DOF = 19
# the smallest and the largest true area (u^2) of the calibration family's nests, the sizes the
# factor and the intervals above were calibrated on (stcvision.controllers.buffon.online.calibration_area_range
# computes them from the family's definitions; a test holds the two equal)
CALIBRATED_AREA_U2 = (1256.6, 20106.2)
# the online rule's trials stay calibrated up to this blind fraction (measured: 0.43 in a 30 u
# circle, 1.10 of the truth, as at 31,000 u^2); fixed lengths keep MAX_BLIND_FRACTION
MAX_BLIND_FRACTION_ONLINE = 0.45


def buffon_area(l1, l2, n):
    """Buffon/Barbier: the area in which two random curves of lengths ``l1`` and ``l2`` cross
    ``n`` times on average, 2 l1 l2 / (pi n) (inf where n = 0). Arrays broadcast."""
    n = np.asarray(n, dtype=float)
    with np.errstate(divide="ignore"):
        return 2.0 * np.asarray(l1) * np.asarray(l2) / (math.pi * n)


def default_correction(ts) -> float:
    """The factor for a trial set: the online rule's, or the fixed default length's."""
    return ONLINE_CORRECTION if getattr(ts, "online", False) else AREA_CORRECTION


def self_crossing_area(l1, n_self):
    """Poincare's formula for one curve: a uniform curve of length ``l1`` meets itself
    l1^2 / (pi A) times, so its ``n_self`` self-encounters give A = l1^2 / (pi n_self)
    (inf where n_self = 0). Arrays broadcast."""
    n = np.asarray(n_self, dtype=float)
    with np.errstate(divide="ignore"):
        return np.asarray(l1, dtype=float) ** 2 / (math.pi * n)


def reading_coverage(l1, n_self, trail_width_u: float = PAPER_TRAIL_WIDTH_U):
    """The coverage the first visit's trail was read at, by its own count: pi w n_self / L1
    (rule (1) of :mod:`stcvision.controllers.buffon.stopping`; nan where L1 = 0). Arrays broadcast."""
    l1 = np.asarray(l1, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(l1 > 0, math.pi * trail_width_u * np.asarray(n_self, dtype=float) / l1, np.nan)


def online_area(
    l1,
    l2,
    n,
    blind,
    n_self,
    self_blind,
    *,
    w: float | None = None,
    trail_width_u: float = PAPER_TRAIL_WIDTH_U,
    slope: float | None = None,
):
    """The online rule's uncorrected estimate (u^2; :data:`ONLINE_CORRECTION` not applied): the
    geometric mean, weighted by ``w`` (None: :data:`ONLINE_SECOND_WEIGHT`), of the second
    visit's Buffon estimate and the first visit's own self-crossing estimate, each with its
    visit's dead-time correction (``blind``, ``self_blind``: the share of the visit's steps its
    counter was blind), brought back to :data:`REFERENCE_COVERAGE` from the coverage its trail
    was read at by ``slope`` (None: :data:`COVERAGE_SLOPE`; module doc)."""
    w = ONLINE_SECOND_WEIGHT if w is None else w
    slope = COVERAGE_SLOPE if slope is None else slope
    a2 = buffon_area(l1, l2, n) * (1.0 - np.asarray(blind, dtype=float))
    a1 = self_crossing_area(l1, n_self) * (1.0 - np.asarray(self_blind, dtype=float))
    back = np.exp(-slope * (reading_coverage(l1, n_self, trail_width_u) - REFERENCE_COVERAGE))
    with np.errstate(invalid="ignore"):
        return a2**w * a1 ** (1.0 - w) * back


def area_estimates(ts, *, dead_time: bool = True, correction: float | None = None) -> np.ndarray:
    """Per-trial area estimates (u^2) from a :class:`~stcvision.controllers.buffon.batched.TrialSet`;
    inf where a trial counted no crossing. ``correction`` None: :func:`default_correction`.
    An online trial set's corrected estimate (``dead_time``) is :func:`online_area`;
    ``dead_time=False`` is the raw Buffon formula for every set."""
    if dead_time and getattr(ts, "online", False):
        if ts.n_self is None or ts.self_blind is None:
            raise BadInputError(
                "an online trial set without the first visit's self-encounters and blind share (stored by an "
                "older version): "
                "run it again (--fresh)"
            )
        a = online_area(ts.l1_u, ts.l2_u, ts.crossings, ts.blind_fraction, ts.n_self, ts.self_blind,
                        trail_width_u=ts.trail_width_u)  # fmt: skip
    else:
        a = buffon_area(ts.l1_u, ts.l2_u, ts.crossings)
        if dead_time:
            a = a * (1.0 - ts.blind_fraction)
    return a * (default_correction(ts) if correction is None else correction)


def _t95() -> float:
    return float(stats.t.ppf(0.975, CALIBRATION_DOF))


def trial_half_width(
    rate_rel_se,
    *,
    coverage_offset=0.0,
    w: float = ONLINE_SECOND_WEIGHT,
    extra: float = TRIAL_EXTRA_SIGMA,
    correction_se: float = ONLINE_CORRECTION_SE,
    shape: float = SHAPE_SIGMA,
    slope_se: float = COVERAGE_SLOPE_SE,
    dof: int = CALIBRATION_DOF,
) -> np.ndarray:
    """The per-trial 95 % interval's half-width in log (module doc): t(dof) sqrt((w se)^2 +
    extra^2 + correction_se^2 + shape^2 + (slope_se d)^2) for each trial's crossing-rate relative
    error ``rate_rel_se`` (inf where it is not finite) and the distance d (``coverage_offset``) of
    its reading coverage from :data:`REFERENCE_COVERAGE`; the shipped calibration by default,
    another weight's own calibration when given."""
    se = w * np.where(np.isfinite(rate_rel_se), rate_rel_se, np.inf)
    back = slope_se * np.nan_to_num(np.asarray(coverage_offset, dtype=float), nan=np.inf)
    return float(stats.t.ppf(0.975, dof)) * np.sqrt(se**2 + extra**2 + correction_se**2 + shape**2 + back**2)


def trial_intervals(est: np.ndarray, rate_rel_se: np.ndarray, coverage_offset=0.0) -> np.ndarray:
    """(n, 2) per-trial 95 % intervals of the online rule's estimates ``est`` (see module doc)."""
    h = trial_half_width(np.asarray(rate_rel_se, float), coverage_offset=coverage_offset)
    with np.errstate(invalid="ignore", over="ignore"):
        return np.column_stack([est * np.exp(-h), est * np.exp(h)])


def area_interval(est: np.ndarray, *, online: bool, seed: int = 0) -> list[float] | None:
    """The over-trials 95 % interval of the median estimate (see module doc)."""
    if not online:
        return median_ci95(est, seed)
    est = np.asarray(est, float)
    if len(est) < 3 or not np.all(np.isfinite(est)) or not np.all(est > 0):
        return None
    lg = np.log(est)
    ci = median_ci95(lg, seed)
    med = float(np.median(lg))
    sys_h = _t95() * math.hypot(ONLINE_CORRECTION_SE, SHAPE_SIGMA)
    lo = med - math.hypot(med - ci[0], sys_h)
    hi = med + math.hypot(ci[1] - med, sys_h)
    return [math.exp(lo), math.exp(hi)]


def median_ci95(x: np.ndarray, seed: int = 0) -> list[float] | None:
    """Percentile-bootstrap 95 % interval of the median of ``x`` (None for fewer than 3 values)."""
    x = np.asarray(x, dtype=float)
    if len(x) < 3:
        return None
    if not np.isfinite(np.median(x)):
        return None
    if np.all(x == x[0]):
        return [float(x[0]), float(x[0])]
    res = stats.bootstrap(
        (x,),
        np.median,
        confidence_level=0.95,
        n_resamples=2000,
        method="percentile",
        rng=np.random.default_rng(seed),
    )
    return [float(res.confidence_interval.low), float(res.confidence_interval.high)]


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def summarise(ts, area_true_u2: float, *, correction: float | None = None) -> dict:
    """The figures of one nest's trial set (the keys of ``stcvision buffon --json``); an area that
    is infinite (most trials counted no crossing) is None."""
    nbc = ts.nbc
    correction = default_correction(ts) if correction is None else correction
    est = area_estimates(ts, correction=correction)
    online = bool(getattr(ts, "online", False))
    trial_ci = None
    if online and ts.rate_rel_se is not None:
        offset = reading_coverage(ts.l1_u, ts.n_self, ts.trail_width_u) - REFERENCE_COVERAGE
        tci = trial_intervals(est, ts.rate_rel_se, offset)
        trial_ci = [[_finite(lo), _finite(hi)] for lo, hi in tci]
        holds = (tci[:, 0] <= area_true_u2) & (area_true_u2 <= tci[:, 1])
    raw = area_estimates(ts, dead_time=False, correction=1.0)
    q1, med, q3 = np.percentile(nbc, [25, 50, 75])
    trial_note = _trial_interval_note(float(np.median(est))) if trial_ci is not None else None
    warning = _warning(ts)
    return {
        "trials": len(nbc),
        "nbc_median": float(med),
        "nbc_q1": float(q1),
        "nbc_q3": float(q3),
        "crossings_median": float(np.median(ts.crossings)),
        "l1_median_u": float(np.median(ts.l1_u)),
        "l2_median_u": float(np.median(ts.l2_u)),
        "blind_fraction_median": float(np.median(ts.blind_fraction)),
        "area_true": float(area_true_u2),
        "area_estimate_median": _finite(np.median(est)),
        "area_rel_error_median": _finite(np.median(np.abs(est - area_true_u2) / area_true_u2)),
        "area_bias": _finite(np.median(est) / area_true_u2 - 1.0),
        "area_ci95": area_interval(est, online=online),
        "trial_area_ci95": trial_ci,
        "trial_ci95_coverage": float(np.mean(holds)) if trial_ci is not None else None,
        "trial_ci95_note": trial_note,
        "online": online,
        "robot_steps_median": float(np.median(ts.steps)) if ts.steps is not None else None,
        "rate_rel_se_median": float(np.median(ts.rate_rel_se)) if ts.rate_rel_se is not None else None,
        "converged": int(np.sum(ts.converged)) if ts.converged is not None else None,
        "area_raw_median": _finite(np.median(raw)),
        "area_raw_rel_error_median": _finite(np.median(np.abs(raw - area_true_u2) / area_true_u2)),
        "area_raw_bias": _finite(np.median(raw) / area_true_u2 - 1.0),
        "area_correction": correction,
        "area_warning": warning,
        "area_trusted": warning is None,
        "escapes": int(ts.escapes),
    }


def _trial_interval_note(estimate: float) -> str | None:
    """Why the per-trial intervals of a nest that reads below the calibrated sizes say more than
    they should (measured: in a 707 u^2 circle they held the truth in 67 % of 48 trials;
    docs/results/buffon.md), or None."""
    smallest = CALIBRATED_AREA_U2[0]
    if not (math.isfinite(estimate) and estimate < smallest):
        return None
    return (
        f"the nest reads {estimate:,.0f} u^2, below the {smallest:,.0f} u^2 of the smallest nest the per-trial "
        "intervals were calibrated on: there they hold the true area less often than 95 %"
    )


def _warning(ts) -> str | None:
    b = float(np.median(ts.blind_fraction))
    online = bool(getattr(ts, "online", False))
    limit = MAX_BLIND_FRACTION_ONLINE if online else MAX_BLIND_FRACTION
    if online and ts.converged is not None and not np.all(ts.converged):
        return (
            f"{int(np.sum(~ts.converged))} trial(s) ended without the online rule's stop (the most steps a visit "
            "may take, or a first visit on its own trail most of the time: a nest too small for the trail); "
            "the area is not measured"
        )
    moved = float(np.sum(ts.l1_u) + np.sum(ts.l2_u)) / (ts.robot_steps * CRUISE_STEP_U)
    if moved < MIN_PATH_FRACTION:
        return (
            f"robot stuck: its visits covered {moved:.0%} of the path of its cruising speed "
            f"(an open nest gives ~80 %); the area is not measured"
        )
    if b > limit:
        return (
            f"trail blended: the counter was blind for {b:.0%} of the second visit (limit {limit:.0%}); "
            "the corrections do not hold there; use shorter visits or a thinner trail"
        )
    if np.median(ts.crossings) < 10:
        return f"too few crossings ({np.median(ts.crossings):.0f} median) for an area; use longer visits"
    return None


def calibrate_area_correction(ts, area_true_u2: float) -> float:
    """The factor that makes the median dead-time-corrected estimate of a trial set of the
    reference nest equal its true area."""
    return float(area_true_u2 / np.median(area_estimates(ts, correction=1.0)))
