"""Rerun recordings: streamed to their file as they are logged, kept whole when a signal stops
the run (rerun's own verifier accepts them and they hold every frame logged before the signal),
and opened with a default layout read back from the file's blueprint."""

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from stcvision.sim_camera.scene import EXAMPLE_SCENE, Scene

ROOT = Path(__file__).resolve().parents[2]
#: frames of the video: far more than the run reads before the signal (it is sent after READ_BEFORE lines)
VIDEO_FRAMES = 60
READ_BEFORE = 3


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    """A lossless video of one rendered frame repeated, and its dark frame."""
    d = tmp_path_factory.mktemp("rrvideo")
    scene = Scene.from_dict(EXAMPLE_SCENE)
    cam = scene.camera()
    rng = np.random.default_rng(3)
    frame = cam.render(scene.pose, rng=rng, t_s=scene.t_s, phosphor=scene.phosphor,
                       red_lights_m=scene.red_lights_m, board=scene.board).image  # fmt: skip
    cv2.imwrite(str(d / "dark.png"), cam.median_dark(4, rng=rng))
    h, w = frame.shape[:2]
    vw = cv2.VideoWriter(str(d / "run.mkv"), cv2.VideoWriter_fourcc(*"FFV1"), 10, (w, h))
    for _ in range(VIDEO_FRAMES):
        vw.write(frame)
    vw.release()
    return d


def _rerun() -> str:
    rerun = shutil.which("rerun", path=str(Path(sys.executable).parent))
    assert rerun, "the rerun CLI ships with rerun-sdk"
    return rerun


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_keeps_the_recording_with_every_frame_logged_before_it(video, tmp_path, rrd_contents, signum):
    """pipeline --video --rrd stopped by Ctrl-C (SIGTERM) once it printed READ_BEFORE frames
    (a frame's line is printed after the frame is logged): exit 130 (143) with one line that
    says the recording was kept; the file verifies, holds those frames at least, and is named
    as interrupted; no temporary is left, and its mode is the umask's."""
    rrd = tmp_path / "run.rrd"
    argv = ["pipeline", "--video", video / "run.mkv", "--dark", video / "dark.png", "--rrd", rrd, "--json"]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    p = subprocess.Popen([sys.executable, "-m", "stcvision", *map(str, argv)], env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    try:
        printed = [p.stdout.readline() for _ in range(READ_BEFORE)]
        assert all(line.startswith("{") for line in printed), p.stderr.read()
        p.send_signal(signum)
        rest = p.stdout.read()
        assert p.wait(timeout=120) == 128 + signum
    finally:
        p.kill()
    assert '"summary"' not in rest, "the run ended before the signal"
    err = p.stderr.read()
    assert err.count("\n") == 1 and f"interrupted; kept {rrd}" in err
    assert subprocess.run([_rerun(), "rrd", "verify", str(rrd)], capture_output=True).returncode == 0
    contents = rrd_contents(rrd)
    frames = contents.times("/raw", "frame")
    assert set(range(READ_BEFORE)) <= set(frames) and len(frames) < VIDEO_FRAMES
    assert contents.times("/ground/boxes", "frame")[:READ_BEFORE] == list(range(READ_BEFORE))
    name = signal.Signals(signum).name
    props = contents.properties()
    assert props["/__properties:RecordingInfo:name"] == [f"run.rrd (interrupted by {name})"]
    assert props["/__properties/interrupted:signal"] == [name]
    assert sorted(f.name for f in tmp_path.iterdir()) == ["run.rrd"]
    assert rrd.stat().st_mode & 0o777 == 0o666 & ~_umask()


def test_a_finished_recording_opens_with_the_pipelines_layout(video, tmp_path, cli, rrd_contents):
    """The default blueprint travels in the file: the raw frame, the ground view (cells, boxes,
    dots), the channels, the observation and the timings, the time panel open on ``frame``;
    the recording is not named as interrupted."""
    rrd = tmp_path / "run.rrd"
    code, _, err = cli("pipeline", "--video", video / "run.mkv", "--frames", "2", "--dark", video / "dark.png",
                       "--rrd", rrd)  # fmt: skip
    assert code == 0, err
    contents = rrd_contents(rrd)
    views = contents.views()
    assert ("2D", "raw frame", "raw") in views and ("2D", "ground view", "ground") in views
    assert ("TextDocument", "observation", "observation") in views and ("TimeSeries", "stage ms", "timing") in views
    assert contents.time_panel() == {"state": 3, "timeline": "frame"}  # 3: expanded (rerun's PanelState)
    assert contents.properties()["/__properties:RecordingInfo:name"] == ["run.rrd"]
    assert contents.times("/raw", "frame") == [0, 1]


def test_a_signal_a_library_wrapped_in_another_error_still_keeps_the_recording(tmp_path):
    """A SIGTERM that lands inside code which re-raises it as another error (an import's
    dataclass machinery, say) ends the recording as a signal does: kept, named interrupted;
    an error with no signal behind it removes the recording."""
    import rerun as rr

    from stcvision.errors import Terminated
    from stcvision.fileio import kept_partial, new_run
    from stcvision.rr import RecordingFile

    new_run()
    kept = tmp_path / "kept.rrd"
    f = RecordingFile(kept)
    f.rec.log("x", rr.Scalars(1.0))
    try:
        try:
            raise Terminated(signal.SIGTERM)
        except Terminated as exc:
            raise RuntimeError("wrapped by a library") from exc
    except RuntimeError as wrapped:
        f.end(wrapped)
    assert kept.exists() and kept_partial() == [kept]
    gone = tmp_path / "gone.rrd"
    g = RecordingFile(gone)
    g.end(RuntimeError("a plain error"))
    assert not gone.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["kept.rrd"]
    new_run()


def test_a_signal_as_the_file_sink_starts_removes_the_file_it_began(tmp_path, monkeypatch):
    """A signal that lands while rerun's file sink starts (nothing recorded yet) stops the sink
    and removes its file: an interrupted run that recorded nothing leaves nothing."""
    import rerun as rr

    from stcvision.errors import Terminated
    from stcvision.fileio import kept_partial, new_run
    from stcvision.rr import RecordingFile

    def signalled(self, name, *args, **kwargs):
        raise Terminated(signal.SIGTERM)  # the signal's exception, raised right after the sink starts

    new_run()
    monkeypatch.setattr(rr.RecordingStream, "send_recording_name", signalled)
    with pytest.raises(Terminated):
        RecordingFile(tmp_path / "run.rrd")
    assert list(tmp_path.iterdir()) == [] and kept_partial() == []
    new_run()
