"""The window stage: the sum over the dot-sized square around every pixel, in the mirror image.

:func:`window_sums` is the stage: ``cv2.boxFilter`` (the reference) or, for 3 x 3 windows of a
pair of 8-bit images, the compiled :func:`box3_pair` (of 16-bit ones :func:`box3_pair_wide`),
bit for bit the same and faster.
"""

from __future__ import annotations

import cv2
import numba
import numpy as np

from stcvision.errors import BadInputError
from stcvision.stages.common import Scratch, check_image, new_arrays
from stcvision.stages.compiled import uidx


def window_sums(image, window_px: int, *, scratch: Scratch = new_arrays) -> np.ndarray:
    """Sum over the dot-sized square around every pixel, no rounding.

    The sums are uint16 for a uint8 image, float32 for a uint16 one (exact: 9 x 65535 < 2^24).
    3 x 3 windows of a pair of 8-bit images are summed by a compiled pass (:func:`box3_pair`,
    bit for bit OpenCV's box filter and faster), of a pair of 16-bit images by
    :func:`box3_pair_wide` (the same), into ``scratch`` (the next call lending the same scratch
    overwrites them).

    The ant-like STC paper (Srour & Abboud), "Finding the green dots": "we look for the square of
    pixels (of a dot's size) that has the highest average value". Filtering once, in the mirror
    image where the pixels are, and unwarping the sums keeps every photon of a dot and the noise of
    exactly ``window_px**2`` pixels, wherever the dot lies (the unwarp would otherwise skip pixels
    near the robot, where the ground view is coarser than the mirror image).

    Parameters
    ----------
    image : numpy.ndarray or tuple of numpy.ndarray
        An image (uint8 or uint16), or a pair (green, red) of 2-D images of one shape and dtype,
        whose sums come as one (h, w, 2) image, green first.
    window_px : int
        The side of the square (px), a dot's size.
    scratch : Scratch
        Lends the compiled pass's output and buffers; default new arrays.

    Returns
    -------
    numpy.ndarray
        The window sums, of the image's (or the pair's) shape.

    Raises
    ------
    BadInputError
        When ``image`` is not a uint8 or uint16 image, or the pair's images differ.
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
        if window_px == 3 and g.dtype == np.uint16 and g.flags.c_contiguous and r.flags.c_contiguous:
            sums = scratch("sums wide", (*g.shape, 2), np.float32)
            h, w = g.shape
            rows = scratch("rows wide", (6 * w,), np.uint32)
            box3_pair_wide(g.reshape(-1), r.reshape(-1), h, w, sums.reshape(-1), rows)
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
    hs[oh] = np.uint16(src[o]) + np.uint16(src[o + uidx(1)])
    for x in range(uidx(1), uidx(w - 1)):
        hs[oh + x] = np.uint16(src[o + x - uidx(1)]) + np.uint16(src[o + x]) + np.uint16(src[o + x + uidx(1)])
    hs[oh + uidx(w - 1)] = np.uint16(src[o + uidx(w - 2)]) + np.uint16(src[o + uidx(w - 1)])


@numba.njit(cache=True)
def box3_pair(g, r, h, w, sums, scratch):
    """Sum 3 x 3 windows of two uint8 images into one two-channel uint16 image.

    3 x 3 window sums of the (h, w) uint8 images ``g`` and ``r`` (flat) into the (h, w, 2)
    uint16 image ``sums`` (flat, green first; exact), zeros beyond their edges:
    ``cv2.boxFilter(img, CV_16U, (3, 3), normalize=False, borderType=BORDER_CONSTANT)`` of
    each, bit for bit (integers), row by row: each row's sums along it into a ring of three
    rows (``scratch``: 6 w uint16), then the sums of three of those, interleaved, in loops
    LLVM vectorises.
    """
    uw = uidx(w)
    for y in range(h + 1):
        if y < h:
            slot = uidx(2 * (y % 3)) * uw
            _row3(g, uidx(y) * uw, w, scratch, slot)
            _row3(r, uidx(y) * uw, w, scratch, slot + uw)
        if y == 0:
            continue
        yy = y - 1  # the output row: rows yy - 1, yy, yy + 1 (those inside)
        o = uidx(2 * yy) * uw
        mid = uidx(2 * (yy % 3)) * uw
        up = uidx(2 * ((yy + 2) % 3)) * uw
        dn = uidx(2 * ((yy + 1) % 3)) * uw
        if yy >= 1 and yy + 1 < h:
            for x in range(uw):
                sums[o + uidx(2) * x] = scratch[up + x] + scratch[mid + x] + scratch[dn + x]
                sums[o + uidx(2) * x + uidx(1)] = scratch[up + uw + x] + scratch[mid + uw + x] + scratch[dn + uw + x]
        elif yy >= 1:
            for x in range(uw):
                sums[o + uidx(2) * x] = scratch[up + x] + scratch[mid + x]
                sums[o + uidx(2) * x + uidx(1)] = scratch[up + uw + x] + scratch[mid + uw + x]
        elif yy + 1 < h:
            for x in range(uw):
                sums[o + uidx(2) * x] = scratch[mid + x] + scratch[dn + x]
                sums[o + uidx(2) * x + uidx(1)] = scratch[mid + uw + x] + scratch[dn + uw + x]
        else:
            for x in range(uw):
                sums[o + uidx(2) * x] = scratch[mid + x]
                sums[o + uidx(2) * x + uidx(1)] = scratch[mid + uw + x]


@numba.njit(cache=True)
def box3_pair_wide(g, r, h, w, sums, rows):
    """Sum 3 x 3 windows of two uint16 images into one two-channel float32 image.

    The (h, w) uint16 images ``g`` and ``r`` (flat) summed over 3 x 3 windows into the (h, w, 2)
    float32 image ``sums`` (flat, green first), zeros beyond their edges: what
    ``cv2.boxFilter(cv2.merge([g, r]), CV_32F, (3, 3), normalize=False,
    borderType=BORDER_CONSTANT)`` gives, bit for bit (whole numbers up to 9 x 65535, under
    2^24: exact in float32, whatever the order of the additions). Row by row: the sums along
    the row of each image into a ring of three rows per image (``rows``: 6 w uint32), then the
    sums of three of those down the columns, interleaved.
    """
    uw = uidx(w)
    for y in range(h + 1):
        if y < h:
            slot = uidx(2 * (y % 3)) * uw
            for c in range(2):
                src = g if c == 0 else r
                o, oh = uidx(y) * uw, slot + uidx(c) * uw
                if w == 1:
                    rows[oh] = np.uint32(src[o])
                    continue
                rows[oh] = np.uint32(src[o]) + np.uint32(src[o + uidx(1)])
                for x in range(uidx(1), uw - uidx(1)):
                    left, right = np.uint32(src[o + x - uidx(1)]), np.uint32(src[o + x + uidx(1)])
                    rows[oh + x] = left + np.uint32(src[o + x]) + right
                rows[oh + uw - uidx(1)] = np.uint32(src[o + uw - uidx(2)]) + np.uint32(src[o + uw - uidx(1)])
        if y == 0:
            continue
        yy = y - 1  # the output row: the ring's rows of yy - 1, yy, yy + 1 (those inside)
        o = uidx(2 * yy) * uw
        mid = uidx(2 * (yy % 3)) * uw
        # a row outside the image adds nothing: its ring slot is the middle row's, weighted 0
        up = uidx(2 * ((yy + 2) % 3)) * uw if yy >= 1 else mid
        dn = uidx(2 * ((yy + 1) % 3)) * uw if yy + 1 < h else mid
        ku = np.uint32(1 if yy >= 1 else 0)
        kd = np.uint32(1 if yy + 1 < h else 0)
        for x in range(uw):
            sums[o + uidx(2) * x] = np.float32(ku * rows[up + x] + rows[mid + x] + kd * rows[dn + x])
            sums[o + uidx(2) * x + uidx(1)] = np.float32(
                ku * rows[up + uw + x] + rows[mid + uw + x] + kd * rows[dn + uw + x]
            )
