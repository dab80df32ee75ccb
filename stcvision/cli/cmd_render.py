"""Render a synthetic catadioptric frame of a scene: writes frame.png (the dark-room frame),
dark.png (a median of dark frames at the same settings), lights_on.png (the lit calibration
frame at the same pose) and truth.json (ground truth) into --out. Frames have the camera's
ADC depth: 8-bit PNGs for the webcam, 16-bit PNGs holding the ADC counts for a 12- or 16-bit
sensor (``--camera lowlight|cooled|FILE.json``, or ``"sensor": {"adc_bits": 16}`` in the scene).

Print a documented example scene with --example-scene.
"""

from __future__ import annotations

from stcvision.cli._args import positive, seed
from stcvision.limits import MAX_DARK_FRAMES

#: the set, written as one unit (truth.json, its marker, last: see stcvision.fileio.write_set)
OUTPUTS = ("frame.png", "dark.png", "lights_on.png", "truth.json")


def add_parser(p):
    p.add_argument("--scene", metavar="SCENE.json", help="scene description (see --example-scene)")
    p.add_argument("--out", metavar="DIR", help="output folder")
    p.add_argument("--seed", type=seed, default=0, help="seed of the temporal noise (default 0)")
    p.add_argument(
        "--dark-frames",
        type=positive(int, maximum=MAX_DARK_FRAMES, why="they are held in memory for the median"),
        default=16,
        metavar="N",
        help=f"dark frames median-stacked into dark.png (default 16, at most {MAX_DARK_FRAMES})",
    )
    p.add_argument(
        "--camera",
        metavar="NAME|FILE.json",
        help="camera profile whose sensor the scene's sensor overrides apply to (default webcam; "
        "see stcvision cover --list-cameras)",
    )
    p.add_argument("--force", action="store_true", help="overwrite existing outputs in --out")
    p.epilog = (
        "The four files appear together: a new (or empty) --out is made whole and renamed into place; into a "
        "folder holding other files, truth.json is written last (a set without it is incomplete: run again)."
    )
    p.add_argument("--example-scene", action="store_true", help="print an example scene and exit")


def run(args):
    import json

    from stcvision.errors import BadInputError

    if args.example_scene:
        from stcvision.sim_camera.scene import EXAMPLE_SCENE

        print(json.dumps(EXAMPLE_SCENE, indent=2))
        return 0
    if not args.scene or not args.out:
        raise BadInputError("render needs --scene SCENE.json and --out DIR (or --example-scene)")
    import numpy as np

    from stcvision.fileio import check_output_folder, dumps, image_bytes, write_set
    from stcvision.sim_camera.scene import Scene

    out = check_output_folder(args.out, OUTPUTS, overwrite=args.force)
    base = None
    if args.camera:
        from stcvision.sim_camera.hardware import load_camera

        base = load_camera(args.camera).sensor
    scene = Scene.from_file(args.scene, sensor_base=base)
    cam = scene.camera()
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(args.seed).spawn(3)]
    frame = cam.render(
        scene.pose,
        rng=rngs[0],
        t_s=scene.t_s,
        phosphor=scene.phosphor,
        red_lights_m=scene.red_lights_m,
        board=scene.board,
        truth=True,
    )
    dark = cam.median_dark(args.dark_frames, rng=rngs[1])
    lit = cam.lights_on(scene.pose, board=scene.board, rng=rngs[2])
    truth = frame.truth
    truth["scene"] = str(args.scene)
    truth["seed"] = args.seed
    truth["dark_frames"] = args.dark_frames
    images = (frame.image, dark, lit.image)
    files = {name: image_bytes(img) for name, img in zip(OUTPUTS, images, strict=False)}
    files[OUTPUTS[-1]] = (dumps(truth) + "\n").encode()
    write_set(out, files, overwrite=args.force)
    dots = truth["dots"]
    return {
        "out": str(out),
        "files": [str(out / n) for n in OUTPUTS],
        "dots": len(dots),
        "dots_visible": sum(d["visible"] for d in dots),
        "dots_detectable": sum(d["detectable"] for d in dots),
        "red_lights_visible": sum(r["visible"] for r in truth["red_lights"]),
        "pose": truth["pose"],
        "adc_bits": scene.sensor.adc_bits,
        "dtype": str(frame.image.dtype),
    }


def format_text(r):
    return (
        f"wrote {', '.join(r['files'])} ({r['adc_bits']}-bit ADC, {r['dtype']} PNGs)\n"
        f"dots: {r['dots']} ({r['dots_visible']} visible, {r['dots_detectable']} detectable at SNR>=5); "
        f"red lights visible: {r['red_lights_visible']}"
    )
