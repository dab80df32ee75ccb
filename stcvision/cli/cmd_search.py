"""Run the TASTI 2 chemical-search robot (seed 001): a radial "flower" or an Archimedes spiral of
straight steps, on-the-spot turns and tongue readings, detouring round obstacles by avoid/unavoid
moves (--policy simple, improved, or none), navigating by dead reckoning; --beacon drops a
two-light red beacon at the start and corrects the odometry from the catadioptric camera
whenever the beacon is in view. Coordinates are metres relative to the start, heading 0 = +x.

`stcvision search reproduce --out DIR` regenerates the paper's figures (1, 2, 6, 7, 8, 11-14),
a summary.md comparing with the paper's statements and the tables of shadow area and odometry
error over many seeds per policy, with and without the beacon.
"""

from __future__ import annotations

from stcvision.cli._args import seed

NESTED = False


def add_parser(p):
    import re

    from stcvision.cli._args import pair, positive

    # "--patch -0.5,0.3,0.175": argparse takes a value starting with "-<digit>" for an option
    # unless it looks like a number; coordinates lists should read as values
    p._negative_number_matcher = re.compile(r"^-\.?\d")

    p.add_argument(
        "action",
        nargs="?",
        choices=("run", "reproduce"),
        default="run",
        help="run (default): one search; reproduce: the paper's figures and tables into --out",
    )
    p.add_argument("--pattern", choices=("radial", "spiral"), default="radial", help="search pattern (default radial)")
    p.add_argument("--petals", type=int, default=12, help="radial: petals (default 12)")
    p.add_argument("--steps-per-petal", type=int, default=32, help="radial: steps per petal n (default 32)")
    p.add_argument("--step-m", type=float, default=0.141, help="step length between sampling points (default 0.141 m)")
    p.add_argument("--spacing-m", type=float, default=None, help="spiral: distance between turns (default 0.25 m)")
    p.add_argument(
        "--max-steps", type=int, default=None, help="cap on search steps (spiral default 150; radial: one flower)"
    )
    p.add_argument("--policy", choices=("none", "simple", "improved"), default="improved", help="obstacle policy")
    p.add_argument(
        "--obstacle",
        type=pair(float, 3),
        action="extend",
        nargs="+",
        default=[],
        metavar="X,Y,R",
        help="round obstacles (metres, relative to the start): --obstacle A B or --obstacle A --obstacle B",
    )
    p.add_argument("--patch", type=pair(float, 3), metavar="X,Y,R", help="the chemical patch (metres)")
    p.add_argument(
        "--threshold",
        type=positive(float),
        default=0.5,
        help="tongue reading that ends the search (patch concentration is 1; default 0.5)",
    )
    p.add_argument(
        "--odometry-noise",
        choices=("on", "off"),
        default="on",
        help="on: TASTI 2's wheel errors (Ed, Eb, slip); off: exact wheels (encoder counts only)",
    )
    p.add_argument(
        "--beacon", action="store_true", help="drop a red two-light beacon at the start and take camera fixes"
    )
    p.add_argument("--seed", type=seed, default=0, help="seed of the robot, sensors and camera (default 0)")
    p.add_argument("--rrd", metavar="OUT.rrd", help="rerun recording of the run")
    p.add_argument("--plot", metavar="OUT.png", help="plot of the paths, sampling points and shadow")
    p.add_argument("--out", metavar="DIR", help="reproduce: output folder")
    p.add_argument("--seeds", type=int, default=8, help="reproduce: seeds per row of the tables (default 8; 10-20 min)")
    p.add_argument("--force", action="store_true", help="overwrite --rrd, --plot or files in --out")
    from stcvision.sweep import add_sweep_arguments

    add_sweep_arguments(p)  # reproduce: where its rows run


def _pattern(args):
    from controllers.search.patterns import RadialPattern, SpiralPattern

    if args.pattern == "radial":
        return RadialPattern(
            petals=args.petals, steps_per_petal=args.steps_per_petal, step_m=args.step_m, max_steps=args.max_steps
        )
    kw = {} if args.max_steps is None else {"max_steps": args.max_steps}
    return SpiralPattern(step_m=args.step_m, spacing_m=args.spacing_m, **kw)


def _check_plot(path, force):
    """Refuse, before the run, a --plot that is not a new .png file (or an existing one without --force)."""
    from pathlib import Path

    from stcvision.errors import OutputError
    from stcvision.fileio import check_output_file

    if path is None:
        return
    check_output_file(path, overwrite=force, what="plot")
    if Path(path).suffix.lower() != ".png":
        raise OutputError(f"plot {path} does not end in .png; expected OUT.png")


