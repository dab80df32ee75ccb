"""The labelling helper without a browser: the sheet holds the pipeline's proposals (the page's
own data), accepted labels become the folder's labels.jsonl, and eval then scores the pipeline
against its own proposal perfectly; bad input is one line and exit 2. The page itself runs in a
real browser in tests/browser (make test-browser)."""

import json
import re
import shutil

import pytest


@pytest.fixture
def folder(smoke, tmp_path):
    d = tmp_path / "frames"
    d.mkdir()
    for name in ("000000.png", "000001.png"):
        shutil.copy(smoke / "frames" / name, d / name)
    return d


def test_the_sheet_holds_the_proposals_and_accepted_labels_score(cli, smoke, folder, tmp_path):
    dark = smoke / "dark" / "webcam.png"
    code, out, err = cli("label", folder, "--dark", dark, "--out", tmp_path / "sheet", "--json")
    assert code == 0, err
    r = json.loads(out)
    assert r["frames"] == 2 and r["untrusted"] == []
    page = (tmp_path / "sheet" / "index.html").read_text()
    data = json.loads(re.search(r'<script id="proposals" type="application/json">(.*?)</script>', page, re.S)[1])
    proposed = [json.loads(x) for x in (tmp_path / "sheet" / "proposed.jsonl").read_text().splitlines()]
    assert data == proposed and [p["frame"] for p in proposed] == ["000000.png", "000001.png"]
    assert all(len(p["boxes"]) == 5 and len(p["neighbours"]) == 4 and p["dots"] for p in proposed)
    code, out, err = cli("label", folder, "--accept", tmp_path / "sheet" / "proposed.jsonl")
    assert code == 0, err
    code, out, err = cli("eval", folder, "--dark", dark, "--json")
    assert code == 0, err
    e = json.loads(out)
    assert e["box_accuracy"] == 1.0 and e["obstacle_accuracy"] == 1.0 and e["dot_recall"] == 1.0
    assert e["heading_err_deg_rms"] == pytest.approx(0.0, abs=1e-3)  # proposals are rounded to 0.001 deg
    code, _, err = cli("label", folder, "--accept", tmp_path / "sheet" / "proposed.jsonl")
    assert code == 2 and "--force" in err  # labels.jsonl is there now


def test_bad_label_input_is_one_line(cli, folder, tmp_path):
    for argv, says in [
        ([folder], "--dark DARK.png"),
        ([tmp_path / "nope"], "not a folder"),
        ([folder, "--accept", tmp_path / "missing.jsonl"], "missing.jsonl"),
    ]:
        code, _, err = cli("label", *argv)
        assert code == 2 and says in err and err.count("\n") == 1, err
    (tmp_path / "l.jsonl").write_text(json.dumps({"frame": "elsewhere.png"}) + "\n")
    code, _, err = cli("label", folder, "--accept", tmp_path / "l.jsonl")
    assert code == 2 and "does not hold" in err
