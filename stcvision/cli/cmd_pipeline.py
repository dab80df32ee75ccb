"""Run the vision pipeline on frames from disk, a video file, a live camera or a robot's recording
(ROS 1 bag, ROS 2 bag, MCAP file): dark frame, phi/theta unwarp, red/green channels, dot
search, heading fit, cell observation. Prints per-frame results (dots, heading, boxes,
neighbours, obstacles, per-stage ms), each with the frame's time; --rrd logs every stage to a
rerun recording.

  stcvision pipeline FRAME... --dark DARK.png [--profile P.json] [--json]
  stcvision pipeline --video FILE [--start N] [--frames N] [--every K] --dark DARK.png [--json]
  stcvision pipeline --device N --dark DARK.png --spawn          (live, until Ctrl-C)
  stcvision pipeline --bag FILE --topic /camera/image_raw [--start S] [--end S] --dark DARK.png [--json]

With --video, --device or --bag, results stream out frame by frame (--json: one JSON object a
line) and a summary line ends the run. A frame's time (t_s, seconds) is its position in the
order the FRAME files are given, the video container's timestamp, this computer's clock when a
live camera's frame arrived, or a recording's header stamp (also exact, as stamp_ns).
"""

from __future__ import annotations


def add_parser(p):
    from stcvision.cli._args import positive
    from stcvision.limits import MAX_VIDEO_EVERY, MAX_VIDEO_FRAMES

    p.add_argument("frames", nargs="*", metavar="FRAME", help="frame images (BGR: 8-bit PNG/JPEG or 16-bit PNG)")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--video", metavar="FILE", help="read the frames from a video file (any container OpenCV opens)")
    src.add_argument("--device", type=int, metavar="N", help="read a live camera (OpenCV device N) until Ctrl-C")
    src.add_argument(
        "--bag",
        metavar="FILE",
        help="read a recording: a ROS 1 bag (.bag), a ROS 2 bag folder, or an MCAP file (.mcap); with --topic",
    )
    p.add_argument("--topic", metavar="TOPIC", help="--bag: the sensor_msgs/Image or CompressedImage topic to read")
    p.add_argument(
        "--start",
        type=_start,
        default=0,
        metavar="N|S",
        help="--video: first frame (0-based; default 0); --bag: seconds from the recording's start",
    )
    p.add_argument(
        "--end", type=_seconds, metavar="S", help="--bag: stop at S seconds from the recording's start (excluded)"
    )
    p.add_argument(
        "--frames",
        dest="n_frames",
        type=positive(int, maximum=MAX_VIDEO_FRAMES, why="frames one run reads"),
        metavar="N",
        help="--video/--device/--bag: at most N frames",
    )
    p.add_argument(
        "--every",
        type=positive(int, maximum=MAX_VIDEO_EVERY, why="frames between two read"),
        default=1,
        metavar="K",
        help="--video/--device/--bag: one frame in K (default 1)",
    )
    p.add_argument(
        "--profile",
        metavar="PROFILE.json",
        help="calibration profile (default: the shipped profile of the default simulated camera)",
    )
    dark = p.add_mutually_exclusive_group()
    dark.add_argument("--dark", metavar="DARK.png", help="dark frame at the frames' exposure (and depth)")
    dark.add_argument("--no-dark", action="store_true", help="run without a dark frame (not recommended)")
    p.add_argument("--rrd", metavar="OUT.rrd", help="write a rerun recording of every stage")
    p.add_argument("--spawn", action="store_true", help="stream to a spawned rerun viewer")
    p.add_argument("--force", action="store_true", help="overwrite an existing --rrd file")


def _seconds(text: str) -> float:
    """argparse type: seconds from a recording's start, finite and >= 0."""
    import argparse
    import math

    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not math.isfinite(v) or v < 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be a finite number of seconds >= 0")
    return v


def _start(text: str) -> float:
    """argparse type of --start: a frame index (--video) or seconds (--bag); which one the
    source decides, once all the flags are read."""
    import argparse

    try:
        return _seconds(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a frame index (--video) or a number of seconds >= 0 (--bag)"
        ) from None


