"""Each stage on its own, against known inputs."""

import math

import cv2
import numpy as np
import pytest

from stcvision.errors import BadInputError
from stcvision.stages import (
    ChannelParams,
    Dots,
    UnwarpMap,
    filter_channels,
    find_dots,
    fit_heading,
    recalibrate_turn,
    separate_channels,
    subtract_dark,
    unwarp,
)


def test_dark_subtraction_saturates_and_checks_its_inputs():
    frame = np.full((4, 5, 3), 10, np.uint8)
    dark = np.full((4, 5, 3), 12, np.uint8)
    assert (subtract_dark(frame, dark) == 0).all()  # no wrap-around to 254
    assert (subtract_dark(frame, dark, pedestal_dn=10) == 8).all()
    assert frame[0, 0, 0] == 10  # inputs untouched
    with pytest.raises(BadInputError, match="same size"):
        subtract_dark(frame, np.zeros((4, 6, 3), np.uint8))
    with pytest.raises(BadInputError, match="uint8"):
        subtract_dark(frame.astype(np.float32), dark)
    with pytest.raises(BadInputError, match=r"\(H, W, 3\)"):
        subtract_dark(frame[..., 0], dark)
    with pytest.raises(BadInputError, match="exposure"):
        subtract_dark(frame, dark, frame_exposure_s=0.1, dark_exposure_s=0.033)


def test_unwarp_puts_a_floor_point_where_the_profile_says(default_profile, default_camera):
    """A dot rendered at a known floor point lands at that point in the ground view."""
    from stcvision.sim_camera.camera import Pose
    from stcvision.sim_camera.phosphor import PhosphorLayer

    umap = UnwarpMap.from_profile(default_profile)
    s = default_camera.sensor.replace(
        read_noise_e=0.0, dark_current_e_s=0.0, column_offset_e_sigma=0.0, black_level_dn=0.0, prnu_sigma=0.0
    )
    for xy in ([0.3, 0.1], [-0.2, -0.25], [0.05, 0.45]):
        layer = PhosphorLayer()
        layer.charge([xy], t_start_s=-3.1, duration_s=3.0)
        img = default_camera.render(Pose(0, 0, 0), rng=np.random.default_rng(0), phosphor=layer, sensor=s).image
        g = unwarp(img, umap)[..., 1].astype(float)
        g[g < 0.3 * g.max()] = 0  # the dot only (the camera's fixed column offsets remain)
        ys, xs = np.mgrid[0 : g.shape[0], 0 : g.shape[1]]
        c = np.array([(xs * g).sum(), (ys * g).sum()]) / g.sum()
        want = default_profile.robot_to_ground(np.array([xy]))[0]
        assert np.hypot(*(c - want)) < 1.0  # ground px (3.2 mm)


def test_channel_filter_separates_red_lights_from_green_dots():
    img = np.zeros((20, 20, 3), np.uint8)
    img[5, 5] = (3, 200, 16)  # green dot (a little red response)
    img[12, 12] = (20, 40, 255)  # red light leaking into green
    img[15, 3] = (255, 255, 255)  # both channels saturated: a red light's core
    obstacle, marks = filter_channels(img, ChannelParams())
    assert marks[5, 5] == 200 and obstacle[5, 5] == 0
    assert marks[12, 12] == 0 and obstacle[12, 12] == 255
    assert marks[15, 3] == 0 and obstacle[15, 3] == 255


def test_a_dot_is_never_taken_for_red_under_a_wide_dominance_tolerance():
    """A 30 s webcam frame (measured): pedestal 107 DN, the dark frame's spread ~18
    DN, so the dominance tolerance is ~37 DN; a dot 30 DN above the pedestal, its red crosstalk
    6 DN above it (over the leak level), was blacked out as a red light's halo. Its red is a
    fifth of its green: it stays in the marks; a red halo (red 40, green 3 DN up) and a pixel
    saturated in both channels still go."""
    g = np.full((1, 13), 107, np.uint16)
    r = g.copy()
    # a dot, a red halo, a pixel saturated in both (less the dark frame), apart by more than the
    # black-out's margin
    g[0, [0, 6, 12]], r[0, [0, 6, 12]] = (137, 110, 255 - 9), (113, 147, 255 - 12)
    kw = dict(window_area=1, leak_threshold=110.0, background_dn=107.0, noise_dn=18.0)
    obstacle, marks = separate_channels(g, r, ChannelParams(), **kw)
    assert marks[0, [0, 6, 12]].tolist() == [137, 0, 0] and obstacle[0, 0] == 0
    _, old = separate_channels(g, r, ChannelParams(red_min_fraction=0.0), **kw)
    assert old[0, [0, 6, 12]].tolist() == [0, 0, 0]  # the rule before: the dot went with them


