"""Calibrate a robot's camera: dark frames, the mirror's rim, the transformation (phi/theta
model from a lights-on frame of the board grid) and the neighbours calibration (the 12 corners
of the five cells). Automatic, with a preview to check and a manual override, saved as a
versioned profile.

  stcvision calibrate dark FRAME... --out dark.png
  stcvision calibrate dark --bag FILE --topic TOPIC [--start S] [--end S] --out dark.png
  stcvision calibrate rim FRAME
  stcvision calibrate transform FRAME --out PROFILE.json [--center U,V] [--yes] [--force]
  stcvision calibrate neighbors FRAME --profile PROFILE.json [--points POINTS.json] [--yes]
  stcvision calibrate rim|transform|neighbors --bag FILE --topic TOPIC [--stamp S] ...
  stcvision calibrate import FILE --viewpoint-height-m H --out PROFILE.json [--format F] [--camera camN]
                             [--forward-angle-deg A] [--mirrored] [--rim-px R] [--lights-on FRAME] [--force]
  stcvision calibrate export PROFILE.json --format ocamcalib|omnidir|kalibr --out FILE [--force]
  stcvision calibrate target POINTS.xml|FOLDER [--camera 1|2] [--pattern P --board COLSxROWS --spacing S]
                             [--model mei|poly] [--folds K] [--uncertainty-png U.png]
                             [--out PROFILE.json --viewpoint-height-m H --lights-on FRAME] [--force]
  stcvision calibrate rescale PROFILE.json --size WxH --out PROFILE.json [--force]

Wherever a step reads one frame (rim, transform, neighbors, and the lights-on frame of import
and target), --bag FILE --topic TOPIC reads it from a recording (ROS 1/2 bag, MCAP): the message
whose header stamp is --stamp S (seconds, as the pipeline prints them), or the first.

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
    d.add_argument("frames", nargs="*", metavar="FRAME")
    d.add_argument("--bag", metavar="FILE", help="the dark frames of a recording (ROS 1/2 bag, MCAP), with --topic")
    d.add_argument("--topic", metavar="TOPIC", help="--bag: the image topic")
    d.add_argument("--start", type=float, default=0.0, metavar="S", help="--bag: seconds from the recording's start")
    d.add_argument("--end", type=float, metavar="S", help="--bag: up to S seconds from the recording's start")
    d.add_argument("--out", required=True, metavar="DARK.png")
    d.add_argument("--force", action="store_true", help="overwrite --out")
    r = sub.add_parser(
        "rim",
        help="find the mirror's rim circle in a frame",
        description="The mirror's rim circle (centre, radius, fit residual) in any catadioptric image.",
    )
    r.add_argument("frame", nargs="?", metavar="FRAME")
    t = sub.add_parser(
        "transform",
        help="fit the phi/theta model to a lights-on frame of the grid",
        description="Find the rim, fit the grid, write a preview PNG, ask, write the profile.",
    )
    t.add_argument("frame", nargs="?", metavar="FRAME")
    t.add_argument("--out", required=True, metavar="PROFILE.json")
    t.add_argument(
        "--center", type=pair(float, fmt="U,V", example="320,240"), metavar="U,V", help="mirror centre by hand (pixels)"
    )

    _add_subcell_m(t, float)  # its range is checked with the mount's (_check_mount_ranges)
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
    n.add_argument("frame", nargs="?", metavar="FRAME")
    n.add_argument("--profile", required=True, metavar="PROFILE.json")
    n.add_argument("--points", metavar="POINTS.json", help="12 [x, y] ground-view points made by a person")
    n.add_argument("--out", metavar="PROFILE.json", help="write here instead of updating --profile")
    n.add_argument("--preview", metavar="PNG", help="preview image (default: PROFILE.neighbors.png)")
    n.add_argument("--yes", action="store_true", help="accept without asking")
    n.add_argument("--force", action="store_true", help="overwrite an existing --out or preview")
    i, e = _add_lens_file_parsers(sub)
    g, s = _add_target_parsers(sub)
    for q in (r, t, n, i, g):
        _add_bag_frame(q, "FRAME" if q in (r, t, n) else "--lights-on FRAME")
    for q in (d, r, t, n, i, e, g, s):
        q.add_argument("--json", action="store_true", help="print the result as one JSON object")


def _add_subcell_m(q, type_) -> None:
    """--subcell-m: the board's sub-cell side, for the steps that fit the mount to the floor's grid."""
    from stcvision.stc_geometry import DEFAULT_SUBCELL_M

    q.add_argument(
        "--subcell-m",
        type=type_,
        default=DEFAULT_SUBCELL_M,
        help=f"sub-cell side D of the board (default {DEFAULT_SUBCELL_M})",
    )


def _add_bag_frame(q, instead: str) -> None:
    """--bag, --topic and --stamp: the one frame a step reads, from a recording."""
    q.add_argument("--bag", metavar="FILE", help=f"instead of {instead}: a recording (ROS 1/2 bag, MCAP), with --topic")
    q.add_argument("--topic", metavar="TOPIC", help="--bag: the image topic")
    q.add_argument(
        "--stamp", metavar="S", help="--bag: the message with this header stamp (seconds; default: the first)"
    )


def _one_frame(args, path, what: str, *, flag: str = "FRAME", required: bool = True):
    """The frame a step reads: the file ``path`` or, with --bag, one message of a recording
    (:func:`stcvision.bags.read_frame`). Returns (image, its name), or (None, None) when
    neither is given and the frame is optional."""
    from stcvision.errors import BadInputError

    if args.bag is None:
        if args.topic is not None or args.stamp is not None:
            raise BadInputError("--topic and --stamp go with --bag FILE")
        if path is None:
            if required:
                raise BadInputError(f"no {what}: give {flag} or --bag FILE --topic TOPIC [--stamp S]")
            return None, None
        from stcvision.fileio import read_image

        return read_image(path, what=what), f"{what} {path}"
    if path is not None:
        raise BadInputError(f"give {flag} or --bag FILE --topic TOPIC, not both")
    if args.topic is None:
        raise BadInputError("--bag FILE and --topic TOPIC go together")
    from stcvision.bags import parse_stamp, read_frame

    image, name = read_frame(args.bag, args.topic, stamp_ns=None if args.stamp is None else parse_stamp(args.stamp))
    return image, f"{what}: {name}"


def _add_lens_file_parsers(sub):
    """The ``import`` and ``export`` steps: profiles from and to other tools' calibration files."""
    from stcvision.cli._args import pair, positive

    i = sub.add_parser(
        "import",
        help="make a profile from an OCamCalib, Kalibr or OpenCV omnidir calibration",
        description="Read another tool's calibration (format detected from the content) and write the profile "
        "the pipeline uses. The floor is the plane perpendicular to the model's axis, H from its viewpoint, on the "
        "side the centre pixel's ray points to. Checked against the model's own equations: refused if the profile's "
        "floor differs by more than 0.05 degrees of elevation where rays meet the floor within 75 degrees of the axis.",
    )
    i.add_argument("file", metavar="FILE")
    i.add_argument(
        "--viewpoint-height-m",
        type=positive(float),
        required=True,
        metavar="H",
        help="height of the model's viewpoint above the floor (m)",
    )
    i.add_argument("--out", required=True, metavar="PROFILE.json")
    i.add_argument("--format", choices=("ocamcalib", "kalibr", "omnidir"), help="the file's format (default: detected)")
    i.add_argument("--camera", metavar="camN", help="the camera of a Kalibr chain holding several")
    i.add_argument(
        "--forward-angle-deg",
        type=float,
        default=-90.0,
        metavar="A",
        help="image angle atan2(v - cv, u - cu) at which robot-forward appears (default -90: up the image)",
    )
    i.add_argument(
        "--mirrored",
        action="store_true",
        help="the model's frame is the mirror image of the world (a camera looking at a mirror, "
        "calibrated on planar targets, which cannot tell): robot-left then turns the other way",
    )
    i.add_argument(
        "--rim-px",
        type=positive(float),
        metavar="R",
        help="the mirror rim's radius (px; `calibrate rim` measures it); default: the model's field of view",
    )
    i.add_argument(
        "--axis-tilt-deg",
        type=pair(float, fmt="X,Y", example="0.2,-0.1"),
        default=(0.0, 0.0),
        metavar="X,Y",
        help="lean of the model's axis against the floor's normal (the mount; default 0,0)",
    )
    i.add_argument(
        "--image-size",
        type=pair(int, fmt="WxH", example="640x480"),
        metavar="WxH",
        help="image size, for an omnidir file that does not store it",
    )
    i.add_argument(
        "--lights-on",
        metavar="FRAME",
        help="a lights-on frame of the grid at the calibration pose (as for transform): fit the forward angle, "
        "mirror flip and height to it (--forward-angle-deg within 45 degrees tells forward from left), measure the "
        "rim and find the 12 corners; the file's intrinsics are kept",
    )
    _add_subcell_m(i, positive(float))
    i.add_argument("--force", action="store_true", help="overwrite --out")
    e = sub.add_parser(
        "export",
        help="write a profile as an OCamCalib, OpenCV omnidir or Kalibr calibration",
        description="Fit the format's model to the profile's rays inside its rim and write it; refused if it "
        "cannot follow the profile to --max-error-deg. Prints the import flags that give the profile back.",
    )
    e.add_argument("profile", metavar="PROFILE.json")
    e.add_argument("--format", required=True, choices=("ocamcalib", "omnidir", "kalibr"))
    e.add_argument("--out", required=True, metavar="FILE")
    e.add_argument(
        "--max-error-deg",
        type=positive(float),
        default=0.05,
        help="worst elevation error accepted inside the rim (default 0.05)",
    )
    e.add_argument("--force", action="store_true", help="overwrite --out")
    return i, e


