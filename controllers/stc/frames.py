"""The robot's camera in the coverage loop: which frames it takes and what they show.

* **Exposure**: ``webcam`` (1/30 s, gain 16: the STC paper's camera), a fixed ``exposure_s``, or
  ``auto``: every observation takes a short webcam frame (red lights without bloom, fresh marks,
  the pose) and then, while the reading relies on an absence that no frame so far could have
  seen (a mark as old as the clock, at the deciding dot's distance: :mod:`stcvision.controllers.stc.claims`),
  a longer one (:data:`AUTO_LONG`: 2-30 s, then 2 to 64 30 s frames stacked: frame
  stacking), the shortest that covers it (``sizing_snr``); a mark counts if any frame sees it --
  the STC paper's proposal, "a camera with a fully controlled integration time". Dark frames are
  taken once per setting, at the matching exposure (a master dark of 8n frames for a stack of
  n). When not even the longest frame covers a claim the robot stops ("out of sight: ...",
  :class:`stcvision.controllers.stc.claims.OutOfSight`), before deciding.
* **Gain**: the STC paper's webcam keeps the ladder's gains (16 for the short frame, 4 for the long
  ones); any other sensor takes at each rung the lowest gain at which its frame's temporal dark
  noise spans :data:`NOISE_DN` DN (:func:`sensor_gain`: from the sensor's read noise and dark
  current, EMVA 1288 and the astronomer's rule of thumb), its frames digitised at its own ADC
  depth (16-bit frames for a 12- or 16-bit camera: :mod:`stcvision.sim_camera.image_sensor`).
* :class:`RobotCamera`: render -> pipeline, one pipeline per exposure setting.
* :class:`IdealCamera`: the physics-limited camera, the same frames and time, but it sees
  exactly the marks within the frames' visibility horizon.
"""

from __future__ import annotations

import bisect
import dataclasses

import numpy as np

from stcvision.controllers.stc.cellfit import SEARCH as SEARCH_OFFSET
from stcvision.controllers.stc.config import CoverConfig
from stcvision.controllers.stc.fsm import NeighbourObs, StcObservation
from stcvision.controllers.stc.oracle import MarkFloor, landing_oracle, look_oracle, observe_oracle
from stcvision.sim_camera.board import DEFAULT_SUBCELL_M
from stcvision.stc_geometry import DIRECTIONS, NEIGHBOURS

__all__ = [
    "AUTO_LONG",
    "AUTO_REACH_M",
    "ROW_EQUIVALENT_STACK",
    "WEBCAM",
    "Exposures",
    "IdealCamera",
    "RobotCamera",
    "stc_observation",
]

#: the short frame of every observation: the STC paper's webcam (red lights, fresh marks, the pose):
#: (exposure_s, gain, frames averaged)
WEBCAM = (1 / 30, 16.0, 1)
#: ``--exposure auto``, long frames: (exposure_s, gain, frames averaged), shortest first. Each is
#: used while the robot's clock (the oldest age any mark can have) is within its visibility
#: horizon at the distance of what the frame must rule out (:mod:`stcvision.controllers.stc.claims`;
#: ``stcvision.sim_camera.camera.visibility_horizon_s``: the camera's calibration of the phosphor,
#: measured once per robot). The gains are the webcam's (4 keeps its 8-bit
#: quantisation below the dark current's noise at every length); another sensor's come from
#: :func:`sensor_gain`. 60 s frames were tried and read fewer boxes than 30 s ones
#: (the fresh mark's bloom), so beyond 30 s the ladder stacks 30 s frames (frame stacking):
#: averaging n frames divides the noise variance by n.
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
#: ones' up to 0.41 m, 0.45 m with the robot's position margin): the default distance for
#: :meth:`Exposures.horizons`
AUTO_REACH_M = 0.45


#: dots in the cell ahead that make a look read it marked (a row shows at least two)
LOOK_AHEAD_DOTS = 2


def stc_observation(cell_obs) -> StcObservation:
    """Turn the pipeline's per-cell reading into the controller's observation.

    Parameters
    ----------
    cell_obs : CellObservation
        The pipeline's reading of the cell (:class:`stcvision.observation.CellObservation`).

    Returns
    -------
    StcObservation
        The controller's observation (:class:`stcvision.controllers.stc.fsm.StcObservation`):
        the five boxes lit, per neighbour (right, forward, left, back) marked and red, the start
        mark's sub-cell and the landing sub-cells marked.
    """
    neigh = tuple(NeighbourObs(cell_obs.neighbours[d].has_marks, cell_obs.neighbours[d].has_red) for d in NEIGHBOURS)
    return StcObservation(
        boxes=tuple(b.lit for b in cell_obs.boxes),
        neighbours=neigh,
        start_mark=cell_obs.start_mark,
        landing_marked=tuple(cell_obs.landing_marked),
    )


def _merge(a: StcObservation, b: StcObservation) -> StcObservation:
    """Merge what two exposures of one scene show together.

    A mark either one sees is there; the red lights come from the first (short) frame, which
    does not saturate them.
    """
    return StcObservation(
        boxes=tuple(x or y for x, y in zip(a.boxes, b.boxes, strict=True)),
        neighbours=tuple(
            NeighbourObs(x.has_marks or y.has_marks, x.has_red) for x, y in zip(a.neighbours, b.neighbours, strict=True)
        ),
        start_mark=a.start_mark if a.start_mark is not None else b.start_mark,
        landing_marked=tuple(x or y for x, y in zip(a.landing_marked, b.landing_marked, strict=True)),
        # the longer frame's: it sees the cell's rows the shorter may not (each is checked alone)
        other_marks=b.other_marks,
    )


