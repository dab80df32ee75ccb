"""Faults of the robot's hardware injected into the coverage loop (``stcvision cover --fault
NAME[:LEVEL]``, repeatable): they break the robot, never the world. The afterglow law, the
sensor model and the board stay as they are; a fault is a part the loop builds the robot with --
the plant's turn rate and what befalls its moves (its motors and wheels), the floor's marking
(its UV LEDs) or the camera around the renderer (its frames) -- and leaves the maths alone.

=======  ==========================================================================
name     what breaks (LEVEL: what :data:`FAULTS` says, with its default and range)
=======  ==========================================================================
rate     the turn rate drifts off nominal: a sine of amplitude LEVEL, period 10-30 min,
         0 at the start (:func:`_drifting_rate`)
led      one of the four rear UV LEDs is dead: its dot is never laid (LEVEL 1 is the
         robot's rightmost LED, 4 its leftmost)
drop     a fraction LEVEL of the camera's frames is lost: half never arrive, half
         arrive black (all 0 DN)
stray    a white lamp on the floor somewhere on the board, LEVEL times a red light's
         luminance
noise    the camera's temporal noise floor (read noise and dark shot noise of a dark
         pixel) is LEVEL times its own (:meth:`FaultyCamera._noisy`)
bump     on a share :data:`BUMP_PER_MOVE` of forward moves the robot ends pushed LEVEL
         cm in a random direction
slip     on a share :data:`SLIP_PER_MOVE` of forward moves a wheel slips: the move is an
         arc that leaves the robot turned by LEVEL degrees
=======  ==========================================================================

``Faults.events`` counts what each fault did: marks laid with a dead LED, frames lost, frames
with the lamp in view, bumps, slips (``rate`` and ``noise`` act all the time: 0).

``drop``, ``stray`` and ``noise`` are faults of the camera's frames and need
``--perception camera``; the others act on the plant or the floor and run with any perception.

Random streams: each fault draws from its own generator, :func:`fault_stream` (a SeedSequence of
the run's seed and the fault's name, apart from the loop's four spawned children), so adding a
fault never reshuffles the motion, camera, oracle or board streams of a run
(:func:`stcvision.controllers.stc.loop.streams`), and one fault's draws never depend on which other faults
are on.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np

from stcvision.angles import wrap_angle
from stcvision.errors import BadInputError

__all__ = ["FAULTS", "Bump", "FaultSpec", "Faults", "Slip", "fault_stream", "fault_table", "parse_fault"]


@dataclass(frozen=True, kw_only=True, slots=True)
class FaultSpec:
    """A fault's LEVEL: what it means, its default and its range (``lo`` excluded when
    ``lo_open``); ``integer`` levels are whole numbers."""

    name: str
    meaning: str
    default: float
    lo: float
    hi: float
    lo_open: bool = True
    integer: bool = False
    camera_only: bool = False

    def check(self, level: float) -> float:
        ok = math.isfinite(level) and (level > self.lo if self.lo_open else level >= self.lo) and level <= self.hi
        if ok and self.integer and level != int(level):
            ok = False
        if not ok:
            lo = f"({self.lo:g}" if self.lo_open else f"[{self.lo:g}"
            kind = "a whole number " if self.integer else ""
            raise BadInputError(
                f"--fault {self.name}: LEVEL ({self.meaning}) must be {kind}in {lo}, {self.hi:g}], got {level:g}"
            )
        return float(level)


#: every fault, by name (the module docstring's table)
FAULTS = {
    s.name: s
    for s in (
        FaultSpec(name="rate", meaning="turn-rate error amplitude, fraction", default=0.25, lo=0.0, hi=0.5),
        FaultSpec(
            name="led", meaning="the dead LED, 1-4 from the right", default=2, lo=1, hi=4, lo_open=False, integer=True
        ),  # fmt: skip
        FaultSpec(
            name="drop",
            meaning="fraction of frames lost",
            default=0.05,
            lo=0.0,
            hi=0.5,
            lo_open=False,
            camera_only=True,
        ),  # fmt: skip
        FaultSpec(
            name="stray", meaning="lamp luminance in red lights", default=1.0, lo=0.0, hi=10.0, camera_only=True
        ),  # fmt: skip
        FaultSpec(
            name="noise", meaning="noise floor factor", default=3.0, lo=1.0, hi=10.0, lo_open=False, camera_only=True
        ),  # fmt: skip
        FaultSpec(name="bump", meaning="push, cm", default=4.0, lo=0.0, hi=7.0),
        FaultSpec(name="slip", meaning="turn of one slip, degrees", default=5.0, lo=0.0, hi=30.0),
    )
}
#: the fraction of forward moves a bump / a slip happens on
BUMP_PER_MOVE = 1 / 20
SLIP_PER_MOVE = 1 / 10
#: the stray lamp's disc (m): a small lamp, as wide as a red light's diffuser
LAMP_DIAMETER_M = 0.010
#: the stray lamp's colour response (B, G, R): white, every channel alike
LAMP_BGR = (1.0, 1.0, 1.0)


def fault_table() -> list[dict]:
    """Every fault as a JSON object (``stcvision cover --list-faults --json``)."""
    return [
        {
            "kind": "fault",
            "name": s.name,
            "meaning": s.meaning,
            "default": s.default,
            "range": f"{'(' if s.lo_open else '['}{s.lo:g}, {s.hi:g}]",
            "integer": s.integer,
            "camera_only": s.camera_only,
        }
        for s in FAULTS.values()
    ]


def parse_fault(text: str) -> tuple[str, float]:
    """``NAME[:LEVEL]`` -> (name, level), the default level when none is given."""
    name, sep, lv = str(text).partition(":")
    spec = FAULTS.get(name.strip())
    if spec is None:
        names = ", ".join(FAULTS)
        raise BadInputError(f"--fault {text!r}: unknown fault; expected NAME[:LEVEL] with NAME one of {names}")
    if not sep:
        return spec.name, float(spec.default)
    try:
        level = float(lv)
    except ValueError:
        raise BadInputError(f"--fault {text!r}: LEVEL must be a number ({spec.meaning}), got {lv!r}") from None
    return spec.name, spec.check(level)


def fault_stream(seed: int, name: str) -> np.random.Generator:
    """The generator of fault ``name`` in the run of ``seed``: its own SeedSequence (the seed and
    a hash of the name as the spawn key), so it shares nothing with the loop's spawned children
    (spawn keys (0,)..(3,)) nor with another fault's stream."""
    key = zlib.crc32(f"fault:{name}".encode())
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(0xFA17, key)))


