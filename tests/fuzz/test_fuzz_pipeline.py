"""Fuzz the vision pipeline's entry points: ``Pipeline`` (build from odd but valid profiles,
``set_dark``, ``process``) and the public stage functions, with arrays of the wrong dtype,
shape or size, NaN/inf, and frames of the right form whose content is extreme (black, white,
noise, a few hot pixels).

Contract (fuzzlib): a result or a one-line project error. For frames of the right form the
result must also be sane: finite dot positions, a heading that is finite when the fit says ok.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from stcvision.errors import StcVisionError

from .fuzzlib import examples, mutated, numbers, project_call
from .test_fuzz_loaders import _profile_dict, small_arrays

H, W = 480, 640  # the default profile's frame


@functools.cache
def pipeline():
    from stcvision.calibration.profiles import default_profile
    from stcvision.pipeline import Pipeline

    return Pipeline(default_profile())


@pytest.fixture(scope="module", autouse=True)
def _compiled():
    """Compile the stages' kernels before the first example: numba's first compile (seconds, up to
    tens of seconds on a loaded machine) is not the input's time, which the deadline bounds."""
    from stcvision.stages import find_dots

    # every frame type the strategies draw that reaches a kernel: each is a compile of its own
    # (a uint8 frame's first example once took 13.7 s on a loaded machine, over the deadline)
    for dtype in (np.uint8, np.uint16, np.float32, np.float64):
        project_call(find_dots, np.zeros((300, 300), dtype), background_dn=0.0, noise_dn=1.0)
    pipeline().process(np.zeros((H, W, 3), np.uint8))


@st.composite
def frames(draw, shape=(H, W, 3)):
    """A frame of the right form with extreme content."""
    kind = draw(st.sampled_from(["const", "noise", "hot", "stripes"]))
    seed = draw(st.integers(0, 2**16))
    rng = np.random.default_rng(seed)
    if kind == "const":
        return np.full(shape, draw(st.sampled_from([0, 1, 128, 254, 255])), np.uint8)
    if kind == "noise":
        lo = draw(st.integers(0, 255))
        return rng.integers(lo, 256, size=shape, dtype=np.uint8)
    img = np.full(shape, draw(st.integers(0, 40)), np.uint8)
    if kind == "hot":
        n = draw(st.integers(1, 2000))
        img.reshape(-1)[rng.integers(0, img.size, n)] = 255
    else:
        img[:: draw(st.integers(1, 9))] = 255
    return img


wrong_frames = st.one_of(
    small_arrays(),
    st.builds(lambda dt: np.zeros((H, W, 3), dt), st.sampled_from([np.uint16, np.float32, np.float64, np.int8, bool])),
    st.sampled_from([np.zeros((H, W), np.uint8), np.zeros((W, H, 3), np.uint8), np.zeros((H, W, 4), np.uint8)]),
    st.sampled_from([None, [[1, 2, 3]], "frame.png", 3.0]),
    st.builds(lambda v: np.full((H, W, 3), v, np.float64), st.sampled_from([np.nan, np.inf, -1.0, 300.0])),
)


def _check_result(res) -> None:
    d = res.dots
    assert np.isfinite(d.xy_px).all() and np.isfinite(d.snr).all()
    if res.heading.ok:
        assert np.isfinite(res.heading.heading_error_rad)
    assert np.isfinite(res.red.xy_px).all()
    res.to_dict()


@examples(0.5)
@given(st.one_of(frames(), wrong_frames), st.one_of(st.none(), frames(), wrong_frames))
def test_process(frame, dark):
    res = project_call(pipeline().process, frame, dark=dark)
    if not isinstance(res, StcVisionError):
        _check_result(res)
    pipeline().dark = None  # the next example starts without a dark frame


