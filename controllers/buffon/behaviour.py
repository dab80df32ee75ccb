"""The Buffon explorer's exploration behaviour (the Buffon's needle paper of Girgin &
Sahin, sec. 3.2).

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
* r is kept in [-1, 1] and w_l, w_r in [0, 1] after each update. The equations are a shunting
  model (the (1 - r) and (1 + r) factors pull r towards +-1 and no further; w towards 1), whose
  continuous-time solution never leaves those bounds; one update per step is an Euler step of
  size 1, which overshoots when several sensors are saturated: with I_1..I_4 near 1 and
  w ~ 0.3, r <- -1.9 r + c, so r oscillates with growing amplitude. Measured in a triangular
  nest (corners of 53-63 degrees): r became NaN within a few hundred steps of reaching a corner
  and the robot spun there for the rest of the visit, on the pymunk path and the batched path
  alike. In the paper's round and square nests the sensors are rarely saturated for long;
  clipping changes nothing while the equations stay in bounds;
* the escape turn keeps the direction sign(w_r - w_l) it had when the escape began until the
  escape condition clears. As written, the sign is re-chosen every step; in an acute corner
  w_l ~ w_r, so it flips at random and the robot wiggles +-20 degrees facing the corner for
  ever (measured on both paths in the triangular nest above). The paper's nests have no acute
  corners; its text says the rule lets the robot escape "by making steep turns away".
* m = 1 maps to ``speed_scale_m_s`` = 0.19 m/s of wheel speed, one controller update per world
  step: with a Khepera at dt = 0.05 s this gives about 0.034 body lengths of path per step,
  matching the paper's trail of ~1680 body lengths per 50,000-step visit (sec. 4).

One source for the equations: :func:`explorer_core` is plain Python on floats. The scalar
controller :func:`explorer_step` calls it as it is; numba compiles the *same function* for the
batched twin :func:`explorer_step_batch` and for the fused Monte-Carlo loop
(:mod:`stcvision.controllers.buffon.batched`), so the two paths cannot drift apart, and the tests check
them step for step on the same readings and draws.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

__all__ = [
    "Explorer",
    "ExplorerParams",
    "ExplorerState",
    "explorer_core",
    "explorer_step",
    "explorer_step_batch",
    "wheel_speeds",
]


@dataclass(frozen=True, kw_only=True, slots=True)
class ExplorerParams:
    """Constants of sec. 3.2 (``gamma``, ``speed_scale_m_s``: assumptions, see module doc)."""

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
    escape: float = 0.0  # direction of the escape turn in progress (+1 left, -1 right), 0 if none


def explorer_core(r, wl, wr, esc, i0, i1, i2, i3, i4, i5, n, nbar, gamma, front_thr, side_thr):
    """Sec. 3.2 on plain floats: returns (r, w_l, w_r, esc, rbar) after one update with the draws
    ``n`` ~ U(-0.4, 0.4) and ``nbar`` ~ U(0.3, 1); ``esc`` is the escape turn's direction (+1,
    -1) while an escape lasts, 0 otherwise."""
    dr = -0.9 * r + 0.3 * (1 - r) * (wl + 1.5 * i4 + 1.2 * i3) - 0.3 * (1 + r) * (wr + 1.5 * i1 + 1.2 * i2)
    dwl = -0.1 * wl + gamma * (1 - wl) * i1 - 0.7 * wl * (i2 + i3)
    dwr = -0.1 * wr + gamma * (1 - wr) * i4 - 0.7 * wr * (i2 + i3)
    # shunting bounds (see the module doc): r in [-1, 1], w in [0, 1]
    r = min(1.0, max(-1.0, r + dr))
    wl = min(1.0, max(0.0, wl + dwl))
    wr = min(1.0, max(0.0, wr + dwr))
    if i1 + i2 + i3 + i4 > front_thr or i0 > side_thr or i5 > side_thr:
        if esc == 0.0:  # the paper's direction, chosen when the escape begins, kept until it ends
            esc = 1.0 if wr - wl >= 0 else -1.0
        rbar = esc * nbar
    else:
        esc = 0.0
        rbar = min(1.0, max(-1.0, r + n))
    return r, wl, wr, esc, rbar


def wheel_speeds(rbar, speed_scale_m_s):
    """(m_l, m_r) of sec. 3.2 in m/s."""
    base = (1 - abs(rbar)) * 0.25
    return (base - rbar) * speed_scale_m_s, (base + rbar) * speed_scale_m_s


explorer_core_nb = numba.njit(cache=True)(explorer_core)
wheel_speeds_nb = numba.njit(cache=True)(wheel_speeds)


def draws_from_uniforms(u0, u1, params: ExplorerParams):
    """(n, nbar) from two U(0, 1) draws, as ``Generator.uniform(a, b)`` = a + (b - a) u does."""
    n = -params.noise + 2 * params.noise * u0
    nbar = params.escape_min + (params.escape_max - params.escape_min) * u1
    return n, nbar


def explorer_step(
    state: ExplorerState, ir, rng: np.random.Generator, params: ExplorerParams = ExplorerParams()
) -> tuple[ExplorerState, tuple[float, float]]:
    """One update. ``ir`` : (6,) readings in [0, 1]. Returns the new state and the wheel
    speeds (left, right) in m/s. Draws n, then nbar, from ``rng``."""
    i0, i1, i2, i3, i4, i5 = (float(v) for v in ir)
    n = rng.uniform(-params.noise, params.noise)
    nbar = rng.uniform(params.escape_min, params.escape_max)
    r, wl, wr, esc, rbar = explorer_core(
        state.r,
        state.w_l,
        state.w_r,
        state.escape,
        i0,
        i1,
        i2,
        i3,
        i4,
        i5,
        n,
        nbar,
        params.gamma,
        params.front_sum_threshold,
        params.side_threshold,
    )
    return ExplorerState(r, wl, wr, rbar, esc), wheel_speeds(rbar, params.speed_scale_m_s)


@numba.njit(cache=True)
def _step_batch(r, wl, wr, esc, ir, n, nbar, gamma, front_thr, side_thr, k):
    m = r.shape[0]
    rbar = np.empty(m)
    ml = np.empty(m)
    mr = np.empty(m)
    ro, wlo, wro, eo = np.empty(m), np.empty(m), np.empty(m), np.empty(m)
    for j in range(m):
        ro[j], wlo[j], wro[j], eo[j], rbar[j] = explorer_core_nb(
            r[j],
            wl[j],
            wr[j],
            esc[j],
            ir[j, 0],
            ir[j, 1],
            ir[j, 2],
            ir[j, 3],
            ir[j, 4],
            ir[j, 5],
            n[j],
            nbar[j],
            gamma,
            front_thr,
            side_thr,
        )
        ml[j], mr[j] = wheel_speeds_nb(rbar[j], k)
    return ro, wlo, wro, eo, rbar, ml, mr


def explorer_step_batch(r, w_l, w_r, escape, ir, n, nbar, params: ExplorerParams = ExplorerParams()):
    """The batched twin: N robots at once, on given draws.

    r, w_l, w_r, escape, n, nbar : (N,) float; ir : (N, 6) readings. Returns new (r, w_l, w_r,
    escape), rbar and the wheel speeds (m_l, m_r) in m/s, each (N,). Inputs are not modified.
    """
    f = np.ascontiguousarray
    return _step_batch(
        f(r, dtype=float),
        f(w_l, dtype=float),
        f(w_r, dtype=float),
        f(escape, dtype=float),
        f(ir, dtype=float),
        f(n, dtype=float),
        f(nbar, dtype=float),
        params.gamma,
        params.front_sum_threshold,
        params.side_threshold,
        params.speed_scale_m_s,
    )


class Explorer:
    """Drives a pymunk sim robot with the exploration behaviour; call it once per world step."""

    def __init__(self, robot, rng: np.random.Generator, params: ExplorerParams = ExplorerParams()):
        self.robot, self.rng, self.params = robot, rng, params
        self.state = ExplorerState()

    def __call__(self, world=None) -> None:
        ir = self.robot.sensors.ir.read()
        self.state, (ml, mr) = explorer_step(self.state, ir, self.rng, self.params)
        self.robot.set_wheel_speeds(ml, mr)
