"""The STC dependability sweep (stcvision.controllers.stc.experiments, ``stcvision cover sweep --maps``):
maps and random boards of drawn size, obstacles and start; the table's counts against its runs,
the interval against scipy's binomtest; replay by ``stcvision cover``; bad input in one line."""

import csv
import json

import cv2
import numpy as np
import pytest
from scipy.stats import binomtest

from stcvision.controllers.stc import experiments as ex


@pytest.fixture
def two_maps(tmp_path):
    """A text map of 2x2 cells (one an obstacle, start given) and a PNG of 3x2 cells, all free
    (the loader picks the start)."""
    txt = tmp_path / "corner.txt"
    txt.write_text("S...\n....\n..##\n..##\n")
    png = tmp_path / "open.png"
    cv2.imwrite(str(png), np.full((4, 6), 255, np.uint8))
    return txt, png


def _read(path):
    return list(csv.DictReader(path.open()))


def test_maps_and_drawn_boards_sweep_counts_match_runs_and_replay(tmp_path, cli, two_maps):
    out = tmp_path / "sweep"
    argv = ["cover", "sweep", "--maps", f"{two_maps[0]},{two_maps[1]}", "--sizes", "2-4",
            "--obstacle-fraction", "0.05-0.25", "--start", "random",
            "--perceptions", "oracle", "--out", out, "--workers", "1", "--json"]  # fmt: skip
    code, text, err = cli(*argv, "--seeds", "3-4")
    assert code == 0, err
    r = json.loads(text)
    assert r["tasks"] == 3 * 2 and not r["failed"]
    runs = _read(out / "runs.csv")
    assert sorted({x["family"] for x in runs}) == ["map corner", "map open", "random 2-4"]
    assert sorted({x["seed"] for x in runs}) == ["3", "4"]
    # every count of the table is the count of its runs
    table = _read(out / "table.csv")
    for row in table:
        mine = [x for x in runs if row["family"] in ("all", x["family"])]
        assert int(row["runs"]) == len(mine)
        assert int(row["complete"]) == sum(x["complete"] == "True" for x in mine)
        assert int(row["safely_stopped"]) == sum(x["outcome"] == "safely stopped" for x in mine)
        assert int(row["unsafe"]) == sum(x["outcome"] == "unsafe" for x in mine)
        assert int(row["wrong_decisions"]) == sum(int(x["decision_errors"]) for x in mine)
        assert int(row["subcells_twice"]) == sum(int(x["subcells_covered_more_than_once"]) for x in mine)
        ci = binomtest(int(row["complete"]), int(row["runs"])).proportion_ci()
        assert (float(row["complete_ci95_low"]), float(row["complete_ci95_high"])) == pytest.approx((ci.low, ci.high))
    assert [x["family"] for x in table] == ["map corner", "map open", "random 2-4", "all"]
    # the oracle covers every board exactly
    assert all(x["outcome"] == "complete" for x in runs)
    # the start is drawn anywhere (not the loader's pick on every seed) and the size in its range
    starts = {(x["family"], x["start_subcell"]) for x in runs}
    assert len(starts) >= 4
    rnd = [x for x in runs if x["family"] == "random 2-4"]
    assert all(2 <= max(json.loads(x["board_cells"])) <= 4 for x in rnd)
    assert all(0.05 <= float(x["obstacle_fraction_drawn"]) <= 0.25 for x in rnd)
    # each run is the run 'stcvision cover' makes alone on the same board and start
    x = rnd[0]
    h, w = json.loads(x["board_cells"])
    i, j = json.loads(x["start_subcell"])
    code, text, _ = cli("cover", "--board", f"{w}x{h}", "--obstacle-fraction", x["obstacle_fraction_drawn"],
                        "--start", f"{i},{j}", "--seed", x["seed"], "--perception", "oracle", "--json")  # fmt: skip
    one = json.loads(text)
    assert code == 0 and float(x["sim_time_s"]) == one["sim_time_s"] and int(x["decisions"]) == one["decisions"]
    m = next(x for x in runs if x["family"] == "map corner")
    i, j = json.loads(m["start_subcell"])
    code, text, _ = cli("cover", "--map", two_maps[0], "--start", f"{i},{j}", "--seed", m["seed"],
                        "--perception", "oracle", "--json")  # fmt: skip
    assert float(m["sim_time_s"]) == json.loads(text)["sim_time_s"]
    md = (out / "summary.md").read_text()
    assert "| webcam | oracle | auto | map corner | 2 | 2 | 100 % (15.8–100) | 0 | 0 | 0 | 0 |" in md
    assert cv2.imread(str(out / "dependability.png")) is not None
    # the held-out seeds into the same folder run only the new runs
    code, text, _ = cli(*argv, "--seeds", "4-5")
    r2 = json.loads(text)
    assert code == 0 and r2["tasks"] == 6 and r2["skipped"] == 3
    assert {x["seeds"] for x in r2["table"]} == {"4-5"}


