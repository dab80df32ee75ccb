"""The calibration workflow: rim, transformation and neighbours calibration, on rendered
lights-on frames of perturbed cameras and on a real catadioptric image."""

import json

import cv2
import numpy as np
import pytest

from stcvision.calibration.defaults import build_default_profile, calibration_frame
from stcvision.calibration.profiles import default_profile
from stcvision.calibration.rim import detect_rim
from stcvision.calibration.transform import calibrate_neighbors, calibrate_transform, grid_corners_m
from stcvision.cli import main
from stcvision.profile import nominal_corners_px
from stcvision.sim_camera.camera import SyntheticCamera
from stcvision.sim_camera.optics import MirrorCameraParams, rim_points_px


def perturbed(k):
    """Mirror decentre up to +-10 px (1.3 mm), tilt up to +-2 degrees, distance +-5 %."""
    rng = np.random.default_rng(500 + k)
    return MirrorCameraParams(
        mirror_decentre_m=tuple(rng.uniform(-0.0013, 0.0013, 2)),
        mirror_tilt_rad=float(np.radians(rng.uniform(-2, 2))),
        mirror_tilt_axis_rad=float(rng.uniform(0, np.pi)),
        mirror_distance_m=0.10 * float(rng.uniform(0.95, 1.05)),
    )


@pytest.mark.slow
@pytest.mark.parametrize("k", range(4))
def test_transformation_calibration_on_perturbed_cameras(k):
    optics = perturbed(k)
    cam = SyntheticCamera(optics, pattern_seed=k)
    frame = calibration_frame(cam, seed=k)
    prof, rep = calibrate_transform(frame)
    # rim centre against the rim the optics put there (ellipse centre of the true rim points)
    (ex, ey), _, _ = cv2.fitEllipse(rim_points_px(optics).astype(np.float32))
    centre_err = np.hypot(rep.rim.center_px[0] - ex, rep.rim.center_px[1] - ey)
    assert centre_err <= 0.5
    # ground reprojection error of the grid corners: true image position -> profile -> floor
    corners = grid_corners_m(0.16, rho_max_m=0.9)
    uv, ok = cam.projector.project(corners)
    err_mm = 1000 * np.hypot(*(prof.image_to_robot(uv[ok]) - corners[ok]).T)
    print(
        f"camera {k}: centre error {centre_err:.3f} px, corner reprojection median {np.median(err_mm):.2f} mm, "
        f"max {err_mm.max():.2f} mm over {ok.sum()} corners"
    )
    assert np.median(err_mm) <= 5.0
    # the neighbours calibration finds the 12 corners near where the transformation puts them
    prof2, corners_px = calibrate_neighbors(frame, prof)
    nominal = nominal_corners_px(0.16, prof.ground_px_per_m, prof.ground_size_px)
    assert np.hypot(*(corners_px - nominal).T).max() < 4.0
    assert prof2.neighbour_corners_px is not None and "neighbours" in prof2.provenance


def test_shipped_default_profile_is_what_the_workflow_makes():
    """The shipped profile is the workflow's output: the same rim and angles, and the same image ->
    floor mapping to within a micrometre over the whole mirror (the theta polynomial's
    coefficients themselves move by ~1e-4 between scipy/OpenCV releases while the mapping does not).
    The neighbour corners are OpenCV's sub-pixel refinement (``cv2.cornerSubPix``) on float32
    images: from OpenCV 5.0 to 5.1 a corner moved by 0.0018 px and the rim centre fitted to
    them by 2.6e-6 px, so they are held to 0.01 px and 1e-4 px, far below what any stage reads
    (a dot is ~3 px across); the angles stay at 1e-6."""
    fresh_p = build_default_profile()
    shipped_p = default_profile()
    fresh, shipped = fresh_p.to_dict(), shipped_p.to_dict()
    tolerance = {"center_px": 1e-4, "rim_radius_px": 1e-4, "forward_angle_rad": 1e-6, "axis_tilt_rad": 1e-6,
                 "neighbour_corners_px": 0.01}  # fmt: skip
    for key, atol in tolerance.items():
        assert np.allclose(np.asarray(fresh[key], float), np.asarray(shipped[key], float), atol=atol), key
    rng = np.random.default_rng(0)
    ang = rng.uniform(0, 2 * np.pi, 2000)
    rad = np.sqrt(rng.uniform(0.05, 0.95, 2000)) * shipped["rim_radius_px"]
    uv = np.c_[shipped["center_px"][0] + rad * np.cos(ang), shipped["center_px"][1] + rad * np.sin(ang)]
    a, b = fresh_p.image_to_robot(uv), shipped_p.image_to_robot(uv)
    ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    assert ok.sum() > 1500
    assert np.hypot(*(a[ok] - b[ok]).T).max() < 1e-5  # metres on the floor
    assert shipped["provenance"]["method"].startswith("transformation calibration")


