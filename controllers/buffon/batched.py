"""Buffon's method on many robots at once: the fast Monte-Carlo path (numba).

Each trial is one robot making the two visits of the Buffon's needle paper (Girgin & Sahin,
sec. 4):
both start at the central bottom of the nest, heading away from the bottom wall within +-15
degrees (sec. 3.1); the first lays a pheromone trail of width w, the second reads it with the
binary detector at its centre, filters it (:mod:`stcvision.controllers.buffon.counter`) and counts the
crossings. The trials of an experiment are independent worlds, so robots never meet.

One step of one robot, in the order of the pymunk path (:mod:`stcvision.controllers.buffon.pymunk_path`):

1. six IR ray casts from the rim (:func:`stcvision.sim_camera.fastworld.ray_cast`), the Khepera response
   :func:`stcvision.sim_camera.robot_sensors.ir_response` plus Gaussian noise, clipped to [0, 1];
2. the behaviour of sec. 3.2 (:func:`stcvision.controllers.buffon.behaviour.explorer_core`, the same source
   as the scalar controller) gives the wheel speeds;
3. the wheels move the body as :class:`stcvision.sim_camera.robot.DiffDriveRobot` does (true wheel
   diameters and wheelbase, motor gain, slip noise ``slip_k * sqrt(|d|)`` per wheel), with the
   heading at the step's midpoint;
4. frictionless contact (:func:`stcvision.sim_camera.fastworld.push_out`);
5. visit 1 marks the trail along the step; visit 2 reads the cell under the centre and counts.

Randomness: trial i has its own stream ``SeedSequence(seed).spawn(...)[i]``, split into four
components (start heading, behaviour draws, IR noise, wheel slip), so a trial's counts do not
depend on how many trials run beside it or on the worker that runs it.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numba
import numpy as np

from stcvision.controllers.buffon.behaviour import ExplorerParams, explorer_core_nb, wheel_speeds_nb
from stcvision.controllers.buffon.counter import CounterParams, integrate_nb
from stcvision.controllers.buffon.defaults import PAPER_TRAIL_WIDTH_U, PAPER_VISIT_STEPS
from stcvision.controllers.buffon.nests import BODY_LENGTH_M, Nest
from stcvision.controllers.buffon.stopping import (
    StopParams,
    batch_add,
    batch_rel_se,
    first_visit_done,
    first_visit_hopeless,
    new_batch_state,
    second_visit_done,
)
from stcvision.errors import BadInputError
from stcvision.sim_camera.fastworld import (
    StaticGeometry,
    cell_span,
    inside_polygon,
    push_out,
    ray_cast,
    read_cell,
    stamp_segment,
)
from stcvision.sim_camera.robot import KHEPERA, DiffDriveParams
from stcvision.sim_camera.robot_sensors import IrParams

__all__ = [
    "TrialSet",
    "TrialWorld",
    "VisitConfig",
    "run_trials",
    "start_headings",
    "trial_seeds",
]

START_HEADING_SPREAD_RAD = math.radians(15)  # sec. 3.1: "varied within +-15 degrees of the wall"
#: the trail raster's unit of path length: a cell holds the path (in these units, + 1) at which
#: the first visit first laid it; uint32 holds 2,100 km of path, over 20 times the longest visit
STAMP_M = 0.0005
#: steps the compiled loop runs before it returns to Python, which then looks at signals (Ctrl-C,
#: SIGTERM) and at the other threads' failures: ~30-70 ms at 1-2 million steps/s
CHUNK_STEPS = 1 << 16
AUTO = "auto"


@dataclass(frozen=True, kw_only=True, slots=True)
class VisitConfig:
    """Everything a trial needs besides the nest and its seed.

    visit_steps : steps of each visit (sec. 4: 50,000), or ``"auto"``: each visit ends when the
        robot's online rule (``stop``, :mod:`stcvision.controllers.buffon.stopping`) says so, after at most
        ``max_visit_steps``.
    trail_width_u : pheromone trail width in body lengths (sec. 4: 0.1).
    dt_s : world step (the pymunk world's default, 0.05 s).
    """

    visit_steps: int | str = PAPER_VISIT_STEPS
    stop: StopParams = StopParams()
    max_visit_steps: int = 0  # 0: the cap of stcvision.limits
    # trail-aware exploration (beta; 0: the paper's behaviour): docs/results/buffon.md
    trail_turn: float = 0.0
    trail_width_u: float = PAPER_TRAIL_WIDTH_U
    dt_s: float = 0.05
    robot: DiffDriveParams = KHEPERA
    ir: IrParams = IrParams()
    behaviour: ExplorerParams = ExplorerParams()
    counter: CounterParams = CounterParams()

    def __post_init__(self):
        from stcvision.limits import MAX_BUFFON_VISIT_STEPS

        if self.visit_steps != AUTO and not (
            isinstance(self.visit_steps, int) and 0 < self.visit_steps <= MAX_BUFFON_VISIT_STEPS
        ):
            raise BadInputError(
                f"visit steps must be 'auto' or a positive integer at most {MAX_BUFFON_VISIT_STEPS:,} "
                f"(stcvision.limits.MAX_BUFFON_VISIT_STEPS); got {self.visit_steps!r}"
            )
        if not (isinstance(self.trail_turn, int | float) and 0 <= self.trail_turn <= 1):
            raise BadInputError(f"trail turn must be a number in [0, 1]; got {self.trail_turn!r}")
        if not (isinstance(self.max_visit_steps, int) and 0 <= self.max_visit_steps <= MAX_BUFFON_VISIT_STEPS):
            raise BadInputError(f"max visit steps must be an integer in [0, {MAX_BUFFON_VISIT_STEPS:,}]")
        if not (math.isfinite(self.trail_width_u) and self.trail_width_u > 0):
            raise BadInputError(f"trail width must be a positive number of body lengths; got {self.trail_width_u!r}")

    @property
    def trail_width_m(self) -> float:
        return self.trail_width_u * BODY_LENGTH_M

    @property
    def auto(self) -> bool:
        return self.visit_steps == AUTO

    @property
    def step_limit(self) -> int:
        """The most steps one visit can take."""
        from stcvision.limits import MAX_BUFFON_VISIT_STEPS

        if not self.auto:
            return self.visit_steps
        return self.max_visit_steps or MAX_BUFFON_VISIT_STEPS

    def kernel_params(self) -> np.ndarray:
        """The constants the kernel reads, in :data:`_P` order."""
        rb, ir, b, c = self.robot, self.ir, self.behaviour, self.counter
        from stcvision.sim_camera.odometry import true_wheel_diameters_m

        dl, dr = true_wheel_diameters_m(rb.wheel_diameter_m, rb.ed)
        vals = {
            "dt": self.dt_s,
            "gamma": b.gamma,
            "front_thr": b.front_sum_threshold,
            "side_thr": b.side_threshold,
            "speed_scale": b.speed_scale_m_s,
            "noise": b.noise,
            "esc_min": b.escape_min,
            "esc_max": b.escape_max,
            "vmax": rb.max_wheel_speed_m_s,
            "radius": rb.radius_m,
            "b_true": rb.wheelbase_m * rb.eb,
            "dl_ratio": dl / rb.wheel_diameter_m,
            "dr_ratio": dr / rb.wheel_diameter_m,
            "slip_k": rb.slip_k,
            "ir_sat": ir.saturation_m,
            "ir_range": ir.range_m,
            "ir_sigma": ir.noise_sigma,
            "rate": c.rate,
            "thr": c.threshold,
            "hyst": c.hysteresis,
            "half_w": 0.5 * self.trail_width_m,
            "recent_stamps": self.stop.recent_u * BODY_LENGTH_M / STAMP_M,
            "avoid": self.trail_turn,
        }
        return np.array([vals[k] for k in _P], dtype=np.float64)


_P = (
    "dt",
    "gamma",
    "front_thr",
    "side_thr",
    "speed_scale",
    "noise",
    "esc_min",
    "esc_max",
    "vmax",
    "radius",
    "b_true",
    "dl_ratio",
    "dr_ratio",
    "slip_k",
    "ir_sat",
    "ir_range",
    "ir_sigma",
    "rate",
    "thr",
    "hyst",
    "half_w",
    "recent_stamps",
    "avoid",
)
# state columns
X, Y, TH, R, WL, WR, LEVEL, PLEN, ABOVE, GAIN, BLIND, ESC, CROSS, STEPS, GAVE_UP = range(15)
N_STATE = 15


@numba.njit(cache=True, nogil=True)
def _ir_reading(d, sat, rng_m, noise):
    v = 0.0
    if d < rng_m:
        v = min(1.0, max(0.0, (rng_m - d) / (rng_m - sat))) ** 2
    return min(1.0, max(0.0, v + noise))


@numba.njit(cache=True, nogil=True, inline="always")
def _read_ir(ir, x, y, th, irg, geo, ir_cos, ir_sin, radius, ir_sat, ir_range, ir_sigma):
    """The six IR rays from the rim (stcvision.sim_camera.robot_sensors.IrSensors) into ``ir``, their noise from
    the IR stream ``irg`` (one draw per ray, in ray order)."""
    caps, ox, oy, cell, ny, nx, offsets, index = geo
    lo, hi = cell_span(x, y, ox, oy, cell, ny, nx, offsets)
    if lo == hi:  # no solid within reach: the readings are noise around 0
        for q in range(ir_cos.shape[0]):
            ir[q] = _ir_reading(np.inf, ir_sat, ir_range, ir_sigma * irg.standard_normal())
        return
    ct, st_ = math.cos(th), math.sin(th)
    for q in range(ir_cos.shape[0]):
        c = ct * ir_cos[q] - st_ * ir_sin[q]
        sn = st_ * ir_cos[q] + ct * ir_sin[q]
        d = ray_cast(caps, ox, oy, cell, ny, nx, offsets, index, x, y, x + radius * c, y + radius * sn, c, sn, ir_range)
        ir[q] = _ir_reading(d, ir_sat, ir_range, ir_sigma * irg.standard_normal())


@numba.njit(cache=True, nogil=True, inline="always")
def _rule_stops(st, lay, plen, crossings, steps_done, blind, sp, bst, l1_u):
    """Whether the online rule (:mod:`stcvision.controllers.buffon.stopping`) ends the visit now; a first
    visit that cannot reach its coverage gives up (``st[GAVE_UP]``)."""
    coverage, min_self, pi_w, second_ratio = sp[0], sp[1], sp[2], sp[3]
    min_cross, rel_se, batches, max_ratio = sp[4], sp[5], int(sp[6]), sp[7]
    mix_tol, max_coverage = sp[8], sp[9]
    if not lay:
        return second_visit_done(
            bst, plen / BODY_LENGTH_M, crossings, l1_u, second_ratio, min_cross, rel_se, batches, max_ratio
        )
    if first_visit_done(plen / BODY_LENGTH_M, crossings, coverage, min_self, pi_w, bst, batches, mix_tol, max_coverage):
        return True
    if first_visit_hopeless(steps_done, blind, crossings, min_self):
        st[GAVE_UP] = 1.0
        return True
    return False


@numba.njit(cache=True, nogil=True)
def _visit(
    state,
    behaviour_rng,
    ir_rng,
    slip_rng,
    steps,
    grid,
    lay,
    geo,
    outer,
    trail,
    params,
    ir_angles_rad,
    record,
    auto_stop,
    stop_params,
    batch_state,
    first_path_u,
):
    """Advance one robot (``state``, (N_STATE,)) by at most ``steps`` steps (so that the caller
    can look at signals between chunks), drawing from its own generators (numba runs numpy's
    Generator algorithms, bit for bit): ``behaviour_rng`` the behaviour's n and nbar, ``ir_rng``
    the IR noise, ``slip_rng`` the wheel slip. ``grid``: the trail raster (uint32: 0 empty, else
    the path, in :data:`STAMP_M` units + 1, at which the first visit first laid the cell);
    ``lay``: visit 1 (lay, and count encounters with its own older trail) or 2 (sense and count
    crossings); ``record`` (steps or 0, 3): x, y, crossed per step. ``auto_stop``: stop when the
    online rule (:mod:`stcvision.controllers.buffon.stopping`: constants ``stop_params``, batch-means state
    ``batch_state`` of the encounters, first-visit path ``first_path_u``) says so. Returns
    (containment failures, stopped by the rule)."""
    caps, ox, oy, cell, ny, nx, offsets, index = geo
    dt, gamma, front_thr, side_thr, k = params[0], params[1], params[2], params[3], params[4]
    noise, esc_min, esc_max, vmax, radius = params[5], params[6], params[7], params[8], params[9]
    b_true, dl_ratio, dr_ratio, slip_k = params[10], params[11], params[12], params[13]
    ir_sat, ir_range, ir_sigma = params[14], params[15], params[16]
    rate, thr, hyst = params[17], params[18], params[19]
    half_w, recent_stamps, avoid = params[20], params[21], params[22]
    batches = int(stop_params[6])
    ir_cos, ir_sin, ir = np.cos(ir_angles_rad), np.sin(ir_angles_rad), np.empty(6)
    x, y, th = state[X], state[Y], state[TH]
    r, wl, wr, level, plen = state[R], state[WL], state[WR], state[LEVEL], state[PLEN]
    gain, blind, esc, above = state[GAIN], state[BLIND], state[ESC], state[ABOVE] > 0.5
    crossings, done = int(state[CROSS]), int(state[STEPS])
    escapes, stopped = 0, False
    turn = 0.0  # trail-aware exploration: the turn away from the old trail under way (+1 left, -1 right)
    recording = record.shape[0] > 0
    for s in range(steps):
        # 1. six IR rays from the rim (stcvision.sim_camera.robot_sensors.IrSensors), noise from their stream
        _read_ir(ir, x, y, th, ir_rng, geo, ir_cos, ir_sin, radius, ir_sat, ir_range, ir_sigma)
        # 2. the behaviour of sec. 3.2 (the scalar controller's own equations)
        n = -noise + 2.0 * noise * behaviour_rng.random()
        nbar = esc_min + (esc_max - esc_min) * behaviour_rng.random()
        r, wl, wr, esc, rbar = explorer_core_nb(
            r, wl, wr, esc, ir[0], ir[1], ir[2], ir[3], ir[4], ir[5], n, nbar, gamma, front_thr, side_thr
        )
        if lay and avoid > 0.0 and above and esc == 0.0:  # laying over its old trail, no wall escape: turn off it
            rbar = min(1.0, max(-1.0, rbar + avoid * turn))
        ml, mr = wheel_speeds_nb(rbar, k)
        # 3. wheels -> body
        v, dth = _wheels_to_body(ml, mr, vmax, dt, gain, dl_ratio, dr_ratio, slip_k, slip_rng, b_true)
        mid = th + 0.5 * dth
        # 4. frictionless contact
        nx_, ny_, _ = push_out(
            caps, ox, oy, cell, ny, nx, offsets, index, x + v * math.cos(mid), y + v * math.sin(mid), radius
        )
        th += dth
        step_m = math.hypot(nx_ - x, ny_ - y)
        plen += step_m
        # 5. the detector reads the cell it reached; visit 1 then lays its trail there
        seen = _sense_trail(grid, trail, lay, plen, recent_stamps, half_w, x, y, nx_, ny_)
        x, y = nx_, ny_
        level, above, crossed = integrate_nb(level, above, seen, rate, thr, hyst)
        if crossed and avoid > 0.0:
            turn = 1.0 if behaviour_rng.random() < 0.5 else -1.0
        crossings += crossed
        blind += above
        # the batch means of the encounter rate: the second visit's crossings whatever the rule
        # (their standard error is reported), the first visit's self-encounters for the online
        # rule's mixing test (nothing else reads them: a fixed-length visit skips the work)
        if auto_stop or not lay:
            batch_add(batch_state, 1.0 if crossed else 0.0, step_m / BODY_LENGTH_M, batches)
        if (s & 15) == 0 and not inside_polygon(outer, x, y):
            escapes += 1
        if recording:
            record[s, 0], record[s, 1], record[s, 2] = x, y, 1.0 if crossed else 0.0
        if (
            auto_stop
            and (s & 63) == 63
            and _rule_stops(state, lay, plen, crossings, done + s + 1, blind, stop_params, batch_state, first_path_u)
        ):
            stopped = True
            done += s + 1
            break
    else:
        done += steps
    state[X], state[Y], state[TH] = x, y, th
    state[R], state[WL], state[WR], state[LEVEL], state[PLEN] = r, wl, wr, level, plen
    state[ABOVE], state[BLIND], state[ESC] = 1.0 if above else 0.0, blind, esc
    state[CROSS], state[STEPS] = crossings, done
    return escapes, stopped


@numba.njit(cache=True, nogil=True)
def _wheels_to_body(ml, mr, vmax, dt, gain, dl_ratio, dr_ratio, slip_k, slip_rng, b_true):
    """One step's wheel travel (speeds ``ml``, ``mr`` clipped at ``vmax``, over the step ``dt``
    at the battery's ``gain``; each wheel's own ratio, and slip drawn from ``slip_rng``) as
    the body's forward move and turn, as :meth:`stcvision.sim_camera.robot.DiffDriveRobot._pre_step` does:
    (v, dth)."""
    dl = min(vmax, max(-vmax, ml)) * dt * gain * dl_ratio
    dr = min(vmax, max(-vmax, mr)) * dt * gain * dr_ratio
    if slip_k > 0.0:
        n0, n1 = slip_rng.standard_normal(), slip_rng.standard_normal()
        dl += slip_k * math.sqrt(abs(dl)) * n0
        dr += slip_k * math.sqrt(abs(dr)) * n1
    return 0.5 * (dl + dr), (dr - dl) / b_true


@numba.njit(cache=True, nogil=True)
def _sense_trail(grid, trail, lay, plen, recent_stamps, half_w, x, y, nx_, ny_):
    """The detector's reading (1.0 or 0.0) of the cell the robot reached, ``(nx_, ny_)``: on
    the first visit (``lay``) its own trail laid long enough ago (not the stripe being laid),
    which it then extends from ``(x, y)``; on the second, any trail."""
    gox, goy, gcell = trail
    stamp = read_cell(grid, gox, goy, gcell, nx_, ny_)
    if not lay:
        return 1.0 if stamp > 0 else 0.0
    seen = 1.0 if stamp > 0 and plen / STAMP_M + 1.0 - stamp > recent_stamps else 0.0
    stamp_segment(grid, gox, goy, gcell, half_w, x, y, nx_, ny_, np.uint32(plen / STAMP_M + 1.0))
    return seen


@dataclass(frozen=True, slots=True)
class TrialSet:
    """Per-trial results (lengths in body lengths).

    Beside what the estimate needs (L1, L2, N, the blind fraction): the first visit's
    self-encounters ``n_self``, the second visit's batch-means relative standard error of its
    crossing rate ``rate_rel_se`` (:mod:`stcvision.controllers.buffon.stopping`), each trial's robot-steps
    ``steps`` and whether the online rule ended both visits (``converged``; True for fixed
    lengths)."""

    l1_u: np.ndarray
    l2_u: np.ndarray
    crossings: np.ndarray
    blind_fraction: np.ndarray  # share of the second visit's steps spent counted-in (the counter is blind)
    escapes: int
    robot_steps: int
    wall_s: float
    trails: dict = field(default_factory=dict)  # recorded trial: 'visit1', 'visit2' (S, 3) arrays
    cpu_s: float = float("nan")  # process CPU time (honest per-core speed on a shared machine)
    n_self: np.ndarray | None = None
    rate_rel_se: np.ndarray | None = None
    steps: np.ndarray | None = None
    converged: np.ndarray | None = None
    online: bool = False  # both visits' lengths decided by the online rule
    self_blind: np.ndarray | None = None  # share of the first visit's steps its counter was blind on its old trail
    trail_width_u: float = PAPER_TRAIL_WIDTH_U  # the trail the first visit laid (its coverage reads n_self with it)

    @property
    def nbc(self) -> np.ndarray:
        """Normalised Buffon count (sec. 4): crossings / second-visit length (per body length)."""
        return self.crossings / self.l2_u


def _trail_grid_shape(nest: Nest, cell_m: float) -> tuple[int, int]:
    xmin, ymin, xmax, ymax = nest.arena.bounds_m
    shape = (math.ceil((ymax - ymin) / cell_m) + 1, math.ceil((xmax - xmin) / cell_m) + 1)
    from stcvision.limits import MAX_BUFFON_RASTER_BYTES

    if shape[0] * shape[1] * np.dtype(np.uint32).itemsize > MAX_BUFFON_RASTER_BYTES:
        raise BadInputError(
            f"nest {nest.spec!r} with a {cell_m / BODY_LENGTH_M * 2:g} u trail needs a {shape[0]}x{shape[1]} raster, "
            f"over the cap of {MAX_BUFFON_RASTER_BYTES / 2**20:,.0f} MiB (MAX_BUFFON_RASTER_BYTES); "
            "use a wider trail or a smaller nest"
        )
    return shape


def trial_seeds(seed: int | np.random.SeedSequence, trials: int) -> list[list[np.random.SeedSequence]]:
    """Per trial, four seed streams: start heading, behaviour draws, IR noise, wheel slip.
    Trial i's streams depend only on ``seed`` and i, never on how many trials run."""
    root = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    kids = [np.random.SeedSequence(root.entropy, spawn_key=(*root.spawn_key, i)) for i in range(trials)]
    return [k.spawn(4) for k in kids]


