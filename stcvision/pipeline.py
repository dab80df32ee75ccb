"""The pipeline runner: raw frame -> dots, heading, cell observation, with per-stage timing.

Stages (``stcvision.stages``), in the order they run::

    dark      subtract the dark frame (saturating, with a pedestal), mask hot pixels
    window    sums over the dot-sized square, in the mirror image (filter once)
    unwarp    phi/theta remap of the window sums to the ground view (one cv2.remap)
    channels  red-light mask: obstacle and marks images
    dots      window-mean dot search with black-out
    red       red-light blobs
    heading   line fit through the newest mark row
    observe   five boxes, visited sub-cells, four neighbours

The runner is built once per profile (remap table, cell homography); ``process`` allocates only
the images it returns. Logging (``stcvision.rr``) observes the result afterwards.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import cv2
import numpy as np

from stcvision.observation import CellGeometry, CellObservation, ObservationParams, observe_cell
from stcvision.profile import Profile
from stcvision.stages import (
    ChannelParams,
    DotParams,
    Dots,
    HeadingFit,
    HeadingParams,
    RedLights,
    RedParams,
    RowParams,
    UnwarpMap,
    check_frame,
    estimate_background,
    find_dots,
    find_red,
    find_rows,
    fit_heading,
    hot_pixels,
    noise_gain,
    separate_channels,
    subtract_dark,
    unwarp,
    window_sums,
)

__all__ = ["Pipeline", "PipelineParams", "PipelineResult", "STAGES"]

STAGES = ("dark", "window", "unwarp", "channels", "dots", "rows", "red", "heading", "observe")


@dataclass(frozen=True, kw_only=True, slots=True)
class PipelineParams:
    """Parameters of every stage. ``pedestal_dn``: offset kept by the dark subtraction so the
    background noise stays measurable (see :func:`~stcvision.stages.subtract_dark`)."""

    pedestal_dn: int = 10
    channels: ChannelParams = field(default_factory=ChannelParams)
    dots: DotParams = field(default_factory=DotParams)
    rows: RowParams = field(default_factory=RowParams)
    red: RedParams = field(default_factory=RedParams)
    heading: HeadingParams = field(default_factory=HeadingParams)
    observation: ObservationParams = field(default_factory=ObservationParams)
    #: rotate the cell regions by the measured heading error before reading the boxes
    use_heading: bool = True


@dataclass(frozen=True, eq=False)
class PipelineResult:
    """Everything one frame gave, plus the intermediate images (references, not copies).

    ``green`` and ``red_raw`` are the dark-subtracted mirror-image channels; ``obstacle`` and
    ``marks`` the ground-view images of window sums (uint16, ``window_area`` pixels each).
    Display images (8-bit window means, the colour dark-subtracted frame) are made on demand.
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

    @property
    def dark_subtracted(self) -> np.ndarray:
        """The colour frame after dark subtraction (for display; the stages split channels)."""
        if self.dark is None:
            return self.frame
        return subtract_dark(self.frame, self.dark, pedestal_dn=self.pedestal_dn)

    def _u8(self, img: np.ndarray) -> np.ndarray:
        return cv2.convertScaleAbs(img, alpha=1.0 / self.window_area)

    def obstacle_u8(self) -> np.ndarray:
        return self._u8(self.obstacle)

    def marks_u8(self) -> np.ndarray:
        return self._u8(self.marks)

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
            "stage_ms": {k: round(v, 4) for k, v in self.stage_ms.items()},
            "total_ms": round(self.total_ms, 4),
        }
        return out


