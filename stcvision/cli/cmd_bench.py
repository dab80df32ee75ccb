"""Measure speed on one core: the synthetic camera's render time (640x480 with noise) and the
vision pipeline's per-frame time (all stages, and each stage). Reports medians over repeats.

Beside the pipeline, the plain-OpenCV baseline a user would build instead (stcvision.baseline:
blur, mean + 4 sigma threshold and connected components; and cv2.SimpleBlobDetector), on the same
frames in the same process, taking turns frame by frame: its ms per frame, and the recall,
precision and localisation error of pipeline and baseline on a labelled set (stcvision.versus):
by default frames rendered here from the ages recipe at a seed its tuning did not use
(--labelled-frames, --labelled-seed), or a generated dataset (--labelled DIR).

The closed loop (stcvision.controllers.stc.timing): one camera tour (--loop-board, default 22x22
cells, --loop-camera cooled, --loop-seed) timed with its frames: loop_overhead_ratio, the tour's
wall time over its frames x (median render + median pipeline time of those frames), beside the
frames' render and pipeline medians; --loop-profile N adds the cProfile table of a second tour
(its top N functions by own time). --loop-only measures the tour alone, --no-loop skips it.

--sweep measures instead the sweep runner's own cost per task (stcvision.sweep): no-op tasks
in this process, on the local pool and on a Dask cluster (--scheduler, or a LocalCluster of two
single-threaded worker processes started for the purpose).

This is the benchmark behind the performance goals (docs: Results, pipeline speed): tests never time
anything.
"""

from __future__ import annotations

from stcvision.cli._args import pair, positive, seed
from stcvision.limits import MAX_BENCH_FRAMES, MAX_BENCH_PROFILE_ROWS


