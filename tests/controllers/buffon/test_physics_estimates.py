"""The batched path's physics against pymunk, containment, determinism, and the area formula."""

import math

import numpy as np
import pytest
from scipy import stats

from stcvision.controllers.buffon.batched import VisitConfig, run_trials
from stcvision.controllers.buffon.estimate import area_estimates, buffon_area, median_ci95, summarise
from stcvision.controllers.buffon.nests import BODY_LENGTH_M, parse_nest
from stcvision.sim_camera.fastworld import StaticGeometry, push_out, ray_fan
from stcvision.sim_camera.robot import KHEPERA
from stcvision.sim_camera.world import World


def _plus_nest():
    return parse_nest("circle:20", "plus:0.5")


def test_ray_casts_match_pymunk_segment_queries():
    """Random rays in a circle with a + barrier: the capsule model's distances are pymunk's."""
    nest = _plus_nest()
    world = World(nest.arena, seed=0)
    geo = StaticGeometry.from_arena(nest.arena, reach_m=0.25)
    rng = np.random.default_rng(1)
    pts = nest.arena.sample_free_points(400, rng, margin_m=0.03)
    checked = 0
    for (x, y), a in zip(pts, rng.uniform(-np.pi, np.pi, len(pts)), strict=True):
        c, s = math.cos(a), math.sin(a)
        ref = world.ray_distance((x, y), (x + 0.2 * c, y + 0.2 * s))
        rays = np.array([[x], [y], [c], [s], [0.0]])
        ray_fan(*geo.arrays, x, y, rays, 0.2)
        got = rays[4, 0]
        if ref is None:
            assert got == np.inf
        else:
            checked += 1
            assert got == pytest.approx(ref, abs=2e-4)  # pymunk's outer walls: inscribed-polygon faces
    assert checked > 100


def test_push_out_slides_without_tunnelling_through_a_thin_barrier():
    """Drive a disc into the 10 mm barrier at 5x the explorer's top speed: it stops at the face."""
    nest = parse_nest("square:20", "bar:0.5")
    geo = StaticGeometry.from_arena(nest.arena, reach_m=0.1)
    cx, cy = nest.arena.center_m
    r = KHEPERA.radius_m
    x, y = cx - 0.1, cy
    for _ in range(200):
        x, y, touched = push_out(*geo.arrays, x + 0.012, y + 0.0005, r)
    assert x == pytest.approx(cx - r - 0.005, abs=1e-9)  # face of the capsule (half thickness 5 mm)
    assert touched and y > cy + 0.05  # slid along the barrier


@pytest.mark.parametrize(
    "spec,barrier", [("circle:10", None), ("square:20", "plus:0.8"), ("ellipse:300:6", None), ("circle:30", "bar:0.9")]
)
def test_containment_every_step(spec, barrier):
    nest = parse_nest(spec, barrier)
    ts = run_trials(nest, VisitConfig(visit_steps=6000), trials=3, seed=4, record_trial=1)
    assert ts.escapes == 0
    for v in ts.trails.values():
        clear = nest.arena.clearance_m(v[:, :2])
        assert clear.min() > KHEPERA.radius_m - 1e-6  # never inside a wall or barrier


def test_containment_in_a_non_convex_polygon(tmp_path):
    import json

    poly = tmp_path / "L.json"
    poly.write_text(json.dumps([[0, 0], [30, 0], [30, 10], [10, 10], [10, 30], [0, 30]]))
    nest = parse_nest(f"polygon:{poly}")
    ts = run_trials(nest, VisitConfig(visit_steps=8000), trials=2, seed=1, record_trial=0)
    assert ts.escapes == 0
    assert nest.arena.clearance_m(ts.trails["visit1"][:, :2]).min() > KHEPERA.radius_m - 1e-6
    assert nest.area_u2 == pytest.approx(500.0)


def test_determinism_whatever_the_batch():
    nest = parse_nest("circle:20")
    cfg = VisitConfig(visit_steps=3000)
    a = run_trials(nest, cfg, trials=6, seed=11)
    b = run_trials(nest, cfg, trials=6, seed=11, record_trial=2, threads=3)  # neither changes anything
    c = run_trials(nest, cfg, trials=3, seed=11)
    d = run_trials(nest, cfg, trials=6, seed=12)
    assert np.array_equal(a.crossings, b.crossings) and np.array_equal(a.l1_u, b.l1_u)
    assert np.array_equal(a.crossings[:3], c.crossings) and np.array_equal(a.l2_u[:3], c.l2_u)
    assert not np.array_equal(a.crossings, d.crossings)


