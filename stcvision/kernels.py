"""The stages' per-candidate loops, compiled by numba (``cache=True``: compiled once per machine).

Each kernel is the loop of a stage in :mod:`stcvision.stages` or :mod:`stcvision.observation`
that numpy cannot vectorise (a greedy choice, strongest first, where each choice depends on the
earlier ones), or a chain of OpenCV / numpy passes fused into one (issue 18: each pass over the
view, each call on a small array, costs microseconds), written out element by element in the
stage's own arithmetic order, so its results are those of the numpy/OpenCV version it replaced,
bit for bit (the pipeline's outputs on 480-800 dataset frames were compared). Image loops index
views from 0 up or use numpy's error model so the compiler can vectorise them. The stages
document what the loops mean; here is only how.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

__all__ = [
    "accept_free_rows",
    "accept_rows",
    "anchored_rows",
    "assign_boxes",
    "blur_squares",
    "box3_pair",
    "blobs",
    "box_counts",
    "cell_dots",
    "crowded",
    "dot_candidates",
    "free_rows",
    "gauss_centroids",
    "greedy_black_out",
    "group_stats",
    "heading_row",
    "histogram_quartiles",
    "homography",
    "landing_counts",
    "map_at",
    "mark_offset",
    "mirror_shift",
    "nonzero_mask",
    "rotate_about",
    "rank_dots",
    "row_dots",
    "row_orientation",
    "row_snr",
    "sample_quartiles",
    "tls_line",
    "unwarp_border",
    "unwarp_separate_f32",
    "unwarp_separate_u16",
    "window_centroids",
    "zero_ring",
    "zero_where",
]


@numba.njit(cache=True)
def blur_squares(img, xy, snr, lit, tail_sigma, b):
    """Set to 1 in ``img`` (uint8) the square about each lit dot (its position rounded half to
    even, clipped to the image) as far as its blur still shows above 1 sigma:
    half-side ``max(ceil(tail_sigma sqrt(2 ln max(snr, 1))) + 1, b)``
    (:func:`stcvision.stages._taken_floor`)."""
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


@numba.njit(cache=True)
def _taken(img, px, py):
    for i in range(len(px)):
        if img[py[i], px[i]]:
            return True
    return False


@numba.njit(inline="always")
def _grow(a, m):
    """``a`` (1-D) with room for twice ``m`` entries, its first ``m`` kept."""
    out = np.empty(2 * m, a.dtype)
    out[:m] = a[:m]
    return out


@numba.njit(inline="always")
def _row_flags(nx):
    """A zeroed byte per pixel of an image row of ``nx`` pixels (padded to whole uint64
    words), its uint64 view, and room for the positions :func:`_marked` finds."""
    flag = np.zeros((nx + 7) // 8 * 8, np.uint8)
    return flag, flag.view(np.uint64), np.empty(len(flag), np.int64)


@numba.njit(inline="always")
def _marked(flag, words, out):
    """Positions of the non-zero bytes of ``flag`` into ``out`` (scanned eight at a time:
    ``words`` is its uint64 view); returns how many."""
    m = 0
    for k in range(len(words)):
        if words[k] == 0:
            continue
        for i in range(8 * k, 8 * k + 8):
            if flag[i]:
                out[m] = i
                m += 1
    return m


@numba.njit(cache=True)
def dot_candidates(sums, gain, mode, a, c, e, area, background, noise):
    """Candidates of :func:`stcvision.stages.find_dots` in one pass over the window sums: the
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
    only those marked, eight at a time skipped where none is, are tested exactly."""
    h, w = sums.shape
    nx = w - 2 * e
    flag, words, idx = _row_flags(nx)
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
        for t in range(_marked(flag, words, idx)):
            i = idx[t]
            s = c0[i]
            if mode == 0:
                lv = np.rint(_fma32(gain[y, e + i], fa, fc))
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
                xs, ys = _grow(xs, m), _grow(ys, m)
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
    """The black-out of :func:`stcvision.stages.find_dots` (plateaus and chains of maxima that the
    3x3 maximum left) as one greedy loop over candidates
    sorted strongest first: candidate k is kept unless a kept one j has it in its black-out
    square (``|dx|, |dy| <= b``) or its blur explains half of it (``vals[j] exp(-d^2 / (2
    tail_sigma^2)) >= vals[k] / 2``). Each candidate is checked against the kept ones only
    (at most ``max_dots``), so no pair search is needed. Indices of the kept candidates."""
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
    """numpy's pairwise sum of ``a[:n]`` (n < 128: eight interleaved partial sums, then the
    rest in order; below eight, in order), in ``a``'s dtype: the order ``ndarray.sum`` adds a
    small contiguous block in, so the result is numpy's to the bit."""
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
    """Intensity-weighted centroids (:func:`stcvision.stages.find_dots`): over the (2r+1)^2 square about each
    (xs, ys) (coordinates clipped to the image), the float32 values ``max(marks - per_px, 0)``
    and their x- and y-weighted sums (float64), each summed as numpy sums the square; the
    integer position where the square holds nothing above ``per_px``."""
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
    """The rest of :func:`stcvision.stages.find_dots` after the candidates, in one call: the
    candidates sorted strongest first (a stable sort, as numpy's ``kind="stable"``), the
    strongest ``max_candidates`` kept, :func:`greedy_black_out`, then :func:`window_centroids`
    of those kept. Returns (number of candidates, centroids (n, 2), SNRs (n,) float64, window
    means (n,))."""
    nc = len(vals)
    if nc == 0:
        return 0, np.zeros((0, 2)), np.zeros(0), mean[:0]
    order = np.argsort(-vals, kind="mergesort")[:max_candidates]
    xs, ys, vals, mean = xs[order], ys[order], vals[order], mean[order]
    kept = greedy_black_out(xs, ys, vals, b, tail_sigma, max_dots)
    xy = window_centroids(marks, xs[kept], ys[kept], r, per_px)
    return nc, xy, vals[kept].astype(np.float64), mean[kept]


