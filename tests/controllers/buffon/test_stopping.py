"""The online stopping rule on synthetic streams with a known rate, and the online path's
estimates, intervals and determinism on a few small nests."""

import math

import numpy as np
import pytest

from stcvision.controllers.buffon.batched import VisitConfig, run_trials
from stcvision.controllers.buffon.estimate import summarise, trial_intervals
from stcvision.controllers.buffon.nests import parse_nest
from stcvision.controllers.buffon.stopping import (
    StopParams,
    batch_add,
    batch_rel_se,
    first_visit_done,
    mixing_spread,
    new_batch_state,
    second_visit_done,
)

P = StopParams()


def _second_visit(rng, rate_per_u, dl_u=0.1, l1_u=1000.0, modulation=None, max_steps=400_000):
    """Feed a crossing stream (Bernoulli per step, ``rate_per_u`` per body length, optionally
    modulated by a slowly varying factor) through the rule until it stops: (N, L, rel_se)."""
    st = new_batch_state(P.batches)
    n, path = 0, 0.0
    for s in range(max_steps):
        lam = rate_per_u * (modulation(s) if modulation else 1.0)
        crossed = float(rng.random() < lam * dl_u)
        batch_add(st, crossed, dl_u, P.batches)
        n += int(crossed)
        path += dl_u
        if (s & 63) == 63 and second_visit_done(
            st, path, n, l1_u, P.second_ratio, P.min_crossings, P.rel_se, P.batches, P.max_ratio
        ):
            return n, path, batch_rel_se(st, P.batches)
    raise AssertionError("the rule never stopped")


def test_second_visit_stops_with_the_rate_known_to_its_stated_error():
    rng = np.random.default_rng(1)
    rate = 0.7
    runs = [_second_visit(rng, rate) for _ in range(120)]
    n = np.array([r[0] for r in runs])
    est = np.array([r[0] / r[1] for r in runs])
    se = np.array([r[2] for r in runs])
    # a Poisson stream's relative error is 1/sqrt(N): the rule stops near N = 1/rel_se^2 = 400
    assert 300 <= np.median(n) <= 600
    assert np.all(se <= P.rel_se)
    assert abs(np.median(est) / rate - 1) < 0.01
    # the batch-means error is honest: +-1.96 se holds the true rate ~95 % of the time
    holds = np.abs(est / rate - 1) <= 1.96 * se
    assert holds.mean() >= 0.88
    assert np.std(est / rate) == pytest.approx(np.median(se), rel=0.3)


