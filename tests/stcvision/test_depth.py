"""16-bit frames through the pipeline, thresholds from measured noise, and bounded work per frame
(sensor-true frames of any ADC depth).

The 16-bit frames are made here from the camera's own electrons (its noise, fixed pattern and
full well), digitised to ``bits`` bits instead of 8: the contract with the sensor model is a
uint16 frame holding the ADC counts 0..2^b-1 (LSB-aligned); MSB-aligned counts must read the same.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from stcvision.errors import BadInputError
from stcvision.pipeline import Pipeline
from stcvision.sim_camera.camera import Pose, SyntheticCamera
from stcvision.sim_camera.image_sensor import expose
from stcvision.sim_camera.phosphor import PhosphorLayer, mark_dots_m
from stcvision.stages import (
    DotParams,
    estimate_background,
    find_dots,
    hot_pixels,
    noise_floor,
    quantum_dn,
    subtract_dark,
)


def _digitise(cam: SyntheticCamera, sig: np.ndarray, bits: int, rng) -> np.ndarray:
    """The camera's noisy electrons (its own :func:`expose`, which leaves them in ``sig``),
    digitised at ``bits`` bits with the same electrons per full scale as its 8-bit frames."""
    s = cam.sensor
    expose(sig, s, cam.pattern, rng)
    scale = (2**bits - 1) / 255.0
    dn = np.rint(sig * np.float32(s.dn_per_e * scale) + np.float32(s.black_level_dn * scale))
    return np.clip(dn, 0, 2**bits - 1).astype(np.uint16)


def _frames(bits: int, seed: int = 5):
    """A dark frame (median of 8) and one frame of a few marks, 6-40 s old, at ``bits`` bits."""
    cam = SyntheticCamera()
    rng = np.random.default_rng(seed)
    darks = [_digitise(cam, np.zeros((*cam.shape, 3), np.float32), bits, rng) for _ in range(8)]
    dark = np.median(np.stack(darks), axis=0).round().astype(np.uint16)
    layer = PhosphorLayer()
    for k, (x, y) in enumerate([(0.2, 0.1), (0.25, -0.2), (-0.2, 0.2), (0.05, 0.35), (-0.3, -0.1)]):
        layer.charge(
            mark_dots_m((x, y), (0.0, 1.0) if k % 2 else (1.0, 0.0), 0.16), t_start_s=-6.0 - 8 * k, duration_s=3.0
        )
    sig, _ = cam.signal(Pose(0, 0, 0), phosphor=layer)
    return dark, _digitise(cam, sig.copy(), bits, rng), layer


@pytest.fixture(scope="module")
def frames12():
    return _frames(12)


def test_twelve_bit_frames_read_as_the_eight_bit_ones_do(default_profile, frames12):
    """The same electrons at 12 bits: every dot the 8-bit frame shows is found (finer steps
    can only help), nothing is added that is not a mark, and LSB- and MSB-aligned counts
    (x16) give the same dots, SNRs and boxes."""
    dark, frame, layer = frames12
    pipe = Pipeline(default_profile, dark=dark)
    lsb = pipe.process(frame)
    assert not lsb.untrusted
    assert pipe.quantum == 1 and pipe.pedestal >= 10
    truth = default_profile.robot_to_ground(layer.xy_m)
    lit = lsb.dots.xy_px[lsb.dots.lit]
    err = np.min(np.hypot(*(lit[:, None] - truth[None]).transpose(2, 0, 1)), axis=1)
    assert lsb.dots.n_lit >= 18 and err.max() < 1.5  # 20 dots laid, 6-38 s old; no false dot
    msb = Pipeline(default_profile, dark=dark * np.uint16(16)).process(frame * np.uint16(16))
    assert msb.dots.n_lit == lsb.dots.n_lit
    np.testing.assert_allclose(msb.dots.xy_px, lsb.dots.xy_px, atol=1e-6)
    np.testing.assert_allclose(msb.dots.snr, lsb.dots.snr, rtol=1e-5)
    assert msb.observation.to_dict() == lsb.observation.to_dict()


def test_sixteen_bit_dark_frame_must_match_the_frame(default_profile, frames12):
    dark, frame, _ = frames12
    pipe = Pipeline(default_profile, dark=dark)
    with pytest.raises(BadInputError, match="dark frame has dtype uint16, the frame uint8"):
        pipe.process((frame >> 4).astype(np.uint8))
    with pytest.raises(BadInputError, match="dark frame"):
        subtract_dark(frame, (dark >> 4).astype(np.uint8))
    assert subtract_dark(frame, dark, pedestal_dn=100).dtype == np.uint16


def test_display_images_of_a_sixteen_bit_frame_use_the_eight_bits(default_profile, frames12):
    dark, frame, _ = frames12
    pipe = Pipeline(default_profile, dark=dark)
    r = pipe.process(frame)
    marks = r.marks_u8()
    assert marks.dtype == np.uint8 and 0 < int(np.median(marks)) < 255  # not saturated at 255
    assert pipe.ground_view(frame).dtype == np.uint8


def test_noise_and_quantum_are_measured_at_any_depth():
    rng = np.random.default_rng(1)
    v = np.rint(rng.normal(1000.0, 7.0, 20000)).astype(np.uint16)
    med, sigma = estimate_background(v.reshape(100, 200))
    assert med == pytest.approx(1000.0, abs=0.3) and sigma == pytest.approx(7.0, rel=0.05)
    assert quantum_dn(v) == 1 and quantum_dn(v * np.uint16(16)) == 16
    med16, sigma16 = estimate_background((v * np.uint16(16)).reshape(100, 200), quantum=16)
    assert med16 == pytest.approx(16 * med, rel=1e-3) and sigma16 == pytest.approx(16 * sigma, rel=0.02)
    # constant data: the rounding noise of one step, whatever the step
    assert estimate_background(np.full((50, 50), 64, np.uint16), quantum=16)[1] >= noise_floor(16)


def test_hot_pixels_of_a_sixteen_bit_dark_frame(frames12):
    dark, _, _ = frames12
    dark = dark.copy()
    dark[100, 200, 1] += 400  # a hot pixel far above the spread
    hot = hot_pixels(dark)
    assert (100 * dark.shape[1] + 200) * 3 + 1 in set(hot.tolist())
    assert len(hot) < 0.01 * dark.size
    # MSB-aligned: the same pixels
    assert np.array_equal(hot_pixels(dark * np.uint16(16)), hot)


def test_sixty_thousand_candidates_are_reported_in_bounded_memory():
    """A frame whose noise estimate does not describe it (a flat frame brighter than
    the background it was given: every pixel of the plateau a local maximum) gave 61,145
    candidates and a 27.9 GiB pairwise matrix. Now it is read within a small memory budget and
    reported as untrusted, never silently truncated."""
    marks = np.full((256, 256), 12, np.uint8)
    tracemalloc.start()
    try:
        dots = find_dots(marks, background_dn=10.0, noise_dn=0.3)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert "candidates" in dots.untrusted
    assert int(dots.untrusted.split()[0]) > 60000
    assert peak < 64e6  # bytes; the N x N matrix of 61,000 candidates needs 30 GB
    # a frame within the caps is trusted
    rng = np.random.default_rng(2)
    noise = np.clip(np.rint(rng.normal(10, 1.5, (256, 256))), 0, 255).astype(np.uint8)
    assert find_dots(noise, background_dn=10.0, noise_dn=1.5).untrusted == ""
    capped = find_dots(marks, DotParams(max_candidates=10**6, max_dots=50), background_dn=10.0, noise_dn=0.3)
    assert "max_dots" in capped.untrusted and len(capped) == 50


def test_an_untrusted_frame_says_so_in_its_observation(default_profile):
    """A frame the background sample misdescribes (the sampled pixels dark, all others bright):
    the pipeline reads it with bounded work and the observation carries the reason."""
    w, h = default_profile.image_size_px
    frame = np.full((h, w, 3), 8, np.uint8)
    frame[..., 1] = 30  # a green glow
    frame[::5, ::5, 1] = 8  # except exactly at the pixels the noise estimate samples
    dark = np.full((h, w, 3), 8, np.uint8)
    r = Pipeline(default_profile, dark=dark).process(frame)
    assert r.untrusted and r.observation.untrusted == r.untrusted
    assert r.to_dict()["untrusted"] == r.untrusted
