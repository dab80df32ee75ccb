"""Run the TASTI 2 chemical-search robot (Russell's paper): a radial "flower" or an Archimedes spiral of
straight steps, on-the-spot turns and tongue readings, detouring round obstacles by avoid/unavoid
moves (--policy simple, improved, or none), navigating by dead reckoning; --beacon drops a
two-light red beacon at the start and corrects the odometry from the catadioptric camera
whenever the beacon is in view. Coordinates are metres relative to the start, heading 0 = +x.

`stcvision search detours --out DIR` counts how many runs finish round one obstacle of every size
(six radii, three places on each pattern, binomial intervals).

`stcvision search reproduce --out DIR` regenerates the paper's figures (1, 2, 6, 7, 8, 11-14),
a summary.md comparing with the paper's statements and the tables of shadow area and odometry
error over many seeds per policy, with and without the beacon.

`stcvision search --trajectory DIR` writes the true path and the odometry's as TUM files
(true.tum, believed.tum: the start and every move), what evo reads: evo_ape tum on them has as
its max the run's max_odometry_error_m.
"""

from __future__ import annotations

from stcvision.cli._args import seed

NESTED = False


def add_parser(p):
    import re

    from stcvision.cli._args import pair, positive
    from stcvision.limits import MAX_SEARCH_SEEDS, MAX_SEARCH_STEPS

    # "--patch -0.5,0.3,0.175": argparse takes a value starting with "-<digit>" for an option
    # unless it looks like a number; coordinates lists should read as values
    p._negative_number_matcher = re.compile(r"^-\.?\d")

    p.add_argument(
        "action",
        nargs="?",
        choices=("run", "reproduce", "detours"),
        default="run",
        help="run (default): one search; reproduce: the paper's figures and tables into --out; detours: how "
        "many runs finish round one obstacle of every size, at three places on both patterns, into --out",
    )
    p.add_argument("--pattern", choices=("radial", "spiral"), default="radial", help="search pattern (default radial)")
    p.add_argument("--petals", type=int, default=12, help="radial: petals (default 12)")
    p.add_argument("--steps-per-petal", type=int, default=32, help="radial: steps per petal n (default 32)")
    p.add_argument("--step-m", type=float, default=0.141, help="step length between sampling points (default 0.141 m)")
    p.add_argument("--spacing-m", type=float, default=None, help="spiral: distance between turns (default 0.25 m)")
    p.add_argument(
        "--max-steps",
        type=positive(int, maximum=MAX_SEARCH_STEPS, why="stcvision.limits.MAX_SEARCH_STEPS"),
        default=None,
        help="cap on search steps (spiral default 150; radial: one flower); reproduce: every run cut short",
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
    p.add_argument(
        "--seeds",
        type=positive(int, maximum=MAX_SEARCH_SEEDS, why="stcvision.limits.MAX_SEARCH_SEEDS"),
        default=None,
        help="reproduce: seeds per row of the tables (default 8); detours: seeds per cell (default 4)",
    )
    p.add_argument("--trajectory", metavar="DIR",
                   help="write the true and the odometry's paths as TUM files (true.tum, believed.tum)")  # fmt: skip
    p.add_argument(
        "--force", action="store_true", help="overwrite --rrd, --plot, --trajectory's files or files in --out"
    )
    from stcvision.sweep import add_sweep_arguments

    add_sweep_arguments(p)  # reproduce: where its rows run


def _pattern(args):
    from stcvision.controllers.search.patterns import RadialPattern, SpiralPattern

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


def run(args):
    if args.action in ("reproduce", "detours"):
        return _reproduce(args)
    import numpy as np
    from tqdm import tqdm

    from stcvision.controllers.search.controller import Policy, SearchConfig
    from stcvision.controllers.search.metrics import summarise
    from stcvision.controllers.search.run import SearchScene, check_reach, run_search

    pattern = _pattern(args)
    check_reach(pattern)
    scene = SearchScene(obstacles=tuple(args.obstacle), patch=args.patch)
    cfg = SearchConfig(pattern=pattern, policy=Policy(args.policy), threshold=args.threshold)
    _check_plot(args.plot, args.force)
    if args.trajectory:
        from stcvision.fileio import check_output_folder
        from stcvision.tum import TUM_FILES

        check_output_folder(args.trajectory, TUM_FILES, overwrite=args.force)
    if args.rrd:
        from stcvision.rr import check_recording_path

        check_recording_path(args.rrd, overwrite=args.force)
    beacon = None
    if args.beacon:
        from stcvision.controllers.search.beacon import Beacon

        beacon = Beacon()
    bar = tqdm(total=pattern.n_steps, desc="search steps", unit="step", leave=False)

    def progress(steps):
        bar.update(steps - bar.n)

    from stcvision.rr import Recordings

    with Recordings() as recs, bar:
        recorder = None
        if args.rrd:
            from stcvision.controllers.search.recorder import SearchRecorder

            recorder = recs.add(SearchRecorder(args.rrd, scene, pattern))
        result = run_search(
            scene,
            cfg,
            seed=np.random.SeedSequence(args.seed),
            odometry_noise=args.odometry_noise == "on",
            beacon=beacon,
            observer=recorder,
            progress=progress,
        )
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
    if args.trajectory:
        from stcvision.controllers.search.metrics import trajectory_files
        from stcvision.tum import write_tum_files

        write_tum_files(args.trajectory, trajectory_files(result), overwrite=args.force)
        out["trajectory"] = args.trajectory  # only when asked for: a run without it prints what it always did
    if args.plot:
        from stcvision.controllers.search.plots import plot_path, save_figure

        title = f"{pattern.describe()}, policy {args.policy}, seed {args.seed}: {result.reason}"
        save_figure(plot_path(result, title), args.plot, overwrite=True)
    return out


def _reproduce(args):
    import sys
    from pathlib import Path

    from stcvision.controllers.search.experiments import DETOUR_STORE_NAME, STORE_NAME, detours, reproduce
    from stcvision.errors import BadInputError
    from stcvision.sweep import sweep_options_from_args

    if not args.out:
        raise BadInputError(f"search {args.action} needs --out DIR")
    opts = sweep_options_from_args(args)
    store = Path(args.out) / (DETOUR_STORE_NAME if args.action == "detours" else STORE_NAME)
    if store.is_file() and not opts.fresh:
        print(
            f"stcvision search {args.action}: resuming the runs kept in {store} (--fresh starts over)", file=sys.stderr
        )
    if args.action == "detours":
        return detours(args.out, n_seeds=args.seeds or 4, sweep=opts, force=args.force)
    return reproduce(args.out, n_seeds=args.seeds or 8, sweep=opts, force=args.force, max_steps=args.max_steps)


def format_text(r):
    if "finished" in r:
        lo, hi = r["ci95"]
        return f"{r['finished']}/{r['runs']} detours finished (95 % interval {lo:.3f}-{hi:.3f}); wrote {r['summary']}"
    if "figures" in r:
        reused = f" ({r['resumed']} runs reused from the earlier run's store)" if r.get("resumed") else ""
        return f"wrote {len(r['figures'])} figures and {r['summary']}{reused}"
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
    for k in ("plot", "rrd", "trajectory"):
        if r.get(k):
            lines.append(f"wrote {r[k]}")
    return "\n".join(lines)
