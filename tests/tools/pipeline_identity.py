"""Do two checkouts' pipelines read a dataset the same? Runs this checkout's and another's
``Pipeline`` over every frame of one or more datasets (each in its own process, with its own
``stcvision`` on the path) and compares, frame by frame, the ``to_dict`` output plus every
candidate dot's position and SNR, the red blobs' areas and (with ``--pose``) the pose estimates.

    python tests/tools/pipeline_identity.py --other /path/to/other/checkout DATASET [DATASET ...] [--pose]

Prints how many frames differ and the first differences; exit code 1 if any differ. A check for
a change to the pipeline that should not change what it reads (a speed-up, a module split): run
it on the ages, rotation and obstacles sets against a checkout from before the change. With
``--rtol R`` every decision, count, flag and string must still be the same and every number
within R relative (the largest difference found is printed): for a change that reorders
floating-point arithmetic. Not collected by pytest: it needs a second checkout."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parents[2]  # this checkout's root


def dump(datasets: list[str], out: str, pose: bool) -> None:
    """This process's pipeline over the datasets' frames, as JSON in ``out``."""
    import cv2
    import numpy as np

    from stcvision.calibration.profiles import default_profile
    from stcvision.observation import ObservationParams
    from stcvision.pipeline import Pipeline, PipelineParams

    params = PipelineParams(observation=ObservationParams(pose_estimates=True)) if pose else None
    pipe = Pipeline(default_profile(), params)
    res = {}
    for ds in datasets:
        root = Path(ds)
        for line in (root / "labels.jsonl").read_text().splitlines():
            lab = json.loads(line)
            img = cv2.imread(str(root / lab["frame"]), cv2.IMREAD_UNCHANGED)
            dark = cv2.imread(str(root / lab["dark"]), cv2.IMREAD_UNCHANGED)
            r = pipe.process(img, dark=dark)
            d = r.to_dict()
            for k in ("stage_ms", "total_ms", "untrusted"):
                d.pop(k, None)
            d["observation"].pop("untrusted", None)
            d["all_xy"] = np.round(r.dots.xy_px, 6).tolist()
            d["all_snr"] = np.round(r.dots.snr, 6).tolist()
            d["red_area"] = r.red.area_px.tolist()
            o = r.observation
            d["pose"] = [o.position_offset, o.pattern_rotation_rad, o.landmark_offset, o.landmark_rotation_rad]
            res[f"{root.name}:{lab['frame']}"] = d
    Path(out).write_text(json.dumps(res, sort_keys=True, default=float))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("datasets", nargs="+", metavar="DATASET")
    p.add_argument("--other", required=False, metavar="CHECKOUT", help="the other checkout's root")
    p.add_argument("--pose", action="store_true", help="with the pose estimates (the wide view)")
    p.add_argument(
        "--rtol",
        type=float,
        default=0.0,
        help="numbers may differ by this much relative (default 0: bit for bit); all else exactly",
    )
    p.add_argument("--dump", metavar="OUT.json", help=argparse.SUPPRESS)  # internal: one side
    a = p.parse_args(argv)
    if a.dump:
        dump(a.datasets, a.dump, a.pose)
        return 0
    if not a.other:
        p.error("--other CHECKOUT is required")
    with tempfile.TemporaryDirectory(prefix="pipeline-identity-") as tmp:
        outs = []
        for name, root in (("this", HERE), ("other", Path(a.other).resolve())):
            out = str(Path(tmp) / f"{name}.json")
            env = {**os.environ, "PYTHONPATH": str(root)}
            cmd = [sys.executable, __file__, *a.datasets, "--dump", out] + (["--pose"] if a.pose else [])
            subprocess.run(cmd, env=env, check=True)
            outs.append(json.loads(Path(out).read_text()))
    this, other = outs
    worst = [0.0]
    differ = [k for k in this if not _same(this[k], other.get(k), a.rtol, worst)]
    print(
        f"{len(this)} frames, {len(differ)} differ"
        + (f" (rtol {a.rtol:g}; largest relative difference {worst[0]:.3g})" if a.rtol else "")
    )
    for k in differ[:5]:
        fields = [f for f in this[k] if not _same(this[k][f], other[k].get(f), a.rtol, [0.0])]
        print(f"  {k}: {', '.join(fields)}")
    return 1 if differ else 0


def _same(x, y, rtol: float, worst: list) -> bool:
    """``x`` and ``y`` (JSON values) alike: numbers within ``rtol`` relative (``worst[0]``: the
    largest relative difference seen), everything else equal; bools are not numbers here."""
    num = (int, float)
    if isinstance(x, num) and isinstance(y, num) and not isinstance(x, bool) and not isinstance(y, bool):
        if x == y:
            return True
        rel = abs(x - y) / max(abs(x), abs(y))
        worst[0] = max(worst[0], rel)
        return rel <= rtol
    if isinstance(x, list) and isinstance(y, list):
        return len(x) == len(y) and all(_same(a, b, rtol, worst) for a, b in zip(x, y, strict=True))
    if isinstance(x, dict) and isinstance(y, dict):
        return x.keys() == y.keys() and all(_same(x[k], y[k], rtol, worst) for k in x)
    return x == y


if __name__ == "__main__":
    sys.exit(main())
