"""The online estimate's weight checked on the calibration family at a second set of seeds.

For each weight w, the factor and spreads are calibrated on one store of the calibration family
(``docs/buffon_heldout.py --calibration``, seeds 9100 + i) and the per-trial intervals they give
are scored on the same 20 nests run at other seeds (the calibration rows of a
``stcvision buffon online`` sweep store, seeds 0 + position), by nest group: round (open circles
and squares, the short barriers), ellipses, compartment nests, concave polygons. Only
calibration nests are read: no held-out trial.

    python docs/buffon_weight_check.py CAL_DIR/calibration.jsonl ONLINE_DIR/sweep.jsonl [W ...]
"""

from __future__ import annotations

import json
import sys

import numpy as np
from scipy import stats

from controllers.buffon import estimate as est
from controllers.buffon.online import calibrate_online

KEYS = ("l1_u", "l2_u", "crossings", "blind_fraction", "n_self", "self_blind")


def _name(spec: str, barrier: str | None) -> str:
    return spec.split("/")[-1] + (barrier or "")


def _group(rec: dict) -> str:
    if "ellipse" in rec["spec"]:
        return "ellipses"
    if "calibration_" in rec["spec"]:
        return "concave"
    return "compartments" if rec["barrier"] and _name(rec["spec"], rec["barrier"]) in _COMPARTMENTS else "round"


_COMPARTMENTS: set[str] = set()


def main(argv=None) -> int:
    from controllers.buffon.online import CALIBRATION_COMPARTMENTS

    a = argv if argv is not None else sys.argv[1:]
    cal = [json.loads(line) for line in open(a[0])]
    names = {_name(r["spec"], r["barrier"]) for r in cal}
    _COMPARTMENTS.update(_name(s, b) for s, b in CALIBRATION_COMPARTMENTS)
    other: dict[str, dict] = {}
    for line in list(open(a[1]))[1:]:
        r = json.loads(line)
        p = r["params"]
        name = _name(p["spec"], p["barrier"])
        if p.get("visit_steps") == "auto" and not p.get("trail_turn") and name in names and name not in other:
            other[name] = {**r["result"], "spec": p["spec"], "barrier": p["barrier"]}
    t = stats.t.ppf(0.975, len(cal) - 1)
    for w in [float(x) for x in a[2:]] or (0.3, 0.4, 0.5, 0.6):
        est.ONLINE_SECOND_WEIGHT = w
        c, c2 = calibrate_online(cal), calibrate_online(list(other.values()))
        held: dict[str, list] = {}
        for r in other.values():
            log_a = np.log(c["correction"] * est.online_area(*(np.asarray(r[k], float) for k in KEYS)) / r["area_true"])
            spread2 = c["trial_extra_sigma"] ** 2 + c["correction_se_log"] ** 2 + c["shape_sigma_upper"] ** 2
            half = t * np.sqrt((w * np.asarray(r["rate_rel_se"])) ** 2 + spread2)
            held.setdefault(_group(r), []).extend((np.abs(log_a) <= half).tolist())
        cover = ", ".join(f"{g} {np.mean(v):.1%} ({sum(v)}/{len(v)})" for g, v in sorted(held.items()))
        print(f"w {w:.1f}: K {c['correction']:.4f} (other seeds {c2['correction']:.4f}), extra spread "
              f"{c['trial_extra_sigma']:.4f} ({c2['trial_extra_sigma']:.4f}); "
              f"per-trial coverage at the other seeds: {cover}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
