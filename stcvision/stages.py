"""The pipeline's stages, each a pure function with frozen, documented parameters.

Seed 003 sections implemented here: "Noise handling" (dark frame), "Image Transformation and
Filtering" (unwarp, red/green images), "Finding the green dots", "Angle Detection" and
"Rotation and Calibration". Inputs are never modified; outputs are new arrays or small frozen
results. A missing detection is a value (``ok=False`` with a reason), not an exception.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import cv2
import numpy as np
from scipy.spatial import cKDTree

from stcvision import kernels
from stcvision.errors import BadInputError

__all__ = [
    "ChannelParams",
    "DotParams",
    "Dots",
    "RowParams",
    "HeadingFit",
    "HeadingParams",
    "RedLights",
    "RedParams",
    "Recalibration",
    "UnwarpMap",
    "GatherTables",
    "FRAME_DTYPES",
    "check_dark_dtype",
    "check_frame",
    "estimate_background",
    "noise_floor",
    "quantum_dn",
    "robust_sigma",
    "noise_gain",
    "separate_channels",
    "filter_channels",
    "find_dots",
    "find_red",
    "find_rows",
    "fit_heading",
    "hot_pixels",
    "mirror_centroids",
    "recalibrate_turn",
    "subtract_dark",
    "unwarp",
    "window_sums",
]


#: frame dtypes the pipeline reads: 8-bit, or 16-bit holding an ADC's counts (any depth up to 16
#: bits, LSB- or MSB-aligned: every threshold comes from the measured noise, not the depth)
FRAME_DTYPES = (np.uint8, np.uint16)
#: noise of rounding to whole quantisation steps, in steps (uniform error: 1 / sqrt(12))
QUANTISATION_SIGMA = 1.0 / math.sqrt(12.0)


def check_frame(frame: np.ndarray, name: str = "frame") -> None:
    """Contract: ``frame`` is an (H, W, 3) uint8 or uint16 BGR image."""
    if not isinstance(frame, np.ndarray):
        raise BadInputError(f"{name} must be a numpy array, got {type(frame).__name__}")
    if frame.dtype not in FRAME_DTYPES:
        raise BadInputError(f"{name} has dtype {frame.dtype}; expected uint8 or uint16")
    if frame.ndim != 3 or frame.shape[2] != 3:
        raise BadInputError(f"{name} has shape {frame.shape}; expected (H, W, 3) BGR")


def _check_image(image, name: str, dtypes=(np.uint8, np.uint16), ndims=(2, 3)) -> None:
    """Entry contract of the stages below (found by fuzzing: None, 0-d, empty or float arrays
    failed inside OpenCV or numpy): a non-empty numpy image of one of ``dtypes``."""
    if not isinstance(image, np.ndarray) or image.ndim not in ndims or image.size == 0 or image.dtype not in dtypes:
        got = f"{image.shape} {image.dtype}" if isinstance(image, np.ndarray) else type(image).__name__
        want = " or ".join(np.dtype(d).name for d in dtypes)
        raise BadInputError(f"{name} must be a non-empty {'-D or '.join(map(str, ndims))}-D {want} image, got {got}")


# --------------------------------------------------------------------------- dark frame
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
    if pedestal_dn:
        # (frame + pedestal) - dark, both saturating: only already-saturated pixels lose
        return cv2.subtract(cv2.add(frame, (pedestal_dn,) * 3), dark)
    return cv2.subtract(frame, dark)


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


# --------------------------------------------------------------------------- unwarp
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
    """An :class:`UnwarpMap` as gather tables for :func:`stcvision.kernels.unwarp_separate_u16`,
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
    _check_image(image, "image", (np.uint8, np.uint16, np.float32))
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


# --------------------------------------------------------------------------- channels
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
    #: 30 s) took dots 20-40 DN above the background for red and blacked them out (issue 16.7)
    red_min_fraction: float = 0.5

    def levels(self, background_dn: float, noise_dn: float) -> tuple[float, float]:
        """(red threshold, dominance tolerance) per pixel in DN, for a red channel of this
        background and noise."""
        thr = background_dn + self.red_k_sigma * noise_dn if self.red_threshold_dn is None else self.red_threshold_dn
        tol = self.dominance_k_sigma * noise_dn if self.dominance_tol_dn is None else self.dominance_tol_dn
        return float(thr), float(tol)


#: window sums as the stages hold them: uint16 from 8-bit frames, float32 (exact integers up to
#: 2^24) from 16-bit ones, whose nine-pixel sums overflow 16 bits
SUM_DTYPES = (np.uint16, np.float32)


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
    _check_image(image, "image", (np.uint8, *SUM_DTYPES), ndims=(3,))
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
    """:func:`filter_channels` on a green and a red image already split apart."""
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


def window_sums(image: np.ndarray, window_px: int) -> np.ndarray:
    """Sum over the dot-sized square around every pixel, no rounding: uint16 for a uint8 image,
    float32 for a uint16 one (exact: 9 x 65535 < 2^24).

    Seed 003, "Finding the green dots": "we look for the square of pixels (of a dot's size)
    that has the highest average value". Filtering once, in the mirror image where the pixels
    are, and unwarping the sums keeps every photon of a dot and the noise of exactly
    ``window_px**2`` pixels, wherever the dot lies (the unwarp would otherwise skip pixels near
    the robot, where the ground view is coarser than the mirror image).
    """
    _check_image(image, "image", (np.uint8, np.uint16))
    if isinstance(window_px, bool) or not isinstance(window_px, int | np.integer) or window_px < 1:
        raise BadInputError(f"window_px must be a positive integer, got {window_px!r}")
    depth = cv2.CV_16U if image.dtype == np.uint8 else cv2.CV_32F
    return cv2.boxFilter(image, depth, (window_px, window_px), normalize=False, borderType=cv2.BORDER_CONSTANT)


