"""12- and 16-bit lights-on frames through the calibration workflow (rim, transform, neighbours),
LSB- or MSB-aligned as the pipeline takes them."""

import json

import cv2
import numpy as np
import pytest

from stcvision.calibration.defaults import calibration_frame
from stcvision.calibration.frames import geometry_frame
from stcvision.sim_camera.camera import SyntheticCamera
from stcvision.sim_camera.hardware import CAMERAS
from stcvision.sim_camera.optics import MirrorCameraParams, rim_points_px


@pytest.fixture(scope="module")
def lowlight_frame():
    return calibration_frame(SyntheticCamera(sensor=CAMERAS["lowlight"].sensor))


def test_alignment_does_not_matter(lowlight_frame):
    f = lowlight_frame
    assert f.dtype == np.uint16 and f.max() < 4096  # the 12-bit camera's counts, LSB-aligned
    msb = f << np.uint16(4)
    assert np.array_equal(geometry_frame(f), geometry_frame(msb))
    g = geometry_frame(f)
    assert g.dtype == np.uint8 and 200 <= np.percentile(g, 99.9) <= 255
    u8 = np.zeros((4, 4, 3), np.uint8)
    assert geometry_frame(u8) is u8  # 8-bit frames untouched


def test_sixteen_bit_frame_calibrates_through_the_cli(tmp_path, cli):
    """The cooled camera's 16-bit PNG through rim, transform and neighbours."""
    optics = MirrorCameraParams()
    frame = calibration_frame(SyntheticCamera(optics, CAMERAS["cooled"].sensor))
    assert frame.dtype == np.uint16
    path = tmp_path / "lights16.png"
    cv2.imwrite(str(path), frame)
    (ex, ey), _, _ = cv2.fitEllipse(rim_points_px(optics).astype(np.float32))
    code, out, err = cli("calibrate", "rim", path, "--json")
    assert code == 0, err
    rim = json.loads(out)
    assert np.hypot(rim["center_px"][0] - ex, rim["center_px"][1] - ey) < 0.5
    prof = tmp_path / "p.json"
    code, out, err = cli("calibrate", "transform", path, "--out", prof, "--yes", "--json")
    assert code == 0, err
    assert json.loads(out)["line_err_mm_median"] < 1.0
    code, out, err = cli("calibrate", "neighbors", path, "--profile", prof, "--yes", "--json", "--force")
    assert code == 0, err
    assert len(json.loads(out)["corners_px"]) == 12


def test_dataset_lights_on_frames_at_the_cameras_depth(tmp_path, cli):
    """A dataset's 12-bit camera is calibrated on its own 12-bit lights-on frame, and the
    profile the dataset writes for it comes from that frame."""
    from stcvision.datasets import open_dataset
    from stcvision.fileio import read_image

    recipe = {
        "schema_version": 1,
        "name": "deep-calib",
        "dark_frames": 2,
        "calibration": {"lights_on_frames": 1, "profiles": True},
        "groups": [{"name": "webcam", "n": 1}, {"name": "low", "n": 1, "sensor_profile": "lowlight"}],
    }
    (tmp_path / "r.json").write_text(json.dumps(recipe))
    code, _, err = cli("dataset", "generate", tmp_path / "r.json", "--out", tmp_path / "D", "--workers", "1")
    assert code == 0, err
    m = json.loads((tmp_path / "D" / "manifest.json").read_text())
    assert m["counts"]["cameras"] == 2 and m["cameras"]["cam1"]["sensor_profile"] == "lowlight"
    assert read_image(tmp_path / "D" / "calibration" / "cam0_0.png").dtype == np.uint8
    deep = read_image(tmp_path / "D" / "calibration" / "cam1_0.png")
    assert deep.dtype == np.uint16 and 255 < deep.max() < 4096
    assert open_dataset(tmp_path / "D").profile_path("cam1").exists()
