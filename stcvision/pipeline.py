"""The pipeline runner: raw frame -> dots, heading, cell observation, with per-stage timing.

Stages (``stcvision.stages``), in the order they run::

    dark      green and red of the frame, dark frame subtracted (saturating, with a pedestal),
              hot pixels masked; the frame's background and noise
    window    sums over the dot-sized square, in the mirror image (filter once)
    unwarp    phi/theta remap of the window sums to the ground view, and the red/green test
              per ground pixel (one compiled pass: obstacle and marks images; with the pose
              estimates also the wide view's obstacle image)
    channels  the red lights' black-out margin in the marks image
    dots      window-mean dot search with black-out; centroids on the mirror image
    red       red-light blobs; white lights told from red on the raw frame; far red lights
              (landmarks) in a wide view, refined on the mirror image
    heading   line fit through the newest mark row
    observe   five boxes, visited sub-cells, four neighbours

The runner is built once per profile: its front end (:class:`stcvision.stages.front.FrontEnd`:
the remap tables, the background sample; rebuilt for each dark frame) and the cell homography;
``process`` allocates only the images it returns, besides the scratch images it lends the stages
(:class:`stcvision.stages.Scratch`, so one ``Pipeline`` per thread). Each stage's module chooses
its compiled path itself; the window sums of green and red are one two-channel image, which the
unwarp gathers both channels of at once. Each stage is timed under its own name
(:class:`stcvision.stages.StageTimes`). Logging (``stcvision.rr``) observes the result
afterwards.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import cv2
import numpy as np

from stcvision.observation import CellGeometry, CellObservation, ObservationParams, observe_cell
from stcvision.profile import Profile
from stcvision.stages import (
    DARK_ROOM_MAX_STRUCTURE,
    ChannelParams,
    DotParams,
    Dots,
    HeadingFit,
    HeadingParams,
    RedLights,
    RedParams,
    RowParams,
    Scratch,
    StageTimes,
    UnwarpMap,
    check_dark_dtype,
    check_frame,
    find_dots,
    find_rows,
    fit_heading,
    frame_structure,
    mirror_centroids,
    noise_floor,
    noise_gain,
    subtract_dark,
    unwarp,
    window_sums,
)
from stcvision.stages.dark import MIN_PROBE_AGREEMENT, STRUCTURE_BLOCK_PX, hot_pixel_probe, probe_agreement
from stcvision.stages.front import FrontEnd
from stcvision.stages.red import read_red

__all__ = ["Pipeline", "PipelineParams", "PipelineResult", "STAGES", "display_scale"]

STAGES = ("dark", "window", "unwarp", "channels", "dots", "rows", "red", "heading", "observe")


@dataclass(frozen=True, kw_only=True, slots=True)
class PipelineParams:
    """Parameters of every stage.

    The pedestal is the offset kept by the dark subtraction so the background noise stays
    measurable (see :func:`~stcvision.stages.subtract_dark`): ``pedestal_k_sigma`` times the
    dark frame's robust spread (its fixed pattern and noise; the residual after subtraction is
    no wider), and at least ``pedestal_steps`` quantisation steps (10 DN on the webcam, whose
    dark frame spreads by ~1.5 DN), in whole steps.

    Attributes
    ----------
    pedestal_steps : int
        The pedestal's least size, in quantisation steps.
    pedestal_k_sigma : float
        The pedestal in multiples of the dark frame's robust spread.
    channels, dots, rows, red, heading, observation
        The parameters of the stage of that name (:class:`~stcvision.stages.ChannelParams`,
        :class:`~stcvision.stages.DotParams`, :class:`~stcvision.stages.RowParams`,
        :class:`~stcvision.stages.RedParams`, :class:`~stcvision.stages.HeadingParams`,
        :class:`~stcvision.observation.ObservationParams`).
    use_heading : bool
        Rotate the cell regions by the measured heading error before reading the boxes.
    white_blue_ratio : float or None
        A "red" blob whose blue is at least this fraction of its red (dark-subtracted, 9x9 px
        around it in the camera frame) is white light, not a red LED: not an obstacle light nor a
        landmark. None: off. Measured on the webcam's short frame (1/30 s, gain 16): a red light
        0.12-1.0 m away reads 0.84-0.13 (its blue is 2 % of its red, but it saturates), a white
        lamp 0.99-1.0 at every distance. In long frames every red light saturates white: use it
        on short frames only.
    """

    pedestal_steps: int = 10
    pedestal_k_sigma: float = 6.0
    channels: ChannelParams = field(default_factory=ChannelParams)
    dots: DotParams = field(default_factory=DotParams)
    rows: RowParams = field(default_factory=RowParams)
    red: RedParams = field(default_factory=RedParams)
    heading: HeadingParams = field(default_factory=HeadingParams)
    observation: ObservationParams = field(default_factory=ObservationParams)
    use_heading: bool = True
    white_blue_ratio: float | None = None

    def at_pixel_scale(self, k: float) -> PipelineParams:
        """Return these parameters for frames ``k`` times the resolution they were set for.

        The settings in mirror-image pixels follow the scale so that they cover the same floor:
        the dot window (its side rounded, at least one pixel), the mirror-image centroid's
        Gaussian and square. Settings in ground-view pixels (the black-out, the centroid's
        square there, the rows' spacing) and in noise sigmas do not change: the ground view is
        in metres and the noise model follows the frames (:func:`~stcvision.stages.noise_gain`).

        Parameters
        ----------
        k : float
            The frames' pixels per pixel of the camera these parameters were set for.

        Returns
        -------
        PipelineParams
            The scaled parameters (these when ``k`` is 1).
        """
        if k == 1.0:
            return self
        d = self.dots
        return dataclasses.replace(
            self,
            dots=dataclasses.replace(
                d,
                window_px=max(1, round(d.window_px * k)),
                mirror_sigma_px=d.mirror_sigma_px * k,
                mirror_half_px=max(1, round(d.mirror_half_px * k)),
            ),
        )


def display_scale(frame: np.ndarray) -> float:
    """Return the factor taking ``frame``'s values (or window means of them) to 8 bits for display.

    1 for a uint8 frame; for a 16-bit one, whatever its ADC depth and alignment, its brightest
    pixel maps to 255.
    """
    if frame.dtype == np.uint8:
        return 1.0
    return 255.0 / max(float(frame.max()), 1.0)


#: a frame whose background is this many noise sigmas above the dark level is not read as a
#: dark-room frame (:meth:`Pipeline._lit_frame`, with the measured margins on each side)
LIT_BACKGROUND_K_SIGMA = 3.0
#: a background at this share of full scale or more is an overexposed frame (nothing of a dark
#: floor is left to read marks against)
SATURATED_BACKGROUND = 0.9


@dataclass(frozen=True, eq=False)
class PipelineResult:
    """Everything one frame gave, plus the intermediate images (references, not copies).

    ``green`` and ``red_raw`` are the dark-subtracted mirror-image channels (of the part of the
    frame the ground view reads, ``Pipeline.crop``: about half the frame); ``obstacle`` and
    ``marks`` the ground-view images of window sums (``window_area`` pixels each: uint16 from an
    8-bit frame, float32 from a 16-bit one). Display images (8-bit window means, the colour
    dark-subtracted frame) are made on demand. ``untrusted``: why this frame's reading cannot
    be trusted ("" when it can).

    Attributes
    ----------
    frame : numpy.ndarray
        The (H, W, 3) BGR frame as it came in.
    dark : numpy.ndarray or None
        The dark frame subtracted from it (None: none).
    pedestal_dn : int
        The pedestal the dark subtraction kept (DN).
    green, red_raw : numpy.ndarray
        The dark-subtracted green and red of the mirror image's crop.
    obstacle, marks : numpy.ndarray
        The ground-view images of window sums: red lights and obstacles, phosphor marks.
    dots : Dots
        Every dot found, with the rows' own.
    red : RedLights
        The red lights (obstacles) found.
    heading : HeadingFit
        The line fit through the newest mark row.
    observation : CellObservation
        The cell's reading: boxes, visited sub-cells, neighbours.
    stage_ms : dict of str to float
        Each stage's time (ms), under its name, in the order they ran (:data:`STAGES`).
    window_area : int
        Pixels per window sum (the dot window's side squared).
    white_lights_m : numpy.ndarray
        (N, 2) robot-frame positions (m) of the white lights (not red:
        :attr:`PipelineParams.white_blue_ratio`) this frame showed.
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
        """Return the obstacle image as 8-bit window means, for display.

        Returns
        -------
        numpy.ndarray
            The ground view's obstacle image, uint8.
        """
        return self._u8(self.obstacle)

    def marks_u8(self) -> np.ndarray:
        """Return the marks image as 8-bit window means, for display.

        Returns
        -------
        numpy.ndarray
            The ground view's marks image, uint8.
        """
        return self._u8(self.marks)

    @property
    def untrusted(self) -> str:
        """Why this frame's reading cannot be trusted ("" when it can)."""
        return self.dots.untrusted

    @property
    def total_ms(self) -> float:
        """The time of every stage together (ms)."""
        return float(sum(self.stage_ms.values()))

    def to_dict(self, profile: Profile | None = None) -> dict:
        """Return the frame's reading as plain JSON-ready values.

        Parameters
        ----------
        profile : Profile, optional
            Not read: the reading carries its own robot-frame positions.

        Returns
        -------
        dict
            The lit dots (pixel and robot-frame positions, strength, SNR), the dot threshold,
            noise and background, the heading fit, the obstacles, the cell observation, the
            untrusted reason and the stage times (ms).
        """
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


class Pipeline:
    """The vision pipeline: build once per profile, then ``process`` frames.

    Parameters
    ----------
    profile : Profile
        The camera's profile: the mirror's geometry, the ground view, the cell homography.
    params : PipelineParams, optional
        Every stage's parameters (the defaults when None).
    dark : numpy.ndarray, optional
        (H, W, 3) uint8 or uint16 (the frames' dtype): the dark frame for every ``process`` call.
    """

    def __init__(
        self, profile: Profile, params: PipelineParams | None = None, *, dark: np.ndarray | None = None
    ) -> None:
        self.profile = profile
        # a profile rescaled to another resolution carries the scale: the parameters, set for
        # the calibrated camera's pixels, follow it
        self.params = (params or PipelineParams()).at_pixel_scale(profile.pixel_scale)
        p = self.params
        # the wide, coarse ground view for far red-light landmarks (pose estimates only)
        wide = p.observation.pose_estimates and p.observation.landmark_range_m > 0
        self.front = FrontEnd.from_profile(
            profile,
            channels=p.channels,
            window_px=p.dots.window_px,
            pedestal_steps=p.pedestal_steps,
            pedestal_k_sigma=p.pedestal_k_sigma,
            wide_reach_m=p.observation.landmark_range_m + 0.1 if wide else None,
        )
        self.geometry = CellGeometry.from_profile(profile)
        self.gain = noise_gain(self.umap, p.dots.window_px)
        resampled = _resampled_from(profile)
        #: a resized frame's noise: the gain of the noise the resize spread (None: not resized)
        self.gain_resampled = (
            None if resampled is None else noise_gain(self.umap, p.dots.window_px, resampled_from=resampled)
        )
        #: the stages' scratch arrays, reused from frame to frame (never one a result holds)
        self.scratch = Scratch()
        if dark is not None:
            self.set_dark(dark)

    @property
    def umap(self) -> UnwarpMap:
        """The main ground view's unwarp map (of the whole mirror image)."""
        return self.front.umap

    @property
    def wide(self) -> UnwarpMap | None:
        """The wide view's unwarp map (None without the pose estimates)."""
        return self.front.wide

    @property
    def crop(self) -> tuple[int, int, int, int]:
        """(x0, y0, x1, y1): the part of the mirror image the stages read."""
        return self.front.crop

    @property
    def dark(self) -> np.ndarray | None:
        """The dark frame every ``process`` call subtracts (None: none).

        Setting it is :meth:`set_dark`, or with None forgets it.
        """
        return self.front.dark.frame

    @dark.setter
    def dark(self, dark: np.ndarray | None) -> None:
        if dark is None:
            self.front = self.front.with_dark(None)
        else:
            self.set_dark(dark)

    def _probe(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the dark frame's hot-pixel probe, measured once per dark frame.

        See :func:`stcvision.stages.dark.hot_pixel_probe`.
        """
        dark = self.dark
        if getattr(self, "_probe_of", None) is not dark:
            self._probe_of, self._probe_px = dark, hot_pixel_probe(dark)
        return self._probe_px

    @property
    def pedestal(self) -> int:
        """The pedestal the dark subtraction keeps (DN; 0 without a dark frame)."""
        return self.front.dark.pedestal

    @property
    def quantum(self) -> int:
        """The frames' quantisation step (DN), taken from the dark frame."""
        return self.front.dark.quantum

    @property
    def dark_sigma(self) -> float:
        """The dark frame's robust spread (DN)."""
        return self.front.dark.sigma

    def set_dark(self, dark: np.ndarray) -> None:
        """Use ``dark`` as the dark frame from now on.

        Split it once, map its hot pixels once, and take from it the quantisation step and the
        pedestal.

        Parameters
        ----------
        dark : numpy.ndarray
            (H, W, 3) uint8 or uint16, the frames' dtype and shape.

        Raises
        ------
        BadInputError
            When ``dark`` is not a frame of the profile's shape and a frame dtype.
        """
        check_frame(dark, "dark frame")
        self.profile.check_frame(dark.shape, what="dark frame")
        self.front = self.front.with_dark(dark)

    def _lit_frame(self, bg: float, noise: float, frame: np.ndarray) -> str:
        """Say why a frame is not a dark-room frame this pipeline can read ("" when it is).

        Overexposed; showing a scene (:func:`stcvision.stages.frame_structure`); not showing the
        dark frame's hot pixels (another camera); or its
        background (the median of the view, where the floor is unmarked and so dark) more than
        :data:`LIT_BACKGROUND_K_SIGMA` noise sigmas above the dark level. With a dark frame that
        level is the pedestal: measured, dark-room frames of every camera sit at 0.0 sigma and
        lit calibration frames at 16-18. Without one it is zero, and the sensor's own dark signal
        and fixed pattern stay in the frame: webcam, low-light and cooled frames sat at 5.6, 6.3
        and 26 sigma and gave 61-64 dots where the truth had 16.
        """
        full = float(np.iinfo(frame.dtype).max)
        if bg >= SATURATED_BACKGROUND * full:
            return f"the frame's background is at {bg:.0f} of {full:.0f}: overexposed, not a dark-room frame"
        # a lit, textured room inflates the noise estimate as much as its level, so the level
        # test above cannot see it; its structure can. A frame whose pixels spread less than the
        # limit cannot spread more over blocks (a mean varies less than what it averages), so
        # the measure is only taken on frames that might fail it
        if noise >= DARK_ROOM_MAX_STRUCTURE * full:
            structure = frame_structure(frame, block_px=max(1, round(STRUCTURE_BLOCK_PX * self.profile.pixel_scale)))
            if structure > DARK_ROOM_MAX_STRUCTURE:
                return (
                    f"the frame shows a scene ({100 * structure:.1f} % of full scale of structure over "
                    f"{STRUCTURE_BLOCK_PX}-px blocks, a dark room shows under {100 * DARK_ROOM_MAX_STRUCTURE:g} %): "
                    "a lit frame (lights on), not a dark-room frame"
                )
        if self.dark is not None:
            seen = probe_agreement(frame, self._probe())
            if seen is not None and seen < MIN_PROBE_AGREEMENT:
                return (
                    f"the frame shows {100 * seen:.0f} % of the dark frame's hot pixels (a frame of its camera at "
                    f"its settings shows them all): a dark frame of another camera or of other settings"
                )
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

    def _dots_and_rows(self, f, frame: np.ndarray, times: StageTimes):
        """Run the dots and rows stages on the front end's output ``f``, each timed under its name.

        Returns (the dots, every dot with the rows' own); a frame that is not a dark room's
        (``frame``, the raw frame: :meth:`_lit_frame`) marks the reading untrusted.
        """
        p, w = self.params, self.params.dots.window_px
        marks, g, bg, noise, q = f.marks, f.green, f.bg, f.noise, f.quantum
        g2r = self.profile.ground_to_robot
        gain = self._gain(noise, q)
        with times("dots"):
            dots = find_dots(  # robot-frame positions from the mirror-image centroids when they run
                marks,
                p.dots,
                gain=gain,
                background_dn=bg,
                noise_dn=noise,
                ground_to_robot=None if p.dots.mirror_sigma_px > 0 else g2r,
                quantum=q,
            )
            dots = mirror_centroids(  # g is the crop the view reads: its own map
                dots,
                g,
                background_dn=bg,
                umap=self.front.umap_crop,
                ground_to_robot=self.profile.ground_to_robot,
                params=p.dots,
            )
        with times("rows"):
            all_dots = find_rows(
                marks,
                dots,
                gain=gain,
                background_dn=bg,
                noise_dn=noise,
                px_per_m=self.profile.ground_px_per_m,
                window_px=w,
                params=p.rows,
                dot_params=p.dots,
                ground_to_robot=self.profile.ground_to_robot,
                quantum=q,
                buffers=self.scratch,
            )
            lit = self._lit_frame(bg, noise, frame)
            if lit and not all_dots.untrusted:
                all_dots = dataclasses.replace(all_dots, untrusted=lit)
        return dots, all_dots

    def _gain(self, noise: float, quantum: int) -> np.ndarray:
        """Return the noise gain map for a frame of per-pixel ``noise`` (DN) and quantisation step.

        For a frame resized from the calibrated camera's, its noise is two parts: what the resize
        spread over neighbours, and the rounding of the resized frame and of its dark frame to
        whole steps, which is fresh at every pixel. Their variances add, each with its own gain.
        """
        if self.gain_resampled is None:
            return self.gain
        fresh = min(2.0 * noise_floor(quantum) ** 2, noise * noise)
        spread = noise * noise - fresh
        var = spread * self.gain_resampled**2 + fresh * self.gain**2
        return np.sqrt(var, dtype=np.float32) / np.float32(max(noise, 1e-9))

    def process(
        self,
        frame: np.ndarray,
        *,
        dark: np.ndarray | None = None,
        heading_error_rad: float | None = None,
        position_offset: tuple[float, float] | None = None,
    ) -> PipelineResult:
        """Run every stage on one frame.

        Not re-entrant: one ``Pipeline`` per thread (the front end's scratch images are its own).

        Parameters
        ----------
        frame : numpy.ndarray
            (H, W, 3) uint8 or uint16 BGR frame (a uint16 frame holds an ADC's counts; the dark
            frame must have the frame's dtype).
        dark : numpy.ndarray, optional
            A dark frame to use from now on (:meth:`set_dark`) before reading this one.
        heading_error_rad : float, optional
            Read the cell with this heading error instead of this frame's own fit -- e.g. the fit
            of a short frame taken at the same pose, for a long one in which every recent row
            saturates (the newest row is then no longer the brightest).
        position_offset : tuple of float, optional
            Read the cell with the robot this far off its sub-cell centre
            (:func:`stcvision.observation.observe_cell`) instead of where this frame's marks say.

        Returns
        -------
        PipelineResult
            Everything the frame gave, with each stage's time.

        Raises
        ------
        BadInputError
            When the frame (or the dark frame) is not a frame of the profile's shape, or their
            dtypes differ.
        """
        check_frame(frame)
        self.profile.check_frame(frame.shape)
        if dark is not None and dark is not self.dark:
            self.set_dark(dark)
        if self.dark is not None:
            check_dark_dtype(self.dark, frame.dtype)
        p = self.params
        w = p.dots.window_px
        area = w * w
        times = StageTimes()
        f = self.front.run(frame, self.scratch, times)
        g, r, obstacle, marks = f.green, f.red, f.obstacle, f.marks
        dots, all_dots = self._dots_and_rows(f, frame, times)
        lights = self._red_lights(f, frame, area, times)
        red = lights.lights
        with times("heading"):
            heading = fit_heading(dots, p.heading)
        obs = self._observe(f, all_dots, lights, heading, times, heading_error_rad, position_offset)
        if tuple(times.ms) != STAGES:  # every stage timed once, in order (a new stage names itself in STAGES)
            raise RuntimeError(f"stages timed {tuple(times.ms)}, expected {STAGES}")
        return PipelineResult(
            frame,
            self.dark,
            self.pedestal,
            g,
            r,
            obstacle,
            marks,
            all_dots,
            red,
            heading,
            obs,
            times.ms,
            area,
            lights.white_m,
        )

    def _red_lights(self, f, frame: np.ndarray, area: int, times: StageTimes):
        """Run the red stage on the front end's output ``f`` and the raw ``frame``, timed as "red".

        Returns the lights (:func:`stcvision.stages.red.read_red`).
        """
        p = self.params
        with times("red"):
            wide = None if f.wide_obstacle is None else (f.wide_obstacle, self.front.wide_profile.ground_to_robot)
            return read_red(
                f.obstacle,
                frame,
                p.red,
                window_area=area,
                profile=self.profile,
                dark=self.dark,
                pedestal=self.pedestal,
                red_channel=f.red,
                white_blue_ratio=p.white_blue_ratio,
                wide=wide,
            )

    def _observe(self, f, all_dots, lights, heading, times: StageTimes, heading_error_rad, position_offset):
        """Read the cell, timed as "observe".

        The heading error is the one given, else the frame's own fit (when it holds and the
        parameters use it), else none.
        """
        p = self.params
        with times("observe"):
            herr = heading.heading_error_rad if (heading.ok and p.use_heading) else 0.0
            if heading_error_rad is not None:
                herr = float(heading_error_rad)
            red = lights.lights
            return observe_cell(
                all_dots,
                red.xy_px,
                red.peak_dn,
                self.geometry,
                red_threshold_dn=p.channels.levels(*f.red_levels)[0],
                heading_error_rad=herr,
                params=p.observation,
                landmark_px=lights.landmark_px,
                subcell_m=self.profile.subcell_m,
                position_offset=position_offset,
            )

    def ground_view(self, image: np.ndarray) -> np.ndarray:
        """Return the 8-bit colour ground view of an image, as the stages see it.

        Window means; a 16-bit image scaled by :func:`display_scale`.

        Parameters
        ----------
        image : numpy.ndarray
            (H, W, 3) uint8 or uint16 image of the camera.

        Returns
        -------
        numpy.ndarray
            The ground view, uint8.
        """
        w = self.params.dots.window_px
        return cv2.convertScaleAbs(unwarp(window_sums(image, w), self.umap), alpha=display_scale(image) / (w * w))


#: the OpenCV interpolation a profile's ``resampling`` names (:data:`stcvision.profile.RESAMPLINGS`)
_INTERPOLATION = {"area": cv2.INTER_AREA, "linear": cv2.INTER_LINEAR}


def _resampled_from(profile: Profile):
    """``((W, H), interpolation)`` a rescaled profile's frames were resized from (None: not resized)."""
    if profile.resampling == "none":
        return None
    w, h = profile.image_size_px
    k = profile.pixel_scale
    return (max(1, round(w / k)), max(1, round(h / k))), _INTERPOLATION[profile.resampling]


def bench_pipeline(camera, board, layer, pose, *, frames: int, rng, profile: Profile) -> dict:
    """Measure the median per-frame and per-stage times of the pipeline on rendered frames (one core)."""
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
