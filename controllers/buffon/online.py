"""The online rule's experiments: its calibration family, the held-out evaluation family, and the
coverage of its intervals (``stcvision buffon calibrate --online`` and ``buffon online``).

Two families that share no nest:

* :data:`CALIBRATION_NESTS`, :data:`CALIBRATION_POLYGONS` and :data:`CALIBRATION_COMPARTMENTS`:
  circles, squares, ellipses, six barriers (four of them long enough to split the nest into
  compartments) and three concave polygons (L, U, T), 1,300-20,000 u^2;
  :func:`calibrate_online` turns their trials into the factor and the three spreads of
  :mod:`stcvision.controllers.buffon.estimate`;
* :func:`evaluation_nests`: 42 nests of 2,000-30,000 u^2 in six families (circles, squares,
  ellipses, barriers, concave polygons, random simple polygons), other sizes, ratios and
  barrier lengths than the calibration's, each run with its own seed; the coverage of
  ``area_ci95`` (per nest) and of the per-trial intervals (per trial) is counted per family,
  with Clopper-Pearson intervals (:func:`scipy.stats.binomtest`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from scipy import stats

__all__ = [
    "CALIBRATION_COMPARTMENTS",
    "CALIBRATION_NESTS",
    "calibrate_online",
    "calibration_area_range",
    "calibration_family",
    "calibration_rows",
    "coverage_table",
    "evaluation_nests",
]

CALIBRATION_NESTS = (
    ("circle:40", None),
    ("circle:60", None),
    ("circle:80", None),
    ("circle:120", None),
    ("circle:160", None),
    ("square:50", None),
    ("square:90", None),
    ("square:130", None),
    ("ellipse:5000:2", None),
    ("ellipse:12000:3", None),
    ("ellipse:20000:5", None),
    ("circle:100", "bar:0.5"),
    ("square:120", "plus:0.5"),
)
#: concave nests of the calibration family (vertices in u), other shapes and sizes than the
#: evaluation's: without them the calibration saw no concave corner, and the evaluation's concave
#: family was the one whose intervals fell short (92.7 % per trial, measured)
CALIBRATION_POLYGONS = {
    "L": ((0, 0), (80, 0), (80, 45), (45, 45), (45, 80), (0, 80)),
    "U": ((0, 0), (110, 0), (110, 90), (75, 90), (75, 40), (35, 40), (35, 90), (0, 90)),
    "T": ((40, 0), (90, 0), (90, 70), (130, 70), (130, 110), (0, 110), (0, 70), (40, 70)),
}
#: nests split into compartments by long barriers, added to the calibration family after the
#: held-out barrier family's per-trial intervals held 91.7 % (below 95 %): the first visit's
#: self-crossing estimate reads 0.87-0.97 of the truth in them against 0.96-1.04 in open nests
#: (its trail has not spread evenly over the compartments when it stops: an uneven trail meets
#: itself more, while the second visit's independent path does not), so the calibration's shape
#: spread left them out. Other sizes and barrier lengths than both evaluation families'.
CALIBRATION_COMPARTMENTS = (
    ("circle:110", "plus:0.8"),
    ("square:75", "plus:0.6"),
    ("circle:150", "plus:0.9"),
    ("square:120", "bar:0.8"),
)
EVALUATION_SEED = 2000  # the random polygons' shapes
EVALUATION_FAMILIES = ("circles", "squares", "ellipses", "barriers", "concave", "random")


def _l_shape(side: float, cut: float) -> list:
    return [[0, 0], [side, 0], [side, side - cut], [side - cut, side - cut], [side - cut, side], [0, side]]


def _u_shape(w: float, h: float, gap: float, depth: float) -> list:
    a = (w - gap) / 2
    return [[0, 0], [w, 0], [w, h], [w - a, h], [w - a, h - depth], [a, h - depth], [a, h], [0, h]]


def _t_shape(w: float, h: float, stem: float, bar: float) -> list:
    a = (w - stem) / 2
    return [[a, 0], [a + stem, 0], [a + stem, h - bar], [w, h - bar], [w, h], [0, h], [0, h - bar], [a, h - bar]]


def _random_polygon(rng: np.random.Generator, area: float) -> list:
    """A random star-shaped simple polygon (sorted angles, radii within 0.55-1 of the largest),
    scaled to ``area`` u^2, its lowest edge's middle at the bottom."""
    k = int(rng.integers(7, 15))
    ang = np.sort(rng.uniform(0, 2 * math.pi, k))
    rad = rng.uniform(0.55, 1.0, k)
    v = np.c_[rad * np.cos(ang), rad * np.sin(ang)]
    a = 0.5 * abs(np.dot(v[:, 0], np.roll(v[:, 1], -1)) - np.dot(v[:, 1], np.roll(v[:, 0], -1)))
    v = v * math.sqrt(area / a)
    v -= v.min(axis=0)
    return v.round(3).tolist()


