"""The front end: dark subtraction, the frame's background and noise, window sums, the unwarp
to the ground view and the red/green channel separation.

Seed 003 sections: "Noise handling" (dark frame) and "Image Transformation and Filtering"
(unwarp, red/green images). Each public function is the stage as it runs, choosing its compiled
path itself where one exists (bit for bit the OpenCV arithmetic it stands for);
:class:`FrontEnd` is the pipeline's front end, built once from the profile and the dark frame.
"""

from __future__ import annotations

import functools
import math
import sys
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import cv2
import numba
import numpy as np

from stcvision.errors import BadInputError
from stcvision.stages.common import SUM_DTYPES, Scratch, check_frame, check_image, new_arrays, noise_floor
from stcvision.stages.compiled import _U, _as_f32, _f32, _fma32, _lerp, _load_u64


def check_dark_dtype(dark: np.ndarray, frame_dtype) -> None:
    """A dark frame must come from the same ADC as the frames: the same dtype."""
    if dark.dtype != frame_dtype:
        raise BadInputError(
            f"dark frame has dtype {dark.dtype}, the frame {np.dtype(frame_dtype)}; "
            "expected a dark frame from the same camera at the same bit depth"
        )


def quantum_dn(values: np.ndarray) -> int:
    """The quantisation step of integer pixel values (DN): the greatest common divisor of their
    differences -- 1 for LSB-aligned data of any depth, 16 for 12-bit counts MSB-aligned in
    16 bits. Noise floors are fractions of this step, so the alignment does not matter."""
    v = np.asarray(values).reshape(-1).astype(np.int64)
    if not len(v):
        return 1
    return max(int(np.gcd.reduce(v - v.min())), 1)


def robust_sigma(values: np.ndarray) -> tuple[float, float]:
    """(median, 1.4826 x median absolute deviation) of pixel values. The MAD of quantised data
    is a whole number of steps: 0 only says the spread is below half a step, i.e. sigma below
    1.4826 x step / 2 (:data:`UNRESOLVED_SIGMA`)."""
    v = np.asarray(values).reshape(-1).astype(np.float32)
    med = float(np.median(v))
    return med, 1.4826 * float(np.median(np.abs(v - med)))


#: the largest sigma (in quantisation steps) of data whose MAD rounds to 0
UNRESOLVED_SIGMA = 1.4826 * 0.5


def subtract_dark(
    frame: np.ndarray,
    dark: np.ndarray,
    *,
    pedestal_dn: int = 0,
    frame_exposure_s: float | None = None,
    dark_exposure_s: float | None = None,
) -> np.ndarray:
    """Subtract a dark frame, saturating at 0 (never wrapping).

    Seed 003, "Noise handling": "we took a photo in complete darkness ... and deducted this
    photo from every taken snapshot". The dark frame must match the frame's size and, where
    both are known, its exposure (dark current grows with exposure).

    ``pedestal_dn`` keeps a constant offset (``frame - dark + pedestal``, still saturating):
    the background noise then stays symmetric instead of being cut at 0, so the noise level can
    be measured from the image itself (astronomers keep a pedestal for the same reason).

    Parameters
    ----------
    frame, dark : (H, W, 3) BGR, both uint8 or both uint16
    """
    check_frame(frame)
    check_frame(dark, "dark frame")
    check_dark_dtype(dark, frame.dtype)
    if frame.shape != dark.shape:
        raise BadInputError(
            f"dark frame is {dark.shape[1]}x{dark.shape[0]}, frame is {frame.shape[1]}x{frame.shape[0]}; "
            "expected the same size"
        )
    if frame_exposure_s is not None and dark_exposure_s is not None:
        if abs(frame_exposure_s - dark_exposure_s) > 0.01 * max(frame_exposure_s, dark_exposure_s):
            raise BadInputError(
                f"dark frame exposure {dark_exposure_s:g} s does not match the frame's {frame_exposure_s:g} s; "
                "capture dark frames at the same exposure"
            )
    return _dark_subtracted(frame, dark, pedestal_dn)


def _dark_subtracted(image: np.ndarray, dark: np.ndarray, pedestal_dn: int) -> np.ndarray:
    """``(image + pedestal) - dark``, both saturating (only already-saturated pixels lose), of a
    colour frame or of one channel: :func:`subtract_dark` and :func:`dark_channels` alike."""
    if pedestal_dn:
        return cv2.subtract(cv2.add(image, (pedestal_dn,) * 3 if image.ndim == 3 else pedestal_dn), dark)
    return cv2.subtract(image, dark)


def hot_pixels(dark: np.ndarray, *, k_sigma: float = 8.0, quantum: float | None = None) -> np.ndarray:
    """Flat indices (into ``dark.reshape(-1)`` of an (H, W, 3) frame) of hot pixels: dark-frame
    values more than ``k_sigma`` robust sigmas above the typical dark level. Their dark
    current's shot noise is several times the read noise, so they stay noisy after subtraction
    and would pass as faint dots; the pipeline replaces them by the background (a standard
    defect-pixel map). Where the dark frame's spread is below one quantisation step
    (``quantum``, default :func:`quantum_dn` of the frame) its MAD is 0 and only bounds sigma
    (:data:`UNRESOLVED_SIGMA`): the excess is then ``k_sigma`` times that bound, in whole steps
    (6 steps at k = 8)."""
    check_frame(dark, "dark frame")
    v = dark.reshape(-1)
    q = quantum_dn(v[::11]) if quantum is None else quantum
    med, sigma = robust_sigma(v[::11])
    floor = math.ceil(k_sigma * UNRESOLVED_SIGMA) * q
    return np.flatnonzero(v.astype(np.float32) > med + max(k_sigma * sigma, floor))


def estimate_background(image: np.ndarray, sample: np.ndarray | None = None, quantum: int = 1) -> tuple[float, float]:
    """(median, robust sigma) of a uint8 or uint16 image's pixels (or of
    ``image.reshape(-1)[sample]``), whose values are whole multiples of ``quantum`` apart
    (:func:`quantum_dn`).

    From a histogram of the quantisation steps, each spread uniformly over its step (so noise
    levels below a step are not rounded away): the median, and sigma = interquartile range /
    1.349.
    """
    check_image(image, "pixel values", (np.uint8, np.uint16), ndims=(1, 2, 3))
    v = image.reshape(-1)[sample] if sample is not None else image.reshape(-1)[::7]
    # (the pipeline's per-frame sample: sample_quartiles, the same histogram choice)
    if image.dtype == np.uint8 and quantum == 1:
        lo, nbins = 0, 256
    else:  # a histogram of the occupied range only (16-bit data spans few of its 65,536 values)
        lo = int(v.min())
        nbins = (int(v.max()) - lo) // quantum + 1
    # cumulative histogram, its strictly increasing points inverted at the quartiles (compiled)
    q1, med, q3 = histogram_quartiles(np.ascontiguousarray(v), lo, int(quantum), nbins)
    return float(med), float((q3 - q1) / 1.349)


