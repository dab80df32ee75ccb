"""Build an arena or board world, drive a robot around it with the Buffon exploration
behaviour, and draw it.

The world comes from one of --arena (a JSON arena: circle, square, ellipse or polygon with
optional barriers and obstacles; see stcvision.sim_camera.arenas), --map (an STC board map, .txt or .png)
or --board WxH (a random board of W x H cells, obstacles drawn from --seed); default: a 1.1 m
circular arena. A Khepera-sized robot (55 mm) explores it laying a pheromone trail; the command
writes DIR/world.png and reports distance travelled, containment events (robot found outside
the arena; always 0 unless something is broken) and the dead-reckoning error.
"""

from __future__ import annotations

from stcvision.cli._args import pair, positive, seed
from stcvision.limits import MAX_PICTURE_PX, check_board_cells
from stcvision.limits import MAX_WORLD_STEPS as MAX_STEPS


def add_parser(p) -> None:
    src = p.add_mutually_exclusive_group()
    src.add_argument("--arena", metavar="ARENA.json", help="arena description (JSON)")
    src.add_argument("--map", metavar="MAP", help="STC board map: .txt ('.', '#', 'S') or .png")
    src.add_argument(
        "--board", metavar="WxH", type=pair(int, fmt="WxH", example="4x4"), help="random board of W x H cells"
    )
    p.add_argument(
        "--steps",
        type=positive(int, maximum=MAX_STEPS, why="about 10 minutes of wall time at ~2,000 steps/s"),
        default=4000,
        help=f"world steps of 0.05 s (default 4000, at most {MAX_STEPS:,}; a progress bar on a terminal)",
    )
    p.add_argument("--seed", type=seed, default=0, help="seed of everything random (default 0)")
    p.add_argument(
        "--px-per-m",
        type=positive(float),
        default=None,
        help=f"drawing scale (default: fit about 1000 px; the picture at most {MAX_PICTURE_PX:,} px a side)",
    )
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (world.png)")
    p.add_argument("--force", action="store_true", help="overwrite DIR/world.png")


def build_world(args):
    """(world, description) from the parsed arguments."""
    import numpy as np

    from stcvision.sim_camera.arenas import Arena, CircleArena, arena_from_board
    from stcvision.sim_camera.layers import PheromoneLayer
    from stcvision.sim_camera.robot import KHEPERA
    from stcvision.sim_camera.world import World

    if args.arena:
        arena = Arena.from_file(args.arena)
        what = f"arena {args.arena} ({arena.kind})"
    elif args.map:
        from stcvision.sim_camera.board import Board

        arena = arena_from_board(Board.from_file(args.map))
        what = f"board map {args.map}"
    elif args.board:
        from stcvision.sim_camera.board import Board

        w, h = args.board
        check_board_cells(w, h)
        rng = np.random.default_rng(np.random.SeedSequence(args.seed).spawn(1)[0])
        arena = arena_from_board(Board.random((h, w), obstacle_fraction=0.1, rng=rng))
        what = f"random board {w}x{h} cells"
    else:
        arena = CircleArena(radius_m=0.55)
        what = "default circular arena, diameter 1.1 m"
    width = 0.1 * 2 * KHEPERA.radius_m  # Buffon's needle paper sec. 4: 0.1 body length
    xmin, ymin, xmax, ymax = arena.bounds_m
    cell = max(0.5 * width, max(xmax - xmin, ymax - ymin) / 4000)
    world = World(arena, seed=args.seed, pheromone=PheromoneLayer(arena.bounds_m, width_m=width, cell_m=cell))
    return world, what


def run(args) -> dict:
    import math

    from stcvision.controllers.buffon import Explorer
    from stcvision.errors import BadInputError
    from stcvision.fileio import check_output_folder, write_image
    from stcvision.sim_camera.draw import draw_world
    from stcvision.sim_camera.robot import KHEPERA

    out = check_output_folder(args.out, ["world.png"], overwrite=args.force)
    world, what = build_world(args)
    xmin, ymin, xmax, ymax = world.arena.bounds_m
    px = args.px_per_m or min(600.0, 1000.0 / max(xmax - xmin, ymax - ymin))
    side_px = px * max(xmax - xmin, ymax - ymin)
    if side_px > MAX_PICTURE_PX:
        raise BadInputError(
            f"--px-per-m {px:g} draws the {xmax - xmin:g} x {ymax - ymin:g} m world {side_px:,.0f} px wide; "
            f"expected at most {MAX_PICTURE_PX:,} px a side"
        )
    robot = world.add_robot(KHEPERA)
    robot.nozzle_on()
    explorer = Explorer(robot, world.rng())
    _run_with_progress(world, args.steps, explorer)
    img = draw_world(world, px_per_m=px)
    path = write_image(out / "world.png", img, overwrite=args.force)
    pos_err, head_err = robot.odometry.error_to(robot.pose)
    return {
        "path": str(path),
        "world": what,
        "arena_kind": world.arena.kind,
        "area_m2": world.arena.area_m2,
        "steps": world.step_count,
        "sim_time_s": world.time_s,
        "distance_m": robot.distance_travelled_m,
        "containment_events": world.containment_events,
        "odometry_position_error_m": pos_err,
        "odometry_heading_error_deg": math.degrees(head_err),
        "pheromone_area_m2": world.pheromone.marked_area_m2,
    }


def _run_with_progress(world, steps: int, controller, chunk: int = 1000) -> None:
    """``world.run(steps, controller)`` in chunks, with a tqdm bar on a terminal (off otherwise)."""
    from tqdm import tqdm

    with tqdm(total=steps, desc="world", unit="step", unit_scale=True, disable=None, leave=False) as bar:
        done = 0
        while done < steps:
            n = min(chunk, steps - done)
            world.run(n, controller)
            done += n
            bar.update(n)


def format_text(r: dict) -> str:
    return (
        f"{r['world']}: {r['steps']} steps ({r['sim_time_s']:.0f} s), robot travelled "
        f"{r['distance_m']:.2f} m; containment events {r['containment_events']}; "
        f"odometry error {100 * r['odometry_position_error_m']:.1f} cm, "
        f"{r['odometry_heading_error_deg']:.1f} deg\nwrote {r['path']}"
    )
