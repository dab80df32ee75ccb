"""Inputs checked early and said right: frames the pipeline cannot read as dark-room frames are
marked untrusted, eval leaves out the --dark file, outputs are checked before any work, a folder
as --map is called a folder, OpenCV's own log stays quiet, calibrate speaks to people unless
--json, and an interrupted demo leaves no empty folder."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

STCVISION = str(Path(sys.executable).with_name("stcvision"))


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """The example scene rendered with the webcam and with the cooled camera."""
    from stcvision.cli import main

    d = tmp_path_factory.mktemp("scenes")
    scene = d / "scene.json"
    from stcvision.sim_camera.scene import EXAMPLE_SCENE

    scene.write_text(json.dumps(EXAMPLE_SCENE))
    for cam in ("webcam", "cooled"):
        assert main(["render", "--scene", str(scene), "--camera", cam, "--out", str(d / cam)]) == 0
    return d


def pipeline_json(cli, *argv):
    code, out, err = cli("pipeline", *argv, "--json")
    assert code == 0, err
    return json.loads(out)["frames"][0]


def test_no_dark_on_a_cooled_frame_is_marked_untrusted_and_with_its_dark_frame_it_is_not(cli, rendered):
    c = rendered / "cooled"
    bad = pipeline_json(cli, c / "frame.png", "--no-dark")
    assert "no dark frame" in bad["untrusted"] and bad["observation"]["untrusted"]
    good = pipeline_json(cli, c / "frame.png", "--dark", c / "dark.png")
    assert good["untrusted"] == "" and len(good["dots"]) == 16  # the scene's 4 marks of 4 dots
    code, out, _ = cli("pipeline", c / "frame.png", "--no-dark")
    assert code == 0 and "UNTRUSTED: no dark frame" in out


def test_a_lights_on_frame_is_not_read_as_a_dark_room_frame(cli, rendered):
    w = rendered / "webcam"
    lit = pipeline_json(cli, w / "lights_on.png", "--dark", w / "dark.png")
    assert "lit frame" in lit["untrusted"]


def test_eval_of_own_frames_leaves_out_the_dark_file_and_lists_untrusted_frames(cli, rendered, tmp_path):
    w = rendered / "webcam"
    code, out, err = cli("eval", w, "--dark", w / "dark.png", "--out", tmp_path / "r.jsonl", "--json")
    r = json.loads(out)
    assert code == 0 and r["frames"] == 2 and r["excluded"] == [str(w / "dark.png")]
    assert [Path(u["frame"]).name for u in r["untrusted"]] == ["lights_on.png"]
    code, out, _ = cli("eval", w, "--dark", w / "dark.png", "--out", tmp_path / "r2.jsonl")
    assert "untrusted" in out and "lights_on.png" in out and "left out" in out


def test_eval_report_that_cannot_be_written_fails_before_any_work(cli, smoke, tmp_path, monkeypatch):
    import stcvision.evaluate as evaluate

    def no_work(*a, **k):
        raise AssertionError("the evaluation ran before its report folder was checked")

    monkeypatch.setattr(evaluate, "sweep_evaluation", no_work)
    (tmp_path / "file").write_text("x")
    code, _, err = cli("eval", smoke, "--report", tmp_path / "file" / "rep")
    assert code == 2 and err.count("\n") == 1 and "not a folder" in err
    ro = tmp_path / "ro"
    ro.mkdir()
    real_access = os.access
    monkeypatch.setattr("stcvision.fileio.os.access", lambda p, m: False if Path(p) == ro else real_access(p, m))
    code, _, err = cli("eval", smoke, "--report", ro)  # as a user without write permission sees it
    assert code == 2 and "no permission to write" in err


def test_a_folder_as_map_is_called_a_folder(cli, tmp_path):
    code, _, err = cli("cover", "--map", tmp_path)
    assert code == 2 and "is a folder" in err and "does not exist" not in err


def test_a_truncated_png_gives_one_line_without_opencvs_log(rendered, tmp_path):
    png = (rendered / "webcam" / "frame.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(png[: len(png) // 3])
    r = subprocess.run([STCVISION, "pipeline", str(tmp_path / "cut.png"), "--no-dark"], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "not a readable image" in r.stderr, r.stderr


def test_calibrate_prints_a_summary_and_json_only_when_asked(cli, rendered, tmp_path):
    w = rendered / "webcam"
    code, out, _ = cli("calibrate", "rim", w / "lights_on.png")
    assert code == 0 and out.startswith("mirror rim: centre (") and "{" not in out
    code, out, _ = cli("calibrate", "rim", w / "lights_on.png", "--json")
    assert code == 0 and json.loads(out)["radius_px"] > 100
    code, out, _ = cli("calibrate", "dark", w / "dark.png", "--out", tmp_path / "d.png")
    assert code == 0 and out.startswith(f"wrote {tmp_path / 'd.png'}: the median of 1 dark frame") and "{" not in out
    code, out, _ = cli("calibrate", "transform", w / "lights_on.png", "--out", tmp_path / "p.json", "--yes")
    assert code == 0 and "mirror rim:" in out and "grid:" in out and "{" not in out


def test_calibrate_help_keeps_its_examples_on_their_own_lines(cli, capsys):
    from stcvision.cli import main

    with pytest.raises(SystemExit):
        main(["calibrate", "--help"])
    text = capsys.readouterr().out
    assert "\n  stcvision calibrate dark FRAME... --out dark.png\n  stcvision calibrate dark --bag FILE" in text
    assert "\n  stcvision calibrate rim FRAME\n" in text


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_demo_leaves_no_folder(tmp_path, sig):
    out = tmp_path / "a" / "demo"
    proc = subprocess.Popen(
        [STCVISION, "demo", "--out", str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )
    deadline = time.monotonic() + 180
    while not out.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + sig, err
    if f"kept {out / 'demo.rrd'}" in err:  # the signal came after the recording began: it is kept, alone
        assert sorted(str(f.relative_to(tmp_path)) for f in tmp_path.rglob("*")) == ["a", "a/demo", "a/demo/demo.rrd"]
    else:  # before: nothing is left, not even the folders the demo made
        assert not (tmp_path / "a").exists(), err


ROOM = Path(__file__).resolve().parents[2] / "datasets" / "peer_data" / "opencv_omnidir" / "catadioptric_sample.jpg"


@pytest.fixture(scope="module")
def room_profile(tmp_path_factory):
    """The shipped profile with its mirror rim moved to where the real room photograph shows it
    (centre (315, 218) px, radius 265 px), so that only the frame's content can refuse it."""
    from stcvision.calibration.profiles import default_profile_path

    d = json.loads(default_profile_path().read_text())
    d["center_px"], d["rim_radius_px"] = [314.7, 217.7], 264.6
    p = tmp_path_factory.mktemp("room") / "room_profile.json"
    p.write_text(json.dumps(d))
    return p