def _add_target_parsers(sub):
    """The ``target`` and ``rescale`` steps."""
    from stcvision.calibration.target_options import DEFAULT_FOLDS, MODELS, PATTERNS
    from stcvision.cli._args import pair, positive

    g = sub.add_parser(
        "target",
        help="intrinsics from planar targets (checkerboard / circle-grid images or OpenCV points files)",
        description="Fit Mei's unified model and OCamCalib's polynomial to views of a planar target, test each "
        "by k-fold over the views (held-out RMS) and by two calibrations on disjoint halves, and map the chosen "
        "model's projection uncertainty. With --out, the profile: its mount from a lights-on frame, its floor "
        "uncertainty (mm at 0.1-0.9 m) and a verdict on whether the STC robot can work with it.",
    )
    g.add_argument("source", metavar="POINTS|FOLDER", help="an OpenCV FileStorage points file or a folder of images")
    g.add_argument("--camera", type=int, choices=(1, 2), help="the camera of a stereo points file")
    g.add_argument(
        "--image-size", type=pair(int, fmt="WxH", example="1280x960"), metavar="WxH", help="for a file without one"
    )
    g.add_argument("--pattern", choices=PATTERNS, help="the target in the images")
    g.add_argument(
        "--board",
        type=pair(int, fmt="COLSxROWS", example="9x6"),
        metavar="COLSxROWS",
        help="inner corners (or circles) per row and per column",
    )
    g.add_argument("--spacing", type=positive(float), metavar="S", help="distance between neighbouring points (m)")
    g.add_argument(
        "--model",
        choices=tuple(MODELS),
        help="fit this model only (default: all; the richer chosen only when better held out beyond its error)",
    )
    g.add_argument(
        "--folds", type=int, default=DEFAULT_FOLDS, metavar="K", help=f"k-fold over views (default {DEFAULT_FOLDS})"
    )
    g.add_argument(
        "--uncertainty-png", metavar="PNG", help="the uncertainty map (default: SOURCE's name + .uncertainty.png here)"
    )
    g.add_argument("--out", metavar="PROFILE.json", help="also write the profile (needs --viewpoint-height-m)")
    g.add_argument("--viewpoint-height-m", type=positive(float), metavar="H", help="the viewpoint's height (m)")
    g.add_argument("--lights-on", metavar="FRAME", help="fit the mount to this lights-on frame of the grid")
    g.add_argument("--forward-angle-deg", type=float, default=-90.0, metavar="A", help="as for import (default -90)")
    g.add_argument("--mirrored", action="store_true", help="as for import")
    g.add_argument("--rim-px", type=positive(float), metavar="R", help="as for import")
    _add_subcell_m(g, positive(float))
    g.add_argument("--force", action="store_true", help="overwrite --out and the map")
    s = sub.add_parser(
        "rescale",
        help="a profile for the same camera run at another resolution",
        description="Scale a profile's pixel quantities to a camera run at another resolution (same sensor area, "
        "scaled: a binned or resized mode); the aspect ratio must be kept.",
    )
    s.add_argument("profile", metavar="PROFILE.json")
    s.add_argument("--size", required=True, type=pair(int, fmt="WxH", example="640x480"), metavar="WxH")
    s.add_argument("--out", required=True, metavar="PROFILE.json")
    s.add_argument(
        "--native",
        action="store_true",
        help="the camera's own mode at this size (independent pixel noise), not frames resized from the "
        "calibrated size (area-averaged down, interpolated up: the default)",
    )
    s.add_argument("--force", action="store_true", help="overwrite --out")
    return g, s


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
        raise BadInputError(
            "calibrate needs a step: dark, rim, transform, neighbors, import, export, target or rescale (see --help)"
        )
    steps = {"dark": _dark, "rim": _rim, "transform": _transform, "neighbors": _neighbors}
    more = {"import": _import, "export": _export, "target": _target, "rescale": _rescale}
    r = {**steps, **more}[args.step](args)
    return {"step": args.step, **r}


