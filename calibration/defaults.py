"""The shipped default profile, made by running the calibration workflow on the default
simulated camera.

``python -m stcvision.calibration.defaults`` regenerates ``calibration/profiles/default.json``; a test
regenerates it and compares. :func:`calibrate_simulated` runs the same workflow on any
simulated camera (the tests use it on perturbed mirrors).
"""

from __future__ import annotations

import numpy as np

from stcvision.profile import Profile

SEED = 2026
#: The calibration board: 8x8 cells, the robot in the entry sub-cell of cell (3, 4), facing north.
CALIBRATION_MAP = "\n".join(["." * 16] * 15 + ["." * 15 + "S"])
CALIBRATION_SUBCELL = (7, 9)


def calibration_frame(camera, *, seed: int = SEED) -> np.ndarray:
    """A rendered lights-on frame of the calibration board, robot at the calibration pose."""
    from stcvision.sim_camera.board import Board
    from stcvision.sim_camera.camera import Pose

    board = Board.from_text(CALIBRATION_MAP)
    c = board.subcell_center_m(*CALIBRATION_SUBCELL)
    return camera.lights_on(
        Pose(float(c[0]), float(c[1]), np.pi / 2), board=board, rng=np.random.default_rng(seed)
    ).image


def calibrate_simulated(camera, *, seed: int = SEED) -> Profile:
    """The transformation and neighbours calibration on a simulated camera's lights-on frame."""
    from stcvision.calibration.transform import calibrate_neighbors, calibrate_transform

    frame = calibration_frame(camera, seed=seed)
    prof, _ = calibrate_transform(frame)
    prof, _ = calibrate_neighbors(frame, prof)
    return prof


def build_default_profile() -> Profile:
    """Calibrate the default simulated camera (``sim_camera`` defaults, pattern seed 0)."""
    from stcvision.sim_camera.camera import SyntheticCamera

    prof = calibrate_simulated(SyntheticCamera())
    return prof.replace(
        provenance={
            **prof.provenance,
            "camera": "sim_camera defaults, pattern_seed 0",
            "frame": f"stcvision.calibration.defaults.calibration_frame(seed={SEED})",
        }
    )


def main() -> None:
    from stcvision.calibration.profiles import default_profile_path

    prof = build_default_profile()
    path = default_profile_path()
    prof.save(path, overwrite=True)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
