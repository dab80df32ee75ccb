"""The faint-row search: marks whose dots have faded below the single-dot threshold.

They are found as rows of dots at the LEDs' spacing (a matched filter), through a found dot or
where none was.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import cv2
import numba
import numpy as np

from stcvision.stages.common import SUM_DTYPES, noise_floor
from stcvision.stages.compiled import fma32, grow_array, marked_positions, row_flags
from stcvision.stages.dots import DotParams, Dots, window_centroids

#: the dot search's defaults, for a caller of :func:`find_rows` that gives none
_DOT_DEFAULTS = DotParams()


@dataclass(frozen=True, kw_only=True, slots=True)
class RowParams:
    """Parameters of the faint-row search.

    Faint-row search: a mark is a row of ``n_dots`` UV dots ``spacing_m`` apart (the robot's
    rear LEDs; ``stcvision.sim_camera.phosphor.LED_OFFSETS_M``: 4 LEDs 3 cm apart) parallel to a grid axis.
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
    dot_params: DotParams = _DOT_DEFAULTS,
    ground_to_robot=None,
    quantum: float = 1.0,
    buffers=None,
) -> Dots:
    """Find rows of ``params.n_dots`` faint dots that the dot search missed.

    The rows run along either ground-view axis.

    Two searches. *Anchored rows*: a fading mark's brightest dot often passes the dot threshold
    while its other three do not (each dot's SNR scatters by +-1 about the mark's), and a row
    may not run through a found dot. So each found dot that stands alone (no other lit dot
    within 1.5 spacings, none at the row's other places or one spacing beyond its ends) is
    tried as one dot of a row: 4 places x 2 axes, 8 hypotheses, where the free search tries
    every pixel; with so few trials the other three need less (``anchor_min_snr`` each,
    ``anchor_mean_snr`` on average). *Free rows*: where the dot search found nothing, a
    matched filter.

    Parameters
    ----------
    marks : numpy.ndarray
        The window sums the dot search ran on (a plain uint8 image is returned unsearched).
    dots : Dots
        The dot search's result.
    gain : numpy.ndarray
        The :func:`noise_gain` map, as for :func:`find_dots`.
    background_dn, noise_dn : float
        Background level and raw per-pixel noise.
    px_per_m : float
        The ground view's scale (the rows' spacing is in metres).
    window_px : int
        The window sums' side.
    params : RowParams
        The row's dots, spacing and thresholds (``enabled=False``: no search).
    dot_params : DotParams
        The dot search's parameters (its threshold bounds the rows' dots).
    ground_to_robot : callable, optional
        (N, 2) px -> (N, 2) m (``Profile.ground_to_robot``).
    quantum : float
        As for :func:`find_dots`.
    buffers : callable, optional
        ``buffers(name, shape, dtype)`` gives the search's scratch images (a caller reusing
        them from frame to frame: the pipeline), default new ones.

    Returns
    -------
    Dots
        ``dots`` with the rows' dots appended (``lit=True``, ``from_row=True``, ``snr`` the
        row's SNR).
    """
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
    """Return the offsets of a row's dots and of the floor beyond its ends, in whole pixels.

    (offsets of a row's ``n`` dots from its centre, of the floor one spacing beyond either
    end, the larger reach) in whole pixels for a dot spacing of ``step`` px: the same for every
    frame of a profile, so made once (read-only arrays).
    """
    offs = np.round((np.arange(n) - (n - 1) / 2) * step).astype(np.int64)
    # one spacing beyond either end: a row shifted along a real one by a dot has a dot there
    ends = np.round(np.array([-1, 1]) * ((n + 1) / 2) * step).astype(np.int64)
    offs.setflags(write=False)
    ends.setflags(write=False)
    return offs, ends, int(np.abs(ends).max())