def test_path_length_per_step_matches_the_paper():
    """Sec. 4: a 50,000-step visit lays ~1680 body lengths; 2,000 steps in the open: ~0.034 u/step."""
    ts = run_trials(parse_nest("circle:100"), VisitConfig(visit_steps=2000), trials=4, seed=0)
    per_step = ts.l1_u / 2000
    assert per_step == pytest.approx(np.full(4, 1680 / 50000), rel=0.08)


def test_buffon_area_formula_on_random_needles_in_a_torus():
    """Random segments in a 1 x 2 torus: E[N] = 2 L1 L2 / (pi A), so the estimate hits A."""
    rng = np.random.default_rng(0)
    w, h, ell = 1.0, 2.0, 0.05

    def needles(n):
        p = rng.random((n, 2)) * (w, h)
        a = rng.uniform(0, np.pi, n)
        return p, p + ell * np.c_[np.cos(a), np.sin(a)]

    a1, b1 = needles(4000)
    a2, b2 = needles(4000)
    n = 0
    for dx in (-w, 0, w):  # periodic images: the torus
        for dy in (-h, 0, h):
            n += _count_intersections(a1 + (dx, dy), b1 + (dx, dy), a2, b2)
    est = buffon_area(4000 * ell, 4000 * ell, n)
    expected_n = 2 * (4000 * ell) ** 2 / (math.pi * w * h)
    assert n == pytest.approx(expected_n, rel=4 / math.sqrt(expected_n))  # 4 sigma, Poisson
    assert est == pytest.approx(w * h, rel=0.06)
    assert buffon_area(1.0, 1.0, 0) == np.inf


def _count_intersections(a1, b1, a2, b2) -> int:
    d1 = b1 - a1
    d2 = b2 - a2
    total = 0
    for k in range(0, len(a1), 500):
        p, r = a1[k : k + 500, None], d1[k : k + 500, None]
        q, s = a2[None], d2[None]
        den = r[..., 0] * s[..., 1] - r[..., 1] * s[..., 0]
        qp = q - p
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (qp[..., 0] * s[..., 1] - qp[..., 1] * s[..., 0]) / den
            u = (qp[..., 0] * r[..., 1] - qp[..., 1] * r[..., 0]) / den
        total += int(((t >= 0) & (t <= 1) & (u >= 0) & (u <= 1)).sum())
    return total


def test_summary_keys_interval_and_corrections():
    nest = parse_nest("circle:30")
    ts = run_trials(nest, VisitConfig(visit_steps=20000), trials=12, seed=3)
    s = summarise(ts, nest.area_u2)
    assert s["nbc_q1"] <= s["nbc_median"] <= s["nbc_q3"]
    lo, hi = s["area_ci95"]
    assert lo <= s["area_estimate_median"] <= hi
    raw = area_estimates(ts, dead_time=False, correction=1.0)
    np.testing.assert_allclose(area_estimates(ts, correction=1.0), raw * (1 - ts.blind_fraction))
    assert 0 < ts.blind_fraction.min() and ts.blind_fraction.max() < 1
    assert s["nbc_median"] == pytest.approx(np.median(ts.crossings / ts.l2_u))
    assert median_ci95([1.0, 2.0]) is None


@pytest.mark.slow
def test_batched_path_is_a_model_of_the_pymunk_path():
    """Small version of `stcvision buffon compare`: nBC of 10 pymunk trials vs 120 batched trials
    in a 20 u circle, 1,500-step visits, are not told apart (Mann-Whitney, 1 %), and lengths agree."""
    from stcvision.controllers.buffon.pymunk_path import run_trials_pymunk

    nest = parse_nest("circle:20")
    cfg = VisitConfig(visit_steps=1500)
    p = run_trials_pymunk(nest, cfg, trials=10, seed=21)
    b = run_trials(nest, cfg, trials=120, seed=22)
    assert p.escapes == 0 and b.escapes == 0
    assert stats.mannwhitneyu(p.nbc, b.nbc).pvalue > 0.01
    assert np.median(p.l1_u) == pytest.approx(np.median(b.l1_u), rel=0.05)
    assert BODY_LENGTH_M == 0.055


