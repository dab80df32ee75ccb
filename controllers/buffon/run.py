"""The Buffon explorer's runs, as the CLI calls them.

Measure one nest, reproduce the paper, compare the batched path with the pymunk one, recompute
the area correction.

Each returns a JSON-serialisable dict. Progress bars (tqdm) and files are here, around the
simulation; nothing in the simulation prints, plots or logs.
"""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path

import numpy as np

from stcvision.controllers.buffon.batched import VisitConfig, run_trials
from stcvision.controllers.buffon.defaults import CORRECTION_REFERENCE, PAPER_TRAIL_WIDTH_U, PAPER_VISIT_STEPS
from stcvision.controllers.buffon.estimate import (
    AREA_CORRECTION,
    AREA_VISIT_STEPS,
    calibrate_area_correction,
    summarise,
)
from stcvision.controllers.buffon.experiments import experiment_cases, refresh
from stcvision.controllers.buffon.nests import BODY_LENGTH_M, parse_nest
from stcvision.controllers.buffon.stopping import StopParams
from stcvision.errors import BadInputError
from stcvision.fileio import write_bytes_atomic, write_figure
from stcvision.sweep import machine_workers

__all__ = ["calibrate", "compare", "format_text", "measure", "reproduce"]

STORE_NAME = "sweep.jsonl"


def _bar(total: int, desc: str):
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="step", unit_scale=True, disable=None, leave=False)


def measure(
    nest_spec: str,
    barrier: str | None = None,
    *,
    trials: int = 100,
    visit_steps: int | str = "auto",
    trail_width_u: float = PAPER_TRAIL_WIDTH_U,
    seed: int = 0,
    rrd: str | None = None,
    force: bool = False,
    threads: int | None = None,
    trajectory: str | None = None,
) -> dict:
    """Measure one nest with Buffon's method: run the trials, return the nest's nBC and area figures.

    Each trial is one robot making the two visits of the Buffon's needle paper (Girgin &
    Sahin): the first lays a pheromone trail, the second counts its crossings; nBC is the
    crossings per body length of the second visit, and the nest's area follows from it.

    Parameters
    ----------
    nest_spec : str
        The nest: ``circle:DIAMETER``, ``square:SIDE``, ``ellipse:AREA:RATIO`` or
        ``polygon:FILE`` (lengths in body lengths).
    barrier : str, optional
        A centred barrier, ``bar:FRACTION`` (|) or ``plus:FRACTION`` (+).
    trials : int
        Trials (robots), each its own world and random stream.
    visit_steps : int or str
        Steps of each visit (the paper's 50,000), or ``"auto"``: each visit ends when the
        robot's online rule says so.
    trail_width_u : float
        Pheromone trail width in body lengths (the paper's 0.1).
    seed : int
        The trials' seed, >= 0.
    rrd : str, optional
        A rerun recording of the first trial's trails, written to this path.
    force : bool
        Replace an existing recording.
    threads : int, optional
        Threads for the trials (default: one per core).
    trajectory : str, optional
        A folder for the first trial's true paths as TUM files, one per visit
        (:func:`stcvision.controllers.buffon.trajectory.write_trajectory`; the explorer keeps
        no pose estimate, so there is no believed path).

    Returns
    -------
    dict
        JSON-serialisable: the nest, the settings, the nBC and area figures
        (:func:`stcvision.controllers.buffon.estimate.summarise`), the robot-steps and their
        rate per wall and CPU second, and the recording's path.

    Raises
    ------
    BadInputError
        For a nest or barrier that cannot be read or measured, a negative seed, or a bad
        ``visit_steps`` or ``threads``.
    OutputError
        For a recording path that is a folder or does not end in ``.rrd``, or cannot be made.
    FileExistsRefusedError
        For an existing recording without ``force``.
    """
    nest = parse_nest(nest_spec, barrier)
    config = VisitConfig(visit_steps=visit_steps, trail_width_u=trail_width_u)
    if seed < 0:
        raise BadInputError(f"--seed must be >= 0; got {seed}")
    _check_trial_outputs(rrd, trajectory, force)
    with _bar(None if config.auto else 2 * trials * visit_steps, f"buffon {nest.label}") as bar:
        threads = threads or machine_workers()
        ts = run_trials(
            nest,
            config,
            trials=trials,
            seed=seed,
            record_trial=0 if rrd or trajectory else None,
            progress=bar.update,
            threads=threads,
        )
    out = {
        "nest": nest.spec,
        "barrier": nest.barrier,
        "visit_steps": visit_steps,
        "trail_width_u": trail_width_u,
        "seed": seed,
        **summarise(ts, nest.area_u2),
        "robot_steps": ts.robot_steps,
        "threads": threads,
        "robot_steps_per_s": ts.robot_steps / ts.wall_s,
        "robot_steps_per_cpu_s": ts.robot_steps / ts.cpu_s,
        "wall_s": ts.wall_s,
    }
    out.update(_write_trial_outputs(nest, ts, config, rrd, trajectory, force))
    return out