def _check_fresh(obs: StcObservation) -> StcObservation:
    """Refuse a reading of marks in a cell the look found unmarked.

    A cell entered as a child the look found unmarked holds no mark: a box or a start mark
    read in it means the look or this reading was wrong, and either way the cell's parent and
    visited sub-cells cannot be taken from it: the robot stops before deciding
    (``StcObservation.misread``), on every camera.
    """
    lit = [b for b, on in enumerate(obs.boxes, 1) if on]
    if not lit and obs.start_mark is None:
        return obs
    what = f"boxes {{{','.join(map(str, lit))}}}" if lit else f"a start mark in sub-cell {obs.start_mark}"
    return dataclasses.replace(obs, misread=f"misread: {what} lit in a cell entered as new (its look found no mark)")


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
    """Return the gain of a frame of ``exposure_s`` on ``sensor``.

    The gain of a frame of ``exposure_s`` (``n_avg`` frames averaged) on ``sensor``: the lowest
    gain >= 1 at which the frame's temporal dark noise (read noise and the dark current's shot
    noise, ``sqrt(read^2 + dark * t / n)`` electrons) spans :data:`NOISE_DN` DN, so that no faint
    mark is quantised away, and no higher, so that the ADC clips as late as it can (at gain g it
    saturates at ``full_well_e / g`` electrons). The STC paper's webcam (an 8-bit ADC, the default
    sensor) keeps the ladder's own gains (``webcam_gain``: the paper's 16x and the long frames' 4x),
    so its frames are exactly what they were. A robot setting from the sensor's figures, not
    the world.
    """
    from stcvision.sim_camera.image_sensor import SensorParams

    web = SensorParams()
    if sensor.replace(exposure_s=web.exposure_s, gain=web.gain) == web:
        return webcam_gain
    noise_e = (sensor.read_noise_e**2 + sensor.dark_current_e_s * exposure_s) ** 0.5 / n_avg**0.5
    at_unity = sensor.replace(exposure_s=exposure_s, gain=1.0).dn_per_e * noise_e
    return max(1.0, NOISE_DN / at_unity)