def start_headings(start_rng: np.random.Generator) -> tuple[float, float]:
    """The two visits' start headings: away from the bottom wall within +-15 degrees."""
    return tuple(math.pi / 2 + start_rng.uniform(-START_HEADING_SPREAD_RAD, START_HEADING_SPREAD_RAD, 2))


def run_trials(
    nest: Nest,
    config: VisitConfig = VisitConfig(),
    *,
    trials: int = 100,
    seed: int | np.random.SeedSequence = 0,
    record_trial: int | None = None,
    progress: Callable[[int], None] | None = None,
    threads: int = 1,
) -> TrialSet:
    """Run ``trials`` independent two-visit trials of Buffon's method in ``nest``.

    ``progress(n)`` is called with the robot-steps done after each chunk of a visit (for a
    progress bar). ``record_trial`` keeps that trial's two paths (x, y, crossed per step) in
    ``TrialSet.trails``. ``threads`` > 1 runs trials on that many threads (the compiled loop
    releases the GIL); the results do not depend on it. A signal (KeyboardInterrupt, or the
    CLI's SIGTERM exception) stops every thread within one chunk of steps.
    """
    from stcvision.limits import check_buffon_work

    if not (isinstance(trials, int) and trials > 0):
        raise BadInputError(f"trials must be a positive integer; got {trials!r}")
    if not (isinstance(threads, int) and threads > 0):
        raise BadInputError(f"threads must be a positive integer; got {threads!r}")
    check_buffon_work(trials=trials, visit_steps=config.step_limit, raster_bytes=0, threads=threads,
                      record_steps=0, auto=config.auto)  # fmt: skip
    world = TrialWorld(nest, config)
    threads = min(threads, trials)
    check_buffon_work(
        trials=trials,
        visit_steps=config.step_limit,
        raster_bytes=world.raster_bytes,
        threads=threads,
        record_steps=config.step_limit if record_trial is not None and not config.auto else 0,
        auto=config.auto,
    )
    t0, c0 = time.perf_counter(), time.process_time()
    seeds = trial_seeds(seed, trials)
    cancel = threading.Event()

    def one(i: int):
        return world.trial(seeds[i], record=i == record_trial, progress=progress, cancel=cancel)

    if threads == 1:
        rows = [one(i) for i in range(trials)]
    else:
        from concurrent.futures import ThreadPoolExecutor

        pool = ThreadPoolExecutor(max_workers=threads)
        try:
            rows = list(pool.map(one, range(trials)))
        except BaseException:
            cancel.set()  # the other threads stop at their next chunk
            pool.shutdown(wait=True, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
    cols = list(zip(*rows, strict=True))
    l1, l2, n, blind, esc, trails, n_self, se, steps, conv, self_blind = cols
    return TrialSet(
        np.array(l1), np.array(l2), np.array(n, dtype=np.int64), np.array(blind), int(sum(esc)),
        int(sum(steps)), time.perf_counter() - t0, next((t for t in trails if t), {}),
        time.process_time() - c0, np.array(n_self, dtype=np.int64), np.array(se), np.array(steps, dtype=np.int64),
        np.array(conv, dtype=bool), config.auto, np.array(self_blind), config.trail_width_u,
    )  # fmt: skip


class Cancelled(Exception):
    """A trial stopped because another thread's trial failed or was interrupted."""


class TrialWorld:
    """What every trial of one nest shares (walls, raster layout, constants), built once."""

    def __init__(self, nest: Nest, config: VisitConfig):
        rb = config.robot
        self.config = config
        cell = 0.5 * config.trail_width_m  # as stcvision.sim_camera.layers.PheromoneLayer
        xmin, ymin = nest.arena.bounds_m[:2]
        self.trail = (xmin, ymin, cell)
        self.grid_shape = _trail_grid_shape(nest, cell)  # refused before the walls' grid is built
        self.geo = StaticGeometry.from_arena(nest.arena, reach_m=rb.radius_m + config.ir.range_m + 0.005)
        self.raster_bytes = self.grid_shape[0] * self.grid_shape[1] * np.dtype(np.uint32).itemsize
        self.prm = config.kernel_params()
        self.sp = config.stop.array(config.trail_width_u)
        self.ir_ang = np.array(config.ir.angles_rad, dtype=np.float64)
        self.start = nest.start_xy

    def trial(self, seeds, *, record: bool = False, progress=None, cancel: threading.Event | None = None):
        """One trial: (L1 u, L2 u, crossings, blind fraction, escapes, recorded paths,
        self-encounters, rate relative SE, robot-steps, converged, first visit's blind fraction)."""
        from stcvision.limits import MAX_BUFFON_RECORD_STEPS

        c = self.config
        start, beh, irg, slip = (np.random.default_rng(s) for s in seeds)
        gain = _motor_gain(c.robot, start)
        grid = np.zeros(self.grid_shape, dtype=np.uint32)
        out, trails, escapes, converged, steps = [0.0, 0.0, 0, 0.0], {}, 0, True, 0
        n_self, self_blind, rel_se = 0, float("nan"), float("nan")
        limit = c.step_limit
        for visit, heading in enumerate(start_headings(start), 1):
            st = np.zeros(N_STATE)
            st[X], st[Y], st[TH], st[GAIN] = *self.start, heading, gain
            bst = new_batch_state(c.stop.batches)
            recs, stopped = [], False
            geo = self.geo
            while not stopped and st[STEPS] < limit:
                if cancel is not None and cancel.is_set():
                    raise Cancelled("another trial stopped")
                chunk = int(min(CHUNK_STEPS, limit - st[STEPS]))
                keep = record and st[STEPS] < MAX_BUFFON_RECORD_STEPS  # an online visit records its start
                rec = np.zeros((chunk if keep else 0, 3))
                before = int(st[STEPS])
                e, stopped = _visit(st, beh, irg, slip, chunk, grid, visit == 1, geo.arrays, geo.outer, self.trail,
                                    self.prm, self.ir_ang, rec, c.auto, self.sp, bst, out[0])  # fmt: skip
                escapes += e
                if keep:
                    recs.append(rec[: int(st[STEPS]) - before])
                if progress is not None:
                    progress(int(st[STEPS]) - before)
            converged &= (stopped and st[GAVE_UP] == 0.0) or not c.auto
            done = int(st[STEPS])
            steps += done
            out[visit - 1] = st[PLEN] / BODY_LENGTH_M
            if visit == 1:
                n_self, self_blind = int(st[CROSS]), st[BLIND] / max(done, 1)
            else:
                out[2], out[3] = int(st[CROSS]), st[BLIND] / done
                rel_se = batch_rel_se(bst, c.stop.batches)
            if record:
                trails[f"visit{visit}"] = np.concatenate(recs) if recs else np.zeros((0, 3))
        return (*out, escapes, trails, n_self, rel_se, steps, converged, self_blind)


def _motor_gain(rb: DiffDriveParams, rng: np.random.Generator) -> float:
    s = rb.speed_gain_spread
    return float(rng.uniform(1 - s, 1 + s)) if s > 0 else 1.0