def add_parser(p):
    p.add_argument(
        "--frames",
        type=positive(int, maximum=MAX_BENCH_FRAMES),
        default=200,
        metavar="N",
        help=f"frames to time (default 200, at most {MAX_BENCH_FRAMES:,})",
    )
    p.add_argument("--seed", type=seed, default=0, help="seed of the benchmark scene (default 0)")
    p.add_argument("--sweep", action="store_true", help="measure the sweep runner's cost per task instead")
    p.add_argument("--tasks", type=int, default=1000, metavar="N", help="--sweep: no-op tasks per backend (1000)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="--sweep: a Dask cluster (default: a LocalCluster)")
    loop = p.add_argument_group("the closed loop's overhead ratio (one camera tour)")
    src = loop.add_mutually_exclusive_group()
    src.add_argument("--loop-board", type=pair(int, fmt="WxH", example="22x22"), default=LOOP_BOARD, metavar="WxH",
                     help=f"the tour's random board (default {LOOP_BOARD[0]}x{LOOP_BOARD[1]})")  # fmt: skip
    src.add_argument("--loop-map", metavar="FILE", help="the tour's board from a map, as cover --map takes it")
    loop.add_argument("--loop-camera", default="cooled", metavar="NAME|FILE.json", help="its camera (default cooled)")
    loop.add_argument("--loop-seed", type=seed, default=0, metavar="S",
                      help="its seed: board, robot and camera (default 0)")  # fmt: skip
    loop.add_argument("--loop-profile", type=positive(int, maximum=MAX_BENCH_PROFILE_ROWS), metavar="N",
                      help="also profile a tour (cProfile) and print its top N functions by own time")  # fmt: skip
    which = loop.add_mutually_exclusive_group()
    which.add_argument("--loop-only", action="store_true", help="measure the tour alone")
    which.add_argument("--no-loop", action="store_true", help="skip the tour")
    g = p.add_argument_group("the labelled set of the pipeline/baseline comparison")
    g.add_argument(
        "--labelled", metavar="DIR", help="a generated dataset (default: frames rendered from the ages recipe)"
    )
    g.add_argument(
        "--labelled-frames",
        type=int,
        default=60,
        metavar="N",
        help="frames rendered from the ages recipe, spread over its groups (default 60; 0: no comparison)",
    )
    g.add_argument(
        "--labelled-seed",
        type=int,
        default=LABELLED_SEED,
        metavar="S",
        help=f"their seed (default {LABELLED_SEED}; the baseline was tuned at the recipe's own seed, 1)",
    )


#: the closed loop's tour: a 22x22-cell board, whose cooled-camera tour takes ~3,500-3,900 frames
LOOP_BOARD = (22, 22)

#: the ages recipe the labelled set is rendered from, and its held-out seed
AGES_RECIPE = "datasets/recipes/ages.json"
LABELLED_SEED = 2


def _bench_sweep(args) -> dict:
    import tempfile
    from pathlib import Path

    from stcvision.errors import StcVisionError
    from stcvision.limits import MAX_BENCH_SWEEP_TASKS, check_count
    from stcvision.sweep import SweepOptions, machine_workers
    from stcvision.sweep.selftest import measure_overhead

    check_count("--tasks", args.tasks, MAX_BENCH_SWEEP_TASKS)
    rows = []
    with tempfile.TemporaryDirectory(prefix="stcvision-bench-") as tmp:
        store = Path(tmp) / "sweep.jsonl"
        for opts in (SweepOptions(workers=1), SweepOptions(workers=max(2, machine_workers()))):
            rows.append(measure_overhead(opts, store, args.tasks))
        if args.scheduler:
            rows.append(measure_overhead(SweepOptions(scheduler=args.scheduler), store, args.tasks))
        else:
            try:
                from distributed import LocalCluster
            except ImportError:
                raise StcVisionError(
                    "--sweep needs Dask for its cluster figure: pip install 'stcvision[dask]'"
                ) from None
            with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as c:
                rows.append(measure_overhead(SweepOptions(scheduler=c.scheduler_address), store, args.tasks))
                rows[-1]["backend"] = "dask LocalCluster (2 worker processes, 1 thread each)"
    return {"sweep_overhead": rows}


def _ages_recipe(n_frames: int):
    """The repository's ages recipe with its groups scaled to ``n_frames`` frames in all."""
    from pathlib import Path

    from stcvision.datasets import parse_recipe
    from stcvision.errors import BadInputError
    from stcvision.fileio import read_json

    path = Path(__file__).resolve().parents[2] / AGES_RECIPE
    if not path.exists():
        raise BadInputError(f"{path} not found (an installed package has no recipes); give --labelled DIR")
    raw = read_json(path, what="recipe")
    total = sum(g["n"] for g in raw["groups"])
    left = n_frames
    for i, g in enumerate(raw["groups"]):
        share = left if i == len(raw["groups"]) - 1 else round(n_frames * g["n"] / total)
        g["n"] = max(0, min(share, left))
        left -= g["n"]
    raw["groups"] = [g for g in raw["groups"] if g["n"] > 0]
    return parse_recipe(raw, where=str(path))


def _labelled(args, ds=None) -> dict:
    """Pipeline and baseline on the labelled set (:func:`stcvision.versus.compare_detectors`):
    the dataset ``ds`` if given, else frames rendered from the ages recipe."""
    import tempfile

    from stcvision.calibration.profiles import default_profile
    from stcvision.datasets import open_dataset
    from stcvision.versus import compare_detectors

    if ds is not None:
        out = compare_detectors(ds, default_profile=default_profile())
        out["source"] = args.labelled
        return out
    from stcvision.datasets.render import generate
    from stcvision.sweep import SweepOptions

    recipe = _ages_recipe(args.labelled_frames)
    with tempfile.TemporaryDirectory(prefix="stcvision-bench-") as tmp:
        generate(recipe, f"{tmp}/set", seed=args.labelled_seed, options=SweepOptions(workers=1))
        out = compare_detectors(open_dataset(f"{tmp}/set"), default_profile=default_profile())
    out["source"] = f"{AGES_RECIPE}, {recipe.n_frames} frames, seed {args.labelled_seed}"
    return out


def _bench_baseline(camera, board, layer, pose, *, frames: int, seed: int, profile) -> dict:
    """ms per frame of the baseline and of the pipeline on the same rendered frames, taking turns
    (:func:`stcvision.versus.time_detectors`): a busy machine slows them alike, so the ratio holds."""
    import numpy as np

    from stcvision.versus import default_detectors, time_detectors

    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])  # not the pipeline bench's stream
    dark = camera.median_dark(8, rng=rng)
    lights = board.red_lights_m()
    imgs = [camera.render(pose, rng=rng, phosphor=layer, red_lights_m=lights).image for _ in range(8)]
    dets = {name: make(profile, dark) for name, make in default_detectors().items()}
    ms = time_detectors(dets, imgs, frames)
    return {
        "baseline_ms_per_frame": ms["baseline"],
        "baseline_blob_ms_per_frame": ms["blob"],
        "baseline_pipeline_ms_per_frame": ms["pipeline"],
        "baseline_time_ratio": ms["baseline"] / ms["pipeline"],
    }


