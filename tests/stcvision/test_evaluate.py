"""stcvision eval: scoring a dataset, the report, --rrd, --compare, users' own frames, bad sets."""

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from stcvision.cli import main
from stcvision.evaluate import compare

SMOKE = Path(__file__).resolve().parents[2] / "datasets" / "recipes" / "smoke.json"
METRICS = (
    "frames",
    "dot_recall",
    "dot_precision",
    "dot_loc_err_px_median",
    "heading_err_deg_rms",
    "box_accuracy",
    "obstacle_accuracy",
    "ms_per_frame_median",
)


@pytest.fixture(scope="module")
def evaluated(smoke, tmp_path_factory):
    """eval --json --report --rrd on the smoke set, once."""
    import contextlib
    import io

    d = tmp_path_factory.mktemp("eval")
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["eval", str(smoke), "--json", "--report", str(d / "report"), "--rrd", str(d / "worst.rrd")])
    assert code == 0
    (d / "a.json").write_text(buf.getvalue())
    return d, json.loads(buf.getvalue())


def test_smoke_generate_then_eval_gives_every_metric(evaluated):
    _, r = evaluated
    for k in METRICS:
        assert r[k] is not None, k
    assert r["frames"] == 6 and r["frames_skipped"] == 0
    # the pipeline issue's goals, loosely (six frames): see docs/results/pipeline.md, "Accuracy"
    assert r["dot_recall"] >= 0.95 and r["dot_precision"] >= 0.98
    assert r["heading_err_deg_rms"] <= 0.6 and r["box_accuracy"] >= 0.95 and r["obstacle_accuracy"] >= 0.95
    assert set(r["by_exposure"]) == {"33.33 ms, gain 16", "250 ms, gain 8"}
    assert sum(m["frames"] for m in r["by_exposure"].values()) == 6
    assert set(r["by_group"]) == {"webcam", "exp250ms"}
    assert r["by_age"] and all(0 <= b["recall"] <= 1 for b in r["by_age"])
    assert sum(b["expected"] for b in r["by_age"]) >= 10
    assert set(r["stage_ms_median"]) >= {"dark", "dots", "observe"}
    assert sum(map(sum, r["box_confusion"])) == r["boxes_scored"]
    assert sum(map(sum, r["obstacle_confusion"])) == r["obstacles_scored"] == 24


def test_report_and_recording_files(evaluated):
    d, r = evaluated
    rep = d / "report"
    for name in (
        "summary.md",
        "eval.json",
        "frames.jsonl",
        "recall_vs_age.png",
        "heading_error_hist.png",
        "box_confusion.png",
        "obstacle_confusion.png",
        "stage_timing.png",
    ):
        assert (rep / name).stat().st_size > 0, name
    for png in rep.glob("*.png"):
        img = cv2.imread(str(png))
        assert img is not None and img.shape[0] > 200 and img.std() > 5, png
    md = (rep / "summary.md").read_text()
    assert "dot recall" in md and "By exposure" in md and "![recall_vs_age.png]" in md
    assert len((rep / "frames.jsonl").read_text().splitlines()) == 6
    assert (d / "worst.rrd").stat().st_size > 10_000 and 1 <= len(r["rrd_frames"]) <= 10


def test_report_is_never_overwritten_silently(smoke, evaluated, cli):
    d, _ = evaluated
    code, _, err = cli("eval", smoke, "--report", d / "report")
    assert code == 2 and "--force" in err and err.count("\n") == 1