def _import(args):
    import math

    from stcvision.calibration.lens_files import read_lens_file
    from stcvision.calibration.lens_import import profile_from_model
    from stcvision.errors import OutputError
    from stcvision.fileio import check_output_file

    if not str(args.out).lower().endswith(".json"):
        raise OutputError(f"profile {args.out} does not end in .json; expected a .json file name")
    check_output_file(args.out, overwrite=args.force, what="profile")
    model, fmt = read_lens_file(args.file, fmt=args.format, camera=args.camera, image_size=args.image_size)
    prof, fid = profile_from_model(
        model,
        viewpoint_height_m=args.viewpoint_height_m,
        forward_angle_rad=math.radians(args.forward_angle_deg),
        mirrored=args.mirrored,
        rim_radius_px=args.rim_px,
        axis_tilt_rad=tuple(math.radians(t) for t in args.axis_tilt_deg),
        provenance={
            "method": f"imported from {fmt}",
            "file": str(args.file),
            "lens_model": _model_name(model),
            "forward_angle_deg": args.forward_angle_deg,
            "model_frame_mirrored": bool(args.mirrored),
        },
    )
    prof = prof.replace(subcell_m=args.subcell_m)
    mount = {}
    frame, name = _one_frame(args, args.lights_on, "lights-on frame", flag="--lights-on FRAME", required=False)
    if frame is not None:
        from stcvision.calibration.transform import calibrate_mount

        prof, rep = calibrate_mount(frame, prof, subcell_m=args.subcell_m)
        prof = prof.replace(provenance={**prof.provenance, "lights_on_frame": _source_of(args, args.lights_on, name)})
        mount = {
            "forward_angle_deg": math.degrees(prof.forward_angle_rad),
            "viewpoint_height_m": prof.viewpoint_height_m,
            "line_points": rep.line_points,
            "line_err_mm_median": rep.line_err_mm_median,
            "line_err_mm_max": rep.line_err_mm_max,
        }
    prof.save(args.out, overwrite=args.force)
    return {
        "out": str(args.out),
        "format": fmt,
        "lens_model": _model_name(model),
        "image_size_px": list(prof.image_size_px),
        "center_px": list(prof.center_px),
        "rim_radius_px": prof.rim_radius_px,
        "rim_measured": prof.rim_measured,
        "mirrored": prof.mirrored,
        "theta_degree": len(prof.theta_poly) - 1,
        **fid.to_dict(),
        **({"lights_on_fit": mount} if mount else {}),
    }