def _median_ms(fn, n: int) -> float:
    import time

    import numpy as np

    fn()  # warm up
    times = []
    for _ in range(n):
        t0 = time.perf_counter_ns()
        fn()
        times.append(time.perf_counter_ns() - t0)
    return float(np.median(times)) / 1e6


def _bench_loop(args) -> dict:
    """The closed loop's overhead ratio on the tour the options name
    (:func:`stcvision.controllers.stc.timing.bench_loop`), and its profile with --loop-profile."""
    import argparse

    from stcvision.cli.cmd_cover import load_board
    from stcvision.controllers.stc.loop import CoverConfig
    from stcvision.controllers.stc.timing import bench_loop, profile_loop
    from stcvision.limits import check_board_cells
    from stcvision.sim_camera import hardware

    if args.loop_map is None:
        check_board_cells(*args.loop_board, flag="--loop-board")
    where = argparse.Namespace(map=args.loop_map, board=args.loop_board, seed=args.loop_seed, obstacle_fraction=None,
                               start=None, subcell_m=None, resolution=None)  # fmt: skip
    board = load_board(where)
    cfg = CoverConfig(seed=args.loop_seed, camera=hardware.load_camera(args.loop_camera))
    out = bench_loop(board, cfg)
    if args.loop_map:
        out["loop_map"] = args.loop_map
    if args.loop_profile:
        out["loop_profile"] = profile_loop(board, cfg, top=args.loop_profile)
    return out


def run(args):
    if args.sweep:
        return _bench_sweep(args)
    if args.loop_only:
        return _bench_loop(args)
    import cv2
    import numpy as np

    from stcvision.errors import BadInputError
    from stcvision.sim_camera.camera import Pose, SyntheticCamera

    if args.frames < 1:
        raise BadInputError(f"--frames must be >= 1, got {args.frames}")
    from stcvision.limits import MAX_BENCH_LABELLED_FRAMES, check_count

    check_count("--labelled-frames", args.labelled_frames, MAX_BENCH_LABELLED_FRAMES, minimum=0)
    if args.labelled_seed < 0:
        raise BadInputError(f"--labelled-seed must be >= 0, got {args.labelled_seed}")
    labelled = None
    if args.labelled:  # a bad folder is refused before the minutes of timing, not after
        from stcvision.datasets import open_dataset

        labelled = open_dataset(args.labelled)
    cv2.setNumThreads(1)
    from stcvision.sim_camera import scenarios

    board, layer, pose = scenarios.benchmark_scene(args.seed)
    cam = SyntheticCamera()
    rng = np.random.default_rng(args.seed)
    lights = board.red_lights_m()
    render_ms = _median_ms(lambda: cam.render(pose, rng=rng, phosphor=layer, red_lights_m=lights), args.frames)
    # the same scene from a new pose every frame (a dataset; a robot on the move): no projection reused
    moving = iter([Pose(pose.x_m + 1e-3 * k, pose.y_m, pose.heading_rad) for k in range(args.frames + 1)])
    moving_ms = _median_ms(lambda: cam.render(next(moving), rng=rng, phosphor=layer, red_lights_m=lights), args.frames)
    result = {
        "frame_size_px": [cam.optics.width_px, cam.optics.height_px],
        "dots_on_floor": len(layer),
        "render_ms_per_frame": render_ms,
        "render_moving_ms_per_frame": moving_ms,
        "render_frames_per_s": 1000.0 / render_ms,
        "threads": 1,
    }
    from stcvision.controllers.buffon.run import bench as bench_buffon

    result.update(bench_buffon(seed=args.seed))
    try:
        from stcvision.pipeline import bench_pipeline
    except ImportError:
        return result
    from stcvision.calibration.profiles import default_profile

    profile = default_profile()
    result.update(bench_pipeline(cam, board, layer, pose, frames=args.frames, rng=rng, profile=profile))
    result.update(_bench_baseline(cam, board, layer, pose, frames=args.frames, seed=args.seed, profile=profile))
    if args.labelled or args.labelled_frames:
        result["labelled"] = _labelled(args, labelled)
    if not args.no_loop:
        result.update(_bench_loop(args))
    return result