def test_a_real_lit_room_is_untrusted_in_pipeline_and_eval(cli, room_profile, tmp_path):
    """A real catadioptric photograph of a lit room (OpenCV's omnidir sample) read as a
    dark-room frame: its texture inflates the noise estimate as much as its level, so only its
    structure over blocks of pixels gives it away."""
    r = pipeline_json(cli, ROOM, "--no-dark", "--profile", room_profile)
    assert "a lit frame" in r["untrusted"] and "shows a scene" in r["untrusted"]
    frames = tmp_path / "frames"
    frames.mkdir()
    (frames / "room.jpg").write_bytes(ROOM.read_bytes())
    code, out, err = cli(
        "eval", frames, "--no-dark", "--profile", room_profile, "--out", tmp_path / "r.jsonl", "--json"
    )
    assert code == 0, err
    assert [u["frame"] for u in json.loads(out)["untrusted"]] == [str(frames / "room.jpg")]
    code, _, err = cli("eval", frames, "--no-dark", "--out", tmp_path / "r2.jsonl")  # the shipped profile's rim
    assert code == 2 and "shows the mirror's rim" in err and err.count("\n") == 1


def test_every_camera_s_rendered_dark_room_frame_is_trusted(cli, tmp_path):
    from stcvision.sim_camera.scene import EXAMPLE_SCENE

    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(EXAMPLE_SCENE))
    for cam in ("webcam", "lowlight", "cooled"):
        assert cli("render", "--scene", scene, "--camera", cam, "--out", tmp_path / cam)[0] == 0
        assert (
            pipeline_json(cli, tmp_path / cam / "frame.png", "--dark", tmp_path / cam / "dark.png")["untrusted"] == ""
        )


