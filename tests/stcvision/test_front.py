"""The pipeline's compiled front end (``stcvision.stages.front`` and its four stage modules)
against the OpenCV stages it stands for, bit for bit: the unwarp and channel separation against
``cv2.remap`` and the separation written with OpenCV calls (:func:`opencv_separation`, kept here
as the reference), the two-channel dark subtraction against each channel's, the background
sample against ``estimate_background``; and a result's images are its own (the next frame does
not overwrite them)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from stcvision.observation import ObservationParams
from stcvision.pipeline import Pipeline, PipelineParams
from stcvision.stages import (
    ChannelParams,
    estimate_background,
    ground_view,
    noise_floor,
    separate_channels,
    window_sums,
)
from stcvision.stages.channels import black_out, separation_rule
from stcvision.stages.dark import dark_channels, frame_background
from stcvision.stages.ground_view import unwarp_separate


def opencv_separation(
    g: np.ndarray,
    r: np.ndarray,
    params: ChannelParams,
    *,
    window_area: int = 1,
    leak_threshold: float | None = None,
    background_dn: float,
    noise_dn: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The red/green separation written with OpenCV calls (saturating adds, comparisons,
    ``cv2.addWeighted``, a dilated mask): the independent reference the compiled rule
    (``separate_channels``, ``unwarp_separate``) must equal bit for bit."""
    thr, tol = params.levels(background_dn, noise_dn)
    # red-dominated: R >= G up to a tolerance (where both saturate, the dark frame decides which
    # reads higher); saturating add. A green dot has R ~ G / 12 even when its green saturates.
    dominated = cv2.compare(cv2.add(r, float(tol * window_area)), g, cv2.CMP_GE)
    if params.red_min_fraction > 0:  # R - bg >= f (G - bg), in float (no unsigned wrap)
        f, bg = params.red_min_fraction, background_dn * window_area
        redder = cv2.addWeighted(r, 1.0, g, -f, -(1.0 - f) * bg, dtype=cv2.CV_32F)
        dominated = cv2.bitwise_and(dominated, cv2.compare(redder, 0.0, cv2.CMP_GE))
    red = cv2.bitwise_and(cv2.compare(r, float(thr * window_area), cv2.CMP_GT), dominated)
    obstacle = cv2.bitwise_and(r, r, mask=red)
    if leak_threshold is not None:
        leak = cv2.bitwise_and(cv2.compare(r, float(leak_threshold), cv2.CMP_GT), dominated)
        # a leak level at or below the light's own holds every light pixel already
        red = leak if leak_threshold <= thr * window_area else cv2.bitwise_or(red, leak)
    if not cv2.countNonZero(red):
        return obstacle, g  # nothing to black out (the marks image is the green one)
    if params.red_margin_px > 0:
        k = 2 * params.red_margin_px + 1
        red = cv2.dilate(red, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    marks = cv2.bitwise_and(g, g, mask=cv2.bitwise_not(red))
    return obstacle, marks


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
def test_separate_channels_is_the_opencv_separation(dtype):
    """``separate_channels`` (the pipeline's compiled rule over the identity map) equals the
    OpenCV separation on random images of every input type, with and without the red fraction,
    a leak level and a margin: 60 cases each."""
    rng = np.random.default_rng({np.uint8: 1, np.uint16: 2, np.float32: 3}[dtype])
    hi = 255 if dtype == np.uint8 else 9 * 255
    for _ in range(60):
        h, w = (int(v) for v in rng.integers(1, 40, 2))
        g, r = (rng.integers(0, hi + 1, (h, w)).astype(dtype) for _ in range(2))
        if dtype == np.float32:
            g, r = ((v + rng.random((h, w))).astype(np.float32) for v in (g, r))
        params = ChannelParams(red_min_fraction=float(rng.choice([0.0, 0.3])), red_margin_px=int(rng.integers(0, 3)))
        kw = dict(
            window_area=1 if dtype == np.uint8 else 9,
            leak_threshold=None if rng.random() < 0.5 else float(rng.uniform(0, hi)),
            background_dn=float(rng.uniform(0, 30)),
            noise_dn=float(rng.uniform(0.5, 5)),
        )
        got, ref = separate_channels(g, r, params, **kw), opencv_separation(g, r, params, **kw)
        assert got[0].dtype == ref[0].dtype == dtype
        assert np.array_equal(got[0], ref[0]) and np.array_equal(got[1], ref[1]), (params, kw)


@pytest.mark.parametrize("view", ["main", "wide"])
@pytest.mark.parametrize("dtype", [np.uint16, np.float32])
@pytest.mark.parametrize(
    "channels,leak",
    [
        (ChannelParams(), 120.0),  # leak below the light threshold: the leak mask alone
        (ChannelParams(), 5000.0),  # above: lights and leak together
        (ChannelParams(red_margin_px=0, red_min_fraction=0.0), 300.0),
        (ChannelParams(red_threshold_dn=30.5, dominance_tol_dn=2.5, red_min_fraction=0.3), 200.0),
        (ChannelParams(dominance_tol_dn=-3.0), 150.0),  # a negative tolerance saturates at 0
    ],
)
def test_unwarp_and_separation_are_remap_and_separate_channels(
    default_profile, view, dtype, channels, leak, monkeypatch
):
    """The compiled unwarp + separation (``unwarp_separate``: its uint16, float32 and border
    loops) against two ``cv2.remap``s and ``separate_channels``; the wide view's map reads the
    whole frame, and its ground pixels beyond the mirror or at the frame's edge are the border
    pixels, redone with zeros outside."""
    obs = ObservationParams(pose_estimates=True) if view == "wide" else ObservationParams()
    pipe = Pipeline(default_profile, PipelineParams(channels=channels, observation=obs))
    umap, tables = (pipe.wide, pipe.front.wide_tables) if view == "wide" else (pipe.front.umap_crop, pipe.front.tables)
    if view == "wide":
        assert len(tables.border) > 0
    rng = np.random.default_rng(11)
    w, h = umap.image_size_px
    # dots (green), lights (red, with green crosstalk) and a noisy floor, as window sums
    g = rng.normal(90, 14, (h, w)).clip(0)
    r = rng.normal(90, 14, (h, w)).clip(0)
    g[rng.random((h, w)) < 0.01] += 900
    lit = rng.random((h, w)) < 0.005
    r[lit] += rng.uniform(100, 2000, lit.sum())
    g[lit] += 0.06 * r[lit]
    sums = np.dstack([g, r]).round().astype(dtype)
    levels = (10.0, 1.48)
    shape = umap.map_x.shape
    rule = separation_rule(channels, 9, levels, leak, sums.dtype)
    obst, marks, black, n = unwarp_separate(tables, sums, shape, rule, pipe.scratch)
    black_out(marks, black, n, pipe.front.margin, pipe.scratch)
    gg, rr = (
        cv2.remap(
            np.ascontiguousarray(sums[..., c]),
            umap.map_x,
            umap.map_y,
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=0,
        )
        for c in (0, 1)
    )
    ref_o, ref_m = opencv_separation(
        gg, rr, channels, window_area=9, leak_threshold=leak, background_dn=levels[0], noise_dn=levels[1]
    )
    assert obst.dtype == ref_o.dtype and marks.dtype == ref_m.dtype
    assert np.array_equal(obst, ref_o)
    assert np.array_equal(marks, ref_m)
    assert (marks == 0).sum() > (gg == 0).sum()  # something was blacked out
    if dtype == np.uint16:  # the float32 gathers uint16 sums take where the uint32 ones cannot
        monkeypatch.setattr(ground_view, "_U32_GATHERS", False)
        obst2, marks2, black2, n2 = unwarp_separate(tables, sums, shape, rule, pipe.scratch)
        black_out(marks2, black2, n2, pipe.front.margin, pipe.scratch)
        assert n2 == n and np.array_equal(obst2, ref_o) and np.array_equal(marks2, ref_m)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("shape", [(389, 390), (1, 5), (4, 1), (2, 2), (1, 1), (3, 2)])
def test_window_sums_are_box_filter(default_profile, shape, dtype):
    """The compiled 3 x 3 window sums of a pair of 8- or 16-bit images (``window_sums`` of the
    pair, its fast path) against ``window_sums`` of the two-channel image (cv2.boxFilter), edges
    included, on bright and saturated pixels."""
    top = np.iinfo(dtype).max
    gr = np.random.default_rng(4).integers(0, top + 1, (*shape, 2)).astype(dtype)
    gr[0, 0] = top  # saturated: the largest sums
    got = window_sums((np.ascontiguousarray(gr[..., 0]), np.ascontiguousarray(gr[..., 1])), 3)
    ref = window_sums(gr, 3)
    assert got.dtype == ref.dtype == (np.uint16 if dtype == np.uint8 else np.float32)
    assert np.array_equal(got, ref)


def test_channels_are_extract_and_subtract(default_profile):
    """The dark subtraction (one split of the crop's rows, then add and subtract per channel)
    against each channel extracted from the crop, dark-subtracted and its hot pixels set."""
    rng = np.random.default_rng(2)
    w, h = default_profile.image_size_px
    dark = rng.integers(0, 14, (h, w, 3)).astype(np.uint8)
    dark.reshape(-1)[rng.choice(dark.size, 300, replace=False)] = 200  # hot pixels
    frame = rng.integers(0, 256, (h, w, 3)).astype(np.uint8)  # saturating both ways
    pipe = Pipeline(default_profile, dark=dark)
    gr = dark_channels(frame, pipe.crop, pipe.front.dark, pipe.scratch)
    assert all(c.flags.c_contiguous for c in gr)
    x0, y0, x1, y1 = pipe.crop
    for k, (ch, hot) in enumerate(((1, pipe.front.dark.hot_green), (2, pipe.front.dark.hot_red))):
        c = cv2.extractChannel(frame[y0:y1, x0:x1], ch)
        ref = cv2.subtract(cv2.add(c, pipe.pedestal), cv2.extractChannel(dark[y0:y1, x0:x1], ch))
        ref.reshape(-1)[hot] = pipe.pedestal
        assert len(hot) > 0
        assert np.array_equal(gr[k], ref)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_background_is_estimate_background(default_profile, dtype):
    rng = np.random.default_rng(5)
    w, h = default_profile.image_size_px
    hi = 255 if dtype == np.uint8 else 4095
    dark = rng.integers(0, 12, (h, w, 3)).astype(dtype)
    dark.reshape(-1)[rng.choice(dark.size, 500, replace=False)] = hi // 2  # hot pixels
    frame = (rng.normal(30, 4, (h, w, 3)).clip(0, hi)).astype(dtype)
    for d in (None, dark):
        pipe = Pipeline(default_profile, dark=d)
        got = frame_background(frame, pipe.front.sample3, pipe.front.dark)
        q = pipe.quantum
        ref = []
        for k, ch in enumerate((1, 2)):
            v = frame.reshape(-1)[pipe.front.sample3[ch]]
            if d is not None:
                v = cv2.subtract(cv2.add(v, pipe.pedestal), d.reshape(-1)[pipe.front.sample3[ch]]).reshape(-1)
                v[pipe.front.dark.hot_sample[k]] = pipe.pedestal
                assert pipe.front.dark.hot_sample[k].any()
            else:
                q = 1
            bg, noise = estimate_background(v, slice(None), q)
            ref += [bg, max(noise, noise_floor(q))]
        assert got == (*ref, q)


@pytest.mark.parametrize("pose", [False, True])  # with the pose estimates the crop is the whole frame
@pytest.mark.parametrize("with_dark", [False, True])
def test_result_images_are_its_own(default_profile, pose, with_dark):
    """The front end reuses scratch images from frame to frame; what a result holds is not one."""
    rng = np.random.default_rng(3)
    w, h = default_profile.image_size_px
    dark = rng.integers(0, 8, (h, w, 3)).astype(np.uint8) if with_dark else None
    pipe = Pipeline(default_profile, PipelineParams(observation=ObservationParams(pose_estimates=pose)), dark=dark)
    f1 = rng.integers(0, 60, (h, w, 3)).astype(np.uint8)
    f2 = rng.integers(0, 60, (h, w, 3)).astype(np.uint8)
    r1 = pipe.process(f1)
    kept = [x.copy() for x in (r1.green, r1.red_raw, r1.obstacle, r1.marks)]
    pipe.process(f2)
    for a, b in zip(kept, (r1.green, r1.red_raw, r1.obstacle, r1.marks), strict=True):
        assert np.array_equal(a, b)


def test_map_at_is_remap_of_the_map(default_profile):
    """map_at (the unwarp map read at the dots and +-0.5 px, for the mirror-image
    centroids) against cv2.remap of each map at those points, beyond the map's edges too."""
    from stcvision.stages.dots import _JAC_STEPS, map_at

    um = Pipeline(default_profile).front.umap_crop
    pts = np.random.default_rng(0).uniform(-2, um.map_x.shape[0] + 2, (3000, 2))
    q = (pts[:, None, :] + _JAC_STEPS[None]).reshape(1, -1, 2).astype(np.float32)
    ref = np.stack(
        [
            cv2.remap(m, q[..., 0], q[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=-10.0)
            for m in (um.map_x, um.map_y)
        ],
        axis=-1,
    ).reshape(len(pts), len(_JAC_STEPS), 2)
    assert np.array_equal(map_at(um.map_x, um.map_y, pts, _JAC_STEPS, -10.0), ref)


def test_scratch_lends_the_same_array_per_purpose_shape_and_dtype():
    from stcvision.stages import Scratch

    s = Scratch()
    a = s("sums", (4, 5, 2), np.uint16)
    assert s("sums", (4, 5, 2), np.uint16) is a
    assert s("sums", (4, 6, 2), np.uint16) is not a and s("sums", (4, 5, 2), np.float32) is not a
    assert s("black", (4, 5, 2), np.uint16) is not a


def test_front_end_is_built_once_and_takes_each_dark_frame_apart(default_profile):
    """A dark frame changes only the front end's dark part: the unwarp tables and the sample
    stay the ones built from the profile; forgetting the dark frame forgets its pedestal too."""
    rng = np.random.default_rng(8)
    w, h = default_profile.image_size_px
    dark = rng.integers(0, 14, (h, w, 3)).astype(np.uint8)
    pipe = Pipeline(default_profile)
    built = pipe.front
    assert pipe.dark is None and pipe.pedestal == 0
    pipe.set_dark(dark)
    assert pipe.front.tables is built.tables and pipe.front.sample3 is built.sample3
    assert pipe.dark is dark and pipe.pedestal >= PipelineParams().pedestal_steps
    x0, y0, x1, y1 = pipe.crop
    assert pipe.front.dark.green.shape == pipe.front.dark.red.shape == (y1 - y0, x1 - x0)
    pipe.dark = None
    assert pipe.dark is None and pipe.pedestal == 0 and pipe.front.tables is built.tables


@pytest.mark.parametrize(
    "pair",
    [
        (np.zeros((4, 4), np.uint8),),
        (np.zeros((4, 4), np.uint8), np.zeros((4, 5), np.uint8)),
        (np.zeros((4, 4), np.uint8), np.zeros((4, 4), np.uint16)),
        (np.zeros((4, 4, 3), np.uint8), np.zeros((4, 4, 3), np.uint8)),
        (np.zeros((4, 4), np.uint8), None),
    ],
)
def test_window_sums_refuse_a_malformed_pair(pair):
    from stcvision.errors import BadInputError

    with pytest.raises(BadInputError):
        window_sums(pair, 3)


@pytest.mark.parametrize("quantum", [1, 16])
@pytest.mark.parametrize("outliers", [0, 20])
def test_histogram_quartiles_are_numpy_interp(quantum, outliers):
    """The compiled quartiles (each value spread over its step) against numpy's: ``np.interp`` of
    (0.25, 0.5, 0.75) on the strictly increasing points of the cumulative histogram, to the last
    bit, on a dark background with saturated pixels far above it (the 16-bit frame's case, whose
    histogram spans tens of thousands of empty bins beyond the last quartile)."""
    from stcvision.stages.dark import histogram_quartiles

    rng = np.random.default_rng(quantum + outliers)
    v = (np.clip(rng.normal(300, 20, 7000), 0, None).astype(np.int64) // quantum) * quantum
    v[:outliers] = 65535 // quantum * quantum
    lo = int(v.min())
    nbins = (int(v.max()) - lo) // quantum + 1
    cdf = np.concatenate([[0.0], np.cumsum(np.bincount((v - lo) // quantum, minlength=nbins))]) / len(v)
    keep = np.concatenate([[True], np.diff(cdf) > 0])
    edges = lo + (np.arange(nbins + 1) - 0.5) * quantum
    want = np.interp([0.25, 0.5, 0.75], cdf[keep], edges[keep])
    assert np.array_equal(histogram_quartiles(v, lo, quantum, nbins), want)