@numba.njit(cache=True)
def row_dots(marks, z, gain, pts, r, per_px, noise):
    """The rows' dots of :func:`stcvision.stages._with_rows` at ``pts`` ((n, 2) float): their
    pixels (rounded half to even), :func:`window_centroids` there, and their strength
    ``z * gain * noise`` at those pixels in float32 (numpy's arithmetic for float32 images
    and a Python scalar). Returns (xy (n, 2), strength (n,) float32)."""
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


@numba.njit(cache=True, error_model="numpy")
def row_snr(marks, gain, area, background, noise, clip, out):
    """Per-pixel SNR of window sums, clipped (:func:`stcvision.stages._row_snr`), in one pass:
    ``min(fma(marks, 1 / area, -background) * (1 / noise) / gain, clip)`` in float32 (``_fma32``
    below, with the front end's kernels), the
    arithmetic of ``cv2.addWeighted(..., dtype=CV_32F)``, ``cv2.divide(..., scale)`` and
    ``cv2.min`` it replaced (to the bit; numpy's error model: no zero-division check per pixel,
    which would keep the loop from being vectorised). Into ``out`` ((h, w) float32), returned."""
    h, w = marks.shape
    a = np.float32(1.0 / area)
    g = np.float32(-background)
    s = np.float32(1.0 / noise)
    c = np.float32(clip)
    for y in range(h):
        mr, gr, o = marks[y], gain[y], out[y]
        for x in range(w):
            v = _fma32(np.float32(mr[x]), a, g) * s / gr[x]
            o[x] = v if v < c else c
    return out