def _row_snr(
    marks: np.ndarray, gain: np.ndarray, area: int, background_dn: float, noise_dn: float, clip: float, out: np.ndarray
):
    """Compute the per-pixel SNR of the window sums, clipped at the dot threshold.

    Per-pixel SNR of the window sums ``marks`` (float32), clipped at the dot threshold
    ``clip``: a single bright dot must not make a row. One compiled pass
    (:func:`row_snr`) for uint16 sums; float32 ones (16-bit frames) through OpenCV.
    """
    if marks.dtype == np.uint16 and gain.dtype == np.float32:
        return row_snr(marks, gain, area, float(background_dn), float(noise_dn), float(clip), out)
    z = cv2.addWeighted(marks, 1.0 / area, marks, 0.0, -background_dn, dtype=cv2.CV_32F)
    z = cv2.divide(z, gain, scale=1.0 / noise_dn)
    return cv2.min(z, float(clip), dst=z)


@numba.njit(cache=True, error_model="numpy")
def row_snr(marks, gain, area, background, noise, clip, out):
    """Compute the per-pixel SNR of window sums, clipped, in one pass.

    Per-pixel SNR of window sums, clipped (:func:`_row_snr`), in one pass:
    ``min(fma(marks, 1 / area, -background) * (1 / noise) / gain, clip)`` in float32
    (:func:`stcvision.stages.compiled._fma32`), the arithmetic of ``cv2.addWeighted(...,
    dtype=CV_32F)``, ``cv2.divide(..., scale)`` and ``cv2.min`` it replaced (to the bit; numpy's
    error model: no zero-division check per pixel, which would keep the loop from being
    vectorised). Into ``out`` ((h, w) float32), returned.
    """
    h, w = marks.shape
    a = np.float32(1.0 / area)
    g = np.float32(-background)
    s = np.float32(1.0 / noise)
    c = np.float32(clip)
    for y in range(h):
        mr, gr, o = marks[y], gain[y], out[y]
        for x in range(w):
            v = fma32(np.float32(mr[x]), a, g) * s / gr[x]
            o[x] = v if v < c else c
    return out


def _taken_floor(marks: np.ndarray, dots: Dots, dot_params: DotParams, out: np.ndarray) -> np.ndarray:
    """Mark the floor where no row may run nor end.

    uint8 image, non-zero where no row may run nor end: within each lit dot's blur (as far as
    it still shows above 1 sigma, at least the black-out square), and within the black-out
    square of a red light blacked out of the marks image (zero there): the edge of its glare,
    just below the black-out level, runs along the light as a column of faint "dots".
    """
    b = dot_params.blackout_px
    occ = zero_ring(marks, b, out)
    blur_squares(occ, dots.xy_px.reshape(-1, 2), dots.snr, dots.lit, float(dot_params.tail_sigma_px), b)
    return occ


@numba.njit(cache=True)
def zero_ring(marks, b, out):
    """Mark the pixels near a zero of the marks image.

    uint8 image: 1 within ``b`` pixels (along both axes) of a pixel where ``marks`` is 0 --
    ``cv2.dilate(marks == 0, (2b+1)^2 square)``, pixels beyond the border not counted. Zeros
    are few (the red lights' black-out), so: a vectorised scan finds the rows holding any;
    each such row's zeros are grown along it into a row buffer, which is OR-ed into the
    2b + 1 output rows about it (earlier: two OR-doubling passes over a padded copy of the
    whole image: 31 us here for the bench scene's lights; this 22 us).
    """
    h, w = marks.shape
    out[:] = 0  # out: (h, w) uint8, returned
    row = np.zeros(w, np.uint8)
    for y in range(h):
        mr = marks[y]
        nz = 0
        for x in range(w):  # any zero in the row (branch-free: vectorised)
            nz += mr[x] == 0
        if nz == 0:
            continue
        row[:] = 0
        for x in range(w):
            if mr[x] == 0:
                for xx in range(max(x - b, 0), min(x + b + 1, w)):
                    row[xx] = 1
        for yy in range(max(y - b, 0), min(y + b + 1, h)):
            o = out[yy]
            for x in range(w):
                o[x] |= row[x]
    return out