# --------------------------------------------------------------------------- dots
@dataclass(frozen=True, kw_only=True, slots=True)
class DotParams:
    """Dot search (seed 003, "Finding the green dots": the square of a dot's size with the
    highest average, a threshold, then black out and look again).

    ``window_px``: side of the averaging square in mirror-image pixels (3 px: about a UV dot
    near the robot, where a pixel sees ~2 mm of floor). The decision is made on the window mean's
    signal-to-noise ratio: a dot is lit iff ``(mean - background) / noise >= k_sigma``, with
    the background and the raw noise measured on the frame itself and the noise of the window
    mean at each ground pixel from the unwarp's noise gain. ``k_sigma = 5.5`` rather than
    Rose's 5: the noise is a mixture (dark-current non-uniformity, the dark frame's own
    error), so its tail is heavier than a Gaussian's -- measured on rendered dark
    frames, window SNRs above 5 occur 8x more often than Gaussian noise predicts, above 5.5 no
    more often than Gaussian noise does above 5. A fixed
    ``threshold_dn`` (window mean above background) overrides that. ``blackout_px``: half-side
    of the square blacked out around a found dot (3 px ~ 1.2 cm: the end dots of two marks meeting
    at a sub-cell corner are 1.5 cm apart along each axis). A weaker peak near a much brighter
    dot is also dropped when that dot's blur (a Gaussian of ``tail_sigma_px``) explains at least
    half of it: a fresh dot hundreds of sigma strong still shows at 5 sigma a few pixels out.
    Candidates down to ``candidate_snr`` are reported with ``lit=False`` so that decisions carry
    a confidence.

    Positions: first the centroid of the window sums within ``centroid_px`` ground pixels of the
    peak; then (:func:`mirror_centroids`) a Gaussian-weighted centroid (sigma
    ``mirror_sigma_px``, ``mirror_iters`` passes, the ``2 * mirror_half_px + 1`` square) on the
    dark-subtracted mirror image, where the pixels are, mapped back through the unwarp map;
    a shift of more than ``mirror_max_shift_px`` ground pixels (a brighter neighbour
    pulling) keeps the first. ``mirror_sigma_px = 0`` turns it off.

    Caps (never silent: a frame over either is returned with ``Dots.untrusted`` saying why):
    ``max_candidates`` local maxima above the candidate level -- a frame of marks holds a few
    hundred (a 1.15 m ground view holds ~200 sub-cells of 4 dots), so tens of thousands mean the
    noise estimate does not describe the frame (issue 16.5: a cooled sensor quantised to 8 bits
    gave 61,145); only the strongest ``max_candidates`` are examined. ``max_dots`` accepted dots.
    """

    window_px: int = 3
    k_sigma: float = 5.5
    threshold_dn: float | None = None
    blackout_px: int = 3
    tail_sigma_px: float = 1.6
    centroid_px: int = 2
    max_dots: int = 200
    candidate_snr: float = 4.0
    mirror_sigma_px: float = 1.5
    mirror_half_px: int = 2
    mirror_iters: int = 2
    mirror_max_shift_px: float = 1.5
    max_candidates: int = 4000


@dataclass(frozen=True, eq=False)
class Dots:
    """Dots found in a ground-view marks image, strongest first.

    ``xy_px`` (N, 2) ground-view sub-pixel centroids; ``xy_m`` (N, 2) robot frame metres
    (x forward, y left); ``strength`` (N,) window mean above background (DN); ``snr`` (N,);
    ``lit`` (N,) at or above the threshold (``threshold_snr``).
    """

    xy_px: np.ndarray
    xy_m: np.ndarray
    strength: np.ndarray
    snr: np.ndarray
    lit: np.ndarray
    threshold_snr: float
    noise_dn: float
    background_dn: float
    #: (N,) bool: found as part of a faint row by :func:`find_rows`, not singly (None: none are)
    from_row: np.ndarray | None = None
    #: why this frame's dots cannot be trusted ("" when they can): a cap of :class:`DotParams`
    #: was reached, so the search stopped before the frame was read
    untrusted: str = ""

    def __len__(self) -> int:
        return len(self.strength)

    @property
    def n_lit(self) -> int:
        return int(self.lit.sum())


