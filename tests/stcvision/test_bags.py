"""stcvision pipeline --bag: ROS 1 bags, ROS 2 bags (SQLite and MCAP storage) and MCAP files
written by the libraries robots record with (rosbags' writers, mcap's ROS 2 writer), each with a
second, non-image topic, give exactly the PNG frames' results, each line with the header stamp
written; every image encoding read; bad input is one line."""

import json
import os
import signal
import subprocess
import sys
import time

import cv2
import numpy as np
import pytest

from stcvision.sim_camera.scene import EXAMPLE_SCENE, Scene

TOPIC = "/camera/image_raw"
#: the first frame's header stamp (s) and the stamps' spacing (ns): not whole seconds, so that a
#: stamp read as its seconds alone, or rounded through a float, shows
STAMP0_S, STEP_NS = 1_700_000_000, 250_000_007

# the message definitions a ROS 2 recorder stores in an MCAP file, as ros2 bag writes them
_SEP = "=" * 80 + "\n"
_HEADER_DEF = f"{_SEP}MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
_TIME_DEF = f"{_SEP}MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
IMAGE_DEF = (
    "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\n"
    "uint8[] data\n" + _HEADER_DEF + _TIME_DEF
)
STRING_DEF = "string data\n"


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """Four dark-room frames (different noise draws and times) and their dark frame."""
    d = tmp_path_factory.mktemp("bags")
    scene = Scene.from_dict(EXAMPLE_SCENE)
    cam = scene.camera()
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(11).spawn(5)]
    frames = [
        cam.render(
            scene.pose,
            rng=rngs[i],
            t_s=scene.t_s + 5.0 * i,
            phosphor=scene.phosphor,
            red_lights_m=scene.red_lights_m,
            board=scene.board,
        ).image
        for i in range(4)
    ]
    return d, frames, cam.median_dark(4, rng=rngs[4])


def _stamp_ns(i: int) -> int:
    return STAMP0_S * 1_000_000_000 + i * STEP_NS


def _mosaic(bgr, pattern: str):
    """A Bayer sensor's raw image of ``bgr``: ``pattern`` names the colours of the 2x2 tile's
    pixels row by row (``rggb``: red top left)."""
    out = np.zeros(bgr.shape[:2], bgr.dtype)
    ch = {"r": 2, "g": 1, "b": 0}
    for k, c in enumerate(pattern):
        y, x = divmod(k, 2)
        out[y::2, x::2] = bgr[y::2, x::2, ch[c]]
    return out


# encoding -> (the message's pixels from a BGR frame, the BGR frame the pipeline must see),
# the latter by OpenCV's conversions named independently of the reader's table
ENCODINGS = {
    "bgr8": (lambda f: f, lambda f: f),
    "rgb8": (lambda f: f[:, :, ::-1], lambda f: f),
    "mono8": (lambda f: f[:, :, 1], lambda f: cv2.merge([f[:, :, 1]] * 3)),
    "mono16": (
        lambda f: f[:, :, 1].astype(np.uint16) * 16,
        lambda f: cv2.merge([f[:, :, 1].astype(np.uint16) * 16] * 3),
    ),
    "bayer_rggb8": (lambda f: _mosaic(f, "rggb"), lambda f: cv2.cvtColor(_mosaic(f, "rggb"), cv2.COLOR_BayerRGGB2BGR)),
    "bayer_gbrg16": (
        lambda f: _mosaic(f.astype(np.uint16) * 16, "gbrg"),
        lambda f: cv2.cvtColor(_mosaic(f.astype(np.uint16) * 16, "gbrg"), cv2.COLOR_BayerGBRG2BGR),
    ),
}


def _raw_fields(pixels, encoding: str, bigendian: bool = False):
    h, w = pixels.shape[:2]
    dt = pixels.dtype.newbyteorder(">" if bigendian else "<")
    data = np.ascontiguousarray(pixels.astype(dt)).view(np.uint8).reshape(-1)
    return {
        "height": h,
        "width": w,
        "encoding": encoding,
        "is_bigendian": int(bigendian),
        "step": data.size // h,
        "data": data,
    }


