"""Run the ant-like STC robot on a board until it has covered it (closed loop: camera ->
pipeline -> finite-state controller -> robot), with honest time and fading marks.

The board comes from --map (text: '.', '#', 'S' per sub-cell; a ROS map_server YAML with its
image at its resolution; an image map at --resolution M_PER_PX, or one pixel per sub-cell without
it) or --board WxH (random, with --obstacle-fraction). --subcell-m is the robot's footprint, the
board's sub-cell side (default: the camera profile's); a map's sub-cell is free only where the
whole footprint is. --perception camera renders every observation and reads it with the
vision pipeline; oracle reads the floor's ground truth; ideal sees exactly the marks the frames
could show (the physics-limited camera, no pipeline). --exposure webcam is the STC paper's camera
(1/30 s); auto adds long frames sized by the robot's clock (2-30 s, then stacked 30 s frames) for
the dim old marks; or give --exposure-s X.

Exit status: 0 when the robot completed the board (every reachable sub-cell exactly once, back
in its start cell), 3 when it ran but did not (aborted, covered a sub-cell twice, not back: see
abort_reason), 2 for bad input.

  stcvision cover plan --map M --camera C [--robot R]
  stcvision cover sweep [--maps FILE,...] [--sizes N,A-B,...] --runs 6 | --seeds A-B --out DIR
                        [--workers N | --scheduler tcp://H:P]
  stcvision cover faults --out DIR [--cells 6 --runs 3 --faults rate,led,...]
  stcvision cover --fault NAME[:LEVEL] ...   (--list-faults)
  stcvision cover --board 3x3 --trajectory DIR [--trace FILE.jsonl] [--force]

--trajectory DIR writes the robot's true and believed paths as TUM files (true.tum,
believed.tum: the robot's clock, x, y, z 0, the heading as a quaternion; one pose at the start
and one after every forward move), which evo reads: evo_ape tum DIR/true.tum DIR/believed.tum
gives as its max the run's max_position_error_m. --trace FILE.jsonl writes one JSON line per
decision and per look (the observation, the decision, the true and believed pose, the frames
taken, the referee's verdict; the schema is the docs' reference page). Both are written when
the run ends, atomically; existing files are refused without --force.

plan says what the tour needs of the camera, from the physics-limited camera (exposure auto):
does it converge, how long, the oldest mark it reads, the frame lengths it uses. sweep runs the
robot over map files and random boards x seeds x exposure modes x perceptions x cameras through
the sweep runner (resumable; see the docs, Scaling out) and writes the dependability table
(summary.md, table.csv, runs.csv) and its plot (dependability.png).
"""

from __future__ import annotations

from stcvision.cli._args import seed
from stcvision.controllers.stc.experiments import OBSTACLE_FRACTION


def add_parser(p):
    import argparse

    p.formatter_class = argparse.RawDescriptionHelpFormatter  # keep the usage lines of the docstring
    # 'stcvision cover --board 4x4' stays a flat command; a leading 'plan' or 'sweep' is a sub-action
    sub = p.add_subparsers(dest="action", metavar="{plan,sweep,faults}", parser_class=type(p))
    from stcvision.cli.cover_sweep import add_parser as add_sweep_parser

    add_sweep_parser(sub)
    from stcvision.cli.cover_faults import add_parser as add_faults_parser

    add_faults_parser(sub)
    plan = sub.add_parser(
        "plan",
        help="what the tour needs of the camera, from the physics-limited camera",
        description="Does the tour converge with this camera and robot, how long does it take, the oldest mark "
        "it must read, the frame lengths it uses (the physics-limited camera, exposure auto; seconds).",
    )
    add_board_arguments(plan)
    _add_hardware_arguments(plan)
    plan.add_argument("--json", action="store_true", help="print the result as one JSON object")
    add_board_arguments(p)
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
        # (the default is CoverConfig's, not imported here to keep --help fast; a test holds
        # this text to it)
        help="webcam: 1/30 s (the STC paper's camera); auto: plus a long frame (default: auto)",
    )
    _add_hardware_arguments(p)
    p.add_argument(
        "--fault",
        action="append",
        default=[],
        metavar="NAME[:LEVEL]",
        help="inject a hardware fault (repeatable): rate, led, drop, stray, noise, bump, slip; --list-faults for "
        "what each LEVEL means, its default and range",
    )
    p.add_argument(
        "--fsm",
        choices=("python", "c", "firmware"),
        default="python",
        help="the controller that decides: python (the reference), c (the portable C built here by cc), firmware "
        "(that C built for a microcontroller, in its emulator, over the serial protocol; --mcu)",
    )
    p.add_argument("--mcu", default=None, metavar="NAME", help="--fsm firmware: the microcontroller")
    p.add_argument("--move-log", action="store_true",
                   help="a study switch: keep beside the count of moves a map of every cell entered and row laid, "
                   "and check the camera's readings against it (the ant-like robot keeps no such map)")  # fmt: skip
    p.add_argument("--list-faults", action="store_true", help="list the faults with their LEVEL meaning and range")
    p.add_argument("--list-cameras", action="store_true", help="list the camera presets with their sources")
    p.add_argument("--list-robots", action="store_true", help="list the robot presets with their sources")
    p.add_argument("--rrd", metavar="OUT.rrd", help="rerun recording of the world, the camera stages and each decision")
    p.add_argument("--trajectory", metavar="DIR",
                   help="write the robot's true and believed paths there as TUM files (true.tum, believed.tum: "
                   "timestamp x y z qx qy qz qw, what evo reads)")  # fmt: skip
    p.add_argument("--trace", metavar="FILE.jsonl",
                   help="write one JSON line per decision and per look: the observation, the decision, the true "
                   "and believed pose, the frames, the referee's verdict")  # fmt: skip
    p.add_argument("--force", action="store_true", help="overwrite --rrd, --trajectory's files and --trace")


