"""The paper's experiments: :func:`run_trial` (one seeded run from a plain dict of parameters,
JSON in and out, for a sweep runner) and :func:`reproduce` (figures, tables, summary.md).

``run_trial`` parameters (all optional): ``pattern`` "radial"|"spiral", ``petals``,
``steps_per_petal``, ``step_m``, ``spacing_m``, ``max_steps``, ``policy`` "none"|"simple"|
"improved", ``obstacles`` [[x, y, r], ...], ``patch`` [x, y, r] or None, ``odometry_noise``
bool, ``beacon`` bool, ``threshold``.
"""

from __future__ import annotations

import statistics

import numpy as np

from stcvision.controllers.search.controller import Policy, SearchConfig
from stcvision.controllers.search.metrics import summarise
from stcvision.controllers.search.patterns import RadialPattern, SpiralPattern
from stcvision.controllers.search.run import SearchScene, run_search
from stcvision.controllers.search.scenarios import FIG6_OBSTACLE, FIG7_OBSTACLE, FIG13_CAN, PAPER_PATCH
from stcvision.sim_camera.robot_sensors import CapacitiveRingParams

__all__ = [
    "DETOUR_PATTERNS",
    "DETOUR_PLACES",
    "DETOUR_SIZES_M",
    "FIGURES",
    "OUTPUTS",
    "TABLES",
    "build_run",
    "detour_obstacle",
    "detour_tasks",
    "detours",
    "reproduce",
    "row_task",
    "row_tasks",
    "run_trial",
    "table_seed",
]


def _pattern(params: dict):
    if params.get("pattern", "radial") == "radial":
        return RadialPattern(
            petals=params.get("petals", 12),
            steps_per_petal=params.get("steps_per_petal", 32),
            step_m=params.get("step_m", 0.141),
            max_steps=params.get("max_steps"),
        )
    kw = {k: params[k] for k in ("step_m", "spacing_m", "max_steps") if params.get(k) is not None}
    return SpiralPattern(**kw)


def build_run(params: dict, seed: np.random.SeedSequence, **kw):
    """Run the search ``params`` describe; the :class:`SearchRun` itself (for figures)."""
    from stcvision.controllers.search.beacon import Beacon

    scene = SearchScene(
        obstacles=tuple(tuple(map(float, o)) for o in params.get("obstacles", ())),
        patch=None if params.get("patch") is None else tuple(map(float, params["patch"])),
    )
    cfg = SearchConfig(
        pattern=_pattern(params),
        policy=Policy(params.get("policy", "improved")),
        threshold=params.get("threshold", 0.5),
    )
    return run_search(
        scene,
        cfg,
        seed=seed,
        odometry_noise=params.get("odometry_noise", True),
        beacon=Beacon() if params.get("beacon") else None,
        **kw,
    )


def run_trial(params: dict, seed: np.random.SeedSequence) -> dict:
    """One seeded run -> its metrics (JSON-serialisable)."""
    return summarise(build_run(params, seed))


_SPIRAL = {"pattern": "spiral", "max_steps": 60, "patch": list(PAPER_PATCH)}
_RADIAL = {"pattern": "radial", "petals": 12, "steps_per_petal": 32}

#: the tables of ``reproduce``: (name, title, [(row label, params), ...])
TABLES = (
    (
        "spiral_can",
        "Spiral toward the salt patch with the can in the way (Figs. 13-14; the paper: 21 moves "
        "without the can, 30 with it, odometry < 10 mm before it, ~100 mm at the patch)",
        [("no obstacle", {**_SPIRAL, "policy": "simple"})]
        + [(p, {**_SPIRAL, "policy": p, "obstacles": [list(FIG13_CAN)]}) for p in ("none", "simple", "improved")],
    ),
    (
        "spiral_shadow",
        "Spiral with an obstacle the path turns round by > 45 degrees (Figs. 7-8)",
        [(p, {**_SPIRAL, "policy": p, "obstacles": [list(FIG7_OBSTACLE)]}) for p in ("none", "simple", "improved")],
    ),
    (
        "radial_obstacle",
        "Radial flower 12 x 32 with an obstacle on its first petal (Fig. 6), no patch",
        [(p, {**_RADIAL, "policy": p, "obstacles": [list(FIG6_OBSTACLE)]}) for p in ("none", "simple", "improved")],
    ),
    (
        "beacon",
        "The beacon (beyond the paper): odometry error with and without camera fixes",
        [
            ("radial, no beacon", {**_RADIAL, "policy": "improved"}),
            ("radial, beacon", {**_RADIAL, "policy": "improved", "beacon": True}),
            ("spiral + can, no beacon", {**_SPIRAL, "policy": "improved", "obstacles": [list(FIG13_CAN)]}),
            ("spiral + can, beacon", {**_SPIRAL, "policy": "improved", "obstacles": [list(FIG13_CAN)], "beacon": True}),
        ],
    ),
)


