"""How the first visit's mixing test (rule (1b) of ``controllers/buffon/stopping.py``) was chosen:
the measurements behind its form and its two constants, on the calibration family only
(``stcvision.controllers.buffon.online.calibration_family``, nest i with seed ``--seed + i``).

    python docs/measurements/buffon_mixing_choice.py --out DIR [--trials 8] [--seed 9100]

1. *Why a bound on the swings' size, the term a and the later half.* Each trial's first visit is
   run with the first-visit rule of coverage alone (``max_coverage`` = ``coverage``) and its
   encounter stream recorded; at its stop, the bins the robot keeps are rebuilt and the script
   prints, per nest: the Poisson dispersion X^2 / (m - 1) of a rate proportional to l over all
   the bins, the encounter rate per unit path against that l-law over the tenths of the path
   (first and last), the spread (1b) and A1 / truth; and, over all trials, the rank correlation
   of the spread with log A1 about each nest's median.
2. *The constants.* The family is run with the coverage alone and with several (``mix_tol``,
   ``max_coverage``); for each, the spread (log) of the nests' median A1, the single trials' A1
   spread about their nest's median, and the nests' median first-visit length against the
   coverage alone.

Writes DIR/mixing_choice.json with every figure.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
from scipy import stats

from stcvision.controllers.buffon.batched import TrialWorld, VisitConfig, run_trials, trial_seeds
from stcvision.controllers.buffon.estimate import self_crossing_area
from stcvision.controllers.buffon.nests import BODY_LENGTH_M, parse_nest
from stcvision.controllers.buffon.online import CALIBRATION_COMPARTMENTS, calibration_family
from stcvision.controllers.buffon.stopping import StopParams, mixing_spread, new_batch_state

P = StopParams()
COVERAGE_ALONE = StopParams(max_coverage=P.coverage)
SETTINGS = ((0.10, 0.18), (0.12, 0.18), (0.10, 0.16), (0.08, 0.18))


def _bins(steps: int, batches: int, first: int = 64) -> int:
    """The bin width (steps) the batch-means state has after ``steps`` steps."""
    width = first
    while steps // width >= 2 * batches:
        width *= 2
    return width


def _state(enc: np.ndarray, dl: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The robot's bins at the end of a recorded first visit (per step: encounters, path): the
    batch-means state of :func:`stcvision.controllers.buffon.stopping.batch_add`, and the full bins'
    encounters and path edges."""
    width = _bins(len(enc), P.batches)
    k = len(enc) // width
    n = enc[: k * width].reshape(k, width).sum(axis=1)
    path = dl[: k * width].reshape(k, width).sum(axis=1)
    st = new_batch_state(P.batches)
    st[0], st[2] = width, k
    st[3 : 3 + k] = n
    st[3 + 2 * P.batches : 3 + 2 * P.batches + k] = path
    return st, n, np.r_[0.0, np.cumsum(path)]


def streams(rows, trials: int, seed: int) -> list[dict]:
    """Part 1: the first visits at the coverage alone, recorded."""
    out = []
    cfg = VisitConfig(visit_steps="auto", stop=COVERAGE_ALONE)
    for i, r in enumerate(rows):
        nest = parse_nest(r["spec"], r["barrier"])
        world = TrialWorld(nest, cfg)
        recs = []
        for s in trial_seeds(seed + i, trials):
            l1, _, _, _, _, trails, n_self, _, _, _, b1 = world.trial(s, record=True)
            v = trails["visit1"]
            xy = np.vstack([np.asarray(nest.start_xy)[None, :], v[:, :2]])
            dl = np.hypot(*np.diff(xy, axis=0).T) / BODY_LENGTH_M
            st, n, edges = _state(v[:, 2], dl)
            w = np.diff(edges**2)
            expected = n.sum() * w / w.sum()
            x2 = float(np.sum((n - expected) ** 2 / expected))
            tenths = np.interp([0.05, 0.95], (np.arange(len(n)) + 0.5) / len(n), n / expected)
            recs.append({"a1": float(self_crossing_area(l1, n_self) * (1 - b1) / nest.area_u2),
                         "spread": float(mixing_spread(st, P.batches)), "dispersion": x2 / (len(n) - 1),
                         "first_tenth": float(tenths[0]), "last_tenth": float(tenths[1])})  # fmt: skip
        out.append({"nest": f"{Path(r['spec']).name} {r['barrier'] or ''}".strip(), "trials": recs})
    return out


def settings(rows, trials: int, seed: int) -> list[dict]:
    """Part 2: A1 and first-visit length with the coverage alone and each setting."""
    compartments = {f"{s} {b}" for s, b in CALIBRATION_COMPARTMENTS}
    out, base_l1 = [], None
    for tol, cap in ((P.mix_tol, P.coverage), *SETTINGS):
        stop = COVERAGE_ALONE if cap == P.coverage else StopParams(mix_tol=tol, max_coverage=cap)
        meds, resid, l1s, names = [], [], [], []
        for i, r in enumerate(rows):
            nest = parse_nest(r["spec"], r["barrier"])
            ts = run_trials(nest, VisitConfig(visit_steps="auto", stop=stop), trials=trials, seed=seed + i)
            la = np.log(self_crossing_area(ts.l1_u, ts.n_self) * (1 - ts.self_blind) / nest.area_u2)
            meds.append(float(np.median(la)))
            resid.extend((la - np.median(la)).tolist())
            l1s.append(float(np.median(ts.l1_u)))
            names.append(f"{Path(r['spec']).name} {r['barrier'] or ''}".strip())
        base_l1 = base_l1 or l1s
        out.append({
            "mix_tol": None if cap == P.coverage else tol, "max_coverage": cap,
            "a1_nest_spread": float(np.std(meds, ddof=1)), "a1_trial_spread": float(np.sqrt(np.mean(np.square(resid)))),
            "first_visit_length_ratio": float(np.median(np.array(l1s) / np.array(base_l1))),
            "compartments_a1": {n: round(math.exp(m), 3) for n, m in zip(names, meds, strict=True)
                                if n in compartments},
        })  # fmt: skip
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--trials", type=int, default=8)
    ap.add_argument("--seed", type=int, default=9100)
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    rows = calibration_family(a.out / "nests")
    part1 = streams(rows, a.trials, a.seed)
    print("nest | dispersion (l-law, all bins) | first / last tenth against the l-law | spread (1b) | A1 / truth")
    spreads, logs = [], []
    for r in part1:
        t = r["trials"]

        def med(key: str, t=t) -> float:
            return float(np.median([x[key] for x in t]))

        print(f"{r['nest']} | {med('dispersion'):.1f} | {med('first_tenth'):.2f} / {med('last_tenth'):.2f} | "
              f"{med('spread'):.3f} | {med('a1'):.3f}")  # fmt: skip
        la = np.log([x["a1"] for x in t])
        logs.extend((la - np.median(la)).tolist())
        spreads.extend(x["spread"] for x in t)
    rho = stats.spearmanr(spreads, logs)
    print(f"rank correlation of the spread with log A1 about each nest's median: {rho.statistic:.2f} "
          f"(p = {rho.pvalue:.2g}, {len(spreads)} trials)")  # fmt: skip
    part2 = settings(rows, a.trials, a.seed)
    for s in part2:
        print(json.dumps(s))
    (a.out / "mixing_choice.json").write_text(json.dumps({"streams": part1, "settings": part2}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