@numba.njit(cache=True)
def zero_ring(marks, b, out):
    """uint8 image: 1 within ``b`` pixels (along both axes) of a pixel where ``marks`` is 0 --
    ``cv2.dilate(marks == 0, (2b+1)^2 square)``, pixels beyond the border not counted. Zeros
    are few (the red lights' black-out), so: a vectorised scan finds the rows holding any;
    each such row's zeros are grown along it into a row buffer, which is OR-ed into the
    2b + 1 output rows about it (earlier: two OR-doubling passes over a padded copy of the
    whole image: 31 us here for the bench scene's lights; this 22 us)."""
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


@numba.njit(cache=True, error_model="numpy")
def free_rows(z, occ, offs, ends, e, gate, thr, min_dot, spread, end_max, ok):
    """Free-row candidates of :func:`stcvision.stages._free_rows`: where every dot of the row
    at ``offs`` (along x for axis 0, along y for axis 1) has ``z >= gate`` on a free pixel
    (``occ`` 0) -- a mask, then per image row the AND of its shifted rows, both loops the
    compiler vectorises, scanned eight pixels at a time -- the float32 row sum (added dot by
    dot, in ``offs`` order), its least dot and mean pass (``sum >= thr``, ``low >= min_dot``,
    ``low >= mean - spread``) and the floor at ``ends`` is free and below ``end_max``. All
    comparisons in float32, as numpy makes them against Python floats. Returns (xs, ys, row SNR
    = sum / sqrt(n), axis) over the interior (``e`` from the border): axis 0 first, each in
    row-major order."""
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
    acc, words, idx = _row_flags(nx)
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
            for t in range(_marked(acc, words, idx)):
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
                    xs, ys, st, ax = _grow(xs, m), _grow(ys, m), _grow(st, m), _grow(ax, m)
                xs[m] = e + i
                ys[m] = y
                st[m] = total / sq
                ax[m] = axis
                m += 1
    return xs[:m], ys[:m], st[:m], ax[:m]


@numba.njit(cache=True)
def map_at(map_x, map_y, xy, steps, border):
    """The unwarp map (``map_x``, ``map_y``: (S, S) float32) read at each ground-view point
    ``xy[i]`` plus each of ``steps`` ((K, 2); the points rounded to float32 after the add):
    (N, K, 2) float64 mirror-image positions, as ``cv2.remap`` of each map (``INTER_LINEAR``,
    ``BORDER_CONSTANT`` ``border``) at those points computes them (:func:`_lerp`), in one pass
    instead of two OpenCV calls and the arrays around them."""
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
                out[i, j, c] = _lerp(aa, bb, p00, p01, p10, p11)
    return out


@numba.njit(cache=True, error_model="numpy")
def mirror_shift(m, c, ok, xy, max_shift2):
    """The ground-view positions of :func:`stcvision.stages.mirror_centroids`: per dot, the
    mirror-image centroid ``c`` taken back through the unwarp map's local Jacobian (``m``: the
    map at the dot and +-0.5 px in x and y, (n, 5, 2)); a dot whose centroid could not be
    measured (``ok``), whose Jacobian is singular or whose shift exceeds ``sqrt(max_shift2)``
    keeps ``xy``. Element by element as the numpy version."""
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


