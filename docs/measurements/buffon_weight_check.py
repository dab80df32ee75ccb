"""The online estimate's weight chosen by a rule stated in advance, on the calibration family only.

For each weight w, the coverage slope, factor and spreads are calibrated at w on one store of the calibration
family (``docs/measurements/buffon_heldout.py --calibration``, seeds 9100 + i), as they would ship. The
per-trial intervals they give are scored on the same 20 nests' trials at two seed sets: the store
itself (seeds 9100+) and the calibration rows of a ``stcvision buffon online --trials 12`` store
(seeds 0 + the row's position), by nest group: round (open circles and squares, the short
barriers), ellipses, compartment nests, concave polygons. Only calibration nests are read: no
held-out trial.

The rule: a weight is eligible when its per-trial intervals hold in >= 95 % of the trials of every
group, the two seed sets pooled; of the eligible weights the one with the lowest RMS log error of
single trials about the truth (the factor of the 9100+ store, both seed sets pooled) is chosen;
if none is eligible the shipped weight stays. Candidates 0.3, 0.4 and 0.5 unless given.

    python docs/measurements/buffon_weight_check.py CAL_DIR/calibration.jsonl ONLINE_DIR/sweep.jsonl [W ...]

prints two markdown tables (accuracy; per-trial coverage by group), the single trials' spread
about their nest's median by group, and the rule's choice.
"""

from __future__ import annotations

import json
import sys

import numpy as np

from stcvision.controllers.buffon import estimate as est
from stcvision.controllers.buffon.online import CALIBRATION_COMPARTMENTS, calibrate_online

KEYS = ("l1_u", "l2_u", "crossings", "blind_fraction", "n_self", "self_blind")
GROUPS = ("round", "ellipses", "compartments", "concave")
MIN_COVERAGE = 0.95
COMPARTMENTS = {spec.split("/")[-1] + barrier for spec, barrier in CALIBRATION_COMPARTMENTS}


def _name(spec: str, barrier: str | None) -> str:
    return spec.split("/")[-1] + (barrier or "")


def _group(rec: dict) -> str:
    if "ellipse" in rec["spec"]:
        return "ellipses"
    if "calibration_" in rec["spec"]:
        return "concave"
    return "compartments" if _name(rec["spec"], rec["barrier"]) in COMPARTMENTS else "round"


def load(cal_path: str, sweep_path: str) -> tuple[list[dict], list[dict]]:
    """The calibration store's records and the same nests' rows of a ``buffon online`` store."""
    cal = [json.loads(line) for line in open(cal_path)]
    names = {_name(r["spec"], r["barrier"]) for r in cal}
    other: dict[str, dict] = {}
    for line in list(open(sweep_path))[1:]:
        r = json.loads(line)
        p = r["params"]
        name = _name(p["spec"], p["barrier"])
        if p.get("visit_steps") == "auto" and not p.get("trail_turn") and name in names and name not in other:
            other[name] = {**r["result"], "spec": p["spec"], "barrier": p["barrier"]}
    return cal, list(other.values())