def _ms(values) -> str:
    v = [x for x in values if x is not None]
    if not v:
        return "-"
    if len(v) == 1:
        return f"{v[0]:.3g}"
    return f"{statistics.mean(v):.3g} ± {statistics.stdev(v):.2g}"


def table_markdown(title: str, rows: list[tuple[str, list[dict]]]) -> str:
    """Mean ± sd over seeds of each row's metrics."""
    head = (
        "| case | seeds | found | steps | moves | shadow m² | unsampled (true) m² | odometry error at the end m | "
        "worst m | before the obstacle m | beacon fixes |\n|---|---|---|---|---|---|---|---|---|---|---|"
    )
    lines = [f"**{title}**", "", head]
    for label, res in rows:
        lines.append(
            f"| {label} | {len(res)} | {sum(r['found'] for r in res)}/{len(res)} | {_ms([r['steps'] for r in res])} | "
            f"{_ms([r['moves'] for r in res])} | {_ms([r['shadow_area_m2'] for r in res])} | "
            f"{_ms([r['unsampled_area_m2'] for r in res])} | "
            f"{_ms([r['odometry_error_m'] for r in res])} | {_ms([r['max_odometry_error_m'] for r in res])} | "
            f"{_ms([r['odometry_error_before_obstacle_m'] for r in res])} | {_ms([r['beacon_fixes'] for r in res])} |"
        )
    return "\n".join(lines)


#: the figures of ``reproduce`` (file names, known before any work so the output folder is
#: checked for them first)
FIGURES = (
    "fig01_radial.png",
    "fig02_density.png",
    "fig06_radial_obstacle.png",
    "fig07_spiral_simple.png",
    "fig08_spiral_improved.png",
    "fig11_spiral.png",
    "fig12_spiral_timeline.png",
    "fig13_spiral_can.png",
    "fig14_spiral_can_timeline.png",
)
#: every file ``reproduce`` writes; summary.md last (the set is complete when it is there)
OUTPUTS = (*FIGURES, "results.json", "summary.md")
STORE_NAME = "sweep.jsonl"


def cut(params: dict, max_steps: int | None) -> dict:
    """``params`` with its pattern cut at ``max_steps`` search steps (None: as they are)."""
    if max_steps is None:
        return params
    return {**params, "max_steps": min(max_steps, params.get("max_steps") or max_steps)}