@numba.njit(cache=True, error_model="numpy")
def heading_row(xy, s, n_dots, radius, max_residual):
    """The dots :func:`stcvision.stages.fit_heading` fits, among lit dots at ``xy`` (robot
    frame, m) of strengths ``s``: the brightest, and of the lines from it to each neighbour
    within ``radius`` the one most neighbours lie on (within ``max_residual``; then the
    brightest in sum; then the first), its ``n_dots`` brightest dots (stable order). Returns
    (status, value, picks): status 0 with the picked indices; 1 with the neighbours' count
    (too few); 2 (no row of ``n_dots``)."""
    first = 0
    for i in range(1, len(s)):
        if s[i] > s[first]:
            first = i
    fx, fy = xy[first, 0], xy[first, 1]
    near = np.empty(len(s), np.int64)
    k = 0
    for i in range(len(s)):
        if np.hypot(xy[i, 0] - fx, xy[i, 1] - fy) <= radius:
            near[k] = i
            k += 1
    near = near[:k]
    if k < n_dots:
        return 1, k, np.zeros(0, np.int64)
    best_c, best_count, best_total = -1, -1, -np.inf
    for ci in range(k):
        j = near[ci]
        if j == first:
            continue
        rx, ry = xy[j, 0] - fx, xy[j, 1] - fy
        norm = np.hypot(rx, ry)
        dx, dy = rx / norm, ry / norm
        count = 0
        total = 0.0
        for t in range(k):  # the neighbours on this line, in order
            i = near[t]
            if abs((xy[i, 0] - fx) * -dy + (xy[i, 1] - fy) * dx) <= max_residual:
                total = s[i] if count == 0 else total + s[i]
                count += 1
        if count > best_count or (count == best_count and total > best_total):
            best_c, best_count, best_total = ci, count, total
    j = near[best_c]
    rx, ry = xy[j, 0] - fx, xy[j, 1] - fy
    norm = np.hypot(rx, ry)
    dx, dy = rx / norm, ry / norm
    row = np.empty(k, np.int64)
    m = 0
    for t in range(k):
        i = near[t]
        if abs((xy[i, 0] - fx) * -dy + (xy[i, 1] - fy) * dx) <= max_residual:
            row[m] = i
            m += 1
    if m < n_dots:
        return 2, m, np.zeros(0, np.int64)
    row = row[:m]
    order = np.argsort(-s[row], kind="mergesort")
    return 0, m, row[order[:n_dots]]


@numba.njit(cache=True)
def tls_line(pts):
    """Total-least-squares line through the points ``pts`` ((n, 2), n >= 2): (angle of its
    direction in (-pi/2, pi/2], RMS spread along it, RMS distance from it), in closed form --
    the principal axis of the points' 2 x 2 scatter matrix, and the RMS of the centred points'
    projections on it and across it: the singular values :func:`numpy.linalg.svd` of the
    centred points gave, divided by sqrt(n), without the LAPACK call and its wrapper (which
    cost ~40 us a frame in the pipeline here)."""
    n = len(pts)
    cx = 0.0
    cy = 0.0
    for i in range(n):
        cx += pts[i, 0]
        cy += pts[i, 1]
    cx /= n
    cy /= n
    sxx = 0.0
    syy = 0.0
    sxy = 0.0
    for i in range(n):
        dx, dy = pts[i, 0] - cx, pts[i, 1] - cy
        sxx += dx * dx
        syy += dy * dy
        sxy += dx * dy
    ang = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
    c, s = math.cos(ang), math.sin(ang)
    along = 0.0
    across = 0.0
    for i in range(n):  # the spreads from the projections (no cancellation for a thin row)
        dx, dy = pts[i, 0] - cx, pts[i, 1] - cy
        along += (dx * c + dy * s) ** 2
        across += (dy * c - dx * s) ** 2
    return ang, math.sqrt(along / n), math.sqrt(across / n)


@numba.njit(cache=True)
def rotate_about(ru, c, s, cx, cy):
    """Points rotated about (cx, cy) by the angle of cosine ``c`` and sine ``s``
    (:func:`stcvision.observation._rotate`), element by element as the numpy version."""
    out = np.empty_like(ru)
    for i in range(len(ru)):
        dx, dy = ru[i, 0] - cx, ru[i, 1] - cy
        out[i, 0] = (c * dx - s * dy) + cx
        out[i, 1] = (s * dx + c * dy) + cy
    return out


