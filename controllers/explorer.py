"""The Buffon explorer's exploration behaviour (seed ``000_65e7c97ffd15e972.txt``, sec. 3.2).

A Braitenberg-style behaviour with noise and short-term memory, from six front IR readings
I_0..I_5 in [0, 1] (0 = left side ... 5 = right side, Khepera order):

    m_l = (1 - |rbar|) 0.25 - rbar,      m_r = (1 - |rbar|) 0.25 + rbar

    rbar = sign(w_r - w_l) * nbar    if sum(I_1..I_4) > 2.7 or I_0 > 0.95 or I_5 > 0.95
         = clip(r + n, -1, 1)        otherwise

    dr   = -0.9 r + 0.3 (1 - r)(w_l + 1.5 I_4 + 1.2 I_3) - 0.3 (1 + r)(w_r + 1.5 I_1 + 1.2 I_2)
    dw_l = -0.1 w_l + gamma (1 - w_l) I_1 - 0.7 w_l (I_2 + I_3)
    dw_r = -0.1 w_r + gamma (1 - w_r) I_4 - 0.7 w_r (I_2 + I_3)

with n ~ U(-0.4, 0.4) and nbar ~ U(0.3, 1.0) drawn every step. rbar = +1 turns left.

Choices the paper leaves open (documented assumptions):

* ``gamma`` (the paper only says it "controls the perceived presence of the wall"): 0.5;
* sign(0) in the escape rule: taken as +1 (turn left), so the escape never drives straight on;
* the activations update first, and rbar uses the updated r;
* m = 1 maps to ``speed_scale_m_s`` = 0.19 m/s of wheel speed, one controller update per world
  step: with a Khepera at dt = 0.05 s this gives about 0.034 body lengths of path per step,
  matching the paper's trail of ~1680 body lengths per 50,000-step visit (sec. 4); measured
  0.027 at 0.15 m/s in a 1.1 m circular arena, scaled up accordingly.

The controller is a pure function :func:`explorer_step` (state, readings, rng) -> (state,
wheel speeds); :class:`Explorer` wraps it for a sim robot.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Explorer", "ExplorerParams", "ExplorerState", "explorer_step"]


@dataclass(frozen=True, kw_only=True, slots=True)
class ExplorerParams:
    gamma: float = 0.5
    speed_scale_m_s: float = 0.19
    noise: float = 0.4  # n ~ U(-noise, noise)
    escape_min: float = 0.3  # nbar ~ U(escape_min, escape_max)
    escape_max: float = 1.0
    front_sum_threshold: float = 2.7
    side_threshold: float = 0.95


@dataclass(frozen=True, slots=True)
class ExplorerState:
    r: float = 0.0  # rotational activation
    w_l: float = 0.0  # perceived presence of a wall on the left
    w_r: float = 0.0  # ... on the right
    rbar: float = 0.0  # last output activation (for logging)


def explorer_step(
    state: ExplorerState, ir, rng: np.random.Generator, params: ExplorerParams = ExplorerParams()
) -> tuple[ExplorerState, tuple[float, float]]:
    """One update. ``ir`` : (6,) readings in [0, 1]. Returns the new state and the wheel
    speeds (left, right) in m/s."""
    i0, i1, i2, i3, i4, i5 = (float(v) for v in ir)
    r, wl, wr = state.r, state.w_l, state.w_r
    dr = -0.9 * r + 0.3 * (1 - r) * (wl + 1.5 * i4 + 1.2 * i3) - 0.3 * (1 + r) * (wr + 1.5 * i1 + 1.2 * i2)
    g = params.gamma
    dwl = -0.1 * wl + g * (1 - wl) * i1 - 0.7 * wl * (i2 + i3)
    dwr = -0.1 * wr + g * (1 - wr) * i4 - 0.7 * wr * (i2 + i3)
    r, wl, wr = r + dr, wl + dwl, wr + dwr
    n = rng.uniform(-params.noise, params.noise)
    nbar = rng.uniform(params.escape_min, params.escape_max)
    if i1 + i2 + i3 + i4 > params.front_sum_threshold or i0 > params.side_threshold or i5 > params.side_threshold:
        rbar = (1.0 if wr - wl >= 0 else -1.0) * nbar
    else:
        rbar = min(1.0, max(-1.0, r + n))
    base = (1 - abs(rbar)) * 0.25
    k = params.speed_scale_m_s
    return ExplorerState(r, wl, wr, rbar), ((base - rbar) * k, (base + rbar) * k)


class Explorer:
    """Drives a sim robot with the exploration behaviour; call it once per world step."""

    def __init__(self, robot, rng: np.random.Generator, params: ExplorerParams = ExplorerParams()):
        self.robot, self.rng, self.params = robot, rng, params
        self.state = ExplorerState()

    def __call__(self, world=None) -> None:
        ir = self.robot.sensors.ir.read()
        self.state, (ml, mr) = explorer_step(self.state, ir, self.rng, self.params)
        self.robot.set_wheel_speeds(ml, mr)
