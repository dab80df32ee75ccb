"""Reproduce the README's coverage table: ``python docs/cover_sweep.py`` (inside .venv).

For each board size, ``--runs`` random boards (``Board.random`` from the board stream of seed 0..runs-1, 15 %
obstacle cells, the same seeds as ``stcvision cover --board WxH --seed S``) are covered in
camera mode at webcam exposure and with exposure control, and by the physics-limited camera
(``--perception ideal``) with exposure control; a run is complete when every
reachable sub-cell is covered exactly once, the robot is back in its start cell, finished, and
made no decision the oracle would not have made. Runs go to a process pool (one whole run per
task: a run is seconds, far above any pool overhead).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor


def one_run(task: tuple[int, int, str, str]) -> dict:
    from controllers.stc.loop import CoverConfig, is_complete, run_cover, streams
    from sim_camera.board import Board

    n, seed, exposure, perception = task
    board = Board.random((n, n), obstacle_fraction=0.15, rng=streams(seed)["board"])
    # a complete tour makes a few decisions per sub-cell; a robot lost in its own faded marks can
    # wander for thousands, so stop it at ten per reachable sub-cell (it has failed long before)
    cap = 10 * 4 * int(board.reachable_cells().sum())
    r = run_cover(board, CoverConfig(perception=perception, exposure=exposure, seed=seed, max_decisions=cap))
    return {"cells": n, "seed": seed, "complete": is_complete(r), **r}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="2,3,4,5,6,7,8,10,12", help="board sizes in cells (default 2,...,8,10,12)")
    ap.add_argument("--runs", type=int, default=6, help="boards per size (default 6)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", action="store_true", help="print every run as one JSON object per line")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    kinds = (("webcam", "camera"), ("auto", "camera"), ("auto", "ideal"))
    # the longest runs first, so the pool is not left waiting on one at the end
    tasks = [(n, s, e, p) for n in sorted(sizes, reverse=True) for e, p in kinds for s in range(args.runs)]
    runs = []
    with ProcessPoolExecutor(args.workers) as ex:
        for r in ex.map(one_run, tasks):  # progress on stderr: the large boards take minutes each
            runs.append(r)
            print(
                f"[{len(runs)}/{len(tasks)}] {r['cells']}x{r['cells']} seed {r['seed']} {r['exposure']} "
                f"{r['perception']}: {'complete' if r['complete'] else r['abort_reason'] or 'incomplete'}",
                file=sys.stderr,
                flush=True,
            )
    if args.json:
        for r in runs:
            print(json.dumps(r, default=str))
        return
    print(
        "| board (cells) | webcam 1/30 s: complete runs | exposure control: complete runs "
        "| physics-limited camera (auto): complete runs "
        "| oldest mark read (auto, median) | robot time (auto, median) | wall time (auto, median) |"
    )
    print("|---|---|---|---|---|---|---|")
    for n in sizes:
        web = [r for r in runs if r["cells"] == n and r["exposure"] == "webcam"]
        auto = [r for r in runs if r["cells"] == n and r["exposure"] == "auto" and r["perception"] == "camera"]
        ideal = [r for r in runs if r["cells"] == n and r["perception"] == "ideal"]
        ok = [r["max_mark_age_read_s"] for r in auto if r["complete"]]
        age = f"{statistics.median(ok):.0f} s" if ok else "—"
        sim = statistics.median(r["sim_time_s"] for r in auto)
        wall = statistics.median(r["wall_s"] for r in auto)
        print(
            f"| {n}x{n} | {sum(r['complete'] for r in web)}/{len(web)} "
            f"| {sum(r['complete'] for r in auto)}/{len(auto)} | {sum(r['complete'] for r in ideal)}/{len(ideal)} "
            f"| {age} | {sim:,.0f} s | {wall:.1f} s |"
        )


if __name__ == "__main__":
    main()
