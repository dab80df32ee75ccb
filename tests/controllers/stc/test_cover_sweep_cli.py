"""stcvision cover sweep over random boards of fixed sizes: the table and plot of a tiny sweep,
its runs equal to single 'stcvision cover' runs, resuming, refusals."""

import csv
import json

import cv2


def test_tiny_cover_sweep_writes_table_and_plot_and_replays(tmp_path, cli):
    out = tmp_path / "sweep"
    argv = ["cover", "sweep", "--sizes", "2,3", "--runs", "2", "--exposures", "webcam,auto"]
    argv += ["--perceptions", "oracle", "--out", out, "--workers", "2", "--json"]
    code, text, _ = cli(*argv)
    r = json.loads(text)
    assert code == 0 and r["tasks"] == 8 and not r["failed"] and r["skipped"] == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "dependability.png",
        "runs.csv",
        "summary.md",
        "sweep.jsonl",
        "table.csv",
    ]
    png = cv2.imread(str(out / "dependability.png"))
    assert png is not None and png.shape[1] > 700
    rows = list(csv.DictReader((out / "table.csv").open()))
    assert [(x["exposure"], x["family"]) for x in rows] == [
        ("auto", "random 2x2"),
        ("auto", "random 3x3"),
        ("auto", "all"),
        ("webcam", "random 2x2"),
        ("webcam", "random 3x3"),
        ("webcam", "all"),
    ]
    # the oracle robot covers every board exactly (controllers/stc.py, verified on 500 boards)
    assert all(x["complete"] == x["runs"] for x in rows)
    assert [x["runs"] for x in rows] == ["2", "2", "4"] * 2
    md = (out / "summary.md").read_text()
    assert "| webcam | oracle | webcam | random 3x3 | 2 | 2 | 100 % (15.8–100) | 0 | 0 | 0 | 0 | 100 % |" in md
    assert "dependability.png" in md and "Runs not complete" not in md
    # a run of the table is the run 'stcvision cover' makes with the same board, seed and settings
    runs = list(csv.DictReader((out / "runs.csv").open()))
    row = next(x for x in runs if (x["family"], x["seed"], x["exposure"]) == ("random 3x3", "1", "webcam"))
    code, text, _ = cli(
        "cover", "--board", "3x3", "--seed", "1", "--perception", "oracle", "--exposure", "webcam", "--json"
    )
    one = json.loads(text)
    assert code == 0
    for k in ("subcells_covered", "subcells_reachable", "decisions", "sim_time_s"):
        assert float(row[k]) == one[k], k
    # a re-run finds every run done and only rewrites the tables
    code, text, _ = cli(*argv)
    r2 = json.loads(text)
    assert code == 0 and r2["skipped"] == 8 and r2["table"] == r["table"]


def test_cover_sweep_refusals(tmp_path, cli):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "summary.md").write_text("my notes")
    code, _, err = cli("cover", "sweep", "--sizes", "2", "--runs", "1", "--perceptions", "oracle", "--out", mine)
    assert code == 2 and "--force" in err and err.count("\n") == 1
    assert (mine / "summary.md").read_text() == "my notes"
    for bad, words in (
        (["--perceptions", "sonar"], "sonar"),
        (["--exposures", "bright"], "bright"),
        (["--sizes", "0"], "--sizes"),
    ):
        code, _, err = cli("cover", "sweep", "--runs", "1", "--out", tmp_path / "x", *bad)
        assert code == 2 and words in err and err.count("\n") == 1, err
    assert not (tmp_path / "x").exists()  # every input is checked before the folder is made


def test_cover_sweep_over_camera_presets(tmp_path, cli):
    out = tmp_path / "cams"
    argv = ("cover", "sweep", "--sizes", "2", "--runs", "1", "--exposures", "auto", "--perceptions", "ideal",
            "--cameras", "webcam,lowlight", "--out", out, "--workers", "1", "--json")  # fmt: skip
    code, text, err = cli(*argv)
    assert code == 0, err
    rows = json.loads(text)["table"]
    assert sorted(r["camera"] for r in rows) == ["lowlight", "webcam"]
    runs = list(csv.DictReader((out / "runs.csv").open()))
    assert sorted(x["camera"] for x in runs) == ["lowlight", "webcam"]
    code, _, err = cli("cover", "sweep", "--sizes", "2", "--cameras", "nope", "--out", tmp_path / "x")
    assert code == 2 and "unknown camera" in err


def test_cover_sweep_with_the_c_controller_gives_the_python_table(tmp_path, cli):
    """The same runs decided by the host-built C step: the same outcomes, row for row."""
    import json

    argv = ("cover", "sweep", "--sizes", "2,3", "--runs", "2", "--perceptions", "oracle", "--workers", "1", "--json")
    tables = {}
    for fsm in ("python", "c"):
        code, out, err = cli(*argv, "--fsm", fsm, "--out", tmp_path / fsm)
        assert code == 0, err
        tables[fsm] = [{k: v for k, v in row.items() if not k.startswith("wall_s")} for row in json.loads(out)["table"]]
    assert tables["c"] == tables["python"] and len(tables["c"]) >= 2
