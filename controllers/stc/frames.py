"""The robot's camera in the coverage loop: which frames it takes and what they show.

* **Exposure**: ``webcam`` (1/30 s, gain 16: the seed's camera), a fixed ``exposure_s``, or
  ``auto``: every observation takes a short webcam frame (red lights without bloom, fresh marks,
  the pose) and, where old marks may matter (returns to a parent, the looks), a long one whose
  length follows the robot's clock (:data:`AUTO_LONG`: 2-30 s, then 2 to 64 30 s frames
  stacked: frame stacking), sized for what the frame must read
  (``CoverConfig.decision_reach_m``, ``look_reach_m``, ``sizing_snr``); a mark counts if either
  frame sees it -- the seed's proposal, "a camera with a fully controlled integration time".
  Dark frames are taken once per setting, at the matching exposure (a master dark of 8n frames
  for a stack of n). Past the longest frame's horizon the robot stops ("out of sight",
  :meth:`Exposures.out_of_sight`).
* **Gain**: the seed's webcam keeps the ladder's gains (16 for the short frame, 4 for the long
  ones); any other sensor takes at each rung the lowest gain at which its frame's temporal dark
  noise spans :data:`NOISE_DN` DN (:func:`sensor_gain`: from the sensor's read noise and dark
  current, EMVA 1288 and the astronomer's rule of thumb), its frames digitised at its own ADC
  depth (16-bit frames for a 12- or 16-bit camera: :mod:`sim_camera.sensor`).
* :class:`RobotCamera`: render -> pipeline, one pipeline per exposure setting.
* :class:`IdealCamera`: the physics-limited camera, the same frames and time, but it sees
  exactly the marks within the frames' visibility horizon.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from controllers.stc.config import CoverConfig
from controllers.stc.fsm import NeighbourObs, StcObservation
from controllers.stc.oracle import MarkFloor, look_oracle, observe_oracle
from stcvision.stcgrid import NEIGHBOURS

__all__ = ["AUTO_LONG", "AUTO_REACH_M", "ROW_EQUIVALENT_STACK", "WEBCAM", "Exposures", "IdealCamera", "RobotCamera"]

#: the short frame of every observation: the seed's webcam (red lights, fresh marks, the pose):
#: (exposure_s, gain, frames averaged)
WEBCAM = (1 / 30, 16.0, 1)
#: ``--exposure auto``, long frames: (exposure_s, gain, frames averaged), shortest first. Each is
#: used while the robot's clock (the oldest age any mark can have) is within its visibility
#: horizon at the distance the frame must read (``CoverConfig.decision_reach_m``,
#: ``look_reach_m``; ``sim_camera.camera.visibility_horizon_s``: the camera's calibration of the
#: phosphor, measured once per robot). The gains are the webcam's (4 keeps its 8-bit
#: quantisation below the dark current's noise at every length); another sensor's come from
#: :func:`sensor_gain`. 60 s frames were tried and read fewer boxes than 30 s ones
#: (the fresh mark's bloom), so beyond 30 s the ladder stacks 30 s frames (issue 6: "frame
#: stacking"): averaging n frames divides the noise variance by n.
AUTO_LONG = (
    (2.0, 4.0, 1),
    (4.0, 4.0, 1),
    (8.0, 4.0, 1),
    (16.0, 4.0, 1),
    (30.0, 4.0, 1),
    *((30.0, 4.0, n) for n in (2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 24, 32, 40, 48, 64)),
)
#: the short frame's test of a red blob for white light (:attr:`stcvision.pipeline.PipelineParams.white_blue_ratio`)
WHITE_BLUE_RATIO = 0.92
#: the far side of the cell ahead (its near sub-cells' marks are 0.1-0.25 m away, its far
#: ones' up to 0.45 m): the default distance for :meth:`Exposures.horizons`
AUTO_REACH_M = 0.45


def _to_stc_obs(cell_obs) -> StcObservation:
    neigh = tuple(NeighbourObs(cell_obs.neighbours[d].has_marks, cell_obs.neighbours[d].has_red) for d in NEIGHBOURS)
    return StcObservation(
        boxes=tuple(b.lit for b in cell_obs.boxes),
        neighbours=neigh,
        start_mark=cell_obs.start_mark,
        landing_marked=tuple(cell_obs.landing_marked),
    )


def _merge(a: StcObservation, b: StcObservation) -> StcObservation:
    """What two exposures of one scene show together: a mark either one sees is there; the red
    lights come from the first (short) frame, which does not saturate them."""
    return StcObservation(
        boxes=tuple(x or y for x, y in zip(a.boxes, b.boxes, strict=True)),
        neighbours=tuple(
            NeighbourObs(x.has_marks or y.has_marks, x.has_red) for x, y in zip(a.neighbours, b.neighbours, strict=True)
        ),
        start_mark=a.start_mark if a.start_mark is not None else b.start_mark,
        landing_marked=tuple(x or y for x, y in zip(a.landing_marked, b.landing_marked, strict=True)),
    )


#: a row of four dots is accepted at a mean dot SNR of 3 (the row search's 6 sigma on the sum of
#: four, halved) where a lone dot needs Rose's 5; in the horizon that is as if (5/3)^2 frames
#: were stacked
ROW_EQUIVALENT_STACK = (5.0 / 3.0) ** 2


#: the temporal noise a frame's digitised dark level must span (DN): EMVA 1288 (Release 3.1,
#: 2016, and 4.0 Linear) holds the linear camera model's noise figures valid only where the
#: temporal dark noise is at least ~0.5 DN, below which the quantisation noise (1/12 DN^2) takes
#: over; the astronomer's rule of thumb for setting a camera's gain is to sample the read noise
#: with ~1-2 ADU (S. B. Howell, Handbook of CCD Astronomy, 2nd ed. 2006, ch. 3; both recalled,
#: not re-checked). At 1 DN the quantisation adds 1/12 of the noise variance (4 % of sigma).
NOISE_DN = 1.0


def sensor_gain(sensor, exposure_s: float, n_avg: int, webcam_gain: float) -> float:
    """The gain of a frame of ``exposure_s`` (``n_avg`` frames averaged) on ``sensor``: the lowest
    gain >= 1 at which the frame's temporal dark noise (read noise and the dark current's shot
    noise, ``sqrt(read^2 + dark * t / n)`` electrons) spans :data:`NOISE_DN` DN, so that no faint
    mark is quantised away, and no higher, so that the ADC clips as late as it can (at gain g it
    saturates at ``full_well_e / g`` electrons). The seed's webcam (an 8-bit ADC, the default
    sensor) keeps the ladder's own gains (``webcam_gain``: the seed's 16x and the issue-6 4x),
    so its frames are exactly what they were. A robot setting from the sensor's figures, not
    the world."""
    from sim_camera.sensor import SensorParams

    web = SensorParams()
    if sensor.replace(exposure_s=web.exposure_s, gain=web.gain) == web:
        return webcam_gain
    noise_e = (sensor.read_noise_e**2 + sensor.dark_current_e_s * exposure_s) ** 0.5 / n_avg**0.5
    at_unity = sensor.replace(exposure_s=exposure_s, gain=1.0).dn_per_e * noise_e
    return max(1.0, NOISE_DN / at_unity)


class Exposures:
    """The frames a robot's camera takes: the ladder of (exposure_s, gain) settings, the short
    webcam frame first, and which long rung the robot's clock asks for."""

    def __init__(self, cfg: CoverConfig):
        from sim_camera.camera import SyntheticCamera

        self.cam = SyntheticCamera(sensor=cfg.camera.sensor)
        self.cfg = cfg
        self._horizons: dict[float, tuple[float, ...]] = {}
        if cfg.exposure == "auto":
            ladder = (WEBCAM, *AUTO_LONG)
        elif cfg.exposure == "webcam":
            ladder = (WEBCAM,)
        else:
            e = float(cfg.exposure)
            ladder = ((e, max(1.0, min(16.0, 16.0 * (1 / 30) / e * 4)), 1),)
        if cfg.gain is not None and cfg.exposure not in ("auto", "webcam"):
            ladder = ((ladder[0][0], cfg.gain, 1),)
        else:
            ladder = tuple((e, sensor_gain(self.cam.sensor, e, n * cfg.n_stack, g), n) for e, g, n in ladder)
        self.ladder = ladder
        self.frames = 0
        self.long_frames = 0
        self.per_rung = [0] * len(self.ladder)  # frames taken at each rung

    def horizons(self, reach_m: float = AUTO_REACH_M) -> tuple[float, ...]:
        """The long rungs' visibility horizons (s) for a dot ``reach_m`` from the robot."""
        if reach_m not in self._horizons:
            from sim_camera.camera import ROSE_SNR, visibility_horizon_s

            eq = (ROSE_SNR / self.cfg.sizing_snr) ** 2  # as if that many more frames were stacked
            self._horizons[reach_m] = tuple(
                visibility_horizon_s(self.cam, sensor=self._sensor(k), rho_m=reach_m, n_stack=eq * self.stack(k))
                for k in range(1, len(self.ladder))
            )
        return self._horizons[reach_m]

    @property
    def controlled(self) -> bool:
        """Exposure control: long frames besides the short one."""
        return len(self.ladder) > 1

    def long_rung(self, t_s: float, reach_m: float = AUTO_REACH_M) -> int | None:
        """The ladder rung for old marks up to ``reach_m`` away at clock ``t_s``: the shortest
        whose horizon covers the oldest mark there can be (the last one beyond them all); None
        without exposure control."""
        if not self.controlled:
            return None
        hs = self.horizons(reach_m)
        return 1 + next((k for k, h in enumerate(hs) if h >= t_s), len(hs) - 1)

    def out_of_sight(self, t_s: float) -> str | None:
        """Why the robot stops at clock ``t_s``, or None: with exposure control it knows its
        camera, and once the clock is past the longest frame's horizon at the decision's reach
        even that frame may miss the marks it must read: every decision would be a guess."""
        if not self.controlled:
            return None
        reach = self.cfg.decision_reach_m
        limit = self.horizons(reach)[-1]
        if t_s <= limit:
            return None
        return (
            f"out of sight: at {t_s:.0f} s the marks may be older than the longest frame sees "
            f"{reach:.2f} m away ({limit:.0f} s)"
        )

    def _sensor(self, k: int):
        e, g, _ = self.ladder[k]
        return self.cam.sensor.replace(exposure_s=e, gain=g)

    def stack(self, k: int) -> int:
        """How many frames rung ``k`` averages."""
        return self.ladder[k][2] * self.cfg.n_stack

    def frame_s(self, k: int) -> float:
        """Counts a frame at rung ``k``; returns the seconds it takes (all its exposures)."""
        self.frames += 1
        self.long_frames += k > 0
        self.per_rung[k] += 1
        return self.ladder[k][0] * self.stack(k)