@numba.njit(cache=True)
def mark_offset(ru, orient, lit, inset, min_dots):
    """The median residuals of :func:`stcvision.observation.mark_offset` over the lit dots:
    per axis (0: right, from the rows along 'up'; 1: up, from those along 'right'), whether
    ``min_dots`` rows' dots were there, and minus the median of each dot's coordinate less its
    nominal one (the nearest integer, half to even, +- ``inset``)."""
    have = np.zeros(2, np.bool_)
    out = np.zeros(2)
    for axis in range(2):
        along = 1 - axis
        r = np.empty(len(ru))
        k = 0
        for i in range(len(ru)):
            if lit[i] and orient[i] == along:
                p = ru[i, axis]
                q = np.round(p)
                r[k] = p - (q + (inset if p >= q else -inset))
                k += 1
        if k >= min_dots:
            have[axis] = True
            out[axis] = -np.median(r[:k])
    return have, out


@numba.njit(cache=True)
def landing_counts(ru, lit, centres, half):
    """Per landing centre, the lit dots within ``half`` of it along both axes."""
    out = np.zeros(len(centres), np.int64)
    for i in range(len(ru)):
        if not lit[i]:
            continue
        for k in range(len(centres)):
            if abs(ru[i, 0] - centres[k, 0]) < half and abs(ru[i, 1] - centres[k, 1]) < half:
                out[k] += 1
    return out


@numba.njit(cache=True)
def anchored_rows(z, occ, xy, snr, crowded, max_snr, reach, step, n, min_snr, mean_snr, end_max, k_sigma):
    """Rows through one lone found dot (:func:`stcvision.stages._anchored_rows`): for each lone
    dot (not ``crowded``, SNR at most ``max_snr``, ``reach`` inside the image), the best of its
    ``2 n`` row hypotheses; a row within 2 px of an accepted one is skipped. Returns the
    accepted rows' points ((R, n - 1, 2) float) and SNRs (R,)."""
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
def accept_rows(taken, xs, ys, axis, order, offs, half, room):
    """Free rows strongest first (:func:`stcvision.stages.find_rows`): a row whose dots fall in
    ``taken`` (the accepted rows' dots grown by ``half``) is skipped; at most ``room`` rows.
    Returns the indices of the accepted candidates."""
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


@numba.njit(cache=True)
def accept_free_rows(shape, rows_xy, xs, ys, st, axis, offs, half, room):
    """The free rows of :func:`stcvision.stages._accept_free_rows`, strongest first (stable):
    the anchored rows' dots ``rows_xy`` ((R, n - 1, 2)) and each accepted row's dots grown by
    ``half`` are taken, a row with a dot on a taken pixel is skipped, at most ``room`` rows
    (:func:`accept_rows`). Returns the accepted rows' points ((A, n, 2) float) and SNRs (A,)."""
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
def row_orientation(ru, tol, span):
    """Per dot (cell units): 1 if it has more row-mates along 'up' than along 'right', 0 if
    fewer, -1 if as many (:func:`stcvision.observation.row_orientation`)."""
    n = len(ru)
    out = np.empty(n, np.int64)
    for i in range(n):
        vertical = 0
        horizontal = 0
        for j in range(n):
            if j == i:
                continue
            dr = abs(ru[i, 0] - ru[j, 0])
            du = abs(ru[i, 1] - ru[j, 1])
            if dr < tol and du < span:
                vertical += 1
            if du < tol and dr < span:
                horizontal += 1
        out[i] = 1 if vertical > horizontal else (0 if horizontal > vertical else -1)
    return out


@numba.njit(cache=True)
def assign_boxes(ru, orient, sub_of_quadrant, box_of, neighbours):
    """Sub-cell, box and neighbour of each dot (:func:`stcvision.observation.assign_boxes`)."""
    n = len(ru)
    sub = np.full(n, -1, np.int64)
    box = np.zeros(n, np.int64)
    nb = np.full(n, -1, np.int64)
    for i in range(n):
        r, u = ru[i, 0], ru[i, 1]
        right, up = r >= 0, u >= 0
        if abs(r) < 1 and abs(u) < 1:
            sub[i] = sub_of_quadrant[int(right), int(up)]
        lr = r - (0.5 if right else -0.5)
        lu = u - (0.5 if up else -0.5)
        horiz = True if orient[i] == 1 else (False if orient[i] == 0 else abs(lr) > abs(lu))
        er = int(np.sign(lr)) if horiz else 0
        eu = 0 if horiz else int(np.sign(lu))
        if sub[i] >= 0:
            box[i] = box_of[sub[i], er + 1, eu + 1]
        for k in range(len(neighbours)):
            if abs(r - 2 * neighbours[k, 0]) < 1 and abs(u - 2 * neighbours[k, 1]) < 1:
                nb[i] = k
    return sub, box, nb


