"""The dot search: window-mean peaks above the frame's noise, the greedy black-out, the centroids.

The search runs first on the ground view's window sums, then on the mirror image.

The ant-like STC paper (Srour & Abboud), "Finding the green dots": the square of a dot's size with
the highest average, a threshold, then black out and look again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numba
import numpy as np

from stcvision.errors import BadInputError
from stcvision.stages.common import SUM_DTYPES, check_image, noise_floor
from stcvision.stages.compiled import fma32, grow_array, marked_positions, remap_lerp, row_flags
from stcvision.stages.dark import estimate_background
from stcvision.stages.ground_view import UnwarpMap


@dataclass(frozen=True, kw_only=True, slots=True)
class DotParams:
    """Parameters of the dot search.

    Dot search (ant-like STC paper, "Finding the green dots": the square of a dot's size with the
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
    noise estimate does not describe the frame (a cooled sensor's frame quantised to 8 bits
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
        """How many dots are lit."""
        return int(self.lit.sum())


def noise_gain(
    umap: UnwarpMap, window_px: int, *, n: int = 12, seed: int = 0, resampled_from: tuple | None = None
) -> np.ndarray:
    """Map the noise of the unwarped window mean per ground pixel.

    Standard deviation, per ground pixel, of the unwarped window mean of noise of unit standard
    deviation per pixel: white noise, or noise white at another size and resized to this one.

    The unwarp interpolates between window means, which lowers their noise by an amount that
    varies across the ground view; this map, computed once, turns the raw image's per-pixel
    noise into each ground pixel's. A frame resized from the camera's own size no longer has
    independent pixels: area averaging leaves them nearly so, interpolating up makes neighbours
    share their noise, so a window's mean is noisier than independent pixels' would be (twice,
    for a 3-pixel window of a frame enlarged by 2 with ``cv2.INTER_LINEAR``). With
    ``resampled_from`` the noise is drawn white at that size and resized as the frames were,
    then scaled to unit standard deviation per pixel, as the frame's own noise is measured.

    Parameters
    ----------
    umap : UnwarpMap
        The unwarp map (the mirror image's size and the ground view).
    window_px : int
        The dot window's side (px).
    n : int
        Monte-Carlo images (the variance is smoothed across the view after).
    seed : int
        Their seed.
    resampled_from : tuple, optional
        ``((W, H), interpolation)``: the size the frames were resized from and the OpenCV
        interpolation flag; None: the frames' pixels are independent.

    Returns
    -------
    numpy.ndarray
        The gain per ground pixel, float32 (large where the mirror does not look).
    """
    rng = np.random.default_rng(seed)
    w, h = umap.image_size_px
    acc = np.zeros(umap.map_x.shape, np.float64)
    for _ in range(n):
        if resampled_from is None:
            z = rng.standard_normal((h, w)).astype(np.float32)
        else:
            (w0, h0), interp = resampled_from
            z = cv2.resize(rng.standard_normal((h0, w0)).astype(np.float32), (w, h), interpolation=interp)
            z /= np.float32(z.std())  # the frame's noise is measured per pixel, after the resize
        b = cv2.boxFilter(z, cv2.CV_32F, (window_px, window_px))  # the window mean, in the mirror image
        g = cv2.remap(b, umap.map_x, umap.map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        acc += g.astype(np.float64) ** 2
    # the gain varies smoothly across the view: smoothing the variance estimate removes the
    # sampling noise of a few Monte-Carlo images (12 samples alone scatter by +-20 %)
    var = cv2.GaussianBlur((acc / n).astype(np.float32), (0, 0), 4.0)
    gain = np.sqrt(var)
    gain[~umap.valid] = 1e4  # no dot where the mirror does not look (finite: OpenCV arithmetic)
    return np.maximum(gain, 1e-3)


def _candidate_level(dtype, gain, params: DotParams, area: int, background_dn: float, noise_dn: float, low: float):
    """Return the dot candidate level for :func:`dot_candidates`.

    (mode, a, c), the level ``gain * a + c`` per pixel in the sums' own units (mode 0: uint16
    sums, rounded to whole DN; 1: float32 sums), or the scalar ``c`` (mode 2: a fixed
    ``threshold_dn``, or no gain map).
    """
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


def _window_sums_and_levels(marks: np.ndarray, w: int, background_dn, noise_dn, quantum: float):
    """Return (window sums, background, noise) of a marks image.

    A plain uint8 image is filtered here and its levels measured when not given; window sums come
    filtered, with their levels. The noise is never taken below the quantisation's rounding noise.
    """
    if background_dn is None or noise_dn is None:
        if marks.dtype != np.uint8:
            raise BadInputError("find_dots: give background_dn and noise_dn with window sums")
        background_dn, noise_dn = estimate_background(marks)
    noise_dn = max(noise_dn, noise_floor(quantum))
    if marks.dtype == np.uint8:  # a plain image: filter it here
        return cv2.boxFilter(marks, cv2.CV_32F, (w, w), normalize=False), background_dn, noise_dn
    return marks, background_dn, noise_dn  # window sums of the mirror image, already unwarped


def _too_many(n_cand: int, n: int, low: float, params: DotParams) -> str:
    """Why a frame's dots are not to be trusted for their number ("" when they are)."""
    if n_cand > params.max_candidates:
        return (
            f"{n_cand} dot candidates above {low:g} sigma, more than the {params.max_candidates} a frame of "
            "marks can hold: the measured noise does not describe this frame"
        )
    if n >= params.max_dots:
        return f"{params.max_dots} dots found, the most a frame is read for (DotParams.max_dots)"
    return ""


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
    """Find dots in a ground-view marks image.

    Filter once (window mean), keep local maxima above the candidate level, accept them
    strongest first while blacking out a square around each.

    Parameters
    ----------
    marks : numpy.ndarray
        (S, S) uint8 image, or window sums (uint16 or float32: :func:`window_sums`, then
        unwarped).
    params : DotParams
        The window, the thresholds, the black-out and the caps.
    gain : numpy.ndarray, optional
        (S, S) float32 :func:`noise_gain` map (noise of a window mean per unit raw noise);
        default: white noise, ``1 / window_px``.
    background_dn, noise_dn : float, optional
        Background level and raw per-pixel noise; default: measured on ``marks`` (median, IQR);
        window sums need them given.
    ground_to_robot : callable, optional
        (N, 2) px -> (N, 2) m (``Profile.ground_to_robot``).
    quantum : float
        The raw pixels' quantisation step (DN, :func:`quantum_dn`); the noise is never taken
        below its rounding noise (:func:`noise_floor`).

    Returns
    -------
    Dots
        The dots found, strongest first.

    Raises
    ------
    BadInputError
        When ``marks`` is not a 2-D uint8 image or window sums, or window sums come without
        ``background_dn`` and ``noise_dn``.
    """
    check_image(marks, "marks image (uint8, or window sums)", (np.uint8, *SUM_DTYPES), ndims=(2,))
    w = params.window_px
    area = w * w
    sums, background_dn, noise_dn = _window_sums_and_levels(marks, w, background_dn, noise_dn, quantum)
    low = min(params.candidate_snr, params.k_sigma)
    # local maxima (3x3) at or above the candidate level, area * (background + snr * noise of
    # the window mean there), in one compiled pass (dot_candidates: the level image,
    # the 3x3 dilation, the compares and findNonZero it replaced, to the bit); the black-out
    # below does the suppression between peaks. Not a dilation over the whole black-out square:
    # that also dropped a dot whose brighter neighbour's flank reaches into the square -- the
    # end dots of two marks meeting at a corner, 1.5 cm (3.9 px) apart along each axis, whose
    # peaks the black-out keeps (a dilation missed 4 of 9 SNR >= 8 dots on ages frames, at SNR 12-20)
    e = w // 2 + 1  # a window cut by the image border sees reflected pixels: no dot there
    mode, a, c = _candidate_level(sums.dtype, gain, params, area, background_dn, noise_dn, low)
    g = gain if (gain is not None and params.threshold_dn is None) else np.full((1, 1), 1.0 / w)
    xs, ys, vals, mean = dot_candidates(sums, g, mode, a, c, e, area, float(background_dn), float(noise_dn))
    if params.threshold_dn is not None:
        vals = mean * (params.k_sigma / params.threshold_dn)
    per_px = background_dn * (area if marks.dtype != np.uint8 else 1)  # sums hold w*w pixels
    # strongest first (at most max_candidates), then the greedy black-out: a candidate is
    # dropped if a kept stronger one shadows it -- it lies in that one's black-out square
    # (half-side blackout_px), or that one's blur (a Gaussian of tail_sigma_px) explains half of
    # it -- checked against the dots kept so far only (earlier a k-d tree of all candidate pairs:
    # the same choice, several times the cost); then the intensity-weighted centroids above the
    # background in the (2 centroid_px + 1)^2 squares: rank_dots, one call
    n_cand, xy, snr_k, strength = rank_dots(
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
    n = len(snr_k)
    untrusted = _too_many(n_cand, n, low, params)
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


@numba.njit(cache=True)
def dot_candidates(sums, gain, mode, a, c, e, area, background, noise):
    """Find the dot candidates in one pass over the window sums.

    Candidates of :func:`stcvision.stages.find_dots` in one pass over the window sums: the
    pixels at least ``e`` inside the border that reach the candidate level and are a 3x3 local
    maximum (``>=`` all eight neighbours, as ``sums >= cv2.dilate(sums, 3x3)``), in row-major
    order (``cv2.findNonZero``'s); with their SNR and window mean above the background.

    The level, per ``mode``: 0, uint16 sums: ``gain * a + c`` rounded half to even and saturated
    to 16 bits, with ``a``, ``c`` rounded to float32 and one fused float32 multiply-add (as
    ``cv2.addWeighted(..., dtype=CV_16U)`` computes it on the FMA machines here); 1, float32 sums:
    ``float32(gain * a) + c`` in float32; 2: the scalar ``c`` (already in the sums' units).
    SNR: ``(sum / area - background) / (noise * gain)`` in float64 (``gain`` of one element:
    ``gain[0, 0]`` everywhere), as the numpy version.

    Per image row, a branch-free loop (vectorised) marks the pixels at or near the level, and
    only those marked, eight at a time skipped where none is, are tested exactly.
    """
    h, w = sums.shape
    nx = w - 2 * e
    flag, words, idx = row_flags(nx)
    xs = np.empty(256, np.int64)
    ys = np.empty(256, np.int64)
    m = 0
    fa = np.float32(a)
    fc = np.float32(c)
    for y in range(e, h - e):
        # the row and its gain as views from the first interior pixel (indices from 0 up: no
        # negative-index check per access, a loop the compiler vectorises)
        c0 = sums[y, e : w - e]
        if mode == 0:
            gr = gain[y, e : w - e]
            for i in range(nx):  # within the level's rounding (float32: off by < 0.01), or saturated
                s = np.float32(c0[i])
                flag[i] = (s + np.float32(2.0) >= gr[i] * fa + fc) | (c0[i] == 65535)
        elif mode == 1:
            gr = gain[y, e : w - e]
            for i in range(nx):
                flag[i] = c0[i] >= np.float32(gr[i] * fa) + fc
        else:
            for i in range(nx):
                flag[i] = c0[i] >= c
        for t in range(marked_positions(flag, words, idx)):
            i = idx[t]
            s = c0[i]
            if mode == 0:
                lv = np.rint(fma32(gain[y, e + i], fa, fc))
                if s < min(max(lv, 0.0), 65535.0):
                    continue
            x = e + i
            up, mid, dn = sums[y - 1], sums[y], sums[y + 1]
            if (
                s < up[x - 1]
                or s < up[x]
                or s < up[x + 1]
                or s < mid[x - 1]
                or s < mid[x + 1]
                or s < dn[x - 1]
                or s < dn[x]
                or s < dn[x + 1]
            ):
                continue
            if m == len(xs):
                xs, ys = grow_array(xs, m), grow_array(ys, m)
            xs[m] = e + i
            ys[m] = y
            m += 1
    mean = np.empty(m)
    vals = np.empty(m)
    for i in range(m):
        mean[i] = np.float64(sums[ys[i], xs[i]]) / area - background
        g = np.float64(gain[0, 0]) if gain.size == 1 else np.float64(gain[ys[i], xs[i]])
        vals[i] = mean[i] / (noise * g)
    return xs[:m], ys[:m], vals, mean


@numba.njit(cache=True)
def greedy_black_out(xs, ys, vals, b, tail_sigma, max_dots):
    """Black out the weaker candidates around the stronger ones, greedily.

    The black-out of :func:`stcvision.stages.find_dots` (plateaus and chains of maxima that the
    3x3 maximum left) as one greedy loop over candidates
    sorted strongest first: candidate k is kept unless a kept one j has it in its black-out
    square (``|dx|, |dy| <= b``) or its blur explains half of it (``vals[j] exp(-d^2 / (2
    tail_sigma^2)) >= vals[k] / 2``). Each candidate is checked against the kept ones only
    (at most ``max_dots``), so no pair search is needed. Indices of the kept candidates.
    """
    n = len(vals)
    out = np.empty(min(n, max_dots), np.int64)
    m = 0
    two_s2 = 2.0 * tail_sigma**2
    # farther than this no kept candidate can shadow (its blur explains half of the weakest
    # candidate only within it): the exponential is evaluated for near pairs only
    vmin = max(vals.min(), 1e-12)
    reach2 = max(2.0 * b * b, two_s2 * math.log(max(2.0 * vals.max() / vmin, 1.0))) * (1 + 1e-9) + 1e-9
    for k in range(n):
        if m >= max_dots:
            break
        shadowed = False
        for t in range(m):
            j = out[t]
            dx = abs(xs[k] - xs[j])
            dy = abs(ys[k] - ys[j])
            d2 = dx * dx + dy * dy
            if d2 > reach2:
                continue
            if (dy <= b and dx <= b) or vals[j] * math.exp(-d2 / two_s2) >= 0.5 * vals[k]:
                shadowed = True
                break
        if not shadowed:
            out[m] = k
            m += 1
    return out[:m]


@numba.njit(inline="always")
def _pairwise_sum(a, n):
    """Sum ``a[:n]`` pairwise, in the order numpy does.

    Numpy's pairwise sum of ``a[:n]`` (n < 128: eight interleaved partial sums, then the
    rest in order; below eight, in order), in ``a``'s dtype: the order ``ndarray.sum`` adds a
    small contiguous block in, so the result is numpy's to the bit.
    """
    if n < 8:
        res = a[0] - a[0]
        for i in range(n):
            res += a[i]
        return res
    r0, r1, r2, r3, r4, r5, r6, r7 = a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7]
    i = 8
    while i < n - (n % 8):
        r0 += a[i]
        r1 += a[i + 1]
        r2 += a[i + 2]
        r3 += a[i + 3]
        r4 += a[i + 4]
        r5 += a[i + 5]
        r6 += a[i + 6]
        r7 += a[i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[i]
        i += 1
    return res


@numba.njit(cache=True)
def window_centroids(marks, xs, ys, r, per_px):
    """Compute intensity-weighted centroids about the given pixels.

    Intensity-weighted centroids (:func:`stcvision.stages.find_dots`): over the (2r+1)^2 square about each
    (xs, ys) (coordinates clipped to the image), the float32 values ``max(marks - per_px, 0)``
    and their x- and y-weighted sums (float64), each summed as numpy sums the square; the
    integer position where the square holds nothing above ``per_px``.
    """
    h, w = marks.shape
    n = len(xs)
    k = 2 * r + 1
    out = np.zeros((n, 2))
    p = np.empty(k * k, np.float32)
    px = np.empty(k * k)
    py = np.empty(k * k)
    thr = np.float32(per_px)
    zero = np.float32(0.0)
    for i in range(n):
        c = 0
        for dy in range(-r, r + 1):
            yy = min(max(ys[i] + dy, 0), h - 1)
            for dx in range(-r, r + 1):
                xx = min(max(xs[i] + dx, 0), w - 1)
                v = max(np.float32(marks[yy, xx]) - thr, zero)
                p[c] = v
                px[c] = xx * np.float64(v)
                py[c] = yy * np.float64(v)
                c += 1
        tot = _pairwise_sum(p, k * k)
        if tot > 0:
            t64 = np.float64(tot)
            out[i, 0] = _pairwise_sum(px, k * k) / t64
            out[i, 1] = _pairwise_sum(py, k * k) / t64
        else:
            out[i, 0] = xs[i]
            out[i, 1] = ys[i]
    return out


@numba.njit(cache=True)
def rank_dots(xs, ys, vals, mean, b, tail_sigma, max_dots, max_candidates, marks, r, per_px):
    """Rank the candidates, black out, and take the centroids of those kept, in one call.

    The rest of :func:`stcvision.stages.find_dots` after the candidates, in one call: the
    candidates sorted strongest first (a stable sort, as numpy's ``kind="stable"``), the
    strongest ``max_candidates`` kept, :func:`greedy_black_out`, then :func:`window_centroids`
    of those kept. Returns (number of candidates, centroids (n, 2), SNRs (n,) float64, window
    means (n,)).
    """
    nc = len(vals)
    if nc == 0:
        return 0, np.zeros((0, 2)), np.zeros(0), mean[:0]
    order = np.argsort(-vals, kind="mergesort")[:max_candidates]
    xs, ys, vals, mean = xs[order], ys[order], vals[order], mean[order]
    kept = greedy_black_out(xs, ys, vals, b, tail_sigma, max_dots)
    xy = window_centroids(marks, xs[kept], ys[kept], r, per_px)
    return nc, xy, vals[kept].astype(np.float64), mean[kept]


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
    """Measure the dots' positions again in the mirror image.

    ``dots`` with positions measured again in the mirror image ``image`` ((H, W), the
    dark-subtracted green channel, background ``background_dn`` per pixel).

    The window sums and the unwarp each blur a dot (a 3x3 box in the mirror image, then bilinear
    interpolation onto ground pixels that are coarser than the mirror's near the robot), and a
    centroid over a few ground pixels of that is pulled toward its integer peak: median image
    error 0.20 px on ages frames, where a SimpleBlobDetector on the raw image reaches 0.135.
    Here each dot's centroid is taken where its photons are: an iterated
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
    # map_at: the map read as cv2.remap reads it, -10 beyond it)
    m = map_at(umap.map_x, umap.map_y, g0, _JAC_STEPS, -10.0)
    # the centroids (gauss_centroids: a loop per dot over its square, compiled), back
    # to the ground view through the inverse Jacobian (mirror_shift)
    c, ok = gauss_centroids(
        image, m[:, 0], float(background_dn), params.mirror_half_px, float(params.mirror_sigma_px), params.mirror_iters
    )
    xy_px = mirror_shift(m, c, ok, g0, float(params.mirror_max_shift_px**2))
    xy_m = ground_to_robot(xy_px) if ground_to_robot is not None else dots.xy_m
    return replace(dots, xy_px=xy_px, xy_m=xy_m)


@numba.njit(cache=True)
def map_at(map_x, map_y, xy, steps, border):
    """Read the unwarp map at ground-view points and steps about them.

    The unwarp map (``map_x``, ``map_y``: (S, S) float32) read at each ground-view point
    ``xy[i]`` plus each of ``steps`` ((K, 2); the points rounded to float32 after the add):
    (N, K, 2) float64 mirror-image positions, as ``cv2.remap`` of each map (``INTER_LINEAR``,
    ``BORDER_CONSTANT`` ``border``) at those points computes them (:func:`remap_lerp`), in one pass
    instead of two OpenCV calls and the arrays around them.
    """
    h, w = map_x.shape
    n, k = len(xy), len(steps)
    out = np.empty((n, k, 2))
    bv = np.float32(border)
    for i in range(n):
        for j in range(k):
            gx = np.float32(xy[i, 0] + steps[j, 0])
            gy = np.float32(xy[i, 1] + steps[j, 1])
            fx = math.floor(gx)
            fy = math.floor(gy)
            x = int(fx)
            y = int(fy)
            aa = gx - np.float32(fx)
            bb = gy - np.float32(fy)
            for c in range(2):
                img = map_x if c == 0 else map_y
                p00 = img[y, x] if (0 <= x < w and 0 <= y < h) else bv
                p01 = img[y, x + 1] if (0 <= x + 1 < w and 0 <= y < h) else bv
                p10 = img[y + 1, x] if (0 <= x < w and 0 <= y + 1 < h) else bv
                p11 = img[y + 1, x + 1] if (0 <= x + 1 < w and 0 <= y + 1 < h) else bv
                out[i, j, c] = remap_lerp(aa, bb, p00, p01, p10, p11)
    return out


@numba.njit(cache=True, error_model="numpy")
def mirror_shift(m, c, ok, xy, max_shift2):
    """Take the mirror-image centroids back to the ground view.

    The ground-view positions of :func:`stcvision.stages.mirror_centroids`: per dot, the
    mirror-image centroid ``c`` taken back through the unwarp map's local Jacobian (``m``: the
    map at the dot and +-0.5 px in x and y, (n, 5, 2)); a dot whose centroid could not be
    measured (``ok``), whose Jacobian is singular or whose shift exceeds ``sqrt(max_shift2)``
    keeps ``xy``. Element by element as the numpy version.
    """
    n = len(xy)
    out = xy.copy()
    for i in range(n):
        jx0, jx1 = m[i, 1, 0] - m[i, 2, 0], m[i, 1, 1] - m[i, 2, 1]
        jy0, jy1 = m[i, 3, 0] - m[i, 4, 0], m[i, 3, 1] - m[i, 4, 1]
        det = jx0 * jy1 - jy0 * jx1
        if not (ok[i] and abs(det) > 1e-6):
            continue
        du, dv = c[i, 0] - m[i, 0, 0], c[i, 1] - m[i, 0, 1]
        g0 = (jy1 * du - jy0 * dv) / det
        g1 = (jx0 * dv - jx1 * du) / det
        if g0 * g0 + g1 * g1 <= max_shift2:
            out[i, 0] = xy[i, 0] + g0
            out[i, 1] = xy[i, 1] + g1
    return out


@numba.njit(cache=True)
def gauss_centroids(image, uv, background, half, sigma, iters):
    """Compute iterated Gaussian-weighted centroids in the mirror image.

    Iterated Gaussian-weighted centroids (:func:`stcvision.stages.mirror_centroids`): around
    each (u, v) of ``uv`` ((n, 2) float), over the square of half-side ``half + 1`` about its
    nearest pixel, the centroid of ``max(image - background, 0)`` weighted by a Gaussian of
    ``sigma`` centred on the current estimate, ``iters`` times. Returns the centroids ((n, 2))
    and whether each could be measured (square inside the image, some signal).
    """
    h, w = image.shape
    n = len(uv)
    out = uv.copy()
    ok = np.zeros(n, np.bool_)
    r = half + 1
    k = -0.5 / (sigma * sigma)
    wx = np.empty(2 * r + 1)
    for i in range(n):
        u0, v0 = int(np.rint(uv[i, 0])), int(np.rint(uv[i, 1]))
        if u0 < r or v0 < r or u0 >= w - r or v0 >= h - r:
            continue
        cu, cv = uv[i, 0], uv[i, 1]
        good = True
        for _ in range(iters):
            for a in range(2 * r + 1):
                wx[a] = math.exp(k * (u0 - r + a - cu) ** 2)
            s = 0.0
            su = 0.0
            sv = 0.0
            for y in range(v0 - r, v0 + r + 1):
                wy = math.exp(k * (y - cv) ** 2)
                for a in range(2 * r + 1):
                    val = image[y, u0 - r + a] - background
                    if val > 0:
                        wgt = val * wy * wx[a]
                        s += wgt
                        su += wgt * (u0 - r + a)
                        sv += wgt * y
            if s <= 0:
                good = False
                break
            cu, cv = su / s, sv / s
        if good:
            out[i, 0] = cu
            out[i, 1] = cv
            ok[i] = True
    return out, ok