@numba.njit(cache=True)
def blur_squares(img, xy, snr, lit, tail_sigma, b):
    """Mark the square about each lit dot as far as its blur shows.

    Set to 1 in ``img`` (uint8) the square about each lit dot (its position rounded half to
    even, clipped to the image) as far as its blur still shows above 1 sigma:
    half-side ``max(ceil(tail_sigma sqrt(2 ln max(snr, 1))) + 1, b)``
    (:func:`_taken_floor`).
    """
    h, w = img.shape
    for i in range(len(xy)):
        if not lit[i]:
            continue
        r = max(np.ceil(tail_sigma * np.sqrt(2 * np.log(max(snr[i], 1.0)))) + 1, b)
        half = np.int64(r)
        x = min(max(np.int64(np.round(xy[i, 0])), 0), w - 1)
        y = min(max(np.int64(np.round(xy[i, 1])), 0), h - 1)
        for yy in range(max(y - half, 0), min(y + half + 1, h)):
            for xx in range(max(x - half, 0), min(x + half + 1, w)):
                img[yy, xx] = 1


def _anchored_rows(z, occ, dots: Dots, step: float, n: int, params: RowParams):
    """Find rows through one found dot.

    Rows through one found dot (:func:`find_rows`): the added points ((R, n - 1, 2) float
    ground px) and the rows' SNRs (R,). ``z``: per-pixel SNR clipped at the dot threshold, before
    the black-out; ``occ``: the lit dots' blur masks; ``step``: the dot spacing (px).
    """
    xy_lit = np.ascontiguousarray(dots.xy_px[dots.lit].reshape(-1, 2), np.float64)
    if not len(xy_lit):
        return np.zeros((0, n - 1, 2)), np.zeros(0)
    snr = np.ascontiguousarray(dots.snr[dots.lit], np.float64)
    near = 1.5 * step
    # lone dots only: no other lit dot within 1.5 spacings (else it is a dot of a row found
    # already, which reads as a mark with one lit neighbour), at most anchor_max_snr, the row's
    # reach inside the image
    if len(xy_lit) <= 256:
        crowded = crowded_dots(xy_lit, near)
    else:  # more dots than a frame is read for: neighbours by a k-d tree, not all pairs
        from scipy.spatial import cKDTree  # only here: its import costs a command ~0.25 s

        pairs = cKDTree(xy_lit).query_pairs(near * (1 + 1e-9), output_type="ndarray")
        d2 = ((xy_lit[pairs[:, 0]] - xy_lit[pairs[:, 1]]) ** 2).sum(axis=1)
        crowded = np.zeros(len(xy_lit), bool)
        crowded[pairs[d2 <= near * near].reshape(-1)] = True
    # each lone dot: 4 places x 2 axes; at each of the row's other places and one spacing beyond
    # either end the best of the three pixels across the row (a lean of a degree or two); a row
    # with another lit dot on it or next to it (occ) is not tried, and the best passing one is
    # kept unless it comes within 2 px of a row kept already (anchored_rows)
    return anchored_rows(
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


@numba.njit(cache=True)
def crowded_dots(xy, near):
    """Tell, per point, whether another point lies within ``near``.

    Per point: another point within ``near`` (all pairs: for the few hundred lit dots a frame
    holds at most, ``DotParams.max_dots``; :func:`_anchored_rows` uses a k-d
    tree beyond that).
    """
    n = len(xy)
    out = np.zeros(n, np.bool_)
    lim = near * near
    for i in range(n):
        for j in range(i + 1, n):
            dx = xy[i, 0] - xy[j, 0]
            dy = xy[i, 1] - xy[j, 1]
            if dx**2 + dy**2 <= lim:
                out[i] = True
                out[j] = True
    return out


@numba.njit(cache=True)
def anchored_rows(z, occ, xy, snr, crowded, max_snr, reach, step, n, min_snr, mean_snr, end_max, k_sigma):
    """Find the rows through lone found dots.

    Rows through one lone found dot (:func:`_anchored_rows`): for each lone
    dot (not ``crowded``, SNR at most ``max_snr``, ``reach`` inside the image), the best of its
    ``2 n`` row hypotheses; a row within 2 px of an accepted one is skipped. Returns the
    accepted rows' points ((R, n - 1, 2) float) and SNRs (R,).
    """
    h, w = z.shape
    lone = np.empty(len(xy), np.bool_)
    for i in range(len(xy)):
        lone[i] = (
            not crowded[i]
            and snr[i] <= max_snr
            and xy[i, 0] >= reach
            and xy[i, 0] < w - reach
            and xy[i, 1] >= reach
            and xy[i, 1] < h - reach
        )
    taken = np.zeros(z.shape, np.uint8)
    out_pts = np.empty((len(xy), n - 1, 2))
    out_s = np.empty(len(xy))
    m = 0
    px = np.empty(n + 1, np.int64)
    py = np.empty(n + 1, np.int64)
    best_x = np.empty(n - 1, np.int64)
    best_y = np.empty(n - 1, np.int64)
    for i in range(len(xy)):
        if not lone[i]:
            continue
        xf, yf = xy[i, 0], xy[i, 1]
        found = False
        best = 0.0
        for axis in range(2):
            ux, uy = (0.0, 1.0) if axis else (1.0, 0.0)
            for k in range(n):
                # the other dots, then one spacing beyond either end, from the anchor's centroid
                c = 0
                for j in range(n):
                    if j != k:
                        px[c] = round(xf + ((j - k) * ux) * step)
                        py[c] = round(yf + ((j - k) * uy) * step)
                        c += 1
                for place in (-1 - k, n - k):
                    px[c] = round(xf + (place * ux) * step)
                    py[c] = round(yf + (place * uy) * step)
                    c += 1
                if _taken(occ, px, py):
                    continue
                total = 0.0
                low = np.inf
                ends = -np.inf
                for c in range(n + 1):
                    v = -np.inf  # the best of the three pixels across the row
                    for d in (-1, 0, 1):
                        zz = z[py[c], px[c] + d] if axis else z[py[c] + d, px[c]]
                        v = max(v, float(zz))
                    if c < n - 1:
                        total += v
                        low = min(low, v)
                    else:
                        ends = max(ends, v)
                if low >= min_snr and total >= (n - 1) * mean_snr and ends < end_max and (not found or total > best):
                    found = True
                    best = total
                    best_x[:] = px[: n - 1]
                    best_y[:] = py[: n - 1]
        if not found or _taken(taken, best_x, best_y):
            continue
        for c in range(n - 1):
            y0, x0 = max(best_y[c] - 2, 0), max(best_x[c] - 2, 0)
            taken[y0 : best_y[c] + 3, x0 : best_x[c] + 3] = 1
            out_pts[m, c, 0] = best_x[c]
            out_pts[m, c, 1] = best_y[c]
        out_s[m] = (best + min(snr[i], k_sigma)) / n
        m += 1
    return out_pts[:m], out_s[:m]


@numba.njit(cache=True)
def _taken(img, px, py):
    for i in range(len(px)):
        if img[py[i], px[i]]:
            return True
    return False


def _free_rows(
    z: np.ndarray, occ: np.ndarray, offs: np.ndarray, ends: np.ndarray, e: int, params: RowParams, ok: np.ndarray
):
    """Find the free-row candidates.

    Free-row candidates of :func:`find_rows`: (x, y, row SNR, axis) where the row sum of the
    SNRs ``z`` at ``offs`` along either axis reaches ``k_sigma * sqrt(n)``, every dot is at least
    ``min_dot_snr`` and within ``spread_snr`` of the row's mean, and the floor at ``ends`` is
    free (``occ`` 0) and below ``end_max_snr``; no dot on a taken pixel. Axis 0 (rows along x)
    first, each in row-major order.

    Those tests together need every dot of the row at or above ``max(min_dot_snr, mean -
    spread_snr)`` with the mean at least ``k_sigma / sqrt(n)``: that bound prunes almost every
    pixel after a dot or two, and only where all dots pass are the row sums and the rest
    computed, in one compiled pass per axis (:func:`free_rows`; earlier about twenty
    OpenCV passes over shifted masks, then numpy on the few pixels left: the same rows).
    """
    n = len(offs)
    gate = max(params.min_dot_snr, params.k_sigma / math.sqrt(n) - params.spread_snr) - 1e-3
    return free_rows(
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


@numba.njit(cache=True, error_model="numpy")
def free_rows(z, occ, offs, ends, e, gate, thr, min_dot, spread, end_max, ok):
    """Find the free-row candidates in compiled passes.

    Free-row candidates of :func:`_free_rows`: where every dot of the row
    at ``offs`` (along x for axis 0, along y for axis 1) has ``z >= gate`` on a free pixel
    (``occ`` 0) -- a mask, then per image row the AND of its shifted rows, both loops the
    compiler vectorises, scanned eight pixels at a time -- the float32 row sum (added dot by
    dot, in ``offs`` order), its least dot and mean pass (``sum >= thr``, ``low >= min_dot``,
    ``low >= mean - spread``) and the floor at ``ends`` is free and below ``end_max``. All
    comparisons in float32, as numpy makes them against Python floats. Returns (xs, ys, row SNR
    = sum / sqrt(n), axis) over the interior (``e`` from the border): axis 0 first, each in
    row-major order.
    """
    h, w = z.shape
    n = len(offs)
    g = np.float32(gate)
    t32 = np.float32(thr)
    md = np.float32(min_dot)
    sp = np.float32(spread)
    em = np.float32(end_max)
    nf = np.float32(n)
    sq = np.float32(math.sqrt(n))  # ok: (h, w) uint8 scratch
    for y in range(h):
        zr, orow, okr = z[y], occ[y], ok[y]
        for x in range(w):
            okr[x] = (zr[x] >= g) & (orow[x] == 0)
    nx = w - 2 * e
    acc, words, idx = row_flags(nx)
    xs = np.empty(256, np.int64)
    ys = np.empty(256, np.int64)
    st = np.empty(256, np.float32)
    ax = np.empty(256, np.int64)
    m = 0
    zf, of = z.ravel(), occ.ravel()
    for axis in range(2):
        stride = w if axis else 1
        for y in range(e, h - e):
            acc[:nx] = 1
            for o in offs:  # the row's dots as shifted views: indices the compiler can vectorise
                src = ok[y + o, e : w - e] if axis else ok[y, e + o : w - e + o]
                for i in range(nx):
                    acc[i] &= src[i]
            for t in range(marked_positions(acc, words, idx)):
                i = idx[t]
                base = y * w + e + i  # flat index of (x, y); the row's dots stride apart
                total = zf[base + offs[0] * stride]
                low = total
                for c in range(1, n):
                    v = zf[base + offs[c] * stride]
                    total += v
                    low = min(low, v)
                if not (total >= t32 and low >= md and low >= total / nf - sp):
                    continue
                free = True
                for o in ends:
                    p = base + o * stride
                    free &= zf[p] < em and of[p] == 0
                if not free:
                    continue
                if m == len(xs):
                    xs, ys, st, ax = grow_array(xs, m), grow_array(ys, m), grow_array(st, m), grow_array(ax, m)
                xs[m] = e + i
                ys[m] = y
                st[m] = total / sq
                ax[m] = axis
                m += 1
    return xs[:m], ys[:m], st[:m], ax[:m]


def _accept_free_rows(shape, xs, ys, st, ax, offs, rows_xy: np.ndarray, b: int, max_rows: int):
    """Accept the free rows strongest first, after the anchored rows.

    The free rows accepted strongest first, after the anchored rows ``rows_xy`` ((R, n - 1,
    2)): a row may not share a dot with one already accepted (within ``b`` along both axes;
    :func:`accept_rows`), at most ``max_rows`` rows in all. Returns their points ((A,
    n, 2) float) and SNRs (A,), in the order accepted.
    """
    if not len(xs):
        return np.zeros((0, len(offs), 2)), np.zeros(0, np.float32)
    return accept_free_rows(shape, rows_xy, xs, ys, st, ax, offs, b, max_rows - len(rows_xy))


@numba.njit(cache=True)
def accept_free_rows(shape, rows_xy, xs, ys, st, axis, offs, half, room):
    """Accept the free rows strongest first (the compiled loop).

    The free rows of :func:`_accept_free_rows`, strongest first (stable):
    the anchored rows' dots ``rows_xy`` ((R, n - 1, 2)) and each accepted row's dots grown by
    ``half`` are taken, a row with a dot on a taken pixel is skipped, at most ``room`` rows
    (:func:`accept_rows`). Returns the accepted rows' points ((A, n, 2) float) and SNRs (A,).
    """
    taken = np.zeros(shape, np.uint8)
    h, w = shape
    for r in range(rows_xy.shape[0]):
        for c in range(rows_xy.shape[1]):
            x, y = np.int64(rows_xy[r, c, 0]), np.int64(rows_xy[r, c, 1])
            taken[max(y - half, 0) : min(y + half + 1, h), max(x - half, 0) : min(x + half + 1, w)] = 1
    order = np.argsort(-st, kind="mergesort")
    acc = accept_rows(taken, xs, ys, axis, order, offs, half, room)
    n = len(offs)
    pts = np.empty((len(acc), n, 2))
    s = np.empty(len(acc), st.dtype)
    for k in range(len(acc)):
        i = acc[k]
        for c in range(n):
            pts[k, c, 0] = xs[i] if axis[i] else xs[i] + offs[c]
            pts[k, c, 1] = ys[i] + offs[c] if axis[i] else ys[i]
        s[k] = st[i]
    return pts, s


@numba.njit(cache=True)
def accept_rows(taken, xs, ys, axis, order, offs, half, room):
    """Accept free rows strongest first, skipping those on taken pixels.

    Free rows strongest first (:func:`stcvision.stages.find_rows`): a row whose dots fall in
    ``taken`` (the accepted rows' dots grown by ``half``) is skipped; at most ``room`` rows.
    Returns the indices of the accepted candidates.
    """
    out = np.empty(min(len(order), max(room, 0)), np.int64)
    m = 0
    n = len(offs)
    px = np.empty(n, np.int64)
    py = np.empty(n, np.int64)
    h, w = taken.shape
    for i in order:
        if m >= room:
            break
        for c in range(n):
            px[c] = xs[i] if axis[i] else xs[i] + offs[c]
            py[c] = ys[i] + offs[c] if axis[i] else ys[i]
        if _taken(taken, px, py):
            continue
        for c in range(n):
            taken[max(py[c] - half, 0) : min(py[c] + half + 1, h), max(px[c] - half, 0) : min(px[c] + half + 1, w)] = 1
        out[m] = i
        m += 1
    return out[:m]


def _with_rows(dots, marks, z, gain, pts, snr, area, background_dn, noise_dn, dot_params, ground_to_robot):
    """Append the rows' dots to the found dots.

    ``dots`` with the rows' dots at ``pts`` (SNR ``snr``) appended: centroids as
    :func:`find_dots` takes them, strength the window mean above background, ``lit`` and
    ``from_row`` set.
    """
    # centroids and strengths at the rows' pixels (row_dots: one call)
    xy, strength = row_dots(marks, z, gain, pts, dot_params.centroid_px, float(background_dn * area), noise_dn)
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


@numba.njit(cache=True)
def row_dots(marks, z, gain, pts, r, per_px, noise):
    """Measure the rows' dots: pixels, centroids and strengths.

    The rows' dots of :func:`_with_rows` at ``pts`` ((n, 2) float): their
    pixels (rounded half to even), :func:`window_centroids` there, and their strength
    ``z * gain * noise`` at those pixels in float32 (numpy's arithmetic for float32 images
    and a Python scalar). Returns (xy (n, 2), strength (n,) float32).
    """
    n = len(pts)
    xs = np.empty(n, np.int64)
    ys = np.empty(n, np.int64)
    strength = np.empty(n, np.float32)
    nz = np.float32(noise)
    for i in range(n):
        xs[i] = int(np.rint(pts[i, 0]))
        ys[i] = int(np.rint(pts[i, 1]))
        strength[i] = np.float32(z[ys[i], xs[i]] * gain[ys[i], xs[i]]) * nz
    return window_centroids(marks, xs, ys, r, per_px), strength