def add_board_arguments(p) -> None:
    from stcvision.cli._args import pair

    src = p.add_mutually_exclusive_group()
    src.add_argument(
        "--map", metavar="FILE", help="board map: .txt ('.', '#', 'S'), a ROS map_server .yaml, or an image"
    )
    src.add_argument(
        "--board",
        type=pair(int, fmt="WxH", example="4x4"),
        metavar="WxH",
        help="random board of W x H cells (default 4x4)",
    )
    p.add_argument(
        "--obstacle-fraction", type=float, default=None, help=f"for --board only (default {OBSTACLE_FRACTION})"
    )
    p.add_argument(
        "--start", type=pair(int, fmt="I,J", example="1,2"), metavar="I,J", help="start sub-cell (row, column)"
    )
    p.add_argument("--seed", type=seed, default=0, help="seed of the board, the robot and the camera (default 0)")
    from stcvision.cli._args import positive
    from stcvision.limits import MAX_CALIBRATION_SUBCELL_M

    p.add_argument(
        "--subcell-m",
        type=positive(float, maximum=MAX_CALIBRATION_SUBCELL_M),
        metavar="M",
        help="the robot's footprint: the board's sub-cell side in metres (default: the camera profile's, 0.16)",
    )
    p.add_argument(
        "--resolution",
        type=positive(float),
        metavar="M_PER_PX",
        help="an image --map's resolution, metres per pixel (without it one pixel is one sub-cell)",
    )


def _add_hardware_arguments(p) -> None:
    p.add_argument(
        "--camera",
        default="webcam",
        metavar="NAME|FILE.json",
        help="camera preset (webcam, lowlight, cooled; --list-cameras) or a camera JSON file (default webcam)",
    )
    p.add_argument("--robot", default="lego", metavar="NAME|FILE.json", help="robot preset (lego) or a robot JSON file")


def load_board(args):
    from stcvision.controllers.stc.experiments import random_board
    from stcvision.errors import BadInputError
    from stcvision.sim_camera.board import Board

    subcell_m = args.subcell_m
    if subcell_m is None:  # the footprint the camera's profile is calibrated for
        from stcvision.calibration.profiles import default_profile

        subcell_m = default_profile().subcell_m
    if args.map:
        if args.obstacle_fraction is not None:
            raise BadInputError("--obstacle-fraction is for a random --board; a --map has its obstacles drawn in it")
        board = Board.from_file(args.map, start_subcell=args.start, subcell_m=subcell_m, m_per_px=args.resolution)
        from stcvision.controllers.stc.experiments import check_map_board

        check_map_board(board, args.map)
        return board
    if args.resolution is not None:
        raise BadInputError("--resolution is for an image --map; a random --board has no pixels")
    w, h = args.board if args.board else (4, 4)
    fraction = OBSTACLE_FRACTION if args.obstacle_fraction is None else args.obstacle_fraction
    board = random_board(w, h, fraction, args.seed, subcell_m)
    if args.start:
        board = Board(board.blocked, args.start, board.subcell_m)
    return board


