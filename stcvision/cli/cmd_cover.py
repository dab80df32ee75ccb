"""Run the ant-like STC robot on a board until it has covered it (closed loop: camera ->
pipeline -> finite-state controller -> robot), with honest time and fading marks.

The board comes from --map (text or PNG, one pixel = one sub-cell) or --board WxH (random, with
--obstacle-fraction). --perception camera renders every observation and reads it with the
vision pipeline; oracle reads the floor's ground truth; ideal sees exactly the marks the frames
could show (the physics-limited camera, no pipeline). --exposure webcam is the seed's camera
(1/30 s); auto adds long frames sized by the robot's clock (2-30 s, then stacked 30 s frames) for
the dim old marks; or give --exposure-s X.

  stcvision cover sweep --sizes 2,3,4 --runs 6 --out DIR [--workers N | --scheduler tcp://H:P]

runs the robot over boards x seeds x exposure modes x perceptions through the sweep runner
(resumable; see README 'Scaling out') and writes a table (summary.md, table.csv, runs.csv) and a
plot (coverage.png) of complete runs and sub-cells covered vs board size.
"""

from __future__ import annotations


def add_parser(p):
    import argparse

    from stcvision.cli._args import pair

    p.formatter_class = argparse.RawDescriptionHelpFormatter  # keep the usage lines of the docstring
    # 'stcvision cover --board 4x4' stays a flat command; a leading 'sweep' is an optional sub-action
    sub = p.add_subparsers(dest="action", metavar="{sweep}", parser_class=type(p))
    _add_sweep_parser(sub)

    src = p.add_mutually_exclusive_group()
    src.add_argument("--map", metavar="FILE", help="board map: .txt ('.', '#', 'S') or .png")
    src.add_argument("--board", type=pair(int), metavar="WxH", help="random board of W x H cells (default 4x4)")
    p.add_argument("--obstacle-fraction", type=float, default=0.15, help="for --board (default 0.15)")
    p.add_argument("--start", type=pair(int), metavar="I,J", help="start sub-cell (row, column)")
    p.add_argument(
        "--perception",
        choices=("camera", "oracle", "ideal"),
        default="camera",
        help="camera: render and read every frame; oracle: the floor's ground truth; ideal: the marks the "
        "frames could show at all (the physics-limited camera, no pipeline)",
    )
    ex = p.add_mutually_exclusive_group()
    ex.add_argument("--exposure-s", type=float, metavar="X", help="fixed exposure in seconds")
    ex.add_argument(
        "--exposure",
        choices=("webcam", "auto"),
        default=None,
        help="webcam: 1/30 s (the seed's camera); auto: plus a long frame (default: auto)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the board, the robot and the camera (default 0)")
    p.add_argument("--rrd", metavar="OUT.rrd", help="rerun recording of the world, the camera stages and each decision")
    p.add_argument("--force", action="store_true", help="overwrite --rrd")


def _add_sweep_parser(sub):
    import argparse

    from stcvision.cli._args import positive
    from stcvision.sweep import add_sweep_arguments

    def ints(text):
        try:
            return [int(t) for t in text.split(",")]
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not comma-separated integers (e.g. 2,3,4)") from None

    def words(text):
        return [t for t in text.split(",") if t]

    s = sub.add_parser(
        "sweep",
        help="coverage over boards x seeds x exposure modes x perceptions: a table and a plot",
        description="Run the STC robot over random boards (sizes x seeds) for every exposure mode and "
        "perception, through the sweep runner (resumable: OUT/sweep.jsonl), and write summary.md, table.csv, "
        "runs.csv and coverage.png (complete runs and sub-cells covered vs board size).",
    )
    s.add_argument(
        "--sizes",
        type=ints,
        default=[2, 3, 4, 5, 6, 7, 8, 10, 12],
        metavar="N,N,...",
        help="board sizes in cells per side (default 2,...,8,10,12)",
    )
    s.add_argument("--runs", type=positive(int), default=6, help="boards (seeds 0..runs-1) per size (default 6)")
    for flag, default, help_ in (
        ("--exposures", ["webcam", "auto"], "exposure modes: webcam, auto or seconds (default webcam,auto)"),
        (
            "--perceptions",
            ["camera", "ideal"],
            "camera, ideal (the physics-limited camera) or oracle (default camera,ideal)",
        ),
    ):
        s.add_argument(flag, type=words, default=default, metavar=f"{flag[2].upper()},...", help=help_)
    s.add_argument("--obstacle-fraction", type=float, default=0.15, help="obstacle cells of the boards (default 0.15)")
    s.add_argument(
        "--decisions-per-subcell",
        type=positive(int),
        default=10,
        help="stop a run after this many decisions per reachable sub-cell (default 10)",
    )
    s.add_argument("--out", required=True, metavar="DIR", help="folder for the store, the tables and the plot")
    s.add_argument("--force", action="store_true", help="overwrite tables/plot in a folder that holds no cover sweep")
    s.add_argument("--json", action="store_true", help="print the result as one JSON object")
    add_sweep_arguments(s)


