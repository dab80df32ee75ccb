"""Buffon's online area measurement on a second held-out family of nests: per-nest single-trial
median error, trusted or not, coverage of ``area_ci95`` (per nest) and of the per-trial
intervals (per trial), per family, with Clopper-Pearson intervals (scipy.stats.binomtest).

The family (44 nests, 2,000-30,000 u^2, shares no nest with the calibration family nor with
``stcvision buffon online``'s evaluation family): seven circles, seven squares, six ellipses, six
nests with barriers, eight concave polygons (L, U, T) and ten random simple polygons whose shapes
come from ``--shape-seed``. Nest i runs its trials with seed ``--seed + i``, on one thread.

    python docs/measurements/buffon_heldout.py --out DIR [--trials 12] [--seed 7300] [--shape-seed 7100] [--nests N]

writes DIR/heldout.jsonl (every trial's raw measurements, so that a changed estimator can be
scored again without running the robots: ``--rescore``) and prints the markdown table.

    python docs/measurements/buffon_heldout.py --calibration --out DIR [--trials 12] [--seed 9100]

runs the calibration family instead (``stcvision.controllers.buffon.online.calibration_family``, nest i
with seed ``--seed + i``) into DIR/calibration.jsonl and prints what
``stcvision.controllers.buffon.online.calibrate_online`` makes of it (the factor and the spreads that
``controllers/buffon/estimate.py`` ships).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from stcvision.controllers.buffon import online as exp
from stcvision.controllers.buffon.batched import VisitConfig, run_trials
from stcvision.controllers.buffon.experiments import refresh, result_of
from stcvision.controllers.buffon.nests import parse_nest


def family(folder: Path, shape_seed: int) -> list[dict]:
    """The held-out family: dicts with family, spec, barrier (polygons written to ``folder``)."""
    folder.mkdir(parents=True, exist_ok=True)
    rows = [{"family": "circles", "spec": f"circle:{d}", "barrier": None} for d in (52, 70, 88, 105, 135, 165, 192)]
    rows += [{"family": "squares", "spec": f"square:{s}", "barrier": None} for s in (47, 62, 80, 98, 125, 155, 172)]
    ellipses = ((2500, 3), (4500, 1.5), (8000, 5), (13000, 2.5), (18000, 7), (26000, 1.8))
    rows += [{"family": "ellipses", "spec": f"ellipse:{a}:{r}", "barrier": None} for a, r in ellipses]
    barriers = (("circle:80", "bar:0.6"), ("circle:140", "bar:0.45"), ("square:90", "plus:0.7"),
                ("square:160", "bar:0.8"), ("ellipse:14000:2", "plus:0.5"), ("circle:190", "bar:0.35"))  # fmt: skip
    rows += [{"family": "barriers", "spec": s, "barrier": b} for s, b in barriers]
    polys = {"L1": exp._l_shape(70, 30), "L2": exp._l_shape(150, 60), "U1": exp._u_shape(100, 80, 40, 45),
             "U2": exp._u_shape(140, 100, 40, 50), "T1": exp._t_shape(120, 100, 50, 40),
             "T2": exp._t_shape(150, 120, 45, 45), "L3": exp._l_shape(115, 55),
             "U3": exp._u_shape(170, 90, 60, 40)}  # fmt: skip
    rng = np.random.default_rng(shape_seed)
    for i, area in enumerate(np.exp(rng.uniform(math.log(2000), math.log(30000), 10))):
        polys[f"random_{i}"] = exp._random_polygon(rng, float(area))
    for name, v in polys.items():
        p = folder / f"h_{name}.json"
        p.write_text(json.dumps(v))
        rows.append({"family": "random" if name.startswith("random") else "concave", "spec": f"polygon:{p}",
                     "barrier": None})  # fmt: skip
    return rows


def run(out: Path, trials: int, seed: int, rows: list[dict], name: str = "heldout") -> list[dict]:
    """Run (or resume) every nest's trials into ``out/NAME.jsonl``; the stored records."""
    store = out / f"{name}.jsonl"
    done = {json.loads(line)["i"]: json.loads(line) for line in store.open()} if store.exists() else {}
    for i, r in enumerate(rows):
        if i in done:
            continue
        nest = parse_nest(r["spec"], r["barrier"])
        ts = run_trials(nest, VisitConfig(visit_steps="auto"), trials=trials, seed=seed + i, threads=1)
        rec = {"i": i, **r, "seed": seed + i, **result_of(ts, nest.area_u2)}
        with store.open("a") as f:
            f.write(json.dumps(rec) + "\n")
        done[i] = rec
        print(f"{i + 1}/{len(rows)} {r['family']} {Path(r['spec']).name} {r['barrier'] or ''}", file=sys.stderr)
    return [done[i] for i in range(len(rows))]


def table(records: list[dict]) -> str:
    """The coverage table of the records, scored by this version's estimators."""
    rows = []
    for rec in records:
        r = {"family": rec["family"], **refresh(rec, rec["area_true"])}
        ci = r["area_ci95"]
        r["ci_holds"] = bool(ci is not None and ci[0] <= r["area_true"] <= ci[1])
        r["trial_holds"] = round((r["trial_ci95_coverage"] or 0) * r["trials"])
        rows.append(r)
    md = ["| family | nests | `area_ci95` holds (95 % CI) | trials | `trial_area_ci95` holds (95 % CI) "
          "| median error: median / worst nest | nests above 5 % | untrusted |",
          "|---|---:|---|---:|---|---|---:|---:|"]  # fmt: skip
    for t in exp.coverage_table(rows):
        a, b = t["area_ci95_coverage_ci"], t["trial_ci95_coverage_ci"]
        over = sum(r["area_rel_error_median"] > 0.05 for r in rows if t["family"] in ("all", r["family"]))
        md.append(
            f"| {t['family']} | {t['nests']} | {t['area_ci95_coverage']:.0%} ({a[0]:.0%}-{a[1]:.0%}) | {t['trials']} | "
            f"{t['trial_ci95_coverage']:.1%} ({b[0]:.0%}-{b[1]:.0%}) | {t['median_error_median']:.1%} / "
            f"{t['median_error_max']:.1%} | {over} | {t['untrusted']} |"
        )
    return "\n".join(md)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--trials", type=int, default=12)
    ap.add_argument("--seed", type=int, default=7300)
    ap.add_argument("--shape-seed", type=int, default=7100)
    ap.add_argument("--nests", type=int, default=None, help="only the first N nests")
    ap.add_argument("--rescore", action="store_true", help="score the stored trials again, run nothing")
    ap.add_argument("--calibration", action="store_true", help="run the calibration family and print its factor")
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    if a.calibration:
        cal = exp.calibrate_online(run(a.out, a.trials, a.seed, exp.calibration_family(a.out / "nests"), "calibration"))
        print(json.dumps({k: v for k, v in cal.items() if k != "nest_median_bias"}, indent=1))
        return 0
    if a.rescore:
        records = [json.loads(line) for line in (a.out / "heldout.jsonl").open()]
    else:
        records = run(a.out, a.trials, a.seed, family(a.out / "nests", a.shape_seed)[: a.nests])
    print(table(records))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
