"""Label a folder of your own frames: the pipeline proposes, you correct on a review sheet.

  stcvision label FOLDER (--dark D.png | --no-dark) [--profile P.json] [--out SHEET] [--force]
  stcvision label FOLDER --accept labels.jsonl [--force]

The first form runs the pipeline on every frame of FOLDER and writes a review sheet (default
FOLDER-review/): index.html, one page to open in any browser, showing each frame with the
proposed dots circled, the ground view the pipeline read, and a form holding the proposal (boxes,
neighbours' red lights and marks, heading error, dots). Correct it, press "Make labels.jsonl" and
save the file; the second form checks that file and writes it as FOLDER/labels.jsonl, which
'stcvision eval FOLDER' scores the pipeline against (format: docs/how-to/label-real-frames.md).
"""

from __future__ import annotations


def add_parser(p):
    p.add_argument("dir", metavar="FOLDER", help="a folder of your own frames")
    p.add_argument("--dark", metavar="DARK.png", help="the dark frame at the frames' exposure")
    p.add_argument("--no-dark", action="store_true", help="read the frames without a dark frame")
    p.add_argument("--profile", metavar="PROFILE.json", help="the camera's calibration profile (default: shipped)")
    p.add_argument("--out", metavar="SHEET", help="the review sheet's folder (default: FOLDER-review)")
    p.add_argument("--accept", metavar="LABELS.jsonl", help="write these corrected labels as FOLDER/labels.jsonl")
    p.add_argument("--force", action="store_true", help="replace an existing sheet or labels.jsonl")


def run(args):
    from pathlib import Path

    from stcvision.errors import BadInputError

    root = Path(args.dir)
    if not root.is_dir():
        raise BadInputError(f"{root} is not a folder; expected a folder of frames")
    if args.accept:
        if args.dark or args.no_dark or args.out or args.profile:
            raise BadInputError("--accept writes the labels only; drop --dark/--no-dark/--out/--profile")
        from stcvision.review import accept_labels

        return {"mode": "accept", **accept_labels(root, args.accept, overwrite=args.force)}
    if bool(args.dark) == bool(args.no_dark):
        raise BadInputError("give --dark DARK.png (captured at the frames' exposure) or --no-dark")
    from stcvision.datasets import list_images
    from stcvision.fileio import check_output_folder, read_image
    from stcvision.limits import MAX_DATASET_FRAMES
    from stcvision.review import REVIEW_FILES, review_folder

    out = Path(args.out) if args.out else root.resolve().parent / f"{root.resolve().name}-review"
    check_output_folder(out, REVIEW_FILES, overwrite=args.force)
    paths = [p for p in list_images(root) if not args.dark or Path(p).resolve() != Path(args.dark).resolve()]
    if not paths:
        raise BadInputError(f"{root} holds no frames (.png, .tif, .jpg, ...)")
    if len(paths) > MAX_DATASET_FRAMES:
        raise BadInputError(f"{root} holds {len(paths)} frames; at most {MAX_DATASET_FRAMES} in one sheet")
    if args.profile:
        from stcvision.profile import Profile

        profile = Profile.load(args.profile)
    else:
        from stcvision.calibration.profiles import default_profile

        profile = default_profile()
    dark = read_image(args.dark, what="dark frame") if args.dark else None
    return {
        "mode": "sheet",
        **review_folder(paths, root=root, profile=profile, dark=dark, out=out, overwrite=args.force),
    }


def format_text(r):
    if r["mode"] == "accept":
        return (
            f"wrote {r['labels']}: {r['frames']} frames labelled ({r['boxes']} boxes and {r['neighbours']} neighbour "
            "fields set); score the pipeline with: stcvision eval FOLDER"
        )
    lines = [f"wrote the review sheet {r['sheet']} ({r['frames']} frames): open it, correct, make labels.jsonl"]
    lines += [f"untrusted {f}: label it from scratch" for f in r["untrusted"]]
    return "\n".join(lines)