@numba.njit(cache=True)
def histogram_quartiles(v, lo, quantum, nbins):
    """Quartiles of integer values ``v`` (``lo`` + whole steps of ``quantum``), each value
    spread uniformly over its step (:func:`stcvision.stages.estimate_background`): ``np.interp``
    of (0.25, 0.5, 0.75) on the cumulative histogram, step by step as numpy computes it."""
    counts = np.zeros(nbins, np.int64)  # whole counts: the float sums of 1.0 exactly
    if quantum == 1:  # no integer division per value (the common case, measured 2x faster)
        for x in v:
            counts[np.int64(x) - lo] += 1
    else:
        for x in v:
            counts[(np.int64(x) - lo) // quantum] += 1
    hist = counts.astype(np.float64)
    cdf = np.empty(nbins + 1)
    cdf[0] = 0.0
    acc = 0.0
    for i in range(nbins):
        acc += hist[i]
        cdf[i + 1] = acc
    total = cdf[nbins]
    # the strictly increasing points (the first, then each bin that holds values)
    xp = np.empty(nbins + 1)
    fp = np.empty(nbins + 1)
    m = 0
    for i in range(nbins + 1):
        c = cdf[i] / total
        if i == 0 or c > cdf[i - 1] / total:
            xp[m] = c
            fp[m] = lo + (i - 0.5) * quantum
            m += 1
    out = np.empty(3)
    for k, q in enumerate((0.25, 0.5, 0.75)):
        j = 0
        while j + 1 < m and xp[j + 1] <= q:
            j += 1
        if j == m - 1 or xp[j] == q:
            out[k] = fp[j]
        else:
            slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
            out[k] = slope * (q - xp[j]) + fp[j]
    return out


@numba.njit(cache=True)
def _quartiles_of(v, quantum, whole_u8):
    if whole_u8:
        return histogram_quartiles(v, 0, 1, 256)
    lo = np.int64(v.min())
    return histogram_quartiles(v, lo, quantum, (np.int64(v.max()) - lo) // quantum + 1)


@numba.njit(cache=True)
def sample_quartiles(flat, idx, dark_g, dark_r, hot_g, hot_r, ped, top, quantum, whole_u8, out_g, out_r):
    """Quartiles (:func:`histogram_quartiles`, one row per channel) of the green and red of a
    flat BGR frame at the flat green indices ``idx`` (red: the next byte, so one pass reads
    each pixel once), dark-subtracted as the pipeline subtracts them (``max(min(v + ped, top) -
    dark, 0)``, ``ped`` where hot), the values left in ``out_g``, ``out_r``; ``whole_u8``:
    8-bit values in steps of 1 (a histogram of all 256 values, else of the occupied range), as
    :func:`stcvision.stages.estimate_background` chooses."""
    for i in range(len(idx)):
        j = idx[i]
        out_g[i] = ped if hot_g[i] else max(min(np.int64(flat[j]) + ped, top) - np.int64(dark_g[i]), 0)
        out_r[i] = ped if hot_r[i] else max(min(np.int64(flat[j + 1]) + ped, top) - np.int64(dark_r[i]), 0)
    out = np.empty((2, 3))
    out[0] = _quartiles_of(out_g, quantum, whole_u8)
    out[1] = _quartiles_of(out_r, quantum, whole_u8)
    return out


def window_sums(image, window_px: int, *, scratch: Scratch = new_arrays) -> np.ndarray:
    """Sum over the dot-sized square around every pixel, no rounding: uint16 for a uint8 image,
    float32 for a uint16 one (exact: 9 x 65535 < 2^24). ``image``: an image, or a pair (green,
    red) of 2-D images, whose sums come as one (h, w, 2) image, green first; 3 x 3 windows of a
    pair of 8-bit images by a compiled pass (:func:`box3_pair`, bit for bit OpenCV's box filter
    and faster), into ``scratch`` (the next call lending the same scratch overwrites them).

    Seed 003, "Finding the green dots": "we look for the square of pixels (of a dot's size)
    that has the highest average value". Filtering once, in the mirror image where the pixels
    are, and unwarping the sums keeps every photon of a dot and the noise of exactly
    ``window_px**2`` pixels, wherever the dot lies (the unwarp would otherwise skip pixels near
    the robot, where the ground view is coarser than the mirror image).
    """
    if isinstance(image, tuple):
        if len(image) != 2:
            raise BadInputError(f"window_sums takes an image or a (green, red) pair, got a {len(image)}-tuple")
        g, r = image
        for c, name in ((g, "green"), (r, "red")):
            check_image(c, f"{name} image", (np.uint8, np.uint16), ndims=(2,))
        if g.shape != r.shape or g.dtype != r.dtype:
            raise BadInputError(f"green and red images differ: {g.shape} {g.dtype} and {r.shape} {r.dtype}")
        if window_px == 3 and g.dtype == np.uint8 and g.flags.c_contiguous and r.flags.c_contiguous:
            sums = scratch("sums", (*g.shape, 2), np.uint16)
            h, w = g.shape
            box3_pair(g.reshape(-1), r.reshape(-1), h, w, sums.reshape(-1), scratch("rows", (6 * w,), np.uint16))
            return sums
        image = cv2.merge([g, r])
    check_image(image, "image", (np.uint8, np.uint16))
    if isinstance(window_px, bool) or not isinstance(window_px, int | np.integer) or window_px < 1:
        raise BadInputError(f"window_px must be a positive integer, got {window_px!r}")
    depth = cv2.CV_16U if image.dtype == np.uint8 else cv2.CV_32F
    return cv2.boxFilter(image, depth, (window_px, window_px), normalize=False, borderType=cv2.BORDER_CONSTANT)


@numba.njit(inline="always")
def _row3(src, o, w, hs, oh):
    """``hs[oh + x]``: the sum of ``src[o + x]`` and its neighbours in the row of ``w``."""
    if w == 1:
        hs[oh] = np.uint16(src[o])
        return
    hs[oh] = np.uint16(src[o]) + np.uint16(src[o + _U(1)])
    for x in range(_U(1), _U(w - 1)):
        hs[oh + x] = np.uint16(src[o + x - _U(1)]) + np.uint16(src[o + x]) + np.uint16(src[o + x + _U(1)])
    hs[oh + _U(w - 1)] = np.uint16(src[o + _U(w - 2)]) + np.uint16(src[o + _U(w - 1)])


@numba.njit(cache=True)
def box3_pair(g, r, h, w, sums, scratch):
    """3 x 3 window sums of the (h, w) uint8 images ``g`` and ``r`` (flat) into the (h, w, 2)
    uint16 image ``sums`` (flat, green first; exact), zeros beyond their edges:
    ``cv2.boxFilter(img, CV_16U, (3, 3), normalize=False, borderType=BORDER_CONSTANT)`` of
    each, bit for bit (integers), row by row: each row's sums along it into a ring of three
    rows (``scratch``: 6 w uint16), then the sums of three of those, interleaved, in loops
    LLVM vectorises."""
    uw = _U(w)
    for y in range(h + 1):
        if y < h:
            slot = _U(2 * (y % 3)) * uw
            _row3(g, _U(y) * uw, w, scratch, slot)
            _row3(r, _U(y) * uw, w, scratch, slot + uw)
        if y == 0:
            continue
        yy = y - 1  # the output row: rows yy - 1, yy, yy + 1 (those inside)
        o = _U(2 * yy) * uw
        mid = _U(2 * (yy % 3)) * uw
        up = _U(2 * ((yy + 2) % 3)) * uw
        dn = _U(2 * ((yy + 1) % 3)) * uw
        if yy >= 1 and yy + 1 < h:
            for x in range(uw):
                sums[o + _U(2) * x] = scratch[up + x] + scratch[mid + x] + scratch[dn + x]
                sums[o + _U(2) * x + _U(1)] = scratch[up + uw + x] + scratch[mid + uw + x] + scratch[dn + uw + x]
        elif yy >= 1:
            for x in range(uw):
                sums[o + _U(2) * x] = scratch[up + x] + scratch[mid + x]
                sums[o + _U(2) * x + _U(1)] = scratch[up + uw + x] + scratch[mid + uw + x]
        elif yy + 1 < h:
            for x in range(uw):
                sums[o + _U(2) * x] = scratch[mid + x] + scratch[dn + x]
                sums[o + _U(2) * x + _U(1)] = scratch[mid + uw + x] + scratch[dn + uw + x]
        else:
            for x in range(uw):
                sums[o + _U(2) * x] = scratch[mid + x]
                sums[o + _U(2) * x + _U(1)] = scratch[mid + uw + x]


@dataclass(frozen=True, eq=False)
class UnwarpMap:
    """Remap table from the ground view to the mirror image, built once from a profile.

    ``map_x``, ``map_y`` : (S, S) float32 maps; ``fixed1``, ``fixed2``: the same as
    OpenCV's fixed-point ``CV_16SC2`` maps, the faster choice for colour images (measured here:
    ~0.55 ms against ~0.85 ms for a 360x360 colour remap); ``valid`` : (S, S) bool, ground
    pixels the mirror sees.
    """

    map_x: np.ndarray
    map_y: np.ndarray
    valid: np.ndarray
    image_size_px: tuple[int, int]
    fixed1: np.ndarray | None = None
    fixed2: np.ndarray | None = None

    @classmethod
    def from_profile(cls, profile) -> UnwarpMap:
        """For every ground-view pixel: robot-frame floor point -> phi (azimuth, preserved) and
        theta (elevation, from the profile's radial polynomial) -> image pixel."""
        n = profile.ground_size_px
        gy, gx = np.mgrid[0:n, 0:n].astype(float)
        xy = profile.ground_to_robot(np.column_stack([gx.ravel(), gy.ravel()]))
        uv = profile.robot_to_image(xy)
        w, h = profile.image_size_px
        ok = np.isfinite(uv).all(1) & (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1)
        uv[~ok] = -10.0
        mx = uv[:, 0].reshape(n, n).astype(np.float32)
        my = uv[:, 1].reshape(n, n).astype(np.float32)
        f1, f2 = cv2.convertMaps(mx, my, cv2.CV_16SC2)
        return cls(mx, my, ok.reshape(n, n), tuple(profile.image_size_px), f1, f2)

    def reach_px(self, margin: int = 2) -> tuple[int, int, int, int]:
        """(x0, y0, x1, y1): the part of the mirror image the map reads, with ``margin`` pixels
        more on every side (a window sum there sees only pixels inside), clipped to the image."""
        w, h = self.image_size_px
        mx, my = self.map_x[self.valid], self.map_y[self.valid]
        if not len(mx):
            return 0, 0, w, h
        x0, y0 = max(int(np.floor(mx.min())) - margin, 0), max(int(np.floor(my.min())) - margin, 0)
        x1, y1 = min(int(np.floor(mx.max())) + 2 + margin, w), min(int(np.floor(my.max())) + 2 + margin, h)
        return x0, y0, x1, y1

    def cropped(self, x0: int, y0: int, x1: int, y1: int) -> UnwarpMap:
        """The same map reading the crop ``image[y0:y1, x0:x1]`` (shifting a map by whole pixels
        is exact in float32)."""
        mx, my = self.map_x - np.float32(x0), self.map_y - np.float32(y0)
        f1, f2 = cv2.convertMaps(mx, my, cv2.CV_16SC2)
        return UnwarpMap(mx, my, self.valid, (x1 - x0, y1 - y0), f1, f2)


class GatherTables(NamedTuple):
    """An :class:`UnwarpMap` as gather tables for :func:`unwarp_separate_u16`,
    which unwarps the green and red window sums in one pass, bit for bit as ``cv2.remap`` with
    the float maps does. Per ground pixel (flat, in order): ``base``, the source pixel (flat
    index) at the top left of the four it reads; ``alpha``, ``beta``, the map's fractional parts;
    ``border``: the ground pixels some of whose four source pixels lie outside the image (read
    as zeros), with their map coordinates ``border_xy``."""

    base: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    border: np.ndarray
    border_xy: np.ndarray

    @classmethod
    def from_map(cls, umap: UnwarpMap) -> GatherTables:
        w, h = umap.image_size_px
        mx, my = umap.map_x.reshape(-1), umap.map_y.reshape(-1)
        fx, fy = np.floor(mx), np.floor(my)
        inside = (fx >= 0) & (fy >= 0) & (fx + 1 < w) & (fy + 1 < h)
        ix, iy = np.where(inside, fx, 0).astype(np.int64), np.where(inside, fy, 0).astype(np.int64)
        out = np.flatnonzero(~inside)
        return cls(
            (iy * w + ix).astype(np.int32 if w * h < 2**31 else np.int64),
            np.where(inside, mx - fx, 0).astype(np.float32),
            np.where(inside, my - fy, 0).astype(np.float32),
            out.astype(np.int64),
            np.ascontiguousarray(np.column_stack([mx[out], my[out]]), np.float32),
        )


def unwarp(image: np.ndarray, umap: UnwarpMap) -> np.ndarray:
    """Ground view (top-down, robot-centred, forward up) of a mirror image: one ``cv2.remap``.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) uint8, the profile's image size.
    """
    check_image(image, "image", (np.uint8, np.uint16, np.float32))
    h, w = image.shape[:2]
    if (w, h) != umap.image_size_px:
        raise BadInputError(
            f"image is {w}x{h}; the unwarp map was built for {umap.image_size_px[0]}x{umap.image_size_px[1]}"
        )
    if image.ndim == 3 and umap.fixed1 is not None:
        m1, m2 = umap.fixed1, umap.fixed2
    else:
        m1, m2 = umap.map_x, umap.map_y
    return cv2.remap(image, m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)


@dataclass(frozen=True, kw_only=True, slots=True)
class ChannelParams:
    """Red/green separation (seed 003: "In the obstacle image, we keep all the pixels that the
    red color is bigger than a threshold. And in the visited cells, we keep the colors that the
    red colors is less than a threshold").

    A pixel is *red light* iff its red value (after dark subtraction) is ``red_k_sigma`` noise
    levels above the red background and at least its green value (less ``dominance_k_sigma``
    noise levels): a red LED leaks only a few per cent into green (so R >> G, and where both
    saturate R ~ G), while a green phosphor dot shows about a twelfth as much red as green --
    also when its green saturates in a long exposure, where a ratio test would mistake it for
    red. Background and noise are the caller's (the pipeline: the pedestal and the dark frame's
    spread), so the rule holds at any bit depth and gain; on the webcam (dark frame spread
    1.48 DN, 10 DN pedestal) the defaults are the levels the webcam was tuned at, 40 DN and a
    3 DN tolerance. ``red_threshold_dn`` and ``dominance_tol_dn`` (per pixel, DN) override the
    noise rule with fixed levels.

    Red-light pixels go to the obstacle image and are blacked out of the marks image, which
    removes the crosstalk; the black-out extends ``red_margin_px`` beyond them, over the light's
    faint halo (blooming and lens glare carry green too), and over every red-dominated pixel
    whose red is ``leak_k_sigma`` noise levels above the background (a light's faint halo grows
    with the exposure). Red lights stand at cell centres, marks at least 4 cm away.
    """

    red_k_sigma: float = 20.25
    dominance_k_sigma: float = 2.03
    red_threshold_dn: float | None = None
    dominance_tol_dn: float | None = None
    red_margin_px: int = 2
    leak_k_sigma: float = 5.0
    #: ... and only where its red above the background is at least this fraction of its green
    #: (a dot's red is ~8 % of its green, a red LED's green ~6 % of its red, both ~1 where both
    #: saturate): on long webcam frames the tolerance (2 x the dark frame's spread, ~37 DN at
    #: 30 s) took dots 20-40 DN above the background for red and blacked them out (measured)
    red_min_fraction: float = 0.5

    def levels(self, background_dn: float, noise_dn: float) -> tuple[float, float]:
        """(red threshold, dominance tolerance) per pixel in DN, for a red channel of this
        background and noise."""
        thr = background_dn + self.red_k_sigma * noise_dn if self.red_threshold_dn is None else self.red_threshold_dn
        tol = self.dominance_k_sigma * noise_dn if self.dominance_tol_dn is None else self.dominance_tol_dn
        return float(thr), float(tol)


def filter_channels(
    image: np.ndarray,
    params: ChannelParams = ChannelParams(),
    *,
    window_area: int = 1,
    leak_threshold: float | None = None,
    background_dn: float | None = None,
    noise_dn: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Split a dark-subtracted BGR image into (obstacle, marks) single-channel images.

    ``image`` is uint8, or window sums (see :func:`window_sums`) with ``window_area`` pixels per
    sum; the thresholds are per pixel and scale with it. The outputs keep the input dtype.
    ``background_dn``, ``noise_dn``: the red channel's per-pixel background and noise (default:
    measured on a uint8 ``image``). ``leak_threshold`` (same units as ``image``; default: none)
    is the lower red level above which a red-dominated pixel is still kept out of the marks
    image: a bright light's faint halo (lens glare, blooming) carries green by crosstalk far
    beyond the pixels bright enough to count as the light itself.
    """
    check_image(image, "image", (np.uint8, *SUM_DTYPES), ndims=(3,))
    if image.shape[2] != 3:
        raise BadInputError(f"image must be (H, W, 3) uint8 or window sums, got {image.shape} {image.dtype}")
    r = cv2.extractChannel(image, 2)
    if background_dn is None or noise_dn is None:
        if image.dtype != np.uint8:
            raise BadInputError("filter_channels: give background_dn and noise_dn with window sums")
        background_dn, noise_dn = estimate_background(r)
    return separate_channels(
        cv2.extractChannel(image, 1),
        r,
        params,
        window_area=window_area,
        leak_threshold=leak_threshold,
        background_dn=background_dn,
        noise_dn=noise_dn,
    )


def separate_channels(
    g: np.ndarray,
    r: np.ndarray,
    params: ChannelParams = ChannelParams(),
    *,
    window_area: int = 1,
    leak_threshold: float | None = None,
    background_dn: float,
    noise_dn: float,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`filter_channels` on a green and a red image already split apart: the rule the
    pipeline runs (:func:`separation_rule`, the compiled loops of :func:`unwarp_separate` over the
    identity map, :func:`black_out`), so what it shows is what the pipeline computes.

    Red-dominated where ``r + tol >= g`` (saturating as the images' dtype does) and, with
    ``params.red_min_fraction``, ``r - bg >= f (g - bg)``; a red light where also ``r > thr``:
    ``obstacle`` keeps its red, ``marks`` the green with the lights (and, with
    ``leak_threshold``, the red-dominated pixels above it) blacked out, grown by
    ``params.red_margin_px``.
    """
    check_image(g, "g", (np.uint8, *SUM_DTYPES), ndims=(2,))
    check_image(r, "r", (np.uint8, *SUM_DTYPES), ndims=(2,))
    if g.shape != r.shape or g.dtype != r.dtype:
        raise BadInputError(f"g and r must match, got {g.shape} {g.dtype} and {r.shape} {r.dtype}")
    dtype = g.dtype
    # uint8 runs as uint16: its values are exact there, and the dominance test's saturation at
    # 255 or 65535 decides alike (both sides of the comparison are at most 255)
    work = np.uint16 if dtype == np.uint8 else dtype
    sums = np.stack([g, r], axis=-1).astype(work, copy=False)
    h, w = g.shape
    leak = float(leak_threshold) if leak_threshold is not None else _NO_LEAK
    rule = separation_rule(params, window_area, (background_dn, noise_dn), leak, work)
    scratch = Scratch()
    obstacle, marks, black, n = unwarp_separate(_identity_tables(w, h), sums, (h, w), rule, scratch)
    black_out(marks, black, n, _margin(params.red_margin_px), scratch)
    return obstacle.astype(dtype, copy=False), marks.astype(dtype, copy=False)


#: the leak level that blacks out nothing beyond the lights (above any sum)
_NO_LEAK = 2.0**40


@functools.lru_cache(maxsize=4)
def _identity_tables(w: int, h: int) -> GatherTables:
    """The gather tables of the map that reads every pixel where it stands (kept per image size:
    building them is 8 of a 640x480 call's 10 ms; the compiled loops only read them)."""
    my, mx = np.mgrid[0:h, 0:w].astype(np.float32)
    return GatherTables.from_map(UnwarpMap(mx, my, np.ones((h, w), bool), (w, h)))


def _margin(red_margin_px: int) -> np.ndarray | None:
    """The structuring element the black-out grows by (None: not grown)."""
    if red_margin_px <= 0:
        return None
    k = 2 * red_margin_px + 1
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))


