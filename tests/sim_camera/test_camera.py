"""The synthetic camera: sensor noise, crosstalk, saturation, visibility horizon, determinism,
ground truth."""

import json

import numpy as np
import pytest

from stcvision.errors import BadInputError
from stcvision.sim_camera.board import Board
from stcvision.sim_camera.camera import ROSE_SNR, Pose, SyntheticCamera, visibility_horizon_s
from stcvision.sim_camera.image_sensor import SensorParams, expose
from stcvision.sim_camera.phosphor import PhosphorLayer
from stcvision.sim_camera.scene import EXAMPLE_SCENE, Scene


def _rngs(n, seed=0):
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(n)]


def test_dark_frame_mean_and_spread_match_the_model(default_camera):
    cam = default_camera
    s = cam.sensor
    frames = np.stack([cam.dark_frame(rng=r) for r in _rngs(24)]).astype(float)
    g = s.dn_per_e
    pat = cam.pattern
    normal = ~pat.hot
    dark_e = pat.dark_gain[..., 1] * s.dark_current_e_s * s.exposure_s
    expected_mean = s.black_level_dn + g * (dark_e + pat.column_offset_e[None, :])
    mean = frames[..., 1].mean(0)
    # per-pixel mean over 24 frames within 0.35 DN of the model (standard error ~0.26 DN)
    assert np.median(np.abs(mean - expected_mean)[normal]) < 0.35
    # temporal spread: sqrt(dark + read^2) electrons, plus quantisation 1/12 DN^2
    std = frames[..., 1].std(0, ddof=1)
    expected_std = np.sqrt((dark_e + s.read_noise_e**2) * g * g + 1 / 12)
    assert np.median(std[normal]) == pytest.approx(np.median(expected_std[normal]), rel=0.06)
    # column offsets are a fixed pattern the dark frame captures
    col = mean.mean(0) - mean.mean()
    assert np.corrcoef(col, pat.column_offset_e)[0, 1] > 0.95


def test_hot_pixels_show_in_a_long_dark_frame(default_camera):
    cam = default_camera
    s = cam.sensor.replace(exposure_s=2.0, gain=4.0)
    dark = cam.dark_frame(rng=np.random.default_rng(3), sensor=s).astype(float)[..., 1]
    # hot pixels collect hot_pixel_factor (100x) the mean dark current: threshold at 20x
    hot = dark > s.black_level_dn + 20 * s.dn_per_e * s.dark_current_e_s * 2.0
    found = hot.mean()
    assert found == pytest.approx(s.hot_pixel_fraction, rel=0.3)
    assert (hot & cam.pattern.hot).sum() / hot.sum() > 0.95


def test_temporal_noise_of_a_uniform_signal(default_camera):
    cam = default_camera
    s = cam.sensor.replace(gain=2.0, prnu_sigma=0.0)
    S = 3000.0
    frames = []
    for r in _rngs(16, seed=5):
        sig = np.full((*cam.shape, 3), S, np.float32)
        frames.append(expose(sig, s, cam.pattern, r)[..., 1].astype(float))
    std = np.stack(frames).std(0, ddof=1)
    dark = cam.pattern.dark_gain[..., 1] * s.dark_current_e_s * s.exposure_s
    expected = np.sqrt((S + dark + s.read_noise_e**2) * s.dn_per_e**2 + 1 / 12)
    ok = ~cam.pattern.hot
    assert np.median(std[ok]) == pytest.approx(np.median(expected[ok]), rel=0.05)


def test_a_stack_rendered_at_once_matches_the_average_of_its_frames(default_camera):
    """``n_avg``: the average of 8 frames of a uniform signal, rendered at once, has the mean and
    the temporal spread of 8 frames rendered one by one and averaged (within the 10 % a
    16-sample spread estimate allows), and 1/sqrt(8) of one frame's spread."""
    cam = default_camera
    s = cam.sensor.replace(exposure_s=30.0, gain=4.0, prnu_sigma=0.0)
    S = 400.0
    ok = ~cam.pattern.hot

    def frame(r, n):
        return expose(np.full((*cam.shape, 3), S, np.float32), s, cam.pattern, r, n_avg=n)[..., 1].astype(float)

    at_once = np.stack([frame(r, 8) for r in _rngs(16, seed=7)])
    by_hand = np.stack([np.mean([frame(q, 1) for q in _rngs(8, seed=100 + i)], 0) for i in range(16)])
    single = np.stack([frame(r, 1) for r in _rngs(16, seed=9)])
    sd_once, sd_hand = np.median(at_once.std(0, ddof=1)[ok]), np.median(by_hand.std(0, ddof=1)[ok])
    assert sd_once == pytest.approx(sd_hand, rel=0.1)
    assert sd_once == pytest.approx(np.median(single.std(0, ddof=1)[ok]) / np.sqrt(8), rel=0.1)
    assert np.median(np.abs(at_once.mean(0) - by_hand.mean(0))[ok]) < 0.2
    with pytest.raises(BadInputError, match="n_avg"):
        expose(np.zeros((*cam.shape, 3), np.float32), s, cam.pattern, np.random.default_rng(0), n_avg=0)