def _target(args):
    import math
    from pathlib import Path

    from stcvision.calibration.target import calibrate_target, load_views, target_profile
    from stcvision.errors import BadInputError, OutputError
    from stcvision.fileio import check_output_file, raise_if_signalled, write_bytes_atomic

    png = args.uncertainty_png or f"{Path(args.source).resolve().name or 'target'}.uncertainty.png"
    if Path(png).suffix.lower() != ".png":
        raise OutputError(f"uncertainty map {png} does not end in .png; expected a .png file name")
    check_output_file(png, overwrite=args.force or _own_preview(png), what="uncertainty map")
    if args.out is not None:
        if not str(args.out).lower().endswith(".json"):
            raise OutputError(f"profile {args.out} does not end in .json; expected a .json file name")
        if args.viewpoint_height_m is None:
            raise BadInputError("--out needs --viewpoint-height-m (the first guess the lights-on frame refines)")
        check_output_file(args.out, overwrite=args.force, what="profile")
        floor_png_path = str(Path(args.out).with_suffix(".floor.png"))
        if Path(floor_png_path).resolve() == Path(png).resolve():
            raise OutputError(f"--uncertainty-png {png} is where the floor plot goes; expected another file name")
        check_output_file(floor_png_path, overwrite=args.force, what="floor uncertainty plot")
        _check_mount_ranges(args.subcell_m, args.viewpoint_height_m)
    elif args.lights_on or args.bag or args.viewpoint_height_m:
        raise BadInputError(
            "--lights-on (or --bag) and --viewpoint-height-m make a profile: give --out PROFILE.json too"
        )
    frame, name = _one_frame(args, args.lights_on, "lights-on frame", flag="--lights-on FRAME", required=False)
    views, kind = load_views(
        args.source,
        camera=args.camera,
        image_size=args.image_size,
        pattern=args.pattern,
        board=args.board,
        spacing=args.spacing,
        should_stop=raise_if_signalled,
    )
    res = calibrate_target(views, model=args.model, folds=args.folds, should_stop=raise_if_signalled)
    rep = {"source": str(args.source), "source_kind": kind, **res.report}
    if args.out is not None:
        prof, floor, floor_png = target_profile(
            res.fit,
            viewpoint_height_m=args.viewpoint_height_m,
            forward_angle_rad=math.radians(args.forward_angle_deg),
            mirrored=args.mirrored,
            rim_px=args.rim_px,
            subcell_m=args.subcell_m,
            lights_on=frame,
            provenance={
                "method": f"calibrate target ({rep['model']} model on {len(views)} views of a planar target)",
                "source": str(args.source),
                "rms_px": rep["rms_px"],
                "heldout_rms_px": rep["heldout_rms_px"],
                **({"lights_on_frame": _source_of(args, args.lights_on, name)} if frame is not None else {}),
            },
            n_views=len(views),
            heldout_ratio=rep["heldout_rms_px"] / rep["rms_px"],
            cv_ratio=rep["cross_validation"].get("diff_over_predicted", 1.0),
        )
        prof.save(args.out, overwrite=args.force)
        write_bytes_atomic(floor_png_path, _tag_png(floor_png), overwrite=True)  # checked above
        rep.update(out=str(args.out), **floor, floor_png=floor_png_path)
    write_bytes_atomic(png, _tag_png(res.png), overwrite=True)  # checked above
    rep["uncertainty_png"] = png
    return rep


