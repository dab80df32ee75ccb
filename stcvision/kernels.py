"""The stages' per-candidate loops, compiled by numba (``cache=True``: compiled once per machine).

Each kernel is the loop of a stage in :mod:`stcvision.stages` that numpy cannot vectorise (a
greedy choice, strongest first, where each choice depends on the earlier ones), written out
element by element in the stage's own arithmetic order, so its results are those of the
numpy/Python version it replaced, bit for bit (the pipeline's outputs on 800 dataset frames were
compared). The stages document what the loops mean; here is only how.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

__all__ = [
    "anchored_rows",
    "accept_rows",
    "black_out",
    "fill_squares",
    "gauss_centroids",
    "separate_pair",
    "zero_where",
    "sample_quartiles",
]


@numba.njit(cache=True)
def fill_squares(img, xs, ys, half):
    """Set the squares of half-side ``half[i]`` around (xs[i], ys[i]) to 1 in ``img`` (uint8)."""
    h, w = img.shape
    for i in range(len(xs)):
        r = half[i]
        y0, y1 = max(ys[i] - r, 0), min(ys[i] + r + 1, h)
        x0, x1 = max(xs[i] - r, 0), min(xs[i] + r + 1, w)
        for y in range(y0, y1):
            for x in range(x0, x1):
                img[y, x] = 1


@numba.njit(cache=True)
def _taken(img, px, py):
    for i in range(len(px)):
        if img[py[i], px[i]]:
            return True
    return False


@numba.njit(cache=True)
def black_out(starts, shadowers, max_dots):
    """Greedy black-out (:func:`stcvision.stages._black_out`): candidate i (strongest first) is
    kept unless a kept candidate among ``shadowers[starts[i]:starts[i + 1]]`` shadows it."""
    n = len(starts) - 1
    keep = np.zeros(n, np.bool_)
    out = np.empty(min(n, max_dots), np.int64)
    m = 0
    for i in range(n):
        if m >= max_dots:
            break
        shadowed = False
        for t in range(starts[i], starts[i + 1]):
            if keep[shadowers[t]]:
                shadowed = True
                break
        if shadowed:
            continue
        keep[i] = True
        out[m] = i
        m += 1
    return out[:m]


@numba.njit(cache=True)
def anchored_rows(z, occ, xy, snr, lone, step, n, min_snr, mean_snr, end_max, k_sigma):
    """Rows through one lone found dot (:func:`stcvision.stages._anchored_rows`): for each lone
    dot, the best of its ``2 n`` row hypotheses; a row within 2 px of an accepted one is
    skipped. Returns the accepted rows' points ((R, n - 1, 2) float) and SNRs (R,)."""
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
# channel separation and the background sample. (Dark subtraction, window sums and the unwarp
# stay OpenCV's: compiled versions, bit for bit the same, measured slower or no faster within
# the pipeline on this machine.) Indices are cast to ``np.uintp`` in the inner loops: numba then
# drops its negative-index wraparound test and LLVM can vectorise them (measured here: a
# 390 x 390 row-sum pass 316 -> 22 us).

_U = np.uintp
_f32 = np.float32


@intrinsic
def _fma32(typingctx, a, b, c):
    """``a * b + c`` in float32 with one rounding (LLVM's ``llvm.fma.f32``: the hardware FMA
    where there is one, a correctly rounded library call elsewhere): OpenCV's vectorised
    ``addWeighted`` on this machine (AVX2) rounds so; without FMA hardware OpenCV may round
    twice, and the two differ only where the result is within a rounding step of 0."""
    sig = types.float32(types.float32, types.float32, types.float32)

    def codegen(context, builder, signature, args):
        f32 = ir.FloatType()
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(f32, [f32, f32, f32]), "llvm.fma.f32")
        return builder.call(fn, args)

    return sig, codegen


@numba.njit(cache=True)
def separate_pair(g, r, thr, tol, bottom, top, frac, gamma, leak, obstacle, marks, black):
    """The red/green separation of :func:`stcvision.stages.separate_channels` (the rule is
    documented there) in one pass over the flat ground-view green ``g`` and red ``r``, in
    float32 as OpenCV's arithmetic has it: red-dominated where ``r + tol >= g`` (the
    add, saturating at ``bottom`` and ``top``) and, with ``frac`` (the negated ``red_min_fraction``; 0: off),
    ``fma(r, 1, fma(g, frac, gamma)) >= 0`` (``cv2.addWeighted``); a light pixel where also
    ``r > thr`` (``obstacle`` keeps its red, else 0); ``marks`` is ``g``; ``black`` (uint8) 1
    where the marks are to be blacked out before the margin grows it: the light pixels and the
    red-dominated ones with ``r > leak``. Returns the number of those. (The thresholds are the
    caller's, as OpenCV compares: whole numbers below them for integer images.)"""
    n = 0
    one = np.float32(1.0)
    zero = np.float32(0.0)
    use_frac = frac != zero
    for i in range(_U(len(g))):
        gv = _f32(g[i])
        rv = _f32(r[i])
        dom = min(max(rv + tol, bottom), top) >= gv
        if use_frac:
            dom = dom & (_fma32(rv, one, _fma32(gv, frac, gamma)) >= zero)
        light = dom & (rv > thr)
        obstacle[i] = r[i] if light else 0
        marks[i] = g[i]
        b = light | (dom & (rv > leak))
        black[i] = b
        n += b
    return n


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