class Exposures:
    """The frames a robot's camera takes, and which one the robot's clock asks for.

    The frames are a ladder of (exposure_s, gain) settings, the short webcam frame first; the
    class also says which long rung the robot's clock asks for.
    """

    def __init__(self, cfg: CoverConfig, subcell_m: float = DEFAULT_SUBCELL_M, *, frame_noise: bool | None = None):
        from stcvision.sim_camera.camera import SyntheticCamera

        if frame_noise is not None:  # size the horizons as the camera-mode robot does (or not)
            self.frame_noise = frame_noise
        self.cam = SyntheticCamera(sensor=cfg.camera.sensor)
        self.cfg = cfg
        self.subcell_m = subcell_m
        self._horizons: dict[tuple[int, float], list[float]] = {}  # a few curves per rung: bounded
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
        #: rung -> (the camera's sensor, its settings at the rung, the rung's noise floor), worked
        #: out once per rung and sensor rather than at every frame
        self._settings: dict[int, tuple] = {}
        self.agreed = 0  # returns' boxes taken by two longer frames' agreement (:meth:`_check_return`)
        self.reread_old = 0  # returns read again for an unlit box near its frames' reach (:meth:`_check_old_boxes`)
        self.disputed = 0  # boxes one frame read lit and a longer one unlit, read again (:meth:`_check_disputed`)
        self.starts_dropped = 0  # start marks read outside the start cell, dropped (:meth:`_check_start_away`)

    #: the distances (m) at which each rung's horizon is tabulated once (1 cm steps, read at
    #: the next step out: never longer than the truth)
    RHO = np.round(np.arange(0.05, 1.0, 0.01), 2)
    #: the same as Python floats, searched by :func:`bisect.bisect_left` (numpy's searchsorted
    #: on one number costs more than the search)
    _RHO_LIST = RHO.tolist()

    #: with ``CoverConfig.size_by_frame_noise``, size the frames by the noise they will have
    #: (:meth:`stack_equivalent`); the physics-limited camera keeps the idealised noise (an
    #: upper bound)
    frame_noise = False

    def _curve(self, k: int, snr: float | None = None) -> list[float]:
        """Return rung ``k``'s visibility horizon (s) at :data:`RHO`.

        Rung ``k``'s horizon (s) at :data:`RHO`, for a lone dot at ``snr`` (default
        ``CoverConfig.sizing_snr``; the camera's calibration of the phosphor,
        :func:`stcvision.sim_camera.camera.visibility_horizon_s`).
        """
        snr = self.cfg.sizing_snr if snr is None else snr
        if (k, snr) not in self._horizons:
            from stcvision.sim_camera.camera import ROSE_SNR, visibility_horizon_s

            eq = (ROSE_SNR / snr) ** 2  # as if that many more frames were stacked
            n = self.stack_equivalent(k) if self.frame_noise and self.cfg.size_by_frame_noise else self.stack(k)
            curve = visibility_horizon_s(self.cam, sensor=self._sensor(k), rho_m=self.RHO, n_stack=eq * n)
            self._horizons[(k, snr)] = curve.tolist()
        return self._horizons[(k, snr)]

    def stack_equivalent(self, k: int) -> float:
        """Return the frames rung ``k`` is worth in the visibility horizon.

        The frames rung ``k`` is worth in the horizon: :func:`stcvision.sim_camera.camera.visibility_horizon_s`
        divides a frame's noise by the square root of the frames stacked, rounding included, but a
        stack arrives digitised once at the ADC's depth and is read against a dark frame digitised
        too, so its noise is :func:`stcvision.controllers.stc.health.noise_floor_dn` (the figure the noise
        check holds every frame to; measured 1.05-1.28x of it). On the webcam's 8-bit frames
        the two roundings are as large as a 30 s frame's noise over 32: 32 frames are worth 12
        (its 64 x 30 s frame sees a mark 0.45 m away for 8,900 s, not 17,100 s: a box 0.13-0.21
        m away, 24,746 s old, read at a dot SNR of 4.6-6.2 in a 32 x 30 s frame where the
        idealised noise promised 9-12, was missed); a 12- or 16-bit camera's, whose gain makes
        its noise span a DN, 0.8-0.85 of their number.
        """
        s, n = self._sensor(k), self.stack(k)
        idealised = (s.dark_current_e_s * s.exposure_s + s.read_noise_e**2 + 1 / (12 * s.dn_per_e**2)) / n
        return n * idealised * s.dn_per_e**2 / self._noise_floor(k) ** 2

    def _noise_floor(self, k: int) -> float:
        """Return rung ``k``'s noise floor by the camera's figures.

        Rung ``k``'s noise floor by the camera's figures (:func:`stcvision.controllers.stc.health.noise_floor_dn`),
        with its dark frame (a median of 8, or a mean of 8n frames for a stack of n).
        """
        return self._rung(k)[2]

    def horizon(self, k: int, rho_m: float, snr: float | None = None) -> float:
        """Return how old (s) a mark may be and still be seen in a frame at rung ``k``.

        How old (s) a mark ``rho_m`` from the robot may be and still be seen in a frame at rung
        ``k`` (its deciding dot at ``snr``, default ``CoverConfig.sizing_snr``).
        """
        i = min(bisect.bisect_left(self._RHO_LIST, rho_m - 1e-9), len(self._RHO_LIST) - 1)
        return self._curve(k, snr)[i]

    def horizons(self, reach_m: float = AUTO_REACH_M) -> tuple[float, ...]:
        """Return the long rungs' visibility horizons (s) for a dot ``reach_m`` from the robot."""
        return tuple(self.horizon(k, reach_m) for k in range(1, len(self.ladder)))

    @property
    def controlled(self) -> bool:
        """Exposure control: long frames besides the short one."""
        return len(self.ladder) > 1

    def rung_for(self, t_s: float, rho_m: float) -> int | None:
        """Return the shortest rung that sees marks as old as the clock.

        The shortest rung (the short frame included) whose horizon ``rho_m`` away covers marks
        as old as the clock ``t_s``; None when none does.
        """
        return next((k for k in range(len(self.ladder)) if self.horizon(k, rho_m) >= t_s), None)

    def decision_claims(self, fresh: bool, at_start: bool):
        """Return what a decision's reading takes for absent.

        See :func:`stcvision.controllers.stc.claims.decision_claims`.
        """
        from stcvision.controllers.stc.claims import decision_claims

        kw = dict(fresh=fresh, at_start=at_start, subcell_m=self.subcell_m, margin_m=self.cfg.position_margin_m)
        return lambda obs: decision_claims(obs, **kw)

    def look_claims(self, landing: bool):
        """Return what a look's reading takes for absent: the sub-cell ahead (``landing``) or the cell ahead."""
        from stcvision.controllers.stc.claims import ahead_claims, landing_claims

        f = landing_claims if landing else ahead_claims
        return lambda marked: f(marked, subcell_m=self.subcell_m, margin_m=self.cfg.position_margin_m)

    def sure(self, t_s: float, read, merge, claims):
        """Take frames until every claim of the reading is covered.

        (reading, seconds, the (rung, clock) of each frame taken): with exposure control,
        frames until every claim of the reading is covered
        (:func:`stcvision.controllers.stc.claims.read_until_sure`; raises
        :class:`stcvision.controllers.stc.claims.OutOfSight` when no frame can cover one, unless
        ``CoverConfig.stop_out_of_sight`` is off: then the longest frame is taken and the reading
        kept); without it (the STC paper's camera) the short frame alone, whatever it misses.
        """
        from stcvision.controllers.stc.claims import read_until_sure

        if not self.controlled:
            reading, dt = read(0, t_s)
            return reading, dt, [(0, t_s)]
        return read_until_sure(self, t_s, read, merge, claims, strict=self.cfg.stop_out_of_sight)

    def decision(self, t_s: float, read, fresh: bool, at_start: bool, start_cell: bool = True):
        """Read a decision: its frames, and whether each landing reading is sure.

        (StcObservation, seconds): a decision's frames (:meth:`sure`), and per direction
        whether its landing reading is sure (``StcObservation.landing_known``): a mark was seen,
        or a frame taken could have seen one as old as the clock was then. Without exposure
        control the STC paper's robot takes what it sees for sure. ``start_cell``: the robot's count of
        its moves puts it in its start cell (elsewhere a start mark read is not its own:
        :meth:`_check_start_away`).
        """
        from stcvision.controllers.stc.claims import landing_claim

        seen: list = []  # (rung, reading) of every frame this decision takes

        def read(k, t, _read=read):
            reading, dk = _read(k, t)
            seen.append((k, reading))
            return reading, dk

        obs, dt, taken = self.sure(t_s, read, _merge, self.decision_claims(fresh, at_start))
        obs, dt = self._check_lines(t_s, read, obs, dt, taken)
        if fresh and not obs.misread:
            obs = _check_fresh(obs)
            if obs.misread and self.controlled:
                obs, dt = self._settle_fresh(t_s, read, obs, dt, taken)
        if not self.controlled or obs.misread:
            return obs, dt
        if obs.start_mark is not None and not start_cell:
            obs, dt = self._check_start_away(t_s, read, obs, dt, taken)
            if obs.misread:
                return obs, dt
        if not (fresh or at_start):
            obs, dt = self._check_old_boxes(t_s, read, obs, dt, taken)
        obs, dt = self._check_disputed(t_s, read, obs, dt, taken, seen)
        if self.cfg.check_returns and not (fresh or at_start):
            obs, dt = self._check_return(t_s, read, obs, dt, taken)
        kw = dict(subcell_m=self.subcell_m, margin_m=self.cfg.position_margin_m)
        rho = [landing_claim(d, **kw).rho_m for d in range(4)]
        known = tuple(
            bool(m) or any(self.horizon(k, r) >= tk for k, tk in taken)
            for m, r in zip(obs.landing_marked, rho, strict=True)
        )
        return dataclasses.replace(obs, landing_known=known), dt

    def _longer(self, t_s: float, read, obs, dt: float, taken: list):
        """Read a decision once more with a frame one rung longer than any taken.

        A decision's reading once more with a frame one rung longer than any taken (the
        longest again at the top), merged: (reading, seconds, the rung, that frame's own reading).
        """
        k = min(max(j for j, _ in taken) + 1, len(self.ladder) - 1)
        more, dk = read(k, t_s + dt)
        taken.append((k, t_s + dt))
        return _merge(obs, more), dt + dk, k, more

    def _check_lines(self, t_s: float, read, obs, dt: float, taken: list):
        """Check that the cell's lit rows lie on its box and start-mark lines.

        At a decision the cell's marks lie on the box and start-mark lines only; a reading
        with lit rows of the cell on none (``StcObservation.other_marks``: no offset of the
        robot puts them there, :mod:`stcvision.controllers.stc.cellfit`) reads the boxes from regions
        the marks do not fill, so a box may be missed or taken from a neighbour. With exposure
        control it is read once more with a frame one rung longer than any taken (more rows to
        fit); still so, or on a camera without control, it says why
        (``StcObservation.misread``) and the robot stops before deciding. Returns (reading,
        seconds).
        """
        if not obs.other_marks:
            return obs, dt
        label = self.frame_label(max(j for j, _ in taken))
        if self.controlled:
            obs, dt, k, _ = self._longer(t_s, read, obs, dt, taken)
            label = self.frame_label(k)
        if obs.other_marks:
            why = (
                f"misread: {obs.other_marks} lit dots of rows in the cell on no box or start-mark line at any offset "
                f"of the robot within {100 * SEARCH_OFFSET * self.subcell_m:.1f} cm, also with a {label} frame"
            )
            obs = dataclasses.replace(obs, misread=why)
        return obs, dt

    def _check_old_boxes(self, t_s: float, read, obs, dt: float, taken: list):
        """Check, at a return, that a box read unlit was read by frames that could see it.

        At a return, a box read unlit decides the parent, and a tour may show the set left
        without it ({4} for {2,4}: a wrong parent no cross-check of the boxes sees). The claims
        size the frames so that a mark as old as the clock still shows each dot ~84 % of the
        time (``CoverConfig.sizing_snr``): two of a row's four are then read 98.6 % of the time,
        so over a long tour's returns an old row at the edge of a frame's reach is missed now
        and then. Where no frame taken reaches the clock at ``CoverConfig.return_snr`` (each dot
        found ~98 % of the time, two of four > 99.99 %) for an unlit box's deciding dot, the
        cell is read again with the next longer frame (the longest again at the top), merged:
        the clock, not a record of where the robot has been, says a mark there may be that old.
        Returns (reading, seconds).
        """
        from stcvision.controllers.stc.claims import distance_m

        margin, snr = self.cfg.position_margin_m, self.cfg.return_snr
        for b, lit in enumerate(obs.boxes, 1):
            rho = distance_m(f"box {b}", self.subcell_m, margin)
            if not lit and not any(self.horizon(k, rho, snr) >= tk for k, tk in taken):
                self.reread_old += 1
                obs, dt, _, _ = self._longer(t_s, read, obs, dt, taken)
                return obs, dt
        return obs, dt

    def _check_disputed(self, t_s: float, read, obs, dt: float, taken: list, seen: list):
        """Settle a box read lit only by frames shorter than one that read it unlit.

        A box read lit only by frames shorter than one that read it unlit. At one pose a longer
        frame sees every mark a shorter one can, with more signal, so the two cannot both be
        right; the merge (any frame's mark counts) would keep the lit one. On a cooled camera the
        faint-row search of a short frame, summing four windows on the noise, found a row
        across an old row's one dot (19x19 board, seed 2739: box 3 in the short frame at row SNR
        6.0, nothing there in the 2 s frame at a dot SNR of 24-36 for the old row beside it),
        and at a return the boxes {3,4} for {4} sent the robot into a visited sub-cell. So such a
        box is read once more at the rung that read it lit: a mark there shows again (the longer
        frame's miss was its own), a row of noise does not, and the box is taken from that
        frame. Returns (reading, seconds).
        """
        disputed = []
        for b, lit in enumerate(obs.boxes):
            lit_at = [k for k, o in seen if o.boxes[b]]
            if lit and lit_at and any(k > max(lit_at) and not o.boxes[b] for k, o in seen):
                disputed.append((b, max(lit_at)))
        if not disputed:
            return obs, dt
        boxes, again = list(obs.boxes), {}
        for b, k in disputed:
            if k not in again:
                again[k], dk = read(k, t_s + dt)
                taken.append((k, t_s + dt))
                dt += dk
            boxes[b] = again[k].boxes[b]
            self.disputed += 1
        return dataclasses.replace(obs, boxes=tuple(boxes)), dt

    def _check_return(self, t_s: float, read, obs, dt: float, taken: list):
        """Read again a return's reading that no STC tour shows.

        A return's reading that no STC tour shows (:func:`stcvision.controllers.stc.claims.return_misread`)
        is read once more with a frame one rung longer than any taken (the longest again at the
        top), merged. Still wrong merged, the frames disagree: a mark one frame alone shows (a
        short frame's noise or a neighbour's fresh row read into a box) is kept by the merge
        however many frames follow, so the boxes are taken by agreement instead: the longer
        frame's own reading, when it is one an STC tour shows and a second frame at its rung
        reads the same boxes (the longer frame sees every mark the shorter ones could, and
        ``_check_lines`` has held each frame's rows to the cell's lines). Otherwise it says why
        (``StcObservation.misread``: the loop stops rather than decide on it). Returns
        (reading, seconds).
        """
        from stcvision.controllers.stc.claims import return_misread

        if return_misread(obs) is None:
            return obs, dt
        merged, dt, k, more = self._longer(t_s, read, obs, dt, taken)
        why = return_misread(merged)
        if why is None:
            return merged, dt
        if return_misread(more) is None:
            settled, dt = self._agree(t_s, read, merged, more, dt, taken, k)
            if settled is not None:
                return settled, dt
            why += f"; two {self.frame_label(k)} frames disagree"
        return dataclasses.replace(merged, misread=f"{why}, also with a {self.frame_label(k)} frame"), dt

    def _agree(self, t_s: float, read, merged, more, dt: float, taken: list, k: int):
        """Take a second frame at rung ``k`` to confirm what a longer frame read.

        A second frame at rung ``k``: when it reads the boxes and start mark that frame's
        ``more`` read, with every row of the cell on its lines, the reading takes them from
        ``more`` instead of the merge (which keeps any one frame's mark). Returns (the settled
        reading or None, seconds).
        """
        if more.other_marks:
            return None, dt
        again, dk = read(k, t_s + dt)
        taken.append((k, t_s + dt))
        dt += dk
        if again.boxes != more.boxes or again.start_mark != more.start_mark or again.other_marks:
            return None, dt
        self.agreed += 1
        return dataclasses.replace(merged, boxes=more.boxes, start_mark=more.start_mark), dt

    def _longer_agreed(self, t_s: float, read, obs, dt: float, taken: list, wanted):
        """Read once more with a longer frame, and confirm it when it reads what is wanted.

        :meth:`_longer`, then, when that frame's own reading is ``wanted``, :meth:`_agree` with
        a second frame at its rung: (the settled reading or None, the merged reading, seconds,
        the rung).
        """
        merged, dt, k, more = self._longer(t_s, read, obs, dt, taken)
        if wanted(more):
            settled, dt = self._agree(t_s, read, merged, more, dt, taken, k)
            if settled is not None:
                return settled, merged, dt, k
        return None, merged, dt, k

    def _settle_fresh(self, t_s: float, read, obs, dt: float, taken: list):
        """Settle a cell entered as new that reads with a box or a start mark.

        A cell entered as new (its look found no mark) read with a box or a start mark
        (spiral_stc_test lowlight seed 222: box 5 in the short frame, a neighbour's row; the
        look was right): read once more with a frame one rung longer; two frames at that rung
        agreeing on no mark settle it, otherwise the misread stands. Returns (reading, seconds).
        """
        clean = dataclasses.replace(obs, misread="")
        settled, _, dt, k = self._longer_agreed(
            t_s, read, clean, dt, taken, lambda m: not any(m.boxes) and m.start_mark is None
        )
        if settled is not None:
            return settled, dt
        return dataclasses.replace(obs, misread=f"{obs.misread}, also with a {self.frame_label(k)} frame"), dt

    def _check_start_away(self, t_s: float, read, obs, dt: float, taken: list):
        """Settle a start mark read where the count says the robot is not in its start cell.

        A start mark read where the robot's count of its moves says it is not in its start
        cell is a row read at a start-mark line that is not its own (spiral_stc_test_2 lowlight
        seed 209: the short and the 4 s frame, read at the pipeline's offset 1 cm off the truth,
        put a row on sub-cell 3's start-mark line; the 4 s frame read again against the cell's
        own rows did not, but the merge kept the start mark). It is read once more with a frame
        one rung longer than any taken: when that frame and a second at its rung agree on a
        reading without the start mark, the robot decides on it. Otherwise, with the cell's rows
        on their lines (no other marks: the offset the boxes were read at is the cell's), the
        count being sure, the row is another cell's laid off its line, and the start mark is
        dropped (spiral_stc_test_3 lowlight seed 2060: a neighbour's row laid about 2 cm low,
        read on sub-cell 1's start-mark line by the 4 s and the 8 s frame; the robot stood
        0.5 cm off); the boxes read with it face the checks after this one. With rows of the
        cell off the lines it says why (``StcObservation.misread``) and the robot stops before
        deciding. Returns (reading, seconds).
        """
        settled, merged, dt, k = self._longer_agreed(t_s, read, obs, dt, taken, lambda m: m.start_mark is None)
        if settled is not None:
            return settled, dt
        if not merged.other_marks:
            self.starts_dropped += 1
            return dataclasses.replace(merged, start_mark=None), dt
        why = (
            f"misread: a start mark in sub-cell {obs.start_mark} where the robot's count of its moves puts it "
            f"outside its start cell, also with a {self.frame_label(k)} frame"
        )
        return dataclasses.replace(merged, misread=why), dt

    def frame_label(self, k: int) -> str:
        """Rung ``k`` in words: "2 s", "4 x 30 s"."""
        e, _, n = self.ladder[k]
        n *= self.cfg.n_stack
        length = f"{e:g} s" if e >= 1 else f"1/{round(1 / e)} s"
        return length if n == 1 else f"{n} x {length}"

    def _sensor(self, k: int):
        return self._rung(k)[1]

    def _rung(self, k: int) -> tuple:
        """Return (the camera's sensor, its settings at rung ``k``, the rung's noise floor)."""
        base = self.cam.sensor
        hit = self._settings.get(k)
        if hit is None or hit[0] is not base:
            from stcvision.controllers.stc.health import noise_floor_dn

            e, g, _ = self.ladder[k]
            s, n = base.replace(exposure_s=e, gain=g), self.stack(k)
            hit = self._settings[k] = (base, s, noise_floor_dn(s, n_avg=n, n_dark=8 * n))
        return hit

    def stack(self, k: int) -> int:
        """How many frames rung ``k`` averages."""
        return self.ladder[k][2] * self.cfg.n_stack

    def frame_s(self, k: int) -> float:
        """Count a frame at rung ``k``; return the seconds it takes (all its exposures)."""
        self.frames += 1
        self.long_frames += k > 0
        self.per_rung[k] += 1
        return self.ladder[k][0] * self.stack(k)


