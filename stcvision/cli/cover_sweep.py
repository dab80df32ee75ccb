"""``stcvision cover sweep``: the STC robot's dependability table over map files and random
boards x seeds x exposure modes x perceptions x camera presets (the experiment itself:
:mod:`stcvision.controllers.stc.experiments`)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["add_parser", "format_text", "sweep_cover"]


def add_parser(sub) -> None:
    import argparse

    from stcvision.cli._args import positive
    from stcvision.controllers.stc.experiments import OBSTACLE_FRACTION
    from stcvision.limits import MAX_DECISIONS_PER_SUBCELL
    from stcvision.sweep import add_sweep_arguments

    def words(text):
        return [t for t in text.split(",") if t]

    s = sub.add_parser(
        "sweep",
        help="dependability over maps and random boards x seeds x cameras: a table and a plot",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="""\
Run the STC robot over map files (--maps) and random boards (--sizes), each for every seed,
exposure mode, perception and camera preset, through the sweep runner (resumable:
OUT/sweep.jsonl), and write the dependability table: summary.md, table.csv, runs.csv and
dependability.png (per camera and board family: runs, complete with the rate's 95 % interval,
safely stopped by reason, unsafe, wrong decisions, sub-cells covered twice, times). Every run
not complete is listed with the 'stcvision cover' command that replays it.

  stcvision cover sweep --maps A.png,B.txt --runs 20 --cameras cooled,lowlight --out D
  stcvision cover sweep --sizes 8-22 --obstacle-fraction 0.05-0.25 --start random \\
      --seeds 100-119 --out D""",
    )
    s.add_argument("--maps", type=words, default=[], metavar="FILE,...",
                   help="map files (.txt '.', '#', 'S' or an image, one pixel a sub-cell); the start as the map "
                   "gives it or as the loader picks (unless --start random)")  # fmt: skip
    s.add_argument("--sizes", default=None, metavar="N,WxH,A-B,...",
                   help="random boards: N (N x N cells), WxH, A-B (square, the side drawn per seed from A..B) or "
                   "A-BxC-D (width and height drawn apart); default 2,...,8,10,12 when no --maps")  # fmt: skip
    seeds = s.add_mutually_exclusive_group()
    seeds.add_argument("--runs", type=int, default=None, help="seeds 0..runs-1 per board family (default 6)")
    seeds.add_argument("--seeds", default=None, metavar="A-B,...",
                       help="the seeds to run, e.g. 100-119 (held-out seeds) or 0-4,50")  # fmt: skip
    for flag, default, help_ in (
        ("--exposures", ["auto"], "exposure modes: webcam, auto or seconds (default auto, as 'stcvision cover')"),
        ("--perceptions", ["camera", "ideal"], "camera, ideal (the physics-limited camera) or oracle "
                                               "(default camera,ideal)"),
        ("--cameras", ["webcam"], "camera presets or JSON files (webcam, lowlight, cooled; default webcam)"),
    ):  # fmt: skip
        s.add_argument(flag, type=words, default=default, metavar=f"{flag[2].upper()},...", help=help_)
    s.add_argument("--obstacle-fraction", default=str(OBSTACLE_FRACTION),
                   metavar="F|A-B", help=f"obstacle cells of the random boards, or a range drawn per seed "
                   f"(default {OBSTACLE_FRACTION})")  # fmt: skip
    s.add_argument("--start", choices=("board", "random"), default="board",
                   help="board: the map's start or the loader's pick; random: any free sub-cell, drawn per seed "
                   "(default board)")  # fmt: skip
    cap = positive(int, maximum=MAX_DECISIONS_PER_SUBCELL, why="a lost robot's decisions per sub-cell")
    s.add_argument("--decisions-per-subcell", type=cap, default=10,
                   help="stop a run after this many decisions per reachable sub-cell (default 10)")  # fmt: skip
    s.add_argument("--move-log", action="store_true",
                   help="the study switch's robot, which keeps a map of where it has been (tabled apart)")  # fmt: skip
    s.add_argument("--fsm", choices=("python", "c", "firmware"), default="python",
                   help="the controller that decides every run: Python, the host-built C, or the firmware in its "
                   "emulator (default python)")  # fmt: skip
    s.add_argument("--out", required=True, metavar="DIR", help="folder for the store, the tables and the plot")
    s.add_argument("--force", action="store_true", help="overwrite tables/plot in a folder that holds no cover sweep")
    s.add_argument("--json", action="store_true", help="print the result as one JSON object")
    add_sweep_arguments(s)


def sweep_cover(args) -> dict:
    """The ``cover sweep`` action."""
    from stcvision.controllers.stc.experiments import first_seeds, parse_fraction, parse_seeds, parse_sizes, sweep
    from stcvision.sweep import sweep_options_from_args

    sizes = args.sizes if args.sizes is not None else ("" if args.maps else "2,3,4,5,6,7,8,10,12")
    seeds = parse_seeds(args.seeds) if args.seeds is not None else first_seeds(6 if args.runs is None else args.runs)
    return sweep(args.out, maps=args.maps, sizes=parse_sizes(sizes) if sizes else [], seeds=seeds,
                 exposures=args.exposures, perceptions=args.perceptions, cameras=args.cameras,
                 obstacle_fraction=parse_fraction(args.obstacle_fraction),
                 start=args.start, decisions_per_subcell=args.decisions_per_subcell, move_log=args.move_log,
                 options=sweep_options_from_args(args), force=args.force, fsm=args.fsm)  # fmt: skip


def format_text(r: dict) -> str:
    from stcvision.controllers.stc.experiments import markdown_table

    lines = [markdown_table(r["table"]), "", r["summary"]]
    if r["files"]:
        lines.append(f"wrote {', '.join(Path(f).name for f in r['files'])} in {r['out']}")
    return "\n".join(lines)
