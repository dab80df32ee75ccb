"""Build the shipped default profile by calibrating the default simulated camera.

Run ``python -m calibration.defaults`` to regenerate ``calibration/profiles/default.json``.
"""

from __future__ import annotations

import numpy as np

from stcvision.profile import Profile

SEED = 2026


def target_profile(camera, *, seed: int = SEED, n: int = 800) -> Profile:
    """Calibrate a simulated camera with a perfectly measured target: ``n`` floor points at
    known positions (0.09..0.9 m from the robot) and where the camera images them. The
    pipeline's model stays its own (a fitted central radial model), not the renderer's."""
    from calibration.fit import fit_profile

    rng = np.random.default_rng(seed)
    r = np.sqrt(rng.uniform(0.09**2, 0.9**2, n))
    a = rng.uniform(-np.pi, np.pi, n)
    xy = np.column_stack([r * np.cos(a), r * np.sin(a)])
    uv, ok = camera.projector.project(xy)
    prof, rep = fit_profile(
        uv[ok], xy[ok], image_size_px=(camera.optics.width_px, camera.optics.height_px),
        rim_radius_px=_rim_radius(camera),
    )
    return prof.replace(provenance={
        "method": "target fit: known floor points imaged by a simulated camera",
        "seed": seed,
        "fit": rep.to_dict(),
    })


def build_default_profile() -> Profile:
    """Calibrate the default simulated camera (``sim_camera`` defaults, pattern seed 0).

    Interim method, until the automatic grid workflow replaces it: :func:`target_profile`.
    """
    from sim_camera.camera import SyntheticCamera

    prof = target_profile(SyntheticCamera())
    return prof.replace(provenance={**prof.provenance, "camera": "sim_camera defaults, pattern_seed 0"})


def _rim_radius(cam) -> float:
    """Rim radius measured on the camera's own mirror mask (the furthest mirror pixel)."""
    v, u = np.nonzero(cam.table.mirror)
    cx, cy = u.mean(), v.mean()
    return float(np.hypot(u - cx, v - cy).max())


def main() -> None:
    from calibration.profiles import default_profile_path

    prof = build_default_profile()
    path = default_profile_path()
    prof.save(path, overwrite=True)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