def _figures(seed: np.random.SeedSequence, max_steps: int | None = None) -> dict[str, bytes]:
    """Figs. 1, 2, 6, 7, 8, 11-14 as PNG bytes (nothing is written here), in :data:`FIGURES`'
    order; the runs' patterns cut at ``max_steps``."""
    from stcvision.controllers.search.patterns import planned_points
    from stcvision.controllers.search.plots import plot_density, plot_path, plot_pattern, plot_timeline
    from stcvision.fileio import figure_png

    def png(fig):
        return figure_png(fig, bbox_inches="tight")

    fig1 = planned_points(RadialPattern(petals=12, steps_per_petal=30, step_m=12.0))
    s1, s2, s3, s4, s5 = seed.spawn(5)
    ideal = {"odometry_noise": False}
    r6 = build_run(cut({**_RADIAL, **ideal, "policy": "simple", "obstacles": [list(FIG6_OBSTACLE)]}, max_steps), s1)
    r7 = build_run(cut({**_SPIRAL, **ideal, "policy": "simple", "obstacles": [list(FIG7_OBSTACLE)]}, max_steps), s2)
    r8 = build_run(cut({**_SPIRAL, **ideal, "policy": "improved", "obstacles": [list(FIG7_OBSTACLE)]}, max_steps), s3)
    r11 = build_run(cut({**_SPIRAL, "policy": "simple"}, max_steps), s4)
    r13 = build_run(cut({**_SPIRAL, "policy": "simple", "obstacles": [list(FIG13_CAN)]}, max_steps), s5)
    pngs = (
        png(plot_pattern(fig1, "Fig. 1: radial search, 12 petals, 30 steps per petal, step 12 units")),
        png(plot_density(fig1, "Fig. 2: sampling points by distance from the centre (12 x 30)")),
        png(plot_path(r6, "Fig. 6: radial search avoiding an obstacle (simple policy, exact wheels)")),
        png(plot_path(r7, "Fig. 7: spiral, simple policy: the shadow (red) left of the obstacle")),
        png(plot_path(r8, "Fig. 8: spiral, improved policy")),
        png(plot_path(r11, "Fig. 11: TASTI 2's spiral toward the 350 mm patch (odometry noise on)")),
        png(plot_timeline(r11, "Fig. 12: tongue reading and phase (phase 1 only)", 0.5)),
        png(plot_path(r13, "Fig. 13: the spiral avoids the can")),
        png(plot_timeline(r13, "Fig. 14: tongue reading and phase during the detour", 0.5)),
    )
    return dict(zip(FIGURES, pngs, strict=True))


def table_seed(root_seed: int, index: int) -> np.random.SeedSequence:
    """Seed ``index`` of the tables' runs: the same in every row (the rows' runs are paired) and
    independent of how many seeds a reproduction asks for (more seeds reuse the runs done)."""
    return np.random.SeedSequence(root_seed, spawn_key=(1, index))


def row_task(params: dict, seed: np.random.SeedSequence) -> dict:
    """One run of one row of a table, the sweep runner's unit of work: ``params["run"]`` on seed
    ``params["seed_index"]`` of ``params["root_seed"]`` (:func:`table_seed`; the runner's
    ``seed`` is not needed). ``params["row"]`` ("table/label") is what makes two rows with the
    same parameters (e.g. the same case in two tables) two tasks."""
    return run_trial(params["run"], table_seed(params["root_seed"], params["seed_index"]))


def row_tasks(n_seeds: int, root_seed: int, max_steps: int | None = None) -> dict:
    """``{(table, label, seed_index): Task}`` of every row of :data:`TABLES` (patterns cut at
    ``max_steps``); a duplicate row id is refused here, before anything is written."""
    from stcvision.errors import BadInputError
    from stcvision.sweep import Task

    tasks = {}
    for t, _, rows in TABLES:
        for label, params in rows:
            _pattern(cut(params, max_steps))  # a bad --max-steps fails here, in one line
            for k in range(n_seeds):
                if (t, label, k) in tasks:
                    raise BadInputError(f"table {t} lists the row {label!r} twice")
                tasks[(t, label, k)] = Task(
                    experiment="stcvision.controllers.search.experiments:row_task",
                    params={
                        "row": f"{t}/{label}",
                        "run": cut(params, max_steps),
                        "seed_index": k,
                        "root_seed": root_seed,
                    },
                    seed=root_seed,
                )
    return tasks


