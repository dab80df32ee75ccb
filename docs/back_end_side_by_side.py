"""The pipeline's back-end stages (dots, rows, red, heading, observe) of two checkouts side by
side in one process, taking turns frame by frame on the same front-end output (this checkout's
``Pipeline`` front end on ``stcvision bench``'s scene, one thread): the other checkout's
``stages.py``, ``observation.py`` and ``kernels.py`` (a checkout from before the stages became
the ``stcvision.stages`` package, one module per stage) are loaded beside this one's, so a busy
machine slows both alike and the ratio holds. Checks first that both give the same dots, red
lights, heading and observation on the scene's frames (bit for bit).

    python docs/back_end_side_by_side.py --other /path/to/other/checkout [--frames 600]

Prints per-stage medians of the thread's CPU time (ms) for both, as JSON. Run it with its own
``NUMBA_CACHE_DIR``: numba caches the other checkout's kernels under this script's module names.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from pathlib import Path

import numpy as np

STAGES = ("dots", "rows", "red", "heading", "observe")


def load_other(root: Path):
    """The other checkout's kernels, stages and observation modules (its stages and observation
    calling its own kernels)."""
    mods = {}
    for name in ("kernels", "stages", "observation"):
        spec = importlib.util.spec_from_file_location(f"other_{name}", root / "stcvision" / f"{name}.py")
        m = importlib.util.module_from_spec(spec)
        sys.modules[f"other_{name}"] = m
        # its ``from stcvision import kernels`` finds the other checkout's kernels (this one has
        # none: its loops live with their stages)
        sys.modules["stcvision.kernels"] = mods.get("kernels", m)
        try:
            spec.loader.exec_module(m)
        finally:
            del sys.modules["stcvision.kernels"]
        if name != "kernels":
            m.kernels = mods["kernels"]
        mods[name] = m
    return mods["stages"], mods["observation"]


def front(pipe, frame) -> dict:
    """What the back end reads, copied (the front end reuses its scratch images)."""
    f = pipe.front.run(frame, pipe.scratch, time.perf_counter_ns, [])
    return dict(
        g=f.green.copy(),
        obstacle=f.obstacle.copy(),
        marks=f.marks.copy(),
        bg=f.bg,
        noise=f.noise,
        q=f.quantum,
        red_levels=f.red_levels,
    )


def back(st, ob, pipe, f: dict, times: dict | None = None):
    """The back-end stages as ``Pipeline.process`` calls them, with ``st`` and ``ob`` as the
    stages and observation modules; their CPU times appended to ``times``."""
    p, prof = pipe.params, pipe.profile
    w = p.dots.window_px
    clock = time.thread_time_ns
    t = [clock()]
    dots = st.find_dots(
        f["marks"],
        p.dots,
        gain=pipe.gain,
        background_dn=f["bg"],
        noise_dn=f["noise"],
        ground_to_robot=prof.ground_to_robot,
        quantum=f["q"],
    )
    dots = st.mirror_centroids(
        dots,
        f["g"],
        background_dn=f["bg"],
        umap=pipe.front.umap_crop,
        ground_to_robot=prof.ground_to_robot,
        params=p.dots,
    )
    t.append(clock())
    all_dots = st.find_rows(
        f["marks"],
        dots,
        gain=pipe.gain,
        background_dn=f["bg"],
        noise_dn=f["noise"],
        px_per_m=prof.ground_px_per_m,
        window_px=w,
        params=p.rows,
        dot_params=p.dots,
        ground_to_robot=prof.ground_to_robot,
        quantum=f["q"],
    )
    t.append(clock())
    red = st.find_red(f["obstacle"], p.red, window_area=w * w)
    t.append(clock())
    heading = st.fit_heading(dots, p.heading)
    t.append(clock())
    obs = ob.observe_cell(
        all_dots,
        red.xy_px,
        red.peak_dn,
        pipe.geometry,
        red_threshold_dn=p.channels.levels(*f["red_levels"])[0],
        heading_error_rad=heading.heading_error_rad if (heading.ok and p.use_heading) else 0.0,
        params=p.observation,
        subcell_m=prof.subcell_m,
    )
    t.append(clock())
    if times is not None:
        for i, k in enumerate(STAGES):
            times[k].append((t[i + 1] - t[i]) / 1e6)
    return all_dots, red, heading, obs


def same(a, b) -> bool:
    (da, ra, ha, oa), (db, rb, hb, obb) = a, b
    arrays = [(getattr(da, k), getattr(db, k)) for k in ("xy_px", "xy_m", "strength", "snr", "lit")]
    arrays += [(getattr(ra, k), getattr(rb, k)) for k in ("xy_px", "peak_dn", "area_px")]
    arrays += [(ha.points_m, hb.points_m)]
    if da.from_row is not None or db.from_row is not None:
        arrays.append((da.from_row, db.from_row))
    scal = [(ha.ok, hb.ok), (ha.reason, hb.reason)] + [
        (repr(getattr(ha, k)), repr(getattr(hb, k))) for k in ("line_angle_rad", "residual_m")
    ]
    return (
        all(x is not None and y is not None and np.array_equal(x, y) for x, y in arrays)
        and all(x == y for x, y in scal)
        and repr(oa) == repr(obb)
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--other", required=True, metavar="CHECKOUT")
    ap.add_argument("--frames", type=int, default=600)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    import cv2

    import stcvision.observation as this_ob
    import stcvision.stages as this_st
    from calibration.profiles import default_profile
    from sim_camera.scenarios import benchmark_frames
    from stcvision.pipeline import Pipeline

    cv2.setNumThreads(1)
    other_st, other_ob = load_other(Path(a.other).resolve())
    dark, imgs = benchmark_frames(a.seed)
    pipe = Pipeline(default_profile(), dark=dark)
    fronts = [front(pipe, im) for im in imgs]
    identical = all(same(back(this_st, this_ob, pipe, f), back(other_st, other_ob, pipe, f)) for f in fronts)
    times = {v: {k: [] for k in STAGES} for v in ("this", "other")}
    sides = (("this", this_st, this_ob), ("other", other_st, other_ob))
    for i in range(a.frames):
        for name, st, ob in sides[:: 1 if i % 2 else -1]:
            back(st, ob, pipe, fronts[i % len(fronts)], times[name])
    out = {"identical": identical, "frames": a.frames}
    for v, tv in times.items():
        out[v] = {k: round(float(np.median(x)), 4) for k, x in tv.items()}
        out[v]["back_end_median"] = round(float(np.median(np.sum([tv[k] for k in STAGES], axis=0))), 4)
    print(json.dumps(out, indent=1))
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())
