"""Render a synthetic catadioptric frame of a scene: writes frame.png (the dark-room frame),
dark.png (a median of dark frames at the same settings), lights_on.png (the lit calibration
frame at the same pose) and truth.json (ground truth) into --out. Frames have the camera's
ADC depth: 8-bit PNGs for the webcam, 16-bit PNGs holding the ADC counts for a 12- or 16-bit
sensor (``--camera lowlight|cooled|FILE.json``, or ``"sensor": {"adc_bits": 16}`` in the scene).

Print a documented example scene with --example-scene.
"""

from __future__ import annotations

OUTPUTS = ("frame.png", "dark.png", "lights_on.png", "truth.json")


def add_parser(p):
    p.add_argument("--scene", metavar="SCENE.json", help="scene description (see --example-scene)")
    p.add_argument("--out", metavar="DIR", help="output folder")
    p.add_argument("--seed", type=int, default=0, help="seed of the temporal noise (default 0)")
    p.add_argument(
        "--dark-frames", type=int, default=16, metavar="N", help="dark frames median-stacked into dark.png (default 16)"
    )
    p.add_argument(
        "--camera",
        metavar="NAME|FILE.json",
        help="camera profile whose sensor the scene's sensor overrides apply to (default webcam; "
        "see stcvision cover --list-cameras)",
    )
    p.add_argument("--force", action="store_true", help="overwrite existing outputs in --out")
    p.add_argument("--example-scene", action="store_true", help="print an example scene and exit")


def run(args):
    import json
    from pathlib import Path

    from stcvision.errors import BadInputError

    if args.example_scene:
        from sim_camera.scene import EXAMPLE_SCENE

        print(json.dumps(EXAMPLE_SCENE, indent=2))
        return 0
    if not args.scene or not args.out:
        raise BadInputError("render needs --scene SCENE.json and --out DIR (or --example-scene)")
    if args.dark_frames < 1:
        raise BadInputError(f"--dark-frames must be >= 1, got {args.dark_frames}")
    if args.seed < 0:
        raise BadInputError(f"--seed must be >= 0, got {args.seed}")
    import numpy as np

    from sim_camera.scene import Scene
    from stcvision.errors import FileExistsRefusedError
    from stcvision.fileio import write_image, write_json

    base = None
    if args.camera:
        from sim_camera.hardware import load_camera

        base = load_camera(args.camera).sensor
    scene = Scene.from_file(args.scene, sensor_base=base)
    out = Path(args.out)
    if not args.force:
        taken = [n for n in OUTPUTS if (out / n).exists()]
        if taken:
            raise FileExistsRefusedError(f"{out} already holds {', '.join(taken)}; use --force to overwrite")
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
    write_image(out / "frame.png", frame.image, overwrite=True)
    write_image(out / "dark.png", dark, overwrite=True)
    write_image(out / "lights_on.png", lit.image, overwrite=True)
    write_json(out / "truth.json", truth, overwrite=True)
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
