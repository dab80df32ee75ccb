"""The calibration workflow on each camera preset's own lights-on frames (8-bit webcam, 12-bit
low-light, 16-bit cooled; the 12-bit camera's frames also MSB-aligned, shifted into the top 12
bits): rim centre error against the optics' true rim, and the grid corners' ground reprojection
error out to 0.9 m (true image point -> profile -> floor), over the perturbed mirrors of
``tests/calibration/test_workflow.py``:

    python docs/measurements/calibration_depth.py [--mirrors 4]

Prints a markdown table (docs/explanation/calibration.md, "12- and 16-bit lights-on frames").
"""

from __future__ import annotations

import argparse

import numpy as np


def measure(camera_name: str, k: int, *, msb: bool = False) -> dict:
    import cv2

    from stcvision.calibration.defaults import calibration_frame
    from stcvision.calibration.transform import calibrate_neighbors, calibrate_transform, grid_corners_m
    from stcvision.sim_camera.camera import SyntheticCamera
    from stcvision.sim_camera.hardware import CAMERAS
    from stcvision.sim_camera.optics import MirrorCameraParams, rim_points_px

    rng = np.random.default_rng(500 + k)  # the perturbed mirrors of tests/calibration/test_workflow.py
    optics = MirrorCameraParams(
        mirror_decentre_m=tuple(rng.uniform(-0.0013, 0.0013, 2)),
        mirror_tilt_rad=float(np.radians(rng.uniform(-2, 2))),
        mirror_tilt_axis_rad=float(rng.uniform(0, np.pi)),
        mirror_distance_m=0.10 * float(rng.uniform(0.95, 1.05)),
    )
    sensor = CAMERAS[camera_name].sensor
    cam = SyntheticCamera(optics, sensor, pattern_seed=k)
    frame = calibration_frame(cam, seed=k)
    if msb:
        frame = frame << np.uint16(16 - sensor.adc_bits)
    prof, rep = calibrate_transform(frame)
    prof, _ = calibrate_neighbors(frame, prof)
    (ex, ey), _, _ = cv2.fitEllipse(rim_points_px(optics).astype(np.float32))
    corners = grid_corners_m(prof.subcell_m, rho_max_m=0.9)
    uv, ok = cam.projector.project(corners)
    err_mm = 1000 * np.hypot(*(prof.image_to_robot(uv[ok]) - corners[ok]).T)
    return {
        "dtype": str(frame.dtype),
        "max_dn": int(frame.max()),
        "centre_err_px": float(np.hypot(rep.rim.center_px[0] - ex, rep.rim.center_px[1] - ey)),
        "ground_err_mm_median": float(np.median(err_mm)),
        "ground_err_mm_max": float(err_mm.max()),
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--mirrors", type=int, default=4)
    a = p.parse_args(argv)
    print(
        "| camera | frames | rim centre error (px), worst | ground error median (mm), range "
        "| ground error max (mm), worst |"
    )
    print("|---|---|---|---|---|")
    for name, msb in (("webcam", False), ("lowlight", False), ("lowlight", True), ("cooled", False)):
        rows = [measure(name, k, msb=msb) for k in range(a.mirrors)]
        med = [r["ground_err_mm_median"] for r in rows]
        kind = f"{rows[0]['dtype']}, max {max(r['max_dn'] for r in rows)} DN" + (", MSB-aligned" if msb else "")
        print(
            f"| {name} | {kind} | {max(r['centre_err_px'] for r in rows):.3f} | {min(med):.2f}-{max(med):.2f} | "
            f"{max(r['ground_err_mm_max'] for r in rows):.2f} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
