"""Robot sensors: IR proximity (Khepera), capacitive ring (TASTI 2), tongue, pheromone, encoders.

Sensors are read on demand by controllers (``robot.sensors.ir.read()``); only the encoders are
updated every step by the world (:mod:`stcvision.sim_camera.odometry`). Ray sensors use pymunk
``segment_query_first`` against walls, obstacles and other robots (never the robot itself).
All noise comes from a per-sensor ``numpy.random.Generator`` split off the robot's seed stream.

IR (Buffon explorer; the Buffon's needle paper of Girgin & Sahin, sec. 3 and 3.2): six front sensors
on the body's rim, pointing at the Khepera angles +90, +45, +10, -10, -45, -90 degrees (index 0 =
left ... 5 = right; K-Team Khepera user manual, sensor layout). Reading I in [0, 1] (0 = no object,
1 = very close, the paper's convention) vs. distance d from the rim::

    I(d) = 1                                    d <= d_sat   (5 mm)
    I(d) = ((d_max - d) / (d_max - d_sat))^2    d_sat < d < d_max
    I(d) = 0                                    d >= d_max   (50 mm, Khepera IR range ~5 cm)

plus Gaussian noise (sigma 0.02 by default), clipped to [0, 1]. The quadratic fall-off is an
assumption shaped like the sampled Khepera responses (Miglino, Lund & Nolfi 1995, ref. [9] of the
Buffon's needle paper).

Capacitive ring (the TASTI 2 paper by Russell, sec. IV): nine electrodes of 20
degrees each over the front 180 degrees, on a ring of radius 153 mm, connected in parallel, so
one proximity signal. Model: electrode k sees the smallest gap g_k over a few radial rays in its
sector and contributes exp(-g_k / lambda) (lambda = 10 mm: fringing fields decay over about an
electrode width; assumed); the signal is the sum. The stop threshold is the signal for a steel
can (radius 36.5 mm, assumed) dead ahead at a 15 mm gap, so a robot that halts when the signal
reaches it stops "1.5cm away from the can", as the paper reports.

Tongue: the chemical layer's concentration at the turning centre (TASTI 2 moved its tongue
there, TASTI 2 paper sec. IV) plus Gaussian noise. Pheromone detector: binary reading of the
pheromone layer at the body centre (Buffon's needle paper sec. 3); the robot's leaky integrator and
crossing counter (sec. 4) are the Buffon controller's, in :mod:`stcvision.controllers.buffon.counter`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "CapacitiveRing",
    "CapacitiveRingParams",
    "IrParams",
    "IrSensors",
    "PheromoneDetector",
    "SensorSuite",
    "TongueSensor",
    "capacitive_signal_for_can",
    "ir_response",
]


@dataclass(frozen=True, kw_only=True, slots=True)
class IrParams:
    angles_rad: tuple[float, ...] = tuple(math.radians(a) for a in (90, 45, 10, -10, -45, -90))
    saturation_m: float = 0.005
    range_m: float = 0.05
    noise_sigma: float = 0.02


def ir_response(d_m, params: IrParams = IrParams()) -> np.ndarray:
    """Noise-free IR reading in [0, 1] for distance(s) ``d_m`` from the rim (inf = nothing)."""
    d = np.asarray(d_m, dtype=float)
    x = (params.range_m - d) / (params.range_m - params.saturation_m)
    return np.clip(x, 0.0, 1.0) ** 2


class IrSensors:
    """Six Khepera-like front IR proximity sensors of one robot."""

    def __init__(self, world, robot, params: IrParams, rng: np.random.Generator):
        self.world, self.robot, self.params, self.rng = world, robot, params, rng

    def distances_m(self) -> np.ndarray:
        """Distance from the rim to the first solid along each sensor axis (inf if none)."""
        x, y, th = self.robot.pose
        r = self.robot.params.radius_m
        rng_m = self.params.range_m
        out = np.full(len(self.params.angles_rad), np.inf)
        for k, a in enumerate(self.params.angles_rad):
            c, s = math.cos(th + a), math.sin(th + a)
            start = (x + r * c, y + r * s)
            d = self.world.ray_distance(start, (start[0] + rng_m * c, start[1] + rng_m * s), self.robot)
            if d is not None:
                out[k] = d
        return out

    def read(self) -> np.ndarray:
        """(6,) readings in [0, 1] with noise."""
        v = ir_response(self.distances_m(), self.params)
        if self.params.noise_sigma > 0:
            v = v + self.rng.normal(0.0, self.params.noise_sigma, v.shape)
        return np.clip(v, 0.0, 1.0)


@dataclass(frozen=True, kw_only=True, slots=True)
class CapacitiveRingParams:
    ring_radius_m: float = 0.153
    n_electrodes: int = 9
    electrode_span_rad: float = math.radians(20)
    rays_per_electrode: int = 5
    decay_m: float = 0.010
    range_m: float = 0.10
    noise_sigma: float = 0.002
    stop_gap_m: float = 0.015
    reference_can_radius_m: float = 0.0365

    def ray_angles_rad(self) -> np.ndarray:
        """(n_electrodes, rays) ray directions in the robot frame (0 = forward)."""
        centres = (np.arange(self.n_electrodes) - (self.n_electrodes - 1) / 2) * self.electrode_span_rad
        offs = (np.arange(self.rays_per_electrode) - (self.rays_per_electrode - 1) / 2) * (
            0.8 * self.electrode_span_rad / max(1, self.rays_per_electrode - 1)
        )
        return centres[:, None] + offs[None, :]


def _signal_from_gaps(gaps: np.ndarray, p: CapacitiveRingParams) -> float:
    g = gaps.min(axis=1)
    return float(np.where(np.isfinite(g), np.exp(-g / p.decay_m), 0.0).sum())


def capacitive_signal_for_can(
    gap_m: float,
    p: CapacitiveRingParams = CapacitiveRingParams(),
    can_radius_m: float | None = None,
) -> float:
    """Noise-free ring signal with a can of ``can_radius_m`` dead ahead, ``gap_m`` from the ring
    (pure geometry: each ray from the ring against the circle)."""
    rc = p.reference_can_radius_m if can_radius_m is None else can_radius_m
    R = p.ring_radius_m
    cx = R + gap_m + rc
    ang = p.ray_angles_rad()
    ox, oy = R * np.cos(ang), R * np.sin(ang)
    dx, dy = np.cos(ang), np.sin(ang)
    # |o + t d - c|^2 = rc^2  ->  t^2 + 2 t (d.(o-c)) + |o-c|^2 - rc^2 = 0
    bx, by = ox - cx, oy
    bq = dx * bx + dy * by
    cq = bx * bx + by * by - rc * rc
    disc = bq * bq - cq
    t = -bq - np.sqrt(np.maximum(disc, 0.0))
    gaps = np.where((disc >= 0) & (t >= 0) & (t <= p.range_m), t, np.inf)
    return _signal_from_gaps(gaps, p)


class CapacitiveRing:
    """TASTI 2's front capacitive ring: one proximity signal from nine parallel electrodes."""

    def __init__(self, world, robot, params: CapacitiveRingParams, rng: np.random.Generator):
        self.world, self.robot, self.params, self.rng = world, robot, params, rng
        self._angles = params.ray_angles_rad()
        self.stop_threshold = capacitive_signal_for_can(params.stop_gap_m, params)

    def gaps_m(self) -> np.ndarray:
        """(n_electrodes, rays) gap from the ring to the first solid along each ray."""
        x, y, th = self.robot.pose
        R = self.params.ring_radius_m
        L = self.params.range_m
        out = np.full(self._angles.shape, np.inf)
        for idx, a in np.ndenumerate(self._angles):
            c, s = math.cos(th + a), math.sin(th + a)
            start = (x + R * c, y + R * s)
            d = self.world.ray_distance(start, (start[0] + L * c, start[1] + L * s), self.robot)
            if d is not None:
                out[idx] = d
        return out

    def read(self) -> float:
        """Proximity signal (sum over electrodes, >= 0) with noise."""
        v = _signal_from_gaps(self.gaps_m(), self.params)
        if self.params.noise_sigma > 0:
            v += float(self.rng.normal(0.0, self.params.noise_sigma))
        return max(0.0, v)

    def obstacle_ahead(self) -> bool:
        """True when the signal reaches the stop threshold (~1.5 cm from a can)."""
        return self.read() >= self.stop_threshold


