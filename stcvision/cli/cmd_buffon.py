"""Measure a nest's area blind, with Buffon's needle (Girgin & Sahin's method): a Khepera-sized
explorer makes two visits from the nest's central bottom, lays a pheromone trail on the first,
counts its crossings on the second; nBC = crossings / second-visit length, and the area is
A = 2 L1 L2 / (pi N) (with a dead-time and a calibrated correction; see the docs' page on the
Buffon's-needle explorer). By default the robot ends each visit itself (--visit-steps auto).
Lengths are in body lengths (u = 55 mm).

  stcvision buffon --nest circle:100 [--barrier plus:0.5] [--trials 100] [--json] [--rrd R.rrd] [--trajectory DIR]
  stcvision buffon reproduce --out DIR [--trials 100] [--workers N | --scheduler tcp://H:P]
  stcvision buffon online --out DIR [--trials 12] [--workers N]
  stcvision buffon compare --nest square:88.6 --out DIR [--trials 100] [--visit-steps 3000]
  stcvision buffon calibrate [--trials 100]

Nests: circle:DIAMETER, square:SIDE, ellipse:AREA:RATIO (r1/r2), polygon:FILE (JSON [[x, y], ...]
in body lengths). Barriers: bar:FRACTION (|) or plus:FRACTION (+) of the nest's extent, centred.
"""

from __future__ import annotations

from stcvision.cli._args import seed

NESTED = True  # --json belongs to each action


def visit_steps(text: str):
    """argparse type of ``--visit-steps``: ``auto`` or a positive integer within the cap."""
    import argparse

    from stcvision.cli._args import positive
    from stcvision.limits import MAX_BUFFON_VISIT_STEPS

    if text == "auto":
        return text
    try:
        return positive(int, maximum=MAX_BUFFON_VISIT_STEPS, why="MAX_BUFFON_VISIT_STEPS")(text)
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"{exc} (or 'auto')") from None


def add_parser(p):
    import argparse

    from stcvision.cli._args import positive
    from stcvision.limits import MAX_BUFFON_TRIALS, MAX_BUFFON_VISIT_STEPS

    p.formatter_class = argparse.RawDescriptionHelpFormatter
    sub = p.add_subparsers(dest="action", metavar="{reproduce,online,compare,calibrate}", parser_class=type(p))
    _nest_arguments(p, required=False)
    p.add_argument(
        "--visit-steps",
        type=visit_steps,
        default="auto",
        metavar="N|auto",
        help=f"steps of 0.05 s per visit, or 'auto': the robot ends each visit itself (first: when its "
        "trail covers a set share of the floor, judged from how often it meets it, and it meets it at a "
        "steady rate; second: when its crossing rate is pinned down), at most "
        f"{MAX_BUFFON_VISIT_STEPS:,} (default auto)",
    )
    p.add_argument(
        "--trials",
        type=positive(int, maximum=MAX_BUFFON_TRIALS, why="MAX_BUFFON_TRIALS"),
        default=100,
        help="independent trials (default 100)",
    )
    p.add_argument("--seed", type=seed, default=0, help="seed of every trial's streams (default 0)")
    p.add_argument("--threads", type=positive(int), metavar="N", help="threads for the trials (default: one per core)")
    p.add_argument("--rrd", metavar="OUT.rrd", help="record trial 0 in rerun (nest, trail, path, crossings, nBC)")
    p.add_argument(
        "--trajectory",
        metavar="DIR",
        help="write trial 0's true paths as TUM files (visit1.true.tum, visit2.true.tum) for evo; the "
        "explorer keeps no pose estimate, so there is no believed path",
    )
    p.add_argument("--force", action="store_true", help="overwrite --rrd and --trajectory's files")
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")
    _add_reproduce(sub)
    _add_online(sub)
    _add_compare(sub)
    _add_calibrate(sub)


def _nest_arguments(p, *, required: bool) -> None:
    from stcvision.cli._args import positive
    from stcvision.controllers.buffon.defaults import PAPER_TRAIL_WIDTH_U

    p.add_argument(
        "--nest",
        required=required,
        metavar="SPEC",
        help="circle:DIAMETER | square:SIDE | ellipse:AREA:RATIO | polygon:FILE (body lengths)",
    )
    p.add_argument("--barrier", metavar="B", help="bar:FRACTION (|) or plus:FRACTION (+), centred")
    p.add_argument(
        "--trail-width",
        type=positive(float),
        default=PAPER_TRAIL_WIDTH_U,
        metavar="W",
        help=f"pheromone trail width in body lengths (default {PAPER_TRAIL_WIDTH_U:g}, the paper's)",
    )


def _trials():
    from stcvision.cli._args import positive
    from stcvision.limits import MAX_BUFFON_TRIALS

    return positive(int, maximum=MAX_BUFFON_TRIALS, why="MAX_BUFFON_TRIALS")