@numba.njit(inline="always")
def _red_test(gv, rv, use_frac, thr, tol, bottom, top, frac, gamma, leak):
    """The red/green separation of one ground pixel (:func:`unwarp_separate_u16`): (a red
    light, to black out). Pure: the loops store the results themselves (an inlined helper
    that stored into the output arrays ran the uint16 loop 3x slower, 0.69 vs 0.24 ms)."""
    dom = min(max(rv + tol, bottom), top) >= gv
    if use_frac:
        dom = dom & (_fma32(rv, np.float32(1.0), _fma32(gv, frac, gamma)) >= np.float32(0.0))
    light = dom & (rv > thr)
    return light, light | (dom & (rv > leak))


@numba.njit(cache=True)
def unwarp_border(src, w, h, border, border_xy, rnd, rule, obstacle, marks, black):
    """The ground pixels ``border`` some of whose four source pixels lie outside the image
    (zeros there, as ``BORDER_CONSTANT``), from their map coordinates ``border_xy``: the
    change they make to the black-out count."""
    thr, tol, bottom, top, frac, gamma, leak = rule
    dn = 0
    use_frac = frac != np.float32(0.0)
    p = np.zeros(8, np.float32)
    for i in range(len(border)):
        mx = border_xy[i, 0]
        my = border_xy[i, 1]
        x = int(math.floor(mx))
        y = int(math.floor(my))
        for k in range(4):
            xx = x + (k & 1)
            yy = y + (k >> 1)
            inside = 0 <= xx < w and 0 <= yy < h
            p[k] = _f32(src[2 * (yy * w + xx)]) if inside else np.float32(0.0)
            p[4 + k] = _f32(src[2 * (yy * w + xx) + 1]) if inside else np.float32(0.0)
        aa = mx - np.float32(x)
        bb = my - np.float32(y)
        j = border[i]
        old = black[j]
        gv = _lerp(aa, bb, p[0], p[1], p[2], p[3])
        rv = _lerp(aa, bb, p[4], p[5], p[6], p[7])
        if rnd:
            gv = min(max(np.rint(gv), np.float32(0.0)), np.float32(65535.0))
            rv = min(max(np.rint(rv), np.float32(0.0)), np.float32(65535.0))
        light, b = _red_test(gv, rv, use_frac, thr, tol, bottom, top, frac, gamma, leak)
        obstacle[j] = rv if light else np.float32(0.0)
        marks[j] = gv
        black[j] = b
        dn += b - old
    return dn


