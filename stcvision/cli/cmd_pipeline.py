"""Run the vision pipeline on frames from disk: dark frame, phi/theta unwarp, red/green
channels, dot search, heading fit, cell observation. Prints per-frame results (dots, heading,
boxes, neighbours, obstacles, per-stage ms); --rrd logs every stage to a rerun recording.
"""

from __future__ import annotations


def add_parser(p):
    p.add_argument("frames", nargs="+", metavar="FRAME", help="frame images (BGR: 8-bit PNG/JPEG or 16-bit PNG)")
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
    from stcvision.pipeline import Pipeline
    from stcvision.profile import Profile
    from stcvision.rr import check_recording_path

    if args.dark is None and not args.no_dark:
        raise BadInputError("no dark frame: pass --dark DARK.png (captured at the frames' exposure) or --no-dark")
    if args.profile:
        profile = Profile.load(args.profile)
    else:
        from calibration.profiles import default_profile

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
    results = []
    try:
        for i, path in enumerate(args.frames):
            frame = read_image(path, what="frame")
            profile.check_frame(frame.shape, what=f"frame {path}")
            if dark is not None:
                check_same_depth(frame, dark, args.dark, frame_path=path)
            if i == 0:  # where its mirror rim shows (lights on), it must be where the profile has it
                from calibration.rim import check_rim_matches

                check_rim_matches(frame, profile, frame_name=f"frame {path}", profile_name=profile_name)
            res = pipe.process(frame)
            if logger is not None:
                logger.log(res, frame=i)
            d = res.to_dict()
            d["frame"] = str(path)
            results.append(d)
    except BaseException:
        if logger is not None:
            logger.abort()
        raise
    if logger is not None:
        logger.close()
    return {"frames": results, "rrd": args.rrd, "profile": args.profile or "default"}


def format_text(r):
    out = []
    for f in r["frames"]:
        obs = f["observation"]
        lit = [b for b, v in obs["boxes"].items() if v["lit"]]
        nb = ", ".join(
            f"{k}:{'M' if v['has_marks'] else '-'}{'R' if v['has_red'] else '-'}" for k, v in obs["neighbours"].items()
        )
        h = f["heading"]
        head = f"{h['heading_error_deg']:+.2f} deg" if h["ok"] else f"no fit ({h['reason']})"
        out.append(
            f"{f['frame']}: {len(f['dots'])} dots, heading {head}, lit boxes {lit or 'none'}, "
            f"visited {[k for k, v in obs['visited'].items() if v] or 'none'}, neighbours {nb}, "
            f"{len(f['obstacles'])} red lights, {f['total_ms']:.2f} ms"
            + (f"\n  UNTRUSTED: {f['untrusted']}" if f["untrusted"] else "")
        )
    if r["rrd"]:
        out.append(f"wrote {r['rrd']}")
    return "\n".join(out)
