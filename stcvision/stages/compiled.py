"""Compiled helpers shared by the stages' loops (numba): fused multiply-adds, bit casts and wide
loads numba does not expose, the bilinear interpolation ``cv2.remap`` uses, and the bit-set
helpers of the compiled 3 x 3 maximum tests.

The loops themselves live with their stage (``stcvision.stages.dark``, ``window``, ``ground_view``,
``channels``, ``dots``, ``rows``, ``red``, ``heading``; ``stcvision.observation``). Each is a
loop numpy cannot vectorise (a greedy choice, strongest first, where each choice depends on the
earlier ones), or a chain of
OpenCV / numpy passes fused into one (each pass over the view, each call on a small array,
costs microseconds), written out element by element in the stage's own arithmetic order, so its
results are those of the numpy/OpenCV version it replaced, bit for bit. Image loops index views
from 0 up or use numpy's error model so the compiler can vectorise them. Indices are cast to
``np.uintp`` (:data:`uidx`) in the inner loops: numba then drops its negative-index wraparound
test and LLVM can vectorise them (measured: a 390 x 390 row-sum pass 316 -> 22 us).
"""

from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

__all__ = [
    "as_f32",
    "f32",
    "fma32",
    "fma64",
    "grow_array",
    "load_u64",
    "marked_positions",
    "remap_lerp",
    "row_flags",
    "uidx",
]


#: the index type of the inner loops (see above): ``uidx(i)``
uidx = np.uintp

#: the float type of the loops that compute as OpenCV does in float32: ``f32(x)``
f32 = np.float32


def _fma_codegen(ty, name: str):
    """LLVM code calling the fused multiply-add intrinsic ``name`` on three values of ``ty``."""

    def codegen(context, builder, signature, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ty, [ty, ty, ty]), name)
        return builder.call(fn, args)

    return codegen


@intrinsic
def fma32(typingctx, a, b, c):
    """``a * b + c`` in float32 with one rounding (LLVM's ``llvm.fma.f32``: the hardware FMA
    where there is one, a correctly rounded library call elsewhere): OpenCV's vectorised
    ``addWeighted`` on this machine (AVX2) rounds so; without FMA hardware OpenCV may round
    twice, and the two differ only where the result is within a rounding step of 0."""
    return types.float32(types.float32, types.float32, types.float32), _fma_codegen(ir.FloatType(), "llvm.fma.f32")


@intrinsic
def fma64(typingctx, a, b, c):
    """``a * b + c`` in float64 with one rounding (``llvm.fma.f64``), as :func:`fma32`."""
    return types.float64(types.float64, types.float64, types.float64), _fma_codegen(ir.DoubleType(), "llvm.fma.f64")


@intrinsic
def as_f32(typingctx, v):
    """The float32 whose bits are the uint32 ``v`` (a bitcast)."""

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.FloatType())

    return types.float32(types.uint32), codegen


@intrinsic
def load_u64(typingctx, arr, idx):
    """``arr[idx]`` and ``arr[idx + 1]`` of a uint32 array as one uint64 (one unaligned 8-byte
    load, little-endian: ``arr[idx]`` in the low half), where numba would make two loads."""
    sig = types.uint64(arr, idx)

    def codegen(context, builder, signature, args):
        a, i = args
        ary = context.make_array(signature.args[0])(context, builder, a)
        p64 = builder.bitcast(builder.gep(ary.data, [i]), ir.IntType(64).as_pointer())
        return builder.load(p64, align=4)

    return sig, codegen


@numba.njit(inline="always")
def remap_lerp(aa, bb, p00, p01, p10, p11):
    """``cv2.remap``'s bilinear step on this machine (float maps, float32 arithmetic, FMA)."""
    v0 = fma32(aa, p01 - p00, p00)
    return fma32(bb, fma32(aa, p11 - p10, p10) - v0, v0)


@numba.njit(inline="always")
def grow_array(a, m):
    """``a`` (1-D) with room for twice ``m`` entries, its first ``m`` kept."""
    out = np.empty(2 * m, a.dtype)
    out[:m] = a[:m]
    return out


@numba.njit(inline="always")
def row_flags(nx):
    """A zeroed byte per pixel of an image row of ``nx`` pixels (padded to whole uint64
    words), its uint64 view, and room for the positions :func:`marked_positions` finds."""
    flag = np.zeros((nx + 7) // 8 * 8, np.uint8)
    return flag, flag.view(np.uint64), np.empty(len(flag), np.int64)


@numba.njit(inline="always")
def marked_positions(flag, words, out):
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
