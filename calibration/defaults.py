"""Build the shipped default profile by calibrating the default simulated camera.

Run ``python -m calibration.defaults`` to regenerate ``calibration/profiles/default.json``.
"""

from __future__ import annotations

import numpy as np

from stcvision.profile import Profile

SEED = 2026


def build_default_profile() -> Profile:
    """Calibrate the default simulated camera (``sim_camera`` defaults, pattern seed 0).

    Interim method (until the automatic grid workflow replaces it): the transformation is
    fitted to correspondences between 600 floor points at known positions (0.09..0.9 m) and
    where the rendering camera images them -- a perfectly measured calibration target. The
    pipeline's model stays its own (central radial model, fitted), not the renderer's.
    """
    from calibration.fit import fit_profile
    from sim_camera.camera import SyntheticCamera

    cam = SyntheticCamera()
    rng = np.random.default_rng(SEED)
    r = np.sqrt(rng.uniform(0.09**2, 0.9**2, 800))
    a = rng.uniform(-np.pi, np.pi, 800)
    xy = np.column_stack([r * np.cos(a), r * np.sin(a)])
    uv, ok = cam.projector.project(xy)
    prof, rep = fit_profile(
        uv[ok], xy[ok], image_size_px=(cam.optics.width_px, cam.optics.height_px),
        rim_radius_px=_rim_radius(cam),
    )
    return prof.replace(provenance={
        "method": "target fit (interim): known floor points imaged by the default simulated camera",
        "camera": "sim_camera defaults, pattern_seed 0",
        "seed": SEED,
        "fit": rep.to_dict(),
    })


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
