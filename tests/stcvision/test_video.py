"""stcvision pipeline --video: a lossless video of rendered frames gives exactly the PNG frames'
results, each line with the container's timestamp and a summary line at the end; a lossy one is
warned about; frames of the wrong size are refused as PNGs are."""

import json

import cv2
import numpy as np
import pytest

from stcvision.sim_camera.scene import EXAMPLE_SCENE, Scene


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """Four dark-room frames (different noise draws and times) and their dark frame."""
    d = tmp_path_factory.mktemp("video")
    scene = Scene.from_dict(EXAMPLE_SCENE)
    cam = scene.camera()
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(7).spawn(5)]
    frames = []
    for i in range(4):
        f = cam.render(
            scene.pose,
            rng=rngs[i],
            t_s=scene.t_s + 5.0 * i,
            phosphor=scene.phosphor,
            red_lights_m=scene.red_lights_m,
            board=scene.board,
        ).image
        cv2.imwrite(str(d / f"f{i}.png"), f)
        frames.append(f)
    cv2.imwrite(str(d / "dark.png"), cam.median_dark(4, rng=rngs[4]))
    return d, frames


def _write_video(path, frames, fourcc):
    h, w = frames[0].shape[:2]
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), 10, (w, h))
    assert vw.isOpened(), f"this OpenCV build cannot write {fourcc}"
    for f in frames:
        vw.write(f)
    vw.release()


@pytest.mark.parametrize("fourcc, suffix", [("FFV1", ".mkv"), ("MPNG", ".avi")])
def test_lossless_video_gives_the_png_frames_results(rendered, tmp_path, cli, fourcc, suffix, results_only):
    d, frames = rendered
    video = tmp_path / f"run{suffix}"
    _write_video(video, frames, fourcc)
    code, out, err = cli("pipeline", *[d / f"f{i}.png" for i in range(4)], "--dark", d / "dark.png", "--json")
    assert code == 0, err
    png = json.loads(out)["frames"]
    code, out, err = cli("pipeline", "--video", video, "--dark", d / "dark.png", "--json")
    assert code == 0, err
    assert "warning" not in err
    *lines, summary = [json.loads(ln) for ln in out.splitlines()]
    assert [ln["frame"] for ln in lines] == [0, 1, 2, 3]
    # the container's timestamps: 10 frames a second
    assert [ln["t_s"] for ln in lines] == [0.0, 0.1, 0.2, 0.3]
    assert summary["summary"]["frames"] == 4 and summary["summary"]["clock"] == "container"
    assert (summary["summary"]["first_t_s"], summary["summary"]["last_t_s"]) == (0.0, 0.3)
    assert [results_only(x) for x in lines] == [results_only(x) for x in png]
    assert sum(len(x["dots"]) for x in lines) > 0
    # --start, --frames, --every pick frames 1 and 3
    code, out, err = cli(
        "pipeline", "--video", video, "--dark", d / "dark.png", "--json", "--start", "1", "--every", "2"
    )
    assert code == 0, err
    lines = [json.loads(ln) for ln in out.splitlines()][:-1]
    assert [ln["frame"] for ln in lines] == [1, 3] and [ln["t_s"] for ln in lines] == [0.1, 0.3]
    assert [results_only(x) for x in lines] == [results_only(png[1]), results_only(png[3])]
    code, out, _ = cli("pipeline", "--video", video, "--dark", d / "dark.png", "--frames", "1")
    assert code == 0 and len(out.splitlines()) == 2 and out.startswith("0 t=0.000000 s: ")
    assert out.splitlines()[1].startswith(f"1 frame of video {video}, t 0.000000 .. 0.000000 s (container)")


def test_lossy_video_is_warned_and_wrong_size_refused(rendered, tmp_path, cli):
    d, frames = rendered
    video = tmp_path / "run.avi"
    _write_video(video, frames[:2], "MJPG")
    code, out, err = cli("pipeline", "--video", video, "--dark", d / "dark.png", "--json")
    assert code == 0
    assert "MJPG" in err and "lossy" in err and "faint" in err and "hot pixels" in err
    small = tmp_path / "small.mkv"
    _write_video(small, [cv2.resize(f, (320, 240)) for f in frames[:1]], "FFV1")
    code, out, err = cli("pipeline", "--video", small, "--dark", d / "dark.png")
    assert code == 2 and "320x240" in err and err.count("\n") == 1
    # not a video, a missing one, frames and a video at once, --start past the end
    video = tmp_path / "two.mkv"
    _write_video(video, frames[:2], "FFV1")
    (tmp_path / "x.mkv").write_text("not a video")
    for argv, words in (
        (["--video", tmp_path / "x.mkv"], "cannot be opened"),
        (["--video", tmp_path / "none.mkv"], "does not exist"),
        ([d / "f0.png", "--video", video], "not both"),
        (["--video", video, "--start", "99"], "has 2 frames"),
        ([d / "f0.png", "--every", "2"], "--video"),
    ):
        code, _, err = cli("pipeline", *argv, "--dark", d / "dark.png")
        assert code == 2 and words in err and err.count("\n") == 1, err


def test_a_camera_that_is_not_there_is_one_line(rendered, cli):
    d, _ = rendered
    code, out, err = cli("pipeline", "--device", "97", "--dark", d / "dark.png")
    assert code == 2 and out == "" and "camera device 97 cannot be opened" in err and err.count("\n") == 1


def test_a_live_cameras_frames_carry_this_computers_clock(rendered, tmp_path, cli, monkeypatch):
    """A camera's frames are timed by this computer's clock as they arrive (a lossless video
    stands in for the camera: no camera is attached where the tests run)."""
    import time

    import stcvision.video as video

    d, frames = rendered
    _write_video(tmp_path / "cam.mkv", frames[:2], "FFV1")

    def fake_device(index):
        src = video.open_video(tmp_path / "cam.mkv")
        src.live, src.name = True, f"camera device {index}"
        return src

    monkeypatch.setattr(video, "open_device", fake_device)
    before = time.time()
    code, out, err = cli("pipeline", "--device", "0", "--dark", d / "dark.png", "--json")
    after = time.time()
    assert code == 0, err
    *lines, summary = [json.loads(ln) for ln in out.splitlines()]
    assert [ln["frame"] for ln in lines] == [0, 1]
    assert before <= lines[0]["t_s"] <= lines[1]["t_s"] <= after
    assert summary["summary"]["clock"] == "computer clock" and summary["summary"]["frames"] == 2
