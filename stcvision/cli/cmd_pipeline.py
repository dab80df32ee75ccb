"""Run the vision pipeline on frames from disk, a video file or a live camera: dark frame,
phi/theta unwarp, red/green channels, dot search, heading fit, cell observation. Prints
per-frame results (dots, heading, boxes, neighbours, obstacles, per-stage ms); --rrd logs every
stage to a rerun recording.

  stcvision pipeline FRAME... --dark DARK.png [--profile P.json] [--json]
  stcvision pipeline --video FILE [--start N] [--frames N] [--every K] --dark DARK.png [--json]
  stcvision pipeline --device N --dark DARK.png --spawn          (live, until Ctrl-C)

With --video or --device, results stream out frame by frame (--json: one JSON object a line).
"""

from __future__ import annotations


def add_parser(p):
    from stcvision.cli._args import positive
    from stcvision.limits import MAX_VIDEO_EVERY, MAX_VIDEO_FRAMES

    p.add_argument("frames", nargs="*", metavar="FRAME", help="frame images (BGR: 8-bit PNG/JPEG or 16-bit PNG)")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--video", metavar="FILE", help="read the frames from a video file (any container OpenCV opens)")
    src.add_argument("--device", type=int, metavar="N", help="read a live camera (OpenCV device N) until Ctrl-C")
    p.add_argument("--start", type=int, default=0, metavar="N", help="--video: first frame (0-based; default 0)")
    p.add_argument(
        "--frames",
        dest="n_frames",
        type=positive(int, maximum=MAX_VIDEO_FRAMES, why="frames one run reads"),
        metavar="N",
        help="--video/--device: at most N frames",
    )
    p.add_argument(
        "--every",
        type=positive(int, maximum=MAX_VIDEO_EVERY, why="frames between two read"),
        default=1,
        metavar="K",
        help="--video/--device: one frame in K (default 1)",
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


def run(args):
    from stcvision.errors import BadInputError
    from stcvision.fileio import check_same_depth, read_image
    from stcvision.limits import MAX_VIDEO_FRAMES
    from stcvision.pipeline import Pipeline
    from stcvision.profile import Profile
    from stcvision.rr import check_recording_path

    streaming = args.video is not None or args.device is not None
    if streaming and args.frames:
        raise BadInputError("give frame files or --video/--device, not both")
    if not streaming and not args.frames:
        raise BadInputError("no frames: give FRAME files, --video FILE or --device N")
    if not streaming and (args.start or args.n_frames or args.every != 1):
        raise BadInputError("--start, --frames and --every apply to --video and --device")
    if not 0 <= args.start <= MAX_VIDEO_FRAMES:
        raise BadInputError(f"--start {args.start}: expected 0..{MAX_VIDEO_FRAMES:,}")
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
    if args.rrd or args.spawn:
        from stcvision.rr import PipelineLogger, open_recording

        if args.rrd:
            logger = PipelineLogger.to_file(args.rrd, pipe, spawn=args.spawn)
        else:
            rec, _ = open_recording(None, spawn=True)
            logger = PipelineLogger(rec, pipe)

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
        if logger is not None:
            recs.add(logger)
        if streaming:
            _stream(args, process)
        else:
            for i, path in enumerate(args.frames):
                d = process(read_image(path, what="frame"), i, f"frame {path}")
                d["frame"] = str(path)
                results.append(d)
    if streaming:
        if args.rrd and not args.json:
            print(f"wrote {args.rrd}")
        return None  # printed frame by frame
    return {"frames": results, "rrd": args.rrd, "profile": args.profile or "default"}


def _stream(args, process) -> None:
    """Frames of --video or --device through ``process``, each result printed as it comes (a
    JSON line with --json), with a progress bar on a terminal; a live camera runs until Ctrl-C."""
    import sys

    from tqdm import tqdm

    from stcvision.errors import BadInputError, Terminated
    from stcvision.fileio import dumps
    from stcvision.video import codec_warning, open_device, open_video

    src = open_video(args.video) if args.video is not None else open_device(args.device)
    try:
        warn = codec_warning(src)
        if warn:
            print(f"stcvision pipeline: warning: {warn}", file=sys.stderr)
        total = None
        if src.frame_count is not None:
            total = max(0, -(-(src.frame_count - args.start) // args.every))
            total = min(total, args.n_frames) if args.n_frames else total
        elif args.n_frames:
            total = args.n_frames
        n = 0
        with tqdm(total=total, desc=src.name, unit="frame", disable=None, file=sys.stderr, dynamic_ncols=True) as bar:
            try:
                for i, frame in src.frames(start=args.start, count=args.n_frames, every=args.every):
                    d = process(frame, n, f"frame {i} of {src.name}")
                    d["frame"] = i
                    print(dumps(d, indent=None) if args.json else _frame_line(d), flush=True)
                    n += 1
                    bar.update()
            except KeyboardInterrupt as exc:  # Ctrl-C ends a live run; a video's is an interruption
                if not src.live or isinstance(exc, Terminated):
                    raise
        if n == 0:
            raise BadInputError(f"{src.name}: no frame read (from frame {args.start})")
    finally:
        src.close()


def _frame_line(f) -> str:
    obs = f["observation"]
    lit = [b for b, v in obs["boxes"].items() if v["lit"]]
    nb = ", ".join(
        f"{k}:{'M' if v['has_marks'] else '-'}{'R' if v['has_red'] else '-'}" for k, v in obs["neighbours"].items()
    )
    h = f["heading"]
    head = f"{h['heading_error_deg']:+.2f} deg" if h["ok"] else f"no fit ({h['reason']})"
    return (
        f"{f['frame']}: {len(f['dots'])} dots, heading {head}, lit boxes {lit or 'none'}, "
        f"visited {[k for k, v in obs['visited'].items() if v] or 'none'}, neighbours {nb}, "
        f"{len(f['obstacles'])} red lights, {f['total_ms']:.2f} ms"
        + (f"\n  UNTRUSTED: {f['untrusted']}" if f["untrusted"] else "")
    )


def format_text(r):
    out = [_frame_line(f) for f in r["frames"]]
    if r["rrd"]:
        out.append(f"wrote {r['rrd']}")
    return "\n".join(out)