def reproduce(
    out, *, n_seeds: int = 8, root_seed: int = 2024, sweep=None, force: bool = False, max_steps: int | None = None
) -> dict:
    """Write the figures, the tables over ``n_seeds`` seeds per row and summary.md into ``out``
    (``max_steps``: every run's pattern cut at that many search steps, a quick look; the paper's
    statements need the whole patterns).

    Everything is checked before the first file: the rows (:func:`row_tasks`) and the folder (new,
    holding none of :data:`OUTPUTS`, holding an earlier reproduction's store, or ``force``). The
    runs go through the sweep runner, one task per row and seed, into ``out/sweep.jsonl``: an
    interrupted reproduction leaves only that store and the next one resumes from it. The
    figures and tables are made in memory and written last, as one set (summary.md last)."""
    from stcvision.fileio import dumps, write_set
    from stcvision.sweep import SweepOptions, output_folder, run_sweep

    tasks = row_tasks(n_seeds, root_seed, max_steps)
    out = output_folder(out, OUTPUTS, store=STORE_NAME, force=force, what="search reproduction")
    report = run_sweep(list(tasks.values()), out / STORE_NAME, sweep or SweepOptions(), desc="search reproduce")
    report.raise_if_failed("table runs")
    results = {
        (t, label): [report.results[tasks[(t, label, k)].key] for k in range(n_seeds)]
        for t, _, rows in TABLES
        for label, _ in rows
    }
    tables = {
        t: table_markdown(title, [(label, results[(t, label)]) for label, _ in rows]) for t, title, rows in TABLES
    }
    figures = _figures(np.random.SeedSequence(root_seed).spawn(2)[0], max_steps)
    md = _summary_markdown(tables, results, list(figures), n_seeds, max_steps)
    files = {
        **figures,
        "results.json": dumps({f"{t}/{label}": runs for (t, label), runs in results.items()}).encode(),
        "summary.md": md.encode(),
    }
    write_set(out, files, overwrite=True)
    return {"out": str(out), "figures": list(figures), "summary": str(out / "summary.md"), "tables": tables,
            "sweep": report.summary(), "resumed": report.skipped}  # fmt: skip


def _summary_markdown(tables: dict, results: dict, figures: list[str], n_seeds: int, max_steps=None) -> str:
    def mean(key, t, label):
        v = [r[key] for r in results[(t, label)] if r[key] is not None]
        return statistics.mean(v) if v else float("nan")

    free_moves = mean("moves", "spiral_can", "no obstacle")
    can_moves = mean("moves", "spiral_can", "simple")
    before = mean("odometry_error_before_obstacle_m", "spiral_can", "simple")
    after = mean("odometry_error_m", "spiral_can", "simple")
    sh_s = mean("shadow_area_m2", "spiral_shadow", "simple")
    sh_i = mean("shadow_area_m2", "spiral_shadow", "improved")
    b0 = mean("odometry_error_m", "beacon", "radial, no beacon")
    b1 = mean("odometry_error_m", "beacon", "radial, beacon")
    w0 = mean("max_odometry_error_m", "beacon", "radial, no beacon")
    w1 = mean("max_odometry_error_m", "beacon", "radial, beacon")
    rows = [
        ("moves to the patch without the obstacle (Fig. 11)", "21", f"{free_moves:.1f}"),
        ("moves to the patch with the obstacle (Fig. 13)", "30", f"{can_moves:.1f}"),
        ("odometry error just before the obstacle", "< 10 mm", f"{before * 1000:.0f} mm"),
        ("odometry error at the patch after the detour", "~100 mm", f"{after * 1000:.0f} mm"),
        ("shadow area, simple vs improved (Figs. 7, 8)", "improved leaves less", f"{sh_s:.3f} vs {sh_i:.3f} m²"),
        ("beacon: odometry error at the end, radial (not in the paper)", "-", f"{b0 * 1000:.0f} -> {b1 * 1000:.0f} mm"),
        ("beacon: worst odometry error, radial", "-", f"{w0 * 1000:.0f} -> {w1 * 1000:.0f} mm"),
    ]
    lines = [
        "# TASTI 2 search: the paper's figures and statements, reproduced",
        "",
        "Paper: Russell, *TASTI 2 Searches for Chemicals in the Presence of Obstacles*. "
        "Regenerate with `stcvision search reproduce --out DIR`. Layouts: "
        "`controllers/search/scenarios.py` (the paper gives no coordinates; ours are chosen so the "
        "patch is first sampled on step 21, as in the paper). Means over "
        f"{n_seeds} seeds (the same seeds in every row).",
        "",
        *(
            [
                f"**Cut short**: every pattern stopped after {max_steps} search steps (`--max-steps`); the paper's "
                "statements hold for the whole patterns only.",
                "",
            ]
            if max_steps is not None
            else []
        ),  # fmt: skip
        "| statement | paper | here (mean) |",
        "|---|---|---|",
        *[f"| {a} | {b} | {c} |" for a, b, c in rows],
        "",
        "Figures (paths: true blue, dead-reckoned dashed green, planned dotted grey, sensing points "
        "circles, shadow red; Figs. 6-8 with exact wheels, as the paper's simulations; 11-14 with "
        "TASTI 2's wheel errors):",
        "",
        *[f"- ![{f}]({f}) `{f}`" for f in figures],
        "",
        *[tables[t] + "\n" for t, _, _ in TABLES],
        "Shadow area: the part of the pattern's intended sensing footprint (discs of step/sqrt(2) "
        "around the planned sampling points, minus the floor within a robot radius + 15 mm of an "
        "obstacle) that the executed moves did not cover (the detour's doing); unsampled (true): "
        "the same against the true sensing positions, drift included "
        "(docs/explanation/search.md, 'Shadow area').",
    ]
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------ detours
#: obstacle radii of the detour check (m): from the ring's reference can to 0.5 m, larger than
#: the robot (0.153 m) and wider than three turns of the default spiral
DETOUR_SIZES_M = (CapacitiveRingParams().reference_can_radius_m, 0.1, 0.2, 0.3, 0.4, 0.5)
#: where the obstacle stands: on the planned path at these fractions of the pattern's steps (moved
#: on along the path until it clears the start by 5 cm)
DETOUR_PLACES = (0.25, 0.5, 0.75)
#: the two patterns, cut so that one run takes seconds: three petals of the flower, 90 spiral steps
DETOUR_PATTERNS = (
    ("radial", {"pattern": "radial", "petals": 12, "steps_per_petal": 32, "max_steps": 96}),
    ("spiral", {"pattern": "spiral", "max_steps": 90}),
)
DETOUR_OUTPUTS = ("detours.png", "results.json", "summary.md")
#: the detour check's own store, so that it and a reproduction never take each other's folder
DETOUR_STORE_NAME = "detours.jsonl"
DETOUR_CLEAR_START_M = 0.05