def test_self_crossing_area_on_random_needles_in_a_torus():
    """Poincare's formula for one curve: n random needles of total length L in a torus of area A
    meet each other L^2 / (pi A) times on average (each pair once), so the self-crossing estimate
    hits A."""
    from stcvision.controllers.buffon.estimate import self_crossing_area

    rng = np.random.default_rng(1)
    w, h, ell, n = 1.0, 2.0, 0.05, 2000
    p = rng.random((n, 2)) * (w, h)
    a = rng.uniform(0, np.pi, n)
    q = p + ell * np.c_[np.cos(a), np.sin(a)]
    pairs = 0
    for dx in (-w, 0, w):
        for dy in (-h, 0, h):
            pairs += _count_intersections(p + (dx, dy), q + (dx, dy), p, q)
    pairs //= 2  # every pair counted from both of its needles
    expected = (n * ell) ** 2 / (math.pi * w * h)
    assert pairs == pytest.approx(expected, rel=4 / math.sqrt(expected))  # 4 sigma, Poisson
    assert self_crossing_area(n * ell, pairs) == pytest.approx(w * h, rel=0.1)  # 4 sigma of ~1,600 pairs
    assert self_crossing_area(1.0, 0) == np.inf


def test_online_estimate_is_the_weighted_geometric_mean_of_the_two_visits():
    """Both visits' dead-time corrected estimates, in the stated weights."""
    from stcvision.controllers.buffon.estimate import (
        COVERAGE_SLOPE,
        ONLINE_SECOND_WEIGHT,
        REFERENCE_COVERAGE,
        online_area,
        self_crossing_area,
    )

    l1, l2, n, b, ns = np.array([900.0]), np.array([500.0]), np.array([60]), np.array([0.25]), np.array([458])
    b1 = np.array([0.15])
    a2 = buffon_area(l1, l2, n) * (1 - b)
    a1 = self_crossing_area(l1, ns) * (1 - b1)
    mean = np.exp(ONLINE_SECOND_WEIGHT * np.log(a2) + (1 - ONLINE_SECOND_WEIGHT) * np.log(a1))
    rho = math.pi * 0.1 * ns / l1  # the first visit's reading coverage, trail 0.1 u (rule (1))
    expected = mean * np.exp(-COVERAGE_SLOPE * (rho - REFERENCE_COVERAGE))
    np.testing.assert_allclose(online_area(l1, l2, n, b, ns, b1), expected)
    np.testing.assert_allclose(online_area(l1, l2, n, b, ns, b1, slope=0.0), mean)
    assert 0 < ONLINE_SECOND_WEIGHT < 1


def test_online_estimate_is_brought_back_to_the_reference_coverage():
    """Two trials with the same two raw estimates, read at the reference coverage and 0.05 above
    it: the first is left as it is, the second divided by exp(0.05 kappa); a wider trail reads
    the same count at a higher coverage."""
    from stcvision.controllers.buffon.estimate import COVERAGE_SLOPE, REFERENCE_COVERAGE, online_area, reading_coverage

    l1 = np.array([2000.0, 2000.0])
    ns = np.array([REFERENCE_COVERAGE, REFERENCE_COVERAGE + 0.05]) * l1 / (math.pi * 0.1)
    np.testing.assert_allclose(reading_coverage(l1, ns), [REFERENCE_COVERAGE, REFERENCE_COVERAGE + 0.05])
    np.testing.assert_allclose(reading_coverage(l1, ns, 0.2), 2 * reading_coverage(l1, ns))
    # the same raw estimates: crossings and self-encounters scaled so that both A1 and A2 agree
    a = online_area(l1, 0.5 * l1, np.array([300.0, 300.0]), 0.2, ns, 0.15)
    raw = online_area(l1, 0.5 * l1, np.array([300.0, 300.0]), 0.2, ns, 0.15, slope=0.0)
    np.testing.assert_allclose(a / raw, [1.0, math.exp(-0.05 * COVERAGE_SLOPE)])
