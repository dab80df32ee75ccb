"""Evaluate the vision pipeline offline, on a dataset or on your own frames.

  stcvision eval DIR [--profile P.json] [--json] [--report OUTDIR] [--rrd R.rrd] [--workers N | --scheduler tcp://H:P]
  stcvision eval --compare A.json B.json
  stcvision eval LABELLED_FOLDER [--dark D.png | --no-dark] [--profile P.json] [--json] [--report OUTDIR]
  stcvision eval FOLDER_OF_IMAGES (--dark D.png | --no-dark) [--out RESULTS.jsonl] [--rrd R.rrd]
  stcvision eval --bag FILE --topic TOPIC (--dark D.png | --no-dark) [--out RESULTS.jsonl] [--rrd R.rrd]

On a dataset (made by 'stcvision dataset generate') every frame is run through the pipeline
(chunks of frames are tasks of the sweep runner: --workers N, --scheduler tcp://HOST:PORT; with
--store FILE an interrupted evaluation resumes, --fresh starts over) and scored against its
label: dot recall and precision, dot location error, heading error RMS,
box and obstacle accuracy, median ms per frame, with breakdowns by mark age, exposure, group,
camera (with the profile's floor error at the true dot positions) and neighbour configuration.
--report writes a markdown summary and PNG plots; --rrd logs the worst frames to a rerun
recording. Each camera's own profile from the dataset is used if it
has one, else the shipped default (or --profile for all).

--compare prints, per metric, whether B is better, worse or the same as A (A and B are saved
'--json' outputs).

On a folder of your own frames with labels.jsonl in the hand-label format
(docs/how-to/label-real-frames.md: per frame, boxes lit or not, neighbours' red lights and marks,
the heading error, dots) the same metrics and report are computed against your labels; what a
label leaves out is not scored.

On a folder of images without labels the pipeline runs on each and writes per-frame results
(JSONL); there is no truth, so no accuracy. --bag does the same on a robot's recording (a ROS 1
bag, a ROS 2 bag folder or an MCAP file, as 'stcvision pipeline --bag' reads it), each line with
its frame's header stamp.
"""

from __future__ import annotations


def add_parser(p):
    import argparse

    p.formatter_class = argparse.RawDescriptionHelpFormatter  # keep the usage lines of the docstring
    p.add_argument("dir", nargs="?", metavar="DIR", help="a dataset folder, or a folder of your own frames")
    p.add_argument("--bag", metavar="FILE", help="a recording: ROS 1 bag, ROS 2 bag folder or MCAP file (with --topic)")
    p.add_argument("--topic", metavar="TOPIC", help="--bag: the sensor_msgs/Image or CompressedImage topic")
    p.add_argument("--profile", metavar="PROFILE.json", help="calibration profile for every frame")
    p.add_argument("--report", metavar="OUTDIR", help="write summary.md, eval.json, frames.jsonl and PNG plots")
    p.add_argument("--rrd", metavar="OUT.rrd", help="rerun recording of the worst frames (dataset) or every frame")
    p.add_argument("--worst", type=int, default=10, metavar="N", help="frames logged with --rrd (default 10)")
    p.add_argument("--compare", nargs=2, metavar=("A.json", "B.json"), help="compare two saved --json outputs")
    p.add_argument("--dark", metavar="DARK.png", help="own frames: dark frame at the frames' exposure")
    p.add_argument("--no-dark", action="store_true", help="own frames: run without a dark frame")
    p.add_argument("--out", metavar="RESULTS.jsonl", help="own frames: per-frame results (default: DIR-results.jsonl)")
    p.add_argument("--force", action="store_true", help="overwrite existing report, recording or results files")
    p.add_argument(
        "--store",
        metavar="FILE.jsonl",
        help="dataset: keep the chunks' results here, so an interrupted run resumes (default: a temporary "
        "store, removed at the end; after changing the pipeline use --fresh)",
    )
    from stcvision.sweep import add_sweep_arguments

    add_sweep_arguments(p)


def _load_profile(path):
    if path:
        from stcvision.profile import Profile

        return Profile.load(path)
    return None


def _default_profile():
    from stcvision.calibration.profiles import default_profile

    return default_profile()