def _check_trial_outputs(rrd: str | None, trajectory: str | None, force: bool) -> None:
    """Refuse, before any trial runs, a recording or a trajectory folder that cannot be written."""
    if rrd is not None:
        from stcvision.rr import check_recording_path

        check_recording_path(rrd, overwrite=force)
    if trajectory is not None:
        from stcvision.controllers.buffon.trajectory import VISIT_FILES
        from stcvision.fileio import check_output_folder

        check_output_folder(trajectory, VISIT_FILES, overwrite=force)


def _write_trial_outputs(nest, ts, config, rrd: str | None, trajectory: str | None, force: bool) -> dict:
    """Write the first trial's recording and TUM files; returns the result's keys saying so."""
    out = {}
    if rrd:
        from stcvision.controllers.buffon.rr import record_trial

        record_trial(rrd, nest, ts.trails["visit1"], ts.trails["visit2"])
        out["rrd"] = str(rrd)
    if trajectory:
        from stcvision.controllers.buffon.trajectory import write_trajectory

        write_trajectory(trajectory, nest.start_xy, ts.trails, config.dt_s, overwrite=force)
        out["trajectory"] = str(trajectory)  # only when asked for: a run without it prints what it always did
        out["trajectory_steps"] = [len(ts.trails["visit1"]), len(ts.trails["visit2"])]
    return out


def format_text(r: dict) -> str:
    """Format a run's result as the text the CLI prints."""
    if "claims" in r:
        return r["summary_text"] + ("\n" + r["online_summary_text"] if r.get("online_summary_text") else "")
    if "paths" in r:
        return "\n".join(f"{k}: {v}" for k, v in r.items() if k != "paths")
    if "area_correction_measured" in r:
        return (
            f"area correction on {r['reference']}: measured {r['area_correction_measured']:.3f}, "
            f"95 % interval {r['ci95']}, shipped {r['area_correction_shipped']:.3f}"
        )
    ci = r["area_ci95"]
    ci_text = f"{_num(ci[0])}-{_num(ci[1])}" if ci else "n/a (fewer than 3 trials)"
    lines = [
        f"nest {r['nest']}{' ' + r['barrier'] if r['barrier'] else ''}: true area {r['area_true']:,.1f} u^2",
        f"nBC median {r['nbc_median']:.4f} (IQR {r['nbc_q1']:.4f}-{r['nbc_q3']:.4f}) over {r['trials']} trials; "
        f"crossings median {r['crossings_median']:.0f}",
        f"area estimate median {_num(r['area_estimate_median'])} u^2, 95 % CI {ci_text}; "
        f"median |error| {_pct(r['area_rel_error_median'])} (raw formula {_pct(r['area_raw_rel_error_median'])})",
        f"{r['robot_steps']:,} robot-steps in {r['wall_s']:.1f} s ({r['robot_steps_per_s']:,.0f}/s)"
        + (
            f"; visits ended by the online rule, median {r['robot_steps_median']:,.0f} steps a trial"
            if r["online"]
            else ""
        ),
    ]
    if r.get("trial_ci95_coverage") is not None:
        lo, hi = r["trial_area_ci95"][0]
        lines.insert(
            3,
            f"trial 0 alone: 95 % interval {_num(lo)}-{_num(hi)}; {r['trial_ci95_coverage']:.0%} of the trials' "
            "own intervals hold the true area",
        )
    if r.get("trial_ci95_note"):
        lines.append(f"note: {r['trial_ci95_note']}")
    if r.get("area_warning"):
        lines.append(f"WARNING: {r['area_warning']}")
    if r.get("trajectory"):
        lines.append(f"wrote {r['trajectory']}: trial 0's true paths, a TUM file a visit")
    return "\n".join(lines)


def _num(x) -> str:
    return "inf" if x is None else f"{x:,.1f}"