@numba.njit(cache=True)
def crowded(xy, near):
    """Per point: another point within ``near`` (all pairs: for the few hundred lit dots a frame
    holds at most, ``DotParams.max_dots``; :func:`stcvision.stages._anchored_rows` uses a k-d
    tree beyond that)."""
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
def group_stats(code, n, lit, value):
    """Per code 0..n-1: lit dots with it, and the largest ``value`` of any dot with it (0.0
    where none has it) (:func:`stcvision.observation._group_stats`)."""
    counts = np.zeros(n, np.int64)
    best = np.full(n, -np.inf)
    seen = np.zeros(n, np.bool_)
    for i in range(len(code)):
        c = code[i]
        seen[c] = True
        if lit[i]:
            counts[c] += 1
        if value[i] > best[c]:
            best[c] = value[i]
    for c in range(n):
        if not seen[c]:
            best[c] = 0.0
    return counts, best


@numba.njit(cache=True)
def cell_dots(ru, lit, tol, span, inset, min_dots):
    """Row orientation and mark offset of the dots ``ru`` (cell units, already rotated), in
    one call (:func:`stcvision.observation._cell_dots`): per dot, :func:`row_orientation` among
    the lit dots (-1 for the rest), then :func:`mark_offset` over the lit dots. Returns
    (orient, have, offset)."""
    idx = np.flatnonzero(lit)
    sub = np.empty((len(idx), 2))
    for k in range(len(idx)):
        sub[k, 0] = ru[idx[k], 0]
        sub[k, 1] = ru[idx[k], 1]
    orient = np.full(len(ru), -1, np.int64)
    o = row_orientation(sub, tol, span)
    for k in range(len(idx)):
        orient[idx[k]] = o[k]
    have, off = mark_offset(ru, orient, lit, inset, min_dots)
    return orient, have, off


@numba.njit(cache=True)
def box_counts(box, nb, sub, lit, snr):
    """Per box code (box + 3: -3..5) and neighbour code (nb + 1: -1..3): the lit dots and the
    best SNR of any dot (:func:`group_stats`), and the stray lit dots (in a sub-cell, in no
    box) (:func:`stcvision.observation._read_boxes`)."""
    n_box, best_box = group_stats(box + 3, 9, lit, snr)
    n_nb, best_nb = group_stats(nb + 1, 5, lit, snr)
    stray = 0
    for i in range(len(box)):
        if sub[i] >= 0 and box[i] == 0 and lit[i]:
            stray += 1
    return n_box, best_box, n_nb, best_nb, stray


@numba.njit(cache=True)
def gauss_centroids(image, uv, background, half, sigma, iters):
    """Iterated Gaussian-weighted centroids (:func:`stcvision.stages.mirror_centroids`): around
    each (u, v) of ``uv`` ((n, 2) float), over the square of half-side ``half + 1`` about its
    nearest pixel, the centroid of ``max(image - background, 0)`` weighted by a Gaussian of
    ``sigma`` centred on the current estimate, ``iters`` times. Returns the centroids ((n, 2))
    and whether each could be measured (square inside the image, some signal)."""
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


# --- front end ---
# The pipeline's front end where one compiled pass beats a chain of OpenCV calls (issue 18): the
# unwarp of both channels with their separation, and the background sample. (Dark subtraction
# and window sums stay OpenCV's: compiled versions, bit for bit the same, measured slower on
# this machine.) Indices are cast to ``np.uintp`` in the inner loops: numba then drops its
# negative-index wraparound test and LLVM can vectorise them (measured here: a 390 x 390
# row-sum pass 316 -> 22 us).