class IdealCamera(Exposures):
    """The physics-limited camera: the camera's frames and time, but the marks seen exactly.

    The physics-limited camera (``--perception ideal``): it takes the same frames as the
    camera and spends the same time, but instead of rendering and reading them it sees exactly
    the marks with a dot whose age is within the frame's visibility horizon at its distance
    (:func:`stcvision.sim_camera.camera.visibility_horizon_s`, the Rose criterion on the camera model; for
    a row of four dots with ``rows``), and nothing else. No pipeline error and no drift beyond
    the oracle's: what it cannot do, no pipeline on this camera can.
    """

    def __init__(self, cfg: CoverConfig, board, *, rows: bool = True):
        super().__init__(cfg, board.subcell_m)
        from stcvision.sim_camera.camera import visibility_horizon_s

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
        """Return the marks that frames at ``rungs`` taken from ``xy`` at ``t_s`` see.

        The marks (``marks``: the (sub-cell, edge) of every four dots laid, in order; or of
        the dots ``dot_mark`` gives the mark of) that frames at ``rungs`` taken from ``xy`` at
        ``t_s`` see.
        """
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

    def _seen(self, xy, phosphor, marks, k: int, t_s: float, dot_mark=None) -> tuple[MarkFloor, float]:
        """Return what a frame at rung ``k`` from ``xy`` at clock ``t_s`` sees, and its seconds."""
        return self.floor_seen(xy, t_s, phosphor, marks, [k], dot_mark), self.frame_s(k)

    def observe(self, xy, t_s, phosphor, marks, sub, hc, *, fresh: bool = False, at_start: bool = False,
                dot_mark=None, start_cell: bool = True):  # fmt: skip
        """(StcObservation, seconds spent): the frames :meth:`RobotCamera.observe` takes."""

        def read(k, t):
            seen, dt = self._seen(xy, phosphor, marks, k, t, dot_mark)
            # it reads every mark in its box exactly (the start mark under the robot, which
            # the oracle counts as at no box, included): no rows on no line
            return dataclasses.replace(observe_oracle(seen, self.board, sub, hc, camera_view=True), other_marks=0), dt

        return self.decision(t_s, read, fresh, at_start, start_cell)

    def look(self, xy, t_s, phosphor, marks, sub, hc, *, landing: bool = False, dot_mark=None):
        """Look ahead as :meth:`RobotCamera.look` does: (marked, seconds spent).

        (marked, seconds spent): the frames :meth:`RobotCamera.look` takes; ``landing``: the
        sub-cell ahead (before a return to the parent), else the cell ahead (a child).
        """

        def read(k, t):
            seen, dt = self._seen(xy, phosphor, marks, k, t, dot_mark)
            return (landing_oracle if landing else look_oracle)(seen, sub, hc).marked, dt

        return self.sure(t_s, read, bool.__or__, self.look_claims(landing))[:2]


