"""``stcvision cover sweep``: STC coverage over boards x seeds x exposure modes x perceptions x
camera presets.

One task is one whole run of :func:`controllers.stc.loop.run_cover` (seconds to minutes: far above
the sweep's per-task cost), run through :mod:`stcvision.sweep` (local pool or Dask cluster,
results kept in ``OUT/sweep.jsonl`` as each run ends). Run ``(N, seed S, exposure E, perception
P)`` is the board and robot of ``stcvision cover --board NxN --seed S --exposure E --perception
P``: the task draws from the run's own seed, not from the sweep's key stream, so any run of the
table can be replayed alone (with ``--rrd``).

Here, under the CLI, because it reaches into ``controllers`` and ``sim_camera`` (DESIGN.md).
"""

from __future__ import annotations

import csv
import io
import statistics
from collections.abc import Sequence
from pathlib import Path

from stcvision.errors import BadInputError

__all__ = ["cover_run", "plan", "summarise", "sweep_cover", "write_outputs"]

EXPERIMENT = "stcvision.cli.cover_sweep:cover_run"
STORE = "sweep.jsonl"
OUTPUTS = ("runs.csv", "table.csv", "summary.md", "coverage.png")
#: run_cover's result fields kept per run (runs.csv and the store hold these)
RUN_FIELDS = (
    "subcells_reachable",
    "subcells_covered",
    "subcells_covered_more_than_once",
    "finished",
    "returned_to_start",
    "abort_reason",
    "decisions",
    "decision_errors",
    "max_mark_age_read_s",
    "sim_time_s",
    "wall_s",
    "frames",
)


def cover_run(params: dict, seed) -> dict:
    """One board run (the sweep's task). ``params``: cells, seed, exposure, perception,
    obstacle_fraction, decisions_per_subcell. ``seed`` (the sweep's stream) is not used: the
    run's own ``params["seed"]`` makes it the same run as ``stcvision cover --seed``."""
    from controllers.stc.loop import CoverConfig, is_complete, run_cover
    from stcvision.cli.cmd_cover import random_board

    n = params["cells"]
    board = random_board(n, n, params["obstacle_fraction"], params["seed"])
    # a complete tour makes a few decisions per sub-cell; a robot lost in its own faded marks can
    # wander for thousands, so it is stopped at decisions_per_subcell per reachable sub-cell
    cap = params["decisions_per_subcell"] * int(board.reachable_cells().sum()) * 4
    from sim_camera import hardware

    cfg = CoverConfig(
        perception=params["perception"],
        exposure=params["exposure"],
        seed=params["seed"],
        max_decisions=cap,
        camera=hardware.load_camera(params.get("camera", "webcam")),
    )
    r = run_cover(board, cfg)
    return {**params, "complete": is_complete(r), **{k: r[k] for k in RUN_FIELDS}}


def _exposure(text: str) -> str | float:
    if text in ("webcam", "auto"):
        return text
    try:
        v = float(text)
    except ValueError:
        raise BadInputError(f"exposure {text!r} is not webcam, auto or seconds") from None
    if not 0 < v <= 60:
        raise BadInputError(f"exposure {text!r} must be in (0, 60] seconds")
    return v


def plan(
    sizes: Sequence[int],
    runs: int,
    exposures: Sequence[str],
    perceptions: Sequence[str],
    cameras: Sequence[str] = ("webcam",),
    *,
    obstacle_fraction: float = 0.15,
    decisions_per_subcell: int = 10,
):
    """The tasks, largest boards first (so the pool is not left waiting on one at the end)."""
    from stcvision.sweep import Task

    if not sizes or min(sizes) < 1:
        raise BadInputError(f"--sizes must be board sizes >= 1 cell, got {list(sizes)}")
    if runs < 1:
        raise BadInputError(f"--runs must be >= 1, got {runs}")
    from stcvision.limits import MAX_DECISIONS_PER_SUBCELL, check_board_cells, check_count

    for n in sizes:
        check_board_cells(n, n, flag="--sizes")
    check_count("--decisions-per-subcell", decisions_per_subcell, MAX_DECISIONS_PER_SUBCELL)
    if not 0 <= obstacle_fraction < 1:
        raise BadInputError(f"--obstacle-fraction must be in [0, 1), got {obstacle_fraction}")
    for p in perceptions:
        if p not in ("camera", "oracle", "ideal"):
            raise BadInputError(f"perception {p!r} is not camera, oracle or ideal")
    from sim_camera import hardware

    for c in cameras:
        hardware.load_camera(c)  # an unknown preset or a bad file: one line, exit 2
    return [
        Task(
            experiment=EXPERIMENT,
            params={
                "cells": n,
                "seed": s,
                "exposure": _exposure(e),
                "perception": p,
                "camera": c,
                "obstacle_fraction": obstacle_fraction,
                "decisions_per_subcell": decisions_per_subcell,
            },
            seed=s,
        )
        for n in sorted(set(sizes), reverse=True)
        for e in exposures
        for p in perceptions
        for c in cameras
        for s in range(runs)
    ]