class IdealCamera(Exposures):
    """The physics-limited camera (``--perception ideal``): it takes the same frames as the
    camera and spends the same time, but instead of rendering and reading them it sees exactly
    the marks with a dot whose age is within the frame's visibility horizon at its distance
    (:func:`sim_camera.camera.visibility_horizon_s`, the Rose criterion on the camera model; for
    a row of four dots with ``rows``), and nothing else. No pipeline error and no drift beyond
    the oracle's: what it cannot do, no pipeline on this camera can."""

    RHO = np.arange(0.05, 1.0, 0.01)

    def __init__(self, cfg: CoverConfig, board, *, rows: bool = True):
        super().__init__(cfg)
        from sim_camera.camera import visibility_horizon_s

        self.board = board
        n = ROW_EQUIVALENT_STACK if rows else 1.0
        self.curves = [
            visibility_horizon_s(self.cam, sensor=self._sensor(k), rho_m=self.RHO, n_stack=n * self.stack(k))
            for k in range(len(self.ladder))
        ]
        if cfg.ideal_horizon_factor != 1.0:
            for c in self.curves:
                c[c > 0] *= cfg.ideal_horizon_factor

    def floor_seen(self, xy, t_s: float, phosphor, marks: list, rungs, dot_mark=None) -> MarkFloor:
        """The marks (``marks``: the (sub-cell, edge) of every four dots laid, in order; or of
        the dots ``dot_mark`` gives the mark of) that frames at ``rungs`` taken from ``xy`` at
        ``t_s`` see."""
        seen = MarkFloor(self.board.shape_subcells)
        if not marks:
            return seen
        d = np.hypot(*(phosphor.xy_m - np.asarray(xy)).T)
        h = np.max([np.interp(d, self.RHO, self.curves[k], left=0.0, right=0.0) for k in rungs], axis=0)
        dot_vis = phosphor.ages_s(t_s) <= h
        vis = np.unique(dot_mark[dot_vis]) if dot_mark is not None else dot_vis.reshape(-1, 4).any(axis=1)
        for i in vis if dot_mark is not None else np.flatnonzero(vis):
            seen.mark(*marks[i])
        return seen

    def _rungs(self, t_s: float, reach_m: float, short_only: bool = False) -> list[int]:
        k = self.long_rung(t_s, reach_m)
        return [0] if k is None or short_only else [0, k]

    def observe(self, xy, t_s, phosphor, marks, sub, hc, *, fresh: bool = False, dot_mark=None):
        """(StcObservation, seconds spent): the frames :meth:`RobotCamera.observe` takes."""
        rungs = self._rungs(t_s, self.cfg.decision_reach_m, fresh)
        dt = sum(self.frame_s(r) for r in rungs)
        seen = self.floor_seen(xy, t_s, phosphor, marks, rungs, dot_mark)
        return observe_oracle(seen, self.board, sub, hc, camera_view=True), dt

    def look(self, xy, t_s, phosphor, marks, sub, hc, *, dot_mark=None):
        """(marked, seconds spent): the frames :meth:`RobotCamera.look` takes."""
        rungs = self._rungs(t_s, self.cfg.look_reach_m)
        dt = sum(self.frame_s(r) for r in rungs)
        return look_oracle(self.floor_seen(xy, t_s, phosphor, marks, rungs, dot_mark), sub, hc).marked, dt