def _pct(x) -> str:
    return "n/a" if x is None else f"{x:.1%}"


# ----------------------------------------------------------------------------- output folder
def _out_dir(out: str | Path, force: bool, names: tuple[str, ...]) -> Path:
    from stcvision.sweep import output_folder

    return output_folder(out, names, store=STORE_NAME, force=force, what="Buffon run")


def _run_tasks(tasks, out: Path, sweep, desc: str):
    from stcvision.sweep import run_sweep

    report = run_sweep(tasks, out / STORE_NAME, sweep, desc=desc)
    report.raise_if_failed("nests' tasks")
    return report


# --------------------------------------------------------------------------------- reproduce
REPRODUCE_FILES = (
    "nests.csv",
    "summary.md",
    "fig3_patterns.png",
    "fig4_shape.png",
    "fig5_compactness.png",
    "fig6_barriers.png",
    "fig7_thickness.png",
    "area_accuracy.png",
)


def reproduce(
    out: str | Path, *, trials: int = 100, seed: int = 0, sweep=None, force: bool = False, online_trials: int = 6
) -> dict:
    """Reproduce the paper: every experiment set of sec. 5 plus the absolute-area set.

    Every experiment set of sec. 5 plus the absolute-area set, through the sweep runner; then
    (``online_trials`` > 0) the online rule's experiments (:func:`online`) into ``out/online``.
    """
    from stcvision.controllers.buffon import report
    from stcvision.sweep import SweepOptions, Task

    out = _out_dir(out, force, REPRODUCE_FILES)
    cases = experiment_cases()
    tasks = {
        c: Task(experiment="stcvision.controllers.buffon.experiments:nest_task", params=c.params(trials), seed=seed)
        for c in cases
    }
    t0 = time.perf_counter()
    rep = _run_tasks(list(tasks.values()), out, sweep or SweepOptions(), "buffon reproduce (nests)")
    results = {c: refresh(rep.results[t.key], rep.results[t.key]["area_true"]) for c, t in tasks.items()}
    steps = sum(r["robot_steps"] for r in results.values())
    busy = sum(r["wall_s"] for r in results.values())
    _write_tables(out, {"nests.csv": report.table_csv(cases, results)}, report.figures(cases, results, _patterns(seed)))
    wall = time.perf_counter() - t0
    text = report.claims(cases, results, trials=trials, wall_s=wall, steps_per_s=steps / busy)
    _write_tables(out, {"summary.md": text}, {})
    return {
        "out": str(out),
        "nests": len(cases),
        "trials": trials,
        "robot_steps": steps,
        "robot_steps_per_s_per_worker": steps / busy,
        "wall_s": wall,
        "sweep": rep.summary(),
        "claims": True,
        "summary_text": text,
    } | _online_part(out, online_trials, seed, sweep)


def _online_part(out: Path, trials: int, seed: int, sweep) -> dict:
    """Run the online rule's experiments beside the paper's, in their own folder (and store)."""
    if not trials:
        return {}
    r = online(out / "online", trials=trials, seed=seed, sweep=sweep)
    return {"online": {k: r[k] for k in ("out", "nests", "trials", "coverage", "shape_pairs", "wall_s")},
            "online_summary_text": r["summary_text"]}  # fmt: skip


def _patterns(seed: int) -> dict:
    """Fig. 3: one trial in the smallest, a middle and the standard circle (paths in u)."""
    out = {}
    for d in (10, 50, 100):
        nest = parse_nest(f"circle:{d}")
        ts = run_trials(nest, VisitConfig(visit_steps=PAPER_VISIT_STEPS), trials=1, seed=seed, record_trial=0)
        scale = np.array([1 / BODY_LENGTH_M, 1 / BODY_LENGTH_M, 1.0])
        outline = nest.arena.outer_vertices() / BODY_LENGTH_M
        out[f"circle, diameter {d} u"] = (outline, ts.trails["visit1"] * scale, ts.trails["visit2"] * scale)
    return out


# ----------------------------------------------------------------------------------- compare
PYMUNK_CHUNK_TRIALS = 5


