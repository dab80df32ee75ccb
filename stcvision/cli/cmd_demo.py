"""Run the toolkit's main job on an embedded default: the ant-like STC robot covers a 4x4-cell
board with obstacle cells in closed loop -- every decision from a rendered catadioptric frame
read by the vision pipeline -- on honest phosphor physics (marks fade by the afterglow law; the
camera takes a webcam frame plus a 2 s frame for the dim old marks).

Writes OUT/demo.rrd (rerun: the world, the camera stages and every decision on the sim_time and
decision timelines), OUT/coverage.png (the floor as the run left it) and prints a summary.
"""

from __future__ import annotations

#: the default board: 4x4 cells, 15 % obstacle cells (Board.random, seed 0)
DEFAULT_CELLS = (4, 4)


def add_parser(p) -> None:
    p.add_argument("--out", default="out", metavar="DIR", help="output folder (default: out)")
    p.add_argument("--seed", type=int, default=0, help="seed of the robot and the camera (default 0)")


def run(args) -> dict:
    from pathlib import Path

    import numpy as np

    from controllers.stc.loop import CoverConfig, run_cover
    from controllers.stc.observers import FloorPicture
    from controllers.stc.recorder import CoverRecorder
    from sim_camera.board import Board
    from stcvision.fileio import write_image

    out = Path(args.out)
    board = Board.random(DEFAULT_CELLS, obstacle_fraction=0.15, rng=np.random.default_rng(0))
    recorder = CoverRecorder(out / "demo.rrd", board)
    picture = FloorPicture(board)
    try:
        result = run_cover(
            board, CoverConfig(perception="camera", exposure="auto", seed=args.seed), observers=[recorder, picture]
        )
    finally:
        recorder.close()
    write_image(out / "coverage.png", picture.image, overwrite=True)
    result["files"] = [str(out / "demo.rrd"), str(out / "coverage.png")]
    return result


def format_text(r: dict) -> str:
    from stcvision.cli.cmd_cover import format_text as cover_text

    return cover_text(r) + "\nwrote " + ", ".join(r["files"])
