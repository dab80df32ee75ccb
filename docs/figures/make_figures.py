"""Regenerate the documentation's figures: ``python docs/figures/make_figures.py`` (inside .venv).

``docs/frame_and_lights_on.png``: a rendered dark-room frame beside the lights-on frame of the same
pose (the README's picture). ``docs/figures/pipeline_stages.png``: the same frame through the
pipeline's stages (the explanation page "The vision pipeline, stage by stage").
``docs/figures/target_uncertainty.png``: the projection-uncertainty map of ``calibrate target`` on
OpenCV's omnidirectional sample (the how-to "Calibrate from a checkerboard").
"""

from pathlib import Path

import cv2
import numpy as np

from stcvision.sim_camera.scene import EXAMPLE_SCENE, Scene

#: the figures folder (this script's own) and the docs folder above it, where the README's picture lives
FIGURES = Path(__file__).resolve().parent
DOCS = FIGURES.parent


def main() -> None:
    scene = Scene.from_dict(EXAMPLE_SCENE)
    cam = scene.camera()
    rng = np.random.default_rng(0)
    frame = cam.render(scene.pose, rng=rng, phosphor=scene.phosphor, red_lights_m=scene.red_lights_m).image
    dark = cam.median_dark(16, rng=rng)
    lit = cam.lights_on(scene.pose, board=scene.board, rng=rng).image
    shown = cv2.convertScaleAbs(cv2.subtract(frame, dark), alpha=6.0)  # 6x brighter to be seen
    crop = (slice(16, 464), slice(96, 544))  # the mirror
    pair = np.hstack([shown[crop], np.full((448, 8, 3), 255, np.uint8), lit[crop]])
    cv2.imwrite(str(DOCS / "frame_and_lights_on.png"), pair)
    print("wrote", DOCS / "frame_and_lights_on.png")
    stages_figure(frame, dark, FIGURES / "pipeline_stages.png")
    target_figure(FIGURES / "target_uncertainty.png")


def target_figure(path: Path) -> None:
    """The uncertainty map ``calibrate target`` writes for OpenCV's real omnidirectional sample."""
    from stcvision.calibration.target import calibrate_target, load_views

    views, _ = load_views(DOCS.parent / "datasets" / "peer_data" / "opencv_omnidir" / "omni_calib_data.xml")
    path.write_bytes(calibrate_target(views).png)
    print("wrote", path)


def stages_figure(frame: np.ndarray, dark: np.ndarray, path: Path) -> None:
    """The frame, dark-subtracted, unwarped with the reading drawn over it, and the two channel
    images the dot and red-light searches read."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from stcvision.calibration.profiles import default_profile
    from stcvision.fileio import write_figure
    from stcvision.pipeline import Pipeline

    pipe = Pipeline(default_profile(), dark=dark)
    r = pipe.process(frame)
    ground = pipe.ground_view(r.dark_subtracted)
    panels = [
        ("1 raw frame", cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)),
        ("2 dark-subtracted (6x)", cv2.cvtColor(cv2.convertScaleAbs(r.dark_subtracted, alpha=6.0), cv2.COLOR_BGR2RGB)),
        ("3 unwarped ground view (6x)", cv2.cvtColor(cv2.convertScaleAbs(ground, alpha=6.0), cv2.COLOR_BGR2RGB)),
        ("4 marks: green window sums", r.marks_u8()),
        ("5 obstacles: red window sums", r.obstacle_u8()),
    ]
    fig, axes = plt.subplots(1, 5, figsize=(17, 3.9))
    for ax, (title, img) in zip(axes, panels, strict=True):
        ax.imshow(img, cmap="gray" if img.ndim == 2 else None)
        ax.set_title(title, fontsize=10)
        ax.set_axis_off()
    d = r.dots
    lit_px = d.xy_px[d.lit]
    axes[3].scatter(lit_px[:, 0], lit_px[:, 1], s=30, facecolors="none", edgecolors="lime", linewidths=1)
    if len(r.red):
        axes[4].scatter(r.red.xy_px[:, 0], r.red.xy_px[:, 1], s=80, facecolors="none", edgecolors="red")
    lit_boxes = [b.box for b in r.observation.boxes if b.lit]
    fig.suptitle(
        f"{int(d.lit.sum())} dots found, heading error {np.degrees(r.heading.heading_error_rad):+.2f} deg, "
        f"lit boxes {lit_boxes}, {len(r.red)} red lights",
        fontsize=11,
    )
    fig.tight_layout()
    path.parent.mkdir(exist_ok=True)
    write_figure(path, fig, overwrite=True, dpi=80)
    print("wrote", path)


if __name__ == "__main__":
    main()