@numba.njit(cache=True)
def unwarp_separate_u16(src32, w, base, alpha, beta, rule, obstacle, marks, black, scratch):
    """The unwarp of the green and red window sums and their red/green separation, in one pass
    over the ground view: ``cv2.remap`` (float maps, ``INTER_LINEAR``, ``BORDER_CONSTANT`` 0) of
    each channel as it computes on this machine (:func:`_lerp`; rounded half to even and
    saturated for uint16 sums), then the rule and the arithmetic of
    :func:`stcvision.stages.separate_channels` in float32 as OpenCV has it: red-dominated where
    ``r + tol >= g`` (the add saturating at ``bottom`` and ``top``) and, with ``frac`` (the
    negated ``red_min_fraction``; 0: off), ``fma(r, 1, fma(g, frac, gamma)) >= 0``
    (``cv2.addWeighted``); a light pixel where also ``r > thr`` (``obstacle`` keeps its red,
    else 0); ``marks`` is the green; ``black`` (uint8) 1 where the marks are to be blacked out
    before the margin grows it: the light pixels and the red-dominated ones with ``r > leak``.
    Returns the number of those. (The thresholds are the caller's, as OpenCV compares: whole
    numbers below them for integer sums.)

    :func:`unwarp_separate_u16` takes uint16 sums on a little-endian machine as uint32
    ``src32`` (the (h, w, 2) green/red sums, flat: one unaligned 8-byte load gathers both
    channels of a source pixel and its right neighbour, green in the low half; ``scratch``
    (2, N) uint64); :func:`unwarp_separate_f32`
    any sums ``src`` (flat; ``rnd``: integers, to round and saturate; ``scratch`` (8, N)
    float32); the caller then redoes the border pixels with :func:`unwarp_border`. The loops store
    the outputs themselves around the pure :func:`_red_test` (this one has it written out). Ground
    pixel ``i`` reads the four source pixels from pixel ``base[i]`` with weights ``alpha[i]``,
    ``beta[i]``; the ``border`` pixels are redone from their map coordinates ``border_xy``
    (:func:`unwarp_border`). Block by block: the gathers into ``scratch``, then the arithmetic
    over contiguous arrays, which LLVM vectorises (measured here: the two remaps and the
    separation 348 us; this 221 us with a 4-byte load per source pixel, 166 us with these)."""
    thr, tol, bottom, top, frac, gamma, leak = rule
    zero = np.float32(0.0)
    hi = np.float32(65535.0)
    use_frac = frac != zero
    n = 0
    nb = scratch.shape[1]
    row = _U(w)
    lo = np.uint64(0xFFFF)
    s0, s1 = scratch[0], scratch[1]
    N = len(base)
    for start in range(0, N, nb):
        m = _U(min(nb, N - start))
        st = _U(start)
        for i in range(m):  # a source pixel and its right neighbour, both channels: one load
            o = _U(base[st + i])
            s0[i] = _load_u64(src32, o)
            s1[i] = _load_u64(src32, o + row)
        for i in range(m):
            j = st + i
            aa = alpha[j]
            bb = beta[j]
            q0, q1 = s0[i], s1[i]  # (green, red) of the left pixel in the low half, the right's above
            p00, p01 = _f32(q0 & lo), _f32((q0 >> np.uint64(32)) & lo)
            p10, p11 = _f32(q1 & lo), _f32((q1 >> np.uint64(32)) & lo)
            v0 = _fma32(aa, p01 - p00, p00)
            gv = min(max(np.rint(_fma32(bb, _fma32(aa, p11 - p10, p10) - v0, v0)), zero), hi)
            p00, p01 = _f32((q0 >> np.uint64(16)) & lo), _f32(q0 >> np.uint64(48))
            p10, p11 = _f32((q1 >> np.uint64(16)) & lo), _f32(q1 >> np.uint64(48))
            v0 = _fma32(aa, p01 - p00, p00)
            rv = min(max(np.rint(_fma32(bb, _fma32(aa, p11 - p10, p10) - v0, v0)), zero), hi)
            # the separation as _red_test has it, written out: this is the bench's loop, and
            # through the inlined helper it measured no faster and at times slower here
            dom = min(max(rv + tol, bottom), top) >= gv
            if use_frac:
                dom = dom & (_fma32(rv, np.float32(1.0), _fma32(gv, frac, gamma)) >= zero)
            light = dom & (rv > thr)
            obstacle[j] = rv if light else zero
            marks[j] = gv
            b = light | (dom & (rv > leak))
            black[j] = b
            n += b
    return n


