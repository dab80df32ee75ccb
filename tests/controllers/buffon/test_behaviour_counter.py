"""Sec. 3.2 behaviour (scalar vs hand-computed, scalar vs batched) and the sec. 4 counter."""

import math

import numpy as np
import pytest

from stcvision.controllers.buffon.behaviour import (
    ExplorerParams,
    ExplorerState,
    explorer_core,
    explorer_step,
    explorer_step_batch,
)
from stcvision.controllers.buffon.counter import CounterParams, LeakyIntegrator, count_crossings
from stcvision.sim_camera.fastworld import deposit_segment, read_cell


class _Fixed:
    """A stand-in Generator returning given uniforms (maps U(a, b) exactly as numpy does)."""

    def __init__(self, *u):
        self.u = list(u)

    def uniform(self, a, b):
        return a + (b - a) * self.u.pop(0)


def test_one_update_against_hand_computed_values():
    # r = 0.2, w_l = 0.1, w_r = 0.3; I = (0, 0.5, 0.2, 0.1, 0.4, 0); n draw 0.75 -> n = 0.2
    s = ExplorerState(0.2, 0.1, 0.3)
    ir = [0.0, 0.5, 0.2, 0.1, 0.4, 0.0]
    new, (ml, mr) = explorer_step(s, ir, _Fixed(0.75, 0.5), ExplorerParams())
    # dr = -0.18 + 0.3*0.8*(0.1+0.6+0.12) - 0.3*1.2*(0.3+0.75+0.24) = -0.18 + 0.1968 - 0.4644
    assert new.r == pytest.approx(0.2 - 0.4476)
    # dw_l = -0.01 + 0.5*0.9*0.5 - 0.7*0.1*0.3 = 0.194 ; dw_r = -0.03 + 0.5*0.7*0.4 - 0.7*0.3*0.3 = 0.047
    assert new.w_l == pytest.approx(0.1 + 0.194)
    assert new.w_r == pytest.approx(0.3 + 0.047)
    rbar = (0.2 - 0.4476) + 0.2  # no escape: sum(I1..I4) = 1.2 <= 2.7
    assert new.rbar == pytest.approx(rbar)
    base = (1 - abs(rbar)) * 0.25
    assert ml == pytest.approx((base - rbar) * 0.19) and mr == pytest.approx((base + rbar) * 0.19)


def test_escape_rule_turns_away_by_nbar():
    # I_0 > 0.95: rbar = sign(w_r - w_l) * nbar, nbar draw 0.5 -> 0.65
    s = ExplorerState(0.0, 0.6, 0.1)
    new, _ = explorer_step(s, [0.99, 0, 0, 0, 0, 0], _Fixed(0.5, 0.5))
    assert new.rbar == pytest.approx(-0.65)
    assert new.w_l > new.w_r  # the left wall is still perceived
    new, _ = explorer_step(ExplorerState(), [0, 0.8, 0.8, 0.8, 0.8, 0], _Fixed(0.5, 0.0))
    assert new.rbar == pytest.approx(0.3)  # sign(0) taken as +1 (documented)
    # the escape keeps its direction while it lasts, whatever w_r - w_l does meanwhile ...
    s = ExplorerState(0.0, 0.1, 0.6, escape=-1.0)
    new, _ = explorer_step(s, [0.99, 0, 0, 0, 0, 0], _Fixed(0.5, 1.0))
    assert new.rbar == pytest.approx(-1.0) and new.escape == -1.0
    # ... and ends with it
    new, _ = explorer_step(new, [0, 0, 0, 0, 0, 0], _Fixed(0.5, 1.0))
    assert new.escape == 0.0


def test_activations_stay_within_the_shunting_bounds():
    """Saturated sensors (an acute corner) for 500 steps: r in [-1, 1], w in [0, 1], no NaN
    (the unclipped Euler step diverges: r <- -1.9 r + c)."""
    rng = np.random.default_rng(0)
    s = ExplorerState()
    for _ in range(500):
        s, (ml, mr) = explorer_step(s, rng.uniform(0.9, 1.0, 6), rng)
        assert -1 <= s.r <= 1 and 0 <= s.w_l <= 1 and 0 <= s.w_r <= 1 and np.isfinite([ml, mr]).all()


def test_clipping_of_r_plus_n():
    new, (ml, mr) = explorer_step(ExplorerState(r=20.0), [0] * 6, _Fixed(1.0, 0.5))  # r' = 0.1 r = 2, clipped to 1
    assert new.rbar == 1.0 and ml == pytest.approx(-0.19) and mr == pytest.approx(0.19)


