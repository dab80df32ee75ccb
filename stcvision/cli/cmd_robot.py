"""Drive an ant-like STC robot over a serial link, or be one: the simulated robot on a
pseudo-terminal that ``robot run`` is tested against.

  stcvision robot run --port /dev/ttyUSB0 [--camera robot] [--robot lego] [--fsm python|c|firmware] [--rrd R.rrd]
  stcvision robot run --port /dev/ttyUSB0 --camera 0 --profile P.json (--dark D.png | --no-dark) [--robot lego]
  stcvision robot sim --board 3x3 [--seed S] [--perception oracle|camera] [--link-fault KIND@N]

run drives the robot on --port (a serial device, or any pyserial URL) with the chosen
controller: the robot answers the protocol's requests (docs: Serial protocol), reading its floor
with its camera, laying rows, driving one sub-cell, turning by the robot's turn time. With
--camera N (a camera on this computer) or --camera VIDEO (a recording of one) the frames are read
here by the vision pipeline with the camera's calibration --profile and --dark frame, and a frame
it cannot trust stops the robot before any decision. Exit 0
when the robot reports the board complete, 3 when it stopped (a link failure is one line: a
lost byte, a bad checksum, a reply that never came, a port that is gone), 2 for bad input.

sim opens a pseudo-terminal, prints its path on the first line, and answers as a robot: the
simulator's plant, floor and camera (or oracle) behind the protocol, until it is told to stop
(or hears nothing for a minute); then prints what it did. --link-fault breaks the link at the
Nth request (drop a byte of the reply, corrupt its checksum, never reply, hang up).
"""

from __future__ import annotations

NESTED = True  # --json belongs to each action


def add_parser(p):
    import argparse

    from stcvision.cli._args import positive
    from stcvision.cli.cmd_cover import add_board_arguments
    from stcvision.limits import MAX_LINK_TIMEOUT_S

    p.formatter_class = argparse.RawDescriptionHelpFormatter
    sub = p.add_subparsers(dest="action", metavar="{run,sim}", parser_class=type(p), required=True)
    r = sub.add_parser("run", help="drive a robot over a serial link")
    r.add_argument("--port", required=True, metavar="DEVICE", help="the robot's serial port (or a pyserial URL)")
    r.add_argument(
        "--camera",
        default="robot",
        metavar="robot|N|VIDEO",
        help="where the readings come from: the robot's own camera (default), camera device N here, or a video",
    )
    r.add_argument("--robot", default="lego", metavar="NAME|FILE.json", help="robot preset: turn and LED times")
    r.add_argument("--profile", metavar="PROFILE.json", help="--camera N|VIDEO: the camera's calibration profile")
    r.add_argument("--dark", metavar="DARK.png", help="--camera N|VIDEO: the dark frame at the camera's exposure")
    r.add_argument("--no-dark", action="store_true", help="--camera N|VIDEO: read without a dark frame")
    r.add_argument("--fsm", choices=("python", "c", "firmware"), default="python", help="the controller")
    r.add_argument("--mcu", default=None, metavar="NAME", help="--fsm firmware: the microcontroller")
    r.add_argument(
        "--timeout",
        type=positive(float, maximum=MAX_LINK_TIMEOUT_S, why="MAX_LINK_TIMEOUT_S"),
        default=10.0,
        metavar="S",
        help="seconds to wait for each reply (default 10)",
    )
    r.add_argument("--rrd", metavar="OUT.rrd", help="rerun recording of every request on the link and every tick")
    r.add_argument("--force", action="store_true", help="overwrite --rrd")
    r.add_argument("--json", action="store_true", help="print the result as one JSON object")
    s = sub.add_parser("sim", help="a simulated robot on a pseudo-terminal")
    add_board_arguments(s)
    s.add_argument("--perception", choices=("oracle", "camera", "ideal"), default="oracle", help="its reading")
    s.add_argument("--link-fault", default=None, metavar="KIND@N", help="drop, corrupt, mute or hangup at request N")
    s.add_argument("--json", action="store_true", help="print the result as one JSON object")


def run(args):
    from stcvision.sim_camera import hardware

    if args.action == "run":
        from stcvision.controllers.stc.robot_link import run_robot

        if args.mcu and args.fsm != "firmware":
            from stcvision.errors import BadInputError

            raise BadInputError("--mcu names the chip of --fsm firmware")
        if args.rrd:
            from stcvision.rr import check_recording_path

            check_recording_path(args.rrd, overwrite=args.force)
        calibration, dark = _pc_camera_inputs(args)
        r = run_robot(args.port, camera=args.camera, profile=hardware.load_robot(args.robot), fsm=args.fsm,
                      mcu=args.mcu, timeout_s=args.timeout, rrd=args.rrd, calibration=calibration,
                      dark=dark)  # fmt: skip
        r["rrd"] = args.rrd
        from stcvision.cli import EXIT_INCOMPLETE, EXIT_OK

        r["exit_code"] = EXIT_OK if r["complete"] else EXIT_INCOMPLETE
        return r
    from stcvision.cli.cmd_cover import load_board
    from stcvision.controllers.stc.loop import CoverConfig
    from stcvision.controllers.stc.simrobot import parse_link_fault, serve_pty

    fault = parse_link_fault(args.link_fault)
    board = load_board(args)
    cfg = CoverConfig(perception=args.perception, seed=args.seed)
    return serve_pty(board, cfg, ready=lambda path: print(path, flush=True), link_fault=fault)


def _pc_camera_inputs(args):
    """The calibration profile and dark frame of ``--camera N|VIDEO`` (None, None for the
    robot's own camera, which needs neither)."""
    from stcvision.errors import BadInputError

    if args.camera == "robot":
        if args.profile or args.dark or args.no_dark:
            raise BadInputError("--profile, --dark and --no-dark are for a camera on this computer (--camera N|VIDEO)")
        return None, None
    if not args.profile:
        raise BadInputError(f"--camera {args.camera}: give the camera's calibration --profile PROFILE.json")
    if bool(args.dark) == bool(args.no_dark):
        raise BadInputError(f"--camera {args.camera}: give --dark DARK.png (at the camera's exposure) or --no-dark")
    from stcvision.fileio import read_image
    from stcvision.profile import Profile

    profile = Profile.load(args.profile)
    dark = read_image(args.dark, what="dark frame") if args.dark else None
    if dark is not None:
        profile.check_frame(dark.shape, what=f"dark frame {args.dark}")
    return profile, dark


def format_text(r) -> str:
    if "ended" in r:
        return f"simulated robot on {r['port']}: {r['ended']} after {r['requests']} requests, {r['moves']} moves"
    rows = [f"robot on {r['port']} ({r.get('robot_says', '?')}), controller {r['fsm']}"]
    if "subcells_covered" in r:
        rows.append(f"sub-cells covered / reachable: {r['subcells_covered']} / {r['subcells_reachable']}, "
                    f"twice {r['subcells_covered_more_than_once']}")  # fmt: skip
    rows.append(f"complete: {r['complete']}; decisions {r['decisions']}, looks {r['looks']}, commands {r['commands']}")
    if "moves" in r:
        rows.append(f"the robot's odometry: {r['moves']} moves, {r['turns']} turns, {r['robot_clock_s']:.0f} s")
    if r["abort_reason"]:
        rows.append(f"stopped: {r['abort_reason']}")
    if r.get("rrd"):
        rows.append(f"wrote {r['rrd']}")
    return "\n".join(rows)
