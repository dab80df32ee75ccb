"""The channels stage: the red/green separation into the obstacle and marks images.

The obstacle image holds the red lights, the marks image the green phosphor; the red lights are
blacked out of the marks with a margin.

:class:`ChannelParams` holds the rule and :func:`separation_rule` turns it into the thresholds
the compiled pass compares with. :func:`separate_channels` (and :func:`filter_channels` on a
colour image) is the stage on images already in place: the compiled rule of
:func:`stcvision.stages.ground_view.unwarp_separate` over the identity map, then :func:`black_out`.
In the pipeline the per-pixel test runs inside the unwarp's pass and this stage is the black-out
alone.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import cv2
import numba
import numpy as np

from stcvision.errors import BadInputError
from stcvision.stages.common import SUM_DTYPES, Scratch, check_image, new_arrays
from stcvision.stages.compiled import uidx
from stcvision.stages.dark import estimate_background
from stcvision.stages.ground_view import GatherTables, UnwarpMap, unwarp_separate


@dataclass(frozen=True, kw_only=True, slots=True)
class ChannelParams:
    """Red/green separation: which pixels are red light, which are marks.

    Red/green separation (ant-like STC paper: "In the obstacle image, we keep all the pixels that
    the red color is bigger than a threshold. And in the visited cells, we keep the colors that the
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
    #: 30 s) took dots 20-40 DN above the background for red and blacked them out (measured)
    red_min_fraction: float = 0.5

    def levels(self, background_dn: float, noise_dn: float) -> tuple[float, float]:
        """Return the (red threshold, dominance tolerance) per pixel in DN.

        (red threshold, dominance tolerance) per pixel in DN, for a red channel of this
        background and noise.
        """
        thr = background_dn + self.red_k_sigma * noise_dn if self.red_threshold_dn is None else self.red_threshold_dn
        tol = self.dominance_k_sigma * noise_dn if self.dominance_tol_dn is None else self.dominance_tol_dn
        return float(thr), float(tol)


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

    The thresholds are per pixel and scale with ``window_area``. The outputs keep the input dtype.

    Parameters
    ----------
    image : numpy.ndarray
        (H, W, 3) uint8, or window sums (see :func:`window_sums`) with ``window_area`` pixels
        per sum.
    params : ChannelParams
        The red and dominance thresholds.
    window_area : int
        Pixels per sum (1 for a plain image).
    leak_threshold : float, optional
        Same units as ``image``; default none. The lower red level above which a red-dominated
        pixel is still kept out of the marks image: a bright light's faint halo (lens glare,
        blooming) carries green by crosstalk far beyond the pixels bright enough to count as the
        light itself.
    background_dn, noise_dn : float, optional
        The red channel's per-pixel background and noise (default: measured on a uint8
        ``image``; window sums need them given).

    Returns
    -------
    tuple of numpy.ndarray
        (obstacle, marks), single-channel images of the input dtype.

    Raises
    ------
    BadInputError
        When ``image`` is not a 3-channel uint8 image or window sums, or window sums come without
        ``background_dn`` and ``noise_dn``.
    """
    check_image(image, "image", (np.uint8, *SUM_DTYPES), ndims=(3,))
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
    """Separate a green and a red image already split apart, as the pipeline does.

    :func:`filter_channels` on a green and a red image already split apart: the rule the
    pipeline runs (:func:`separation_rule`, the compiled loops of :func:`unwarp_separate` over the
    identity map, :func:`black_out`), so what it shows is what the pipeline computes.

    Red-dominated where ``r + tol >= g`` (saturating as the images' dtype does) and, with
    ``params.red_min_fraction``, ``r - bg >= f (g - bg)``; a red light where also ``r > thr``:
    ``obstacle`` keeps its red, ``marks`` the green with the lights (and, with
    ``leak_threshold``, the red-dominated pixels above it) blacked out, grown by
    ``params.red_margin_px``.
    """
    check_image(g, "g", (np.uint8, *SUM_DTYPES), ndims=(2,))
    check_image(r, "r", (np.uint8, *SUM_DTYPES), ndims=(2,))
    if g.shape != r.shape or g.dtype != r.dtype:
        raise BadInputError(f"g and r must match, got {g.shape} {g.dtype} and {r.shape} {r.dtype}")
    dtype = g.dtype
    # uint8 runs as uint16: its values are exact there, and the dominance test's saturation at
    # 255 or 65535 decides alike (both sides of the comparison are at most 255)
    work = np.uint16 if dtype == np.uint8 else dtype
    sums = np.stack([g, r], axis=-1).astype(work, copy=False)
    h, w = g.shape
    leak = float(leak_threshold) if leak_threshold is not None else _NO_LEAK
    rule = separation_rule(params, window_area, (background_dn, noise_dn), leak, work)
    scratch = Scratch()
    obstacle, marks, black, n = unwarp_separate(_identity_tables(w, h), sums, (h, w), rule, scratch)
    black_out(marks, black, n, black_out_margin(params.red_margin_px), scratch)
    return obstacle.astype(dtype, copy=False), marks.astype(dtype, copy=False)


#: the leak level that blacks out nothing beyond the lights (above any sum)
_NO_LEAK = 2.0**40


@functools.lru_cache(maxsize=4)
def _identity_tables(w: int, h: int) -> GatherTables:
    """Build the gather tables of the map that reads every pixel where it stands.

    They are kept per image size: building them is 8 of a 640x480 call's 10 ms; the compiled
    loops only read them.
    """
    my, mx = np.mgrid[0:h, 0:w].astype(np.float32)
    return GatherTables.from_map(UnwarpMap(mx, my, np.ones((h, w), bool), (w, h)))


def black_out_margin(red_margin_px: int) -> np.ndarray | None:
    """Return the structuring element the black-out grows by.

    An ellipse reaching ``red_margin_px`` beyond a pixel.

    Parameters
    ----------
    red_margin_px : int

    Returns
    -------
    (k, k) uint8 ndarray or None
        None where the margin is 0 (not grown).
    """
    if red_margin_px <= 0:
        return None
    k = 2 * red_margin_px + 1
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))


def separation_rule(channels: ChannelParams, window_area: int, red_levels, leak: float, dtype) -> tuple:
    """Turn the channel parameters into the levels the compiled unwarp compares with.

    The red/green separation of :func:`separate_channels` for window sums of ``dtype`` as the
    compiled unwarp takes it: (light threshold, dominance tolerance, the saturation's bottom and
    top, the red fraction's weight and offset, leak level), float32 as OpenCV rounds them:
    ``red_levels`` the red channel's per-pixel background and noise, ``leak`` (in sums) the
    level above which a red-dominated pixel is blacked out too.
    """
    thr, tol = channels.levels(*red_levels)
    thr_a, tol_a = float(thr * window_area), float(tol * window_area)
    # the red-fraction test as cv2.addWeighted(r, 1, g, -f, -(1 - f) bg) >= 0 takes it
    frac = np.float32(-channels.red_min_fraction if channels.red_min_fraction > 0 else 0.0)
    gamma = np.float32(-(1.0 - channels.red_min_fraction) * (red_levels[0] * window_area))
    if dtype == np.uint16:  # OpenCV: the added scalar rounded, comparisons exact
        tol32, bottom, top = np.float32(np.rint(tol_a)), np.float32(0), np.float32(65535)
        # v > t for whole v <= 65535 is v > floor(t), exact in float32 once clipped
        thr32, leak32 = (np.float32(min(max(math.floor(x), -1), 65536)) for x in (thr_a, leak))
    else:  # float images: the scalars rounded to float32, no saturation
        tol32, thr32, leak32 = np.float32(tol_a), np.float32(thr_a), np.float32(leak)
        bottom, top = np.float32(-np.inf), np.float32(np.inf)
    return thr32, tol32, bottom, top, frac, gamma, leak32


def black_out(marks: np.ndarray, black: np.ndarray, n: int, margin: np.ndarray | None, scratch: Scratch = new_arrays):
    """Black out the red lights' pixels of the marks image, in place.

    Zero in ``marks`` the ``n`` pixels :func:`unwarp_separate` marked in ``black``, grown by
    the structuring element ``margin`` (the red lights' halo; None: not grown), in place.
    """
    if not n:
        return
    if margin is not None:
        black = cv2.dilate(black, margin, dst=scratch("grown", marks.shape, np.uint8))
    zero_where(marks.reshape(-1), black.reshape(-1))


@numba.njit(cache=True)
def zero_where(img, mask):
    """``img[mask != 0] = 0`` (flat arrays)."""
    for i in range(uidx(len(img))):
        if mask[i]:
            img[i] = 0