@numba.njit(cache=True)
def unwarp_separate_f32(
    src64,
    green_low,
    w,
    base,
    alpha,
    beta,
    rnd,
    rule,
    obstacle,
    marks,
    black,
    scratch,
):
    """:func:`unwarp_separate_u16` for float32 sums (16-bit frames; and uint16 sums on a
    big-endian machine, converted: ``rnd`` rounds and saturates): ``src64``, the (h, w, 2)
    sums as one uint64 per pixel (both channels: green in the low half where ``green_low``),
    four aligned loads per ground pixel; ``scratch`` (4, N) uint64. The separation written
    out, as there."""
    thr, tol, bottom, top, frac, gamma, leak = rule
    zero = np.float32(0.0)
    hi = np.float32(65535.0)
    use_frac = frac != zero
    n = 0
    nb = scratch.shape[1]
    row = _U(w)
    lo = np.uint64(0xFFFFFFFF)
    gs = np.uint64(0) if green_low else np.uint64(32)
    rs = np.uint64(32) if green_low else np.uint64(0)
    s0, s1, s2, s3 = scratch[0], scratch[1], scratch[2], scratch[3]
    N = len(base)
    for start in range(0, N, nb):
        m = _U(min(nb, N - start))
        st = _U(start)
        for i in range(m):
            o = _U(base[st + i])
            s0[i] = src64[o]
            s1[i] = src64[o + _U(1)]
            s2[i] = src64[o + row]
            s3[i] = src64[o + row + _U(1)]
        for i in range(m):
            j = st + i
            aa = alpha[j]
            bb = beta[j]
            q0, q1, q2, q3 = s0[i], s1[i], s2[i], s3[i]
            p00, p01 = _as_f32(np.uint32((q0 >> gs) & lo)), _as_f32(np.uint32((q1 >> gs) & lo))
            p10, p11 = _as_f32(np.uint32((q2 >> gs) & lo)), _as_f32(np.uint32((q3 >> gs) & lo))
            v0 = _fma32(aa, p01 - p00, p00)
            gv = _fma32(bb, _fma32(aa, p11 - p10, p10) - v0, v0)
            p00, p01 = _as_f32(np.uint32((q0 >> rs) & lo)), _as_f32(np.uint32((q1 >> rs) & lo))
            p10, p11 = _as_f32(np.uint32((q2 >> rs) & lo)), _as_f32(np.uint32((q3 >> rs) & lo))
            v0 = _fma32(aa, p01 - p00, p00)
            rv = _fma32(bb, _fma32(aa, p11 - p10, p10) - v0, v0)
            if rnd:
                gv = min(max(np.rint(gv), zero), hi)
                rv = min(max(np.rint(rv), zero), hi)
            light, b = _red_test(gv, rv, use_frac, thr, tol, bottom, top, frac, gamma, leak)
            obstacle[j] = rv if light else zero
            marks[j] = gv
            black[j] = b
            n += b
    return n