_U = np.uintp
_f32 = np.float32


def _fma_codegen(ty, name: str):
    """LLVM code calling the fused multiply-add intrinsic ``name`` on three values of ``ty``."""

    def codegen(context, builder, signature, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ty, [ty, ty, ty]), name)
        return builder.call(fn, args)

    return codegen


@intrinsic
def _fma32(typingctx, a, b, c):
    """``a * b + c`` in float32 with one rounding (LLVM's ``llvm.fma.f32``: the hardware FMA
    where there is one, a correctly rounded library call elsewhere): OpenCV's vectorised
    ``addWeighted`` on this machine (AVX2) rounds so; without FMA hardware OpenCV may round
    twice, and the two differ only where the result is within a rounding step of 0."""
    return types.float32(types.float32, types.float32, types.float32), _fma_codegen(ir.FloatType(), "llvm.fma.f32")


@intrinsic
def _fma64(typingctx, a, b, c):
    """``a * b + c`` in float64 with one rounding (``llvm.fma.f64``), as :func:`_fma32`."""
    return types.float64(types.float64, types.float64, types.float64), _fma_codegen(ir.DoubleType(), "llvm.fma.f64")


@intrinsic
def _as_f32(typingctx, v):
    """The float32 whose bits are the uint32 ``v`` (a bitcast)."""

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.FloatType())

    return types.float32(types.uint32), codegen


@intrinsic
def _load_u64(typingctx, arr, idx):
    """``arr[idx]`` and ``arr[idx + 1]`` of a uint32 array as one uint64 (one unaligned 8-byte
    load, little-endian: ``arr[idx]`` in the low half), where numba would make two loads."""
    sig = types.uint64(arr, idx)

    def codegen(context, builder, signature, args):
        a, i = args
        ary = context.make_array(signature.args[0])(context, builder, a)
        p64 = builder.bitcast(builder.gep(ary.data, [i]), ir.IntType(64).as_pointer())
        return builder.load(p64, align=4)

    return sig, codegen


@numba.njit(cache=True)
def homography(H, p):
    """(N, 2) points ``p`` through the homography ``H`` ((3, 3)): ``[p, 1] @ H.T`` then divided
    by the third coordinate, each row of the product as OpenBLAS's dgemm computes it on this
    machine for N >= 2 (``fma(y, h1, x * h0) + h2``: bit for bit on 100,000 points; numpy takes
    another path for N = 1, which :func:`stcvision.observation._apply` keeps)."""
    n = len(p)
    out = np.empty((n, 2))
    for i in range(n):
        x, y = p[i, 0], p[i, 1]
        a = _fma64(y, H[0, 1], x * H[0, 0]) + H[0, 2]
        b = _fma64(y, H[1, 1], x * H[1, 0]) + H[1, 2]
        c = _fma64(y, H[2, 1], x * H[2, 0]) + H[2, 2]
        out[i, 0] = a / c
        out[i, 1] = b / c
    return out


@numba.njit(inline="always")
def _lerp(aa, bb, p00, p01, p10, p11):
    """``cv2.remap``'s bilinear step on this machine (float maps, float32 arithmetic, FMA)."""
    v0 = _fma32(aa, p01 - p00, p00)
    return _fma32(bb, _fma32(aa, p11 - p10, p10) - v0, v0)


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
def unwarp_border(src, w, h, border, border_xy, rnd, thr, tol, bottom, top, frac, gamma, leak, obstacle, marks, black):
    """The ground pixels ``border`` some of whose four source pixels lie outside the image
    (zeros there, as ``BORDER_CONSTANT``), from their map coordinates ``border_xy``: the
    change they make to the black-out count."""
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
def unwarp_separate_u16(
    src32, w, base, alpha, beta, thr, tol, bottom, top, frac, gamma, leak, obstacle, marks, black, scratch
):
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
    thr,
    tol,
    bottom,
    top,
    frac,
    gamma,
    leak,
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