class Pipeline:
    """Build once per profile, then ``process`` frames.

    Parameters
    ----------
    profile : Profile
    params : PipelineParams
    dark : (H, W, 3) uint8, optional -- the dark frame for every ``process`` call.
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
        self.dark = None
        # the wide, coarse ground view for far red-light landmarks (pose estimates only)
        self.wide = None
        if self.params.observation.pose_estimates and self.params.observation.landmark_range_m > 0:
            reach = self.params.observation.landmark_range_m + 0.1
            n = 160
            self._wide_profile = profile.replace(ground_size_px=n, ground_px_per_m=(n - 1) / (2 * reach))
            self.wide = UnwarpMap.from_profile(self._wide_profile)
        if dark is not None:
            self.set_dark(dark)

    def set_dark(self, dark: np.ndarray) -> None:
        """Use ``dark`` (H, W, 3) uint8 from now on: split it once, map its hot pixels once."""
        check_frame(dark, "dark frame")
        self.profile.check_frame(dark.shape)
        self.dark = dark
        self._dark_g = cv2.extractChannel(dark, 1)
        self._dark_r = cv2.extractChannel(dark, 2)
        hot = hot_pixels(dark)
        self._hot_g = hot[hot % 3 == 1] // 3  # flat indices into one channel
        self._hot_r = hot[hot % 3 == 2] // 3

    def _channel(self, frame: np.ndarray, ch: int) -> np.ndarray:
        c = cv2.extractChannel(frame, ch)
        if self.dark is None:
            return c
        ped = self.params.pedestal_dn
        c = cv2.subtract(cv2.add(c, ped), self._dark_g if ch == 1 else self._dark_r)
        c.reshape(-1)[self._hot_g if ch == 1 else self._hot_r] = ped  # defect-pixel map
        return c

    def process(
        self,
        frame: np.ndarray,
        *,
        dark: np.ndarray | None = None,
        heading_error_rad: float | None = None,
        position_offset: tuple[float, float] | None = None,
    ) -> PipelineResult:
        """Run every stage on one (H, W, 3) uint8 BGR frame.

        ``heading_error_rad``: read the cell with this heading error instead of this frame's own
        fit -- e.g. the fit of a short frame taken at the same pose, for a long one in which
        every recent row saturates (the newest row is then no longer the brightest).
        ``position_offset``: read the cell with the robot this far off its sub-cell centre
        (:func:`stcvision.observation.observe_cell`) instead of where this frame's marks say."""
        check_frame(frame)
        self.profile.check_frame(frame.shape)
        if dark is not None and dark is not self.dark:
            self.set_dark(dark)
        p = self.params
        w = p.dots.window_px
        area = w * w
        clock = time.perf_counter_ns
        t = [clock()]
        g = self._channel(frame, 1)  # only green and red carry marks and lights
        r = self._channel(frame, 2)
        t.append(clock())
        gs, rs = window_sums(g, w), window_sums(r, w)
        t.append(clock())
        G, R = unwarp(gs, self.umap), unwarp(rs, self.umap)
        t.append(clock())
        # background and noise, measured on raw pixels inside the rim
        bg, noise = estimate_background(g, self._sample)
        bg_r, noise_r = estimate_background(r, self._sample)
        leak = area * bg_r + p.channels.leak_k_sigma * max(noise_r, 0.3) * w
        obstacle, marks = separate_channels(G, R, p.channels, window_area=area, leak_threshold=leak)
        t.append(clock())
        dots = find_dots(
            marks,
            p.dots,
            gain=self.gain,
            background_dn=bg,
            noise_dn=noise,
            ground_to_robot=self.profile.ground_to_robot,
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
        )
        t.append(clock())
        red = find_red(obstacle, p.red, window_area=area)
        t.append(clock())
        heading = fit_heading(dots, p.heading)
        t.append(clock())
        landmark_px = self._far_lights(gs, rs, r, leak) if self.wide is not None else None
        herr = heading.heading_error_rad if (heading.ok and p.use_heading) else 0.0
        if heading_error_rad is not None:
            herr = float(heading_error_rad)
        obs = observe_cell(
            all_dots,
            red.xy_px,
            red.peak_dn,
            self.geometry,
            red_threshold_dn=p.channels.red_threshold_dn,
            heading_error_rad=herr,
            params=p.observation,
            landmark_px=landmark_px,
            subcell_m=self.profile.subcell_m,
            position_offset=position_offset,
        )
        t.append(clock())
        stage_ms = {name: (t[i + 1] - t[i]) / 1e6 for i, name in enumerate(STAGES)}
        return PipelineResult(
            frame, self.dark, p.pedestal_dn, g, r, obstacle, marks, all_dots, red, heading, obs, stage_ms, area
        )

    def _far_lights(self, gs: np.ndarray, rs: np.ndarray, red: np.ndarray, leak: float) -> np.ndarray:
        """Red lights out to ``landmark_range_m`` for the landmark fit, as ground-view pixels of
        the main view (beyond its edges too): found in the wide, coarse view of the window sums
        ``gs``, ``rs`` and refined on the dark-subtracted red channel ``red``."""
        p = self.params
        area = p.dots.window_px**2
        obst, _ = separate_channels(
            unwarp(gs, self.wide), unwarp(rs, self.wide), p.channels, window_area=area, leak_threshold=leak
        )
        far = find_red(obst, p.red, window_area=area)
        xy_m = self._refine_lights(red, self._wide_profile.ground_to_robot(far.xy_px)) if len(far) else np.zeros((0, 2))
        return self.profile.robot_to_ground(xy_m)

    def _refine_lights(self, red: np.ndarray, xy_m: np.ndarray, *, half: int = 6) -> np.ndarray:
        """Robot-frame positions of red lights found in the coarse wide view, refined on the
        full-resolution mirror image: the centroid of the pixels above half the peak in a patch
        around each (a far light covers a few pixels there, each ~2 cm of floor at 0.85 m, so
        the coarse view alone is off by up to a centimetre). Lights that cannot be refined (at
        the image edge, nothing above the pedestal) are dropped."""
        uv = self.profile.robot_to_image(xy_m)
        h, w = red.shape
        ped = float(self.params.pedestal_dn)
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
        """8-bit colour ground view of an image, as the stages see it (window means)."""
        w = self.params.dots.window_px
        return cv2.convertScaleAbs(unwarp(window_sums(image, w), self.umap), alpha=1.0 / (w * w))


def bench_pipeline(camera, board, layer, pose, *, frames: int, rng, profile: Profile) -> dict:
    """Median per-frame and per-stage times of the pipeline on rendered frames (one core)."""
    dark = camera.median_dark(8, rng=rng)
    lights = board.red_lights_m()
    imgs = [camera.render(pose, rng=rng, phosphor=layer, red_lights_m=lights).image for _ in range(8)]
    pipe = Pipeline(profile, dark=dark)
    pipe.process(imgs[0])
    totals, stages = [], {s: [] for s in STAGES}
    for i in range(frames):
        r = pipe.process(imgs[i % len(imgs)])
        totals.append(r.total_ms)
        for k, v in r.stage_ms.items():
            stages[k].append(v)
    return {
        "pipeline_ms_per_frame": float(np.median(totals)),
        "pipeline_ms_p90": float(np.percentile(totals, 90)),
        "stage_ms": {k: float(np.median(v)) for k, v in stages.items()},
    }