def test_scalar_and_batched_twin_agree_step_for_step():
    rng = np.random.default_rng(3)
    n_robots, steps = 64, 200
    p = ExplorerParams()
    r, wl, wr, esc = np.zeros(n_robots), np.zeros(n_robots), np.zeros(n_robots), np.zeros(n_robots)
    states = [ExplorerState() for _ in range(n_robots)]
    for _ in range(steps):
        ir = np.clip(rng.normal(0.2, 0.4, (n_robots, 6)), 0, 1)
        u = rng.random((n_robots, 2))
        n = -p.noise + 2 * p.noise * u[:, 0]
        nbar = p.escape_min + (p.escape_max - p.escape_min) * u[:, 1]
        r, wl, wr, esc, rbar, ml, mr = explorer_step_batch(r, wl, wr, esc, ir, n, nbar, p)
        for j in range(n_robots):
            states[j], (sl, sr) = explorer_step(states[j], ir[j], _Fixed(*u[j]), p)
            s = states[j]
            assert (s.r, s.w_l, s.w_r, s.escape, s.rbar) == (r[j], wl[j], wr[j], esc[j], rbar[j])
            assert (sl, sr) == (ml[j], mr[j])
    assert np.abs(rbar).max() > 0.5  # the escape and clipping branches were exercised


def test_core_is_the_same_function_compiled():
    args = (0.1, 0.2, 0.3, 0.0, 0.9, 0.5, 0.6, 0.7, 0.4, 0.2, 0.05, 0.8, 0.5, 2.7, 0.95)
    from stcvision.controllers.buffon.behaviour import explorer_core_nb

    assert explorer_core_nb(*args) == explorer_core(*args)


# ------------------------------------------------------------------ counter on synthetic trails
CELL = 0.00275  # w / 2, as the batched path and PheromoneLayer
HALF = 0.00275  # trail width 5.5 mm (0.1 body length)


def _raster(segments, size=1.0):
    n = int(size / CELL) + 1
    g = np.zeros((n, n), np.uint8)
    for (x0, y0), (x1, y1) in segments:
        deposit_segment(g, 0.0, 0.0, CELL, HALF, x0, y0, x1, y1)
    return g


def _probe(g, start, end, step=0.0024):
    """Readings along a straight probe path at the explorer's top speed (2.4 mm per step)."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    n = int(np.linalg.norm(end - start) / step)
    pts = start + np.outer(np.arange(n + 1) / n, end - start)
    return [read_cell(g, 0.0, 0.0, CELL, x, y) for x, y in pts]


@pytest.mark.parametrize("angle_deg", [90, 60, 30, 10])
def test_counter_counts_each_trail_crossing_once(angle_deg):
    """Five parallel trails 10 cm apart crossed by one straight path at 90..10 degrees."""
    g = _raster([((0.05, y), (3.15, y)) for y in (0.3, 0.4, 0.5, 0.6, 0.7)], size=3.2)
    a = math.radians(angle_deg)
    d = 0.5 / math.sin(a)  # runs from y = 0.25 to 0.75
    start = (1.6 - 0.5 * d * math.cos(a), 0.25)
    end = (1.6 + 0.5 * d * math.cos(a), 0.75)
    assert count_crossings(_probe(g, start, end)) == 5


def test_counter_path_along_the_trail_counts_one():
    g = _raster([((0.1, 0.5), (0.9, 0.5))])
    readings = _probe(g, (0.05, 0.5), (0.95, 0.5)) + _probe(g, (0.95, 0.5), (0.95, 0.6))
    assert count_crossings(readings) == 1
    # ... and weaving along it within the trail's half width still counts one
    path = [(x, 0.5 + 0.0015 * math.sin(40 * x)) for x in np.arange(0.05, 0.95, 0.0024)]
    assert count_crossings([read_cell(g, 0, 0, CELL, x, y) for x, y in path]) == 1


def test_counter_ignores_one_step_blips_and_needs_re_arming():
    seq = [0] * 10 + [1] + [0] * 10 + [1] * 5 + [0] * 20 + [1] * 4 + [0] * 10
    li = LeakyIntegrator()
    hits = [li.update(x) for x in seq]
    assert li.crossings == 2 and sum(hits) == 2
    # two trails one step apart merge (the counter is blind in between): one crossing
    assert count_crossings([0, 1, 1, 0, 1, 1, 0, 0, 0, 0]) == 1
    assert count_crossings([0, 1, 1, 0, 0, 0, 0, 1, 1, 0]) == 2
    assert count_crossings([1] * 3, CounterParams(threshold=0.9)) == 0