def _default_profile_path() -> str:
    from stcvision.calibration.profiles import default_profile_path

    return str(default_profile_path())


def run(args):
    from pathlib import Path

    from stcvision.errors import BadInputError

    if args.compare:
        if args.dir:
            raise BadInputError("give either DIR or --compare A.json B.json, not both")
        from stcvision.evaluate import compare
        from stcvision.fileio import read_json

        a, b = (read_json(p, what="evaluation") for p in args.compare)
        r = compare(a, b, names=tuple(args.compare))
        r["mode"] = "compare"
        return r
    if (args.bag is None) != (args.topic is None):
        raise BadInputError("--bag FILE and --topic TOPIC go together")
    if args.bag is not None:
        if args.dir or args.compare:
            raise BadInputError("give DIR, --bag FILE or --compare A.json B.json, one of them")
        return _run_bag(args)
    if not args.dir:
        raise BadInputError("eval needs DIR (a dataset or a folder of frames) or --compare A.json B.json")
    from stcvision.limits import MAX_EVAL_WORST_FRAMES, check_count

    check_count("--worst", args.worst, MAX_EVAL_WORST_FRAMES)
    root = Path(args.dir)
    if not root.is_dir():
        raise BadInputError(f"{root} is not a folder; expected a dataset or a folder of frames")
    if args.rrd:
        from stcvision.rr import check_recording_path

        check_recording_path(args.rrd, overwrite=args.force)
    if args.report:  # before any work: an evaluation is minutes lost to a folder it cannot write
        from stcvision.fileio import check_output_folder
        from stcvision.report import REPORT_FILES

        check_output_folder(args.report, REPORT_FILES, overwrite=args.force)
    if (root / "manifest.json").exists() or (root / "labels.jsonl").exists():
        return _run_dataset(args, root)
    return _run_images(args, root)


def _run_dataset(args, root):
    from stcvision.datasets import open_dataset
    from stcvision.errors import BadInputError
    from stcvision.evaluate import log_worst, sweep_evaluation
    from stcvision.report import write_report

    labelled = not (root / "manifest.json").exists()  # a person's labels of real frames
    if args.out:
        raise BadInputError(f"{root} has labels: the scores go to --json or --report; drop --out")
    if not labelled and (args.dark or args.no_dark):
        raise BadInputError(f"{root} is a dataset: its dark frames are in the dataset; drop --dark/--no-dark")
    if args.dark and args.no_dark:
        raise BadInputError("give --dark DARK.png or --no-dark, not both")
    ds = open_dataset(root, dark=args.dark)
    profile = _load_profile(args.profile)
    if labelled:
        _check_labelled(args, ds, profile or _default_profile())
    from stcvision.sweep import sweep_options_from_args

    ev, report = sweep_evaluation(
        ds,
        profile_path=args.profile,
        default_profile_path=None if args.profile else _default_profile_path(),
        options=sweep_options_from_args(args),
        store=args.store,
        dark_path=args.dark,
    )
    r = dict(ev.summary)
    r["mode"] = "labelled" if labelled else "dataset"
    r["sweep"] = report.summary()
    if args.profile:
        r["profile"] = str(args.profile)
    if args.report:
        r["report"] = write_report(ev, args.report, overwrite=args.force)
    if args.rrd:
        r["rrd"] = str(args.rrd)
        r["rrd_frames"] = log_worst(ev, ds, args.rrd, default_profile=_default_profile(), profile=profile, n=args.worst)
    return r


def _check_labelled(args, ds, profile) -> None:
    """Before any work on a person's labelled frames: each needs its dark frame (or --no-dark),
    and the first frame's mirror rim, where it shows, must be where the profile has it."""
    from stcvision.calibration.rim import check_rim_matches
    from stcvision.errors import BadInputError
    from stcvision.fileio import read_image

    missing = [lab["frame"] for lab in ds.labels if lab.get("dark") is None]
    if missing and not args.no_dark:
        raise BadInputError(
            f"{ds.root / missing[0]} has no dark frame (its label names none); pass --dark DARK.png (captured "
            "at the frames' exposure) or --no-dark"
        )
    first = ds.labels[0]["frame"]
    frame = read_image(ds.root / first, what="frame")
    profile.check_frame(frame.shape, what=str(ds.root / first))
    check_rim_matches(
        frame, profile, frame_name=str(ds.root / first), profile_name=f"profile {args.profile or 'default'}"
    )