@numba.njit(cache=True)
def zero_where(img, mask):
    """``img[mask != 0] = 0`` (flat arrays)."""
    for i in range(_U(len(img))):
        if mask[i]:
            img[i] = 0


# --------------------------------------------------------------------------- the front end as it runs
#: the byte order the unwarp's gathers read pairs of channels in (green first in memory)
_LITTLE = sys.byteorder == "little"
#: uint16 window sums gathered as uint32 pairs (little-endian machines); else converted to
#: float32 and gathered as those are (tests switch it off to check that path)
_U32_GATHERS = True


def _no_hot() -> np.ndarray:
    return np.zeros(0, np.int64)


@dataclass(frozen=True, eq=False)
class DarkFrame:
    """What the front end takes from a dark frame, once (the default: none, whose background
    sample is then read as it is, without pedestal).

    ``frame``: the (H, W, 3) dark frame; ``pedestal``, ``quantum``, ``sigma``: the pedestal kept
    by the subtraction, the quantisation step and the dark frame's robust spread (DN);
    ``green``, ``red``: its channels in the crop the view reads; ``hot_green``, ``hot_red``:
    its hot pixels (flat indices into the crop); ``sample``: its green and red at the
    background sample's pixels; ``hot_sample``: which of those are hot.
    """

    frame: np.ndarray | None = None
    pedestal: int = 0
    quantum: int = 1
    sigma: float = 0.0
    green: np.ndarray | None = None
    red: np.ndarray | None = None
    hot_green: np.ndarray = field(default_factory=_no_hot)
    hot_red: np.ndarray = field(default_factory=_no_hot)
    sample: tuple[np.ndarray, np.ndarray] | None = None
    hot_sample: tuple[np.ndarray, np.ndarray] | None = None

    @classmethod
    def measure(cls, dark: np.ndarray, crop, sample3: dict, *, pedestal_steps: int, pedestal_k_sigma: float):
        """Split ``dark`` once, map its hot pixels once, and take from it the quantisation step
        and the pedestal: ``pedestal_k_sigma`` times its robust spread (the residual after
        subtraction is no wider), at least ``pedestal_steps`` steps, in whole steps."""
        check_frame(dark, "dark frame")
        sample = sample3[1] // 3
        gr = np.concatenate([cv2.extractChannel(dark, c).reshape(-1)[sample] for c in (1, 2)])
        q = quantum_dn(gr)
        _, spread = robust_sigma(gr)
        pedestal = int(max(pedestal_steps, math.ceil(pedestal_k_sigma * spread / q - 1e-9)) * q)
        x0, y0, x1, y1 = crop
        part = dark[y0:y1, x0:x1]
        hot = hot_pixels(dark, quantum=q)
        w = dark.shape[1]
        hot_in = []
        for ch in (1, 2):
            px = hot[hot % 3 == ch] // 3  # flat indices into one full channel
            yy, xx = px // w, px % w
            keep = (xx >= x0) & (xx < x1) & (yy >= y0) & (yy < y1)
            hot_in.append((yy[keep] - y0) * (x1 - x0) + (xx[keep] - x0))  # into the crop
        return cls(
            dark,
            pedestal,
            q,
            spread,
            cv2.extractChannel(part, 1),
            cv2.extractChannel(part, 2),
            hot_in[0],
            hot_in[1],
            tuple(np.ascontiguousarray(dark.reshape(-1)[sample3[ch]]) for ch in (1, 2)),
            tuple(np.isin(sample3[ch], hot) for ch in (1, 2)),
        )