def compare(
    nest_spec: str,
    barrier: str | None,
    *,
    out: str | Path,
    trials: int = 100,
    visit_steps: int = 3000,
    trail_width_u: float = PAPER_TRAIL_WIDTH_U,
    seed: int = 0,
    sweep=None,
    force: bool = False,
) -> dict:
    """Compare nBC of the pymunk path and the batched path on the same nest: two-sample tests."""
    from scipy import stats

    from stcvision.sweep import SweepOptions, Task

    nest = parse_nest(nest_spec, barrier)
    out = _out_dir(out, force, ("compare.md", "compare.png"))
    base = {"spec": nest_spec, "barrier": barrier, "trail_width_u": trail_width_u, "visit_steps": visit_steps}
    batched = Task(
        experiment="stcvision.controllers.buffon.experiments:nest_task", params={**base, "trials": trials}, seed=seed
    )
    chunks = [
        Task(
            experiment="stcvision.controllers.buffon.experiments:pymunk_task",
            params={**base, "trials": min(PYMUNK_CHUNK_TRIALS, trials - k), "chunk": k},
            seed=seed,
        )
        for k in range(0, trials, PYMUNK_CHUNK_TRIALS)
    ]
    rep = _run_tasks([batched, *chunks], out, sweep or SweepOptions(), f"buffon compare {nest.label}")
    rb = rep.results[batched.key]
    rp = [rep.results[t.key] for t in chunks]
    nbc_b = np.array(rb["nbc"])
    nbc_p = np.concatenate([r["nbc"] for r in rp])
    mw = stats.mannwhitneyu(nbc_p, nbc_b, alternative="two-sided")
    ks = stats.ks_2samp(nbc_p, nbc_b)
    p_steps = sum(r["robot_steps"] for r in rp) / sum(r["wall_s"] for r in rp)
    res = {
        "nest": nest.spec,
        "barrier": barrier,
        "trials": trials,
        "visit_steps": visit_steps,
        "nbc_median_pymunk": float(np.median(nbc_p)),
        "nbc_median_batched": float(np.median(nbc_b)),
        "nbc_iqr_pymunk": np.percentile(nbc_p, [25, 75]).tolist(),
        "nbc_iqr_batched": np.percentile(nbc_b, [25, 75]).tolist(),
        "l1_median_pymunk": float(np.median(np.concatenate([r["l1_u"] for r in rp]))),
        "l1_median_batched": float(np.median(rb["l1_u"])),
        "mannwhitney_p": float(mw.pvalue),
        "ks_p": float(ks.pvalue),
        "agree_at_5pct": bool(min(mw.pvalue, ks.pvalue) >= 0.05),
        "escapes_pymunk": int(sum(r["escapes"] for r in rp)),
        "escapes_batched": int(rb["escapes"]),
        "robot_steps_per_s_pymunk": p_steps,
        "robot_steps_per_s_batched": rb["robot_steps"] / rb["wall_s"],
        "paths": True,
    }
    res["speed_ratio"] = res["robot_steps_per_s_batched"] / p_steps
    _compare_outputs(out, res, nbc_p, nbc_b)
    return res


def _compare_outputs(out: Path, res: dict, nbc_p, nbc_b) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for x, label in ((nbc_p, "pymunk path"), (nbc_b, "batched path")):
        ax.ecdf(x, label=f"{label} (median {np.median(x):.4f})")
    ax.set(
        xlabel="nBC",
        ylabel="fraction of trials",
        title=f"{res['nest']} {res['barrier'] or ''}: MWU p={res['mannwhitney_p']:.2f}, KS p={res['ks_p']:.2f}",
    )
    ax.legend()
    write_figure(out / "compare.png", fig, overwrite=True)
    md = ["# Batched path vs pymunk path", "", "| figure | pymunk | batched |", "|---|---:|---:|"]
    for k in ("nbc_median", "l1_median", "escapes", "robot_steps_per_s"):
        md.append(f"| {k} | {res[k + '_pymunk']:.4g} | {res[k + '_batched']:.4g} |")
    md += [
        "",
        f"Mann-Whitney U p = {res['mannwhitney_p']:.3g}; Kolmogorov-Smirnov p = {res['ks_p']:.3g} "
        f"({res['trials']} trials each, {res['visit_steps']:,} steps per visit).",
    ]
    write_bytes_atomic(out / "compare.md", "\n".join(md).encode(), overwrite=True)


