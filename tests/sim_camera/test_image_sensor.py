"""Sensor-true frames: the ADC's depth from the camera profile to the frame's dtype,
the conversion gain and black level at 12 and 16 bits, and the coverage loop's gain rule."""

import json

import numpy as np
import pytest

from stcvision.errors import BadInputError
from stcvision.sim_camera import hardware
from stcvision.sim_camera.camera import SyntheticCamera
from stcvision.sim_camera.image_sensor import SensorParams, expose


def _rngs(n, seed=0):
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(n)]


@pytest.fixture(scope="module")
def cam16():
    return SyntheticCamera(sensor=hardware.COOLED.sensor.replace(gain=1.0))


def test_profiles_carry_their_adc_depth_into_the_sensor_and_the_frames():
    assert [hardware.CAMERAS[n].adc_bits for n in ("webcam", "lowlight", "cooled")] == [8, 12, 16]
    for prof in hardware.CAMERAS.values():
        s = prof.sensor
        assert s.adc_bits == prof.adc_bits and s.max_dn == 2**prof.adc_bits - 1
        assert s.dn_per_e == pytest.approx(s.gain * s.max_dn / s.full_well_e, rel=1e-12)
        # the pedestal is the same fraction of the range at every depth (8 DN of 255 for the webcam)
        assert s.black_dn / s.max_dn == pytest.approx(8 / 255, rel=1e-12)
    assert SensorParams().dtype is np.uint8 and SensorParams(adc_bits=12).dtype is np.uint16
    for bad in (7, 17, 12.5, True):
        with pytest.raises(BadInputError, match="adc_bits"):
            SensorParams(adc_bits=bad) if not isinstance(bad, float) else SensorParams.from_dict({"adc_bits": bad})


def test_camera_json_adc_bits_reaches_the_sensor(tmp_path):
    d = hardware.camera_to_dict(hardware.LOWLIGHT)
    assert d["adc_bits"] == 12 and "adc_bits" not in d["sensor"]
    p = tmp_path / "cam.json"
    p.write_text(json.dumps(d | {"adc_bits": 14}))
    assert hardware.load_camera(str(p)).sensor.adc_bits == 14
    p.write_text(json.dumps({k: v for k, v in d.items() if k != "adc_bits"}))
    assert hardware.load_camera(str(p)).sensor.adc_bits == 8  # the schema's default
    p.write_text(json.dumps(d | {"sensor": d["sensor"] | {"adc_bits": 16}}))
    with pytest.raises(BadInputError, match="differ"):
        hardware.load_camera(str(p))
    p.write_text(json.dumps(d | {"adc_bits": 20}))
    with pytest.raises(BadInputError, match="adc_bits must be an integer from 8 to 16"):
        hardware.load_camera(str(p))


def test_sixteen_bit_dark_frames_match_the_model(cam16):
    """The dark-frame checks of test_camera.py at 16 bits: per-pixel mean over 24 frames within
    0.35 DN-equivalents of the model (black_dn + dn_per_e * (dark + column offset)), temporal
    spread sqrt(dark + read^2) e- times dn_per_e (plus 1/12 DN^2), and the dtype is uint16."""
    s = cam16.sensor
    one = cam16.dark_frame(rng=np.random.default_rng(0))
    assert one.dtype == np.uint16 and one.shape == (*cam16.shape, 3)
    frames = np.stack([cam16.dark_frame(rng=r) for r in _rngs(24)]).astype(float)
    g, pat = s.dn_per_e, cam16.pattern
    normal = ~pat.hot
    dark_e = pat.dark_gain[..., 1] * s.dark_current_e_s * s.exposure_s
    expected_mean = s.black_dn + g * (dark_e + pat.column_offset_e[None, :])
    mean = frames[..., 1].mean(0)
    sigma_dn = np.sqrt((dark_e + s.read_noise_e**2) * g * g + 1 / 12)
    # standard error of a 24-frame mean: sigma / sqrt(24) = 0.2 sigma; the median |error| is 0.67 of it
    assert np.median(np.abs(mean - expected_mean)[normal]) < 0.2 * np.median(sigma_dn)
    std = frames[..., 1].std(0, ddof=1)
    assert np.median(std[normal]) == pytest.approx(np.median(sigma_dn[normal]), rel=0.06)
    # the median dark has the frames' dtype
    assert cam16.median_dark(3, rng=np.random.default_rng(1)).dtype == np.uint16