def test_tiny_camera_run_through_the_sweep(tmp_path, cli):
    """The camera itself (render -> pipeline) on one 2x2-cell map, cooled."""
    m = tmp_path / "square.txt"
    m.write_text("S...\n....\n....\n....\n")
    code, text, err = cli("cover", "sweep", "--maps", m, "--runs", "1", "--cameras", "cooled",
                          "--perceptions", "camera", "--out", tmp_path / "o", "--workers", "1", "--json")  # fmt: skip
    assert code == 0, err
    (row,) = json.loads(text)["table"]
    assert (row["family"], row["camera"], row["perception"], row["runs"]) == ("map square", "cooled", "camera", 1)
    (run,) = _read(tmp_path / "o" / "runs.csv")
    assert run["outcome"] == "complete" and int(run["frames"]) > 0 and run["subcells_reachable"] == "16"


def _run(complete, reason=None, errors=0, twice=0, **kw):
    r = {"board": "random", "width": [8, 22], "height": None, "board_cells": [kw.pop("side", 10)] * 2,
         "camera": "cooled", "perception": "camera", "exposure": "auto", "seed": kw.pop("seed", 0),
         "complete": complete, "abort_reason": reason, "decision_errors": errors,
         "subcells_covered_more_than_once": twice, "subcells_reachable": 100, "subcells_covered": 100,
         "sim_time_s": 1000.0, "wall_s": 2.0}  # fmt: skip
    return {**r, **kw}


def test_table_counts_outcomes_reasons_and_bands():
    runs = [
        _run(True, seed=0),
        _run(True, seed=1, side=12),
        _run(False, "out of sight: no mark in the cell ahead (0.43 m away) ... (at sub-cell (9, 3), decision 12)",
             seed=2, subcells_covered=40),
        _run(False, "misread: boxes {1,2} lit in a cell ... (at sub-cell (9, 8), decision 131)", seed=3, side=13),
        _run(False, "misread: boxes {} lit (at sub-cell (1, 1), decision 9)", 1, 1, seed=4, side=22),
        _run(False, None, 2, 0, seed=5, side=18),  # finished with decision errors: unsafe, not a stop
        _run(False, "gave up after 400 decisions", seed=6, side=17),
    ]  # fmt: skip
    assert [ex.outcome_of(r) for r in runs] == ["complete"] * 2 + ["safely stopped"] * 2 + ["unsafe"] * 2 + [
        "safely stopped"
    ]
    assert [ex.family_of(r) for r in runs[:5]] == ["random 8-12", "random 8-12", "random 8-12", "random 13-17",
                                                   "random 18-22"]  # fmt: skip
    rows = {r["family"]: r for r in ex.summarise(runs)}
    assert list(rows) == ["random 8-12", "random 13-17", "random 18-22", "all"]
    a = rows["random 8-12"]
    assert (a["runs"], a["complete"], a["safely_stopped"], a["unsafe"]) == (3, 2, 1, 0)
    assert a["stop_reasons"] == "out of sight x1" and a["seeds"] == "0-2"
    b = rows["random 13-17"]
    assert (b["safely_stopped"], b["stop_reasons"]) == (2, "gave up x1; misread x1")
    c = rows["random 18-22"]
    assert (c["unsafe"], c["wrong_decisions"], c["runs_with_wrong_decisions"], c["subcells_twice"]) == (2, 3, 2, 1)
    al = rows["all"]
    assert (al["runs"], al["complete"], al["safely_stopped"], al["unsafe"]) == (7, 2, 3, 2)
    ci = binomtest(2, 7).proportion_ci(confidence_level=0.95)
    assert (al["complete_ci95_low"], al["complete_ci95_high"]) == (ci.low, ci.high)
    assert "**3** (2 runs)" in ex.markdown_table(list(rows.values()))