def score(w: float, cal: list[dict], other: list[dict]) -> dict:
    """Weight w: the calibration of ``cal`` at w, and its per-trial intervals and errors on both sets."""
    c, c2 = calibrate_online(cal, w=w), calibrate_online(other, w=w)
    widths = {
        "w": w,
        "extra": c["trial_extra_sigma"],
        "correction_se": c["correction_se_log"],
        "shape": c["shape_sigma_upper"],
        "slope_se": c["coverage_slope_se"],
        "dof": c["dof"],
    }
    out = {"w": w, "cal": c, "other": c2, "holds": {}, "resid": {}, "log_err": {}, "worst": {}}
    for label, recs in (("9100+", cal), ("0+", other)):
        errs, worst = [], 0.0
        for r in recs:
            a = c["correction"] * est.online_area(*(np.asarray(r[k], float) for k in KEYS), w=w,
                                                  slope=c["coverage_slope"])  # fmt: skip
            log_a = np.log(a / r["area_true"])
            offset = est.reading_coverage(r["l1_u"], r["n_self"]) - est.REFERENCE_COVERAGE
            half = est.trial_half_width(np.asarray(r["rate_rel_se"], float), coverage_offset=offset, **widths)
            out["holds"].setdefault((label, _group(r)), []).extend((np.abs(log_a) <= half).tolist())
            out["resid"].setdefault(_group(r), []).extend((log_a - np.median(log_a)).tolist())
            errs.extend(log_a.tolist())
            worst = max(worst, float(np.median(np.abs(np.expm1(log_a)))))
        out["log_err"][label], out["worst"][label] = errs, worst
    pooled = {g: out["holds"][("9100+", g)] + out["holds"][("0+", g)] for g in GROUPS}
    out["coverage"] = {g: float(np.mean(v)) for g, v in pooled.items()}
    out["spread"] = {g: float(np.sqrt(np.mean(np.square(out["resid"][g])))) for g in GROUPS}
    out["eligible"] = all(v >= MIN_COVERAGE for v in out["coverage"].values())
    out["rms"] = {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in out["log_err"].items()}
    out["rms"]["both"] = float(np.sqrt(np.mean(np.square(out["log_err"]["9100+"] + out["log_err"]["0+"]))))
    return out


def choose(scores: list[dict]) -> float:
    """The rule: of the eligible weights the lowest pooled RMS log error; none eligible, the shipped one."""
    ok = [s for s in scores if s["eligible"]]
    return min(ok, key=lambda s: s["rms"]["both"])["w"] if ok else est.ONLINE_SECOND_WEIGHT


def tables(scores: list[dict]) -> str:
    md = ["| w | K at seeds 9100+ / 0+ | extra spread 9100+ / 0+ | shape spread 9100+ "
          "| RMS log error 9100+ / 0+ / both | worst nest's median error 9100+ / 0+ |",
          "|---:|---|---|---:|---|---|"]  # fmt: skip
    for s in scores:
        c, c2, r = s["cal"], s["other"], s["rms"]
        md.append(f"| {s['w']:.1f} | {c['correction']:.4f} / {c2['correction']:.4f} | {c['trial_extra_sigma']:.4f} / "
                  f"{c2['trial_extra_sigma']:.4f} | {c['shape_sigma_upper']:.4f} | {r['9100+']:.4f} / {r['0+']:.4f} / "
                  f"{r['both']:.4f} | {s['worst']['9100+']:.1%} / {s['worst']['0+']:.1%} |")  # fmt: skip
    md += ["", "| w | " + " | ".join(f"{g}: both (9100+, 0+)" for g in GROUPS) + " | eligible |",
           "|---:|" + "---|" * len(GROUPS) + "---|"]  # fmt: skip
    for s in scores:
        cells = []
        for g in GROUPS:
            a, b = s["holds"][("9100+", g)], s["holds"][("0+", g)]
            cells.append(f"{s['coverage'][g]:.1%} ({sum(a)}/{len(a)}, {sum(b)}/{len(b)})")
        md.append(f"| {s['w']:.1f} | " + " | ".join(cells) + f" | {'yes' if s['eligible'] else 'no'} |")
    md += ["", "single trials' RMS log spread about their nest's median, both seed sets, by group:"]
    for s in scores:
        md.append(f"w {s['w']:.1f}: " + ", ".join(f"{g} {s['spread'][g]:.4f}" for g in GROUPS))
    return "\n".join(md)


def main(argv=None) -> int:
    a = argv if argv is not None else sys.argv[1:]
    cal, other = load(a[0], a[1])
    scores = [score(float(w), cal, other) for w in (a[2:] or (0.3, 0.4, 0.5))]
    print(tables(scores))
    print(f"\nchosen by the rule: w = {choose(scores):.1f} (shipped {est.ONLINE_SECOND_WEIGHT})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