# --------------------------------------------------------------------------------- calibrate
def calibrate(*, trials: int = 100, seed: int = 0) -> dict:
    """Measure the area correction on the reference nest (the shipped one stays fixed)."""
    from stcvision.controllers.buffon.estimate import area_estimates, median_ci95

    nest = parse_nest(CORRECTION_REFERENCE)
    config = VisitConfig(visit_steps=AREA_VISIT_STEPS)
    with _bar(2 * trials * config.visit_steps, "buffon calibrate") as bar:
        ts = run_trials(nest, config, trials=trials, seed=seed, progress=bar.update, threads=machine_workers())
    k = calibrate_area_correction(ts, nest.area_u2)
    per_trial = nest.area_u2 / area_estimates(ts, correction=1.0)
    ci = median_ci95(per_trial)
    return {
        "reference": nest.spec,
        "trials": trials,
        "visit_steps": config.visit_steps,
        "area_correction_measured": k,
        "ci95": ci,
        "area_correction_shipped": AREA_CORRECTION,
        "area_true": nest.area_u2,
        "escapes": ts.escapes,
        "wall_s": ts.wall_s,
        "shipped_inside_ci": bool(ci is not None and ci[0] <= AREA_CORRECTION <= ci[1]),
    }


# ------------------------------------------------------------------------------------- bench
#: repeats of the batched path's timed set in `bench` (its median is reported)
BENCH_REPEATS = 3


def bench(*, spec: str = "circle:30", seed: int = 0) -> dict:
    """Measure the robot-steps per CPU-second of the batched and the pymunk paths.

    Both paths run the same nest and behaviour one after the other in the calling thread (one
    core): the figures are robot-steps per second of that thread's CPU time
    (``time.thread_time``), which neither other processes on a shared machine nor idle worker
    threads of the numerical libraries count into; wall-clock rates beside them. The batched
    path's timed set (4 trials of two 50,000-step visits) runs :data:`BENCH_REPEATS` times
    after a warm-up (compilation, or loading numba's cache) and a garbage collection, so that
    neither the compiler nor its garbage is timed; its median is reported.
    """
    import gc

    from stcvision.controllers.buffon.pymunk_path import run_trials_pymunk

    nest = parse_nest(spec)
    run_trials(nest, VisitConfig(visit_steps=100), trials=1, seed=seed)  # compile (cached) and warm up
    gc.collect()
    cpu, wall = [], []
    for _ in range(BENCH_REPEATS):
        c0 = time.thread_time()
        ts = run_trials(nest, VisitConfig(visit_steps=PAPER_VISIT_STEPS), trials=4, seed=seed)
        cpu.append(ts.robot_steps / (time.thread_time() - c0))
        wall.append(ts.robot_steps / ts.wall_s)
    c0 = time.thread_time()
    tp = run_trials_pymunk(nest, VisitConfig(visit_steps=1500), trials=1, seed=seed)
    slow = tp.robot_steps / (time.thread_time() - c0)
    fast = float(np.median(cpu))
    return {
        "buffon_nest": spec,
        "buffon_robot_steps_per_cpu_s": fast,
        "buffon_pymunk_robot_steps_per_cpu_s": slow,
        "buffon_speedup": fast / slow,
        "buffon_robot_steps_per_s": float(np.median(wall)),
        "buffon_pymunk_robot_steps_per_s": tp.robot_steps / tp.wall_s,
    }


# ------------------------------------------------------------------------------ online rule
ONLINE_FILES = (
    "online.csv",
    "online_summary.md",
    "online_error_by_size.png",
    "online_coverage.png",
    "online_error_vs_steps.png",
)
#: fixed visit lengths set beside the online rule on the standard circle (error vs robot-steps)
FIXED_STEPS = (50_000, 100_000, 200_000, 300_000)
#: nests outside the acceptance range of 2,000-30,000 u^2 (the size sweep's ends)
SIZE_ENDS = ("circle:10", "circle:20", "circle:30", "circle:250", "circle:400")
#: trail-aware exploration beside the paper's behaviour: nests and the turn (docs/results/buffon.md,
#: "Trail-aware exploration")
TRAIL_AWARE_NESTS = ("circle:100", "square:70", "ellipse:12000:3", "circle:150")
TRAIL_TURN = 0.5
#: equal areas (u^2) at which a circle and a square are measured side by side
SHAPE_PAIR_AREAS = (2000, 5000, 10000, 20000, 30000)