def _rosbags_messages(ts, images, *, compressed: str = "", encoding: str = "bgr8", bigendian=False):
    """(topic, msgtype, log time, message) of the image topic and a /status string topic."""
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    String = ts.types["std_msgs/msg/String"]
    out = []
    for i, pixels in enumerate(images):
        ns = _stamp_ns(i)
        sec, nsec = divmod(ns, 1_000_000_000)
        hdr = {"stamp": Time(sec=sec, nanosec=nsec), "frame_id": "camera"}
        if "seq" in Header.__dataclass_fields__:  # ROS 1's header counts its messages
            hdr["seq"] = i
        if compressed:
            Msg = ts.types["sensor_msgs/msg/CompressedImage"]
            ok, data = cv2.imencode(f".{compressed}", pixels)
            msg = Msg(header=Header(**hdr), format=f"bgr8; {compressed} compressed bgr8", data=data.reshape(-1))
        else:
            Msg = ts.types["sensor_msgs/msg/Image"]
            msg = Msg(header=Header(**hdr), **_raw_fields(pixels, encoding, bigendian))
        out.append(("/status", String.__msgtype__, ns, String(data=f"frame {i}")))  # before: it starts the bag
        out.append((TOPIC, Msg.__msgtype__, ns + 1000, msg))
    return out


def write_ros1(path, images, **kw):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    with Writer(path) as w:
        conns = {}
        for topic, msgtype, t, msg in _rosbags_messages(ts, images, **kw):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=ts)
            w.write(conns[topic], t, ts.serialize_ros1(msg, msgtype))
    return path


def write_ros2(path, images, storage: str = "sqlite3", **kw):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    plugin = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage]
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conns = {}
        for topic, msgtype, t, msg in _rosbags_messages(ts, images, **kw):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=ts)
            w.write(conns[topic], t, ts.serialize_cdr(msg, msgtype))
    return path


def write_mcap(path, images, encoding: str = "bgr8"):
    """An MCAP file as a ROS 2 recorder writes it, through mcap's own ROS 2 writer."""
    from mcap_ros2.writer import Writer

    with open(path, "wb") as fh:
        w = Writer(fh)
        image = w.register_msgdef("sensor_msgs/msg/Image", IMAGE_DEF)
        string = w.register_msgdef("std_msgs/msg/String", STRING_DEF)
        for i, pixels in enumerate(images):
            ns = _stamp_ns(i)
            sec, nsec = divmod(ns, 1_000_000_000)
            w.write_message("/status", string, {"data": f"frame {i}"}, log_time=ns)
            fields = _raw_fields(pixels, encoding)
            fields["data"] = fields["data"].tobytes()
            msg = {"header": {"stamp": {"sec": sec, "nanosec": nsec}, "frame_id": "camera"}, **fields}
            w.write_message(TOPIC, image, msg, log_time=ns + 1000)
        w.finish()
    return path


def _png_results(cli, d, frames, dark, tag):
    """The pipeline's results on ``frames`` written as PNG files."""
    paths = []
    for i, f in enumerate(frames):
        paths.append(d / f"{tag}_{i}.png")
        cv2.imwrite(str(paths[-1]), f)
    cv2.imwrite(str(d / f"{tag}_dark.png"), dark)
    code, out, err = cli("pipeline", *paths, "--dark", d / f"{tag}_dark.png", "--json")
    assert code == 0, err
    r = json.loads(out)
    assert r["clock"] == "order" and [f["t_s"] for f in r["frames"]] == [float(i) for i in range(len(frames))]
    return r["frames"], d / f"{tag}_dark.png"