def detour_obstacle(params: dict, radius_m: float, place: float) -> list[float]:
    """The obstacle ``[x, y, r]`` of one cell: centred on the planned point at ``place`` of the
    pattern's steps, or the first one after it that keeps ``DETOUR_CLEAR_START_M`` off the robot
    at the start."""
    from stcvision.controllers.search.patterns import planned_points
    from stcvision.sim_camera.robot import TASTI2

    pts = planned_points(_pattern(params))
    for k in range(int(place * (len(pts) - 1)), len(pts)):
        if float(np.hypot(*pts[k])) >= radius_m + TASTI2.radius_m + DETOUR_CLEAR_START_M:
            return [round(float(pts[k][0]), 4), round(float(pts[k][1]), 4), radius_m]
    raise ValueError(f"no place on the pattern clears the start for a {radius_m} m obstacle")


def detour_tasks(n_seeds: int, root_seed: int) -> dict:
    """``{(pattern, radius, place, seed_index): Task}`` of the detour check (improved policy,
    odometry noise on, no patch: a run finishes when its pattern is done)."""
    from stcvision.sweep import Task

    tasks = {}
    for name, params in DETOUR_PATTERNS:
        for r in DETOUR_SIZES_M:
            for place in DETOUR_PLACES:
                run = {**params, "policy": "improved", "obstacles": [detour_obstacle(params, r, place)]}
                for k in range(n_seeds):
                    tasks[(name, r, place, k)] = Task(
                        experiment="stcvision.controllers.search.experiments:row_task",
                        params={
                            "row": f"detours/{name}/{r}/{place}",
                            "run": run,
                            "seed_index": k,
                            "root_seed": root_seed,
                        },
                        seed=root_seed,
                    )
    return tasks


def _finished(run: dict) -> bool:
    return run["stop_reason"] == "pattern done" and run["containment_events"] == 0


def _rate(runs: list[dict]) -> tuple[int, int, float, float]:
    """Finished, runs and the exact (Clopper-Pearson) 95 % interval of the finish rate."""
    from scipy.stats import binomtest

    k, n = sum(map(_finished, runs)), len(runs)
    ci = binomtest(k, n).proportion_ci(confidence_level=0.95)
    return k, n, float(ci.low), float(ci.high)


