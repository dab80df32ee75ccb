"""`stcvision search` end to end: output keys, bad input (one line, exit 2), the beacon,
--rrd and --plot, `search reproduce`'s run_trial contract."""

import json

import numpy as np
import pytest

from stcvision.cli import main


def _json(capsys, argv):
    assert main(argv + ["--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_search_prints_the_issue_keys_and_finds_a_reachable_patch(capsys):
    r = _json(
        capsys,
        [
            "search",
            "--pattern",
            "spiral",
            "--max-steps",
            "45",
            "--obstacle",
            "0.43,0.06,0.08",
            "--patch",
            "-0.51,0.306,0.175",
            "--policy",
            "improved",
        ],
    )
    for k in (
        "found",
        "steps",
        "moves",
        "path_length_m",
        "odometry_error_m",
        "max_odometry_error_m",
        "shadow_area_m2",
        "phase_counts",
    ):
        assert k in r
    assert r["found"] and r["steps"] == 21 and r["phase_counts"]["3"] > 0


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--obstacle", "0.1,0,0.05"], "overlaps the start"),
        (["--obstacle", "1,1,0.3", "--patch", "1.1,1,0.1"], "inside the obstacle"),
        (["--petals", "0"], "petals"),
        (["--steps-per-petal", "-3"], "steps per petal"),
        (["--step-m", "0"], "step length"),
        (["--pattern", "spiral", "--max-steps", "0"], "--max-steps"),
        (["--obstacle", "1,2"], "3 comma-separated"),
        (["--obstacle", "nan,1,0.1"], "finite"),
        (["reproduce"], "--out"),
        (["detours"], "--out"),
        (["--petals", "100000000"], "MAX_SEARCH_STEPS"),
        (["--pattern", "spiral", "--max-steps", "100000000"], "MAX_SEARCH_STEPS"),
        (["--step-m", "1e6"], "MAX_SEARCH_REACH_M"),
        (["--obstacle", "1e7,0,0.1"], "MAX_SEARCH_REACH_M"),
        (["--patch", "1e7,0,0.1"], "MAX_SEARCH_REACH_M"),
        (["--obstacle", *[f"{3 + i / 100},3,0.001" for i in range(101)]], "MAX_SEARCH_OBSTACLES"),
        (["--pattern", "spiral", "--spacing-m", "1e-300"], "MIN_SEARCH_SPIRAL_SPACING_M"),
        (["reproduce", "--out", "x", "--seeds", "100000"], "MAX_SEARCH_SEEDS"),
        (["reproduce", "--out", "x", "--seeds", "0"], "must be > 0"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(capsys, argv, message):
    assert _exit(["search", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err


def _exit(argv):
    try:
        return main(argv)
    except SystemExit as e:  # argparse usage errors
        return e.code


def test_beacon_reduces_the_radial_odometry_error(capsys):
    """Two petals of the flower (64 steps): with the beacon the robot gets fixes near the centre
    and its end and worst odometry errors drop (measured 18 -> 3 mm and 67 -> 32 mm on seed 3)."""
    base = ["search", "--pattern", "radial", "--max-steps", "64", "--seed", "3"]
    off = _json(capsys, base)
    on = _json(capsys, base + ["--beacon"])
    assert on["beacon_fixes"] >= 4 and off["beacon_fixes"] == 0
    assert on["odometry_error_m"] < 0.5 * off["odometry_error_m"]
    assert on["max_odometry_error_m"] < off["max_odometry_error_m"]


def test_rrd_and_plot_are_written_and_not_overwritten(tmp_path, capsys, rrd_contents):
    rrd, png = tmp_path / "run.rrd", tmp_path / "run.png"
    argv = ["search", "--pattern", "spiral", "--max-steps", "8", "--rrd", str(rrd), "--plot", str(png)]
    r = _json(capsys, argv)
    assert rrd.stat().st_size > 1000 and png.read_bytes()[:4] == b"\x89PNG" and r["rrd"] == str(rrd)
    # its default layout: the floor map (true and believed paths), the beacon camera, the time series
    contents = rrd_contents(rrd)
    views = contents.views()
    assert ("2D", "world (north up)", "world") in views and ("2D", "beacon camera: raw frame", "raw") in views
    assert ("TimeSeries", "odometry error (m)", "series/odometry_error_m") in views
    assert contents.time_panel() == {"state": 3, "timeline": "sim_time"}
    assert contents.times("/world/believed_path", "move") == list(range(r["moves"]))
    assert _exit(argv) == 2 and "exists" in capsys.readouterr().err


def test_run_trial_is_json_and_deterministic():
    from stcvision.controllers.search.experiments import run_trial

    params = {"pattern": "spiral", "max_steps": 12, "policy": "simple", "obstacles": [[0.4, 0.1, 0.0365]]}
    a = run_trial(params, np.random.SeedSequence(11))
    b = run_trial(params, np.random.SeedSequence(11))
    assert a == b and json.loads(json.dumps(a)) == a


@pytest.mark.slow
def test_reproduce_end_to_end_resumes_and_refuses_without_writing(tmp_path, capsys, monkeypatch):
    """`search reproduce` cut short (every pattern 10 steps, 2 seeds): every figure, table and
    results.json; the two rows with the same parameters in two tables (the can case, improved
    policy, without the beacon) are two tasks by their row ids and, on the same paired seeds,
    give the same runs; a re-run resumes from the store; a refused run writes nothing; a failure
    after the runs leaves only the store, and the next run completes."""
    import stcvision.controllers.search.experiments as ex

    out = tmp_path / "SR"
    argv = ["search", "reproduce", "--out", str(out), "--seeds", "2", "--max-steps", "10", "--workers", "1"]
    r = _json(capsys, argv)
    assert sorted(p.name for p in out.iterdir()) == sorted([*ex.OUTPUTS, ex.STORE_NAME])
    assert all((out / f).read_bytes()[:4] == b"\x89PNG" for f in ex.FIGURES)
    runs = json.loads((out / "results.json").read_text())
    n_rows = sum(len(rows) for _, _, rows in ex.TABLES)
    assert len(runs) == n_rows and all(len(v) == 2 for v in runs.values())
    assert runs["spiral_can/improved"] == runs["beacon/spiral + can, no beacon"]
    assert runs["spiral_can/improved"][0] != runs["spiral_can/improved"][1]  # two seeds differ
    md = (out / "summary.md").read_text()
    assert "Cut short" in md and md.count("| case | seeds |") == len(ex.TABLES) and r["resumed"] == 0

    again = _json(capsys, argv)  # everything in the store: reused, the outputs rewritten
    assert again["resumed"] == 2 * n_rows
    assert json.loads((out / "results.json").read_text()) == runs

    user = tmp_path / "mine"  # a user's folder holding a file of the same name: refused, untouched
    user.mkdir()
    (user / "summary.md").write_text("my notes")
    assert _exit(["search", "reproduce", "--out", str(user), "--seeds", "1", "--max-steps", "10"]) == 2
    err = capsys.readouterr().err
    assert "summary.md exists" in err and len(err.strip().splitlines()) == 1
    assert [p.name for p in user.iterdir()] == ["summary.md"] and (user / "summary.md").read_text() == "my notes"
    bad = tmp_path / "bad"
    assert _exit(["search", "reproduce", "--out", str(bad), "--max-steps", "0"]) == 2
    assert "--max-steps" in capsys.readouterr().err and not bad.exists()

    def broken(*a, **k):
        raise KeyboardInterrupt

    import shutil

    fresh = tmp_path / "SR2"  # an earlier run's store only (seed 0 of every row: the first run's)
    fresh.mkdir()
    shutil.copy(out / ex.STORE_NAME, fresh / ex.STORE_NAME)
    monkeypatch.setattr(ex, "_figures", broken)  # interrupted after the runs, before any output
    argv2 = ["search", "reproduce", "--out", str(fresh), "--seeds", "1", "--max-steps", "10", "--workers", "1"]
    assert _exit(argv2) != 0
    assert [p.name for p in fresh.iterdir()] == [ex.STORE_NAME]
    monkeypatch.undo()
    capsys.readouterr()
    assert main([*argv2, "--json"]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out)["resumed"] == n_rows and "resuming the runs kept in" in cap.err
    assert sorted(p.name for p in fresh.iterdir()) == sorted([*ex.OUTPUTS, ex.STORE_NAME])


def test_detours_writes_its_table_with_intervals_and_resumes(tmp_path, capsys, monkeypatch):
    """`search detours` on one size at one place (both patterns, 2 seeds): the table with the
    finish counts and their binomial intervals, the figure, the runs; a re-run reuses them."""
    import stcvision.controllers.search.experiments as ex

    monkeypatch.setattr(ex, "DETOUR_SIZES_M", (0.2,))
    monkeypatch.setattr(ex, "DETOUR_PLACES", (0.25,))
    monkeypatch.setattr(ex, "DETOUR_PATTERNS", tuple((n, {**p, "max_steps": 40}) for n, p in ex.DETOUR_PATTERNS))
    out = tmp_path / "D"
    argv = ["search", "detours", "--out", str(out), "--seeds", "2", "--workers", "1"]
    r = _json(capsys, argv)
    assert sorted(p.name for p in out.iterdir()) == sorted([*ex.DETOUR_OUTPUTS, ex.DETOUR_STORE_NAME])
    assert r["runs"] == 4 and 0 <= r["finished"] <= 4 and r["ci95"][0] <= r["finished"] / 4 <= r["ci95"][1]
    md = (out / "summary.md").read_text()
    assert "| radial | 0.2 |" in md and "| spiral | 0.2 |" in md and "95 % interval" in md
    assert (out / "detours.png").read_bytes()[:4] == b"\x89PNG"
    assert _json(capsys, argv)["resumed"] == 4
    # a reproduction into the detour check's folder is refused (its summary.md is not a reproduction's)
    assert _exit(["search", "reproduce", "--out", str(out), "--seeds", "1", "--max-steps", "10"]) == 2
    assert "holds no search reproduction" in capsys.readouterr().err