def test_a_correlated_stream_runs_longer_and_its_error_stays_honest():
    rng = np.random.default_rng(2)
    rate = 0.7
    # the rate triples over stretches of 2,000 steps (a path lingering in dense trail)
    mod = lambda s: 1.5 if (s // 2000) % 2 == 0 else 0.5  # noqa: E731
    runs = [_second_visit(rng, rate, l1_u=1000.0, modulation=mod) for _ in range(60)]
    n = np.array([r[0] for r in runs])
    est = np.array([r[0] / r[1] for r in runs])
    se = np.array([r[2] for r in runs])
    assert np.median(n) > 600  # more crossings needed than a Poisson stream's 400
    holds = np.abs(est / rate - 1) <= 1.96 * se + 0.25 / np.sqrt(n)  # the modulation's phase at the stop
    assert holds.mean() >= 0.85


def test_second_visit_needs_its_share_of_the_first_visit_and_stops_at_its_ceiling():
    rng = np.random.default_rng(3)
    n, path, _ = _second_visit(rng, 2.0, l1_u=2000.0)
    assert path >= P.second_ratio * 2000.0 and n > 1000
    # a stream too sparse to reach its error stops at max_ratio * L1
    n, path, se = _second_visit(rng, 0.05, l1_u=300.0)
    assert path == pytest.approx(P.max_ratio * 300.0, rel=0.05) and se > P.rel_se


W_U = 0.1  # the trail width of the synthetic first visits


def _first_visit(rng, area, *, compartments=1, dwell_u=0.0, dl=0.5, local=0.0, rule=P):
    """Feed a first visit's self-encounter stream through the rule until it stops: (path, n,
    spread (1b) at the stop). A uniform curve meets its trail laid so far, T, at 2 T / (pi A)
    per unit path, plus ``local`` per unit path (its own recent loops). With ``compartments``
    > 1 the nest is that many equal parts and the robot stays in one for a path drawn from an
    exponential of mean ``dwell_u`` before it moves to another: it meets only the trail of the
    part it is in, 2 T_c / (pi A / compartments)."""
    st = new_batch_state(rule.batches)
    laid = np.zeros(compartments)
    part, left = 0, rng.exponential(dwell_u) if compartments > 1 else math.inf
    n, path = 0, 0.0
    pi_w = math.pi * W_U
    while True:
        rate = 2 * laid[part] * compartments / (math.pi * area) + local
        hit = int(rng.poisson(rate * dl))
        batch_add(st, float(hit), dl, rule.batches)
        n += hit
        path += dl
        laid[part] += dl
        left -= dl
        if left <= 0:
            part = (part + 1 + int(rng.integers(compartments - 1))) % compartments
            left = rng.exponential(dwell_u)
        if first_visit_done(path, n, rule.coverage, rule.min_self, pi_w, st, rule.batches, rule.mix_tol,
                            rule.max_coverage):  # fmt: skip
            return path, n, mixing_spread(st, rule.batches)


@pytest.mark.parametrize("area", [300.0, 8000.0, 120_000.0])
def test_first_visit_stops_at_the_target_coverage(area):
    """Self-encounters of a uniform curve come at rate 2 L / (pi A) per unit length: the rule
    must stop where w L / A reaches the coverage (a mixed stream passes the test (1b))."""
    rng = np.random.default_rng(4)
    # steps of a tenth of the target path / 1,000 at most: the test (1b) needs ``batches`` full
    # bins of 64 steps (a real first visit, ~0.04 u a step, has them after ~40 u of path)
    dl = min(2.0, P.coverage * area / W_U / 1000)
    path, n, _ = _first_visit(rng, area, dl=dl)
    assert W_U * path / area == pytest.approx(P.coverage, rel=0.25 if area < 1000 else 0.08)


def test_mixing_spread_of_a_steady_stream_is_counting_noise_as_scipy_says():
    """A mixed stream (Poisson about a rate a + b l, the local loops included) is called
    unmixed only when its X^2 beats chi-square(m - 2) by tol^2 N: the rate at which that
    happens is scipy's chi-square tail, and small."""
    from scipy import stats

    rng = np.random.default_rng(6)
    area, dl, local = 2000.0, 0.5, 0.05
    path_stop = P.coverage * area / W_U
    spreads, tails = [], []
    for _ in range(200):
        st = new_batch_state(P.batches)
        path = 0.0
        while path < path_stop:
            batch_add(st, float(rng.poisson((2 * path / (math.pi * area) + local) * dl)), dl, P.batches)
            path += dl
        k = int(st[2])
        m = k - k // 2
        count = float(st[3 + k // 2 : 3 + k].sum())
        spreads.append(mixing_spread(st, P.batches))
        tails.append(stats.chi2.sf(m - 2 + P.mix_tol**2 * count, m - 2))
    rejected = np.mean(np.array(spreads) > P.mix_tol)
    assert np.mean(tails) < 0.05
    # the share rejected is the chi-square tail's, within the binomial noise of 200 streams
    assert rejected <= np.mean(tails) + 3 * math.sqrt(np.mean(tails) / 200) + 0.01
    assert np.median(spreads) < 0.5 * P.mix_tol


def test_a_two_compartment_stream_waits_and_reads_nearer_the_area():
    """A robot that moves between two halves of the nest only every ~1/4 of its target path
    meets its trail at a swinging rate: the test (1b) holds it beyond the target coverage (to
    the largest coverage at most), and its self-crossing area, L^2 / (pi n), reads nearer the
    truth than the same stream (same draws) stopped at the target; a mixed stream stops at the
    target."""
    area = 4000.0
    dwell = P.coverage * area / W_U / 4
    at_target = StopParams(max_coverage=P.coverage)
    split = [_first_visit(np.random.default_rng([7, i]), area, compartments=2, dwell_u=dwell) for i in range(24)]
    short = [_first_visit(np.random.default_rng([7, i]), area, compartments=2, dwell_u=dwell, rule=at_target)
             for i in range(24)]  # fmt: skip
    mixed = [_first_visit(np.random.default_rng([8, i]), area) for i in range(24)]
    cov = lambda runs: np.array([W_U * p / area for p, _, _ in runs])  # noqa: E731
    a1 = lambda runs: np.array([p**2 / (math.pi * n) / area for p, n, _ in runs])  # noqa: E731
    assert np.all(cov(mixed) < 1.1 * P.coverage)
    assert abs(np.median(a1(mixed)) - 1) < 0.05
    waited = cov(split) > 1.02 * cov(short)
    assert waited.mean() >= 0.3
    assert np.all(cov(split) < 1.1 * P.max_coverage)
    # a stream that stopped below the largest coverage passed the test
    for p, n, spread in split:
        assert spread <= P.mix_tol or math.pi * W_U * n / p >= P.max_coverage
    # where it waited, the trail evened out: the area read low by less (mostly: a stream may
    # also wait into a long stay in one half)
    err_waited = np.abs(np.log(a1(split)[waited]))
    err_short = np.abs(np.log(a1(short)[waited]))
    assert np.median(err_waited) < 0.6 * np.median(err_short)


def test_bad_stop_params():
    from stcvision.errors import BadInputError

    with pytest.raises(BadInputError):
        StopParams(coverage=0)
    with pytest.raises(BadInputError):
        StopParams(batches=1)
    with pytest.raises(BadInputError):
        StopParams(max_coverage=0.1)  # below the target coverage
    with pytest.raises(BadInputError):
        StopParams(mix_tol=0)


def test_online_trials_are_deterministic_whatever_the_sweep_workers(tmp_path):
    """The same nests' tasks through the sweep runner in this process and on a pool of two
    processes: every stored per-trial figure is the same."""
    from stcvision.sweep import SweepOptions, Task, run_sweep

    params = {"trail_width_u": 0.1, "trials": 2, "visit_steps": "auto", "barrier": None}
    tasks = [
        Task(experiment="stcvision.controllers.buffon.experiments:nest_task", params={**params, "spec": s}, seed=21 + i)
        for i, s in enumerate(("circle:25", "square:22"))
    ]
    one = run_sweep(tasks, tmp_path / "one.jsonl", SweepOptions(workers=1))
    two = run_sweep(tasks, tmp_path / "two.jsonl", SweepOptions(workers=2))
    keys = ("l1_u", "l2_u", "crossings", "blind_fraction", "n_self", "self_blind", "rate_rel_se", "steps",
            "area_estimates")  # fmt: skip
    for t in tasks:
        for k in keys:
            assert one.results[t.key][k] == two.results[t.key][k], k


def test_online_trials_are_deterministic_whatever_the_threads():
    nest = parse_nest("circle:25")
    cfg = VisitConfig(visit_steps="auto")
    a = run_trials(nest, cfg, trials=3, seed=5, threads=1)
    b = run_trials(nest, cfg, trials=3, seed=5, threads=2)
    for k in ("l1_u", "l2_u", "crossings", "blind_fraction", "rate_rel_se", "steps", "n_self", "self_blind"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    assert a.online and a.converged.all()


def test_online_estimate_and_intervals_on_a_small_family():
    """Three small nests of the acceptance range's low end (not in the calibration family), six
    trials each: estimates near the truth, and the per-trial intervals hold it."""
    held, n = 0, 0
    for spec in ("circle:52", "square:46", "ellipse:2200:2.5"):
        nest = parse_nest(spec)
        ts = run_trials(nest, VisitConfig(visit_steps="auto"), trials=6, seed=11)
        s = summarise(ts, nest.area_u2)
        assert s["area_trusted"], s["area_warning"]
        assert abs(s["area_bias"]) < 0.08
        assert s["area_ci95"][0] <= nest.area_u2 <= s["area_ci95"][1]
        held += round(s["trial_ci95_coverage"] * 6)
        assert s["trial_ci95_note"] is None  # within the calibrated sizes
        n += 6
        ci = np.array(s["trial_area_ci95"])
        assert np.all(ci[:, 0] < ci[:, 1])
    assert held / n >= 0.8


def test_trial_interval_widens_with_the_measured_error():
    ci = trial_intervals(np.array([1000.0, 1000.0]), np.array([0.01, 0.2]))
    assert ci[0, 0] > ci[1, 0] and ci[0, 1] < ci[1, 1]
    assert ci[0, 0] < 1000 < ci[0, 1]


def test_trial_interval_carries_the_coverage_slopes_error():
    """A trial read away from the reference coverage carries the slope's standard error times
    that distance, in quadrature: t sqrt(h0^2 / t^2 + (se_kappa d)^2)."""
    from scipy import stats

    from stcvision.controllers.buffon.estimate import CALIBRATION_DOF, COVERAGE_SLOPE_SE, trial_half_width

    h0, h = trial_half_width(np.array([0.02, 0.02]), coverage_offset=np.array([0.0, 0.05]))
    t = stats.t.ppf(0.975, CALIBRATION_DOF)
    assert h == pytest.approx(t * math.sqrt((h0 / t) ** 2 + (COVERAGE_SLOPE_SE * 0.05) ** 2), rel=1e-12)


def _docs_script(name: str):
    """docs/measurements/NAME.py (a results page's measurement script), loaded as a module."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[3] / "docs" / "measurements" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_heldout_family_script_runs_resumes_and_rescores(tmp_path, capsys):
    """docs/measurements/buffon_heldout.py (the held-out measurement of the results page) on its first nest,
    two trials: it stores the raw trials, and a rescore of the store prints the same table."""
    mod = _docs_script("buffon_heldout")
    assert len(mod.family(tmp_path / "n", 7100)) == 44
    assert mod.main(["--out", str(tmp_path), "--trials", "2", "--nests", "1"]) == 0
    first = capsys.readouterr().out
    assert "| circles | 1 |" in first and "| all | 1 |" in first
    assert mod.main(["--out", str(tmp_path), "--rescore"]) == 0
    assert capsys.readouterr().out == first


def test_calibration_recovers_a_planted_factor_and_spread():
    """Synthetic trials whose two estimates read c times the true area, the second visit's with a
    log-normal error of 0.06 it does not report: the calibration gives K = 1/c and a per-trial
    extra spread of w * 0.06."""
    from stcvision.controllers.buffon.estimate import ONLINE_SECOND_WEIGHT, REFERENCE_COVERAGE
    from stcvision.controllers.buffon.online import calibrate_online

    rng = np.random.default_rng(8)
    c, sigma, trials = 1.08, 0.06, 40
    records = []
    for area in (2000.0, 5000.0, 9000.0, 15000.0, 22000.0, 30000.0):
        b2, b1 = np.full(trials, 0.25), np.full(trials, 0.18)
        l1 = REFERENCE_COVERAGE * c * area / (0.1 * (1 - b1))  # its own count reads it at the reference coverage
        l2 = 0.5 * l1
        n = 2 * l1 * l2 * (1 - b2) / (math.pi * c * area) * np.exp(-sigma * rng.standard_normal(trials))
        n_self = l1**2 * (1 - b1) / (math.pi * c * area)
        records.append({"area_true": area, "l1_u": l1, "l2_u": l2, "crossings": n, "blind_fraction": b2,
                        "n_self": n_self, "self_blind": b1, "rate_rel_se": np.zeros(trials)})  # fmt: skip
    cal = calibrate_online(records)
    assert cal["correction"] == pytest.approx(1 / c, rel=0.01)
    assert cal["trial_extra_sigma"] == pytest.approx(ONLINE_SECOND_WEIGHT * sigma, rel=0.15)
    assert cal["shape_sigma"] < 0.01


def test_calibration_recovers_a_planted_coverage_slope():
    """Synthetic trials read at coverages spread about the reference, whose log estimate grows
    2.0 per unit of coverage on top of a factor 1.05 and a 0.02 log-normal scatter: the calibration
    measures the slope within its standard error (times 3), and once the estimates are brought
    back, K = 1 / 1.05 and no extra spread is left beyond the scatter."""
    from stcvision.controllers.buffon.estimate import ONLINE_SECOND_WEIGHT, REFERENCE_COVERAGE
    from stcvision.controllers.buffon.online import calibrate_online

    rng = np.random.default_rng(3)
    kappa, c, sigma, trials = 2.0, 1.05, 0.02, 30
    records = []
    for area in (2500.0, 6000.0, 12000.0, 20000.0):
        rho = REFERENCE_COVERAGE + rng.uniform(0.0, 0.05, trials)  # the coverage each trial stopped at
        bias = c * np.exp(kappa * (rho - REFERENCE_COVERAGE) + sigma * rng.standard_normal(trials))
        b1, b2 = np.full(trials, 0.2), np.full(trials, 0.25)
        l1 = rho * bias * area / (0.1 * (1 - b1))  # the trail that its own count reads at rho (rule (1))...
        n_self = l1**2 * (1 - b1) / (math.pi * bias * area)  # ...with A1 = bias * A
        l2 = 0.5 * l1
        n = 2 * l1 * l2 * (1 - b2) / (math.pi * bias * area)  # A2 = bias * A
        records.append({"area_true": area, "l1_u": l1, "l2_u": l2, "crossings": n, "blind_fraction": b2,
                        "n_self": n_self, "self_blind": b1, "rate_rel_se": np.zeros(trials)})  # fmt: skip
    cal = calibrate_online(records)
    assert abs(cal["coverage_slope"] - kappa) < 3 * cal["coverage_slope_se"]
    assert cal["correction"] == pytest.approx(1 / c, rel=0.01)
    assert cal["trial_extra_sigma"] == pytest.approx(sigma, rel=0.2)
    assert 0 < ONLINE_SECOND_WEIGHT < 1


def test_heldout_script_calibration_mode_prints_the_factor(tmp_path, capsys, monkeypatch):
    """docs/measurements/buffon_heldout.py --calibration on a shrunk calibration family (two small nests, three
    trials): it stores the trials and prints calibrate_online's factor and spreads."""
    import json

    mod = _docs_script("buffon_heldout")
    small = [
        {"family": "calibration", "spec": s, "barrier": b} for s, b in (("circle:24", None), ("square:22", "bar:0.4"))
    ]
    monkeypatch.setattr(mod.exp, "calibration_family", lambda folder: small)
    assert mod.main(["--calibration", "--out", str(tmp_path), "--trials", "3", "--seed", "9100"]) == 0
    cal = json.loads(capsys.readouterr().out)
    assert cal["nests"] == 2 and cal["trials"] == 6 and cal["correction"] > 0
    assert len((tmp_path / "calibration.jsonl").read_text().splitlines()) == 2


def test_mixing_choice_script_measures_the_rule_on_a_shrunk_family(tmp_path, capsys, monkeypatch):
    """docs/measurements/buffon_mixing_choice.py (the results page's measurements behind the mixing test) on
    two small nests, two trials, one setting: it prints the per-nest table and writes every
    figure, the coverage-alone row first."""
    import json

    mod = _docs_script("buffon_mixing_choice")
    small = [
        {"family": "calibration", "spec": s, "barrier": b} for s, b in (("circle:30", None), ("square:30", "plus:0.6"))
    ]
    monkeypatch.setattr(mod, "calibration_family", lambda folder: small)
    monkeypatch.setattr(mod, "SETTINGS", ((P.mix_tol, P.max_coverage),))
    assert mod.main(["--out", str(tmp_path), "--trials", "2", "--seed", "3"]) == 0
    out = capsys.readouterr().out
    assert "circle:30 |" in out and "rank correlation" in out
    saved = json.loads((tmp_path / "mixing_choice.json").read_text())
    assert len(saved["streams"]) == 2 and all(len(r["trials"]) == 2 for r in saved["streams"])
    first, second = saved["settings"]
    assert first["mix_tol"] is None and first["first_visit_length_ratio"] == 1.0
    assert second["first_visit_length_ratio"] >= 1.0


def test_weight_check_rule_keeps_the_shipped_weight_when_a_group_undercovers(tmp_path, capsys):
    """docs/measurements/buffon_weight_check.py on synthetic stores (ten round nests and one of each other group,
    at each seed set): two of the ellipse's twelve first visits read 1.8 times the truth, so no
    weight covers that group and the rule keeps the shipped weight (which it leaves set); with the
    ellipse as steady as the others every weight is eligible and the lowest RMS error wins."""
    import json

    from stcvision.controllers.buffon import estimate as est

    mod = _docs_script("buffon_weight_check")
    nests = [(f"circle:{40 + d}", None) for d in range(10)]
    nests += [("ellipse:5000:2", None), ("square:75", "plus:0.6"), ("polygon:/x/calibration_L.json", None)]

    def stores(bad: bool, tag: str):
        rng = np.random.default_rng(5)
        cal, sweep = tmp_path / f"cal_{tag}.jsonl", tmp_path / f"sweep_{tag}.jsonl"
        lines, rows = [], [json.dumps({"kind": "stcvision-sweep-store"})]
        for store in ("cal", "sweep"):
            for spec, barrier in nests:
                area, n = 4000.0, 12
                l1 = np.full(n, 2.6 * area)
                l2 = 0.5 * l1
                e1, e2 = 0.03 * rng.standard_normal(n), 0.03 * rng.standard_normal(n)
                if bad and "ellipse" in spec:
                    e1[:2] = 0.6
                # every first visit read at the reference coverage; A1 = A exp(e1) through its blind share
                n_self = est.REFERENCE_COVERAGE * l1 / (math.pi * 0.1)
                b1 = 1 - np.exp(e1) * math.pi * n_self * area / l1**2
                rec = {"area_true": area, "l1_u": l1.tolist(), "l2_u": l2.tolist(),
                       "crossings": (2 * l1 * l2 / (math.pi * area) * np.exp(-e2)).tolist(),
                       "blind_fraction": [0.0] * n, "n_self": n_self.tolist(),
                       "self_blind": b1.tolist(), "rate_rel_se": [0.03] * n}  # fmt: skip
                if store == "cal":
                    lines.append(json.dumps({"spec": spec, "barrier": barrier, **rec}))
                else:
                    params = {"spec": spec, "barrier": barrier, "visit_steps": "auto"}
                    rows.append(json.dumps({"params": params, "result": rec}))
        cal.write_text("\n".join(lines) + "\n")
        sweep.write_text("\n".join(rows) + "\n")
        return str(cal), str(sweep)

    shipped = est.ONLINE_SECOND_WEIGHT
    assert mod.main([*stores(True, "bad")]) == 0
    out = capsys.readouterr().out
    assert f"chosen by the rule: w = {shipped:.1f}" in out and "| no |" in out and "| yes |" not in out
    assert est.ONLINE_SECOND_WEIGHT == shipped
    cal, other = mod.load(*stores(False, "good"))
    scores = [mod.score(w, cal, other) for w in (0.3, 0.4, 0.5)]
    assert all(s["eligible"] for s in scores)
    assert mod.choose(scores) == min(scores, key=lambda s: s["rms"]["both"])["w"]


def test_coverage_response_script_prints_a_row_per_forced_coverage(capsys):
    """docs/measurements/buffon_coverage_response.py (the results page's measurement of how the estimates
    grow with the reading coverage) runs on one small nest, two trials, and prints one row per
    forced coverage with a positive estimate."""
    mod = _docs_script("buffon_coverage_response")
    mod.main(["--trials", "2", "--nests", "circle:30", "--threads", "1"])
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| circle:30 |")]
    assert [float(r.split("|")[2]) for r in rows] == list(mod.COVERAGES)
    assert all(float(r.split("|")[5]) > 0 for r in rows)


def test_the_shipped_calibrated_sizes_are_the_calibration_familys():
    """The range the per-trial intervals say they were calibrated on is the family's own."""
    from stcvision.controllers.buffon.estimate import CALIBRATED_AREA_U2
    from stcvision.controllers.buffon.online import calibration_area_range

    assert calibration_area_range() == pytest.approx(CALIBRATED_AREA_U2, abs=0.1)