class Faults:
    """The faults of one run (``cfg.faults``: (name, level) pairs), each with its own stream.
    The loop builds its parts with what they give (:meth:`rate_factor`, :meth:`disturbances`,
    :meth:`lay_filter`, :meth:`camera_wrap`); :attr:`events` counts what each fault did."""

    def __init__(self, faults, seed: int, perception: str):
        self.faults: dict[str, float] = {}
        for name, level in faults:
            spec = FAULTS.get(name)
            if spec is None:
                raise BadInputError(f"unknown fault {name!r}; expected one of {', '.join(FAULTS)}")
            if spec.camera_only and perception != "camera":
                raise BadInputError(f"--fault {name} is a fault of the camera's frames: it needs --perception camera")
            if name in self.faults:
                raise BadInputError(f"--fault {name} given twice")
            self.faults[name] = spec.check(float(level))
        self.rngs = {name: fault_stream(seed, name) for name in self.faults}
        self.events = dict.fromkeys(self.faults, 0)

    def __bool__(self) -> bool:
        return bool(self.faults)

    def labels(self) -> list[str]:
        return [f"{n}:{v:g}" for n, v in self.faults.items()]

    # ------------------------------------------------------------------ the parts they give
    # Each fault is a part the loop builds the robot with (the plant's turn rate and the moves'
    # disturbances, the floor's LEDs, the camera around the renderer), never a method swapped
    # on a built object: reading Plant.forward or Floor.lay tells what runs.
    def rate_factor(self):
        """``rate``: the turn rate's factor over time (:func:`_drifting_rate`), else None."""
        if "rate" not in self.faults:
            return None
        return _drifting_rate(self.faults["rate"], self.rngs["rate"])

    def disturbances(self) -> tuple:
        """``slip`` then ``bump``: what may befall the robot after each forward move."""
        f = self.faults
        out = []
        if "slip" in f:
            out.append(Slip(math.radians(f["slip"]), self.rngs["slip"], self.events))
        if "bump" in f:
            out.append(Bump(f["bump"] / 100, self.rngs["bump"], self.events))
        return tuple(out)

    def lay_filter(self):
        """``led``: the dots a mark keeps when one LED is dead (counting the marks), else None."""
        if "led" not in self.faults:
            return None
        dead = int(self.faults["led"]) - 1

        def without_dead_led(xy_m):
            self.events["led"] += 1
            return np.delete(np.asarray(xy_m, float).reshape(-1, 2), dead, axis=0)

        return without_dead_led

    def camera_wrap(self, board):
        """``drop``, ``stray``, ``noise``: the function that puts the robot's camera inside a
        :class:`FaultyCamera` (the stray lamp placed on ``board`` now), else None."""
        f = self.faults
        if not any(n in f for n in ("drop", "stray", "noise")):
            return None
        lamp = None
        if "stray" in f:
            w, h = board.size_m
            lamp = self.rngs["stray"].uniform((0.0, 0.0), (w, h)).reshape(1, 2)
        return lambda cam: FaultyCamera(cam, self, lamp_m=lamp)