def test_calibrate_dark_takes_only_dark_frames_of_one_kind(cli, rendered, tmp_path):
    import cv2

    room_png = tmp_path / "room.png"
    cv2.imwrite(str(room_png), cv2.imread(str(ROOM)))
    out = tmp_path / "dark.png"
    for frames, says in [
        ([ROOM], "taken losslessly"),
        ([room_png], "it shows a scene"),
        ([rendered / "webcam" / "lights_on.png"], "it shows a scene"),
        ([rendered / "webcam" / "dark.png", rendered / "cooled" / "dark.png"], "8-bit"),
    ]:
        code, _, err = cli("calibrate", "dark", *frames, "--out", out)
        assert code == 2 and says in err and err.count("\n") == 1, err
    bright = cv2.imread(str(rendered / "webcam" / "dark.png"), cv2.IMREAD_UNCHANGED).astype("int32") + 12
    other = tmp_path / "other.png"
    cv2.imwrite(str(other), bright.clip(0, 255).astype("uint8"))  # the same pattern at another gain's level
    code, _, err = cli("calibrate", "dark", rendered / "webcam" / "dark.png", other, "--out", out)
    assert code == 2 and "typical levels" in err
    assert cli("calibrate", "dark", rendered / "webcam" / "dark.png", "--out", out)[0] == 0


def test_a_dark_frame_of_another_camera_is_untrusted(cli, tmp_path):
    """The webcam's dark frame holds its hot pixels; a frame of another webcam (another fixed
    pattern) shows none of them, a frame of its own all."""
    from stcvision.sim_camera.scene import EXAMPLE_SCENE

    for seed in (0, 7):
        scene = tmp_path / f"scene{seed}.json"
        scene.write_text(json.dumps({**EXAMPLE_SCENE, "pattern_seed": seed}))
        assert cli("render", "--scene", scene, "--camera", "webcam", "--out", tmp_path / f"cam{seed}")[0] == 0
    own = pipeline_json(cli, tmp_path / "cam0" / "frame.png", "--dark", tmp_path / "cam0" / "dark.png")
    other = pipeline_json(cli, tmp_path / "cam0" / "frame.png", "--dark", tmp_path / "cam7" / "dark.png")
    assert own["untrusted"] == "" and "another camera" in other["untrusted"]


def test_eval_counts_the_frames_it_does_not_trust(cli, room_profile, tmp_path):
    """A labelled folder holding the real room photograph: scored, and counted untrusted."""
    d = tmp_path / "labelled"
    d.mkdir()
    (d / "room.jpg").write_bytes(ROOM.read_bytes())
    (d / "labels.jsonl").write_text(json.dumps({"frame": "room.jpg", "boxes": {"1": False}}) + "\n")
    code, out, err = cli("eval", d, "--no-dark", "--profile", room_profile, "--json")
    assert code == 0, err
    r = json.loads(out)
    assert r["frames_untrusted"] == 1 and "lit frame" in r["untrusted"][0]["reason"]