def _median(v):
    return statistics.median(v) if v else None


def summarise(runs: list[dict]) -> list[dict]:
    """One row per (board size, exposure, perception, camera): complete runs, sub-cells covered, times."""
    groups: dict[tuple, list[dict]] = {}
    key = lambda r: (r["cells"], str(r["exposure"]), r["perception"], r.get("camera", "webcam"))  # noqa: E731
    for r in sorted(runs, key=lambda r: (*key(r), r["seed"])):
        groups.setdefault(key(r), []).append(r)
    rows = []
    for (n, e, p, c), rs in groups.items():
        ok = [r for r in rs if r["complete"]]
        rows.append(
            {
                "cells": n,
                "exposure": e,
                "perception": p,
                "camera": c,
                "runs": len(rs),
                "complete": len(ok),
                "subcells_reachable_mean": statistics.fmean(r["subcells_reachable"] for r in rs),
                "subcells_covered_mean": statistics.fmean(r["subcells_covered"] for r in rs),
                "covered_fraction_mean": statistics.fmean(r["subcells_covered"] / r["subcells_reachable"] for r in rs),
                "oldest_mark_read_s_median_complete": _median([r["max_mark_age_read_s"] for r in ok]),
                "sim_time_s_median": _median([r["sim_time_s"] for r in rs]),
                "wall_s_median": _median([r["wall_s"] for r in rs]),
            }
        )
    return rows


def _csv(rows: list[dict], fields: Sequence[str]) -> bytes:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(fields), extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue().encode()


def markdown_table(rows: list[dict]) -> str:
    def num(v, fmt):
        return "—" if v is None else format(v, fmt)

    out = [
        "| board (cells) | exposure | perception | camera | complete runs | sub-cells covered (mean / reachable) "
        "| oldest mark read (complete, median) | robot time (median) | wall time (median) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        out.append(
            f"| {r['cells']}x{r['cells']} | {r['exposure']} | {r['perception']} | {r['camera']} "
            f"| {r['complete']}/{r['runs']} "
            f"| {r['subcells_covered_mean']:.1f} / {r['subcells_reachable_mean']:.1f} "
            f"| {num(r['oldest_mark_read_s_median_complete'], ',.0f')} s | {num(r['sim_time_s_median'], ',.0f')} s "
            f"| {num(r['wall_s_median'], '.1f')} s |"
        )
    return "\n".join(out)


def _replay(r: dict) -> str:
    return (
        f"stcvision cover --board {r['cells']}x{r['cells']} --seed {r['seed']} --perception {r['perception']} "
        + (f"--exposure {r['exposure']}" if isinstance(r["exposure"], str) else f"--exposure-s {r['exposure']}")
        + f" --obstacle-fraction {r['obstacle_fraction']} --camera {r.get('camera', 'webcam')} --rrd run.rrd"
    )


