"""Run the toolkit's main job on an embedded default: an 8x8-cell STC board with a few obstacle
cells (Board.random, seed 0), a small Lego-like robot driving sub-cell to sub-cell with timed
90-degree turns (whose angle drifts: motor gain and battery fade), drawn to OUT/world.png.

(For now this exercises the simulation substrate; the STC controller and camera come later.)
"""

from __future__ import annotations


def add_parser(p) -> None:
    p.add_argument("--out", default="out", metavar="DIR", help="output folder (default: out)")
    p.add_argument("--seed", type=int, default=0, help="seed (default 0)")


def run(args) -> dict:
    import math
    from pathlib import Path

    import numpy as np

    from sim_camera.arenas import arena_from_board
    from sim_camera.board import Board
    from sim_camera.draw import draw_world
    from sim_camera.robot import LEGO_STC
    from sim_camera.world import World
    from stcvision.fileio import write_image

    board = Board.random((8, 8), obstacle_fraction=0.1, rng=np.random.default_rng(0))
    arena = arena_from_board(board)
    world = World(arena, seed=args.seed)
    robot = world.add_robot(LEGO_STC)
    rng = world.rng()
    d = board.subcell_m
    turn_s = (math.pi / 2) / LEGO_STC.nominal_turn_rate_rad_s
    moves = blocked = 0
    for _ in range(120):  # a simple random walk of sub-cell moves (not STC yet)
        robot.leds_on()
        robot.drive_distance(d)
        res = world.run_until_done(robot, timeout_s=10)
        robot.leds_off()
        moves += 1
        if res.status != "done":
            blocked += 1
            robot.drive_distance(-0.5 * d)
            world.run_until_done(robot, timeout_s=10)
        robot.rotate_for(turn_s, int(rng.choice([-1, 1])))
        world.run_until_done(robot)
    img = draw_world(world, px_per_m=400)
    path = write_image(Path(args.out) / "world.png", img, overwrite=True)
    pos_err, head_err = robot.odometry.error_to(robot.pose)
    return {
        "path": str(path),
        "board_cells": list(board.shape_cells),
        "moves": moves,
        "blocked_moves": blocked,
        "sim_time_s": world.time_s,
        "distance_m": robot.distance_travelled_m,
        "containment_events": world.containment_events,
        "turn_rate_error_pct": 100
        * (robot.true_turn_rate_rad_s(world.time_s) / LEGO_STC.nominal_turn_rate_rad_s - 1),
        "odometry_position_error_m": pos_err,
        "odometry_heading_error_deg": math.degrees(head_err),
    }


def format_text(r: dict) -> str:
    return (
        f"demo: {r['board_cells'][0]}x{r['board_cells'][1]}-cell board, {r['moves']} moves "
        f"({r['blocked_moves']} blocked), {r['distance_m']:.2f} m in {r['sim_time_s']:.0f} s; "
        f"turn rate off by {r['turn_rate_error_pct']:+.1f} %; odometry error "
        f"{100 * r['odometry_position_error_m']:.1f} cm; containment events "
        f"{r['containment_events']}\nwrote {r['path']}"
    )