def test_red_light_leaks_into_green_by_the_configured_crosstalk(default_camera):
    cam = default_camera
    s = cam.sensor.replace(exposure_s=1e-4, gain=1.0)  # short enough not to saturate
    sig, info = cam.signal(Pose(0, 0, 0), red_lights_m=np.array([[0.3, 0.1]]), sensor=s)
    assert sig.max() < s.full_well_e
    ratio = sig[..., 1].sum() / sig[..., 2].sum()
    assert ratio == pytest.approx(s.red_led_bgr[1] / s.red_led_bgr[2], rel=1e-3)
    # measured on noisy frames too (exposure chosen so the brightest red pixel reads ~200 DN):
    # summed green over summed red around the light
    u, v = np.rint(info["lights"]["uv"][0]).astype(int)
    s2 = cam.sensor.replace(gain=4.0)
    peak_e_per_s = sig[..., 2].max() / s.exposure_s
    s2 = s2.replace(exposure_s=200 / s2.dn_per_e / peak_e_per_s)
    acc = np.zeros(3)
    for r in _rngs(8, seed=9):
        img = cam.render(Pose(0, 0, 0), rng=r, red_lights_m=np.array([[0.3, 0.1]]), sensor=s2).image
        dark = cam.dark_frame(rng=r, sensor=s2)
        diff = img.astype(float) - dark
        acc += diff[v - 6 : v + 7, u - 6 : u + 7].reshape(-1, 3).sum(0)
    assert acc[1] / acc[2] == pytest.approx(0.06, abs=0.02)


def test_bright_red_lights_saturate_and_bloom(default_camera):
    cam = default_camera
    light = np.array([[0.4, -0.2]])
    img = cam.render(Pose(0, 0, 0), rng=np.random.default_rng(0), red_lights_m=light).image
    sat = img[..., 2] == 255
    assert sat.sum() >= 4
    nobloom = cam.sensor.replace(bloom_fraction=0.0, glare_fraction=0.0)
    img2 = cam.render(Pose(0, 0, 0), rng=np.random.default_rng(0), red_lights_m=light, sensor=nobloom).image
    assert sat.sum() > (img2[..., 2] == 255).sum()


def test_visibility_horizon_at_webcam_settings_is_about_a_minute(default_camera):
    """The ant-like STC paper: the webcam saw a dot 'only in the first minute or so'."""
    h = visibility_horizon_s(default_camera)
    assert 45.0 <= h <= 90.0
    assert h < 120.0


def _window_snr(cam, age_s, sensor, n=24, seed=0, rho=0.25):
    layer = PhosphorLayer()
    xy = np.array([[rho * np.cos(0.7), rho * np.sin(0.7)]])
    layer.charge(xy, t_start_s=-age_s - 3.0, duration_s=3.0)
    rngs = _rngs(2 * n + 16, seed)
    dark = np.median(np.stack([cam.dark_frame(rng=r, sensor=sensor) for r in rngs[:16]]), 0)
    pose = Pose(0, 0, 0)
    f = cam.render(pose, rng=rngs[16], phosphor=layer, sensor=sensor, truth=True)
    u, v = np.rint(f.truth["dots"][0]["uv_px"]).astype(int)
    on, off = [], []
    for k in range(n):
        img = cam.render(pose, rng=rngs[17 + k], phosphor=layer, sensor=sensor).image[..., 1]
        d = img.astype(float) - dark[..., 1]
        on.append(d[v - 1 : v + 2, u - 1 : u + 2].sum())
        off.append(d[v - 1 + 40 : v + 2 + 40, u - 1 : u + 2].sum())  # same ring, no dot
    on, off = np.array(on), np.array(off)
    return (on.mean() - off.mean()) / off.std(ddof=1), f.truth["dots"][0]["snr"]


def test_rendered_frames_confirm_the_horizon(default_camera):
    """Measured SNR on rendered frames agrees with the analytic SNR and the Rose criterion."""
    cam = default_camera
    snr30, model30 = _window_snr(cam, 30.0, cam.sensor)
    snr120, model120 = _window_snr(cam, 120.0, cam.sensor, seed=1)
    assert snr30 >= ROSE_SNR and model30 >= ROSE_SNR
    assert snr120 < ROSE_SNR and model120 < ROSE_SNR
    # the model's window SNR (signal / total noise incl. shot) tracks the measurement
    assert snr30 == pytest.approx(model30, rel=0.35)