def test_compare(evaluated, tmp_path, cli):
    d, a = evaluated
    same = compare(a, a)
    assert same["worse"] == same["better"] == 0 and same["same_dataset"]
    b = dict(a, dot_recall=a["dot_recall"] - 0.05, heading_err_deg_rms=a["heading_err_deg_rms"] / 2)
    (tmp_path / "b.json").write_text(json.dumps(b))
    code, out, _ = cli("eval", "--compare", d / "a.json", tmp_path / "b.json", "--json")
    r = json.loads(out)
    verdict = {row["metric"]: row["verdict"] for row in r["rows"]}
    assert code == 0 and verdict["dot_recall"] == "worse" and verdict["heading_err_deg_rms"] == "better"
    assert verdict["box_accuracy"] == "same" and r["worse"] >= 1 and r["better"] >= 1
    code, out, _ = cli("eval", "--compare", d / "a.json", tmp_path / "b.json")
    assert code == 0 and "dot_recall" in out and "worse" in out and "better" in out
    (tmp_path / "junk.json").write_text('{"x": 1}')
    code, _, err = cli("eval", "--compare", d / "a.json", tmp_path / "junk.json")
    assert code == 2 and "junk.json" in err and err.count("\n") == 1


def test_users_own_frames_without_labels(smoke, tmp_path, cli):
    own = tmp_path / "robot_frames"
    own.mkdir()
    for k in range(3):
        shutil.copy(smoke / "frames" / f"{k:06d}.png", own / f"f{k}.png")
    (own / "f1b.png").write_bytes(b"not a png")  # a corrupt frame in the middle
    code, _, err = cli("eval", own)
    assert code == 2 and "--dark" in err and err.count("\n") == 1
    code, out, err = cli("eval", own, "--dark", smoke / "dark" / "webcam.png", "--rrd", tmp_path / "own.rrd")
    assert code == 0 and "no accuracy" in out and "f1b.png" in err
    res = tmp_path / "robot_frames-results.jsonl"
    lines = [json.loads(s) for s in res.read_text().splitlines()]
    assert [Path(x["frame"]).name for x in lines] == ["f0.png", "f1.png", "f1b.png", "f2.png"]
    assert "skipped" in lines[2] and all("dots" in x and "heading" in x for x in lines if "skipped" not in x)
    assert (tmp_path / "own.rrd").stat().st_size > 10_000
    code, out, _ = cli("eval", own, "--no-dark", "--out", tmp_path / "r2.jsonl", "--json")
    r = json.loads(out)
    assert code == 0 and r["frames"] == 3 and r["frames_skipped"] == 1 and r["accuracy"] is None
    # never overwrites the results without --force
    code, _, err = cli("eval", own, "--no-dark", "--out", tmp_path / "r2.jsonl")
    assert code == 2 and "--force" in err


def _broken(smoke, tmp_path, how):
    d = tmp_path / "bad"
    shutil.copytree(smoke, d)
    how(d)
    return d


def _drop_label(d):
    lines = (d / "labels.jsonl").read_text().splitlines()
    (d / "labels.jsonl").write_text("\n".join(lines[:-1]) + "\n")
    (d / "frames" / "000005.png").unlink()


def _small_frame(d):
    cv2.imwrite(str(d / "frames" / "000002.png"), np.zeros((240, 320, 3), np.uint8))


@pytest.mark.parametrize(
    ("how", "words"),
    [
        (lambda d: (d / "manifest.json").unlink(), "no manifest.json"),
        (lambda d: (d / "frames" / "000003.png").unlink(), "000003.png, but that frame is missing"),
        (lambda d: shutil.copy(d / "frames" / "000001.png", d / "frames" / "000042.png"), "000042.png has no label"),
        (_drop_label, "lists 6 frames but"),
        (_small_frame, "is 320x240; expected 640x480"),
        (lambda d: (d / "labels.jsonl").write_text("{oops\n"), "line 1 is not valid JSON"),
        (lambda d: (d / "dark" / "webcam.png").unlink(), "webcam.png"),
        (lambda d: (d / "labels.jsonl").unlink(), "no labels.jsonl"),
    ],
)
def test_bad_datasets_are_one_line_errors(smoke, tmp_path, cli, how, words):
    d = _broken(smoke, tmp_path, how)
    code, _, err = cli("eval", d)
    assert code == 2 and words in err and err.count("\n") == 1, err


