"""Run the toolkit's main job on an embedded default: the ant-like STC robot covers a 4x4-cell
board with obstacle cells in closed loop -- every decision from a rendered catadioptric frame
read by the vision pipeline -- on honest phosphor physics (marks fade by the afterglow law; the
camera takes a webcam frame plus a 2 s frame for the dim old marks).

Writes OUT/demo.rrd (rerun: the world, the camera stages and every decision on the sim_time and
decision timelines), OUT/coverage.png (the floor as the run left it) and prints a summary.
Existing files are kept unless --force; the exit status is 3 if the robot did not complete.
"""

from __future__ import annotations

from stcvision.cli._args import seed

#: the default board: 4x4 cells, 15 % obstacle cells (Board.random, seed 0)
DEFAULT_CELLS = (4, 4)


#: what the demo writes into --out
OUTPUTS = ("demo.rrd", "coverage.png")


def add_parser(p) -> None:
    p.add_argument("--out", default="out", metavar="DIR", help="output folder (default: out)")
    p.add_argument("--seed", type=seed, default=0, help="seed of the robot and the camera (default 0)")
    p.add_argument("--force", action="store_true", help="overwrite demo.rrd and coverage.png in --out")


def run(args) -> dict:
    import numpy as np

    from stcvision.cli.cmd_cover import run_recorded
    from stcvision.compiles import at_first_compile
    from stcvision.controllers.stc.loop import CoverConfig
    from stcvision.controllers.stc.observers import FloorPicture
    from stcvision.fileio import check_output_folder, write_image
    from stcvision.rr import check_recording_path
    from stcvision.sim_camera.board import Board
    from stcvision.warm import start_compiling_from_the_end

    # a first run compiles ~35 CPU-seconds of kernels: a second process compiles them from the
    # last while this one compiles them from the first
    at_first_compile(start_compiling_from_the_end)
    out = check_output_folder(args.out, OUTPUTS, overwrite=args.force)
    check_recording_path(out / OUTPUTS[0], overwrite=args.force)
    made = _missing_folders(out)  # made by this run: an interrupted one takes them away again
    board = Board.random(DEFAULT_CELLS, obstacle_fraction=0.15, rng=np.random.default_rng(0))
    picture = FloorPicture(board)
    cfg = CoverConfig(perception="camera", exposure="auto", seed=args.seed)
    try:
        result = run_recorded(board, cfg, out / OUTPUTS[0], observers=[picture])
        write_image(out / OUTPUTS[1], picture.image, overwrite=args.force)
    except BaseException:  # Ctrl-C, SIGTERM, an error: no empty folder left behind
        from stcvision.fileio import remove_live_temps, remove_own_temps

        remove_live_temps()
        for folder in made:  # deepest first; one that holds anything is kept
            remove_own_temps(folder)  # (a signal between a temporary's creation and its registration)
            try:
                folder.rmdir()
            except OSError:
                break
        raise
    result["files"] = [str(out / name) for name in OUTPUTS]
    return result


def _missing_folders(out):
    """``out`` and those of its parents that do not exist yet, deepest first."""
    missing = []
    for folder in (out, *out.parents):
        if folder.exists():
            break
        missing.append(folder)
    return missing


def format_text(r: dict) -> str:
    from stcvision.cli.cmd_cover import format_text as cover_text

    return cover_text(r) + "\nwrote " + ", ".join(r["files"])
