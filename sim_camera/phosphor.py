"""The phosphorescent floor: UV-charged dots and their afterglow.

Afterglow law
-------------
A dot charged for ``charge_s`` seconds by a UV LED glows, ``t`` seconds after the charge ended,
with luminance (hyperbolic "Becquerel" decay of long-persistence phosphors such as
SrAl2O4:Eu,Dy)::

    L(t) = L_sat * (1 - exp(-charge_s / fill_s)) * (1 + t / tau_s) ** -n

Parameters (world constants; see :class:`AfterglowLaw`):

* ``n = 1.1``: the late-time exponent. ISO 17398 / DIN 67510-1 photoluminescent classes specify
  the luminance 10 min and 60 min after excitation (class A 20 and 2.8 mcd/m^2, B 81 and 11.2,
  C 140 and 20, D 210 and 29): a ratio of ~7.1 for a 6x longer time, i.e. ``n = ln 7.1 / ln 6
  = 1.09``.
* ``tau_s = 10 s``: the onset of the power law; the fast initial component of SrAl2O4:Eu,Dy
  decays on a scale of seconds to tens of seconds.
* ``fill_s = 2 s``: charging saturates within a few seconds under a close UV LED; the ant-like STC
  paper (Srour & Abboud) charges "for a few seconds ... to allow the surface to absorb the light"
  (its section "Marking Sub-cells").
* ``l_sat_cd_m2 = 0.45``: the saturated initial luminance of a dot. This is the one constant fitted
  to an observation: with the paper's webcam (``stcvision.sim_camera.image_sensor.SensorParams`` defaults,
  exposure 1/30 s, gain 16) a dot charged for 3 s at the reference distance (0.25 m from the
  robot, a mark in its own cell) stays detectable (Rose criterion, SNR >= 5 in the paper's 3x3
  search window) for about a minute and not at two (the paper's "Limitations": "it could be seen
  by the camera we used only in the first minute or so"). The same law then gives ~3.8 mcd/m^2
  at 10 minutes, above the 0.3 mcd/m^2 perception limit DIN 67510 uses for the dark-adapted
  eye, consistent with the paper's "could be still seen by humans until after 10 minutes".
  A fresh dot (0.35 cd/m^2) is of the order of commercial pigments a minute after a short
  charge.

A dot is a small disc (``dot_diameter_m``, the spot of one UV LED) laid by a row of four rear
LEDs (the ant-like STC paper, "The Robot": "4 UV LEDs").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stcvision.errors import BadInputError

__all__ = ["AfterglowLaw", "PhosphorLayer"]


@dataclass(frozen=True, kw_only=True, slots=True)
class AfterglowLaw:
    """``L(t) = l_sat_cd_m2 * (1 - exp(-charge_s / fill_s)) * (1 + t / tau_s) ** -n``.

    See the module docstring for where each default comes from.
    """

    l_sat_cd_m2: float = 0.45
    fill_s: float = 2.0
    tau_s: float = 10.0
    n: float = 1.1

    def __post_init__(self) -> None:
        for name in ("l_sat_cd_m2", "fill_s", "tau_s", "n"):
            if not getattr(self, name) > 0:
                raise BadInputError(f"AfterglowLaw.{name} must be > 0, got {getattr(self, name)}")

    def initial_cd_m2(self, charge_s) -> np.ndarray:
        """Luminance just after a charge of ``charge_s`` seconds."""
        charge_s = np.asarray(charge_s, float)
        return self.l_sat_cd_m2 * -np.expm1(-np.maximum(charge_s, 0.0) / self.fill_s)

    def luminance_cd_m2(self, age_s, charge_s=3.0) -> np.ndarray:
        """Luminance (cd/m^2) ``age_s`` seconds after the end of a ``charge_s`` charge.

        Negative ages (the charge has not ended yet) give the luminance at the end of the part
        of the charge done so far is not modelled: they return 0.
        """
        age_s = np.asarray(age_s, float)
        lum = self.initial_cd_m2(charge_s) * (1.0 + np.maximum(age_s, 0.0) / self.tau_s) ** -self.n
        return np.where(age_s >= 0, lum, 0.0)

    def age_at_luminance_s(self, lum_cd_m2, charge_s=3.0) -> np.ndarray:
        """Inverse of :meth:`luminance_cd_m2`: the age at which a dot has dimmed to ``lum_cd_m2``."""
        l0 = self.initial_cd_m2(charge_s)
        ratio = l0 / np.asarray(lum_cd_m2, float)
        return np.where(ratio > 1, self.tau_s * (ratio ** (1.0 / self.n) - 1.0), 0.0)


class PhosphorLayer:
    """All UV dots on the floor: position (world, m), charge end time and charge duration.

    Append-only; queried vectorised. ``luminance_at(t)`` gives every dot's luminance at sim
    time ``t``. Dots whose charge has not ended by ``t`` do not glow yet.
    """

    def __init__(
        self, law: AfterglowLaw | None = None, *, dot_diameter_m: float = 0.008, rear_led_x_m: float = -0.06
    ) -> None:
        if not dot_diameter_m > 0:
            raise BadInputError(f"dot_diameter_m must be > 0, got {dot_diameter_m}")
        self.law = law or AfterglowLaw()
        self.dot_diameter_m = float(dot_diameter_m)
        self.rear_led_x_m = float(rear_led_x_m)
        self._xy = np.zeros((0, 2))
        self._t_end = np.zeros(0)
        self._charge = np.zeros(0)
        self._lit: dict[int, tuple[float, np.ndarray]] = {}

    def led_positions_m(self, pose) -> np.ndarray:
        """World positions (4, 2) under the rear UV LEDs of a robot at ``pose`` (x, y, heading):
        a row across the robot, ``rear_led_x_m`` behind its turning centre."""
        x, y, h = pose
        c, s = np.cos(h), np.sin(h)
        offs = np.asarray(LED_OFFSETS_M)
        lx = np.full(4, self.rear_led_x_m)
        return np.column_stack([x + c * lx - s * offs, y + s * lx + c * offs])

    def on_step(self, world) -> None:
        """World layer hook: a robot's LEDs switched on start charging the floor under them;
        switched off, the dots are laid with the charge time they got."""
        for robot in world.robots:
            rid = id(robot)
            if robot.leds_lit and rid not in self._lit:
                self._lit[rid] = (world.time_s, self.led_positions_m(robot.pose))
            elif not robot.leds_lit and rid in self._lit:
                t0, xy = self._lit.pop(rid)
                if world.time_s > t0:
                    self.charge(xy, t_start_s=t0, duration_s=world.time_s - t0)

    def __len__(self) -> int:
        return len(self._t_end)

    @property
    def xy_m(self) -> np.ndarray:
        return self._xy

    @property
    def charge_end_s(self) -> np.ndarray:
        return self._t_end

    @property
    def charge_s(self) -> np.ndarray:
        return self._charge

    def charge(self, xy_m, *, t_start_s: float, duration_s: float) -> None:
        """Add dots at world positions ``xy_m`` ((N, 2) m) charged from ``t_start_s`` for ``duration_s``."""
        xy = np.asarray(xy_m, float).reshape(-1, 2)
        if not duration_s > 0:
            raise BadInputError(f"charge duration must be > 0 s, got {duration_s}")
        self._xy = np.vstack([self._xy, xy])
        self._t_end = np.concatenate([self._t_end, np.full(len(xy), t_start_s + duration_s)])
        self._charge = np.concatenate([self._charge, np.full(len(xy), float(duration_s))])

    def ages_s(self, t_s: float) -> np.ndarray:
        """Age of every dot at sim time ``t_s`` (negative while still charging)."""
        return t_s - self._t_end

    def luminance_at(self, t_s: float) -> np.ndarray:
        """Luminance (cd/m^2) of every dot at sim time ``t_s``."""
        return self.law.luminance_cd_m2(self.ages_s(t_s), self._charge)

    def query(self, xy_m, t_s: float, radius_m: float | None = None) -> np.ndarray:
        """Luminance at world points ``xy_m`` ((M, 2)): the brightest dot within ``radius_m``
        (default: the dot radius) of each point, 0 where there is none."""
        pts = np.asarray(xy_m, float).reshape(-1, 2)
        r = self.dot_diameter_m / 2 if radius_m is None else radius_m
        if len(self) == 0:
            return np.zeros(len(pts))
        lum = self.luminance_at(t_s)
        d2 = ((pts[:, None, :] - self._xy[None, :, :]) ** 2).sum(-1)
        return np.where(d2 <= r * r, lum[None, :], 0.0).max(axis=1)


#: Lateral positions (m, robot y) of the four rear UV LEDs (ant-like STC paper: "4 UV LEDs"), 3 cm
#: apart.
LED_OFFSETS_M = (-0.045, -0.015, 0.015, 0.045)
#: How far inside its sub-cell a mark lies: the rear LEDs sit 6 cm behind the turning centre of
#: a robot whose footprint is the 16 cm sub-cell, so dots land 2 cm inside the rear edge
#: (docs/explanation/stc-geometry.md, "Marks and the five boxes": "a few centimetres from the edge
#: line").
MARK_INSET_M = 0.02


def mark_dots_m(centre_xy_m, edge_dir, subcell_m: float, *, inset_m: float = MARK_INSET_M) -> np.ndarray:
    """World positions (4, 2) of a mark: a row of four dots inside the sub-cell centred at
    ``centre_xy_m``, parallel to and ``inset_m`` inside its edge in unit direction ``edge_dir``."""
    c = np.asarray(centre_xy_m, float)
    n = np.asarray(edge_dir, float)
    n = n / np.linalg.norm(n)
    t = np.array([-n[1], n[0]])
    offs = np.asarray(LED_OFFSETS_M)
    return c + n * (subcell_m / 2 - inset_m) + offs[:, None] * t