def calibration_area_range() -> tuple[float, float]:
    """The smallest and the largest true area (u^2) of the calibration family's nests: the sizes
    the online rule's factor and intervals were calibrated on (shipped as
    :data:`~stcvision.controllers.buffon.estimate.CALIBRATED_AREA_U2`)."""
    from stcvision.controllers.buffon.nests import parse_nest
    from stcvision.sim_camera.arenas import polygon_area

    areas = [parse_nest(s, b).area_u2 for s, b in CALIBRATION_NESTS + CALIBRATION_COMPARTMENTS]
    areas += [abs(polygon_area(np.asarray(v, float))) for v in CALIBRATION_POLYGONS.values()]
    return min(areas), max(areas)


def calibration_polygons(folder: str | Path) -> list[dict]:
    """The calibration family's concave nests, written to ``folder`` as JSON."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for name, v in CALIBRATION_POLYGONS.items():
        p = folder / f"calibration_{name}.json"
        p.write_text(json.dumps([list(q) for q in v]))
        out.append({"family": "calibration", "spec": f"polygon:{p}", "barrier": None})
    return out


def calibration_rows(nests) -> list[dict]:
    """(spec, barrier) pairs of the calibration family (:data:`CALIBRATION_NESTS`,
    :data:`CALIBRATION_COMPARTMENTS`) as dicts with family, spec, barrier."""
    return [{"family": "calibration", "spec": s, "barrier": b} for s, b in nests]


def calibration_family(folder: str | Path) -> list[dict]:
    """The whole calibration family in its order (:data:`CALIBRATION_NESTS`, the polygons of
    :func:`calibration_polygons`, :data:`CALIBRATION_COMPARTMENTS`): dicts with family, spec, barrier."""
    compartments = calibration_rows(CALIBRATION_COMPARTMENTS)
    return calibration_rows(CALIBRATION_NESTS) + calibration_polygons(folder) + compartments


def evaluation_nests(folder: str | Path) -> list[dict]:
    """The held-out family: dicts with family, spec, barrier; polygon nests are written to
    ``folder`` as JSON (body lengths)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for d in (55, 75, 95, 115, 150, 185):
        out.append({"family": "circles", "spec": f"circle:{d}", "barrier": None})
    for s in (45, 65, 85, 110, 140, 170):
        out.append({"family": "squares", "spec": f"square:{s}", "barrier": None})
    for a, r in ((3000, 2.5), (6000, 6), (9000, 3.5), (15000, 2), (22000, 8), (28000, 4)):
        out.append({"family": "ellipses", "spec": f"ellipse:{a}:{r}", "barrier": None})
    for spec, bar in (
        ("circle:90", "bar:0.7"),
        ("circle:130", "plus:0.6"),
        ("square:100", "bar:0.4"),
        ("square:150", "plus:0.8"),
        ("ellipse:10000:3", "bar:0.5"),
        ("circle:170", "plus:0.3"),
    ):
        out.append({"family": "barriers", "spec": spec, "barrier": bar})
    polys = [
        ("L1", _l_shape(60, 25)),
        ("L2", _l_shape(130, 70)),
        ("U1", _u_shape(90, 70, 30, 40)),
        ("U2", _u_shape(160, 120, 50, 70)),
        ("T1", _t_shape(110, 90, 40, 35)),
        ("T2", _t_shape(170, 140, 60, 50)),
        ("L3", _l_shape(95, 40)),
        ("U3", _u_shape(120, 60, 40, 30)),
    ]
    for name, v in polys:
        p = folder / f"concave_{name}.json"
        p.write_text(json.dumps(v))
        out.append({"family": "concave", "spec": f"polygon:{p}", "barrier": None})
    rng = np.random.default_rng(EVALUATION_SEED)
    for i, area in enumerate(np.exp(rng.uniform(math.log(2000), math.log(30000), 10))):
        p = folder / f"random_{i}.json"
        p.write_text(json.dumps(_random_polygon(rng, float(area))))
        out.append({"family": "random", "spec": f"polygon:{p}", "barrier": None})
    return out