def _loop_text(r) -> list[str]:
    """The closed loop's lines of the text table."""
    if r["loop_overhead_ratio"] is None:
        return [f"closed loop: the tour took no frames ({r['loop_wall_s']:.1f} s)"]
    w, h = r["loop_board_cells"]
    lines = [
        f"closed loop, {w}x{h} cells, {r['loop_camera']} camera, seed {r['loop_seed']}: "
        f"{r['loop_wall_s']:.1f} s for {r['loop_frames']} frames ({1e3 * r['loop_wall_s'] / r['loop_frames']:.2f} "
        f"ms a frame; complete {r['loop_complete']})",
        f"  its frames: render {r['loop_render_ms_median']:.2f} ms, pipeline {r['loop_pipeline_ms_median']:.2f} ms "
        f"(medians; means {r['loop_render_ms_mean']:.2f} and {r['loop_pipeline_ms_mean']:.2f})",
        f"  loop overhead ratio {r['loop_overhead_ratio']:.3f} (wall / (frames x (median render + median "
        f"pipeline))), {r['loop_overhead_ratio_cpu']:.3f} on CPU time; the frames' own time is "
        f"{100 * r['loop_frame_share']:.1f} % of the wall time, {100 * r['loop_frame_cpu_share']:.1f} % of the "
        "CPU time",
        "  pipeline stages (medians, ms): " + ", ".join(f"{k} {v:.3f}" for k, v in r["loop_stage_ms_median"].items()),
    ]
    if "loop_profile" in r:
        lines.append(r["loop_profile"])
    return lines


def format_text(r):
    if "sweep_overhead" in r:
        return "\n".join(
            f"sweep, {x['backend']}: {x['ms_per_task']:.2f} ms per no-op task ({x['tasks']} tasks in "
            f"{x['wall_s']:.2f} s, store writes and pool start-up / client connection included)"
            for x in r["sweep_overhead"]
        )
    if "render_ms_per_frame" not in r:  # --loop-only
        return "\n".join(_loop_text(r))
    lines = [
        f"render: {r['render_ms_per_frame']:.2f} ms/frame ({r['render_frames_per_s']:.0f} frames/s), "
        f"{r['frame_size_px'][0]}x{r['frame_size_px'][1]} with noise, {r['dots_on_floor']} dots on the floor, 1 thread"
    ]
    if "render_moving_ms_per_frame" in r:
        lines.append(f"render from a new pose every frame: {r['render_moving_ms_per_frame']:.2f} ms/frame")
    if "buffon_robot_steps_per_cpu_s" in r:
        lines.append(
            f"buffon ({r['buffon_nest']}): batched {r['buffon_robot_steps_per_cpu_s']:,.0f} robot-steps per CPU-second "
            f"({r['buffon_robot_steps_per_s']:,.0f} per wall-clock second), pymunk "
            f"{r['buffon_pymunk_robot_steps_per_cpu_s']:,.0f} per CPU-second ({r['buffon_speedup']:.0f}x), one thread"
        )
    if "pipeline_ms_per_frame" in r:
        lines.append(f"pipeline: {r['pipeline_ms_per_frame']:.3f} ms/frame (median, all stages, 1 thread)")
        for k, v in r["stage_ms"].items():
            lines.append(f"  {k:<16s} {v:.3f} ms")
    if "baseline_ms_per_frame" in r:
        lines.append(
            f"baseline (plain OpenCV): {r['baseline_ms_per_frame']:.3f} ms/frame, SimpleBlobDetector "
            f"{r['baseline_blob_ms_per_frame']:.3f} ms/frame, against the pipeline's "
            f"{r['baseline_pipeline_ms_per_frame']:.3f} on the same frames, taking turns "
            f"({r['baseline_time_ratio']:.2f}x the pipeline's time)"
        )
    if "labelled" in r:
        from stcvision.versus import format_comparison

        lines.append(f"pipeline and baseline on {r['labelled']['source']}:")
        lines.append(format_comparison(r["labelled"]))
    if "loop_overhead_ratio" in r:
        lines += _loop_text(r)
    return "\n".join(lines)
