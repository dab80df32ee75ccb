"""The fault experiment (``stcvision cover faults``): the outcome of the STC robot per hardware
fault and level, through the sweep runner; its table, plot and markdown summary.

One task is one run of :func:`stcvision.controllers.stc.loop.run_cover` on the board of ``stcvision cover
--board NxN --seed S`` with one fault (:mod:`stcvision.controllers.stc.faults`), so any run of the table is
replayed alone with ``stcvision cover --board NxN --seed S --fault NAME:LEVEL``. Outcomes
(:func:`outcome`): complete; aborted with a reason, none covered twice; aborted with sub-cells
covered twice; finished with the right coverage but decision errors the referee saw; and the
one the robot must never show, finished with the wrong coverage ("wrong success").
"""

from __future__ import annotations

from pathlib import Path

from stcvision.errors import BadInputError

__all__ = ["LEVELS", "OUTCOMES", "fault_run", "markdown_table", "outcome", "plan", "sweep_faults"]

EXPERIMENT = f"{__name__}:fault_run"
STORE = "sweep.jsonl"
OUTPUTS = ("runs.csv", "summary.md", "faults.png")
#: the levels the table tries per fault: the default and a milder and/or a harsher one
LEVELS = {
    "none": (0,),
    "rate": (0.1, 0.25, 0.5),
    "led": (1, 2),
    "drop": (0.05, 0.2),
    "stray": (1.0, 5.0),
    "noise": (1.5, 3.0),
    "bump": (2.0, 4.0, 6.0),
    "slip": (2.0, 5.0, 10.0),
}
OUTCOMES = ("complete", "aborted, none twice", "aborted, some twice", "finished, decision errors", "wrong success")
RUN_FIELDS = (
    "subcells_reachable",
    "subcells_covered",
    "subcells_covered_more_than_once",
    "finished",
    "abort_reason",
    "decision_errors",
    "sim_time_s",
    "wall_s",
    "frames",
)


def outcome(r: dict) -> str:
    """Which of :data:`OUTCOMES` a :func:`run_cover` summary is."""
    if r["complete"]:
        return "complete"
    if r["abort_reason"] is not None or not r["finished"]:
        return "aborted, some twice" if r["subcells_covered_more_than_once"] else "aborted, none twice"
    right = r["subcells_covered"] == r["subcells_reachable"] and r["subcells_covered_more_than_once"] == 0
    return "finished, decision errors" if right else "wrong success"


def fault_run(params: dict, seed) -> dict:
    """One run (the sweep's task); ``seed`` (the sweep's stream) is not used: the run's own
    ``params["seed"]`` makes it the same run as ``stcvision cover --seed S --fault F:L``."""
    from stcvision.controllers.stc.experiments import random_board
    from stcvision.controllers.stc.loop import CoverConfig, is_complete, run_cover
    from stcvision.sim_camera import hardware

    n = params["cells"]
    board = random_board(n, n, params["obstacle_fraction"], params["seed"])
    faults = () if params["fault"] == "none" else ((params["fault"], float(params["level"])),)
    cfg = CoverConfig(
        exposure=params["exposure"],
        seed=params["seed"],
        camera=hardware.load_camera(params["camera"]),
        faults=faults,
        max_decisions=10 * int(board.reachable_cells().sum()) * 4,
    )
    r = run_cover(board, cfg)
    out = {**params, "complete": is_complete(r), **{k: r[k] for k in RUN_FIELDS}}
    out["outcome"] = outcome(out)
    out["fault_events"] = sum(r.get("fault_events", {}).values())
    return out


def plan(faults, runs: int, *, cells: int, obstacle_fraction: float, exposure: str, camera: str):
    from stcvision.controllers.stc.faults import FAULTS
    from stcvision.limits import MAX_FAULT_RUNS, check_board_cells, check_count
    from stcvision.sweep import Task

    check_count("--runs", runs, MAX_FAULT_RUNS, why="runs per fault level")
    check_board_cells(cells, cells, flag="--cells")
    if not 0 <= obstacle_fraction < 1:
        raise BadInputError(f"--obstacle-fraction must be in [0, 1), got {obstacle_fraction}")
    if len(set(faults)) != len(faults):
        raise BadInputError(f"--faults names a fault twice: {','.join(faults)}")
    for f in faults:
        if f not in LEVELS:
            raise BadInputError(f"fault {f!r} is not one of {', '.join(LEVELS)}")
    return [
        Task(
            experiment=EXPERIMENT,
            params={
                "fault": f,
                "level": lv if f == "none" else FAULTS[f].check(float(lv)),
                "cells": cells,
                "seed": s,
                "obstacle_fraction": obstacle_fraction,
                "exposure": exposure,
                "camera": camera,
            },
            seed=s,
        )
        for f in faults
        for lv in LEVELS[f]
        for s in range(runs)
    ]


def summarise(runs: list[dict]) -> list[dict]:
    """One row per (fault, level): how many runs ended in each outcome, and the abort reasons."""
    from stcvision.controllers.stc.experiments import stop_kind

    groups: dict[tuple, list[dict]] = {}
    order = list(LEVELS)
    for r in sorted(runs, key=lambda r: (order.index(r["fault"]), r["level"], r["seed"])):
        groups.setdefault((r["fault"], r["level"]), []).append(r)
    rows = []
    for (f, lv), rs in groups.items():
        reasons = sorted({stop_kind(r["abort_reason"]) for r in rs if r["abort_reason"]})
        counts = {o: sum(r["outcome"] == o for r in rs) for o in OUTCOMES}
        rows.append({"fault": f, "level": lv, "runs": len(rs), **counts, "abort_reasons": "; ".join(reasons)})
    return rows


