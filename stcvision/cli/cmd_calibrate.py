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
    import argparse

    from stcvision.cli._args import pair

    p.formatter_class = argparse.RawDescriptionHelpFormatter  # the examples one per line, as written
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
    t.add_argument(
        "--center", type=pair(float, fmt="U,V", example="320,240"), metavar="U,V", help="mirror centre by hand (pixels)"
    )
    t.add_argument("--subcell-m", type=float, default=0.16, help="sub-cell side D of the board (default 0.16)")
    t.add_argument(
        "--viewpoint-m",
        type=float,
        default=0.25,
        help="rough height of the mirror above the floor (default 0.25; theta absorbs the rest)",
    )
    t.add_argument("--preview", metavar="PNG", help="preview image (default: PROFILE.preview.png)")
    t.add_argument("--yes", action="store_true", help="accept without asking")
    t.add_argument("--force", action="store_true", help="overwrite an existing profile and preview")
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
    n.add_argument("--force", action="store_true", help="overwrite an existing --out or preview")
    for q in (d, r, t, n):
        q.add_argument("--json", action="store_true", help="print the result as one JSON object")


def _confirm(preview: str, yes: bool) -> None:
    from stcvision.errors import BadInputError

    if yes:
        return
    if not sys.stdin.isatty():
        raise BadInputError(
            f"no terminal to confirm on: the profile was not written; look at the preview {preview} and re-run "
            "with --yes to accept"
        )
    answer = input(f"Preview written to {preview}. Does this look right? [y/N] ").strip().lower()
    if answer not in ("y", "yes"):
        raise BadInputError(
            f"not accepted; the profile was not written, only the preview {preview} "
            "(try --center U,V, or --points for the corners)"
        )


def run(args):
    from stcvision.errors import BadInputError

    if args.step is None:
        raise BadInputError("calibrate needs a step: dark, rim, transform or neighbors (see --help)")
    r = {"dark": _dark, "rim": _rim, "transform": _transform, "neighbors": _neighbors}[args.step](args)
    return {"step": args.step, **r}


#: what a dark frame may be written as: lossless only (JPEG would blur the hot pixels away)
DARK_SUFFIXES = (".png", ".tif", ".tiff")


