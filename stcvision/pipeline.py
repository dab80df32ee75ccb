"""The pipeline runner: raw frame -> dots, heading, cell observation, with per-stage timing.

Stages (``stcvision.stages``), in the order they run::

    dark      green and red of the frame, dark frame subtracted (saturating, with a pedestal),
              hot pixels masked; the frame's background and noise
    window    sums over the dot-sized square, in the mirror image (filter once)
    unwarp    phi/theta remap of the window sums to the ground view, and the red/green test
              per ground pixel (one compiled pass: obstacle and marks images)
    channels  the red lights' black-out margin in the marks image
    dots      window-mean dot search with black-out; centroids on the mirror image
    red       red-light blobs
    heading   line fit through the newest mark row
    observe   five boxes, visited sub-cells, four neighbours

The runner is built once per profile (remap table, cell homography); ``process`` allocates only
the images it returns, besides a few scratch images it keeps (so one ``Pipeline`` per thread). The
unwarp with the channel separation, and the background sample, are compiled passes
(``stcvision.kernels``), bit-identical to the OpenCV stages they stand for; the window sums of
green and red are one two-channel image, which the unwarp gathers both channels of at once. Logging
(``stcvision.rr``) observes the result afterwards.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import cv2
import numpy as np

from stcvision import kernels
from stcvision.observation import CellGeometry, CellObservation, ObservationParams, observe_cell
from stcvision.profile import Profile
from stcvision.stages import (
    ChannelParams,
    DotParams,
    Dots,
    GatherTables,
    HeadingFit,
    HeadingParams,
    RedLights,
    RedParams,
    RowParams,
    UnwarpMap,
    check_dark_dtype,
    check_frame,
    find_dots,
    find_red,
    find_rows,
    fit_heading,
    hot_pixels,
    mirror_centroids,
    noise_floor,
    noise_gain,
    quantum_dn,
    robust_sigma,
    subtract_dark,
    unwarp,
    window_sums,
)

__all__ = ["Pipeline", "PipelineParams", "PipelineResult", "STAGES", "display_scale"]

#: the byte order the unwarp's gathers read pairs of channels in (green first in memory)
_LITTLE = sys.byteorder == "little"
#: uint16 window sums gathered as uint32 pairs (little-endian machines); else converted to
#: float32 and gathered as those are (tests switch it off to check that path)
_U32_GATHERS = True

STAGES = ("dark", "window", "unwarp", "channels", "dots", "rows", "red", "heading", "observe")


@dataclass(frozen=True, kw_only=True, slots=True)
class PipelineParams:
    """Parameters of every stage.

    The pedestal is the offset kept by the dark subtraction so the background noise stays
    measurable (see :func:`~stcvision.stages.subtract_dark`): ``pedestal_k_sigma`` times the
    dark frame's robust spread (its fixed pattern and noise; the residual after subtraction is
    no wider), and at least ``pedestal_steps`` quantisation steps (10 DN on the webcam, whose
    dark frame spreads by ~1.5 DN), in whole steps.
    """

    pedestal_steps: int = 10
    pedestal_k_sigma: float = 6.0
    channels: ChannelParams = field(default_factory=ChannelParams)
    dots: DotParams = field(default_factory=DotParams)
    rows: RowParams = field(default_factory=RowParams)
    red: RedParams = field(default_factory=RedParams)
    heading: HeadingParams = field(default_factory=HeadingParams)
    observation: ObservationParams = field(default_factory=ObservationParams)
    #: rotate the cell regions by the measured heading error before reading the boxes
    use_heading: bool = True
    #: a "red" blob whose blue is at least this fraction of its red (dark-subtracted, 9x9 px
    #: around it in the camera frame) is white light, not a red LED: not an obstacle light nor a
    #: landmark. None: off. Measured on the webcam's short frame (1/30 s, gain 16): a red light
    #: 0.12-1.0 m away reads 0.84-0.13 (its blue is 2 % of its red, but it saturates), a white
    #: lamp 0.99-1.0 at every distance. In long frames every red light saturates white: use it
    #: on short frames only.
    white_blue_ratio: float | None = None


def display_scale(frame: np.ndarray) -> float:
    """Factor taking ``frame``'s values (or window means of them) to 8 bits for display: 1 for
    a uint8 frame; for a 16-bit one, whatever its ADC depth and alignment, its brightest pixel
    maps to 255."""
    if frame.dtype == np.uint8:
        return 1.0
    return 255.0 / max(float(frame.max()), 1.0)


#: a frame whose background is this many noise sigmas above the dark level is not read as a
#: dark-room frame (:meth:`Pipeline._lit_frame`, with the measured margins on each side)
LIT_BACKGROUND_K_SIGMA = 3.0


@dataclass(frozen=True, eq=False)
class PipelineResult:
    """Everything one frame gave, plus the intermediate images (references, not copies).

    ``green`` and ``red_raw`` are the dark-subtracted mirror-image channels (of the part of the
    frame the ground view reads, ``Pipeline.crop``: about half the frame); ``obstacle`` and
    ``marks`` the ground-view images of window sums (``window_area`` pixels each: uint16 from an
    8-bit frame, float32 from a 16-bit one). Display images (8-bit window means, the colour
    dark-subtracted frame) are made on demand. ``untrusted``: why this frame's reading cannot
    be trusted ("" when it can).
    """

    frame: np.ndarray
    dark: np.ndarray | None
    pedestal_dn: int
    green: np.ndarray
    red_raw: np.ndarray
    obstacle: np.ndarray
    marks: np.ndarray
    dots: Dots
    red: RedLights
    heading: HeadingFit
    observation: CellObservation
    stage_ms: dict[str, float]
    window_area: int = 9
    #: (N, 2) robot-frame positions (m) of the white lights (not red:
    #: :attr:`PipelineParams.white_blue_ratio`) this frame showed
    white_lights_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def dark_subtracted(self) -> np.ndarray:
        """The colour frame after dark subtraction (for display; the stages split channels)."""
        if self.dark is None:
            return self.frame
        return subtract_dark(self.frame, self.dark, pedestal_dn=self.pedestal_dn)

    def _u8(self, img: np.ndarray) -> np.ndarray:
        return cv2.convertScaleAbs(img, alpha=display_scale(self.frame) / self.window_area)

    def obstacle_u8(self) -> np.ndarray:
        return self._u8(self.obstacle)

    def marks_u8(self) -> np.ndarray:
        return self._u8(self.marks)

    @property
    def untrusted(self) -> str:
        return self.dots.untrusted

    @property
    def total_ms(self) -> float:
        return float(sum(self.stage_ms.values()))

    def to_dict(self, profile: Profile | None = None) -> dict:
        d = self.dots
        out = {
            "dots": [
                {
                    "xy_px": [round(float(x), 3) for x in d.xy_px[i]],
                    "xy_m": [round(float(x), 5) for x in d.xy_m[i]],
                    "strength_dn": round(float(d.strength[i]), 3),
                    "snr": round(float(d.snr[i]), 2),
                }
                for i in np.flatnonzero(d.lit)
            ],
            "dot_threshold_snr": d.threshold_snr,
            "noise_dn": d.noise_dn,
            "background_dn": d.background_dn,
            "heading": {
                "ok": self.heading.ok,
                "heading_error_deg": None if not self.heading.ok else float(np.degrees(self.heading.heading_error_rad)),
                "residual_mm": None if not self.heading.ok else 1000 * self.heading.residual_m,
                "reason": self.heading.reason,
            },
            "obstacles": [
                {"xy_px": [round(float(x), 2) for x in self.red.xy_px[i]], "peak_dn": float(self.red.peak_dn[i])}
                for i in range(len(self.red))
            ],
            "observation": self.observation.to_dict(),
            "untrusted": self.untrusted,
            "stage_ms": {k: round(v, 4) for k, v in self.stage_ms.items()},
            "total_ms": round(self.total_ms, 4),
        }
        return out


class _Front(NamedTuple):
    """What the front end (:meth:`Pipeline._front`) gives the later stages."""

    green: np.ndarray
    red: np.ndarray
    sums: np.ndarray
    obstacle: np.ndarray
    marks: np.ndarray
    bg: float
    noise: float
    quantum: int
    red_levels: tuple[float, float]
    leak: float


class Pipeline:
    """Build once per profile, then ``process`` frames.

    Parameters
    ----------
    profile : Profile
    params : PipelineParams
    dark : (H, W, 3) uint8 or uint16 (the frames' dtype), optional -- the dark frame for every
        ``process`` call.
    """

    def __init__(
        self, profile: Profile, params: PipelineParams | None = None, *, dark: np.ndarray | None = None
    ) -> None:
        self.profile = profile
        self.params = params or PipelineParams()
        self.umap = UnwarpMap.from_profile(profile)
        self.geometry = CellGeometry.from_profile(profile)
        self.gain = noise_gain(self.umap, self.params.dots.window_px)
        # raw pixels inside the mirror rim, sparsely, for the per-frame background/noise estimate
        w, h = profile.image_size_px
        vv, uu = np.mgrid[0:h:5, 0:w:5]
        inside = np.hypot(uu - profile.center_px[0], vv - profile.center_px[1]) < 0.95 * profile.rim_radius_px
        self._sample = (vv[inside] * w + uu[inside]).ravel()
        self._sample3 = {ch: self._sample * 3 + ch for ch in (1, 2)}  # into a flat BGR frame
        # the wide, coarse ground view for far red-light landmarks (pose estimates only)
        self.wide = None
        if self.params.observation.pose_estimates and self.params.observation.landmark_range_m > 0:
            reach = self.params.observation.landmark_range_m + 0.1
            n = 160
            self._wide_profile = profile.replace(ground_size_px=n, ground_px_per_m=(n - 1) / (2 * reach))
            self.wide = UnwarpMap.from_profile(self._wide_profile)
        # the part of the mirror image the main view reads: the mirror-image stages run on that
        # crop only (about half the frame); the wide view reads nearly the whole mirror
        self._crop = (0, 0, w, h) if self.wide is not None else self.umap.reach_px()
        x0, y0, x1, y1 = self._crop
        self._umap_crop = self.umap.cropped(x0, y0, x1, y1)
        self._tables = GatherTables.from_map(self._umap_crop)
        self._wide_tables = GatherTables.from_map(self.wide) if self.wide is not None else None
        # the front end's scratch images, made once (the images a result holds are new per frame)
        self._scratch = {}  # (purpose, shape, dtype) -> scratch arrays, made on first use
        k = 2 * self.params.channels.red_margin_px + 1
        self._margin = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)) if k > 1 else None
        self._no_dark()
        if dark is not None:
            self.set_dark(dark)

    @property
    def crop(self) -> tuple[int, int, int, int]:
        """(x0, y0, x1, y1): the part of the mirror image the stages read."""
        return self._crop

    def _crop_view(self, image: np.ndarray) -> np.ndarray:
        x0, y0, x1, y1 = self._crop
        return image[y0:y1, x0:x1]

    def _no_dark(self) -> None:
        """No dark frame: the background sample is then read as it is, without pedestal."""
        self.dark = None
        self.pedestal = 0
        self.quantum = 1
        self.dark_sigma = 0.0
        self._hot_g = self._hot_r = np.zeros(0, np.int64)
        self._dark_sample = None
        self._hot_sample = [np.zeros(len(self._sample), bool)] * 2

    def _buffer(self, purpose: str, shape, dtype) -> np.ndarray:
        """A scratch array of the front end, reused from frame to frame (never one a result
        holds: the next ``process`` call overwrites it)."""
        key = (purpose, tuple(shape), np.dtype(dtype))
        if key not in self._scratch:
            self._scratch[key] = np.empty(shape, dtype)
        return self._scratch[key]

    def set_dark(self, dark: np.ndarray) -> None:
        """Use ``dark`` (H, W, 3) uint8 or uint16 from now on: split it once, map its hot pixels
        once, and take from it the quantisation step and the pedestal."""
        check_frame(dark, "dark frame")
        self.profile.check_frame(dark.shape, what="dark frame")
        p = self.params
        gr = np.concatenate([cv2.extractChannel(dark, c).reshape(-1)[self._sample] for c in (1, 2)])
        q = quantum_dn(gr)
        _, spread = robust_sigma(gr)
        self.quantum = q
        self.dark_sigma = spread
        self.pedestal = int(max(p.pedestal_steps, math.ceil(p.pedestal_k_sigma * spread / q - 1e-9)) * q)
        self.dark = dark
        crop = self._crop_view(dark)
        self._dark_g, self._dark_r = cv2.extractChannel(crop, 1), cv2.extractChannel(crop, 2)
        hot = hot_pixels(dark, quantum=q)
        x0, y0, x1, y1 = self._crop
        w = dark.shape[1]
        hot_in = []
        for ch in (1, 2):
            px = hot[hot % 3 == ch] // 3  # flat indices into one full channel
            yy, xx = px // w, px % w
            keep = (xx >= x0) & (xx < x1) & (yy >= y0) & (yy < y1)
            hot_in.append((yy[keep] - y0) * (x1 - x0) + (xx[keep] - x0))  # into the crop
        self._hot_g, self._hot_r = hot_in
        self._dark_sample = [np.ascontiguousarray(dark.reshape(-1)[self._sample3[ch]]) for ch in (1, 2)]
        self._hot_sample = [np.isin(self._sample3[ch], hot) for ch in (1, 2)]

    def _channels(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Green and red of the crop of ``frame`` the view reads, dark-subtracted: two new
        (h, w) images. One ``cv2.split`` of the crop's rows (a contiguous block: OpenCV's
        vectorised path, ~2x faster here than extracting or mixing channels out of the crop),
        then per channel the pedestal added and the dark frame subtracted, both saturating,
        and the hot pixels set to the pedestal."""
        x0, y0, x1, y1 = self._crop
        rows = frame[y0:y1]
        # into the pipeline's own planes, reused frame to frame (the results hold the
        # dark-subtracted copies below, never these): writing fresh memory each frame made the
        # split 3x slower alone here (64 against 20 us; ~10 us of the pipeline's frame)
        planes = cv2.split(rows, [self._buffer(f"plane {c}", rows.shape[:2], rows.dtype) for c in range(3)])
        g, r = planes[1][:, x0:x1], planes[2][:, x0:x1]
        if self.dark is None:
            return g.copy(), r.copy()  # new images: the planes are scratch
        ped = self.pedestal
        g = cv2.subtract(cv2.add(g, ped), self._dark_g)
        r = cv2.subtract(cv2.add(r, ped), self._dark_r)
        g.reshape(-1)[self._hot_g] = ped  # defect-pixel map
        r.reshape(-1)[self._hot_r] = ped
        return g, r

    def _background(self, frame: np.ndarray) -> tuple[float, float, float, float, int]:
        """(green background, green noise, red background, red noise, quantisation step) of
        ``frame``: :func:`~stcvision.stages.estimate_background` of raw pixels inside the rim
        (:attr:`_sample`), dark-subtracted as :meth:`_channel` does it (one compiled pass over
        both channels); the noise never below the rounding noise of one step."""
        flat = frame.reshape(-1)
        n = len(self._sample)
        vals = self._buffer("sample g", (n,), frame.dtype), self._buffer("sample r", (n,), frame.dtype)
        if self.dark is None:
            dark = [self._buffer("no dark", (n,), frame.dtype)] * 2
            dark[0][:] = 0
            q = quantum_dn(flat[self._sample3[1]])
        else:
            dark, q = self._dark_sample, self.quantum
        top, whole = np.iinfo(frame.dtype).max, frame.dtype == np.uint8 and q == 1
        quart = kernels.sample_quartiles(
            flat, self._sample3[1], *dark, *self._hot_sample, self.pedestal, top, q, whole, *vals
        )
        (gq1, g_med, gq3), (rq1, r_med, rq3) = quart
        floor = noise_floor(q)
        g_noise, r_noise = max(float((gq3 - gq1) / 1.349), floor), max(float((rq3 - rq1) / 1.349), floor)
        return float(g_med), g_noise, float(r_med), r_noise, q

    def _window_sums(self, g: np.ndarray, r: np.ndarray) -> np.ndarray:
        """:func:`~stcvision.stages.window_sums` of the green and red images ``g``, ``r`` as one
        (h, w, 2) image, green first (the pipeline's scratch for 8-bit frames: the next frame
        overwrites it): 3 x 3 windows of 8-bit pixels by a compiled pass
        (:func:`stcvision.kernels.box3_pair`, bit for bit OpenCV's box filter, faster here),
        others by OpenCV."""
        w = self.params.dots.window_px
        if w != 3 or g.dtype != np.uint8:
            return window_sums(cv2.merge([g, r]), w)
        sums = self._buffer("sums", (*g.shape, 2), np.uint16)  # scratch: no result holds it
        h, wd = g.shape
        kernels.box3_pair(
            g.reshape(-1), r.reshape(-1), h, wd, sums.reshape(-1), self._buffer("rows", (6 * wd,), np.uint16)
        )
        return sums

    def _unwarp_separate(
        self, tables: GatherTables, sums: np.ndarray, shape, leak: float, red_levels: tuple[float, float]
    ) -> tuple[np.ndarray, np.ndarray, int]:
        """(obstacle, marks, n): the ground views of the (h, w, 2) green/red window sums
        ``sums`` through ``tables`` and their red/green separation, the rule and the arithmetic
        of ``cv2.remap`` then :func:`~stcvision.stages.separate_channels`, in one compiled pass
        (:func:`stcvision.kernels.unwarp_separate_u16`; new arrays); ``n`` ground pixels of the
        marks are to be blacked out (:meth:`_black_out`)."""
        area = self.params.dots.window_px**2
        cp = self.params.channels
        thr, tol = cp.levels(*red_levels)
        thr_a, tol_a = float(thr * area), float(tol * area)
        # the red-fraction test as cv2.addWeighted(r, 1, g, -f, -(1 - f) bg) >= 0 takes it
        frac = np.float32(-cp.red_min_fraction if cp.red_min_fraction > 0 else 0.0)
        gamma = np.float32(-(1.0 - cp.red_min_fraction) * (red_levels[0] * area))
        if sums.dtype == np.uint16:  # OpenCV: the added scalar rounded, comparisons exact
            tol32, bottom, top = np.float32(np.rint(tol_a)), np.float32(0), np.float32(65535)
            # v > t for whole v <= 65535 is v > floor(t), exact in float32 once clipped
            thr32, leak32 = (np.float32(min(max(math.floor(x), -1), 65536)) for x in (thr_a, leak))
            # both channels in one uint32 load, green in the low half (little-endian machines)
            src32 = sums.reshape(-1).view(np.uint32) if (_LITTLE and _U32_GATHERS) else None
        else:  # float images: the scalars rounded to float32, no saturation
            tol32, thr32, leak32 = np.float32(tol_a), np.float32(thr_a), np.float32(leak)
            bottom, top = np.float32(-np.inf), np.float32(np.inf)
            src32 = None
        h, w = sums.shape[:2]
        scratch = self._buffer("gather", (2, 256) if src32 is not None else (4, 256), np.uint64)
        obstacle = np.empty(shape, sums.dtype)
        marks = np.empty(shape, sums.dtype)
        black = self._buffer("black", shape, np.uint8)
        flat = obstacle.reshape(-1), marks.reshape(-1), black.reshape(-1)
        sep = (thr32, tol32, bottom, top, frac, gamma, leak32, *flat)
        base, alpha, beta, border, border_xy = tables
        src, rnd = sums.reshape(-1), sums.dtype == np.uint16
        if src32 is not None:
            n = kernels.unwarp_separate_u16(src32, w, base, alpha, beta, *sep, scratch)
        else:  # float32 pairs, one uint64 per pixel (uint16 sums converted: exact)
            src64 = np.ascontiguousarray(sums, np.float32).reshape(-1).view(np.uint64)
            n = kernels.unwarp_separate_f32(src64, _LITTLE, w, base, alpha, beta, rnd, *sep, scratch)
        if len(border):
            n += kernels.unwarp_border(src, w, h, border, border_xy, rnd, *sep)
        return obstacle, marks, n

    def _black_out(self, marks: np.ndarray, n: int) -> None:
        """Zero in ``marks`` the ``n`` pixels :meth:`_unwarp_separate` marked, grown by the
        red-light margin (``ChannelParams.red_margin_px``), in place."""
        if not n:
            return
        black = self._buffer("black", marks.shape, np.uint8)
        if self._margin is not None:
            black = cv2.dilate(black, self._margin, dst=self._buffer("grown", marks.shape, np.uint8))
        kernels.zero_where(marks.reshape(-1), black.reshape(-1))

    def _front(self, frame: np.ndarray, clock, t: list) -> _Front:
        """The mirror-image stages and the channel separation (dark, window, unwarp, channels;
        their end times appended to ``t``)."""
        p = self.params
        w = p.dots.window_px
        g, r = self._channels(frame)  # only green and red carry marks and lights
        # background and noise, measured on raw pixels inside the rim
        bg, noise, bg_r, noise_r, q = self._background(frame)
        t.append(clock())
        sums = self._window_sums(g, r)
        t.append(clock())
        # a red light's level: above the pedestal by the dark frame's spread (a fixed rule per
        # dark frame), or without one above the frame's own red background by its noise
        red_levels = (self.pedestal, max(self.dark_sigma, noise_floor(q))) if self.dark is not None else (bg_r, noise_r)
        leak = w * w * bg_r + p.channels.leak_k_sigma * noise_r * w
        obstacle, marks, n = self._unwarp_separate(self._tables, sums, self._umap_crop.map_x.shape, leak, red_levels)
        t.append(clock())
        self._black_out(marks, n)
        t.append(clock())
        return _Front(g, r, sums, obstacle, marks, bg, noise, q, red_levels, leak)

    def _lit_frame(self, bg: float, noise: float) -> str:
        """Why a frame is not a dark-room frame this pipeline can read ("" when it is): its
        background (the median of the view, where the floor is unmarked and so dark) more than
        :data:`LIT_BACKGROUND_K_SIGMA` noise sigmas above the dark level. With a dark frame that
        level is the pedestal: measured, dark-room frames of every camera sit at 0.0 sigma and
        lit calibration frames at 16-18. Without one it is zero, and the sensor's own dark signal
        and fixed pattern stay in the frame: webcam, low-light and cooled frames sat at 5.6, 6.3
        and 26 sigma and gave 61-64 dots where the truth had 16."""
        excess = (bg - self.pedestal) / max(noise, 1e-9)
        if excess <= LIT_BACKGROUND_K_SIGMA:
            return ""
        if self.dark is None:
            return (
                f"no dark frame, and the frame's background is {excess:.1f} sigma above zero: the sensor's dark "
                "signal and fixed pattern (hot pixels) are read as dots; use the dark frame taken at this exposure"
            )
        return (
            f"the frame's background is {excess:.1f} sigma above the dark frame's level: a lit frame (lights on) "
            "or a dark frame of other settings, not a dark-room frame at the dark frame's exposure"
        )

    def process(
        self,
        frame: np.ndarray,
        *,
        dark: np.ndarray | None = None,
        heading_error_rad: float | None = None,
        position_offset: tuple[float, float] | None = None,
    ) -> PipelineResult:
        """Run every stage on one (H, W, 3) uint8 or uint16 BGR frame (a uint16 frame holds an
        ADC's counts; the dark frame must have the frame's dtype).

        ``heading_error_rad``: read the cell with this heading error instead of this frame's own
        fit -- e.g. the fit of a short frame taken at the same pose, for a long one in which
        every recent row saturates (the newest row is then no longer the brightest).
        ``position_offset``: read the cell with the robot this far off its sub-cell centre
        (:func:`stcvision.observation.observe_cell`) instead of where this frame's marks say.

        Not re-entrant: one ``Pipeline`` per thread (the front end's scratch images are its own)."""
        check_frame(frame)
        self.profile.check_frame(frame.shape)
        if dark is not None and dark is not self.dark:
            self.set_dark(dark)
        if self.dark is not None:
            check_dark_dtype(self.dark, frame.dtype)
        p = self.params
        w = p.dots.window_px
        area = w * w
        clock = time.perf_counter_ns
        t = [clock()]
        f = self._front(frame, clock, t)
        g, r, obstacle, marks, bg, noise, q = f.green, f.red, f.obstacle, f.marks, f.bg, f.noise, f.quantum
        g2r = self.profile.ground_to_robot
        dots = find_dots(  # robot-frame positions from the mirror-image centroids when they run
            marks,
            p.dots,
            gain=self.gain,
            background_dn=bg,
            noise_dn=noise,
            ground_to_robot=None if p.dots.mirror_sigma_px > 0 else g2r,
            quantum=q,
        )
        dots = mirror_centroids(  # g is the crop the view reads: its own map
            dots, g, background_dn=bg, umap=self._umap_crop, ground_to_robot=self.profile.ground_to_robot, params=p.dots
        )
        t.append(clock())
        all_dots = find_rows(
            marks,
            dots,
            gain=self.gain,
            background_dn=bg,
            noise_dn=noise,
            px_per_m=self.profile.ground_px_per_m,
            window_px=w,
            params=p.rows,
            dot_params=p.dots,
            ground_to_robot=self.profile.ground_to_robot,
            quantum=q,
            buffers=self._buffer,
        )
        lit = self._lit_frame(bg, noise)
        if lit and not all_dots.untrusted:
            all_dots = dataclasses.replace(all_dots, untrusted=lit)
        t.append(clock())
        red = find_red(obstacle, p.red, window_area=area)
        white_m = np.zeros((0, 2))
        if p.white_blue_ratio is not None:
            xy_m = self.profile.ground_to_robot(red.xy_px) if len(red) else np.zeros((0, 2))
            white = self._white(frame, xy_m)
            white_m = xy_m[white]
            red = RedLights(red.xy_px[~white], red.peak_dn[~white], red.area_px[~white])
        t.append(clock())
        heading = fit_heading(dots, p.heading)
        t.append(clock())
        landmark_px = self._far_lights(f, frame) if self.wide is not None else None
        herr = heading.heading_error_rad if (heading.ok and p.use_heading) else 0.0
        if heading_error_rad is not None:
            herr = float(heading_error_rad)
        obs = observe_cell(
            all_dots,
            red.xy_px,
            red.peak_dn,
            self.geometry,
            red_threshold_dn=p.channels.levels(*f.red_levels)[0],
            heading_error_rad=herr,
            params=p.observation,
            landmark_px=landmark_px,
            subcell_m=self.profile.subcell_m,
            position_offset=position_offset,
        )
        t.append(clock())
        stage_ms = {name: (t[i + 1] - t[i]) / 1e6 for i, name in enumerate(STAGES)}
        return PipelineResult(
            frame, self.dark, self.pedestal, g, r, obstacle, marks, all_dots, red, heading, obs, stage_ms, area, white_m
        )

    def _white(self, frame: np.ndarray, xy_m: np.ndarray, *, half: int = 4) -> np.ndarray:
        """Per light at robot-frame ``xy_m``: white (:attr:`PipelineParams.white_blue_ratio`)."""
        uv = self.profile.robot_to_image(xy_m)
        h, w = frame.shape[:2]
        out = np.zeros(len(uv), bool)
        for i, (u, v) in enumerate(uv):
            if not (np.isfinite(u) and np.isfinite(v)):
                continue
            u0, v0 = int(round(u)), int(round(v))
            sl = (slice(max(v0 - half, 0), min(v0 + half + 1, h)), slice(max(u0 - half, 0), min(u0 + half + 1, w)))
            patch = frame[sl].astype(np.float32)
            if self.dark is not None:
                patch -= self.dark[sl]
            b, r = float(patch[..., 0].sum()), float(patch[..., 2].sum())
            out[i] = r > 0 and b >= self.params.white_blue_ratio * r
        return out

    def _far_lights(self, f: _Front, frame: np.ndarray) -> np.ndarray:
        """Red lights out to ``landmark_range_m`` for the landmark fit, as ground-view pixels of
        the main view (beyond its edges too): found in the wide, coarse view of the window sums
        of the front end ``f`` and refined on its dark-subtracted red channel."""
        p = self.params
        area = p.dots.window_px**2
        obst, _, _ = self._unwarp_separate(self._wide_tables, f.sums, self.wide.map_x.shape, f.leak, f.red_levels)
        far = find_red(obst, p.red, window_area=area)
        xy_m = (
            self._refine_lights(f.red, self._wide_profile.ground_to_robot(far.xy_px)) if len(far) else np.zeros((0, 2))
        )
        if p.white_blue_ratio is not None and len(xy_m):
            xy_m = xy_m[~self._white(frame, xy_m)]
        return self.profile.robot_to_ground(xy_m)

    def _refine_lights(self, red: np.ndarray, xy_m: np.ndarray, *, half: int = 6) -> np.ndarray:
        """Robot-frame positions of red lights found in the coarse wide view, refined on the
        full-resolution mirror image: the centroid of the pixels above half the peak in a patch
        around each (a far light covers a few pixels there, each ~2 cm of floor at 0.85 m, so
        the coarse view alone is off by up to a centimetre). Lights that cannot be refined (at
        the image edge, nothing above the pedestal) are dropped."""
        uv = self.profile.robot_to_image(xy_m)
        h, w = red.shape
        ped = float(self.pedestal)
        out = []
        for u, v in uv:
            if not (np.isfinite(u) and np.isfinite(v)):
                continue
            u0, v0 = int(round(u)), int(round(v))
            if u0 - half < 0 or v0 - half < 0 or u0 + half >= w or v0 + half >= h:
                continue
            patch = red[v0 - half : v0 + half + 1, u0 - half : u0 + half + 1].astype(np.float32) - ped
            top = float(patch.max())
            if top <= 0:
                continue
            wgt = np.maximum(patch - 0.5 * top, 0.0)
            yy, xx = np.mgrid[-half : half + 1, -half : half + 1]
            tot = float(wgt.sum())
            out.append((u0 + float((xx * wgt).sum()) / tot, v0 + float((yy * wgt).sum()) / tot))
        if not out:
            return np.zeros((0, 2))
        xy = self.profile.image_to_robot(np.array(out))
        return xy[np.isfinite(xy).all(axis=1)]

    def ground_view(self, image: np.ndarray) -> np.ndarray:
        """8-bit colour ground view of an image, as the stages see it (window means; a 16-bit
        image scaled by :func:`display_scale`)."""
        w = self.params.dots.window_px
        return cv2.convertScaleAbs(unwarp(window_sums(image, w), self.umap), alpha=display_scale(image) / (w * w))


def bench_pipeline(camera, board, layer, pose, *, frames: int, rng, profile: Profile) -> dict:
    """Median per-frame and per-stage times of the pipeline on rendered frames (one core)."""
    dark = camera.median_dark(8, rng=rng)
    lights = board.red_lights_m()
    imgs = [camera.render(pose, rng=rng, phosphor=layer, red_lights_m=lights).image for _ in range(8)]
    pipe = Pipeline(profile, dark=dark)
    pipe.process(imgs[0])
    totals, stages = [], {s: [] for s in STAGES}
    cpu0 = time.thread_time_ns()
    for i in range(frames):
        r = pipe.process(imgs[i % len(imgs)])
        totals.append(r.total_ms)
        for k, v in r.stage_ms.items():
            stages[k].append(v)
    cpu_ms = (time.thread_time_ns() - cpu0) / 1e6 / frames
    return {
        "pipeline_ms_per_frame": float(np.median(totals)),
        "pipeline_ms_p90": float(np.percentile(totals, 90)),
        # CPU time of this thread per frame: what the pipeline costs when other processes share
        # the core (wall-clock medians then include their turns)
        "pipeline_cpu_ms_per_frame": float(cpu_ms),
        "stage_ms": {k: float(np.median(v)) for k, v in stages.items()},
    }