def calibrate_online(results: list[dict], *, w: float | None = None, slope: float | None = None) -> dict:
    """The coverage slope, factor and spreads of the online rule from the calibration family's
    stored results (each with ``area_true`` and per-trial ``l1_u``, ``l2_u``, ``crossings``,
    ``blind_fraction``, ``n_self``, ``self_blind``, ``rate_rel_se``; ``trail_width_u`` if not the
    paper's) for the weight ``w`` (None: the shipped
    :data:`~stcvision.controllers.buffon.estimate.ONLINE_SECOND_WEIGHT`): see
    :mod:`stcvision.controllers.buffon.estimate`. The slope (the log estimate's on the reading coverage,
    within nests, pooled) is measured on ``results`` unless ``slope`` is given (or the trials of
    every nest were read at one coverage: then the shipped one and its error are used)."""
    from stcvision.controllers.buffon.defaults import PAPER_TRAIL_WIDTH_U
    from stcvision.controllers.buffon.estimate import (
        COVERAGE_SLOPE,
        COVERAGE_SLOPE_SE,
        ONLINE_SECOND_WEIGHT,
        REFERENCE_COVERAGE,
        online_area,
        reading_coverage,
    )

    w = ONLINE_SECOND_WEIGHT if w is None else w
    keys = ("l1_u", "l2_u", "crossings", "blind_fraction", "n_self", "self_blind")
    logs, offsets = [], []  # per nest: each trial's log estimate over the truth, and rho - rho0
    for r in results:
        width = float(r.get("trail_width_u", PAPER_TRAIL_WIDTH_U))
        a = online_area(*(np.asarray(r[k], float) for k in keys), w=w, trail_width_u=width, slope=0.0)
        logs.append(np.log(a / r["area_true"]))
        offsets.append(reading_coverage(r["l1_u"], r["n_self"], width) - REFERENCE_COVERAGE)
    within_x = np.concatenate([o - o.mean() for o in offsets])  # about each nest's own mean
    if np.ptp(within_x) > 0:
        fit = stats.linregress(within_x, np.concatenate([g - g.mean() for g in logs]))
        measured, measured_se, r_value = float(fit.slope), float(fit.stderr), float(fit.rvalue)
    else:  # every nest's trials read at one coverage: nothing to measure the slope on
        measured, measured_se, r_value = COVERAGE_SLOPE, COVERAGE_SLOPE_SE, math.nan
    slope = measured if slope is None else slope
    meds, samp, resid, se2 = [], [], [], []
    for r, log_a, offset in zip(results, logs, offsets, strict=True):
        d = log_a - slope * offset
        m = float(np.median(d))
        meds.append(m)
        samp.append(math.pi / 2 * np.var(d, ddof=1) / len(d))  # the sampling variance of a median
        resid.extend((d - m).tolist())
        se2.extend(((w * np.asarray(r["rate_rel_se"])) ** 2).tolist())
    meds = np.array(meds)
    n = len(meds)
    between = float(np.var(meds, ddof=1))
    shape2 = max(0.0, between - float(np.mean(samp)))
    n_trials = len(resid)
    within = float(np.sum(np.square(resid)) / (n_trials - n))
    extra2 = max(0.0, within - float(np.mean(se2)))
    k = math.exp(-float(np.mean(meds)))
    return {
        "nests": n,
        "trials": n_trials,
        "coverage_slope": slope,
        "coverage_slope_se": measured_se,
        "coverage_slope_r": r_value,
        "correction": k,
        "correction_se_log": math.sqrt(between / n),
        "shape_sigma": math.sqrt(shape2),
        # the nests' whole spread, sampling included: what ships when the two cannot be told apart
        "shape_sigma_upper": math.sqrt(between),
        "trial_extra_sigma": math.sqrt(extra2),
        "dof": n - 1,
        "nest_median_bias": (np.exp(meds) - 1).tolist(),
    }


def coverage_table(rows: list[dict]) -> list[dict]:
    """Per family (and all): nests, their ``area_ci95`` coverage, trials and per-trial coverage,
    each with a Clopper-Pearson 95 % interval, and the single-trial median |error| range."""
    fams = sorted({r["family"] for r in rows}) + ["all"]
    out = []
    for f in fams:
        rs = [r for r in rows if f in ("all", r["family"])]
        k = sum(bool(r["ci_holds"]) for r in rs)
        kt = sum(r["trial_holds"] for r in rs)
        nt = sum(r["trials"] for r in rs)
        ci_n = stats.binomtest(k, len(rs)).proportion_ci()
        ci_t = stats.binomtest(kt, nt).proportion_ci()
        errs = [r["area_rel_error_median"] for r in rs]
        out.append(
            {
                "family": f,
                "nests": len(rs),
                "area_ci95_coverage": k / len(rs),
                "area_ci95_coverage_ci": [ci_n.low, ci_n.high],
                "trials": nt,
                "trial_ci95_coverage": kt / nt,
                "trial_ci95_coverage_ci": [ci_t.low, ci_t.high],
                "median_error_max": max(errs),
                "median_error_median": float(np.median(errs)),
                "untrusted": sum(not r["area_trusted"] for r in rs),
            }
        )
    return out