def _add_reproduce(sub):
    _folder_action(
        sub,
        "reproduce",
        100,
        help="the paper's five experiment sets and trail thickness: figures, CSV, summary",
        description="Run every nest of sec. 5 (and the absolute-area set) through the sweep runner "
        "(resumable: DIR/sweep.jsonl) and write the figures, nests.csv and summary.md; then the online rule's "
        "experiments (as `buffon online`) into DIR/online.",
    )
    s = sub.choices["reproduce"]
    s.add_argument(
        "--online-trials",
        type=lambda t: 0 if t == "0" else _trials()(t),
        default=6,
        metavar="N",
        help="trials per nest of the online rule's experiments in DIR/online (default 6; 0 skips them)",
    )


def _add_online(sub):
    _folder_action(
        sub,
        "online",
        12,
        help="the online visit lengths: calibration, held-out coverage of the intervals, error vs steps",
        description="Run the online rule on its calibration family, on a held-out family of 42 nests (circles, "
        "squares, ellipses, barriers, concave and random polygons; 2,000-30,000 u^2) and on the size sweep's ends, "
        "and fixed lengths beside it on the standard circle; write online.csv, online_summary.md and figures.",
    )


def _folder_action(sub, name: str, trials: int, **texts) -> None:
    """An action that runs nests through the sweep runner into an output folder."""
    s = sub.add_parser(name, **texts)
    s.add_argument("--trials", type=_trials(), default=trials, help=f"trials per nest (default {trials})")
    _folder_run_arguments(s)


def _folder_run_arguments(s) -> None:
    """--out DIR, --seed, --force, --json and the sweep runner's options."""
    from stcvision.sweep import add_sweep_arguments

    s.add_argument("--out", required=True, metavar="DIR", help="output folder (its sweep.jsonl makes a re-run resume)")
    s.add_argument("--seed", type=seed, default=0, help="seed of the run (default 0)")
    s.add_argument("--force", action="store_true", help="write into a folder that holds other files")
    s.add_argument("--json", action="store_true", help="print the result as one JSON object")
    add_sweep_arguments(s)


def _add_compare(sub):
    from stcvision.cli._args import positive
    from stcvision.limits import MAX_PYMUNK_VISIT_STEPS

    s = sub.add_parser(
        "compare",
        help="the batched path against the pymunk path: a two-sample test of nBC",
        description="Run the same trials on the pymunk world (one Python call per step) and on the "
        "batched path and test whether their nBC distributions differ (Mann-Whitney U and "
        "Kolmogorov-Smirnov, two-sided).",
    )
    _nest_arguments(s, required=True)
    s.add_argument("--trials", type=_trials(), default=100, help="trials per path (default 100)")
    s.add_argument(
        "--visit-steps",
        type=positive(int, maximum=MAX_PYMUNK_VISIT_STEPS, why="the pymunk path runs ~3,000 steps/s"),
        default=3000,
        metavar="N",
        help="steps per visit (default 3,000: the pymunk path runs ~3,000 steps/s)",
    )
    _folder_run_arguments(s)


def _add_calibrate(sub):
    from stcvision.controllers.buffon.defaults import CORRECTION_REFERENCE

    s = sub.add_parser(
        "calibrate",
        help=f"recompute the fixed lengths' area correction on {CORRECTION_REFERENCE}",
        description="Measure A_true / median(A_dt) on the standard circle at 300,000-step visits: the factor of "
        "fixed visit lengths (held fixed; this shows where it comes from). The online rule's factor, its "
        "interval and spreads are recomputed by `buffon online` on its calibration family.",
    )
    s.add_argument("--trials", type=_trials(), default=100, help="trials (default 100)")
    s.add_argument("--seed", type=seed, default=0)
    s.add_argument("--json", action="store_true", help="print the result as one JSON object")


def run(args):
    from stcvision.controllers.buffon import run as buffon
    from stcvision.errors import BadInputError

    if args.action in ("reproduce", "compare", "online"):
        from stcvision.sweep import sweep_options_from_args

        opts = sweep_options_from_args(args)
        if args.action == "online":
            return buffon.online(args.out, trials=args.trials, seed=args.seed, sweep=opts, force=args.force)
        if args.action == "reproduce":
            return buffon.reproduce(
                args.out,
                trials=args.trials,
                seed=args.seed,
                sweep=opts,
                force=args.force,
                online_trials=args.online_trials,
            )
        return buffon.compare(
            args.nest,
            args.barrier,
            out=args.out,
            trials=args.trials,
            visit_steps=args.visit_steps,
            trail_width_u=args.trail_width,
            seed=args.seed,
            sweep=opts,
            force=args.force,
        )
    if args.action == "calibrate":
        return buffon.calibrate(trials=args.trials, seed=args.seed)
    if not args.nest:
        raise BadInputError(
            "--nest is required (e.g. --nest circle:100), or give an action: reproduce, compare, calibrate"
        )
    return buffon.measure(
        args.nest,
        args.barrier,
        trials=args.trials,
        visit_steps=args.visit_steps,
        trail_width_u=args.trail_width,
        seed=args.seed,
        rrd=args.rrd,
        threads=args.threads,
        force=args.force,
        trajectory=args.trajectory,
    )


def format_text(r: dict) -> str:
    from stcvision.controllers.buffon.run import format_text as fmt

    return fmt(r)