def random_board(w: int, h: int, obstacle_fraction: float, seed: int):
    """The random board of ``--board WxH --obstacle-fraction F --seed S`` (also the sweep's)."""
    import numpy as np

    from sim_camera.board import Board
    from stcvision.errors import BadInputError

    if w < 1 or h < 1:
        raise BadInputError(f"--board must be at least 1x1 cells, got {w}x{h}")
    if not 0 <= obstacle_fraction < 1:
        raise BadInputError(f"--obstacle-fraction must be in [0, 1), got {obstacle_fraction}")
    return Board.random((h, w), obstacle_fraction=obstacle_fraction, rng=np.random.default_rng(seed))


def load_board(args):
    from sim_camera.board import Board

    if args.map:
        return Board.from_file(args.map, start_subcell=args.start)
    w, h = args.board if args.board else (4, 4)
    board = random_board(w, h, args.obstacle_fraction, args.seed)
    if args.start:
        board = Board(board.blocked, args.start, board.subcell_m)
    return board


def run(args):
    from pathlib import Path

    if getattr(args, "action", None) == "sweep":
        from stcvision.cli.cover_sweep import sweep_cover

        return sweep_cover(args)

    from controllers.cover import CoverConfig, run_cover
    from stcvision.errors import FileExistsRefusedError

    board = load_board(args)
    exposure = args.exposure_s if args.exposure_s is not None else (args.exposure or "auto")
    if args.exposure_s is not None and not 0 < args.exposure_s <= 60:
        from stcvision.errors import BadInputError

        raise BadInputError(f"--exposure-s must be in (0, 60] seconds, got {args.exposure_s}")
    if args.rrd and Path(args.rrd).exists() and not args.force:
        raise FileExistsRefusedError(f"{args.rrd} exists; refusing to overwrite it (use --force)")
    cfg = CoverConfig(perception=args.perception, exposure=exposure, seed=args.seed)
    recorder = None
    if args.rrd:
        from controllers.cover_rr import CoverRecorder

        recorder = CoverRecorder(args.rrd, board)
    try:
        result = run_cover(board, cfg, recorder=recorder)
    finally:
        if recorder is not None:
            recorder.close()
    result["rrd"] = args.rrd
    return result


def format_text(r):
    if r.get("action") == "sweep":
        from stcvision.cli.cover_sweep import format_text as sweep_text

        return sweep_text(r)
    rows = [
        (
            "board",
            f"{r['board_cells'][0]}x{r['board_cells'][1]} cells, perception {r['perception']}, "
            f"exposure {r['exposure']}",
        ),
        ("sub-cells covered / reachable", f"{r['subcells_covered']} / {r['subcells_reachable']}"),
        ("covered more than once", str(r["subcells_covered_more_than_once"])),
        ("finished / back in start cell", f"{r['finished']} / {r['returned_to_start']}"),
        ("abort reason", str(r["abort_reason"])),
        ("moves / turns / decisions", f"{r['moves']} / {r['turns']} / {r['decisions']}"),
        ("decision errors (vs oracle)", str(r["decision_errors"])),
        ("oldest mark read", f"{r['max_mark_age_read_s']:.0f} s"),
        ("sim time / wall time", f"{r['sim_time_s']:.0f} s / {r['wall_s']:.1f} s"),
    ]
    w = max(len(k) for k, _ in rows)
    text = "\n".join(f"{k:<{w}}  {v}" for k, v in rows)
    return text + (f"\nwrote {r['rrd']}" if r.get("rrd") else "")