def test_drawn_boards_are_the_seeds_own_and_replayable():
    params = {"board": "random", "width": [8, 22], "height": None, "obstacle_fraction": [0.05, 0.25],
              "start": "random"}  # fmt: skip
    drawn = [ex.draw_board(params, s) for s in range(30)]
    sides = {b.shape_cells for b, _ in drawn}
    assert len(sides) > 8 and all(h == w and 8 <= w <= 22 for h, w in sides)
    fr = [d["obstacle_fraction_drawn"] for _, d in drawn]
    assert min(fr) >= 0.05 and max(fr) <= 0.25 and len(set(fr)) > 20
    assert len({(b.start_subcell[0] % 2, b.start_subcell[1] % 2) for b, _ in drawn}) == 4  # every start heading
    for s, (b, d) in enumerate(drawn):
        assert b.cell_free[b.start_subcell[0] // 2, b.start_subcell[1] // 2]
        again, _ = ex.draw_board(params, s)
        assert np.array_equal(again.blocked, b.blocked) and again.start_subcell == b.start_subcell
        # the board is exactly --board WxH --obstacle-fraction F --seed S (the run's board stream)
        h, w = b.shape_cells
        assert np.array_equal(ex.random_board(w, h, d["obstacle_fraction_drawn"], s).blocked, b.blocked)
    # a map travels inside the task bit for bit
    board = ex.random_board(5, 3, 0.3, 7)
    back = ex.decode_grid(ex.encode_grid(board))
    assert np.array_equal(back.blocked, board.blocked) and back.start_subcell == board.start_subcell


def test_bad_input_is_one_line_and_writes_nothing(tmp_path, cli, two_maps):
    out = tmp_path / "never"
    base = ("cover", "sweep", "--perceptions", "oracle", "--out", out)
    for bad, words in (
        (["--maps", tmp_path / "missing.png", "--runs", "1"], "does not exist"),
        (["--maps", tmp_path, "--runs", "1"], "is a folder"),
        (["--maps", f"{two_maps[0]},{two_maps[0]}", "--runs", "1"], "twice"),
        (["--maps", two_maps[0], "--seeds", "5-2"], "start is above its end"),
        (["--maps", two_maps[0], "--seeds", "a-b"], "--seeds"),
        (["--maps", two_maps[0], "--seeds", "0-3,2"], "twice"),
        (["--maps", two_maps[0], "--seeds", "0-1000000000000"], "over the cap"),
        (["--maps", two_maps[0], "--runs", "1000000000"], "over the cap"),
        (["--maps", two_maps[0], "--runs", "0"], "--runs"),
        (["--sizes", "8-22", "--obstacle-fraction", "0.2-1.5", "--runs", "1"], "[0, 1)"),
        (["--sizes", "4-x", "--runs", "1"], "--sizes"),
        (["--sizes", "200", "--runs", "1"], "cells"),
        (["--sizes", "22", "--runs", "10000", "--cameras", "webcam,lowlight,cooled", "--exposures",
          "auto,webcam"], "over the cap"),
    ):  # fmt: skip
        code, text, err = cli(*base, *bad)
        assert code == 2 and words in err and err.count("\n") == 1 and text == "", (bad, err)
    assert not out.exists()


def test_readme_acceptance_commands_small(tmp_path, cli, peer_data):
    """The two dependability commands of docs/results/stc.md, small: the three peer maps and the
    drawn random boards, with the oracle's perception (the camera is not the point here: the
    plumbing is)."""
    maps = ",".join(str(peer_data / "pythonrobotics_maps" / f"spiral_stc_test{s}.png") for s in ("", "_2", "_3"))
    code, text, err = cli("cover", "sweep", "--maps", maps, "--runs", "1", "--cameras", "cooled,lowlight",
                          "--perceptions", "oracle", "--out", tmp_path / "D", "--workers", "1", "--json")  # fmt: skip
    assert code == 0, err
    rows = json.loads(text)["table"]
    assert [(r["camera"], r["family"]) for r in rows] == [
        (c, f) for c in ("cooled", "lowlight")
        for f in ("map spiral_stc_test", "map spiral_stc_test_2", "map spiral_stc_test_3", "all")
    ]  # fmt: skip
    assert all(r["complete"] == r["runs"] for r in rows)
    code, text, err = cli("cover", "sweep", "--sizes", "8-22", "--obstacle-fraction", "0.05-0.25", "--start",
                          "random", "--seeds", "20-21", "--cameras", "cooled", "--perceptions", "oracle",
                          "--out", tmp_path / "D2", "--workers", "1", "--json")  # fmt: skip
    assert code == 0, err
    rows = json.loads(text)["table"]
    assert sum(r["runs"] for r in rows if r["family"] != "all") == 2
    assert all(r["family"] in ("random 8-12", "random 13-17", "random 18-22", "all") for r in rows)