def markdown_table(rows: list[dict]) -> str:
    out = ["| fault | level | runs | " + " | ".join(OUTCOMES) + " | abort reasons |"]
    out.append("|---" * (len(OUTCOMES) + 4) + "|")
    for r in rows:
        lv = "—" if r["fault"] == "none" else f"{r['level']:g}"
        out.append(f"| {r['fault']} | {lv} | {r['runs']} | " + " | ".join(str(r[o]) for o in OUTCOMES)
                   + f" | {r['abort_reasons'] or '—'} |")  # fmt: skip
    return "\n".join(out)


def plot(rows: list[dict]) -> bytes:
    """PNG: per fault and level, the runs in each outcome (stacked bars)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from stcvision.fileio import figure_png

    fig, ax = plt.subplots(figsize=(max(6.0, 0.55 * len(rows) + 2), 4.2), constrained_layout=True)
    x = np.arange(len(rows))
    base = np.zeros(len(rows))
    colours = ("#3a9a4a", "#8fb3d9", "#e0a040", "#b0b0b0", "#d03030")
    for o, c in zip(OUTCOMES, colours, strict=True):
        v = np.array([r[o] for r in rows], float)
        ax.bar(x, v, bottom=base, color=c, label=o)
        base += v
    ax.set_xticks(x, [r["fault"] if r["fault"] == "none" else f"{r['fault']}:{r['level']:g}" for r in rows],
                  rotation=60, ha="right")  # fmt: skip
    ax.set_ylabel("runs")
    from matplotlib.ticker import MaxNLocator

    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_title("STC coverage under hardware faults: outcome per fault and level")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    return figure_png(fig)


def write_outputs(out: Path, runs: list[dict], rows: list[dict], setup: dict, report_summary: str) -> list[str]:
    """runs.csv, summary.md and faults.png in ``out``; ``setup`` holds the sweep's board
    (cells, obstacle_fraction) and camera (camera, exposure)."""
    from stcvision.controllers.stc.experiments import write_csv as _csv
    from stcvision.controllers.stc.experiments import write_files

    n = setup["cells"]
    md = [
        "# STC coverage under hardware faults",
        "",
        f"Board {n}x{n} cells (`Board.random`, obstacle fraction {setup['obstacle_fraction']}, seed = run seed), "
        f"camera {setup['camera']}, exposure {setup['exposure']}, perception camera; one fault per run "
        "(`stcvision.controllers.stc.faults`). Outcomes: complete (every reachable sub-cell once, back at the start, "
        "no "
        "decision error); aborted with a specific reason; finished with the right coverage but decision errors; "
        "wrong success (finished with the wrong coverage: never allowed).",
        "",
        markdown_table(rows),
        "",
        "![outcome per fault and level](faults.png)",
        "",
        f"Sweep: {report_summary.splitlines()[0]}",
        "",
        f"Replay a run: `stcvision cover --board {n}x{n} --seed S --exposure {setup['exposure']} "
        f"--camera {setup['camera']} --fault NAME:LEVEL`",
        "",
    ]
    fields = ("fault", "level", "seed", "cells", "outcome", "fault_events", "complete", *RUN_FIELDS)
    files = {"runs.csv": _csv(runs, fields), "summary.md": "\n".join(md).encode(), "faults.png": plot(rows)}
    return write_files(out, files)


def sweep_faults(
    out,
    faults=tuple(LEVELS),
    runs: int = 3,
    *,
    cells: int = 6,
    obstacle_fraction: float = 0.15,
    exposure: str = "auto",
    camera: str = "webcam",
    options=None,
    force: bool = False,
) -> dict:
    """Plan the runs (every fault of ``faults`` at each of its :data:`LEVELS`, seeds
    ``0..runs-1``), run them through the sweep runner (``options``: a
    :class:`stcvision.sweep.SweepOptions`; resumable from ``out/sweep.jsonl``), and write the
    table and the plot into ``out``. ``exit_code`` is 1 if any run failed or finished with the
    wrong coverage."""
    from stcvision.sweep import SweepOptions, output_folder, run_sweep

    out = Path(out)
    faults = list(faults)
    tasks = plan(faults, runs, cells=cells, obstacle_fraction=obstacle_fraction, exposure=exposure, camera=camera)
    output_folder(out, OUTPUTS, store=STORE, force=force, what="cover faults sweep")  # a refused plan makes none
    report = run_sweep(tasks, out / STORE, options or SweepOptions(), desc="cover faults")
    runs_done = list(report.results.values())
    rows = summarise(runs_done)
    setup = {"cells": cells, "obstacle_fraction": obstacle_fraction, "exposure": exposure, "camera": camera}
    files = write_outputs(out, runs_done, rows, setup, report.summary()) if runs_done else []
    wrong = sum(r["wrong success"] for r in rows)
    return {
        "action": "faults",
        "out": str(out),
        "files": files,
        "table": rows,
        "tasks": report.total,
        "failed": dict(report.failed),
        "wrong_success": wrong,
        "summary": report.summary(),
        "exit_code": 1 if (report.failed or wrong) else 0,
    }