def _blobs(rng, pts, amp=40.0, sigma=1.0, noise=1.5, size=120):
    ys, xs = np.mgrid[0:size, 0:size].astype(float)
    img = np.full((size, size), 10.0)
    for x, y in pts:
        img += amp * np.exp(-0.5 * ((xs - x) ** 2 + (ys - y) ** 2) / sigma**2)
    img += rng.normal(0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def test_dot_search_finds_every_dot_at_sub_pixel_precision_and_nothing_else():
    rng = np.random.default_rng(3)
    pts = rng.uniform(10, 110, (12, 2))
    # keep dots apart by more than the black-out square
    pts = pts[[all(np.abs(p - q).max() > 10 for q in pts[:i]) for i, p in enumerate(pts)]]
    img = _blobs(rng, pts)
    dots = find_dots(img, background_dn=10.0, noise_dn=1.5)
    assert dots.n_lit == len(pts)
    found = dots.xy_px[dots.lit]
    err = np.min(np.hypot(*(found[:, None] - pts[None]).transpose(2, 0, 1)), axis=0)
    assert err.max() < 0.35
    # pure noise (rounded: sigma = sqrt(1.5^2 + 1/12)): 5-sigma false alarms are rare. 50 images
    # hold ~700,000 window positions; a Gaussian tail predicts ~0.2 false dots
    sigma = float(np.hypot(1.5, np.sqrt(1 / 12)))
    false = sum(find_dots(_blobs(rng, []), background_dn=10.0, noise_dn=sigma).n_lit for _ in range(50))
    assert false <= 2


def _dots(xy, strength=None):
    xy = np.asarray(xy, float)
    s = np.ones(len(xy)) if strength is None else np.asarray(strength, float)
    return Dots(np.zeros_like(xy), xy, s, s * 10, np.ones(len(xy), bool), 5.0, 1.0, 0.0)


@pytest.mark.parametrize("angle_deg", [-20.0, -3.0, 0.0, 0.7, 12.0, 44.0])
def test_heading_fit_recovers_the_row_angle(angle_deg):
    rng = np.random.default_rng(int(angle_deg * 10) % 97)
    a = math.radians(angle_deg)
    d = np.array([math.cos(a), math.sin(a)])
    row = np.array([-0.2, 0.05]) + np.outer([-0.045, -0.015, 0.015, 0.045], d)
    row += rng.normal(0, 0.0003, row.shape)
    other = np.array([[0.1, 0.1], [0.13, 0.1], [0.16, 0.1]])  # an older, dimmer row elsewhere
    fit = fit_heading(_dots(np.vstack([row, other]), [9, 8, 10, 7, 2, 2, 2]))
    assert fit
    folded = (angle_deg + 45) % 90 - 45
    assert math.degrees(fit.line_angle_rad) == pytest.approx(folded, abs=1.0)
    assert fit.heading_error_rad == pytest.approx(-fit.line_angle_rad)


def test_heading_fit_failures_are_values_with_reasons():
    fit = fit_heading(_dots([[0.1, 0.0], [0.13, 0.0]]))
    assert not fit and "fewer than 3" in fit.reason
    scattered = fit_heading(_dots([[0.1, 0.0], [0.13, 0.03], [0.1, 0.06], [0.16, 0.0]], [5, 4, 3, 1]))
    assert not scattered and scattered.reason


def test_recalibration_follows_the_seed_and_is_bounded():
    T = 1.5
    r = recalibrate_turn(T, math.radians(80))  # turned 80 instead of 90 degrees in T
    assert r.accepted and r.turn_time_s == pytest.approx(90 / 80 * T)
    assert r.correction_s == pytest.approx(T * 10 / 80)  # the missing 10 degrees at 80/T
    over = recalibrate_turn(T, math.radians(95))
    assert over.correction_s < 0  # rotate back
    assert recalibrate_turn(T, math.radians(89.5)).turn_time_s == T  # within tolerance
    wild = recalibrate_turn(T, math.radians(30))  # a misreading, not the robot
    assert wild.turn_time_s == pytest.approx(1.25 * T) and "clipped" in wild.reason
    bad = recalibrate_turn(T, float("nan"))
    assert not bad.accepted and bad.turn_time_s == T
    with pytest.raises(BadInputError):
        recalibrate_turn(0.0, 1.0)


def test_unwarp_rejects_a_frame_of_the_wrong_size(default_profile):
    """A frame of another size is refused; one of the profile's size gives the ground view, its
    pixels where the mirror sees the floor from the frame and zero beyond."""
    umap = UnwarpMap.from_profile(default_profile)
    with pytest.raises(BadInputError, match="640x480"):
        unwarp(np.zeros((100, 100, 3), np.uint8), umap)
    w, h = default_profile.image_size_px
    n = default_profile.ground_size_px
    ground = unwarp(np.full((h, w, 3), 77, np.uint8), umap)
    assert ground.shape == (n, n, 3) and ground.dtype == np.uint8
    assert (ground[umap.valid] == 77).all() and (ground[~umap.valid] == 0).all()


def test_tls_line_is_the_svd_fit():
    """The heading fit's closed-form line (stcvision.stages.heading.tls_line) against numpy's SVD of the centred
    points: the direction (modulo pi: a line has no sign) and the RMS spreads along and across
    it, on rows of every orientation, noisy and exact (the residual of a thin row is not lost)."""
    from stcvision.stages.heading import tls_line

    rng = np.random.default_rng(8)
    for k in range(400):
        n = int(rng.integers(2, 9))
        ang = rng.uniform(-np.pi, np.pi) if k % 4 else rng.choice([0.0, np.pi / 2, np.pi / 4, -np.pi / 4])
        t = rng.uniform(-0.05, 0.05, n)
        noise = 0.0 if k % 3 == 0 else 10 ** rng.uniform(-7, -3)
        pts = np.column_stack([0.3 + t * np.cos(ang), 0.1 + t * np.sin(ang)]) + rng.normal(0, noise, (n, 2))
        _, sv, vt = np.linalg.svd(pts - pts.mean(0))
        got, span, resid = tls_line(pts)
        d = (np.arctan2(vt[0, 1], vt[0, 0]) - got + np.pi / 2) % np.pi - np.pi / 2
        assert abs(d) < 1e-9 or sv[0] < 1e-12
        assert span == pytest.approx(sv[0] / np.sqrt(n), rel=1e-12, abs=1e-15)
        assert resid == pytest.approx(sv[-1] / np.sqrt(n), rel=1e-6, abs=1e-15)


def test_red_blobs_are_opencvs_moments():
    """find_red's compiled blob pass (stcvision.stages.red.blobs) against cv2.moments, cv2.boundingRect and
    numpy per contour, as find_red computed them before: random discs and lone pixels (thin
    blobs: zero area, the points' mean), bit for bit."""

    from stcvision.stages import RedParams, find_red

    rng = np.random.default_rng(0)
    for _ in range(60):
        img = np.zeros((120, 130), np.uint16)
        for _ in range(rng.integers(1, 8)):
            c = (int(rng.integers(0, 130)), int(rng.integers(0, 120)))
            cv2.circle(img, c, int(rng.integers(0, 9)), int(rng.integers(50, 4000)), -1)
        img[rng.random(img.shape) < 0.01] = 77
        got = find_red(img, RedParams(min_area_px=2), window_area=9)
        contours, _ = cv2.findContours((img > 0).astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        xy, peak, area = [], [], []
        for c in contours:
            m = cv2.moments(c)
            a = max(m["m00"], float(len(c)))
            if a < 2:
                continue
            xy.append((m["m10"] / m["m00"], m["m01"] / m["m00"]) if m["m00"] > 0 else tuple(c.reshape(-1, 2).mean(0)))
            x, y, w, h = cv2.boundingRect(c)
            peak.append(float(img[y : y + h, x : x + w].max()) / 9)
            area.append(a)
        assert np.array_equal(got.xy_px, np.array(xy, float).reshape(-1, 2))
        assert np.array_equal(got.peak_dn, np.array(peak)) and np.array_equal(got.area_px, np.array(area))


def test_stage_times_keep_each_stage_under_its_own_name():
    """Each stage's time is stored under the name it was timed by, from a clock read on entry and
    exit; a name timed twice or a stage timed inside another is refused, so no stage's time can
    land under another's name."""
    from stcvision.stages import StageTimes

    ticks = iter([0, 2_000_000, 5_000_000, 5_500_000])
    times = StageTimes(clock=lambda: next(ticks))
    with times("dark"):
        pass
    with times("dots"):
        pass
    assert times.ms == {"dark": 2.0, "dots": 0.5}
    with pytest.raises(RuntimeError, match="twice"):
        times("dark")
    outer = StageTimes()
    with pytest.raises(RuntimeError, match="inside"), outer("red"), outer("heading"):
        pass
