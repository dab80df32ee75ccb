"""Calibrate a robot's camera: dark frames, the mirror's rim, the transformation (phi/theta
model from a lights-on frame of the board grid) and the neighbours calibration (the 12 corners
of the five cells). Automatic, with a preview to check and a manual override, saved as a
versioned profile.

  stcvision calibrate dark FRAME... --out dark.png
  stcvision calibrate rim FRAME
  stcvision calibrate transform FRAME --out PROFILE.json [--center U,V] [--yes] [--force]
  stcvision calibrate neighbors FRAME --profile PROFILE.json [--points POINTS.json] [--yes]

For transform and neighbors the robot stands on the board with the room lights on, at the
centre of a sub-cell and facing along the grid (as when it enters a cell).
"""

from __future__ import annotations

import sys

NESTED = True  # --json belongs to each step


def add_parser(p):
    from stcvision.cli._args import pair

    sub = p.add_subparsers(dest="step", metavar="STEP", parser_class=type(p))
    d = sub.add_parser(
        "dark",
        help="median-stack dark frames into one",
        description="Median-stack dark frames "
        "(lens capped or room dark) taken at the exposure of the frames they will correct.",
    )
    d.add_argument("frames", nargs="+", metavar="FRAME")
    d.add_argument("--out", required=True, metavar="DARK.png")
    d.add_argument("--force", action="store_true", help="overwrite --out")
    r = sub.add_parser(
        "rim",
        help="find the mirror's rim circle in a frame",
        description="The mirror's rim circle (centre, radius, fit residual) in any catadioptric image.",
    )
    r.add_argument("frame", metavar="FRAME")
    t = sub.add_parser(
        "transform",
        help="fit the phi/theta model to a lights-on frame of the grid",
        description="Find the rim, fit the grid, write a preview PNG, ask, write the profile.",
    )
    t.add_argument("frame", metavar="FRAME")
    t.add_argument("--out", required=True, metavar="PROFILE.json")
    t.add_argument("--center", type=pair(float), metavar="U,V", help="mirror centre by hand (pixels)")
    t.add_argument("--subcell-m", type=float, default=0.16, help="sub-cell side D of the board (default 0.16)")
    t.add_argument(
        "--viewpoint-m",
        type=float,
        default=0.25,
        help="rough height of the mirror above the floor (default 0.25; theta absorbs the rest)",
    )
    t.add_argument("--preview", metavar="PNG", help="preview image (default: PROFILE.preview.png)")
    t.add_argument("--yes", action="store_true", help="accept without asking")
    t.add_argument("--force", action="store_true", help="overwrite an existing profile")
    n = sub.add_parser(
        "neighbors",
        help="find the 12 corners of the five cells and store them",
        description="Find the 12 corners of the current cell and its four neighbours in the "
        "ground view (or take them from --points), preview, store in the profile.",
    )
    n.add_argument("frame", metavar="FRAME")
    n.add_argument("--profile", required=True, metavar="PROFILE.json")
    n.add_argument("--points", metavar="POINTS.json", help="12 [x, y] ground-view points made by a person")
    n.add_argument("--out", metavar="PROFILE.json", help="write here instead of updating --profile")
    n.add_argument("--preview", metavar="PNG", help="preview image (default: PROFILE.neighbors.png)")
    n.add_argument("--yes", action="store_true", help="accept without asking")
    for q in (d, r, t, n):
        q.add_argument("--json", action="store_true", help="print the result as one JSON object")


def _confirm(preview: str, yes: bool) -> None:
    from stcvision.errors import BadInputError

    if yes:
        return
    if not sys.stdin.isatty():
        raise BadInputError(f"no terminal to confirm on: look at {preview} and re-run with --yes to accept")
    answer = input(f"Preview written to {preview}. Does this look right? [y/N] ").strip().lower()
    if answer not in ("y", "yes"):
        raise BadInputError("not accepted; nothing was written (try --center U,V, or --points for the corners)")


def run(args):
    from stcvision.errors import BadInputError

    if args.step is None:
        raise BadInputError("calibrate needs a step: dark, rim, transform or neighbors (see --help)")
    return {"dark": _dark, "rim": _rim, "transform": _transform, "neighbors": _neighbors}[args.step](args)