def _run_images(args, root):
    from pathlib import Path

    from stcvision.datasets import list_images
    from stcvision.errors import BadInputError, FileExistsRefusedError
    from stcvision.evaluate import evaluate_image_folder
    from stcvision.fileio import read_image

    if args.dark is None and not args.no_dark:
        raise BadInputError(
            f"{root} has no labels (not a dataset); pass --dark DARK.png (captured at the frames' exposure) "
            "or --no-dark"
        )
    if args.report:
        raise BadInputError(f"{root} has no labels, so there is no accuracy to report; drop --report")
    paths = list_images(root)
    excluded = []
    if args.dark:  # the dark frame is not one of the frames, even when it sits among them
        dark_file = Path(args.dark).resolve()
        excluded = [str(p) for p in paths if Path(p).resolve() == dark_file]
        paths = [p for p in paths if Path(p).resolve() != dark_file]
    profile = _load_profile(args.profile) or _default_profile()
    dark = None
    if args.dark:
        dark = read_image(args.dark, what="dark frame")
        profile.check_frame(dark.shape, what=f"dark frame {args.dark}")
    if paths:  # where its mirror rim shows (lights on), it must be where the profile has it
        from stcvision.calibration.rim import check_rim_matches

        first = read_image(paths[0], what="frame")
        profile.check_frame(first.shape, what=str(paths[0]))
        check_rim_matches(first, profile, frame_name=str(paths[0]), profile_name=f"profile {args.profile or 'default'}")
    out = Path(args.out) if args.out else root.resolve().parent / f"{root.resolve().name}-results.jsonl"
    if out.exists() and not args.force:
        raise FileExistsRefusedError(f"{out} exists; refusing to overwrite it (use --out or --force)")
    r = evaluate_image_folder(paths, profile=profile, dark=dark, dark_path=args.dark, out=out, rrd=args.rrd)
    return {"mode": "frames", "dir": str(root), **r, "excluded": excluded, "profile": args.profile or "default"}


def _run_bag(args):
    """A recording's frames through the pipeline into a results file, as a folder of frames."""
    from pathlib import Path

    from stcvision.bags import open_bag
    from stcvision.errors import BadInputError, FileExistsRefusedError
    from stcvision.evaluate import evaluate_recording
    from stcvision.fileio import read_image
    from stcvision.limits import MAX_VIDEO_FRAMES

    if args.dark is None and not args.no_dark:
        raise BadInputError("--bag: pass --dark DARK.png (captured at the frames' exposure) or --no-dark")
    if args.dark and args.no_dark:
        raise BadInputError("give --dark DARK.png or --no-dark, not both")
    if args.report:
        raise BadInputError("a recording has no labels, so there is no accuracy to report; drop --report")
    bag = Path(args.bag)
    out = Path(args.out) if args.out else bag.resolve().parent / f"{bag.resolve().stem}-results.jsonl"
    if out.exists() and not args.force:
        raise FileExistsRefusedError(f"{out} exists; refusing to overwrite it (use --out or --force)")
    if args.rrd:
        from stcvision.rr import check_recording_path

        check_recording_path(args.rrd, overwrite=args.force)
    profile = _load_profile(args.profile) or _default_profile()
    dark = None
    if args.dark:
        dark = read_image(args.dark, what="dark frame")
        profile.check_frame(dark.shape, what=f"dark frame {args.dark}")
    src = open_bag(bag, args.topic)

    profile_name = f"profile {args.profile or 'default'}"

    def frames():
        from stcvision.calibration.rim import check_rim_matches

        for k, f in enumerate(src.frames(count=MAX_VIDEO_FRAMES)):
            if k == 0:  # where its mirror rim shows (lights on), it must be where the profile has it
                name = f"frame {f.index} of {src.name}"
                profile.check_frame(f.image.shape, what=name)
                check_rim_matches(f.image, profile, frame_name=name, profile_name=profile_name)
            yield f

    try:
        r = evaluate_recording(
            frames(),
            name=src.name,
            profile=profile,
            dark=dark,
            dark_path=args.dark,
            out=out,
            rrd=args.rrd,
            total=min(src.frame_count, MAX_VIDEO_FRAMES),
        )
    finally:
        src.close()
    if r["frames"] == 0:
        raise BadInputError(f"{src.name}: no frame on {args.topic}")
    return {"mode": "frames", "dir": src.name, **r, "topic": args.topic, "profile": args.profile or "default"}


