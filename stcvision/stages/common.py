"""What every stage shares: the frame and image contracts, the window sums' dtypes, the noise
floor of quantised data and the scratch arrays a caller lends the stages."""

from __future__ import annotations

import math
import time

import numpy as np

from stcvision.errors import BadInputError

__all__ = [
    "FRAME_DTYPES",
    "QUANTISATION_SIGMA",
    "SUM_DTYPES",
    "Scratch",
    "StageTimes",
    "check_frame",
    "check_image",
    "noise_floor",
]


class Scratch:
    """Scratch arrays lent to the stages and reused from call to call: ``scratch(purpose, shape,
    dtype)`` gives the same array each time for the same three. Never one a result holds: the next
    call overwrites it (so one ``Scratch`` per thread)."""

    def __init__(self) -> None:
        self._arrays: dict = {}

    def __call__(self, purpose: str, shape, dtype) -> np.ndarray:
        key = (purpose, tuple(shape), np.dtype(dtype))
        if key not in self._arrays:
            self._arrays[key] = np.empty(shape, dtype)
        return self._arrays[key]


class StageTimes:
    """Wall time of each stage (ms), kept under the name it was timed by::

        times = StageTimes()
        with times("dots"):
            ...
        times.ms  # {"dots": 0.13}

    A stage's time is recorded against the name given where it runs, never by its position in a
    sequence, so a stage added or timed twice cannot shift the labels of the others: a name timed
    twice, or a stage timed inside another, is an error.

    Parameters
    ----------
    clock : callable, optional
        Nanoseconds now (default :func:`time.perf_counter_ns`).
    """

    __slots__ = ("ms", "_clock", "_name", "_t0")

    def __init__(self, clock=time.perf_counter_ns) -> None:
        self.ms: dict[str, float] = {}
        self._clock = clock
        self._name: str | None = None
        self._t0 = 0

    def __call__(self, name: str) -> StageTimes:
        if self._name is not None:
            raise RuntimeError(f"stage {name!r} timed inside stage {self._name!r}")
        if name in self.ms:
            raise RuntimeError(f"stage {name!r} timed twice")
        self._name = name
        return self

    def __enter__(self) -> None:
        self._t0 = self._clock()

    def __exit__(self, *exc) -> None:
        self.ms[self._name] = (self._clock() - self._t0) / 1e6
        self._name = None


def new_arrays(purpose: str, shape, dtype) -> np.ndarray:
    """A :class:`Scratch` that keeps nothing: a new array every call."""
    return np.empty(shape, dtype)


#: frame dtypes the pipeline reads: 8-bit, or 16-bit holding an ADC's counts (any depth up to 16
#: bits, LSB- or MSB-aligned: every threshold comes from the measured noise, not the depth)
FRAME_DTYPES = (np.uint8, np.uint16)


#: noise of rounding to whole quantisation steps, in steps (uniform error: 1 / sqrt(12))
QUANTISATION_SIGMA = 1.0 / math.sqrt(12.0)


#: window sums as the stages hold them: uint16 from 8-bit frames, float32 (exact integers up to
#: 2^24) from 16-bit ones, whose nine-pixel sums overflow 16 bits
SUM_DTYPES = (np.uint16, np.float32)


def check_frame(frame: np.ndarray, name: str = "frame") -> None:
    """Contract: ``frame`` is an (H, W, 3) uint8 or uint16 BGR image."""
    if not isinstance(frame, np.ndarray):
        raise BadInputError(f"{name} must be a numpy array, got {type(frame).__name__}")
    if frame.dtype not in FRAME_DTYPES:
        raise BadInputError(f"{name} has dtype {frame.dtype}; expected uint8 or uint16")
    if frame.ndim != 3 or frame.shape[2] != 3:
        raise BadInputError(f"{name} has shape {frame.shape}; expected (H, W, 3) BGR")


def check_image(image, name: str, dtypes=(np.uint8, np.uint16), ndims=(2, 3)) -> None:
    """Entry contract of the stages below (found by fuzzing: None, 0-d, empty or float arrays
    failed inside OpenCV or numpy): a non-empty numpy image of one of ``dtypes``."""
    if not isinstance(image, np.ndarray) or image.ndim not in ndims or image.size == 0 or image.dtype not in dtypes:
        got = f"{image.shape} {image.dtype}" if isinstance(image, np.ndarray) else type(image).__name__
        want = " or ".join(np.dtype(d).name for d in dtypes)
        raise BadInputError(f"{name} must be a non-empty {'-D or '.join(map(str, ndims))}-D {want} image, got {got}")


def noise_floor(quantum: float = 1.0) -> float:
    """The least per-pixel noise a measurement may report: the rounding noise of one
    quantisation step (``quantum`` DN), ``quantum / sqrt(12)``."""
    return QUANTISATION_SIGMA * quantum