def online(out: str | Path, *, trials: int = 12, seed: int = 0, sweep=None, force: bool = False) -> dict:
    """Measure the online rule: its calibration and evaluation families, the size sweep's ends.

    The online rule measured: its calibration family again, the held-out evaluation family
    (coverage of both intervals per family), the size sweep's ends, and error vs robot-steps of
    fixed lengths beside the rule on the standard circle; CSV, figures, summary.
    """
    from stcvision.controllers.buffon import online as exp
    from stcvision.controllers.buffon import report
    from stcvision.sweep import SweepOptions, Task

    out = _out_dir(out, force, ONLINE_FILES)
    base = {"trail_width_u": PAPER_TRAIL_WIDTH_U, "trials": trials}
    rows = exp.calibration_rows(exp.CALIBRATION_NESTS)
    rows += exp.evaluation_nests(out / "nests")
    rows += [{"family": "size ends", "spec": s, "barrier": None} for s in SIZE_ENDS]
    for r in rows:
        r["visit_steps"] = "auto"
    for spec in TRAIL_AWARE_NESTS:
        for beta in (0.0, TRAIL_TURN):
            rows.append({"family": f"trail turn {beta:g}", "spec": spec, "barrier": None, "visit_steps": "auto",
                         "trail_turn": beta})  # fmt: skip
    for area in SHAPE_PAIR_AREAS:
        rows.append({"family": "pair circle", "spec": f"circle:{2 * math.sqrt(area / math.pi):.6g}", "barrier": None,
                     "visit_steps": "auto", "pair_area": area})  # fmt: skip
        rows.append({"family": "pair square", "spec": f"square:{math.sqrt(area):.6g}", "barrier": None,
                     "visit_steps": "auto", "pair_area": area})  # fmt: skip
    rows += [{"family": "fixed", "spec": CORRECTION_REFERENCE, "barrier": None, "visit_steps": n} for n in FIXED_STEPS]
    rows += [{"family": "online", "spec": CORRECTION_REFERENCE, "barrier": None, "visit_steps": "auto"}]
    # appended last: the seeds of the rows above (seed + position) stay those of earlier runs
    late = exp.calibration_polygons(out / "nests") + exp.calibration_rows(exp.CALIBRATION_COMPARTMENTS)
    rows += [{**r, "visit_steps": "auto"} for r in late]
    # an online task's key carries the stopping rule's constants: a store written under another
    # rule is not resumed as if its trials were this rule's
    rule = {"stop": dataclasses.asdict(StopParams())}
    tasks = [
        Task(
            experiment="stcvision.controllers.buffon.experiments:nest_task",
            params={**base, "spec": r["spec"], "barrier": r["barrier"], "visit_steps": r["visit_steps"]}
            | ({"trail_turn": r["trail_turn"]} if r.get("trail_turn") else {})
            | (rule if r["visit_steps"] == "auto" else {}),
            seed=seed + i,
        )
        for i, r in enumerate(rows)
    ]
    t0 = time.perf_counter()
    rep = _run_tasks(tasks, out, sweep or SweepOptions(), "buffon online")
    for r, t in zip(rows, tasks, strict=True):
        res = refresh(rep.results[t.key], rep.results[t.key]["area_true"])  # this version's estimators
        r.update({k: v for k, v in res.items() if k not in ("family", "spec", "barrier", "visit_steps", "trail_turn")})
        ci = r["area_ci95"]
        r["ci_holds"] = bool(ci is not None and ci[0] <= r["area_true"] <= ci[1])
        cov = r.get("trial_ci95_coverage")
        r["trial_holds"] = int(round(cov * r["trials"])) if cov is not None else 0
    cal = exp.calibrate_online([r for r in rows if r["family"] == "calibration"])
    evaluation = [r for r in rows if r["family"] in exp.EVALUATION_FAMILIES]
    table = exp.coverage_table(evaluation)
    _write_tables(out, {"online.csv": report.online_csv(rows)}, report.online_figures(rows))
    pairs, aware = report.shape_pairs(rows), report.trail_aware(rows)
    wall = time.perf_counter() - t0
    text = report.online_summary(rows, table, cal, pairs, aware, trials=trials, wall_s=wall)
    _write_tables(out, {"online_summary.md": text}, {})
    result = {"calibration": cal, "coverage": table, "shape_pairs": pairs, "trail_aware": aware}
    return {"out": str(out), "nests": len(rows), "trials": trials, **result, "wall_s": wall,
            "sweep": rep.summary(), "claims": True, "summary_text": text}  # fmt: skip


def _write_tables(out: Path, texts: dict, figures: dict) -> None:
    """Write a folder run's text files and figures, each atomically (its store says it is ours)."""
    for name, text in texts.items():
        write_bytes_atomic(out / name, text.encode(), overwrite=True)
    for name, fig in figures.items():
        write_figure(out / name, fig, overwrite=True)