def _bag_lines(cli, bag, dark, *extra):
    code, out, err = cli("pipeline", "--bag", bag, "--topic", TOPIC, "--dark", dark, "--json", *extra)
    assert code == 0, err
    lines = [json.loads(ln) for ln in out.splitlines()]
    assert "summary" in lines[-1]
    return lines[:-1], lines[-1]["summary"], err


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["ros1", "ros2-sqlite3", "ros2-mcap", "mcap"])
def test_a_recording_gives_the_png_frames_results_and_stamps(rendered, tmp_path, cli, kind, results_only):
    d, frames, dark = rendered
    png, dark_path = _png_results(cli, tmp_path, frames, dark, "bgr")
    bag = {
        "ros1": lambda: write_ros1(tmp_path / "run.bag", frames),
        "ros2-sqlite3": lambda: write_ros2(tmp_path / "run", frames),
        "ros2-mcap": lambda: write_ros2(tmp_path / "run", frames, storage="mcap"),
        "mcap": lambda: write_mcap(tmp_path / "run.mcap", frames),
    }[kind]()
    lines, summary, err = _bag_lines(cli, bag, dark_path)
    assert "warning" not in err
    assert [ln["frame"] for ln in lines] == [0, 1, 2, 3]
    assert [ln["stamp_ns"] for ln in lines] == [_stamp_ns(i) for i in range(4)]
    assert [ln["t_s"] for ln in lines] == [_stamp_ns(i) / 10**9 for i in range(4)]
    assert [results_only(x) for x in lines] == [results_only(x) for x in png]
    assert sum(len(x["dots"]) for x in lines) > 0
    assert summary["frames"] == 4 and summary["clock"] == "header stamp"
    assert summary["first_t_s"] == _stamp_ns(0) / 10**9 and summary["last_t_s"] == _stamp_ns(3) / 10**9
    assert summary["dots"] == sum(len(x["dots"]) for x in png)
    # --start/--end: seconds from the recording's start on its own clock (the /status message
    # starts it, 1 us before the first image): the images recorded 0.25 and 0.5 s later
    lines, summary, _ = _bag_lines(cli, bag, dark_path, "--start", "0.2", "--end", "0.6")
    assert [ln["frame"] for ln in lines] == [1, 2] and summary["frames"] == 2
    assert [ln["stamp_ns"] for ln in lines] == [_stamp_ns(1), _stamp_ns(2)]
    lines, _, _ = _bag_lines(cli, bag, dark_path, "--every", "2", "--frames", "1")
    assert [ln["frame"] for ln in lines] == [0]
    # the text lines carry the exact stamp, and a summary ends them
    code, out, err = cli("pipeline", "--bag", bag, "--topic", TOPIC, "--dark", dark_path)
    assert code == 0, err
    out = out.splitlines()
    assert out[0].startswith("0 t=1700000000.000000000 s: ") and out[1].startswith("1 t=1700000000.250000007 s: ")
    assert out[-1].startswith(f"4 frames of bag {bag}, t 1700000000.000000 .. 1700000000.750000 s (header stamp)")


@pytest.mark.parametrize("encoding", sorted(ENCODINGS))
def test_every_encoding_reads_as_its_bgr_frame(rendered, tmp_path, cli, encoding, results_only):
    d, frames, dark = rendered
    to_msg, to_bgr = ENCODINGS[encoding]
    frames = frames[:2]
    png, dark_path = _png_results(cli, tmp_path, [to_bgr(f) for f in frames], to_bgr(dark), encoding)
    bag = write_ros2(tmp_path / "run", [to_msg(f) for f in frames], storage="mcap", encoding=encoding)
    lines, _, err = _bag_lines(cli, bag, dark_path)
    assert [results_only(x) for x in lines] == [results_only(x) for x in png]
    assert ("no colour" in err) == encoding.startswith("mono"), err


def test_compressed_and_big_endian_images(rendered, tmp_path, cli, results_only):
    d, frames, dark = rendered
    frames = frames[:2]
    png, dark_path = _png_results(cli, tmp_path, frames, dark, "c")
    bag = write_ros1(tmp_path / "png.bag", frames, compressed="png")
    lines, _, err = _bag_lines(cli, bag, dark_path)
    assert [results_only(x) for x in lines] == [results_only(x) for x in png] and "warning" not in err
    f16 = [f.astype(np.uint16) * 16 for f in frames]
    png, dark_path = _png_results(cli, tmp_path, f16, dark.astype(np.uint16) * 16, "be")
    bag = write_ros2(tmp_path / "be", f16, encoding="bgr16", bigendian=True)
    lines, _, _ = _bag_lines(cli, bag, dark_path)
    assert [results_only(x) for x in lines] == [results_only(x) for x in png]