def detours(out, *, n_seeds: int = 4, root_seed: int = 2026, sweep=None, force: bool = False) -> dict:
    """Detours round one obstacle of every size in :data:`DETOUR_SIZES_M` at every place of
    :data:`DETOUR_PLACES` on both patterns, ``n_seeds`` runs each (seeds apart from those the
    controller was developed on): how many finish their pattern, with 95 % intervals; summary.md,
    detours.png and results.json into ``out`` (checked first, resumable like :func:`reproduce`)."""
    import collections

    from stcvision.fileio import dumps, figure_png, write_set
    from stcvision.sweep import SweepOptions, output_folder, run_sweep

    tasks = detour_tasks(n_seeds, root_seed)
    out = output_folder(out, DETOUR_OUTPUTS, store=DETOUR_STORE_NAME, force=force, what="detour check")
    report = run_sweep(list(tasks.values()), out / DETOUR_STORE_NAME, sweep or SweepOptions(), desc="search detours")
    report.raise_if_failed("detour runs")
    cells = collections.defaultdict(list)
    for (name, r, place, _), task in tasks.items():
        cells[(name, r, place)].append(report.results[task.key])
    lines = [
        "# TASTI 2 detours round one obstacle of every size",
        "",
        f"Improved policy, TASTI 2's odometry noise, no patch; a run *finishes* when its pattern is done "
        f"(three petals of the 12 x 32 flower, 90 spiral steps) with no contact. {n_seeds} seeds a cell "
        f"(root seed {root_seed}, none of them used while developing the detour). Intervals: exact "
        "binomial 95 % (`scipy.stats.binomtest`). Regenerate with `stcvision search detours --out DIR`.",
        "",
        "| pattern | obstacle radius m | finished | 95 % interval | places (x, y): finished | other stops |",
        "|---|---|---|---|---|---|",
    ]
    pooled = {}
    for name, params in DETOUR_PATTERNS:
        for r in DETOUR_SIZES_M:
            runs = [x for place in DETOUR_PLACES for x in cells[(name, r, place)]]
            k, n, lo, hi = pooled[(name, r)] = _rate(runs)
            per = ", ".join(
                f"({o[0]:.2f}, {o[1]:.2f}): {sum(map(_finished, cells[(name, r, p)]))}/{len(cells[(name, r, p)])}"
                for p in DETOUR_PLACES
                for o in [detour_obstacle(params, r, p)]
            )
            stops = collections.Counter(x["stop_reason"] for x in runs if not _finished(x))
            other = "; ".join(f"{c} x {why}" for why, c in stops.items()) or "-"
            lines.append(f"| {name} | {r:g} | {k}/{n} | {lo:.2f}-{hi:.2f} | {per} | {other} |")
    k, n, lo, hi = _rate([x for v in cells.values() for x in v])
    lines += ["", f"All cells: {k}/{n} finished (95 % interval {lo:.3f}-{hi:.3f}).", "", "![detours](detours.png)"]
    files = {
        "detours.png": figure_png(_detour_figure(pooled), bbox_inches="tight"),
        "results.json": dumps({"/".join(map(str, key)): runs for key, runs in cells.items()}).encode(),
        "summary.md": ("\n".join(lines) + "\n").encode(),
    }
    write_set(out, files, overwrite=True)
    return {"out": str(out), "summary": str(out / "summary.md"), "finished": k, "runs": n, "ci95": [lo, hi],
            "sweep": report.summary(), "resumed": report.skipped}  # fmt: skip


def _detour_figure(pooled: dict):
    from stcvision.controllers.search.plots import new_figure

    fig, ax = new_figure(figsize=(6, 3.5))
    for dx, (name, _) in zip((-0.004, 0.004), DETOUR_PATTERNS, strict=True):
        rs = np.array(DETOUR_SIZES_M)
        k, n, lo, hi = (np.array(v, float) for v in zip(*(pooled[(name, r)] for r in DETOUR_SIZES_M), strict=True))
        p = k / n
        ax.errorbar(rs + dx, p, yerr=[p - lo, hi - p], fmt="o-", capsize=3, label=name)
    ax.set_xlabel("obstacle radius (m)")
    ax.set_ylabel("runs that finish their pattern")
    ax.set_ylim(-0.05, 1.05)
    ax.legend(fontsize=8)
    ax.set_title("Detours round one obstacle (improved policy, 95 % intervals)", fontsize=9)
    return fig