def _rescale(args):
    from stcvision.calibration.rescale import rescale_profile
    from stcvision.errors import OutputError
    from stcvision.fileio import check_output_file
    from stcvision.profile import Profile

    if not str(args.out).lower().endswith(".json"):
        raise OutputError(f"profile {args.out} does not end in .json; expected a .json file name")
    check_output_file(args.out, overwrite=args.force, what="profile")
    prof = rescale_profile(Profile.load(args.profile), tuple(args.size), native=args.native)
    prof.save(args.out, overwrite=args.force)
    return {
        "out": str(args.out),
        "image_size_px": list(prof.image_size_px),
        "scale": prof.provenance["rescaled"],
        "pixel_scale": prof.pixel_scale,
        "resampling": prof.resampling,
    }


def _model_name(model) -> str:
    if model.kind == "poly":
        return "polynomial with decentering"
    if model.kind == "ocamcalib":
        return f"ocamcalib ({len(model.ss)} ss terms)"
    return f"{model.projection}-{model.distortion}"


def _export(args):
    from stcvision.calibration.lens_files import write_lens_file
    from stcvision.calibration.lens_import import model_from_profile
    from stcvision.fileio import check_output_file
    from stcvision.profile import Profile

    check_output_file(args.out, overwrite=args.force, what="calibration file")
    prof = Profile.load(args.profile)
    model, fid, flags = model_from_profile(prof, args.format, max_err_deg=args.max_error_deg)
    write_lens_file(args.out, model, args.format, overwrite=args.force)
    cmd = (
        f"stcvision calibrate import {args.out} --viewpoint-height-m {flags['viewpoint_height_m']:.6g} "
        f"--forward-angle-deg {flags['forward_angle_deg']:.6f} --rim-px {flags['rim_px']:.4f}"
        + (" --mirrored" if flags["mirrored"] else "")
        + (
            f" --axis-tilt-deg={flags['axis_tilt_deg'][0]:.6f},{flags['axis_tilt_deg'][1]:.6f}"
            if any(flags["axis_tilt_deg"])
            else ""
        )
        + " --out PROFILE.json"
    )
    return {"out": str(args.out), "format": args.format, **fid.to_dict(), "import_flags": flags, "import_command": cmd}