def test_bayer_patterns_come_back_in_their_colours():
    from stcvision.bags import image_from_message

    class Msg:
        pass

    bgr = np.zeros((8, 8, 3), np.uint8)
    bgr[..., 2] = 200  # red
    for pattern in ("rggb", "bggr", "gbrg", "grbg"):
        msg = Msg()
        for k, v in _raw_fields(_mosaic(bgr, pattern), f"bayer_{pattern}8").items():
            setattr(msg, k, v)
        out = image_from_message(msg, "sensor_msgs/msg/Image")
        assert out.shape == (8, 8, 3) and (out[2:6, 2:6] == (0, 0, 200)).all(), pattern


def test_bad_recordings_and_topics_are_one_line(rendered, tmp_path, cli, capsys):
    d, frames, dark = rendered
    cv2.imwrite(str(tmp_path / "dark.png"), dark)
    dark_path = tmp_path / "dark.png"
    bag = write_ros1(tmp_path / "run.bag", frames[:1])
    mcap = write_mcap(tmp_path / "run.mcap", frames[:1])
    (tmp_path / "junk.bag").write_bytes(b"#ROSBAG V2.0\n" + os.urandom(300))
    (tmp_path / "junk.mcap").write_bytes(b"\x89MCAP0\r\n" + os.urandom(300))
    (tmp_path / "cut.mcap").write_bytes(mcap.read_bytes()[: mcap.stat().st_size // 2])
    (tmp_path / "empty").mkdir()
    (tmp_path / "x.txt").write_text("x")
    for argv, words in (
        (["--bag", bag, "--topic", "/nothing"], f"has no topic /nothing; image topics present: {TOPIC}"),
        (
            ["--bag", mcap, "--topic", "/status"],
            f"/status is std_msgs/msg/String, not an image; image topics present: {TOPIC}",
        ),
        (["--bag", tmp_path / "junk.bag", "--topic", TOPIC], "cannot be read"),
        (["--bag", tmp_path / "junk.mcap", "--topic", TOPIC], "cannot be read"),
        (["--bag", tmp_path / "cut.mcap", "--topic", TOPIC], "cannot be read"),
        (["--bag", tmp_path / "empty", "--topic", TOPIC], "without metadata.yaml"),
        (["--bag", tmp_path / "none.bag", "--topic", TOPIC], "does not exist"),
        (["--bag", tmp_path / "x.txt", "--topic", TOPIC], "expected a ROS 1 bag"),
        (["--bag", bag], "--topic"),
        (["--bag", bag, "--topic", TOPIC, "--start", "5"], "no frame read"),
        (["--bag", bag, "--topic", TOPIC, "--start", "2", "--end", "1"], "must be after --start"),
        (["--bag", bag, "--topic", TOPIC, "--start", "-1"], "--start"),
        (["--bag", bag, "--topic", TOPIC, "--frames", "99999999"], "cap"),
        (["--video", bag, "--end", "1"], "--end applies to --bag"),
        (["--video", bag, "--start", "1.5"], "whole number"),
        ([tmp_path / "dark.png", "--bag", bag, "--topic", TOPIC], "not both"),
    ):
        try:
            code, out, err = cli("pipeline", *argv, "--dark", dark_path)
        except SystemExit as exc:  # argparse's own refusal of a flag's value
            code, err = exc.code, capsys.readouterr().err
        assert code == 2 and words in err and err.count("\n") == 1, (argv, err)
        assert "Traceback" not in err


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_a_signal_stops_a_bag_run_within_two_seconds(rendered, tmp_path, sig):
    d, frames, dark = rendered
    cv2.imwrite(str(tmp_path / "dark.png"), dark)
    bag = write_ros1(tmp_path / "long.bag", frames[:1] * 400, compressed="png")
    argv = [sys.executable, "-m", "stcvision", "pipeline", "--bag", str(bag), "--topic", TOPIC]
    proc = subprocess.Popen(
        [*argv, "--dark", str(tmp_path / "dark.png"), "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout.readline().startswith("{")  # running: frames stream out
        proc.send_signal(sig)
        t0 = time.monotonic()
        code = proc.wait(timeout=10)
        took = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert code == 128 + sig and took < 2.0, (code, took)
    err = proc.stderr.read()
    assert "interrupted" in err and "Traceback" not in err


def test_eval_of_a_recording_writes_the_folders_results_with_stamps(rendered, tmp_path, cli, results_only):
    d, frames, dark = rendered
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, f in enumerate(frames):
        cv2.imwrite(str(folder / f"f{i}.png"), f)
    cv2.imwrite(str(tmp_path / "dark.png"), dark)
    code, out, err = cli("eval", folder, "--dark", tmp_path / "dark.png", "--out", tmp_path / "png.jsonl", "--json")
    assert code == 0, err
    png = [json.loads(ln) for ln in (tmp_path / "png.jsonl").read_text().splitlines()]
    bag = write_ros1(tmp_path / "run.bag", frames)
    code, out, err = cli("eval", "--bag", bag, "--topic", TOPIC, "--dark", tmp_path / "dark.png", "--json")
    assert code == 0, err
    r = json.loads(out)
    assert r["frames"] == 4 and r["results"] == str(tmp_path / "run-results.jsonl") and r["accuracy"] is None
    lines = [json.loads(ln) for ln in (tmp_path / "run-results.jsonl").read_text().splitlines()]
    assert [ln["frame"] for ln in lines] == [0, 1, 2, 3]
    assert [ln["stamp_ns"] for ln in lines] == [_stamp_ns(i) for i in range(4)]
    assert [results_only(x) for x in lines] == [results_only(x) for x in png]
    # a second run does not overwrite the results without --force; a topic that is no image is one line
    for argv, words in (
        (["--bag", bag, "--topic", TOPIC], "refusing to overwrite"),
        (["--bag", bag, "--topic", "/status", "--force"], "not an image; image topics present"),
        (["--bag", bag], "go together"),
    ):
        code, _, err = cli("eval", *argv, "--dark", tmp_path / "dark.png")
        assert code == 2 and words in err and err.count("\n") == 1, err


def test_the_frame_cap_and_a_jpeg_topic_are_said(rendered, tmp_path, cli, monkeypatch):
    import stcvision.limits

    d, frames, dark = rendered
    cv2.imwrite(str(tmp_path / "dark.png"), dark)
    bag = write_ros1(tmp_path / "jpeg.bag", frames, compressed="jpg")
    monkeypatch.setattr(stcvision.limits, "MAX_VIDEO_FRAMES", 2)
    lines, summary, err = _bag_lines(cli, bag, tmp_path / "dark.png")
    assert len(lines) == 2 and summary["frames"] == 2
    assert "has 4 frames on /camera/image_raw; reading the first 2 (the cap of one run)" in err
    assert "JPEG" in err and "lossy" in err


def test_calibrate_dark_from_a_recording_equals_the_files(tmp_path, cli):
    cam = Scene.from_dict(EXAMPLE_SCENE).camera()
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(5).spawn(3)]
    darks = [cam.dark_frame(rng=r) for r in rngs]
    for i, f in enumerate(darks):
        cv2.imwrite(str(tmp_path / f"d{i}.png"), f)
    code, _, err = cli("calibrate", "dark", *[tmp_path / f"d{i}.png" for i in range(3)], "--out", tmp_path / "a.png")
    assert code == 0, err
    bag = write_ros2(tmp_path / "darks", darks, storage="mcap")
    code, out, err = cli("calibrate", "dark", "--bag", bag, "--topic", TOPIC, "--out", tmp_path / "b.png", "--json")
    assert code == 0, err
    assert json.loads(out)["frames"] == 3
    a, b = (cv2.imread(str(tmp_path / n), cv2.IMREAD_UNCHANGED) for n in ("a.png", "b.png"))
    assert np.array_equal(a, b)
    # a window: the frames recorded 0.25 and 0.5 s after the recording's start
    code, out, err = cli(
        "calibrate", "dark", "--bag", bag, "--topic", TOPIC, "--start", "0.2", "--out", tmp_path / "c.png", "--json"
    )
    assert code == 0 and json.loads(out)["frames"] == 2, err
    jpeg = write_ros1(tmp_path / "jpeg.bag", darks, compressed="jpg")
    for argv, words in (
        (["--bag", jpeg, "--topic", TOPIC], "JPEG-compressed"),
        (["--bag", bag, "--topic", "/status"], "not an image"),
        (["--bag", bag], "go together"),
        ([tmp_path / "d0.png", "--bag", bag, "--topic", TOPIC], "one of them"),
        (["--bag", bag, "--topic", TOPIC, "--start", "9"], "no frame"),
    ):
        code, _, err = cli("calibrate", "dark", *argv, "--out", tmp_path / "x.png")
        assert code == 2 and words in err and err.count("\n") == 1, (argv, err)
    assert not (tmp_path / "x.png").exists()


@pytest.mark.slow
def test_calibrate_reads_its_one_frame_from_a_recording(tmp_path, cli):
    """rim, transform and import --lights-on read a recording's message as they read a PNG of it:
    the one whose header stamp is --stamp, or the first; the same results, the same profiles
    (their provenance names the recording, the topic and the stamp); bad choices are one line."""
    from stcvision.bags import stamp_text
    from stcvision.calibration.defaults import calibration_frame
    from stcvision.calibration.profiles import default_profile_path
    from stcvision.profile import Profile
    from stcvision.sim_camera.camera import SyntheticCamera

    lights = calibration_frame(SyntheticCamera())
    moved = np.roll(lights, 6, axis=1)  # another frame first: the rim 6 px to the right
    cv2.imwrite(str(tmp_path / "lights.png"), lights)
    cv2.imwrite(str(tmp_path / "moved.png"), moved)
    bag = write_ros2(tmp_path / "cal", [moved, lights], storage="mcap")
    chosen = ["--bag", bag, "--topic", TOPIC, "--stamp", stamp_text(_stamp_ns(1))]

    def rim(*argv):
        code, out, err = cli("calibrate", "rim", *argv, "--json")
        assert code == 0, err
        return {k: v for k, v in json.loads(out).items() if k != "frame"}

    assert rim(*chosen) == rim(tmp_path / "lights.png")
    assert rim("--bag", bag, "--topic", TOPIC) == rim(tmp_path / "moved.png") != rim(tmp_path / "lights.png")

    def profile(step, *argv, name):
        out = tmp_path / name
        code, _, err = cli("calibrate", step, *argv, "--out", out, *(["--yes"] if step == "transform" else []))
        assert code == 0, err
        d = Profile.load(out).to_dict()
        return {k: v for k, v in d.items() if k != "provenance"}, d["provenance"]

    a, _ = profile("transform", tmp_path / "lights.png", name="a.json")
    b, prov = profile("transform", *chosen, name="b.json")
    assert a == b and TOPIC in prov["frame"] and stamp_text(_stamp_ns(1)) in prov["frame"]
    code, _, err = cli(
        "calibrate", "export", default_profile_path(), "--format", "ocamcalib", "--out", tmp_path / "c.txt"
    )
    assert code == 0, err
    h = ["--viewpoint-height-m", "0.3"]
    a, _ = profile("import", tmp_path / "c.txt", *h, "--lights-on", tmp_path / "lights.png", name="c.json")
    b, prov = profile("import", tmp_path / "c.txt", *h, *chosen, name="d.json")
    assert a == b and TOPIC in prov["lights_on_frame"]
    for argv, words in (
        (["--bag", bag, "--topic", TOPIC, "--stamp", "1700000000.1"], "no message on /camera/image_raw has header"),
        (["--bag", bag, "--topic", TOPIC, "--stamp", "soon"], "not a number of seconds"),
        ([tmp_path / "lights.png", "--bag", bag, "--topic", TOPIC], "not both"),
        ([tmp_path / "lights.png", "--stamp", "1"], "go with --bag"),
        (["--bag", bag, "--topic", "/status"], "not an image"),
        ([], "give FRAME or --bag"),
    ):
        code, _, err = cli("calibrate", "rim", *argv)
        assert code == 2 and words in err and err.count("\n") == 1, (argv, err)
