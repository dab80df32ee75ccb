"""Pipeline accuracy against ground truth on rendered frames.

Goals (issue: the vision pipeline): heading RMS <= 0.5 degree; box and obstacle classification
>= 99.9 % inside the visibility horizon. Each test renders random STC entry situations
(``stcvision.sim_camera.scenarios.cell_scene``) and scores them with ``stcvision.scoring``.
"""

import numpy as np
import pytest

from stcvision.calibration.defaults import calibrate_simulated
from stcvision.pipeline import Pipeline
from stcvision.scoring import score_frame, summarize
from stcvision.sim_camera.camera import SyntheticCamera
from stcvision.sim_camera.optics import MirrorCameraParams
from stcvision.sim_camera.scenarios import cell_scene


def median_dark(camera, rng, n=16, sensor=None):
    return camera.median_dark(n, rng=rng, sensor=sensor)


def run_scenes(camera, profile, n, *, seed, sensor=None, **scene_kw):
    rng = np.random.default_rng(seed)
    pipe = Pipeline(profile, dark=median_dark(camera, rng, sensor=sensor))
    scores = []
    for _ in range(n):
        s = cell_scene(rng, **scene_kw)
        f = camera.render(
            s.pose, rng=rng, phosphor=s.phosphor, red_lights_m=s.red_lights_m, board=s.board, sensor=sensor, truth=True
        )
        scores.append(score_frame(pipe.process(f.image), f.truth, profile))
    return summarize(scores)


def check(m, *, heading=0.5, loc_mm=2.0):
    print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in m.items()})  # pytest -s shows it
    # the 300 px ground view (3.8 mm/px, chosen for speed) samples a far dot's peak coarsely:
    # measured recall 98.7-99.8 % of the dots with expected SNR >= 8 (99.1-100 % at 3.2 mm/px)
    assert m["dot_recall"] >= 0.98, m
    assert m["dot_precision"] >= 0.99, m
    assert m["dot_loc_err_mm_median"] <= loc_mm, m
    assert m["heading_err_deg_rms"] <= heading, m
    assert m["heading_fits"] >= 0.95 * m["frames"], m
    assert m["box_accuracy"] >= 0.999, m
    assert m["obstacle_accuracy"] >= 0.999, m


def test_webcam_frames_over_mark_ages(default_camera, default_profile):
    m = run_scenes(default_camera, default_profile, 120, seed=11, age_range_s=(0.0, 90.0))
    check(m)
    assert m["boxes_scored"] >= 400


def test_headings_up_to_20_degrees(default_camera, default_profile):
    m = run_scenes(
        default_camera, default_profile, 80, seed=12, heading_error_deg=(-20.0, 20.0), age_range_s=(0.0, 40.0)
    )
    check(m)


@pytest.mark.parametrize(("exposure_s", "gain", "ages"), [(0.25, 8.0, (0, 300)), (1.0, 2.0, (0, 900))])
def test_longer_exposures_with_matching_dark_frames(default_camera, default_profile, exposure_s, gain, ages):
    s = default_camera.sensor.replace(exposure_s=exposure_s, gain=gain)
    m = run_scenes(default_camera, default_profile, 40, seed=13, sensor=s, age_range_s=ages, fresh_age_s=(30.0, 60.0))
    check(m)


@pytest.mark.slow
@pytest.mark.parametrize("k", range(2))
def test_perturbed_cameras_calibrated_by_the_workflow(k):
    rng = np.random.default_rng(100 + k)
    optics = MirrorCameraParams(
        mirror_decentre_m=tuple(rng.uniform(-0.0012, 0.0012, 2)),
        mirror_tilt_rad=float(np.radians(rng.uniform(-2, 2))),
        mirror_tilt_axis_rad=float(rng.uniform(0, np.pi)),
        mirror_distance_m=0.10 * float(rng.uniform(0.95, 1.05)),
    )
    cam = SyntheticCamera(optics, pattern_seed=k + 1)
    m = run_scenes(cam, calibrate_simulated(cam), 50, seed=14 + k, age_range_s=(0.0, 40.0))
    # a spherical mirror is not central: a decentred one leaves the central model ~1-3 mm off
    check(m, loc_mm=3.0)


def test_default_profile_on_a_perturbed_camera_degrades(default_profile):
    """Calibration matters: the shipped profile reads a decentred, tilted mirror worse."""
    optics = MirrorCameraParams(
        mirror_decentre_m=(0.0012, -0.0010), mirror_tilt_rad=np.radians(2.0), mirror_tilt_axis_rad=0.6
    )
    cam = SyntheticCamera(optics)
    bad = run_scenes(cam, default_profile, 40, seed=15, age_range_s=(0.0, 40.0))
    good = run_scenes(cam, calibrate_simulated(cam), 40, seed=15, age_range_s=(0.0, 40.0))
    print("default profile:", bad, "\nown profile:", good)
    # dots more than 1 cm off do not even match the truth (None): count that as worse
    bad_mm = bad["dot_loc_err_mm_median"] if bad["dot_loc_err_mm_median"] is not None else np.inf
    assert bad_mm > 3 * good["dot_loc_err_mm_median"]
    assert bad["dot_recall"] < good["dot_recall"]
    assert bad["box_accuracy"] < good["box_accuracy"]
