"""Run the toolkit's main job on an embedded default: an 8x8-cell STC board with a few obstacle
cells (Board.random, seed 0); a small Lego-like robot drives sub-cell to sub-cell with timed
90-degree turns (whose angle drifts: motor gain and battery fade), switching its rear UV LEDs on
for a few seconds before every forward move (seed 003, "Marking Sub-cells"). At the end its
catadioptric camera takes a frame of the fading marks and the vision pipeline reads it.

Writes OUT/world.png (the world top-down), OUT/camera.png (the mirror image), OUT/ground.png
(the pipeline's ground view) and OUT/demo.rrd (a rerun recording of the pipeline's stages).
The closed-loop STC coverage run replaces the random walk when the controller lands.
"""

from __future__ import annotations

#: How long the UV LEDs stay on before each forward move (seed 003: "for a few seconds").
LED_ON_S = 3.0


def add_parser(p) -> None:
    p.add_argument("--out", default="out", metavar="DIR", help="output folder (default: out)")
    p.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    p.add_argument("--moves", type=int, default=60, help="sub-cell moves of the walk (default 60)")


def run(args) -> dict:
    import math
    from pathlib import Path

    import numpy as np

    from calibration.profiles import default_profile
    from sim_camera.arenas import arena_from_board
    from sim_camera.board import Board
    from sim_camera.camera import Pose, SyntheticCamera
    from sim_camera.draw import draw_world
    from sim_camera.phosphor import PhosphorLayer
    from sim_camera.robot import LEGO_STC
    from sim_camera.world import World
    from stcvision.errors import BadInputError
    from stcvision.fileio import write_image
    from stcvision.pipeline import Pipeline
    from stcvision.rr import PipelineLogger

    if args.moves < 1:
        raise BadInputError(f"--moves must be >= 1, got {args.moves}")
    out = Path(args.out)
    board = Board.random((8, 8), obstacle_fraction=0.1, rng=np.random.default_rng(0))
    world = World(arena_from_board(board), seed=args.seed)
    phosphor = PhosphorLayer()
    world.add_layer(phosphor)
    robot = world.add_robot(LEGO_STC)
    rng = world.rng()
    d = board.subcell_m
    turn_s = (math.pi / 2) / LEGO_STC.nominal_turn_rate_rad_s
    moves = blocked = 0
    for _ in range(args.moves):  # a random walk of sub-cell moves (not STC yet)
        row_heading = robot.pose[2]  # the newest row will lie across this heading
        robot.leds_on()  # charge the floor behind the robot, standing still
        world.run(int(round(LED_ON_S / world.dt_s)))
        robot.leds_off()
        robot.drive_distance(d)
        res = world.run_until_done(robot, timeout_s=10)
        moves += 1
        if res.status != "done":
            blocked += 1
            robot.drive_distance(-0.5 * d)
            world.run_until_done(robot, timeout_s=10)
        robot.rotate_for(turn_s, int(rng.choice([-1, 1])))
        world.run_until_done(robot)
    world.step()  # let the layer see the last LED switch-off
    img = draw_world(world, px_per_m=400)
    write_image(out / "world.png", img, overwrite=True)

    # the camera at the final pose, and the pipeline on its frame
    cam = SyntheticCamera()
    crng = np.random.default_rng(args.seed + 1)
    x, y, h = robot.pose
    pose = Pose(x, y, h)
    dark = cam.median_dark(16, rng=crng)
    frame = cam.render(
        pose, rng=crng, t_s=world.time_s, phosphor=phosphor, red_lights_m=board.red_lights_m(), board=board, truth=True
    )
    pipe = Pipeline(default_profile(), dark=dark)
    result = pipe.process(frame.image)
    write_image(out / "camera.png", frame.image, overwrite=True)
    write_image(out / "ground.png", pipe.ground_view(result.dark_subtracted), overwrite=True)
    logger = PipelineLogger.to_file(out / "demo.rrd", pipe)
    logger.log(result, frame=0, sim_time_s=world.time_s)
    logger.close()

    pos_err, head_err = robot.odometry.error_to(robot.pose)
    ages = phosphor.ages_s(world.time_s)
    visible = [dt for dt in frame.truth["dots"] if dt["visible"]]
    return {
        "out": str(out),
        "files": [str(out / n) for n in ("world.png", "camera.png", "ground.png", "demo.rrd")],
        "board_cells": list(board.shape_cells),
        "moves": moves,
        "blocked_moves": blocked,
        "sim_time_s": world.time_s,
        "distance_m": robot.distance_travelled_m,
        "containment_events": world.containment_events,
        "turn_rate_error_pct": 100 * (robot.true_turn_rate_rad_s(world.time_s) / LEGO_STC.nominal_turn_rate_rad_s - 1),
        "odometry_position_error_m": pos_err,
        "odometry_heading_error_deg": math.degrees(head_err),
        "dots_laid": len(phosphor),
        "dots_in_view": len(visible),
        "dots_detectable": sum(dt["detectable"] for dt in visible),
        "dots_found": result.dots.n_lit,
        "newest_mark_age_s": float(ages.min()) if len(ages) else None,
        "heading_fit_deg": math.degrees(result.heading.heading_error_rad) if result.heading.ok else None,
        # the fit sees the newest row: it measures how far the robot has turned since laying it,
        # off a multiple of 90 degrees (the seed's check after each rotation)
        "true_turn_off_90_deg": math.degrees(_fold90(h - row_heading)),
        "pipeline_ms": result.total_ms,
    }


def _fold90(a: float) -> float:
    import math

    q = math.pi / 2
    return (a + q / 2) % q - q / 2


def format_text(r: dict) -> str:
    head = f"{r['heading_fit_deg']:+.2f} deg" if r["heading_fit_deg"] is not None else "no fit"
    rows = [
        ("board", f"{r['board_cells'][0]}x{r['board_cells'][1]} cells"),
        ("moves (blocked)", f"{r['moves']} ({r['blocked_moves']})"),
        ("sim time", f"{r['sim_time_s']:.0f} s, {r['distance_m']:.2f} m driven"),
        ("turn rate off nominal", f"{r['turn_rate_error_pct']:+.1f} %"),
        (
            "odometry error",
            f"{100 * r['odometry_position_error_m']:.1f} cm, {r['odometry_heading_error_deg']:+.1f} deg",
        ),
        ("containment events", str(r["containment_events"])),
        ("UV dots laid", str(r["dots_laid"])),
        ("dots in view / detectable / found", f"{r['dots_in_view']} / {r['dots_detectable']} / {r['dots_found']}"),
        ("heading fit on the newest row", f"{head} (true: {r['true_turn_off_90_deg']:+.2f} deg)"),
        ("pipeline (one cold frame)", f"{r['pipeline_ms']:.2f} ms"),
    ]
    w = max(len(k) for k, _ in rows)
    return "\n".join(f"{k:<{w}}  {v}" for k, v in rows) + "\nwrote " + ", ".join(r["files"])
