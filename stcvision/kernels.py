"""The stages' per-candidate loops, compiled by numba (``cache=True``: compiled once per machine).

Each kernel is the loop of a stage in :mod:`stcvision.stages` that numpy cannot vectorise (a
greedy choice, strongest first, where each choice depends on the earlier ones), written out
element by element in the stage's own arithmetic order, so its results are those of the
numpy/Python version it replaced, bit for bit (the pipeline's outputs on 800 dataset frames were
compared). The stages document what the loops mean; here is only how.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["anchored_rows", "accept_rows", "black_out", "fill_squares"]


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