#: what a dark frame may be written as: lossless only (JPEG would blur the hot pixels away)
DARK_SUFFIXES = (".png", ".tif", ".tiff")


def _dark(args):
    from pathlib import Path

    import numpy as np

    from stcvision.calibration.dark import median_dark
    from stcvision.errors import BadInputError
    from stcvision.fileio import check_output_file, read_image, read_json, write_image
    from stcvision.stages import hot_pixels

    out = check_output_file(args.out, overwrite=args.force, what="dark frame")
    if out.suffix.lower() not in DARK_SUFFIXES:
        raise BadInputError(
            f"--out {out}: a dark frame must be stored losslessly; expected .png (JPEG loses the hot pixels)"
        )
    if bool(args.frames) == (args.bag is not None):
        raise BadInputError("give dark FRAME files or --bag FILE --topic TOPIC, one of them")
    if args.bag is not None:
        frames, names = _bag_darks(args)
        exposures = []
    else:
        if args.topic is not None or args.start or args.end is not None:
            raise BadInputError("--topic, --start and --end apply to --bag")
        lossy = [f for f in args.frames if Path(f).suffix.lower() not in DARK_SUFFIXES]
        if lossy:
            raise BadInputError(
                f"{lossy[0]}: a dark frame must be taken losslessly; expected .png or .tiff frames (JPEG smears the "
                "hot pixels and the fixed pattern the subtraction removes)"
            )
        frames, exposures, names = [], [], [str(f) for f in args.frames]
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
    dark = median_dark(frames, names)  # 8 or 16 bits, as taken
    write_image(out, dark, overwrite=args.force)
    hot = hot_pixels(dark)
    return {
        "out": str(out),
        "frames": len(frames),
        "hot_pixels": int(len(np.unique(hot // 3))),
        "mean_dn": float(dark.mean()),
    }


def _bag_darks(args):
    """The dark frames of a recording's topic (all of them, or those recorded in --start..--end):
    at most MAX_DARK_FRAMES, held in memory for the median; never JPEG-compressed ones."""
    import math

    from stcvision.bags import open_bag
    from stcvision.errors import BadInputError
    from stcvision.limits import MAX_DARK_FRAMES

    if args.topic is None:
        raise BadInputError("--bag FILE and --topic TOPIC go together")
    for flag, v in (("--start", args.start), ("--end", args.end)):
        if v is not None and (not math.isfinite(v) or v < 0):
            raise BadInputError(f"{flag} {v}: expected seconds >= 0 from the recording's start")
    if args.end is not None and args.end <= args.start:
        raise BadInputError(f"--end {args.end:g} must be after --start {args.start:g}")
    src = open_bag(args.bag, args.topic)
    frames, names = [], []
    try:
        for f in src.frames(start_s=args.start, end_s=args.end, count=MAX_DARK_FRAMES + 1):
            if src.encoding == "jpeg":
                raise BadInputError(
                    f"{src.name}: {args.topic} is JPEG-compressed; a dark frame must be taken losslessly (JPEG smears "
                    "the hot pixels and the fixed pattern the subtraction removes)"
                )
            if len(frames) == MAX_DARK_FRAMES:
                raise BadInputError(
                    f"{src.name}: more than {MAX_DARK_FRAMES} frames on {args.topic} (the cap of frames held in memory "
                    "for the median, MAX_DARK_FRAMES); choose a window with --start and --end"
                )
            frames.append(f.image)
            names.append(f"frame {f.index} of {src.name}")
    finally:
        src.close()
    if not frames:
        raise BadInputError(f"{src.name}: no frame on {args.topic} in the window given")
    return frames, names


def _sidecar_exposure(d, path) -> float:
    import math

    from stcvision.errors import BadInputError

    v = d.get("exposure_s") if isinstance(d, dict) else None
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
        raise BadInputError(f"frame sidecar {path}: expected an object with exposure_s, a number > 0 (seconds)")
    return float(v)


def _rim(args):
    from stcvision.calibration.rim import detect_rim

    frame, name = _one_frame(args, args.frame, "frame")
    return {**detect_rim(frame).to_dict(), **({"frame": name} if args.bag else {})}


def _source_of(args, path, name: str) -> str:
    """A frame's source as a profile's provenance keeps it: the file as given, or the recording's
    file, topic and stamp."""
    return str(path) if args.bag is None else name


#: the PNG text chunk that marks a preview this command wrote: a re-run (e.g. with --yes after
#: looking at it) replaces its own preview, never a user's file of the same name without --force
PREVIEW_TAG = b"Software\x00stcvision calibrate preview"


def _preview_png(image) -> bytes:
    """``image`` as PNG bytes with :data:`PREVIEW_TAG` as a tEXt chunk before IEND."""
    from stcvision.fileio import image_bytes

    return _tag_png(image_bytes(image, ".png"))


def _tag_png(png: bytes) -> bytes:
    """PNG bytes with :data:`PREVIEW_TAG` as a tEXt chunk before IEND."""
    import struct
    import zlib

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


def _check_mount_ranges(subcell_m: float, viewpoint_m: float, *, flag: str = "--viewpoint-height-m") -> None:
    """The board's sub-cell and the viewpoint's height within what the grid fits sample."""
    from stcvision.errors import BadInputError
    from stcvision.limits import (
        MAX_CALIBRATION_SUBCELL_M,
        MAX_VIEWPOINT_M,
        MIN_CALIBRATION_SUBCELL_M,
        MIN_VIEWPOINT_M,
    )

    if not MIN_CALIBRATION_SUBCELL_M <= subcell_m <= MAX_CALIBRATION_SUBCELL_M:
        raise BadInputError(
            f"--subcell-m must be in [{MIN_CALIBRATION_SUBCELL_M:g}, {MAX_CALIBRATION_SUBCELL_M:g}] m (the fit "
            f"samples grid lines every cm out to 1 m), got {subcell_m:g}"
        )
    if not MIN_VIEWPOINT_M <= viewpoint_m <= MAX_VIEWPOINT_M:
        raise BadInputError(f"{flag} must be in [{MIN_VIEWPOINT_M:g}, {MAX_VIEWPOINT_M:g}] m, got {viewpoint_m:g}")


def _transform(args):
    from pathlib import Path

    from stcvision.calibration.transform import calibrate_neighbors, calibrate_transform, draw_preview
    from stcvision.errors import BadInputError

    preview = args.preview or str(Path(args.out).with_suffix(".preview.png"))
    _check_outputs(args, args.out, preview, out_force=args.force)
    _check_mount_ranges(args.subcell_m, args.viewpoint_m, flag="--viewpoint-m")
    frame, name = _one_frame(args, args.frame, "lights-on frame")
    prof, rep = calibrate_transform(
        frame, subcell_m=args.subcell_m, center_px=args.center, viewpoint_height_m=args.viewpoint_m
    )
    prof = prof.replace(provenance={**prof.provenance, "frame": _source_of(args, args.frame, name)})
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

    from stcvision.calibration.rim import check_rim_matches
    from stcvision.calibration.transform import calibrate_neighbors, draw_preview, with_corners
    from stcvision.errors import BadInputError
    from stcvision.fileio import read_json
    from stcvision.profile import Profile

    out = args.out or args.profile
    preview = args.preview or str(Path(out).with_suffix(".neighbors.png"))
    # updating --profile in place is what the command is for; another existing --out needs --force
    _check_outputs(args, out, preview, out_force=args.force or args.out is None)
    prof = Profile.load(args.profile)
    frame, name = _one_frame(args, args.frame, "lights-on frame")
    prof.check_frame(frame.shape, what=name)
    rim = check_rim_matches(
        frame, prof, frame_name=_source_of(args, args.frame, name), profile_name=f"profile {args.profile}"
    )
    if rim is None and not args.points:
        raise BadInputError(
            f"{name} shows no mirror rim, so no grid to find corners on; expected a lights-on "
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
    if step in ("import", "export"):
        fit = (
            f"; the profile against the {r['format']} model over {r['n_pixels']:,} pixels: ray elevation "
            f"{r['elevation_err_deg_max']:.4f} deg at worst, azimuth {r['azimuth_err_deg_max']:.4f} deg"
        )
        if step == "import":
            return f"wrote {r['out']} ({r['lens_model']}){fit}"
        return f"wrote {r['out']}{fit}\nimport it back with: {r['import_command']}"
    if step == "target":
        return _target_text(r)
    if step == "rescale":
        return (
            f"wrote {r['out']}: the profile at {r['image_size_px'][0]}x{r['image_size_px'][1]} (x{r['scale']:.4g}; "
            f"x{r['pixel_scale']:.4g} the calibrated camera's pixels, frames {r['resampling']} resampled)"
        )
    return f"wrote {r['out']}: {len(r['corners_px'])} neighbour corners (preview {r['preview']})"


def _target_text(r) -> str:
    lines = [f"{r['views']} views, {r['points']} points ({r['source_kind']} {r['source']})"]
    lines += [f"  refused {x['view']}: {x['reason']}" for x in r["refused_views"]]
    lines.append(f"model            in-sample RMS   held-out RMS ({r['folds']}-fold)")
    for name, m in r["models"].items():
        if "failed" in m:
            lines.append(f"{name:<16} not fitted: {m['failed']}")
            continue
        mark = " <- chosen" if name == r["model"] else ""
        lines.append(f"{name:<16} {m['rms_px']:.3f} px       {m['heldout_rms_px']:.3f} px{mark}")
    cv = r["cross_validation"]
    if "failed" in cv:
        lines.append(f"two halves of the views could not be calibrated apart: {cv['failed']}")
    else:
        lines.append(
            f"two halves of the views differ by {cv['diff_px_median']:.2f} px (median) where their uncertainties "
            f"predict {cv['predicted_px_median']:.2f} px; {100 * cv['within_95_fraction']:.0f} % within the 95 % bound"
        )
    u = r["uncertainty"]
    lines.append(
        f"projection uncertainty where the target was seen: {u['sigma_px_median_where_observed']:.2f} px "
        f"(1 sigma, median), {u['r95_px_max_where_observed']:.2f} px (95 %, worst); map {r['uncertainty_png']}"
    )
    if r.get("mount"):
        m = r["mount"]
        lines.append(
            f"mount from the lights-on frame: forward {m['forward_angle_deg']:.2f} +- {m['forward_angle_deg_std']:.2f} "
            f"deg, height {1000 * m['viewpoint_height_m']:.1f} +- {m['viewpoint_height_mm_std']:.1f} mm, "
            f"{'mirrored' if m['mirrored'] else 'not mirrored'}; tape lines {m['line_err_mm_median']:.2f} mm off the "
            "model (median)"
        )
    if "floor" in r:
        fl = ", ".join(f"{x['distance_m']:g} m {x['r95_mm']:.1f}" for x in r["floor"] if x["r95_mm"] is not None)
        lines.append(f"floor, 95 % bound (mm): {fl}; plot {r['floor_png']}")
        v = r["verdict"]
        lines.append(
            "verdict: good enough for the STC robot"
            if v["ok"]
            else "verdict: not yet good enough for the STC robot: " + "; ".join(v["advice"])
        )
        lines.append(f"wrote {r['out']}")
    return "\n".join(lines)