def dark_channels(frame: np.ndarray, crop, dark: DarkFrame, scratch: Scratch = new_arrays):
    """Green and red of the crop ``(x0, y0, x1, y1)`` of ``frame``, dark-subtracted as
    :func:`subtract_dark` subtracts (the pedestal added, the dark frame subtracted, both
    saturating) and the hot pixels set to the pedestal: two new (h, w) images. One
    ``cv2.split`` of the crop's rows (a contiguous block: OpenCV's vectorised path, ~2x faster
    here than extracting or mixing channels out of the crop), into ``scratch``'s planes: writing
    fresh memory each frame made the split 3x slower alone here (64 against 20 us)."""
    x0, y0, x1, y1 = crop
    rows = frame[y0:y1]
    planes = cv2.split(rows, [scratch(f"plane {c}", rows.shape[:2], rows.dtype) for c in range(3)])
    g, r = planes[1][:, x0:x1], planes[2][:, x0:x1]
    if dark.frame is None:
        return g.copy(), r.copy()  # new images: the planes are scratch
    ped = dark.pedestal
    g = _dark_subtracted(g, dark.green, ped)
    r = _dark_subtracted(r, dark.red, ped)
    g.reshape(-1)[dark.hot_green] = ped  # defect-pixel map
    r.reshape(-1)[dark.hot_red] = ped
    return g, r


def frame_background(frame: np.ndarray, sample3: dict, dark: DarkFrame, scratch: Scratch = new_arrays):
    """(green background, green noise, red background, red noise, quantisation step) of
    ``frame``: :func:`estimate_background` of its raw pixels at ``sample3`` (flat indices into
    the BGR frame per channel), dark-subtracted as :func:`dark_channels` does it, in one
    compiled pass over both channels (:func:`sample_quartiles`); the noise never below the
    rounding noise of one step."""
    flat = frame.reshape(-1)
    n = len(sample3[1])
    vals = scratch("sample g", (n,), frame.dtype), scratch("sample r", (n,), frame.dtype)
    if dark.frame is None:
        zeros = scratch("no dark", (n,), frame.dtype)
        zeros[:] = 0
        dk, hot = (zeros, zeros), (np.zeros(n, bool),) * 2
        q = quantum_dn(flat[sample3[1]])
    else:
        dk, hot, q = dark.sample, dark.hot_sample, dark.quantum
    top, whole = np.iinfo(frame.dtype).max, frame.dtype == np.uint8 and q == 1
    quart = sample_quartiles(flat, sample3[1], *dk, *hot, dark.pedestal, top, q, whole, *vals)
    (gq1, g_med, gq3), (rq1, r_med, rq3) = quart
    floor = noise_floor(q)
    g_noise, r_noise = max(float((gq3 - gq1) / 1.349), floor), max(float((rq3 - rq1) / 1.349), floor)
    return float(g_med), g_noise, float(r_med), r_noise, q


def separation_rule(channels: ChannelParams, window_area: int, red_levels, leak: float, dtype) -> tuple:
    """The red/green separation of :func:`separate_channels` for window sums of ``dtype`` as the
    compiled unwarp takes it: (light threshold, dominance tolerance, the saturation's bottom and
    top, the red fraction's weight and offset, leak level), float32 as OpenCV rounds them:
    ``red_levels`` the red channel's per-pixel background and noise, ``leak`` (in sums) the
    level above which a red-dominated pixel is blacked out too."""
    thr, tol = channels.levels(*red_levels)
    thr_a, tol_a = float(thr * window_area), float(tol * window_area)
    # the red-fraction test as cv2.addWeighted(r, 1, g, -f, -(1 - f) bg) >= 0 takes it
    frac = np.float32(-channels.red_min_fraction if channels.red_min_fraction > 0 else 0.0)
    gamma = np.float32(-(1.0 - channels.red_min_fraction) * (red_levels[0] * window_area))
    if dtype == np.uint16:  # OpenCV: the added scalar rounded, comparisons exact
        tol32, bottom, top = np.float32(np.rint(tol_a)), np.float32(0), np.float32(65535)
        # v > t for whole v <= 65535 is v > floor(t), exact in float32 once clipped
        thr32, leak32 = (np.float32(min(max(math.floor(x), -1), 65536)) for x in (thr_a, leak))
    else:  # float images: the scalars rounded to float32, no saturation
        tol32, thr32, leak32 = np.float32(tol_a), np.float32(thr_a), np.float32(leak)
        bottom, top = np.float32(-np.inf), np.float32(np.inf)
    return thr32, tol32, bottom, top, frac, gamma, leak32


def unwarp_separate(tables: GatherTables, sums: np.ndarray, shape, rule: tuple, scratch: Scratch = new_arrays):
    """(obstacle, marks, black, n): the ground views (``shape``) of the (h, w, 2) green/red
    window sums ``sums`` through ``tables`` and their red/green separation by ``rule``
    (:func:`separation_rule`), the arithmetic of ``cv2.remap`` then :func:`separate_channels`,
    in one compiled pass: uint16 sums on a little-endian machine by :func:`unwarp_separate_u16`,
    others by :func:`unwarp_separate_f32`, the border pixels by :func:`unwarp_border`.
    ``obstacle`` and ``marks`` are new; ``black`` (scratch, uint8) is 1 at the ``n`` ground
    pixels of the marks to black out (:func:`black_out`)."""
    src32 = sums.reshape(-1).view(np.uint32) if (sums.dtype == np.uint16 and _LITTLE and _U32_GATHERS) else None
    h, w = sums.shape[:2]
    gather = scratch("gather", (2, 256) if src32 is not None else (4, 256), np.uint64)
    obstacle = np.empty(shape, sums.dtype)
    marks = np.empty(shape, sums.dtype)
    black = scratch("black", shape, np.uint8)
    out = obstacle.reshape(-1), marks.reshape(-1), black.reshape(-1)
    base, alpha, beta, border, border_xy = tables
    src, rnd = sums.reshape(-1), sums.dtype == np.uint16
    if src32 is not None:  # both channels in one uint32 load, green in the low half
        n = unwarp_separate_u16(src32, w, base, alpha, beta, rule, *out, gather)
    else:  # float32 pairs, one uint64 per pixel (uint16 sums converted: exact)
        src64 = np.ascontiguousarray(sums, np.float32).reshape(-1).view(np.uint64)
        n = unwarp_separate_f32(src64, _LITTLE, w, base, alpha, beta, rnd, rule, *out, gather)
    if len(border):
        n += unwarp_border(src, w, h, border, border_xy, rnd, rule, *out)
    return obstacle, marks, black, n