def plot(rows: list[dict]) -> bytes:
    """PNG: complete runs and sub-cells covered vs board size, one line per exposure/perception."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    from matplotlib.ticker import MaxNLocator

    kinds = sorted({(str(r["exposure"]), r["perception"], r["camera"]) for r in rows})
    markers, styles = "osD^v<>", ("-", "--", ":", "-.")
    for i, (e, p, c) in enumerate(kinds):
        rs = sorted((r for r in rows if (str(r["exposure"]), r["perception"], r["camera"]) == (e, p, c)),
                    key=lambda r: r["cells"])  # fmt: skip
        x = [r["cells"] for r in rs]
        # overlapping lines stay visible: a marker and a dash per kind, hollow markers of decreasing size
        style = dict(marker=markers[i % 7], ls=styles[i % 4], mfc="none", ms=10 - 1.2 * (i % 5), alpha=0.85)
        a.plot(x, [r["complete"] / r["runs"] for r in rs], label=f"{p}, {c}, exposure {e}", **style)
        b.plot(x, [r["covered_fraction_mean"] for r in rs], label=f"{p}, {c}, exposure {e}", **style)
    a.set(xlabel="board size (cells per side)", ylabel="complete runs (fraction)", ylim=(-0.05, 1.05))
    b.set(xlabel="board size (cells per side)", ylabel="sub-cells covered / reachable (mean)", ylim=(-0.05, 1.05))
    a.set_title("complete tours")
    b.set_title("coverage")
    for ax in (a, b):
        ax.grid(alpha=0.3)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    b.legend(fontsize=8, loc="lower left")
    from stcvision.fileio import figure_png

    return figure_png(fig)


def write_outputs(out: Path, runs: list[dict], rows: list[dict], report_summary: str) -> list[str]:
    """runs.csv, table.csv (``rows``: :func:`summarise` of ``runs``), summary.md, coverage.png."""
    failed = [r for r in runs if not r["complete"]]
    md = [
        "# STC coverage sweep",
        "",
        "A run is complete when every reachable sub-cell was covered exactly once, the robot finished "
        "back in its start cell and (camera) made no decision the oracle would not have made "
        "(`controllers.stc.loop.is_complete`). Boards: `Board.random`, seed = run seed.",
        "",
        markdown_table(rows),
        "",
        "![coverage vs board size](coverage.png)",
        "",
        f"Sweep: {report_summary.splitlines()[0]}",
        "",
    ]
    if failed:
        md += ["## Incomplete runs (replay one with the command)", ""]
        md += [
            f"- {r['cells']}x{r['cells']} seed {r['seed']} {r['perception']} {r.get('camera', 'webcam')} "
            f"{r['exposure']}: "
            f"{r['abort_reason'] or 'incomplete'} -- `{_replay(r)}`"
            for r in failed
        ]
        md.append("")
    run_fields = ("cells", "seed", "exposure", "perception", "camera", "obstacle_fraction", "complete", *RUN_FIELDS)
    files = {
        "runs.csv": _csv(runs, run_fields),
        "table.csv": _csv(rows, list(rows[0]) if rows else ["cells"]),
        "summary.md": "\n".join(md).encode(),
        "coverage.png": plot(rows),
    }
    return write_files(out, files)


def write_files(out: Path, files: dict[str, bytes]) -> list[str]:
    """Each of ``files`` (name -> bytes) into ``out``, atomically; returns their paths."""
    from stcvision.fileio import write_bytes_atomic

    for name, data in files.items():
        write_bytes_atomic(out / name, data, overwrite=True)
    return [str(out / name) for name in files]


def sweep_cover(args) -> dict:
    """The ``cover sweep`` action: plan, run through the sweep, write the table and the plot."""
    from stcvision.sweep import output_folder, run_sweep, sweep_options_from_args

    out = Path(args.out)
    tasks = plan(  # first: a refused plan makes no folder
        args.sizes,
        args.runs,
        args.exposures,
        args.perceptions,
        args.cameras,
        obstacle_fraction=args.obstacle_fraction,
        decisions_per_subcell=args.decisions_per_subcell,
    )
    output_folder(out, OUTPUTS, store=STORE, force=args.force, what="cover sweep")
    report = run_sweep(tasks, out / STORE, sweep_options_from_args(args), desc="cover sweep")
    runs = list(report.results.values())
    rows = summarise(runs)
    files = write_outputs(out, runs, rows, report.summary()) if runs else []
    return {
        "action": "sweep",
        "out": str(out),
        "files": files,
        "table": rows,
        "tasks": report.total,
        "skipped": report.skipped,
        "failed": dict(report.failed),
        "wall_s": report.wall_s,
        "summary": report.summary(),
        "exit_code": 1 if report.failed else 0,
    }


def format_text(r: dict) -> str:
    lines = [markdown_table(r["table"]), "", r["summary"]]
    if r["files"]:
        lines.append(f"wrote {', '.join(Path(f).name for f in r['files'])} in {r['out']}")
    return "\n".join(lines)