class RobotCamera(Exposures):
    """Camera and pipeline at the robot: one pipeline per exposure setting.

    Camera + pipeline at the robot: one pipeline per exposure setting, each holding the dark
    frame taken at its exposure (so no dark frame is re-prepared between the short and the long
    frame of a decision).
    """

    frame_noise = True

    def __init__(self, board, cfg: CoverConfig, rng: np.random.Generator, *, camera_wrap=None):
        super().__init__(cfg, board.subcell_m)
        if camera_wrap is not None:  # the camera's faults (its visibility horizons stay the healthy camera's)
            self.cam = camera_wrap(self.cam)
        self.board = board
        self.lights = board.red_lights_m()
        self.rng = rng
        self.pipes: dict = {}
        self.darks: dict = {}
        self.dark_levels: dict = {}  # each dark frame's level as frame_fault reads it, measured once
        self.dark_level = None  # ... the last pipeline's
        self.pipe = None  # the pipeline that read the last frame (for the recording)
        self.bad_frames = 0  # frames lost or black, taken again
        self.refits = 0  # frames read again against the cell's own marks (:meth:`_on_cell_lines`)
        self.unproven = 0  # decisions' neighbours read marked by dots showing no tour's row (:meth:`_neighbour_rows`)
        self._doubted: set[int] = set()
        self.relooked = 0  # looks taken again for dots in no row in the cell ahead (:meth:`_look_again`)
        self.last_image = None  # the last frame shot (read again by :meth:`_on_cell_lines`)
        #: where each frame's render and pipeline time go (None: not timed;
        #: :class:`stcvision.controllers.stc.timing.FrameTimes`)
        self.times = None
        from stcvision.controllers.stc.health import NoiseCheck

        self.noise_check = NoiseCheck()

    def _pipeline(self, k: int):
        """Return the pipeline of rung ``k``, holding its dark frame.

        The pipeline of rung ``k``'s exposure and gain (stacked rungs share it), holding the
        dark frame of rung ``k``: for a stack of n frames a master dark of 8n frames at the same
        exposure (taken once, before the run, lens capped), so that its own noise stays well
        below the stack's.
        """
        e, g, _ = self.ladder[k]
        n = self.stack(k)
        if (e, g) not in self.pipes:
            from stcvision.calibration.profiles import default_profile
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
        if (e, g, n) not in self.dark_levels:
            from stcvision.controllers.stc.health import sampled_level

            self.dark_levels[(e, g, n)] = sampled_level(self.darks[(e, g, n)])
        self.dark_level = self.dark_levels[(e, g, n)]
        return pipe

    def shoot(
        self, pose, t_s: float, phosphor, k: int = 0, *, heading_error_rad: float | None = None, position_offset=None
    ):
        """Take and read a frame at rung ``k``: (pipeline result, capture seconds).

        Returns (pipeline result, capture seconds). A stacked rung is the average of its
        frames (:meth:`stcvision.sim_camera.camera.SyntheticCamera.render`, ``n_avg``); the frame is read
        with ``heading_error_rad`` and ``position_offset`` when given
        (:meth:`stcvision.pipeline.Pipeline.process`).
        A frame lost or black (:func:`stcvision.controllers.stc.health.frame_fault`) is taken again, up to
        :data:`~stcvision.controllers.stc.health.FRAME_RETRIES` times (their time counts), then the robot
        stops (:class:`~stcvision.controllers.stc.health.RobotStop`): it never reads a frame it cannot trust.
        """
        from stcvision.controllers.stc.health import FRAME_RETRIES, RobotStop, frame_fault
        from stcvision.sim_camera.camera import Pose

        dt = 0.0
        times = self.times
        for _ in range(FRAME_RETRIES + 1):
            t0 = times.now() if times is not None else None
            frame = self.cam.render(
                Pose(*pose), rng=self.rng, t_s=t_s + dt, phosphor=phosphor, red_lights_m=self.lights,
                sensor=self._sensor(k), n_avg=self.stack(k),
            )  # fmt: skip
            if times is not None:
                times.add_render(t0)
            self.pipe = self._pipeline(k)  # (after the first frame: the camera stream's order)
            dt += self.frame_s(k)
            img = None if frame is None else frame.image
            why = frame_fault(img, self.pipe.dark, dark_level=self.dark_level)
            if why is None:
                break
            self.bad_frames += 1
        else:
            raise RobotStop(f"camera: {FRAME_RETRIES + 1} frames in a row {why}")
        t0 = times.now() if times is not None else None
        res = self.pipe.process(img, heading_error_rad=heading_error_rad, position_offset=position_offset)
        if times is not None:
            times.add_pipeline(t0, res.stage_ms)
        self.last_image = img
        if res.observation.untrusted:  # the pipeline could not read this frame honestly (too many candidates)
            raise RobotStop(f"camera: a frame the pipeline cannot trust ({res.observation.untrusted})")
        self.noise_check.check(res.dots.noise_dn, self._noise_floor(k))
        return res, dt

    def _as_short(self, short) -> dict:
        """Read a long frame as after the short one at the same pose.

        How a long frame is read after the short one at the same pose: with the short frame's
        heading fit (the long frame's recent rows all saturate) and, when the red lights in it
        are sure, their offset (the long frame has no far lights, and its many old rows, each
        laid where the robot then stood, may mislead its own offset by more than the rows' 2 cm
        inset: a row of the cell behind then reads as a start mark).
        """
        from stcvision.controllers.stc.config import LANDMARK_OFFSET_SIGMA

        o = short.observation
        sure = (
            self.cfg.use_landmarks
            and o.landmark_offset is not None
            and o.landmark_offset_sigma <= LANDMARK_OFFSET_SIGMA
        )
        return {"heading_error_rad": _fit(short), "position_offset": o.landmark_offset if sure else None}

    def observe(self, pose, t_s, phosphor, *, fresh: bool = False, at_start: bool = False, start_cell: bool = True):
        """Make one observation: the short frame, and the long frames its claims ask for.

        One observation: (StcObservation, the short frame's result, the last long frame's
        result or None, seconds spent): the short frame, and with exposure control the long
        frames its claims ask for (:meth:`sure`), what any of them sees of the marks merged. The
        pose comes from the short frame, whose red lights do not saturate; the long ones are
        read with its heading fit (their recent rows all saturate).
        """
        res: list = []

        def read(k, t):
            r, dt = self.shoot(pose, t, phosphor, k, **(self._as_short(res[0]) if res else {}))
            r, off_line = self._on_cell_lines(r)
            res.append(r)
            obs = dataclasses.replace(stc_observation(r.observation), other_marks=off_line)
            return self._neighbour_rows(r, obs), dt

        self._doubted = set()  # (this decision's only: at most the four neighbours)
        obs, dt = self.decision(t_s, read, fresh, at_start, start_cell)
        self.unproven += sum(not obs.neighbours[d].has_marks for d in self._doubted)
        return obs, res[0], (res[-1] if len(res) > 1 else None), dt

    def _neighbour_rows(self, res, obs: StcObservation) -> StcObservation:
        """Check that a neighbour read marked shows a row an STC tour lays there.

        A neighbour read marked (lit dots in it, no red light) whose dots show no row an STC
        tour lays there (:func:`stcvision.controllers.stc.cellfit.shows_tour_row`: a row of this cell or of
        another neighbour read across the cell's edge, a noise peak, a bloom) is read as
        unmarked: it stays a candidate child, and the look from next to it, 2-3x closer, reads
        it again before the robot enters it or moves on (:meth:`look`). Passed by on such a
        reading, a new cell would be left uncovered.
        """
        from stcvision.controllers.stc.cellfit import shows_tour_row

        doubt = [d for d, n in enumerate(obs.neighbours) if n.has_marks and not n.has_red]
        if not doubt:
            return obs
        cell_pts, lit = self._dots(res, res.observation.position_offset)
        neigh = list(obs.neighbours)
        for d in doubt:
            if not shows_tour_row(cell_pts, lit, 2 * np.asarray(DIRECTIONS[d])):
                neigh[d] = NeighbourObs(False, False)
                self._doubted.add(d)
        return dataclasses.replace(obs, neighbours=tuple(neigh))

    def _dots(self, res, offset) -> tuple[np.ndarray, np.ndarray]:
        """Return a result's dots in cell units, and which are lit.

        A result's dots in cell units, rotated by its heading and shifted by ``offset`` (the
        robot's offset from its sub-cell centre, cell units; None: not shifted), and which are lit.
        """
        from stcvision.controllers.stc.cellfit import frame_dots

        cell_pts, lit = frame_dots(res, self.pipe.geometry)
        return (cell_pts + np.asarray(offset) if offset is not None else cell_pts), lit

    def _on_cell_lines(self, res):
        """Localise the robot against the cell's own marks.

        Localisation against the cell's own marks (:mod:`stcvision.controllers.stc.cellfit`): where the
        pipeline's offset leaves lit row dots of the cell on no box or start-mark line, as many
        as make a mark (``ObservationParams.min_dots``: a lone dot of a row crossing the cell's
        edge, or a noise peak beside a row, makes none), the frame is read again with the offset
        that puts them on the lines. Returns (result, the cell's row dots still on no line: 0
        when the reading is consistent; at least ``min_dots`` when it is not, or when two
        offsets explain them).
        """
        from stcvision.controllers.stc.cellfit import fit_cell_offset, frame_dots
        from stcvision.observation import ObservationParams

        need = ObservationParams().min_dots
        cell_pts, lit = frame_dots(res, self.pipe.geometry)
        start = res.observation.position_offset or (0.0, 0.0)
        base = fit_cell_offset(cell_pts, lit, start, search=False)
        if base is None or base.off_line < need:
            return res, 0
        fit = fit_cell_offset(cell_pts, lit, start)
        if fit.off_line < need and not fit.ambiguous:
            again = self.pipe.process(
                self.last_image, heading_error_rad=res.observation.heading_error_rad, position_offset=fit.offset
            )
            self.refits += 1
            # the fit moved only the axes the cell's rows measured: the robot's localisation
            # takes those (an offset given to the pipeline counts as no reading of the marks)
            axes = res.observation.position_offset_axes
            o = dataclasses.replace(again.observation, position_offset_axes=axes)
            return dataclasses.replace(again, observation=o), 0
        return res, max(fit.off_line, need)

    def look(self, pose, t_s, phosphor, *, landing: bool = False):
        """Look ahead before leaving a cell.

        The look ahead: (marked, the short frame's result (for the pose), the last long
        frame's result or None, seconds spent). ``landing``: marks in the sub-cell just ahead
        (before a return to the parent: does the tour close there?), else in the cell ahead (a
        child). What any frame sees counts (it is never less right); the long frames are read
        with the short frame's heading fit.
        """
        from stcvision.controllers.stc.cellfit import shows_row
        from stcvision.observation import LANDING_DOTS, marks_ahead, marks_landing_ahead

        count, need = (marks_landing_ahead, LANDING_DOTS) if landing else (marks_ahead, LOOK_AHEAD_DOTS)
        res: list = []

        def read(k, t):
            """Read a frame at rung ``k``: ((marked, shows a tour's row), seconds)."""
            how = self._as_short(res[0]) if res else {}
            herr = how.get("heading_error_rad")
            r, dt = self.shoot(pose, t, phosphor, k, **how)
            res.append(r)
            off = r.observation.position_offset if k > 0 else None
            n = count(r.dots, self.pipe.geometry, heading_error_rad=herr or 0.0, offset=off)
            row = landing or (n >= need and shows_row(*self._dots(r, off), AHEAD_CENTRE))
            return (n >= need, row), dt

        claims = self.look_claims(landing)
        (marked, row), dt, taken = self.sure(t_s, read, _either, lambda m: claims(m[0]))
        if marked and not row:
            (marked, row), dt = self._look_again(t_s, read, dt, taken)
        return marked, res[0], (res[-1] if len(res) > 1 else None), dt

    def _look_again(self, t_s: float, read, dt: float, taken: list):
        """Look again at a child read marked by dots that show no row of the robot's LEDs.

        A child read marked by lit dots in the cell ahead that show no row of the robot's LEDs
        (:func:`stcvision.controllers.stc.cellfit.shows_row`: a noise peak, two dots of a faint row, a
        bloom): a mark the tour laid there shows its row once a frame sees most of its dots, so
        it is looked at once more with a frame one rung longer than any taken (the longest again
        at the top). A row there: the cell is marked; no dot: it is new (the first entry's check
        reads its floor again: :meth:`_settle_fresh`); dots and no row again: no reading
        explains them, and the robot stops before it decides. The look does not ask on which
        line the row lies: it reads its short frame where the robot believes it stands (the rows
        in view were laid at many times, so they do not say where it stands), and on open floor,
        beyond the red lights, a visited cell's rows lay 3-4 cm off their lines there
        (spiral_stc_test_3: the robot 1.9 cm off, its rows laid 2 cm off the other way).
        Returns ((marked, row), seconds).
        """
        from stcvision.controllers.stc.health import RobotStop

        k = min(max(j for j, _ in taken) + 1, len(self.ladder) - 1)
        (marked, row), dk = read(k, t_s + dt)
        self.relooked += 1
        if marked and not row:
            raise RobotStop(
                "misread: lit dots in the cell ahead that show no row of the robot's LEDs, also with a "
                f"{self.frame_label(k)} frame"
            )
        return (marked, row), dt + dk


#: the cell ahead of a robot at a look, in cell units: it stands in the front-right sub-cell of
#: its own cell, facing the cell ``[-1, 1] x [0, 2]`` (:func:`stcvision.observation.marks_ahead`)
AHEAD_CENTRE = (0.0, 1.0)


def _either(a: tuple[bool, bool], b: tuple[bool, bool]) -> tuple[bool, bool]:
    """Merge what two frames of a look show together: dots either saw, a row either saw."""
    return a[0] or b[0], a[1] or b[1]


def _fit(res) -> float | None:
    """Return a frame's heading fit (None if it failed)."""
    return res.heading.heading_error_rad if res.heading.ok else None