def run(args):

    if args.action == "sweep":
        from stcvision.cli.cover_sweep import sweep_cover

        return sweep_cover(args)
    if args.action == "faults":
        from stcvision.cli.cover_faults import sweep_faults

        return sweep_faults(args)

    from stcvision.controllers.stc.loop import CoverConfig
    from stcvision.sim_camera import hardware

    if getattr(args, "list_cameras", False):
        return [hardware.camera_to_dict(c) for c in hardware.CAMERAS.values()]
    if getattr(args, "list_robots", False):
        return [hardware.robot_to_dict(r) for r in hardware.ROBOTS.values()]
    if getattr(args, "list_faults", False):
        from stcvision.controllers.stc.faults import fault_table

        return fault_table()
    camera, robot = hardware.load_camera(args.camera), hardware.load_robot(args.robot)
    board = load_board(args)
    if args.action == "plan":
        from stcvision.controllers.stc.plan import plan

        return plan(board, CoverConfig(seed=args.seed, camera=camera, robot=robot))
    # no option given: the library's own default (CoverConfig), so that the command and
    # run_cover(board) with no options are one run
    exposure = args.exposure_s if args.exposure_s is not None else (args.exposure or CoverConfig.exposure)
    if args.exposure_s is not None and not 0 < args.exposure_s <= 60:
        from stcvision.errors import BadInputError

        raise BadInputError(f"--exposure-s must be in (0, 60] seconds, got {args.exposure_s}")
    if args.rrd:
        from stcvision.rr import check_recording_path

        check_recording_path(args.rrd, overwrite=args.force)
    from stcvision.controllers.stc.faults import Faults, parse_fault

    if args.mcu and args.fsm != "firmware":
        from stcvision.errors import BadInputError

        raise BadInputError("--mcu names the chip of --fsm firmware")
    faults = tuple(parse_fault(f) for f in args.fault)
    Faults(faults, args.seed, args.perception)  # a fault twice or one the perception has no frames for: exit 2
    cfg = CoverConfig(perception=args.perception, exposure=exposure, seed=args.seed, camera=camera, robot=robot,
                      faults=faults, move_log=args.move_log, fsm=args.fsm, mcu=args.mcu)  # fmt: skip
    outputs = _check_outputs(args, board)
    result = run_recorded(board, cfg, args.rrd, outputs.observers, perception_hook=outputs.attach)
    result["rrd"] = args.rrd
    outputs.write(result, overwrite=args.force)
    return result


class _Outputs:
    """The run's --trajectory and --trace observers, and their files written when it ends."""

    def __init__(self, args, board):
        from stcvision.controllers.stc.paths import JsonTrace, PathLog

        self.args = args
        self.paths = PathLog(board) if args.trajectory else None
        self.trace = JsonTrace(board) if args.trace else None
        self.observers = [o for o in (self.paths, self.trace) if o is not None]

    def attach(self, perception) -> None:
        if self.trace is not None:
            self.trace.attach(perception)

    def write(self, result: dict, *, overwrite: bool) -> None:
        # the keys appear only with their options: a run without them prints what it always did
        from stcvision.controllers.stc.paths import write_trace
        from stcvision.tum import write_tum_files

        if self.paths is not None:
            write_tum_files(self.args.trajectory, self.paths.tum(), overwrite=overwrite)
            result["trajectory"] = self.args.trajectory
        if self.trace is not None:
            write_trace(self.args.trace, self.trace, overwrite=overwrite)
            result["trace"] = self.args.trace


def _check_outputs(args, board) -> _Outputs:
    """Refuse, before the run, --trajectory and --trace files that exist (without --force) or cannot be made."""
    from stcvision.fileio import check_output_file, check_output_folder
    from stcvision.tum import TUM_FILES

    if args.trajectory:
        check_output_folder(args.trajectory, TUM_FILES, overwrite=args.force)
    if args.trace:
        check_output_file(args.trace, overwrite=args.force, what="trace")
    return _Outputs(args, board)


