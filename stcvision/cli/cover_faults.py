"""``stcvision cover faults``: the parser and the printing of the fault experiment
(:mod:`stcvision.controllers.stc.fault_sweep`)."""

from __future__ import annotations

from pathlib import Path


def sweep_faults(args) -> dict:
    """The ``cover faults`` action: :func:`stcvision.controllers.stc.fault_sweep.sweep_faults` with the
    command's options."""
    from stcvision.controllers.stc.fault_sweep import sweep_faults as run
    from stcvision.sweep import sweep_options_from_args

    return run(args.out, args.faults, args.runs, cells=args.cells, obstacle_fraction=args.obstacle_fraction,
               exposure=args.exposure, camera=args.camera, options=sweep_options_from_args(args),
               force=args.force)  # fmt: skip


def add_parser(sub) -> None:
    from stcvision.cli._args import positive
    from stcvision.controllers.stc.fault_sweep import LEVELS
    from stcvision.sweep import add_sweep_arguments

    s = sub.add_parser(
        "faults",
        help="outcome per hardware fault and level: a table and a plot (the fault table of the docs' STC robot page)",
        description="Run the STC robot (camera perception) with each fault of stcvision.controllers.stc.faults at the "
        "levels of LEVELS, over seeds, through the sweep runner (resumable: OUT/sweep.jsonl); write summary.md, "
        "runs.csv and faults.png. Exit 1 if any run reported success with the wrong coverage.",
    )
    s.add_argument("--faults", type=lambda t: [w for w in t.split(",") if w], default=list(LEVELS),
                   metavar="F,...", help=f"faults to run (default all: {','.join(LEVELS)})")  # fmt: skip
    s.add_argument("--cells", type=positive(int), default=6, help="board size in cells per side (default 6)")
    from stcvision.limits import MAX_FAULT_RUNS

    runs = positive(int, maximum=MAX_FAULT_RUNS, why="runs per fault level")
    s.add_argument("--runs", type=runs, default=3, help="boards (seeds 0..runs-1) per level (default 3)")
    s.add_argument("--obstacle-fraction", type=float, default=0.15, help="obstacle cells (default 0.15)")
    s.add_argument("--exposure", choices=("webcam", "auto"), default="auto", help="default auto")
    s.add_argument("--camera", default="webcam", help="camera preset or JSON file (default webcam)")
    s.add_argument("--out", required=True, metavar="DIR", help="folder for the store, the table and the plot")
    s.add_argument("--force", action="store_true", help="write into a folder that holds no fault sweep")
    s.add_argument("--json", action="store_true", help="print the result as one JSON object")
    add_sweep_arguments(s)


def format_text(r: dict) -> str:
    from stcvision.controllers.stc.fault_sweep import markdown_table

    lines = [markdown_table(r["table"]), "", r["summary"]]
    if r["files"]:
        lines.append(f"wrote {', '.join(Path(f).name for f in r['files'])} in {r['out']}")
    return "\n".join(lines)