def run(args):
    from stcvision.errors import BadInputError
    from stcvision.fileio import check_same_depth, dumps, read_image
    from stcvision.limits import MAX_VIDEO_FRAMES
    from stcvision.pipeline import Pipeline
    from stcvision.profile import Profile
    from stcvision.rr import check_recording_path

    streaming = args.video is not None or args.device is not None or args.bag is not None
    if streaming and args.frames:
        raise BadInputError("give frame files or --video/--device/--bag, not both")
    if not streaming and not args.frames:
        raise BadInputError("no frames: give FRAME files, --video FILE, --device N or --bag FILE --topic TOPIC")
    if not streaming and (args.start or args.n_frames or args.every != 1):
        raise BadInputError("--start, --frames and --every apply to --video, --device and --bag")
    if (args.bag is None) != (args.topic is None):
        raise BadInputError("--bag FILE and --topic TOPIC go together")
    if args.bag is None and args.end is not None:
        raise BadInputError("--end applies to --bag (seconds from the recording's start)")
    if args.bag is not None and args.end is not None and args.end <= args.start:
        raise BadInputError(f"--end {args.end:g} must be after --start {args.start:g}")
    if args.bag is None:
        if args.start != int(args.start):
            raise BadInputError(f"--start {args.start:g}: a video's first frame is a whole number")
        if not 0 <= args.start <= MAX_VIDEO_FRAMES:
            raise BadInputError(f"--start {args.start:g}: expected 0..{MAX_VIDEO_FRAMES:,}")
        args.start = int(args.start)
    if args.dark is None and not args.no_dark:
        raise BadInputError("no dark frame: pass --dark DARK.png (captured at the frames' exposure) or --no-dark")
    if args.profile:
        profile = Profile.load(args.profile)
    else:
        from stcvision.calibration.profiles import default_profile

        profile = default_profile()
    profile_name = f"profile {args.profile}" if args.profile else "the default profile"
    dark = None
    if args.dark:
        dark = read_image(args.dark, what="dark frame")
        profile.check_frame(dark.shape, what=f"dark frame {args.dark}")
    if args.rrd:
        check_recording_path(args.rrd, overwrite=args.force)
    pipe = Pipeline(profile, dark=dark)
    logger = None

    def process(frame, i: int, name: str):
        profile.check_frame(frame.shape, what=name)
        if dark is not None:
            check_same_depth(frame, dark, args.dark, frame_path=name)
        if i == 0:  # where its mirror rim shows (lights on), it must be where the profile has it
            from stcvision.calibration.rim import check_rim_matches

            check_rim_matches(frame, profile, frame_name=name, profile_name=profile_name)
        res = pipe.process(frame)
        if logger is not None:
            logger.log(res, frame=i)
        return res.to_dict()

    results = []
    from stcvision.rr import Recordings

    with Recordings() as recs:
        if args.rrd or args.spawn:
            from stcvision.rr import PipelineLogger

            logger = recs.add(PipelineLogger.to_file(args.rrd, pipe, spawn=args.spawn))
        if streaming:
            summary = _stream(args, process)
        else:
            for i, path in enumerate(args.frames):
                d = process(read_image(path, what="frame"), i, f"frame {path}")
                # frame files carry no time of their own: a frame's is its place in the order given
                d["frame"], d["t_s"] = str(path), float(i)
                results.append(d)
    if streaming:
        summary["rrd"] = args.rrd
        print(dumps({"summary": summary}, indent=None) if args.json else _summary_line(summary), flush=True)
        return None  # printed frame by frame
    return {"frames": results, "clock": "order", "rrd": args.rrd, "profile": args.profile or "default"}


def _open_source(args):
    """The frame source the flags name, with the clock its frames' times are on."""
    if args.bag is not None:
        from stcvision.bags import open_bag

        return open_bag(args.bag, args.topic), "header stamp"
    from stcvision.video import open_device, open_video

    if args.video is not None:
        return open_video(args.video), "container"
    return open_device(args.device), "computer clock"