def noise_gain(umap: UnwarpMap, window_px: int, *, n: int = 12, seed: int = 0) -> np.ndarray:
    """Standard deviation, per ground pixel, of the unwarped window mean of unit white noise.

    The unwarp interpolates between window means, which lowers their noise by an amount that
    varies across the ground view; this map, computed once, turns the raw image's per-pixel
    noise into each ground pixel's.
    """
    rng = np.random.default_rng(seed)
    w, h = umap.image_size_px
    acc = np.zeros(umap.map_x.shape, np.float64)
    for _ in range(n):
        z = rng.standard_normal((h, w)).astype(np.float32)
        b = cv2.boxFilter(z, cv2.CV_32F, (window_px, window_px))  # the window mean, in the mirror image
        g = cv2.remap(b, umap.map_x, umap.map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        acc += g.astype(np.float64) ** 2
    # the gain varies smoothly across the view: smoothing the variance estimate removes the
    # sampling noise of a few Monte-Carlo images (12 samples alone scatter by +-20 %)
    var = cv2.GaussianBlur((acc / n).astype(np.float32), (0, 0), 4.0)
    gain = np.sqrt(var)
    gain[~umap.valid] = 1e4  # no dot where the mirror does not look (finite: OpenCV arithmetic)
    return np.maximum(gain, 1e-3)


def estimate_background(image: np.ndarray, sample: np.ndarray | None = None, quantum: int = 1) -> tuple[float, float]:
    """(median, robust sigma) of a uint8 or uint16 image's pixels (or of
    ``image.reshape(-1)[sample]``), whose values are whole multiples of ``quantum`` apart
    (:func:`quantum_dn`).

    From a histogram of the quantisation steps, each spread uniformly over its step (so noise
    levels below a step are not rounded away): the median, and sigma = interquartile range /
    1.349.
    """
    _check_image(image, "pixel values", (np.uint8, np.uint16), ndims=(1, 2, 3))
    v = image.reshape(-1)[sample] if sample is not None else image.reshape(-1)[::7]
    # (the pipeline's per-frame sample: kernels.sample_quartiles, the same histogram choice)
    if image.dtype == np.uint8 and quantum == 1:
        lo, nbins = 0, 256
    else:  # a histogram of the occupied range only (16-bit data spans few of its 65,536 values)
        lo = int(v.min())
        nbins = (int(v.max()) - lo) // quantum + 1
    # cumulative histogram, its strictly increasing points inverted at the quartiles (compiled)
    q1, med, q3 = kernels.histogram_quartiles(np.ascontiguousarray(v), lo, int(quantum), nbins)
    return float(med), float((q3 - q1) / 1.349)


def noise_floor(quantum: float = 1.0) -> float:
    """The least per-pixel noise a measurement may report: the rounding noise of one
    quantisation step (``quantum`` DN), ``quantum / sqrt(12)``."""
    return QUANTISATION_SIGMA * quantum


def _candidate_level(dtype, gain, params: DotParams, area: int, background_dn: float, noise_dn: float, low: float):
    """The dot candidate level for :func:`kernels.dot_candidates`: (mode, a, c), the level
    ``gain * a + c`` per pixel in the sums' own units (mode 0: uint16 sums, rounded to whole
    DN; 1: float32 sums), or the scalar ``c`` (mode 2: a fixed ``threshold_dn``, or no gain map)."""
    if params.threshold_dn is not None:
        level = np.float32(area * (background_dn + params.threshold_dn * low / params.k_sigma))
    elif gain is not None and dtype == np.uint16:
        return 0, area * low * noise_dn, area * background_dn + 0.5
    elif gain is not None:
        return 1, area * low * noise_dn, area * background_dn
    else:
        level = np.float32(area * (background_dn + low * noise_dn / params.window_px))
    if dtype == np.uint16:
        return 2, 0.0, float(min(int(np.ceil(level)), 65535))
    return 2, 0.0, float(level)


def find_dots(
    marks: np.ndarray,
    params: DotParams = DotParams(),
    *,
    gain: np.ndarray | None = None,
    background_dn: float | None = None,
    noise_dn: float | None = None,
    ground_to_robot=None,
    quantum: float = 1.0,
) -> Dots:
    """Find dots in a ground-view marks image: filter once (window mean), keep local maxima
    above the candidate level, accept them strongest first while blacking out a square around
    each.

    Parameters
    ----------
    marks : (S, S) uint8 image, or window sums (uint16 or float32: :func:`window_sums`, then unwarped)
    gain : (S, S) float32 :func:`noise_gain` map (noise of a window mean per unit raw noise);
        default: white noise, ``1 / window_px``.
    background_dn, noise_dn : background level and raw per-pixel noise; default: measured on
        ``marks`` (median, IQR).
    ground_to_robot : callable (N, 2) px -> (N, 2) m, optional (``Profile.ground_to_robot``).
    quantum : the raw pixels' quantisation step (DN, :func:`quantum_dn`); the noise is never
        taken below its rounding noise (:func:`noise_floor`).
    """
    _check_image(marks, "marks image (uint8, or window sums)", (np.uint8, *SUM_DTYPES), ndims=(2,))
    w = params.window_px
    area = w * w
    if background_dn is None or noise_dn is None:
        if marks.dtype != np.uint8:
            raise BadInputError("find_dots: give background_dn and noise_dn with window sums")
        background_dn, noise_dn = estimate_background(marks)
    noise_dn = max(noise_dn, noise_floor(quantum))
    if marks.dtype == np.uint8:  # a plain image: filter it here
        sums = cv2.boxFilter(marks, cv2.CV_32F, (w, w), normalize=False)
    else:  # window sums of the mirror image, already unwarped
        sums = marks
    low = min(params.candidate_snr, params.k_sigma)
    # local maxima (3x3) at or above the candidate level, area * (background + snr * noise of
    # the window mean there), in one compiled pass (kernels.dot_candidates: the level image,
    # the 3x3 dilation, the compares and findNonZero it replaced, to the bit); the black-out
    # below does the suppression between peaks. Not a dilation over the whole black-out square:
    # that also dropped a dot whose brighter neighbour's flank reaches into the square -- the
    # end dots of two marks meeting at a corner, 1.5 cm (3.9 px) apart along each axis, whose
    # peaks the black-out keeps (issue 18: 4 of 9 missed SNR >= 8 dots on ages frames, at SNR 12-20)
    e = w // 2 + 1  # a window cut by the image border sees reflected pixels: no dot there
    mode, a, c = _candidate_level(sums.dtype, gain, params, area, background_dn, noise_dn, low)
    g = gain if (gain is not None and params.threshold_dn is None) else np.full((1, 1), 1.0 / w)
    xs, ys, vals, mean = kernels.dot_candidates(sums, g, mode, a, c, e, area, float(background_dn), float(noise_dn))
    if params.threshold_dn is not None:
        vals = mean * (params.k_sigma / params.threshold_dn)
    per_px = background_dn * (area if marks.dtype != np.uint8 else 1)  # sums hold w*w pixels
    # strongest first (at most max_candidates), then the greedy black-out: a candidate is
    # dropped if a kept stronger one shadows it -- it lies in that one's black-out square
    # (half-side blackout_px), or that one's blur (a Gaussian of tail_sigma_px) explains half of
    # it -- checked against the dots kept so far only (earlier a k-d tree of all candidate pairs:
    # the same choice, several times the cost); then the intensity-weighted centroids above the
    # background in the (2 centroid_px + 1)^2 squares: kernels.rank_dots, one call
    n_cand, xy, snr_k, strength = kernels.rank_dots(
        xs,
        ys,
        vals,
        mean,
        params.blackout_px,
        float(params.tail_sigma_px),
        params.max_dots,
        params.max_candidates,
        marks,
        params.centroid_px,
        float(per_px),
    )
    untrusted = ""
    if n_cand > params.max_candidates:
        untrusted = (
            f"{n_cand} dot candidates above {low:g} sigma, more than the {params.max_candidates} a frame of "
            "marks can hold: the measured noise does not describe this frame"
        )
    n = len(snr_k)
    if n >= params.max_dots and not untrusted:
        untrusted = f"{params.max_dots} dots found, the most a frame is read for (DotParams.max_dots)"
    if not n:
        strength = np.zeros(0)
    xy_m = ground_to_robot(xy) if (ground_to_robot is not None and n) else np.zeros((n, 2))
    return Dots(
        xy,
        xy_m,
        strength,
        snr_k,
        snr_k >= params.k_sigma,
        float(params.k_sigma),
        float(noise_dn),
        float(background_dn),
        untrusted=untrusted,
    )


#: ground-view steps at which the unwarp map is read for a dot: the dot, then +-0.5 px in x and y
_JAC_STEPS = np.array([[0.0, 0.0], [0.5, 0.0], [-0.5, 0.0], [0.0, 0.5], [0.0, -0.5]])


def mirror_centroids(
    dots: Dots,
    image: np.ndarray,
    *,
    background_dn: float,
    umap: UnwarpMap,
    ground_to_robot=None,
    params: DotParams = DotParams(),
) -> Dots:
    """``dots`` with positions measured again in the mirror image ``image`` ((H, W), the
    dark-subtracted green channel, background ``background_dn`` per pixel).

    The window sums and the unwarp each blur a dot (a 3x3 box in the mirror image, then bilinear
    interpolation onto ground pixels that are coarser than the mirror's near the robot), and a
    centroid over a few ground pixels of that is pulled toward its integer peak: median image
    error 0.20 px on ages frames, where a SimpleBlobDetector on the raw image reaches 0.135
    (issue 18). Here each dot's centroid is taken where its photons are: an iterated
    Gaussian-weighted centroid (the weight follows the estimate, which keeps the noise of the
    square's corners out) of the background-subtracted pixels around the dot's mirror position
    (the unwarp map ``umap`` at the dot), taken back to the ground view through the map's local
    Jacobian (the shift is under a pixel, where the map is linear) and to the robot frame with
    ``ground_to_robot``. A dot off the image or the mirror, or whose centroid moved more than
    ``params.mirror_max_shift_px`` ground pixels (a brighter neighbour pulling), keeps its
    position.
    """
    n = len(dots)
    if not n or params.mirror_sigma_px <= 0:
        return dots
    g0 = dots.xy_px.astype(np.float64)
    # the dots' mirror positions, and the map's Jacobian there (central differences, +-0.5 px;
    # kernels.map_at: the map read as cv2.remap reads it, -10 beyond it)
    m = kernels.map_at(umap.map_x, umap.map_y, g0, _JAC_STEPS, -10.0)
    # the centroids (kernels.gauss_centroids: a loop per dot over its square, compiled), back
    # to the ground view through the inverse Jacobian (kernels.mirror_shift)
    c, ok = kernels.gauss_centroids(
        image, m[:, 0], float(background_dn), params.mirror_half_px, float(params.mirror_sigma_px), params.mirror_iters
    )
    xy_px = kernels.mirror_shift(m, c, ok, g0, float(params.mirror_max_shift_px**2))
    xy_m = ground_to_robot(xy_px) if ground_to_robot is not None else dots.xy_m
    return replace(dots, xy_px=xy_px, xy_m=xy_m)


# --------------------------------------------------------------------------- rows
@dataclass(frozen=True, kw_only=True, slots=True)
class RowParams:
    """Faint-row search: a mark is a row of ``n_dots`` UV dots ``spacing_m`` apart (the robot's
    rear LEDs; ``sim_camera.phosphor.LED_OFFSETS_M``: 4 LEDs 3 cm apart) parallel to a grid axis.
    Old marks fade below the single-dot threshold well before all four of their dots are lost
    in the noise: summing the four window SNRs at the row's spacing (a matched filter for the
    row) gains sqrt(4) = 2 in SNR over one dot, i.e. at k_sigma 6 against the dots' 5.5 the
    same frame reads marks about 1.7x older (the afterglow falls as t^-1.1).

    A row is accepted where ``sum / sqrt(n_dots) >= k_sigma``, every one of its dots is at least
    ``min_dot_snr`` and no more than ``spread_snr`` below the row's mean (a mark's dots are
    about equally bright), and the floor one spacing beyond either end is below
    ``end_max_snr`` (else it is a real row shifted by one dot: three real dots and one of
    noise). Single dots are clipped at the dot threshold, and free rows are sought only where the
    dot search found nothing (no row dot, nor the floor beyond its ends, within a lit dot's
    blur), so a bright dot cannot make a row of noise; a lone found dot of at most
    ``anchor_max_snr`` may anchor a row (:func:`find_rows`). ``k_sigma`` is set by the same argument as
    :class:`DotParams` (heavier-than-Gaussian tail), a little higher still: a closed-loop run
    makes hundreds of looks, and at 5.5 one of them found a row of noise (5.7) on a 2 s frame;
    no row is found on rendered frames without old marks (tests/stcvision/test_rows.py).
    """

    enabled: bool = True
    spacing_m: float = 0.03
    n_dots: int = 4
    k_sigma: float = 6.0
    min_dot_snr: float = 0.0
    end_max_snr: float = 2.5
    spread_snr: float = 2.5
    max_rows: int = 40
    #: rows through one found dot (see :func:`find_rows`): the other three dots must each reach
    #: ``anchor_min_snr`` and together ``3 * anchor_mean_snr``; anchors brighter than
    #: ``anchor_max_snr`` are not completed (the rest of their row would have been found)
    anchored: bool = True
    anchor_min_snr: float = 1.0
    anchor_mean_snr: float = 2.5
    anchor_max_snr: float = 11.0


def find_rows(
    marks: np.ndarray,
    dots: Dots,
    *,
    gain: np.ndarray,
    background_dn: float,
    noise_dn: float,
    px_per_m: float,
    window_px: int,
    params: RowParams = RowParams(),
    dot_params: DotParams = DotParams(),
    ground_to_robot=None,
    quantum: float = 1.0,
    buffers=None,
) -> Dots:
    """Rows of ``params.n_dots`` faint dots along either ground-view axis that the dot search
    missed; returns ``dots`` with the rows' dots appended (``lit=True``, ``from_row=True``,
    ``snr`` the row's SNR). ``marks``: the window sums the dot search ran on; ``quantum`` as
    for :func:`find_dots`; ``buffers``: ``buffers(name, shape, dtype)`` gives the search's
    scratch images (a caller reusing them from frame to frame: the pipeline), default new ones.

    Two searches. *Anchored rows*: a fading mark's brightest dot often passes the dot threshold
    while its other three do not (each dot's SNR scatters by +-1 about the mark's), and a row
    may not run through a found dot. So each found dot that stands alone (no other lit dot
    within 1.5 spacings, none at the row's other places or one spacing beyond its ends) is
    tried as one dot of a row: 4 places x 2 axes, 8 hypotheses, where the free search tries
    every pixel; with so few trials the other three need less (``anchor_min_snr`` each,
    ``anchor_mean_snr`` on average). *Free rows*: where the dot search found nothing, the
    matched filter below."""
    area = window_px * window_px
    if not params.enabled or marks.dtype not in SUM_DTYPES:
        return dots
    noise_dn = max(noise_dn, noise_floor(quantum))
    buf = buffers or (lambda name, shape, dtype: np.empty(shape, dtype))
    z = _row_snr(
        marks, gain, area, background_dn, noise_dn, dot_params.k_sigma, buf("row snr", marks.shape, np.float32)
    )
    occ = _taken_floor(marks, dots, dot_params, buf("taken", marks.shape, np.uint8))
    h, w = z.shape
    n = params.n_dots
    step = params.spacing_m * px_per_m
    offs, ends, m = _row_offsets(step, n)
    e = max(m, window_px // 2 + 1)  # rows reaching beyond the image are not sought
    if 2 * e >= min(h, w):
        return dots
    if params.anchored:
        rows_xy, rows_s = _anchored_rows(z, occ, dots, step, n, params)
    else:
        rows_xy, rows_s = np.zeros((0, n - 1, 2)), np.zeros(0)
    xs, ys, st, ax = _free_rows(z, occ, offs, ends, e, params, buf("row mask", marks.shape, np.uint8))
    free_xy, free_s = _accept_free_rows(z.shape, xs, ys, st, ax, offs, rows_xy, dot_params.blackout_px, params.max_rows)
    if not len(rows_s) and not len(free_s):
        return dots
    pts = np.concatenate([rows_xy.reshape(-1, 2), free_xy.reshape(-1, 2)])
    snr = np.concatenate([np.repeat(rows_s, n - 1), np.repeat(free_s, n)])  # float64
    return _with_rows(dots, marks, z, gain, pts, snr, area, background_dn, noise_dn, dot_params, ground_to_robot)


@functools.lru_cache(maxsize=64)
def _row_offsets(step: float, n: int) -> tuple[np.ndarray, np.ndarray, int]:
    """(offsets of a row's ``n`` dots from its centre, of the floor one spacing beyond either
    end, the larger reach) in whole pixels for a dot spacing of ``step`` px: the same for every
    frame of a profile, so made once (read-only arrays)."""
    offs = np.round((np.arange(n) - (n - 1) / 2) * step).astype(np.int64)
    # one spacing beyond either end: a row shifted along a real one by a dot has a dot there
    ends = np.round(np.array([-1, 1]) * ((n + 1) / 2) * step).astype(np.int64)
    offs.setflags(write=False)
    ends.setflags(write=False)
    return offs, ends, int(np.abs(ends).max())


def _row_snr(
    marks: np.ndarray, gain: np.ndarray, area: int, background_dn: float, noise_dn: float, clip: float, out: np.ndarray
):
    """Per-pixel SNR of the window sums ``marks`` (float32), clipped at the dot threshold
    ``clip``: a single bright dot must not make a row. One compiled pass
    (:func:`kernels.row_snr`) for uint16 sums; float32 ones (16-bit frames) through OpenCV."""
    if marks.dtype == np.uint16 and gain.dtype == np.float32:
        return kernels.row_snr(marks, gain, area, float(background_dn), float(noise_dn), float(clip), out)
    z = cv2.addWeighted(marks, 1.0 / area, marks, 0.0, -background_dn, dtype=cv2.CV_32F)
    z = cv2.divide(z, gain, scale=1.0 / noise_dn)
    return cv2.min(z, float(clip), dst=z)


def _taken_floor(marks: np.ndarray, dots: Dots, dot_params: DotParams, out: np.ndarray) -> np.ndarray:
    """uint8 image, non-zero where no row may run nor end: within each lit dot's blur (as far as
    it still shows above 1 sigma, at least the black-out square), and within the black-out
    square of a red light blacked out of the marks image (zero there): the edge of its glare,
    just below the black-out level, runs along the light as a column of faint "dots"."""
    b = dot_params.blackout_px
    occ = kernels.zero_ring(marks, b, out)
    kernels.blur_squares(occ, dots.xy_px.reshape(-1, 2), dots.snr, dots.lit, float(dot_params.tail_sigma_px), b)
    return occ


def _accept_free_rows(shape, xs, ys, st, ax, offs, rows_xy: np.ndarray, b: int, max_rows: int):
    """The free rows accepted strongest first, after the anchored rows ``rows_xy`` ((R, n - 1,
    2)): a row may not share a dot with one already accepted (within ``b`` along both axes;
    :func:`kernels.accept_rows`), at most ``max_rows`` rows in all. Returns their points ((A,
    n, 2) float) and SNRs (A,), in the order accepted."""
    if not len(xs):
        return np.zeros((0, len(offs), 2)), np.zeros(0, np.float32)
    return kernels.accept_free_rows(shape, rows_xy, xs, ys, st, ax, offs, b, max_rows - len(rows_xy))


def _with_rows(dots, marks, z, gain, pts, snr, area, background_dn, noise_dn, dot_params, ground_to_robot):
    """``dots`` with the rows' dots at ``pts`` (SNR ``snr``) appended: centroids as
    :func:`find_dots` takes them, strength the window mean above background, ``lit`` and
    ``from_row`` set."""
    # centroids and strengths at the rows' pixels (kernels.row_dots: one call)
    xy, strength = kernels.row_dots(marks, z, gain, pts, dot_params.centroid_px, float(background_dn * area), noise_dn)
    xy_m = ground_to_robot(xy) if ground_to_robot is not None else np.zeros((len(xy), 2))
    k = len(dots)
    from_row = np.zeros(k, bool) if dots.from_row is None else dots.from_row
    return Dots(
        np.concatenate([dots.xy_px.reshape(-1, 2), xy]),
        np.concatenate([dots.xy_m.reshape(-1, 2), xy_m]),
        np.concatenate([dots.strength, strength]),
        np.concatenate([dots.snr, snr]),
        np.concatenate([dots.lit, np.ones(len(xy), bool)]),
        dots.threshold_snr,
        dots.noise_dn,
        dots.background_dn,
        np.concatenate([from_row, np.ones(len(xy), bool)]),
        untrusted=dots.untrusted,
    )


def _free_rows(
    z: np.ndarray, occ: np.ndarray, offs: np.ndarray, ends: np.ndarray, e: int, params: RowParams, ok: np.ndarray
):
    """Free-row candidates of :func:`find_rows`: (x, y, row SNR, axis) where the row sum of the
    SNRs ``z`` at ``offs`` along either axis reaches ``k_sigma * sqrt(n)``, every dot is at least
    ``min_dot_snr`` and within ``spread_snr`` of the row's mean, and the floor at ``ends`` is
    free (``occ`` 0) and below ``end_max_snr``; no dot on a taken pixel. Axis 0 (rows along x)
    first, each in row-major order.

    Those tests together need every dot of the row at or above ``max(min_dot_snr, mean -
    spread_snr)`` with the mean at least ``k_sigma / sqrt(n)``: that bound prunes almost every
    pixel after a dot or two, and only where all dots pass are the row sums and the rest
    computed, in one compiled pass per axis (:func:`kernels.free_rows`; earlier about twenty
    OpenCV passes over shifted masks, then numpy on the few pixels left: the same rows)."""
    n = len(offs)
    gate = max(params.min_dot_snr, params.k_sigma / math.sqrt(n) - params.spread_snr) - 1e-3
    return kernels.free_rows(
        z,
        occ,
        np.asarray(offs, np.int64),
        np.asarray(ends, np.int64),
        e,
        gate,
        float(np.float32(params.k_sigma * math.sqrt(n))),
        float(params.min_dot_snr),
        float(params.spread_snr),
        float(params.end_max_snr),
        ok,
    )


def _anchored_rows(z, occ, dots: Dots, step: float, n: int, params: RowParams):
    """Rows through one found dot (:func:`find_rows`): the added points ((R, n - 1, 2) float
    ground px) and the rows' SNRs (R,). ``z``: per-pixel SNR clipped at the dot threshold, before
    the black-out; ``occ``: the lit dots' blur masks; ``step``: the dot spacing (px)."""
    xy_lit = np.ascontiguousarray(dots.xy_px[dots.lit].reshape(-1, 2), np.float64)
    if not len(xy_lit):
        return np.zeros((0, n - 1, 2)), np.zeros(0)
    snr = np.ascontiguousarray(dots.snr[dots.lit], np.float64)
    near = 1.5 * step
    # lone dots only: no other lit dot within 1.5 spacings (else it is a dot of a row found
    # already, which reads as a mark with one lit neighbour), at most anchor_max_snr, the row's
    # reach inside the image
    if len(xy_lit) <= 256:
        crowded = kernels.crowded(xy_lit, near)
    else:  # more dots than a frame is read for: neighbours by a k-d tree, not all pairs
        pairs = cKDTree(xy_lit).query_pairs(near * (1 + 1e-9), output_type="ndarray")
        d2 = ((xy_lit[pairs[:, 0]] - xy_lit[pairs[:, 1]]) ** 2).sum(axis=1)
        crowded = np.zeros(len(xy_lit), bool)
        crowded[pairs[d2 <= near * near].reshape(-1)] = True
    # each lone dot: 4 places x 2 axes; at each of the row's other places and one spacing beyond
    # either end the best of the three pixels across the row (a lean of a degree or two); a row
    # with another lit dot on it or next to it (occ) is not tried, and the best passing one is
    # kept unless it comes within 2 px of a row kept already (kernels.anchored_rows)
    return kernels.anchored_rows(
        z,
        occ,
        xy_lit,
        snr,
        crowded,
        float(params.anchor_max_snr),
        int(np.ceil((n + 1) * step)) + 2,
        float(step),
        n,
        float(params.anchor_min_snr),
        float(params.anchor_mean_snr),
        float(params.end_max_snr),
        float(params.k_sigma),
    )


# --------------------------------------------------------------------------- heading
@dataclass(frozen=True, kw_only=True, slots=True)
class HeadingParams:
    """Heading fit (seed 003, "Angle Detection": the newest three dots, a line through them).

    The newest mark is the brightest; its dots are the brightest dot and its lit neighbours
    within ``row_radius_m`` (a row of four UV dots spans 9 cm) that lie on one line with it
    (within ``max_residual_m``). ``max_residual_m`` is also the RMS distance of the dots from
    the fitted line above which the fit is refused.
    """

    n_dots: int = 3
    row_radius_m: float = 0.10
    max_residual_m: float = 0.004
    min_span_m: float = 0.02


@dataclass(frozen=True)
class HeadingFit:
    """Result of :func:`fit_heading`. Falsy when the fit failed (``reason`` says why).

    ``line_angle_rad``: direction of the mark row in the robot frame (x forward, y left),
    folded into [-pi/4, pi/4) around the nearest grid axis. ``heading_error_rad``: how far the
    robot's heading is off the grid (counter-clockwise positive) = ``-line_angle_rad``.
    """

    ok: bool
    line_angle_rad: float = math.nan
    heading_error_rad: float = math.nan
    residual_m: float = math.nan
    points_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    reason: str = ""

    def __bool__(self) -> bool:
        return self.ok


def fit_heading(dots: Dots, params: HeadingParams = HeadingParams()) -> HeadingFit:
    """Total-least-squares line through the newest (brightest) dots of the last mark row."""
    lit = np.flatnonzero(dots.lit)
    if len(lit) < params.n_dots:
        return HeadingFit(False, reason=f"fewer than {params.n_dots} dots ({len(lit)} lit)")
    xy = np.ascontiguousarray(dots.xy_m[lit], np.float64)
    # the row through the brightest dot: of the lines from it to each neighbour within the row
    # radius, the one most other neighbours lie on (another mark can sit within the row radius,
    # across the row), then the brightest; its n_dots brightest dots (kernels.heading_row)
    status, count, pick = kernels.heading_row(
        xy,
        np.ascontiguousarray(dots.strength[lit], np.float64),
        params.n_dots,
        float(params.row_radius_m),
        float(params.max_residual_m),
    )
    if status == 1:
        return HeadingFit(
            False, reason=f"the brightest dot has only {count - 1} lit neighbours within {params.row_radius_m} m"
        )
    if status == 2:
        return HeadingFit(False, reason=f"no row of {params.n_dots} collinear dots at the brightest dot")
    pts = xy[pick]
    # the line's direction, and the spread along and across it (kernels.tls_line: closed form)
    ang, span, resid = kernels.tls_line(pts)
    if span * 2 < params.min_span_m:
        return HeadingFit(False, points_m=pts, reason="dots too close together to define a line")
    if resid > params.max_residual_m:
        return HeadingFit(
            False, residual_m=float(resid), points_m=pts, reason=f"dots not on a line (residual {resid * 1000:.1f} mm)"
        )
    folded = (ang + math.pi / 4) % (math.pi / 2) - math.pi / 4
    return HeadingFit(True, float(folded), float(-folded), float(resid), pts)


# --------------------------------------------------------------------------- recalibration
@dataclass(frozen=True)
class Recalibration:
    """New rotation time and the correction to finish the current turn.

    ``turn_time_s``: time to command for the next 90-degree turn; ``correction_s``: signed
    extra rotation time (negative = rotate back) to complete this one; ``accepted``: the
    measurement was used; ``reason``: why not, or what bound applied.
    """

    turn_time_s: float
    correction_s: float
    accepted: bool
    reason: str = ""


def recalibrate_turn(
    turn_time_s: float,
    measured_turn_rad: float,
    *,
    target_rad: float = math.pi / 2,
    max_ratio: float = 1.25,
    tolerance_rad: float = math.radians(1.0),
) -> Recalibration:
    """Seed 003, "Rotation and Calibration": in time T the robot turned d instead of 90
    degrees, so the next turn gets ``T' = 90/d * T``, and a correction finishes this one.

    Robust to a wild measurement: a non-positive or non-finite ``d`` is rejected (T kept), and
    ``T'/T`` is bounded to ``[1/max_ratio, max_ratio]`` (a Lego robot's rate drifts by a few
    per cent per turn, so a larger jump is a misreading, not the robot). Within
    ``tolerance_rad`` no calibration is needed (seed: "If the robot has done the rotation
    accurate enough, no calibration is needed").
    """
    if not (turn_time_s > 0 and math.isfinite(turn_time_s)):
        raise BadInputError(f"turn_time_s must be > 0, got {turn_time_s}")
    d = measured_turn_rad
    if not math.isfinite(d) or d <= 0:
        return Recalibration(turn_time_s, 0.0, False, f"measured turn {d!r} rad is not a positive angle")
    if abs(d - target_rad) <= tolerance_rad:
        return Recalibration(turn_time_s, 0.0, True, "within tolerance")
    ratio = target_rad / d
    reason = ""
    if ratio > max_ratio or ratio < 1 / max_ratio:
        reason = f"ratio {ratio:.2f} clipped to the +-{(max_ratio - 1) * 100:.0f} % bound"
        ratio = min(max(ratio, 1 / max_ratio), max_ratio)
    # finishing this turn takes (target - d) / (d / T) = T (ratio - 1): bounded with the ratio
    return Recalibration(turn_time_s * ratio, float(turn_time_s * (ratio - 1.0)), True, reason)


# --------------------------------------------------------------------------- red lights
@dataclass(frozen=True, kw_only=True, slots=True)
class RedParams:
    """Red-light blobs in the obstacle image: connected areas of at least ``min_area_px``."""

    min_area_px: int = 2


@dataclass(frozen=True, eq=False)
class RedLights:
    """Red blobs: ``xy_px`` (M, 2) ground-view centroids, ``peak_dn`` (M,), ``area_px`` (M,)."""

    xy_px: np.ndarray
    peak_dn: np.ndarray
    area_px: np.ndarray

    def __len__(self) -> int:
        return len(self.peak_dn)


def find_red(obstacle: np.ndarray, params: RedParams = RedParams(), *, window_area: int = 1) -> RedLights:
    """Blobs of the (already thresholded) obstacle image: outer contours and their moments.
    ``peak_dn`` is per pixel (window sums are divided by ``window_area``)."""
    _check_image(obstacle, "obstacle image (uint8, or window sums)", (np.uint8, *SUM_DTYPES), ndims=(2,))
    if min(obstacle.shape) < 2:  # OpenCV takes a 1 x 1 array for a scalar and fails (fuzzing)
        raise BadInputError(f"obstacle image must be at least 2x2 pixels, got {obstacle.shape}")
    binary = np.empty(obstacle.shape, np.uint8)  # cv2.compare(obstacle, 0, CMP_GT), counted
    if not kernels.nonzero_mask(obstacle, binary):  # no red light in view (most frames): no contour pass
        return RedLights(np.zeros((0, 2)), np.zeros(0), np.zeros(0))
    contours, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return RedLights(np.zeros((0, 2)), np.zeros(0), np.zeros(0))
    # every contour's moments, area, position and peak in one call (kernels.blobs: cv2.moments'
    # and cv2.boundingRect's own arithmetic)
    starts = np.zeros(len(contours) + 1, np.int64)
    np.cumsum([len(c) for c in contours], out=starts[1:])
    xy, peak, area = kernels.blobs(
        obstacle, np.concatenate(contours).reshape(-1, 2), starts, float(params.min_area_px), float(window_area)
    )
    return RedLights(xy, peak, area)