def test_longer_exposure_and_stacking_extend_the_horizon(default_camera):
    cam = default_camera
    base = visibility_horizon_s(cam)
    longer = visibility_horizon_s(cam, sensor=cam.sensor.replace(exposure_s=0.25))
    stacked = visibility_horizon_s(cam, n_stack=16)
    # read-noise limited: SNR ~ exposure, and L ~ t^-1.1 -> horizon grows ~ 7.5^(1/1.1)
    assert longer > 4 * base
    # stacking 16 frames: SNR x4 -> horizon x ~ 4^(1/1.1)
    assert 2.5 * base < stacked < 5 * base
    # but a long exposure saturates the red lights and a fresh dot at the same gain
    s = cam.sensor.replace(exposure_s=0.5)
    img = cam.render(Pose(0, 0, 0), rng=np.random.default_rng(0), red_lights_m=np.array([[0.4, 0.0]]), sensor=s).image
    assert (img[..., 2] == 255).sum() > (
        cam.render(Pose(0, 0, 0), rng=np.random.default_rng(0), red_lights_m=np.array([[0.4, 0.0]])).image[..., 2]
        == 255
    ).sum()


def test_same_seed_gives_byte_identical_frames():
    scene = Scene.from_dict(EXAMPLE_SCENE)
    a = scene.camera().render(
        scene.pose, rng=np.random.default_rng(7), phosphor=scene.phosphor, red_lights_m=scene.red_lights_m
    )
    b = scene.camera().render(
        scene.pose, rng=np.random.default_rng(7), phosphor=scene.phosphor, red_lights_m=scene.red_lights_m
    )
    c = scene.camera().render(
        scene.pose, rng=np.random.default_rng(8), phosphor=scene.phosphor, red_lights_m=scene.red_lights_m
    )
    assert a.image.tobytes() == b.image.tobytes()
    assert a.image.tobytes() != c.image.tobytes()


def test_ground_truth_of_the_example_scene():
    scene = Scene.from_dict(EXAMPLE_SCENE)
    cam = scene.camera()
    f = cam.render(
        scene.pose,
        rng=np.random.default_rng(0),
        phosphor=scene.phosphor,
        red_lights_m=scene.red_lights_m,
        board=scene.board,
        truth=True,
    )
    t = json.loads(json.dumps(f.truth))  # JSON-serialisable
    cell = t["cell"]
    assert cell["cell"] == [3, 3]
    assert cell["robot_subcell_index"] == 0
    lit = {b["box"]: b["n_dots"] for b in cell["boxes"]}
    # marks: (6,7) S edge = box 5, (6,6) E edge = box 3; (5,6) lies in the forward cell
    assert lit == {1: 0, 2: 0, 3: 4, 4: 0, 5: 4}
    assert cell["visited"] == {"1": True, "2": True, "3": False}
    nb = {n["direction"]: n for n in cell["neighbours"]}
    assert nb["forward"]["has_marks"] and nb["back"]["has_marks"]
    assert not nb["left"]["has_marks"] and not nb["right"]["has_marks"]
    for dot in t["dots"]:
        if dot["visible"]:
            u, v = dot["uv_px"]
            assert 0 <= u < 640 and 0 <= v < 480
    # every dot's image position is where the brightest green is after dark subtraction
    dark = cam.dark_frame(rng=np.random.default_rng(1))
    g = f.image[..., 1].astype(int) - dark[..., 1]
    for dot in t["dots"]:
        if dot["visible"] and dot["snr"] > 15:
            u, v = np.rint(dot["uv_px"]).astype(int)
            patch = g[v - 3 : v + 4, u - 3 : u + 4]
            pv, pu = np.unravel_index(np.argmax(patch), patch.shape)
            assert abs(pu - 3) <= 1 and abs(pv - 3) <= 1


def test_obstacle_neighbour_has_red_in_truth():
    board = Board.from_text("S.##\n..##\n")
    c = board.subcell_center_m(1, 1)
    cam = SyntheticCamera()
    f = cam.render(
        Pose(c[0], c[1], np.pi / 2),
        rng=np.random.default_rng(0),
        red_lights_m=board.red_lights_m(),
        board=board,
        truth=True,
    )
    nb = {n["direction"]: n for n in f.truth["cell"]["neighbours"]}
    assert nb["right"]["has_red"] and not nb["right"]["free"]
    # off the board: the border ring of red lights
    assert nb["forward"]["has_red"] and nb["left"]["has_red"] and nb["back"]["has_red"]


def test_lights_on_frame_shows_floor_and_grid(default_camera):
    board = Board.from_text("S...\n....\n....\n....\n")
    c = board.subcell_center_m(1, 1)
    f = default_camera.lights_on(Pose(c[0], c[1], 0.0), board=board, rng=np.random.default_rng(0))
    g = f.image[..., 1]
    t = default_camera.table
    floor = g[t.ground]
    assert 100 < np.median(floor) < 180  # auto exposure
    assert (floor < 0.5 * np.median(floor)).mean() > 0.01  # dark tape lines
    assert np.median(g[~t.mirror]) < 15  # outside the mirror: dark


def test_sensor_parameters_validate():
    from stcvision.errors import BadInputError

    with pytest.raises(BadInputError, match="exposure_s"):
        SensorParams(exposure_s=0)
    with pytest.raises(BadInputError, match="unknown sensor parameter"):
        SensorParams.from_dict({"exposure": 1})