class TongueSensor:
    """Chemical concentration under the turning centre (TASTI 2), with Gaussian noise."""

    def __init__(self, world, robot, rng: np.random.Generator, noise_sigma: float = 0.01):
        self.world, self.robot, self.rng, self.noise_sigma = world, robot, rng, noise_sigma

    def read(self) -> float:
        layer = self.world.chemical
        x, y, _ = self.robot.pose
        c = float(layer.concentration([x, y])[0]) if layer is not None else 0.0
        if self.noise_sigma > 0:
            c += float(self.rng.normal(0.0, self.noise_sigma))
        return c


class PheromoneDetector:
    """Binary pheromone reading at the body centre (Buffon's needle paper sec. 3)."""

    def __init__(self, world, robot):
        self.world, self.robot = world, robot

    def read(self) -> bool:
        layer = self.world.pheromone
        if layer is None:
            return False
        p = self.robot.body.position
        return layer.read_xy(p.x, p.y)


class SensorSuite:
    """All sensors of one robot, each with its own noise stream (fixed spawn order)."""

    def __init__(
        self,
        world,
        robot,
        *,
        ir: IrParams = IrParams(),
        capacitive: CapacitiveRingParams | None = None,
    ):
        ss = robot.sensor_seed.spawn(3)
        if capacitive is None:
            capacitive = CapacitiveRingParams(ring_radius_m=robot.params.radius_m)
        self.ir = IrSensors(world, robot, ir, np.random.default_rng(ss[0]))
        self.capacitive = CapacitiveRing(world, robot, capacitive, np.random.default_rng(ss[1]))
        self.tongue = TongueSensor(world, robot, np.random.default_rng(ss[2]))
        self.pheromone = PheromoneDetector(world, robot)
        self.encoders = robot.encoders