class Slip:
    """One wheel slips on a share :data:`SLIP_PER_MOVE` of forward moves: the move is an arc
    turning the robot by +-``theta_rad``; its chord leans by half of it."""

    def __init__(self, theta_rad: float, rng: np.random.Generator, events: dict):
        self.theta, self.rng, self.events = theta_rad, rng, events

    def after_move(self, plant, start_xy) -> None:
        if self.rng.random() >= SLIP_PER_MOVE:
            return
        theta = self.theta * (1.0 if self.rng.random() < 0.5 else -1.0)
        x0, y0 = start_xy
        dx, dy = plant.x - x0, plant.y - y0
        c, s = math.cos(theta / 2), math.sin(theta / 2)
        plant.x, plant.y = x0 + c * dx - s * dy, y0 + s * dx + c * dy
        plant.heading_rad = wrap_angle(plant.heading_rad + theta)
        self.events["slip"] += 1


class Bump:
    """On a share :data:`BUMP_PER_MOVE` of forward moves the robot ends pushed ``push_m`` in a
    random direction."""

    def __init__(self, push_m: float, rng: np.random.Generator, events: dict):
        self.push, self.rng, self.events = push_m, rng, events

    def after_move(self, plant, start_xy) -> None:
        if self.rng.random() >= BUMP_PER_MOVE:
            return
        a = self.rng.uniform(0, 2 * math.pi)
        plant.x += self.push * math.cos(a)
        plant.y += self.push * math.sin(a)
        self.events["bump"] += 1


def _drifting_rate(amplitude: float, rng: np.random.Generator):
    """The turn rate's factor ``1 +- amplitude * sin(2 pi t / P)``: right at the start (the turn
    time is set before the run to what the first rotation needs: the ant-like STC paper), then
    drifting off nominal by up to ``amplitude`` and back over a period ``P`` of 10-30 minutes."""
    period_s = rng.uniform(600.0, 1800.0)
    sign = 1.0 if rng.random() < 0.5 else -1.0

    def factor(t_s: float) -> float:
        return 1.0 + sign * amplitude * math.sin(2 * math.pi * t_s / period_s)

    return factor


class FaultyCamera:
    """The robot's camera (:class:`stcvision.sim_camera.camera.SyntheticCamera`) with its frame faults:
    lost frames (``render`` returns None: nothing arrived) and black ones, a stray lamp in the
    scene, a raised noise floor (its dark frames too: taken with the same faulty camera). Every
    other attribute is the camera's own."""

    def __init__(self, cam, faults: Faults, *, lamp_m=None):
        self._cam = cam
        self._f = faults
        self._lamp = lamp_m

    def __getattr__(self, name):
        return getattr(self._cam, name)

    def _noisy(self, sensor):
        """``sensor`` with the noise floor of a dark pixel ``noise`` times its own:
        ``r'^2 + D = L^2 (r^2 + D)`` (D the mean dark electrons of the exposure)."""
        s = sensor or self._cam.sensor
        lv = self._f.faults.get("noise")
        if lv is None:
            return s
        d = s.dark_current_e_s * s.exposure_s
        return s.replace(read_noise_e=math.sqrt(lv**2 * (s.read_noise_e**2 + d) - d))

    def dark_frame(self, *, rng, sensor=None, n_avg: int = 1):
        return self._cam.dark_frame(rng=rng, sensor=self._noisy(sensor), n_avg=n_avg)

    def median_dark(self, n: int = 16, *, rng, sensor=None):
        return self._cam.median_dark(n, rng=rng, sensor=self._noisy(sensor))

    def render(self, pose, *, rng, t_s: float = 0.0, phosphor=None, red_lights_m=None, sensor=None, n_avg: int = 1,
               **kw):  # fmt: skip
        from stcvision.sim_camera.camera import RED_LIGHT_CD_M2, Frame
        from stcvision.sim_camera.image_sensor import expose

        f, rngs = self._f.faults, self._f.rngs
        s = self._noisy(sensor)
        if "drop" in f and rngs["drop"].random() < f["drop"]:
            self._f.events["drop"] += 1
            if rngs["drop"].random() < 0.5:
                return None  # the frame never arrived
            return Frame(np.zeros((*self._cam.shape, 3), s.dtype))
        if self._lamp is None:
            return self._cam.render(pose, rng=rng, t_s=t_s, phosphor=phosphor, red_lights_m=red_lights_m, sensor=s,
                                    n_avg=n_avg, **kw)  # fmt: skip
        # the scene as the camera renders it (SyntheticCamera.render), with the lamp added
        cam = self._cam
        if n_avg > 1:
            t_s = t_s + 0.5 * (n_avg - 1) * s.exposure_s
        lamp = (np.reshape(self._lamp, (1, 2)), f["stray"] * RED_LIGHT_CD_M2, LAMP_DIAMETER_M, LAMP_BGR)
        sig, info = cam.signal(pose, t_s=t_s, phosphor=phosphor, red_lights_m=red_lights_m, sensor=s, lamps=lamp)
        self._f.events["stray"] += int(info["lamps"]["visible"].any())  # frames with the lamp in view
        return Frame(expose(sig, s, cam.pattern, rng, n_avg=n_avg))
