"""The front end: the four stages that run on the whole frame before the dot search, put
together -- dark (:mod:`~stcvision.stages.dark`), window (:mod:`~stcvision.stages.window`),
unwarp (:mod:`~stcvision.stages.ground_view`) and channels (:mod:`~stcvision.stages.channels`).

:class:`FrontEnd` is built once from the profile and the dark frame; :meth:`FrontEnd.run` runs
the four stages on a frame, each timed under its own name.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from stcvision.stages.channels import ChannelParams, black_out, black_out_margin, separation_rule
from stcvision.stages.common import Scratch, StageTimes, noise_floor
from stcvision.stages.dark import DarkFrame, dark_channels, frame_background
from stcvision.stages.ground_view import GatherTables, UnwarpMap, unwarp_separate
from stcvision.stages.window import window_sums


class FrontOutput(NamedTuple):
    """What the front end (:meth:`FrontEnd.run`) gives the later stages: the dark-subtracted
    green and red of the crop, their window sums (scratch), the ground views ``obstacle`` and
    ``marks``, the frame's green background and noise, the quantisation step, the red lights'
    levels and the leak level (:func:`separation_rule`), and the wide view's obstacle image
    ``wide_obstacle`` (None without a wide view)."""

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
    wide_obstacle: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class FrontEnd:
    """The pipeline's front end, built once from the profile (:meth:`from_profile`) and the
    dark frame (:meth:`with_dark`): the unwarp map and its gather tables for the crop of the
    mirror image the ground view reads (the whole frame when a wide view is made too), the
    background sample, the black-out margin, and the dark frame's channels and hot pixels."""

    umap: UnwarpMap
    crop: tuple[int, int, int, int]
    umap_crop: UnwarpMap
    tables: GatherTables
    #: raw pixels inside the mirror rim, sparsely, as flat indices into a BGR frame per channel
    sample3: dict
    channels: ChannelParams
    window_px: int
    margin: np.ndarray | None
    pedestal_steps: int
    pedestal_k_sigma: float
    #: the wide, coarse ground view for far red-light landmarks (None: not made)
    wide: UnwarpMap | None = None
    wide_profile: object = None
    wide_tables: GatherTables | None = None
    dark: DarkFrame = field(default_factory=DarkFrame)

    @classmethod
    def from_profile(
        cls,
        profile,
        *,
        channels: ChannelParams,
        window_px: int,
        pedestal_steps: int,
        pedestal_k_sigma: float,
        wide_reach_m: float | None = None,
        wide_size_px: int = 160,
    ) -> FrontEnd:
        """``wide_reach_m``: also a wide view of ``wide_size_px`` pixels reaching this far."""
        umap = UnwarpMap.from_profile(profile)
        w, h = profile.image_size_px
        vv, uu = np.mgrid[0:h:5, 0:w:5]
        inside = np.hypot(uu - profile.center_px[0], vv - profile.center_px[1]) < 0.95 * profile.rim_radius_px
        sample = (vv[inside] * w + uu[inside]).ravel()
        wide = wide_profile = wide_tables = None
        if wide_reach_m is not None:
            n = wide_size_px
            wide_profile = profile.replace(ground_size_px=n, ground_px_per_m=(n - 1) / (2 * wide_reach_m))
            wide = UnwarpMap.from_profile(wide_profile)
            wide_tables = GatherTables.from_map(wide)
        # the mirror-image stages run on the part of the mirror image the main view reads (about
        # half the frame); the wide view reads nearly the whole mirror
        crop = (0, 0, w, h) if wide is not None else umap.reach_px()
        umap_crop = umap.cropped(*crop)
        margin = black_out_margin(channels.red_margin_px)
        return cls(
            umap,
            crop,
            umap_crop,
            GatherTables.from_map(umap_crop),
            {ch: sample * 3 + ch for ch in (1, 2)},
            channels,
            window_px,
            margin,
            pedestal_steps,
            pedestal_k_sigma,
            wide,
            wide_profile,
            wide_tables,
        )

    def with_dark(self, dark: np.ndarray | None) -> FrontEnd:
        """This front end subtracting ``dark`` (None: no dark frame)."""
        if dark is None:
            return replace(self, dark=DarkFrame())
        d = DarkFrame.measure(
            dark, self.crop, self.sample3, pedestal_steps=self.pedestal_steps, pedestal_k_sigma=self.pedestal_k_sigma
        )
        return replace(self, dark=d)

    def red_levels(self, bg_r: float, noise_r: float, quantum: int) -> tuple[float, float]:
        """A red light's level: above the pedestal by the dark frame's spread (a fixed rule per
        dark frame), or without one above the frame's own red background by its noise."""
        d = self.dark
        return (d.pedestal, max(d.sigma, noise_floor(quantum))) if d.frame is not None else (bg_r, noise_r)

    def run(self, frame: np.ndarray, scratch: Scratch, times: StageTimes) -> FrontOutput:
        """The front end on one frame: the dark, window, unwarp and channels stages, each timed
        by ``times`` under its name, their scratch arrays from ``scratch``."""
        w = self.window_px
        with times("dark"):  # only green and red carry marks and lights
            g, r = dark_channels(frame, self.crop, self.dark, scratch)
            bg, noise, bg_r, noise_r, q = frame_background(frame, self.sample3, self.dark, scratch)
        with times("window"):
            sums = window_sums((g, r), w, scratch=scratch)
        with times("unwarp"):
            red_levels = self.red_levels(bg_r, noise_r, q)
            leak = w * w * bg_r + self.channels.leak_k_sigma * noise_r * w
            rule = separation_rule(self.channels, w * w, red_levels, leak, sums.dtype)
            obstacle, marks, black, n = unwarp_separate(self.tables, sums, self.umap_crop.map_x.shape, rule, scratch)
            wide = None
            if self.wide is not None:  # the same sums and rule through the wide view's tables
                # its own scratch: a wide view of the main view's size must not overwrite the
                # main view's black-out mask before the channels stage reads it
                def wide_scratch(purpose, shape, dtype):
                    return scratch("wide " + purpose, shape, dtype)

                wide = unwarp_separate(self.wide_tables, sums, self.wide.map_x.shape, rule, wide_scratch)[0]
        with times("channels"):
            black_out(marks, black, n, self.margin, scratch)
        return FrontOutput(g, r, sums, obstacle, marks, bg, noise, q, red_levels, leak, wide)