def test_rim_of_the_real_opencv_catadioptric_sample(peer_data):
    """OpenCV's omnidir tutorial image. Measured by hand: the rim crosses row 218 at x = 50 and
    x = 579.5, row 150 at x = 58.5 and row 300 at x = 64.5 (edge of the light annulus) -> centre
    (315, 218), radius 265."""
    img = cv2.imread(str(peer_data / "opencv_omnidir" / "catadioptric_sample.jpg"))
    rim = detect_rim(img)
    assert rim.center_px == pytest.approx((315.0, 218.0), abs=3.0)
    assert rim.radius_px == pytest.approx(265.0, abs=3.0)
    assert rim.residual_px < 1.5


@pytest.mark.slow
def test_calibrate_cli_end_to_end(tmp_path, cli):
    cam = SyntheticCamera()
    frame = calibration_frame(cam)
    lights = tmp_path / "lights.png"
    cv2.imwrite(str(lights), frame)
    out = tmp_path / "p.json"
    # without a terminal and without --yes: refuse, write nothing
    code, _, err = cli("calibrate", "transform", lights, "--out", out)
    assert code == 2 and "--yes" in err and not out.exists()
    # ... and says what it did write: the preview to look at, not "nothing"
    assert "the profile was not written" in err and "nothing was written" not in err
    assert (tmp_path / "p.preview.png").exists()
    code, stdout, _ = cli("calibrate", "transform", lights, "--out", out, "--yes", "--json")
    assert code == 0
    r = json.loads(stdout)
    assert r["line_err_mm_median"] < 1.0 and (tmp_path / "p.preview.png").exists()
    # never overwrite without --force
    code, _, err = cli("calibrate", "transform", lights, "--out", out, "--yes")
    assert code == 2 and "--force" in err
    # neighbours from a file a person made
    pts = tmp_path / "pts.json"
    pts.write_text(json.dumps(nominal_corners_px(0.16, 312.5, 360).tolist()))
    code, stdout, _ = cli("calibrate", "neighbors", lights, "--profile", out, "--points", pts, "--yes", "--json")
    assert code == 0 and len(json.loads(stdout)["corners_px"]) == 12
    pts.write_text(json.dumps([[1, 2]] * 11))
    code, _, err = cli("calibrate", "neighbors", lights, "--profile", out, "--points", pts, "--yes")
    assert code == 2 and "12" in err
    # rim on the same frame
    code, stdout, _ = cli("calibrate", "rim", lights, "--json")
    assert code == 0 and json.loads(stdout)["radius_px"] == pytest.approx(223.4, abs=1.0)


def test_dark_stacking_cli(tmp_path, capsys):
    cam = SyntheticCamera()
    rng = np.random.default_rng(0)
    paths = []
    for i in range(5):
        p = tmp_path / f"d{i}.png"
        cv2.imwrite(str(p), cam.dark_frame(rng=rng))
        paths.append(str(p))
    assert main(["calibrate", "dark", *paths, "--out", str(tmp_path / "dark.png"), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["frames"] == 5 and r["hot_pixels"] == pytest.approx(cam.pattern.hot.sum(), rel=0.1)
    cv2.imwrite(str(tmp_path / "small.png"), np.zeros((10, 10, 3), np.uint8))
    assert (
        main(["calibrate", "dark", paths[0], str(tmp_path / "small.png"), "--out", str(tmp_path / "dark_bad.png")]) == 2
    )
    assert "one size" in capsys.readouterr().err
