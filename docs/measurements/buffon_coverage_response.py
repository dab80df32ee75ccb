"""How Buffon's online estimates respond to the coverage at which the first visit's trail is read.

The first visit's stop is forced to one coverage (``StopParams(coverage=c, max_coverage=c)``),
so every trial of a nest is read at the same point; the table gives, per nest and coverage, the
median of each visit's dead-time-corrected estimate over the truth (before the calibrated factor
K) and the log slope of their weighted mean (``stcvision.controllers.buffon.estimate``, 'Read at one
coverage'). The nests are the calibration family's circles; nest i, coverage j runs with seed
``--seed + 10 i + j`` on ``--threads`` threads (the results do not depend on them).

    python docs/measurements/buffon_coverage_response.py [--trials 32] [--seed 11] \\
        [--nests circle:60,circle:100,circle:160]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from stcvision.controllers.buffon.batched import VisitConfig, run_trials
from stcvision.controllers.buffon.estimate import buffon_area, online_area, self_crossing_area
from stcvision.controllers.buffon.nests import parse_nest
from stcvision.controllers.buffon.stopping import StopParams

COVERAGES = (0.10, 0.13, 0.18, 0.24)


def response(spec: str, *, trials: int, seed: int, threads: int = 1, coverages=COVERAGES) -> list[dict]:
    """Per forced coverage: the medians of A1 / A, A2 / A and of their weighted mean over A
    (:func:`~stcvision.controllers.buffon.estimate.online_area` not brought back to one coverage; dead-time
    corrected, no factor)."""
    nest = parse_nest(spec, None)
    out = []
    for j, c in enumerate(coverages):
        config = VisitConfig(visit_steps="auto", stop=StopParams(coverage=c, max_coverage=c))
        ts = run_trials(nest, config, trials=trials, seed=seed + j, threads=threads)
        a1 = self_crossing_area(ts.l1_u, ts.n_self) * (1 - ts.self_blind) / nest.area_u2
        a2 = buffon_area(ts.l1_u, ts.l2_u, ts.crossings) * (1 - ts.blind_fraction) / nest.area_u2
        mean = online_area(ts.l1_u, ts.l2_u, ts.crossings, ts.blind_fraction, ts.n_self, ts.self_blind, slope=0.0)
        out.append({"coverage": c, "a1": float(np.median(a1)), "a2": float(np.median(a2)),
                    "mean": float(np.median(mean / nest.area_u2))})  # fmt: skip
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=32)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--nests", default="circle:60,circle:100,circle:160")
    a = ap.parse_args(argv)
    print("| nest | coverage | A1 / A | A2 / A | weighted mean / A | log slope from the previous row |")
    print("|---|---:|---:|---:|---:|---:|")
    for i, spec in enumerate(a.nests.split(",")):
        prev = None
        for r in response(spec, trials=a.trials, seed=a.seed + 10 * i, threads=a.threads):
            rise = "" if prev is None else math.log(r["mean"] / prev["mean"]) / (r["coverage"] - prev["coverage"])
            slope = rise if rise == "" else f"{rise:.2f}"
            print(f"| {spec} | {r['coverage']:.2f} | {r['a1']:.3f} | {r['a2']:.3f} | {r['mean']:.3f} | {slope} |")
            prev = r


if __name__ == "__main__":
    main()