def _stream(args, process) -> dict:
    """Frames of --video, --device or --bag through ``process``, each result printed as it comes
    (a JSON line with --json), with a progress bar on a terminal; a live camera runs until
    Ctrl-C. Returns the run's summary."""
    import sys

    from tqdm import tqdm

    from stcvision.errors import BadInputError, Terminated
    from stcvision.fileio import dumps
    from stcvision.limits import MAX_VIDEO_FRAMES

    src, clock = _open_source(args)
    bag = args.bag is not None
    try:
        if bag:
            from stcvision.bags import colour_warning

            count = args.n_frames
            if count is None and src.frame_count > MAX_VIDEO_FRAMES:
                count = MAX_VIDEO_FRAMES
                print(
                    f"stcvision pipeline: warning: {src.name} has {src.frame_count:,} frames on {args.topic}; "
                    f"reading the first {MAX_VIDEO_FRAMES:,} (the cap of one run)",
                    file=sys.stderr,
                )
            frames = src.frames(start_s=args.start, end_s=args.end, count=count, every=args.every)
            warned = False
        else:
            from stcvision.video import codec_warning

            warn = codec_warning(src)
            if warn:
                print(f"stcvision pipeline: warning: {warn}", file=sys.stderr)
            frames = src.frames(start=args.start, count=args.n_frames, every=args.every)
        total = None
        if src.frame_count is not None and not (bag and (args.start or args.end is not None)):
            total = max(0, -(-(src.frame_count - (0 if bag else args.start)) // args.every))
            total = min(total, args.n_frames) if args.n_frames else total
        elif args.n_frames:
            total = args.n_frames
        n, dots, untrusted, first, last = 0, 0, 0, None, None
        with tqdm(total=total, desc=src.name, unit="frame", disable=None, file=sys.stderr, dynamic_ncols=True) as bar:
            try:
                for f in frames:
                    if bag and not warned:
                        warned = True
                        warn = colour_warning(src.encoding)
                        if warn:
                            print(f"stcvision pipeline: warning: {warn}", file=sys.stderr)
                    d = process(f.image, n, f"frame {f.index} of {src.name}")
                    d["frame"], d["t_s"] = f.index, f.t_s
                    if f.stamp_ns is not None:
                        d["stamp_ns"] = f.stamp_ns
                    print(dumps(d, indent=None) if args.json else _frame_line(d), flush=True)
                    n += 1
                    dots += len(d["dots"])
                    untrusted += bool(d["untrusted"])
                    first = f.t_s if first is None else first
                    last = f.t_s
                    bar.update()
            except KeyboardInterrupt as exc:  # Ctrl-C ends a live run; a video's is an interruption
                if not src.live or isinstance(exc, Terminated):
                    raise
        if n == 0:
            where = (
                f" on {args.topic} from {args.start:g} s" + (f" to {args.end:g} s" if args.end is not None else "")
                if bag
                else f" (from frame {args.start})"
            )
            raise BadInputError(f"{src.name}: no frame read{where}")
    finally:
        src.close()
    return {
        "source": src.name,
        "clock": clock,
        "frames": n,
        "first_t_s": first,
        "last_t_s": last,
        "dots": dots,
        "untrusted_frames": untrusted,
    }


def _summary_line(s) -> str:
    span = f"t {s['first_t_s']:.6f} .. {s['last_t_s']:.6f} s ({s['clock']})"
    out = (
        f"{s['frames']} frame{'' if s['frames'] == 1 else 's'} of {s['source']}, {span}, {s['dots']} dots in all, "
        f"{s['untrusted_frames']} untrusted frames"
    )
    return out + (f"\nwrote {s['rrd']}" if s["rrd"] else "")


def _frame_line(f) -> str:
    obs = f["observation"]
    lit = [b for b, v in obs["boxes"].items() if v["lit"]]
    nb = ", ".join(
        f"{k}:{'M' if v['has_marks'] else '-'}{'R' if v['has_red'] else '-'}" for k, v in obs["neighbours"].items()
    )
    h = f["heading"]
    head = f"{h['heading_error_deg']:+.2f} deg" if h["ok"] else f"no fit ({h['reason']})"
    if "stamp_ns" in f:
        from stcvision.bags import stamp_text

        when = f"t={stamp_text(f['stamp_ns'])} s"
    elif isinstance(f["frame"], str):  # a frame file: its time is its place in the order given
        when = f"order {f['t_s']:.0f}"
    else:
        when = f"t={f['t_s']:.6f} s"
    return (
        f"{f['frame']} {when}: {len(f['dots'])} dots, heading {head}, lit boxes {lit or 'none'}, "
        f"visited {[k for k, v in obs['visited'].items() if v] or 'none'}, neighbours {nb}, "
        f"{len(f['obstacles'])} red lights, {f['total_ms']:.2f} ms"
        + (f"\n  UNTRUSTED: {f['untrusted']}" if f["untrusted"] else "")
    )


def format_text(r):
    out = [_frame_line(f) for f in r["frames"]]
    if r["rrd"]:
        out.append(f"wrote {r['rrd']}")
    return "\n".join(out)
