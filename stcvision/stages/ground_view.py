"""The unwarp stage: the mirror image remapped to the ground view (top-down, robot-centred).

(The module is not named after the stage: :func:`unwarp` is the package's public function.)

:func:`unwarp` is the stage as OpenCV writes it (one ``cv2.remap``: the reference, and the
display images); :func:`unwarp_separate` is what the pipeline runs: the remap of the green and
red window sums fused with the per-pixel red/green test of the channel separation
(:mod:`stcvision.stages.channels` chooses its rule) in one compiled pass, bit for bit the
arithmetic of ``cv2.remap`` followed by :func:`stcvision.stages.separate_channels`. The compiled
pass comes in two kernels specialised by the sums' type (:func:`unwarp_separate_u16`,
:func:`unwarp_separate_f32`) and one for the pixels at the image's border
(:func:`unwarp_border`). :class:`UnwarpMap` is the remap table built once from a profile,
:class:`GatherTables` the same table as the compiled pass reads it.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numba
import numpy as np

from stcvision.errors import BadInputError
from stcvision.stages.common import Scratch, check_image, new_arrays
from stcvision.stages.compiled import as_f32, f32, fma32, load_u64, remap_lerp, uidx


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
        """Build the map from the profile: for every ground pixel, the image pixel it sees.

        For every ground-view pixel: robot-frame floor point -> phi (azimuth, preserved) and
        theta (elevation, from the profile's radial polynomial) -> image pixel.
        """
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
        """Return the part of the mirror image the map reads, with a margin.

        (x0, y0, x1, y1): the part of the mirror image the map reads, with ``margin`` pixels
        more on every side (a window sum there sees only pixels inside), clipped to the image.
        """
        w, h = self.image_size_px
        mx, my = self.map_x[self.valid], self.map_y[self.valid]
        if not len(mx):
            return 0, 0, w, h
        x0, y0 = max(int(np.floor(mx.min())) - margin, 0), max(int(np.floor(my.min())) - margin, 0)
        x1, y1 = min(int(np.floor(mx.max())) + 2 + margin, w), min(int(np.floor(my.max())) + 2 + margin, h)
        return x0, y0, x1, y1

    def cropped(self, x0: int, y0: int, x1: int, y1: int) -> UnwarpMap:
        """Return the same map reading a crop of the image.

        The crop is ``image[y0:y1, x0:x1]``; shifting a map by whole pixels is exact in float32.
        """
        mx, my = self.map_x - np.float32(x0), self.map_y - np.float32(y0)
        f1, f2 = cv2.convertMaps(mx, my, cv2.CV_16SC2)
        return UnwarpMap(mx, my, self.valid, (x1 - x0, y1 - y0), f1, f2)


class GatherTables(NamedTuple):
    """An unwarp map as the gather tables of the compiled unwarp.

    An :class:`UnwarpMap` as gather tables for :func:`unwarp_separate_u16`,
    which unwarps the green and red window sums in one pass, bit for bit as ``cv2.remap`` with
    the float maps does. Per ground pixel (flat, in order): ``base``, the source pixel (flat
    index) at the top left of the four it reads; ``alpha``, ``beta``, the map's fractional parts;
    ``border``: the ground pixels some of whose four source pixels lie outside the image (read
    as zeros), with their map coordinates ``border_xy``.
    """

    base: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    border: np.ndarray
    border_xy: np.ndarray

    @classmethod
    def from_map(cls, umap: UnwarpMap) -> GatherTables:
        """Build the gather tables of an unwarp map."""
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
    """Unwarp a mirror image to the ground view (top-down, robot-centred, forward up).

    One ``cv2.remap``.

    Parameters
    ----------
    image : numpy.ndarray
        (H, W) or (H, W, 3), the profile's image size: uint8, or uint16 or float32 (window sums).
    umap : UnwarpMap
        The remap tables of the profile's ground view.

    Returns
    -------
    numpy.ndarray
        The ground view, of the image's dtype and channels.

    Raises
    ------
    BadInputError
        When the image is not of the map's image size or a supported dtype.
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


#: the byte order the unwarp's gathers read pairs of channels in (green first in memory)
_LITTLE = sys.byteorder == "little"
#: uint16 window sums gathered as uint32 pairs (little-endian machines); else converted to
#: float32 and gathered as those are (tests switch it off to check that path)
_U32_GATHERS = True


@numba.njit(inline="always")
def _red_test(gv, rv, use_frac, thr, tol, bottom, top, frac, gamma, leak):
    """Apply the red/green separation to one ground pixel.

    The red/green separation of one ground pixel (:func:`unwarp_separate_u16`): (a red
    light, to black out). Pure: the loops store the results themselves (an inlined helper
    that stored into the output arrays ran the uint16 loop 3x slower, 0.69 vs 0.24 ms).
    """
    dom = min(max(rv + tol, bottom), top) >= gv
    if use_frac:
        dom = dom & (fma32(rv, np.float32(1.0), fma32(gv, frac, gamma)) >= np.float32(0.0))
    light = dom & (rv > thr)
    return light, light | (dom & (rv > leak))


@numba.njit(cache=True)
def unwarp_border(src, w, h, border, border_xy, rnd, rule, obstacle, marks, black):
    """Correct the black-out count for the ground pixels that read beyond the image.

    The ground pixels ``border`` some of whose four source pixels lie outside the image
    (zeros there, as ``BORDER_CONSTANT``), from their map coordinates ``border_xy``: the
    change they make to the black-out count.
    """
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
            p[k] = f32(src[2 * (yy * w + xx)]) if inside else np.float32(0.0)
            p[4 + k] = f32(src[2 * (yy * w + xx) + 1]) if inside else np.float32(0.0)
        aa = mx - np.float32(x)
        bb = my - np.float32(y)
        j = border[i]
        old = black[j]
        gv = remap_lerp(aa, bb, p[0], p[1], p[2], p[3])
        rv = remap_lerp(aa, bb, p[4], p[5], p[6], p[7])
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
    """Unwarp the green and red window sums and separate them, in one pass.

    The unwarp of the green and red window sums and their red/green separation, in one pass
    over the ground view: ``cv2.remap`` (float maps, ``INTER_LINEAR``, ``BORDER_CONSTANT`` 0) of
    each channel as it computes on this machine (:func:`remap_lerp`; rounded half to even and
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
    separation 348 us; this 221 us with a 4-byte load per source pixel, 166 us with these).
    """
    thr, tol, bottom, top, frac, gamma, leak = rule
    zero = np.float32(0.0)
    hi = np.float32(65535.0)
    use_frac = frac != zero
    n = 0
    nb = scratch.shape[1]
    row = uidx(w)
    lo = np.uint64(0xFFFF)
    s0, s1 = scratch[0], scratch[1]
    N = len(base)
    for start in range(0, N, nb):
        m = uidx(min(nb, N - start))
        st = uidx(start)
        for i in range(m):  # a source pixel and its right neighbour, both channels: one load
            o = uidx(base[st + i])
            s0[i] = load_u64(src32, o)
            s1[i] = load_u64(src32, o + row)
        for i in range(m):
            j = st + i
            aa = alpha[j]
            bb = beta[j]
            q0, q1 = s0[i], s1[i]  # (green, red) of the left pixel in the low half, the right's above
            p00, p01 = f32(q0 & lo), f32((q0 >> np.uint64(32)) & lo)
            p10, p11 = f32(q1 & lo), f32((q1 >> np.uint64(32)) & lo)
            v0 = fma32(aa, p01 - p00, p00)
            gv = min(max(np.rint(fma32(bb, fma32(aa, p11 - p10, p10) - v0, v0)), zero), hi)
            p00, p01 = f32((q0 >> np.uint64(16)) & lo), f32(q0 >> np.uint64(48))
            p10, p11 = f32((q1 >> np.uint64(16)) & lo), f32(q1 >> np.uint64(48))
            v0 = fma32(aa, p01 - p00, p00)
            rv = min(max(np.rint(fma32(bb, fma32(aa, p11 - p10, p10) - v0, v0)), zero), hi)
            # the separation as _red_test has it, written out: this is the bench's loop, and
            # through the inlined helper it measured no faster and at times slower here
            dom = min(max(rv + tol, bottom), top) >= gv
            if use_frac:
                dom = dom & (fma32(rv, np.float32(1.0), fma32(gv, frac, gamma)) >= zero)
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
    """Unwarp and separate float32 window sums, in one pass.

    :func:`unwarp_separate_u16` for float32 sums (16-bit frames; and uint16 sums on a
    big-endian machine, converted: ``rnd`` rounds and saturates): ``src64``, the (h, w, 2)
    sums as one uint64 per pixel (both channels: green in the low half where ``green_low``),
    four aligned loads per ground pixel; ``scratch`` (4, N) uint64. The separation written
    out, as there.
    """
    thr, tol, bottom, top, frac, gamma, leak = rule
    zero = np.float32(0.0)
    hi = np.float32(65535.0)
    use_frac = frac != zero
    n = 0
    nb = scratch.shape[1]
    row = uidx(w)
    lo = np.uint64(0xFFFFFFFF)
    gs = np.uint64(0) if green_low else np.uint64(32)
    rs = np.uint64(32) if green_low else np.uint64(0)
    s0, s1, s2, s3 = scratch[0], scratch[1], scratch[2], scratch[3]
    N = len(base)
    for start in range(0, N, nb):
        m = uidx(min(nb, N - start))
        st = uidx(start)
        for i in range(m):
            o = uidx(base[st + i])
            s0[i] = src64[o]
            s1[i] = src64[o + uidx(1)]
            s2[i] = src64[o + row]
            s3[i] = src64[o + row + uidx(1)]
        for i in range(m):
            j = st + i
            aa = alpha[j]
            bb = beta[j]
            q0, q1, q2, q3 = s0[i], s1[i], s2[i], s3[i]
            p00, p01 = as_f32(np.uint32((q0 >> gs) & lo)), as_f32(np.uint32((q1 >> gs) & lo))
            p10, p11 = as_f32(np.uint32((q2 >> gs) & lo)), as_f32(np.uint32((q3 >> gs) & lo))
            v0 = fma32(aa, p01 - p00, p00)
            gv = fma32(bb, fma32(aa, p11 - p10, p10) - v0, v0)
            p00, p01 = as_f32(np.uint32((q0 >> rs) & lo)), as_f32(np.uint32((q1 >> rs) & lo))
            p10, p11 = as_f32(np.uint32((q2 >> rs) & lo)), as_f32(np.uint32((q3 >> rs) & lo))
            v0 = fma32(aa, p01 - p00, p00)
            rv = fma32(bb, fma32(aa, p11 - p10, p10) - v0, v0)
            if rnd:
                gv = min(max(np.rint(gv), zero), hi)
                rv = min(max(np.rint(rv), zero), hi)
            light, b = _red_test(gv, rv, use_frac, thr, tol, bottom, top, frac, gamma, leak)
            obstacle[j] = rv if light else zero
            marks[j] = gv
            black[j] = b
            n += b
    return n


def unwarp_separate(tables: GatherTables, sums: np.ndarray, shape, rule: tuple, scratch: Scratch = new_arrays):
    """Unwarp the window sums to the ground views and separate red from green, in one compiled pass.

    (obstacle, marks, black, n): the ground views (``shape``) of the (h, w, 2) green/red
    window sums ``sums`` through ``tables`` and their red/green separation by ``rule``
    (:func:`separation_rule`), the arithmetic of ``cv2.remap`` then :func:`separate_channels`,
    in one compiled pass: uint16 sums on a little-endian machine by :func:`unwarp_separate_u16`,
    others by :func:`unwarp_separate_f32`, the border pixels by :func:`unwarp_border`.
    ``obstacle`` and ``marks`` are new; ``black`` (scratch, uint8) is 1 at the ``n`` ground
    pixels of the marks to black out (:func:`black_out`).
    """
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
