"""stcvision render / pipeline / bench from the command line, as a user runs them."""

import json
import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

from stcvision.cli import main


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    d = tmp_path_factory.mktemp("render")
    scene = d / "scene.json"
    from stcvision.sim_camera.scene import EXAMPLE_SCENE

    scene.write_text(json.dumps(EXAMPLE_SCENE))
    assert main(["render", "--scene", str(scene), "--out", str(d / "out"), "--seed", "3"]) == 0
    return d / "out"


def test_render_writes_frame_dark_lights_on_and_truth(rendered, capsys):
    for name in ("frame.png", "dark.png", "lights_on.png", "truth.json"):
        assert (rendered / name).stat().st_size > 0
    truth = json.loads((rendered / "truth.json").read_text())
    assert truth["cell"]["cell"] == [3, 3] and truth["seed"] == 3
    # never overwrites without --force
    capsys.readouterr()
    assert main(["render", "--scene", str(rendered.parent / "scene.json"), "--out", str(rendered)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--force" in err


def test_pipeline_json_and_rerun_recording(rendered, tmp_path, capsys):
    rrd = tmp_path / "run.rrd"
    code = main(
        ["pipeline", str(rendered / "frame.png"), "--dark", str(rendered / "dark.png"), "--rrd", str(rrd), "--json"]
    )
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    f = out["frames"][0]
    assert f["observation"]["boxes"]["3"]["lit"] and f["observation"]["boxes"]["5"]["lit"]
    assert not f["observation"]["boxes"]["1"]["lit"]
    assert f["heading"]["ok"] and abs(f["heading"]["heading_error_deg"] - 3.0) < 0.5
    assert set(f["stage_ms"]) == {"dark", "window", "unwarp", "channels", "dots", "rows", "red", "heading", "observe"}
    rerun = shutil.which("rerun", path=str(Path(__import__("sys").executable).parent))
    assert rerun, "the rerun CLI ships with rerun-sdk"
    assert subprocess.run([rerun, "rrd", "verify", str(rrd)], capture_output=True).returncode == 0
    text = subprocess.run([rerun, "rrd", "print", "-v", str(rrd)], capture_output=True, text=True).stdout
    from stcvision.rr import ENTITY_PATHS

    for path in ENTITY_PATHS:
        assert f"/{path}" in text, f"entity {path} not logged"
    for stage in f["stage_ms"]:
        assert f"/timing/{stage}" in text


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda d: d / "missing.png", "does not exist"),
        (lambda d: (d / "empty.png").write_bytes(b"") or d / "empty.png", "is empty"),
        (lambda d: (d / "text.png").write_text("hello") and d / "text.png", "not a readable image"),
        (
            lambda d: cv2.imwrite(str(d / "small.png"), np.zeros((240, 320, 3), np.uint8)) and d / "small.png",
            "calibrated for 640x480",
        ),
    ],
)
def test_pipeline_bad_frames_are_one_line_errors(rendered, tmp_path, capsys, make, words):
    frame = make(tmp_path)
    assert main(["pipeline", str(frame), "--dark", str(rendered / "dark.png")]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1


def test_pipeline_needs_a_dark_frame_or_says_so(rendered, capsys):
    assert main(["pipeline", str(rendered / "frame.png")]) == 2
    assert "--dark" in capsys.readouterr().err
    assert main(["pipeline", str(rendered / "frame.png"), "--no-dark", "--json"]) == 0


def test_pipeline_profile_that_does_not_match(rendered, tmp_path, capsys):
    from stcvision.calibration.profiles import default_profile

    p = default_profile().replace(image_size_px=(800, 600))
    p.save(tmp_path / "p.json")
    assert (
        main(
            [
                "pipeline",
                str(rendered / "frame.png"),
                "--dark",
                str(rendered / "dark.png"),
                "--profile",
                str(tmp_path / "p.json"),
            ]
        )
        == 2
    )
    assert "800x600" in capsys.readouterr().err


@pytest.mark.slow
def test_bench_reports_render_and_pipeline_times(capsys):
    # (the closed loop's 22x22 tour has its own tests: tests/controllers/stc/test_timing.py)
    assert main(["bench", "--frames", "5", "--no-loop", "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["render_ms_per_frame"] > 0 and r["pipeline_ms_per_frame"] > 0
    assert set(r["stage_ms"]) >= {"dark", "unwarp", "dots", "observe"}
    assert "loop_overhead_ratio" not in r