def _dark(args):
    from pathlib import Path

    import numpy as np

    from calibration.dark import median_dark
    from stcvision.errors import BadInputError
    from stcvision.fileio import check_output_file, read_image, read_json, write_image
    from stcvision.stages import hot_pixels

    out = check_output_file(args.out, overwrite=args.force, what="dark frame")
    if out.suffix.lower() not in DARK_SUFFIXES:
        raise BadInputError(
            f"--out {out}: a dark frame must be stored losslessly; expected .png (JPEG loses the hot pixels)"
        )
    frames, exposures = [], []
    for f in args.frames:
        frames.append(read_image(f, what="dark frame"))
        side = Path(f).with_suffix(".json")  # optional sidecar: {"exposure_s": ...}
        if side.exists():
            exposures.append(_sidecar_exposure(read_json(side, what="frame sidecar"), side))
    if exposures and (max(exposures) - min(exposures) > 0.01 * max(exposures)):
        raise BadInputError(
            f"dark frames were taken at different exposures ({min(exposures):g}..{max(exposures):g} s); "
            "expected one exposure"
        )
    dark = median_dark(frames, [str(f) for f in args.frames])  # 8 or 16 bits, as taken
    write_image(out, dark, overwrite=args.force)
    hot = hot_pixels(dark)
    return {
        "out": str(out),
        "frames": len(frames),
        "hot_pixels": int(len(np.unique(hot // 3))),
        "mean_dn": float(dark.mean()),
    }


def _sidecar_exposure(d, path) -> float:
    import math

    from stcvision.errors import BadInputError

    v = d.get("exposure_s") if isinstance(d, dict) else None
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
        raise BadInputError(f"frame sidecar {path}: expected an object with exposure_s, a number > 0 (seconds)")
    return float(v)


def _rim(args):
    from calibration.rim import detect_rim
    from stcvision.fileio import read_image

    return detect_rim(read_image(args.frame, what="frame")).to_dict()


#: the PNG text chunk that marks a preview this command wrote: a re-run (e.g. with --yes after
#: looking at it) replaces its own preview, never a user's file of the same name without --force
PREVIEW_TAG = b"Software\x00stcvision calibrate preview"


def _preview_png(image) -> bytes:
    """``image`` as PNG bytes with :data:`PREVIEW_TAG` as a tEXt chunk before IEND."""
    import struct
    import zlib

    from stcvision.fileio import image_bytes

    png = image_bytes(image, ".png")
    chunk = b"tEXt" + PREVIEW_TAG
    text = struct.pack(">I", len(PREVIEW_TAG)) + chunk + struct.pack(">I", zlib.crc32(chunk))
    return png[:-12] + text + png[-12:]  # IEND is the last 12 bytes


def _own_preview(path) -> bool:
    from pathlib import Path

    try:
        with open(Path(path), "rb") as f:
            return f.read(8) == b"\x89PNG\r\n\x1a\n" and PREVIEW_TAG in f.read()
    except OSError:
        return False


def _check_outputs(args, out: str, preview: str, *, out_force: bool) -> None:
    """Refuse, before any work, outputs that exist (without --force) or cannot be made; a preview
    this command wrote before is replaced."""
    from pathlib import Path

    from stcvision.errors import OutputError
    from stcvision.fileio import check_output_file

    for path, suffix, what in ((out, ".json", "profile"), (preview, ".png", "preview")):
        if Path(path).suffix.lower() != suffix:
            raise OutputError(f"{what} {path} does not end in {suffix}; expected a {suffix} file name")
    check_output_file(out, overwrite=out_force, what="profile")
    check_output_file(preview, overwrite=args.force or _own_preview(preview), what="preview")


def _write_preview(preview: str, image) -> None:
    from stcvision.fileio import write_bytes_atomic

    write_bytes_atomic(preview, _preview_png(image), overwrite=True)  # checked by _check_outputs


def _transform(args):
    from pathlib import Path

    from calibration.transform import calibrate_neighbors, calibrate_transform, draw_preview
    from stcvision.errors import BadInputError
    from stcvision.fileio import read_image

    preview = args.preview or str(Path(args.out).with_suffix(".preview.png"))
    _check_outputs(args, args.out, preview, out_force=args.force)
    from stcvision.limits import (
        MAX_CALIBRATION_SUBCELL_M,
        MAX_VIEWPOINT_M,
        MIN_CALIBRATION_SUBCELL_M,
        MIN_VIEWPOINT_M,
    )

    if not MIN_CALIBRATION_SUBCELL_M <= args.subcell_m <= MAX_CALIBRATION_SUBCELL_M:
        raise BadInputError(
            f"--subcell-m must be in [{MIN_CALIBRATION_SUBCELL_M:g}, {MAX_CALIBRATION_SUBCELL_M:g}] m (the fit "
            f"samples grid lines every cm out to 1 m), got {args.subcell_m:g}"
        )
    if not MIN_VIEWPOINT_M <= args.viewpoint_m <= MAX_VIEWPOINT_M:
        raise BadInputError(
            f"--viewpoint-m must be in [{MIN_VIEWPOINT_M:g}, {MAX_VIEWPOINT_M:g}] m, got {args.viewpoint_m:g}"
        )
    frame = read_image(args.frame, what="lights-on frame")
    prof, rep = calibrate_transform(
        frame, subcell_m=args.subcell_m, center_px=args.center, viewpoint_height_m=args.viewpoint_m
    )
    prof = prof.replace(provenance={**prof.provenance, "frame": str(args.frame)})
    import cv2

    try:  # the corners too, when they are where the transformation puts them
        prof, _ = calibrate_neighbors(frame, prof)
    except (BadInputError, cv2.error):  # optional: not found (or off the image), 'neighbors' asks again
        pass
    _write_preview(preview, draw_preview(frame, prof))
    _confirm(preview, args.yes)
    prof.save(args.out, overwrite=args.force)
    return {"out": args.out, "preview": preview, **rep.to_dict()}


def _neighbors(args):
    from pathlib import Path

    from calibration.rim import check_rim_matches
    from calibration.transform import calibrate_neighbors, draw_preview, with_corners
    from stcvision.errors import BadInputError
    from stcvision.fileio import read_image, read_json
    from stcvision.profile import Profile

    out = args.out or args.profile
    preview = args.preview or str(Path(out).with_suffix(".neighbors.png"))
    # updating --profile in place is what the command is for; another existing --out needs --force
    _check_outputs(args, out, preview, out_force=args.force or args.out is None)
    prof = Profile.load(args.profile)
    frame = read_image(args.frame, what="lights-on frame")
    prof.check_frame(frame.shape, what=f"lights-on frame {args.frame}")
    rim = check_rim_matches(frame, prof, frame_name=str(args.frame), profile_name=f"profile {args.profile}")
    if rim is None and not args.points:
        raise BadInputError(
            f"lights-on frame {args.frame} shows no mirror rim, so no grid to find corners on; expected a lights-on "
            "frame of the board (or give the corners with --points)"
        )
    if args.points:
        prof = with_corners(prof, read_json(args.points, what="points file"), method=f"by hand: {args.points}")
    else:
        prof, _ = calibrate_neighbors(frame, prof)
    _write_preview(preview, draw_preview(frame, prof))
    _confirm(preview, args.yes)
    prof.save(out, overwrite=True)
    return {"out": out, "preview": preview, "corners_px": [list(p) for p in prof.neighbour_corners_px]}


def _rim_text(rim: dict) -> str:
    (u, v), (a, b) = rim["center_px"], rim["ellipse_axes_px"]
    return (
        f"mirror rim: centre ({u:.1f}, {v:.1f}) px, radius {rim['radius_px']:.1f} px, fit residual "
        f"{rim['residual_px']:.2f} px over {100 * rim['coverage']:.0f} % of the circle ({rim['n_points']} edge "
        f"points); as an ellipse {a:.1f} x {b:.1f} px at {rim['ellipse_angle_deg']:.1f} deg"
    )


def format_text(r):
    """A person's summary of each step (--json gives every number)."""
    step = r["step"]
    if step == "dark":
        return (
            f"wrote {r['out']}: the median of {r['frames']} dark frame(s), {r['hot_pixels']} hot pixels, "
            f"mean {r['mean_dn']:.1f} DN"
        )
    if step == "rim":
        return _rim_text(r)
    if step == "transform":
        return "\n".join(
            [
                _rim_text(r["rim"]),
                f"grid: forward at {r['forward_angle_deg']:.1f} deg in the image; {r['line_points']} grid-line points "
                f"off the model by {r['line_err_mm_median']:.2f} mm (median), {r['line_err_mm_max']:.1f} mm (max)",
                f"wrote {r['out']} (preview {r['preview']})",
            ]
        )
    return f"wrote {r['out']}: {len(r['corners_px'])} neighbour corners (preview {r['preview']})"