def test_a_corrupt_frame_is_skipped_and_counted(smoke, tmp_path, cli):
    d = _broken(smoke, tmp_path, lambda d: (d / "frames" / "000002.png").write_bytes(b"\x89PNG broken"))
    code, out, err = cli("eval", d, "--json")
    r = json.loads(out)
    assert code == 0 and r["frames"] == 5 and r["frames_skipped"] == 1
    assert r["skipped"][0]["frame"] == "frames/000002.png" and "000002.png" in err


@pytest.mark.slow
def test_each_camera_is_read_with_its_own_workflow_profile(tmp_path, cli):
    recipe = {
        "schema_version": 1,
        "name": "one-perturbed",
        "dark_frames": 4,
        "calibration": {"lights_on_frames": 1, "profiles": True},
        "scene": {"age_range_s": [0, 30]},
        "groups": [
            {
                "name": "tilted",
                "n": 3,
                "pattern_seed": 2,
                "camera": {"mirror_decentre_m": [0.0012, -0.001], "mirror_tilt_rad": 0.0349},
            }
        ],
    }
    (tmp_path / "r.json").write_text(json.dumps(recipe))
    d = tmp_path / "D"
    assert main(["dataset", "generate", str(tmp_path / "r.json"), "--out", str(d)]) == 0
    assert (d / "calibration" / "cam0_0.png").exists() and (d / "profiles" / "cam0.json").exists()
    code, out, _ = cli("eval", d, "--json")
    own = json.loads(out)
    assert code == 0 and own["profile"] == "per camera" and own["dot_recall"] >= 0.95
    from stcvision.calibration.profiles import default_profile_path

    code, out, _ = cli("eval", d, "--json", "--profile", default_profile_path())
    bad = json.loads(out)
    # calibration matters: the shipped profile reads this mirror worse (docs/results/pipeline.md,
    # "Accuracy")
    assert bad["dot_recall"] < own["dot_recall"]
    own_cam, bad_cam = own["by_camera"]["cam0"], bad["by_camera"]["cam0"]
    assert own_cam["profile"] == "profiles/cam0.json" and bad_cam["profile"] == "given"
    assert own_cam["profile_floor_err_mm_median"] < 3.0 < bad_cam["profile_floor_err_mm_median"]


def test_given_profile(smoke, tmp_path, cli):
    from stcvision.calibration.profiles import default_profile_path

    code, out, _ = cli("eval", smoke, "--profile", default_profile_path(), "--json")
    assert code == 0 and json.loads(out)["profile"].endswith("default.json")
    code, _, err = cli("eval", smoke, "--profile", tmp_path / "none.json")
    assert code == 2 and "none.json" in err


def _untimed(d):
    """An eval summary without its timings (which differ run to run) and the sweep's line."""
    if isinstance(d, dict):
        return {k: _untimed(v) for k, v in d.items() if "ms" not in k.split("_") and k != "sweep"}
    if isinstance(d, list):
        return [_untimed(v) for v in d]
    return d


def test_eval_in_chunks_on_a_pool_equals_one_in_process_pass_and_resumes(smoke, tmp_path, cli, monkeypatch):
    import stcvision.evaluate as ce

    code, out, _ = cli("eval", smoke, "--json", "--workers", "1")
    one = json.loads(out)
    monkeypatch.setattr(ce, "FRAMES_PER_TASK", 2)  # three tasks of two frames
    store = tmp_path / "eval.jsonl"
    code, out, _ = cli("eval", smoke, "--json", "--workers", "2", "--store", store)
    pool = json.loads(out)
    assert code == 0 and "3 tasks" in pool["sweep"] and "local pool of 2" in pool["sweep"]
    assert _untimed(pool) == _untimed(one) and pool["frames"] == 6
    assert len(store.read_text().splitlines()) == 1 + 3  # header + one line per chunk
    code, out, _ = cli("eval", smoke, "--json", "--workers", "2", "--store", store)
    again = json.loads(out)
    assert "3 skipped as done" in again["sweep"] and again == {**pool, "sweep": again["sweep"]}