class RobotCamera(Exposures):
    """Camera + pipeline at the robot: one pipeline per exposure setting, each holding the dark
    frame taken at its exposure (so no dark frame is re-prepared between the short and the long
    frame of a decision)."""

    def __init__(self, board, cfg: CoverConfig, rng: np.random.Generator):
        super().__init__(cfg)
        self.board = board
        self.lights = board.red_lights_m()
        self.rng = rng
        self.pipes: dict = {}
        self.darks: dict = {}
        self.pipe = None  # the pipeline that read the last frame (for the recording)
        self.bad_frames = 0  # frames lost or black, taken again
        from controllers.stc.health import NoiseCheck

        self.noise_check = NoiseCheck()

    def _pipeline(self, k: int):
        """The pipeline of rung ``k``'s exposure and gain (stacked rungs share it), holding the
        dark frame of rung ``k``: for a stack of n frames a master dark of 8n frames at the same
        exposure (taken once, before the run, lens capped), so that its own noise stays well
        below the stack's."""
        e, g, _ = self.ladder[k]
        n = self.stack(k)
        if (e, g) not in self.pipes:
            from calibration.profiles import default_profile
            from stcvision.observation import ObservationParams
            from stcvision.pipeline import Pipeline, PipelineParams

            # the pose comes from the short frame: a long one needs no far red lights (two more
            # remaps and the refinement per frame), only its rows and their lean
            obs = ObservationParams(pose_estimates=True)
            if k > 0:
                obs = dataclasses.replace(obs, landmark_range_m=0.0)
            # a short frame tells red lights from white ones (a stray lamp): PipelineParams
            white = WHITE_BLUE_RATIO if e <= WEBCAM[0] else None
            self.pipes[(e, g)] = Pipeline(default_profile(), PipelineParams(observation=obs, white_blue_ratio=white))
        if (e, g, n) not in self.darks:
            s = self._sensor(k)
            self.darks[(e, g, n)] = (
                self.cam.median_dark(8, rng=self.rng, sensor=s)
                if n == 1
                else self.cam.dark_frame(rng=self.rng, sensor=s, n_avg=8 * n)
            )
        pipe = self.pipes[(e, g)]
        if pipe.dark is not self.darks[(e, g, n)]:
            pipe.set_dark(self.darks[(e, g, n)])
        return pipe

    def shoot(self, pose, t_s: float, phosphor, k: int = 0, *, heading_error_rad: float | None = None):
        """Returns (pipeline result, capture seconds). A stacked rung is the average of its
        frames (:meth:`sim_camera.camera.SyntheticCamera.render`, ``n_avg``).
        A frame lost or black (:func:`controllers.stc.health.frame_fault`) is taken again, up to
        :data:`~controllers.stc.health.FRAME_RETRIES` times (their time counts), then the robot
        stops (:class:`~controllers.stc.health.RobotStop`): it never reads a frame it cannot trust."""
        from controllers.stc.health import FRAME_RETRIES, RobotStop, frame_fault
        from sim_camera.camera import Pose

        dt = 0.0
        for _ in range(FRAME_RETRIES + 1):
            frame = self.cam.render(
                Pose(*pose), rng=self.rng, t_s=t_s + dt, phosphor=phosphor, red_lights_m=self.lights,
                sensor=self._sensor(k), n_avg=self.stack(k),
            )  # fmt: skip
            self.pipe = self._pipeline(k)  # (after the first frame: the camera stream's order)
            dt += self.frame_s(k)
            img = None if frame is None else frame.image
            why = frame_fault(img, self.pipe.dark)
            if why is None:
                break
            self.bad_frames += 1
        else:
            raise RobotStop(f"camera: {FRAME_RETRIES + 1} frames in a row {why}")
        res = self.pipe.process(img, heading_error_rad=heading_error_rad)
        self.noise_check.check(res.dots.noise_dn, self._noise_floor(k))
        return res, dt

    def _noise_floor(self, k: int) -> float:
        """Rung ``k``'s noise floor by the camera's figures (:func:`controllers.stc.health.noise_floor_dn`),
        with its dark frame (a median of 8, or a mean of 8n frames for a stack of n)."""
        from controllers.stc.health import noise_floor_dn

        n = self.stack(k)
        return noise_floor_dn(self._sensor(k), n_avg=n, n_dark=8 * n)

    def observe(self, pose, t_s, phosphor, *, fresh: bool = False):
        """One observation: (StcObservation, the short frame's result, the long frame's result
        or None, seconds spent): the short frame, and with exposure
        control a long one at the rung the clock asks for, what either sees of the marks
        merged. The pose comes from the short frame, whose red lights do not saturate.
        ``fresh``: the cell was entered as a child the look found unmarked, so no old mark can
        be in it and the short frame (red lights, the neighbours' recent marks) is enough; the
        looks check the rest."""
        res, dt = self.shoot(pose, t_s, phosphor, 0)
        obs = _to_stc_obs(res.observation)
        k = self.long_rung(t_s, self.cfg.decision_reach_m)
        if k is None or fresh:
            return obs, res, None, dt
        long, dt_k = self.shoot(pose, t_s + dt, phosphor, k, heading_error_rad=_fit(res))
        return _merge(obs, _to_stc_obs(long.observation)), res, long, dt + dt_k

    def look(self, pose, t_s, phosphor):
        """The look at the cell ahead: (marked, the short frame's result (for the pose), the
        long frame's result or None, seconds spent), the long frame at the rung the clock asks
        for (the short frame alone without exposure control)."""
        from stcvision.observation import marks_ahead

        short, dt = self.shoot(pose, t_s, phosphor, 0)
        k = self.long_rung(t_s, self.cfg.look_reach_m)
        long = None
        herr = _fit(short)  # the long frame's recent rows all saturate: its own fit is unsure
        if k is not None:
            long, dt_k = self.shoot(pose, t_s + dt, phosphor, k, heading_error_rad=herr)
            dt += dt_k
        res = long if long is not None else short
        geo = self.pipe.geometry  # one profile: every rung's pipeline has the same geometry
        n = marks_ahead(res.dots, geo, heading_error_rad=herr or 0.0, offset=res.observation.position_offset)
        if long is not None:  # what the short frame sees counts too (it is never less right)
            n = max(n, marks_ahead(short.dots, geo, heading_error_rad=herr or 0.0))
        return n >= 2, short, long, dt


def _fit(res) -> float | None:
    """A frame's heading fit (None if it failed)."""
    return res.heading.heading_error_rad if res.heading.ok else None