def run_recorded(board, cfg, rrd, observers=(), perception_hook=None) -> dict:
    """:func:`stcvision.controllers.stc.recorder.run_cover_recorded` and the command's exit status: 0 when
    the robot completed the board, else :data:`~stcvision.cli.EXIT_INCOMPLETE` (3)."""
    from stcvision.cli import EXIT_INCOMPLETE, EXIT_OK
    from stcvision.controllers.stc.recorder import run_cover_recorded

    result = run_cover_recorded(board, cfg, rrd, observers, perception_hook=perception_hook)
    result["exit_code"] = EXIT_OK if result["complete"] else EXIT_INCOMPLETE
    return result


def _fault_events(r: dict) -> str:
    return ", ".join(f"{f} ({n})" for f, n in zip(r["faults"], r["fault_events"].values(), strict=True))


def format_text(r):
    if isinstance(r, dict) and r.get("action") == "faults":
        from stcvision.cli.cover_faults import format_text as faults_text

        return faults_text(r)
    if isinstance(r, dict) and r.get("action") == "sweep":
        from stcvision.cli.cover_sweep import format_text as sweep_text

        return sweep_text(r)
    if isinstance(r, list) and r and r[0].get("kind") == "fault":  # --list-faults
        return "\n".join(
            f"{f['name']:6s} LEVEL {f['meaning']}: default {f['default']:g}, range {f['range']}"
            + (" (--perception camera)" if f["camera_only"] else "")
            for f in r
        )
    if isinstance(r, list):  # --list-cameras / --list-robots
        out = []
        for p in r:
            figs = p.get(
                "sensor", {k: v for k, v in p.items() if k not in ("schema_version", "kind", "name", "sources")}
            )
            out.append(f"{p['name']}: " + ", ".join(f"{k} {v}" for k, v in figs.items() if k != "description"))
            out += [f"    {k}: {v}" for k, v in p["sources"].items()]
        return "\n".join(out)
    if "converges" in r:  # cover plan
        sizes = ", ".join(f"{f['frame_s']:g} s x {f['count']}" for f in r["frames"])
        return "\n".join(
            [
                f"board {r['board_cells'][0]}x{r['board_cells'][1]} cells (W x H), camera {r['camera']}, "
                f"robot {r['robot']}",
                f"converges: {r['converges']}" + ("" if r["converges"] else f" ({r['abort_reason'] or 'incomplete'})"),
                f"sub-cells covered / reachable: {r['subcells_covered']} / {r['subcells_reachable']}",
                f"tour: {r['tour_s']:.0f} s; oldest mark read: {r['oldest_mark_read_s']:.0f} s; longest frame sees "
                + (f"{r['horizon_limit_s']:.0f} s back" if r["horizon_limit_s"] is not None else "marks of any age")
                + f" {r['horizon_limit_reach_m']:.2f} m away (the look's claim)",
                "in camera mode (frames sized by the noise they will have) the longest frame sees "
                + (f"{r['camera_horizon_limit_s']:.0f} s back" if r["camera_horizon_limit_s"] else "any age")
                + " there: a tour needing more stops 'out of sight' earlier than the plan",
                f"frames (length x count): {sizes}",
            ]
        )
    rows = [
        (
            "board",
            f"{r['board_cells'][0]}x{r['board_cells'][1]} cells, perception {r['perception']}, "
            f"exposure {r['exposure']}, camera {r['camera']}, robot {r['robot']}",
        ),
        ("sub-cells covered / reachable", f"{r['subcells_covered']} / {r['subcells_reachable']}"),
        ("covered more than once", str(r["subcells_covered_more_than_once"])),
        ("complete (every sub-cell once, back, no error)", str(r["complete"])),
        ("finished / back in start cell", f"{r['finished']} / {r['returned_to_start']}"),
        ("abort reason", str(r["abort_reason"])),
        *([("faults (events)", _fault_events(r))] if r.get("faults") else []),
        ("moves / turns / decisions", f"{r['moves']} / {r['turns']} / {r['decisions']}"),
        ("decision errors (vs oracle)", str(r["decision_errors"])),
        ("oldest mark read", f"{r['max_mark_age_read_s']:.0f} s"),
        ("sim time / wall time", f"{r['sim_time_s']:.0f} s / {r['wall_s']:.1f} s"),
    ]
    w = max(len(k) for k, _ in rows)
    text = "\n".join(f"{k:<{w}}  {v}" for k, v in rows)
    wrote = [r[k] for k in ("rrd", "trajectory", "trace") if r.get(k)]
    return text + "".join(f"\nwrote {w}" for w in wrote)
