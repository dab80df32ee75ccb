"""Regenerate the README's figures: ``python docs/make_figures.py`` (inside .venv)."""

from pathlib import Path

import cv2
import numpy as np

from sim_camera.scene import EXAMPLE_SCENE, Scene

HERE = Path(__file__).parent


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
    cv2.imwrite(str(HERE / "frame_and_lights_on.png"), pair)
    print("wrote", HERE / "frame_and_lights_on.png")


if __name__ == "__main__":
    main()