@examples(0.2)
@given(
    mutated(_profile_dict(), max_edits=2, keys=["neighbour_corners_px", "theta_poly", "center_px"]),
    st.sampled_from(["as-is", "corners-coincide", "corners-collinear", "corners-nan-free-huge", "flat-theta"]),
)
def test_pipeline_from_profile(d, twist):
    """Every profile that loads gives a pipeline that runs, or a project error at build time
    (e.g. 12 corners that coincide give no cell geometry)."""
    from stcvision.pipeline import Pipeline
    from stcvision.profile import Profile

    if twist == "corners-coincide":
        d["neighbour_corners_px"] = [[150.0, 150.0]] * 12
    elif twist == "corners-collinear":
        d["neighbour_corners_px"] = [[10.0 * k, 10.0 * k] for k in range(12)]
    elif twist == "corners-nan-free-huge":
        d["neighbour_corners_px"] = [[1e300, -1e300]] * 12
    elif twist == "flat-theta":
        d["theta_poly"] = [0.0, 0.0]
    prof = project_call(Profile.from_dict, d)
    if isinstance(prof, StcVisionError) or prof.ground_size_px > 400:
        return
    pipe = project_call(Pipeline, prof)
    if isinstance(pipe, StcVisionError):
        return
    w, h = prof.image_size_px
    if w * h > 1_000_000:
        return
    frame = np.random.default_rng(0).integers(0, 60, size=(h, w, 3), dtype=np.uint8)
    res = project_call(pipe.process, frame)
    if not isinstance(res, StcVisionError):
        _check_result(res)


# ------------------------------------------------------------------------------------ stages
any_arrays = st.one_of(small_arrays(), frames(shape=(6, 7, 3)), st.sampled_from([None, 1.5, [[0, 1]]]))


@examples(2)
@given(any_arrays, any_arrays, st.one_of(st.integers(-5, 300), numbers))
def test_subtract_dark(frame, dark, pedestal):
    from stcvision.stages import subtract_dark

    if not isinstance(pedestal, int) or isinstance(pedestal, bool):
        pedestal = 0
    out = project_call(subtract_dark, frame, dark, pedestal_dn=max(0, min(pedestal, 255)))
    if not isinstance(out, StcVisionError):
        assert out.dtype == np.uint8 and out.shape == frame.shape


@examples(2)
@given(any_arrays)
def test_hot_pixels(dark):
    from stcvision.stages import hot_pixels

    out = project_call(hot_pixels, dark)
    if not isinstance(out, StcVisionError):
        assert out.ndim == 1 and (out < dark.size).all()


@examples(2)
@given(any_arrays, st.integers(-2, 9))
def test_filter_channels_and_window_sums(image, window):
    from stcvision.stages import filter_channels, window_sums

    out = project_call(filter_channels, image)
    if not isinstance(out, StcVisionError):
        assert all(o.shape == image.shape[:2] for o in out)
    s = project_call(window_sums, image, window)
    if not isinstance(s, StcVisionError):
        assert s.dtype in (np.uint16, np.float32) and s.shape[:2] == image.shape[:2]


@examples(2)
@given(any_arrays)
def test_find_red_and_background(image):
    from stcvision.stages import estimate_background, find_red

    red = project_call(find_red, image)
    if not isinstance(red, StcVisionError):
        assert np.isfinite(red.xy_px).all()
    bg = project_call(estimate_background, image)
    if not isinstance(bg, StcVisionError):
        assert all(np.isfinite(bg))


@examples(1)
@given(st.one_of(any_arrays, frames(), frames(shape=(H, W))))
def test_unwarp(image):
    from stcvision.stages import unwarp

    out = project_call(unwarp, image, pipeline().umap)
    if not isinstance(out, StcVisionError):
        n = pipeline().profile.ground_size_px
        assert out.shape[:2] == (n, n)


@examples(1)
@given(st.one_of(small_arrays(max_side=40), frames(shape=(300, 300)), st.sampled_from([None, 2.0])))
def test_find_dots(marks):
    from stcvision.stages import find_dots

    dots = project_call(find_dots, marks, background_dn=0.0, noise_dn=1.0)
    if not isinstance(dots, StcVisionError):
        assert np.isfinite(dots.xy_px).all()