def black_out(marks: np.ndarray, black: np.ndarray, n: int, margin: np.ndarray | None, scratch: Scratch = new_arrays):
    """Zero in ``marks`` the ``n`` pixels :func:`unwarp_separate` marked in ``black``, grown by
    the structuring element ``margin`` (the red lights' halo; None: not grown), in place."""
    if not n:
        return
    if margin is not None:
        black = cv2.dilate(black, margin, dst=scratch("grown", marks.shape, np.uint8))
    zero_where(marks.reshape(-1), black.reshape(-1))


class FrontOutput(NamedTuple):
    """What the front end (:meth:`FrontEnd.run`) gives the later stages: the dark-subtracted
    green and red of the crop, their window sums (scratch), the ground views ``obstacle`` and
    ``marks``, the frame's green background and noise, the quantisation step, the red lights'
    levels and the leak level (:func:`separation_rule`)."""

    green: np.ndarray
    red: np.ndarray
    sums: np.ndarray
    obstacle: np.ndarray
    marks: np.ndarray
    bg: float
    noise: float
    quantum: int
    red_levels: tuple[float, float]
    leak: float


@dataclass(frozen=True, eq=False)
class FrontEnd:
    """The pipeline's front end, built once from the profile (:meth:`from_profile`) and the
    dark frame (:meth:`with_dark`): the unwarp map and its gather tables for the crop of the
    mirror image the ground view reads (the whole frame when a wide view is made too), the
    background sample, the black-out margin, and the dark frame's channels and hot pixels."""

    umap: UnwarpMap
    crop: tuple[int, int, int, int]
    umap_crop: UnwarpMap
    tables: GatherTables
    #: raw pixels inside the mirror rim, sparsely, as flat indices into a BGR frame per channel
    sample3: dict
    channels: ChannelParams
    window_px: int
    margin: np.ndarray | None
    pedestal_steps: int
    pedestal_k_sigma: float
    #: the wide, coarse ground view for far red-light landmarks (None: not made)
    wide: UnwarpMap | None = None
    wide_profile: object = None
    wide_tables: GatherTables | None = None
    dark: DarkFrame = field(default_factory=DarkFrame)

    @classmethod
    def from_profile(
        cls,
        profile,
        *,
        channels: ChannelParams,
        window_px: int,
        pedestal_steps: int,
        pedestal_k_sigma: float,
        wide_reach_m: float | None = None,
        wide_size_px: int = 160,
    ) -> FrontEnd:
        """``wide_reach_m``: also a wide view of ``wide_size_px`` pixels reaching this far."""
        umap = UnwarpMap.from_profile(profile)
        w, h = profile.image_size_px
        vv, uu = np.mgrid[0:h:5, 0:w:5]
        inside = np.hypot(uu - profile.center_px[0], vv - profile.center_px[1]) < 0.95 * profile.rim_radius_px
        sample = (vv[inside] * w + uu[inside]).ravel()
        wide = wide_profile = wide_tables = None
        if wide_reach_m is not None:
            n = wide_size_px
            wide_profile = profile.replace(ground_size_px=n, ground_px_per_m=(n - 1) / (2 * wide_reach_m))
            wide = UnwarpMap.from_profile(wide_profile)
            wide_tables = GatherTables.from_map(wide)
        # the mirror-image stages run on the part of the mirror image the main view reads (about
        # half the frame); the wide view reads nearly the whole mirror
        crop = (0, 0, w, h) if wide is not None else umap.reach_px()
        umap_crop = umap.cropped(*crop)
        margin = _margin(channels.red_margin_px)
        return cls(
            umap,
            crop,
            umap_crop,
            GatherTables.from_map(umap_crop),
            {ch: sample * 3 + ch for ch in (1, 2)},
            channels,
            window_px,
            margin,
            pedestal_steps,
            pedestal_k_sigma,
            wide,
            wide_profile,
            wide_tables,
        )

    def with_dark(self, dark: np.ndarray | None) -> FrontEnd:
        """This front end subtracting ``dark`` (None: no dark frame)."""
        if dark is None:
            return replace(self, dark=DarkFrame())
        d = DarkFrame.measure(
            dark, self.crop, self.sample3, pedestal_steps=self.pedestal_steps, pedestal_k_sigma=self.pedestal_k_sigma
        )
        return replace(self, dark=d)

    def red_levels(self, bg_r: float, noise_r: float, quantum: int) -> tuple[float, float]:
        """A red light's level: above the pedestal by the dark frame's spread (a fixed rule per
        dark frame), or without one above the frame's own red background by its noise."""
        d = self.dark
        return (d.pedestal, max(d.sigma, noise_floor(quantum))) if d.frame is not None else (bg_r, noise_r)

    def run(self, frame: np.ndarray, scratch: Scratch, clock, t: list) -> FrontOutput:
        """The front end on one frame (dark, window, unwarp, channels; each one's end time from
        ``clock`` appended to ``t``), its scratch arrays from ``scratch``."""
        w = self.window_px
        g, r = dark_channels(frame, self.crop, self.dark, scratch)  # only green and red carry marks and lights
        bg, noise, bg_r, noise_r, q = frame_background(frame, self.sample3, self.dark, scratch)
        t.append(clock())
        sums = window_sums((g, r), w, scratch=scratch)
        t.append(clock())
        red_levels = self.red_levels(bg_r, noise_r, q)
        leak = w * w * bg_r + self.channels.leak_k_sigma * noise_r * w
        rule = separation_rule(self.channels, w * w, red_levels, leak, sums.dtype)
        obstacle, marks, black, n = unwarp_separate(self.tables, sums, self.umap_crop.map_x.shape, rule, scratch)
        t.append(clock())
        black_out(marks, black, n, self.margin, scratch)
        t.append(clock())
        return FrontOutput(g, r, sums, obstacle, marks, bg, noise, q, red_levels, leak)

    def wide_obstacle(self, f: FrontOutput, scratch: Scratch) -> np.ndarray:
        """The obstacle image of the wide view, from the window sums of the front end's output
        ``f`` (:meth:`run`)."""
        rule = separation_rule(self.channels, self.window_px**2, f.red_levels, f.leak, f.sums.dtype)
        return unwarp_separate(self.wide_tables, f.sums, self.wide.map_x.shape, rule, scratch)[0]