def _check_caps(args) -> None:
    """The counts a search command line asks for, against the caps of :mod:`stcvision.limits`."""
    from stcvision.limits import MAX_REPRODUCE_SEEDS, MAX_SEARCH_OBSTACLES, MAX_SEARCH_STEPS, check_count

    check_count("--obstacle", len(args.obstacle), MAX_SEARCH_OBSTACLES, minimum=0, why="obstacles")
    if args.action == "reproduce":
        check_count("--seeds", args.seeds, MAX_REPRODUCE_SEEDS, why="seeds per row of the tables")
        return
    for flag, v in (("--petals", args.petals), ("--steps-per-petal", args.steps_per_petal)):
        check_count(flag, v, MAX_SEARCH_STEPS, why="search steps")
    if args.max_steps is not None:
        check_count("--max-steps", args.max_steps, MAX_SEARCH_STEPS, why="search steps")
    if args.pattern == "radial" and args.max_steps is None:  # the whole flower is run
        check_count(
            "--petals x --steps-per-petal", args.petals * args.steps_per_petal, MAX_SEARCH_STEPS, why="search steps"
        )


def run(args):
    _check_caps(args)
    if args.action == "reproduce":
        return _reproduce(args)
    import numpy as np
    from tqdm import tqdm

    from controllers.search.controller import Policy, SearchConfig
    from controllers.search.metrics import summarise
    from controllers.search.run import SearchScene, run_search

    pattern = _pattern(args)
    scene = SearchScene(obstacles=tuple(args.obstacle), patch=args.patch)
    cfg = SearchConfig(pattern=pattern, policy=Policy(args.policy), threshold=args.threshold)
    _check_plot(args.plot, args.force)
    if args.rrd:
        from stcvision.rr import check_recording_path

        check_recording_path(args.rrd, overwrite=args.force)
    beacon = None
    if args.beacon:
        from controllers.search.beacon import Beacon

        beacon = Beacon()
    recorder = None
    if args.rrd:
        from controllers.search.recorder import SearchRecorder

        recorder = SearchRecorder(args.rrd, scene, pattern)
    bar = tqdm(total=pattern.n_steps, desc="search steps", unit="step", leave=False)

    def progress(steps):
        bar.update(steps - bar.n)

    try:
        result = run_search(
            scene,
            cfg,
            seed=np.random.SeedSequence(args.seed),
            odometry_noise=args.odometry_noise == "on",
            beacon=beacon,
            observer=recorder,
            progress=progress,
        )
    except BaseException:
        if recorder is not None:
            recorder.abort()
        raise
    finally:
        bar.close()
    if recorder is not None:
        recorder.close()
    out = {
        "pattern": pattern.describe(),
        "policy": args.policy,
        "seed": args.seed,
        "odometry_noise": args.odometry_noise,
        "beacon": bool(args.beacon),
        "obstacles": [list(o) for o in scene.obstacles],
        "patch": None if scene.patch is None else list(scene.patch),
        **summarise(result),
        "rrd": args.rrd,
        "plot": args.plot,
    }
    if args.plot:
        from controllers.search.plots import plot_path, save_figure

        title = f"{pattern.describe()}, policy {args.policy}, seed {args.seed}: {result.reason}"
        save_figure(plot_path(result, title), args.plot, overwrite=True)
    return out


def _reproduce(args):
    from pathlib import Path

    from controllers.search.experiments import reproduce
    from stcvision.errors import BadInputError

    if not args.out:
        raise BadInputError("search reproduce needs --out DIR")
    if args.seeds < 1:
        raise BadInputError(f"--seeds must be >= 1, got {args.seeds}")
    from stcvision.sweep import sweep_options_from_args

    out = Path(args.out)
    ours = (out / "sweep.jsonl").exists()  # an earlier (maybe interrupted) reproduction: resume it
    if out.exists() and any(out.iterdir()) and not ours and not args.force:
        from stcvision.errors import FileExistsRefusedError

        raise FileExistsRefusedError(f"{out} is not empty; refusing to overwrite it (use --force)")
    return reproduce(out, n_seeds=args.seeds, sweep=sweep_options_from_args(args))


def format_text(r):
    if "figures" in r:
        return f"wrote {len(r['figures'])} figures and {r['summary']}"
    keys = (
        "pattern",
        "policy",
        "found",
        "stop_reason",
        "steps",
        "moves",
        "blocked_moves",
        "path_length_m",
        "odometry_error_m",
        "max_odometry_error_m",
        "shadow_area_m2",
        "phase_counts",
        "beacon_fixes",
        "sim_time_s",
    )
    w = max(len(k) for k in keys)
    lines = [f"{k:<{w}}  {r[k]}" for k in keys]
    for k in ("plot", "rrd"):
        if r.get(k):
            lines.append(f"wrote {r[k]}")
    return "\n".join(lines)