def test_a_twelve_bit_adc_clips_at_4095_and_keeps_counts_lsb_aligned():
    s = hardware.LOWLIGHT.sensor.replace(gain=1.0, prnu_sigma=0.0)
    cam = SyntheticCamera(sensor=s)
    sig = np.zeros((*cam.shape, 3), np.float32)
    sig[:240] = 2.0 * s.full_well_e  # past the full well: saturated
    sig[240:] = 1000.0
    img = expose(sig, s, cam.pattern, np.random.default_rng(0))
    assert img.dtype == np.uint16 and img.max() == 4095
    assert (img[:240] == 4095).all()  # gain 1: the full well spans the ADC range
    lower = img[240:, :, 1][~cam.pattern.hot[240:]].astype(float)
    # 1000 e- at 4095/11200 DN/e on a 128.5-count pedestal: ~494 counts, not scaled to 16 bits
    expected = s.black_dn + 1000.0 * s.dn_per_e
    assert np.median(lower) == pytest.approx(expected, abs=3.0)
    # lights-on frames have the sensor's depth too, the floor at the same fraction of the range
    from stcvision.sim_camera.board import Board
    from stcvision.sim_camera.camera import Pose

    board = Board.from_text("S...\n....\n....\n....\n")
    c = board.subcell_center_m(1, 1)
    lit = cam.lights_on(Pose(c[0], c[1], 0.0), board=board, rng=np.random.default_rng(0)).image
    assert lit.dtype == np.uint16
    assert 100 / 255 < np.median(lit[..., 1][cam.table.ground]) / 4095 < 180 / 255


def test_sensor_gain_keeps_the_webcam_and_spans_the_noise_on_the_others():
    from stcvision.controllers.stc.config import CoverConfig
    from stcvision.controllers.stc.frames import AUTO_LONG, NOISE_DN, WEBCAM, Exposures, sensor_gain

    web = hardware.WEBCAM.sensor
    assert [sensor_gain(web, e, n, g) for e, g, n in (WEBCAM, *AUTO_LONG)] == [g for _, g, _ in (WEBCAM, *AUTO_LONG)]
    for prof in (hardware.LOWLIGHT, hardware.COOLED):
        s = prof.sensor
        for e, _, n in (WEBCAM, *AUTO_LONG):
            g = sensor_gain(s, e, n, 16.0)
            at = s.replace(exposure_s=e, gain=g)
            noise_dn = at.dn_per_e * np.sqrt(s.read_noise_e**2 + s.dark_current_e_s * e) / np.sqrt(n)
            assert g >= 1.0 and noise_dn >= NOISE_DN - 1e-9
            assert g == 1.0 or noise_dn == pytest.approx(NOISE_DN, rel=1e-9)  # the lowest such gain
    # the cooled 16-bit camera's read noise spans 1.6 DN at gain 1: its short frame needs no gain
    assert sensor_gain(hardware.COOLED.sensor, *WEBCAM[:1], 1, 16.0) == 1.0
    from stcvision.sim_camera.hardware import CAMERAS

    ladder = Exposures(CoverConfig(camera=CAMERAS["webcam"], exposure="auto")).ladder
    assert ladder == (WEBCAM, *AUTO_LONG)


def test_the_noise_table_is_scipys_normal_quantiles_to_the_last_bit():
    """The sensor's inverse-CDF table comes from the standard library (no scipy.special import
    in a rendering command); its 65,536 float32 values must be those ``ndtri`` gives, or every
    frame's noise, and every run's result, would change."""
    from scipy.special import ndtri

    from stcvision.sim_camera import image_sensor

    want = ndtri((np.arange(65536) + 0.5) / 65536).astype(np.float32)
    assert image_sensor._LUT.dtype == np.float32
    np.testing.assert_array_equal(image_sensor._LUT, want)