def _f(v, fmt=".4g"):
    return "-" if v is None else f"{v:{fmt}}"


def format_text(r):
    if r["mode"] == "compare":
        from stcvision.report import format_compare

        return format_compare(r)
    if r["mode"] == "frames":
        out = [
            f"{r['dir']}: {r['frames']} frames run through the pipeline ({r['frames_skipped']} skipped), "
            f"{_f(r['dots_per_frame_median'])} dots per frame (median), {r['heading_fits']} heading fits, "
            f"{_f(r['ms_per_frame_median'], '.2f')} ms per frame (median)",
            f"wrote {r['results']}" + (f" and {r['rrd']}" if r["rrd"] else ""),
            "No labels: without ground truth there is no accuracy to report.",
        ]
        if r.get("excluded"):
            out.insert(1, f"left out {', '.join(r['excluded'])}: it is the --dark frame")
        for u in r.get("untrusted", []):  # their readings are in the results, marked; not to be used
            out.insert(1, f"untrusted {u['frame']}: {u['reason']}")
        return "\n".join(out)

    def pct(v):
        return "-" if v is None else f"{100 * v:.2f} %"

    source = "labelled by hand" if r["mode"] == "labelled" else f"recipe {r['recipe']}, seed {r['seed']}"
    out = [
        f"{r['dataset']} ({source}, profile {r['profile']}): {r['frames']} frames, {r['frames_skipped']} skipped, "
        f"{r['frames_untrusted']} untrusted",
        f"  dot recall            {pct(r['dot_recall'])}",
        f"  dot precision         {pct(r['dot_precision'])}",
        f"  dot loc. error median {_f(r['dot_loc_err_mm_median'], '.2f')} mm, "
        f"{_f(r['dot_loc_err_px_median'], '.2f')} px",
        f"  heading error RMS     {_f(r['heading_err_deg_rms'], '.3f')} deg ({r['heading_fits']} fits)",
        f"  box accuracy          {pct(r['box_accuracy'])} of {r['boxes_scored']} "
        f"(recall {pct(r['box_recall'])}, precision {pct(r['box_precision'])})",
        f"  obstacle accuracy     {pct(r['obstacle_accuracy'])} of {r['obstacles_scored']} "
        f"(recall {pct(r['obstacle_recall'])}, precision {pct(r['obstacle_precision'])})",
        f"  neighbour marks       {pct(r['neighbour_marks_accuracy'])} of {r['neighbour_marks_scored']} "
        f"(recall {pct(r['neighbour_marks_recall'])}, precision {pct(r['neighbour_marks_precision'])})",
        f"  ms per frame median   {_f(r['ms_per_frame_median'], '.2f')}",
        "  by exposure:",
    ]
    for k, m in r["by_exposure"].items():
        out.append(
            f"    {k:<20} {m['frames']:>4} frames  recall {pct(m['dot_recall'])}  "
            f"heading {_f(m['heading_err_deg_rms'], '.3f')} deg  boxes {pct(m['box_accuracy'])}"
        )
    out.append(
        "  recall by mark age: "
        + ", ".join(
            f"{b['age_s'][0]}-{'' if b['age_s'][1] is None else b['age_s'][1]} s {pct(b['recall'])}"
            for b in r["by_age"]
        )
    )
    if r.get("report"):
        from pathlib import Path

        out.append(f"wrote the report to {Path(r['report'][0]).parent}")
    if r.get("rrd"):
        out.append(f"wrote {r['rrd']} ({len(r['rrd_frames'])} worst frames)")
    return "\n".join(out)