@numba.njit(cache=True)
def nonzero_mask(img, out):
    """``out`` (uint8, ``img``'s shape) 255 where ``img`` is above 0, else 0 (``cv2.compare(img,
    0, CMP_GT)``); returns how many (``cv2.countNonZero``), in one pass."""
    h, w = img.shape
    n = 0
    for y in range(h):
        row, o = img[y], out[y]
        for x in range(w):
            v = row[x] > 0
            o[x] = 255 if v else 0
            n += v
    return n


@numba.njit(cache=True)
def blobs(obstacle, pts, starts, min_area, window_area):
    """:func:`stcvision.stages.find_red`'s blobs from their contours (contour ``k``: the points
    ``pts[starts[k]:starts[k + 1]]``, (T, 2) integers, as ``cv2.findContours`` gives them):
    the area ``m00`` and first moments of each (``cv2.moments`` of the polygon: OpenCV's
    contour sums, exact in float64 for integer points, then scaled by +-1/2 and +-1/6 by the
    sign of the area; zero for an area within ``FLT_EPSILON`` of 0); a blob's area is the
    larger of that and its number of points (a thin blob has none), and those under
    ``min_area`` are dropped; its position the centroid, or the mean of its points where the
    area is 0; its peak the largest value of ``obstacle`` in its bounding box
    (``cv2.boundingRect``) over ``window_area``. Returns (xy (M, 2), peak (M,), area (M,))."""
    nc = len(starts) - 1
    xy = np.zeros((nc, 2))
    peak = np.zeros(nc)
    area = np.zeros(nc)
    m = 0
    for k in range(nc):
        a, b = starts[k], starts[k + 1]
        xi_1, yi_1 = float(pts[b - 1, 0]), float(pts[b - 1, 1])
        a00 = 0.0
        a10 = 0.0
        a01 = 0.0
        sx = 0.0
        sy = 0.0
        x0 = x1 = pts[a, 0]
        y0 = y1 = pts[a, 1]
        for i in range(a, b):
            xi, yi = float(pts[i, 0]), float(pts[i, 1])
            dxy = xi_1 * yi - xi * yi_1
            a00 += dxy
            a10 += dxy * (xi_1 + xi)
            a01 += dxy * (yi_1 + yi)
            xi_1, yi_1 = xi, yi
            sx += xi
            sy += yi
            x0 = min(x0, pts[i, 0])
            x1 = max(x1, pts[i, 0])
            y0 = min(y0, pts[i, 1])
            y1 = max(y1, pts[i, 1])
        m00 = m10 = m01 = 0.0
        if abs(a00) > 1.1920928955078125e-07:  # FLT_EPSILON
            h, s6 = (0.5, 0.16666666666666666) if a00 > 0 else (-0.5, -0.16666666666666666)
            m00, m10, m01 = a00 * h, a10 * s6, a01 * s6
        ar = max(m00, float(b - a))
        if ar < min_area:
            continue
        if m00 > 0:
            xy[m, 0], xy[m, 1] = m10 / m00, m01 / m00
        else:
            xy[m, 0], xy[m, 1] = sx / (b - a), sy / (b - a)
        best = obstacle[y0, x0]
        for yy in range(y0, y1 + 1):
            for xx in range(x0, x1 + 1):
                if obstacle[yy, xx] > best:
                    best = obstacle[yy, xx]
        peak[m] = float(best) / window_area
        area[m] = ar
        m += 1
    return xy[:m], peak[:m], area[:m]


@numba.njit(cache=True)
def zero_where(img, mask):
    """``img[mask != 0] = 0`` (flat arrays)."""
    for i in range(_U(len(img))):
        if mask[i]:
            img[i] = 0


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