def _dark(args):
    from pathlib import Path

    import numpy as np

    from stcvision.errors import BadInputError, FileExistsRefusedError
    from stcvision.fileio import check_same_depth, read_image, read_json, write_image
    from stcvision.stages import hot_pixels

    if Path(args.out).exists() and not args.force:
        raise FileExistsRefusedError(f"{args.out} exists; refusing to overwrite it (use --force)")
    frames, exposures = [], []
    for f in args.frames:
        img = read_image(f, what="dark frame")
        if frames and img.shape != frames[0].shape:
            raise BadInputError(
                f"dark frame {f} is {img.shape[1]}x{img.shape[0]}, the first is "
                f"{frames[0].shape[1]}x{frames[0].shape[0]}; expected one size"
            )
        if frames:
            check_same_depth(frames[0], img, f, frame_path=args.frames[0])
        side = Path(f).with_suffix(".json")  # optional sidecar: {"exposure_s": ...}
        if side.exists():
            exposures.append(float(read_json(side, what="frame sidecar").get("exposure_s", "nan")))
        frames.append(img)
    if exposures and (max(exposures) - min(exposures) > 0.01 * max(exposures)):
        raise BadInputError(
            f"dark frames were taken at different exposures ({min(exposures):g}..{max(exposures):g} s); "
            "expected one exposure"
        )
    dark = np.median(np.stack(frames), axis=0).round().astype(frames[0].dtype)  # 8 or 16 bits, as taken
    write_image(args.out, dark, overwrite=True)
    hot = hot_pixels(dark)
    return {
        "out": args.out,
        "frames": len(frames),
        "hot_pixels": int(len(np.unique(hot // 3))),
        "mean_dn": float(dark.mean()),
    }


def _rim(args):
    from calibration.rim import detect_rim
    from stcvision.fileio import read_image

    return detect_rim(read_image(args.frame, what="frame")).to_dict()


def _transform(args):
    from pathlib import Path

    from calibration.transform import calibrate_neighbors, calibrate_transform, draw_preview
    from stcvision.errors import BadInputError, FileExistsRefusedError
    from stcvision.fileio import read_image, write_image

    if Path(args.out).exists() and not args.force:
        raise FileExistsRefusedError(f"profile {args.out} exists; refusing to overwrite it (use --force)")
    if not args.subcell_m > 0:
        raise BadInputError(f"--subcell-m must be > 0, got {args.subcell_m}")
    frame = read_image(args.frame, what="lights-on frame")
    prof, rep = calibrate_transform(
        frame, subcell_m=args.subcell_m, center_px=args.center, viewpoint_height_m=args.viewpoint_m
    )
    prof = prof.replace(provenance={**prof.provenance, "frame": str(args.frame)})
    try:  # the corners too, when they are where the transformation puts them
        prof, _ = calibrate_neighbors(frame, prof)
    except BadInputError:
        pass
    preview = args.preview or str(Path(args.out).with_suffix(".preview.png"))
    write_image(preview, draw_preview(frame, prof), overwrite=True)
    _confirm(preview, args.yes)
    prof.save(args.out, overwrite=args.force)
    return {"out": args.out, "preview": preview, **rep.to_dict()}


def _neighbors(args):
    from pathlib import Path

    from calibration.transform import calibrate_neighbors, draw_preview, with_corners
    from stcvision.fileio import read_image, read_json, write_image
    from stcvision.profile import Profile

    prof = Profile.load(args.profile)
    frame = read_image(args.frame, what="lights-on frame")
    prof.check_frame(frame.shape)
    if args.points:
        prof = with_corners(prof, read_json(args.points, what="points file"), method=f"by hand: {args.points}")
    else:
        prof, _ = calibrate_neighbors(frame, prof)
    out = args.out or args.profile
    preview = args.preview or str(Path(out).with_suffix(".neighbors.png"))
    write_image(preview, draw_preview(frame, prof), overwrite=True)
    _confirm(preview, args.yes)
    prof.save(out, overwrite=True)
    return {"out": out, "preview": preview, "corners_px": [list(p) for p in prof.neighbour_corners_px]}


def format_text(r):
    from stcvision.fileio import dumps

    return dumps(r)
