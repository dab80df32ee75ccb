"""``stcvision robot run`` end to end against the simulated robot on a pseudo-terminal
(``stcvision robot sim``), the protocol's frames, and every failure of the link: one line and a
safe stop, never a hang and never a move the controller did not ask for."""

import json
import subprocess
import sys
import time

import pytest
import serial

from stcvision.controllers.stc import link
from stcvision.controllers.stc.link import Link, LinkError, frame, read_frame

BOARD = ("--board", "3x3", "--seed", "4")


class _Bytes:
    """A port that returns the given bytes, a few at a time."""

    def __init__(self, data: bytes):
        self.data = data

    def read(self, n: int) -> bytes:
        got, self.data = self.data[: min(n, 3)], self.data[min(n, 3) :]
        return got


def test_a_frame_reads_back():
    f = frame(link.REQUESTS["READ"], 7, b"\x01\x02\x03")
    assert read_frame(_Bytes(f), 1.0) == (link.REQUESTS["READ"], 7, b"\x01\x02\x03")
    assert f[0] == link.SYNC and f[1] == link.VERSION and len(f) == 1 + link.HEADER + 3 + link.CRC_BYTES


@pytest.mark.parametrize(
    "damage,words",
    [
        (lambda f: f[:-1] + bytes((f[-1] ^ 0x10,)), "bad checksum"),
        (lambda f: f[:6] + f[7:], "cut short"),
        (lambda f: f[1:], "lost framing"),
        (lambda f: f[:1] + bytes((link.VERSION + 1,)) + f[2:], "protocol version"),
        (lambda f: b"", "no a frame within"),
    ],
)
def test_every_damaged_frame_is_one_line(damage, words):
    f = frame(link.REQUESTS["DRIVE"], 1, b"\x00\x00")
    with pytest.raises(LinkError) as e:
        read_frame(_Bytes(damage(f)), 0.3)
    assert words in str(e.value) and "\n" not in str(e.value)


def test_a_reply_of_the_wrong_type_is_refused():
    port = serial.serial_for_url("loop://", timeout=0.05)  # hears its own request back
    with pytest.raises(LinkError, match="the reply to HELLO is 0x01"):
        Link(port, timeout_s=0.5).request("HELLO")


@pytest.fixture
def sim():
    procs = []

    def start(*extra):
        p = subprocess.Popen([sys.executable, "-m", "stcvision", "robot", "sim", *BOARD, *extra, "--json"],
                             stdout=subprocess.PIPE, text=True)  # fmt: skip
        procs.append(p)
        return p, p.stdout.readline().strip()

    yield start
    for p in procs:
        if p.poll() is None:
            p.terminate()
        p.wait(timeout=10)


def _sim_result(p) -> dict:
    out, _ = p.communicate(timeout=10)
    return json.loads(out)


def test_robot_run_completes_the_board_as_the_loop_does(cli, sim):
    p, port = sim()
    code, out, _ = cli("robot", "run", "--port", port, "--fsm", "c", "--json")
    r = json.loads(out)
    assert code == 0 and r["complete"] and r["abort_reason"] is None
    assert r["subcells_covered"] == r["subcells_reachable"] > 4 and r["subcells_covered_more_than_once"] == 0
    robot = _sim_result(p)
    assert robot["ended"] == "stopped" and robot["carried_out"][-1] == "STOP"
    # the same tour as the closed loop on this board with the oracle's reading
    code, out, _ = cli("cover", *BOARD, "--perception", "oracle", "--json")
    loop = json.loads(out)
    assert (robot["moves"], robot["turns"], r["decisions"], r["looks"]) == (
        loop["moves"], loop["turns"], loop["decisions"], loop["looks"])  # fmt: skip
    assert (r["moves"], r["turns"]) == (loop["moves"], loop["turns"])  # the robot's odometry says so too
    assert r["robot_clock_s"] == pytest.approx(loop["sim_time_s"], abs=1e-3)


@pytest.mark.parametrize(
    "fault,words",
    [
        ("drop", ("cut short", "lost framing", "bad checksum")),
        ("corrupt", ("bad checksum",)),
        ("mute", ("never came",)),
        ("hangup", ("is gone", "never came")),
    ],
)
def test_a_broken_link_is_one_line_and_a_safe_stop(cli, sim, fault, words):
    p, port = sim("--link-fault", f"{fault}@12")
    t0 = time.monotonic()
    code, out, err = cli("robot", "run", "--port", port, "--timeout", "1", "--json")
    r = json.loads(out)
    assert code == 3 and not r["complete"] and time.monotonic() - t0 < 10
    assert any(w in r["abort_reason"] for w in words), r["abort_reason"]
    assert "\n" not in r["abort_reason"] and err == ""
    robot = _sim_result(p)
    if fault == "hangup":
        assert robot["ended"] == "hung up" and "safe_stop_failed" in r
    else:  # the robot heard the stop, and nothing after the fault but the stop
        assert robot["ended"] == "stopped" and robot["carried_out"][-1] == "STOP"
        assert len(robot["carried_out"]) == 12 + 1
    # never a move the controller did not ask for: the moves are the DRIVEs it sent
    assert robot["moves"] == robot["carried_out"].count("DRIVE")


def test_robot_run_text_output_says_how_it_stopped(cli, sim):
    _, port = sim("--link-fault", "corrupt@5")
    code, out, _ = cli("robot", "run", "--port", port, "--timeout", "1")
    assert code == 3 and "stopped: bad checksum in the reply" in out


def test_robot_run_on_a_missing_port_is_one_line(cli):
    code, _, err = cli("robot", "run", "--port", "/dev/no-such-port")
    assert code == 2 and "cannot open the port /dev/no-such-port" in err and err.count("\n") == 1


def test_robot_run_refuses_a_camera_it_cannot_read(cli, tmp_path):
    code, _, err = cli("robot", "run", "--port", "loop://", "--camera", "0")
    assert code == 2 and "calibration --profile" in err and err.count("\n") == 1
    code, _, err = cli("robot", "run", "--port", "loop://", "--camera", "0", "--profile", "x.json")
    assert code == 2 and "--no-dark" in err
    code, _, err = cli("robot", "run", "--port", "loop://", "--profile", "x.json")
    assert code == 2 and "camera on this computer" in err
    from stcvision.calibration.profiles import default_profile_path

    code, _, err = cli("robot", "run", "--port", "loop://", "--camera", str(tmp_path / "no.mkv"),
                       "--profile", default_profile_path(), "--no-dark")  # fmt: skip
    assert code == 2 and "does not exist" in err and err.count("\n") == 1


@pytest.fixture(scope="module")
def camera_videos(tmp_path_factory):
    """The example scene as a camera on the computer would film it (lossless video): five
    dark-room frames, and five lights-on frames; with the camera's dark frame."""
    import cv2

    from stcvision.cli import main
    from stcvision.sim_camera.scene import EXAMPLE_SCENE

    d = tmp_path_factory.mktemp("camera")
    (d / "scene.json").write_text(json.dumps(EXAMPLE_SCENE))
    assert main(["render", "--scene", str(d / "scene.json"), "--camera", "webcam", "--out", str(d / "r")]) == 0
    for name in ("frame", "lights_on"):
        img = cv2.imread(str(d / "r" / f"{name}.png"))
        vw = cv2.VideoWriter(str(d / f"{name}.mkv"), cv2.VideoWriter_fourcc(*"FFV1"), 10, img.shape[1::-1])
        for _ in range(5):
            vw.write(img)
        vw.release()
    return d


def test_a_camera_on_the_computer_is_read_by_the_pipeline(camera_videos):
    """Each frame of a camera here goes through the pipeline into the controller's reading."""
    from stcvision.calibration.profiles import default_profile
    from stcvision.controllers.stc.frames import stc_observation
    from stcvision.controllers.stc.fsm import initial_state
    from stcvision.controllers.stc.robot_link import CameraStop, open_pc_camera
    from stcvision.fileio import read_image
    from stcvision.pipeline import Pipeline

    dark = read_image(camera_videos / "r" / "dark.png")
    eye = open_pc_camera(str(camera_videos / "frame.mkv"), default_profile(), dark)
    res = Pipeline(default_profile(), dark=dark).process(read_image(camera_videos / "r" / "frame.png"))
    decide = initial_state()  # the first tick decides
    assert [eye.read(decide) for _ in range(5)] == [stc_observation(res.observation)] * 5
    with pytest.raises(CameraStop, match="gave no frame after 5"):
        eye.read(decide)
    eye.close()


def test_robot_run_with_a_camera_here_decides_on_its_frames_and_stops_on_an_untrusted_one(cli, sim, camera_videos):
    from stcvision.calibration.profiles import default_profile_path

    here = ("--profile", str(default_profile_path()), "--dark", str(camera_videos / "r" / "dark.png"))
    p, port = sim()
    code, out, err = cli("robot", "run", "--port", port, "--camera", camera_videos / "frame.mkv", *here, "--json")
    r = json.loads(out)
    # the video shows one cell whatever the robot does, so the controller decides on it, acts,
    # and the robot's own report (not the controller's belief) says the board is not covered
    assert code == 3 and r["decisions"] >= 1 and r["commands"] > 0 and not r["complete"], err
    assert r["subcells_covered"] < r["subcells_reachable"]
    robot = _sim_result(p)
    assert robot["carried_out"][-1] == "STOP" and "READ" not in robot["carried_out"]  # read here, not there
    p, port = sim()
    code, out, _ = cli("robot", "run", "--port", port, "--camera", camera_videos / "lights_on.mkv", *here, "--json")
    r = json.loads(out)
    assert code == 3 and r["decisions"] == r["looks"] == 0 and "cannot be trusted" in r["abort_reason"]
    assert _sim_result(p)["moves"] == 0  # no move on a reading it cannot trust (only the start's own acts)


def test_a_bad_link_fault_is_one_line(cli):
    code, _, err = cli("robot", "sim", "--link-fault", "boom@1")
    assert code == 2 and "KIND@N" in err


def test_sigterm_stops_robot_run_and_the_robot(sim):
    import signal

    p, port = sim("--board", "50x50")
    read0 = _bytes_read(p.pid)
    run = subprocess.Popen([sys.executable, "-m", "stcvision", "robot", "run", "--port", port],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)  # fmt: skip
    deadline = time.monotonic() + 60
    while _bytes_read(p.pid) < read0 + 2000 and time.monotonic() < deadline:  # driving: requests arrive
        time.sleep(0.05)
    t0 = time.monotonic()
    run.send_signal(signal.SIGTERM)
    run.wait(timeout=10)
    assert run.returncode == 143 and time.monotonic() - t0 < 2
    robot = _sim_result(p)
    assert robot["ended"] == "stopped" and robot["carried_out"][-1] == "STOP" and robot["moves"] > 0


def _bytes_read(pid: int) -> int:
    """What process ``pid`` has read so far (bytes, /proc/PID/io's rchar)."""
    with open(f"/proc/{pid}/io") as f:
        return int(next(line for line in f if line.startswith("rchar:")).split()[1])


def test_sigterm_stops_the_simulated_robot(sim):
    import signal

    p, _ = sim()
    t0 = time.monotonic()
    p.send_signal(signal.SIGTERM)
    p.wait(timeout=10)
    assert p.returncode == 143 and time.monotonic() - t0 < 2


def test_robot_run_records_every_request_and_tick(cli, sim, tmp_path, rrd_contents):
    import shutil
    from pathlib import Path

    _, port = sim()
    out = tmp_path / "robot.rrd"
    code, text, _ = cli("robot", "run", "--port", port, "--rrd", out, "--json")
    r = json.loads(text)
    assert code == 0 and r["rrd"] == str(out) and out.stat().st_size > 0
    rerun = shutil.which("rerun", path=str(Path(sys.executable).parent))
    assert subprocess.run([rerun, "rrd", "verify", str(out)], capture_output=True).returncode == 0
    printed = subprocess.run([rerun, "rrd", "print", "-v", str(out)], capture_output=True, text=True).stdout
    assert "- /link - data columns" in printed and "- /tick - data columns" in printed
    contents = rrd_contents(out)
    assert contents.views() == [("TextDocument", "tick", "tick"), ("TextLog", "link", "link")]
    assert contents.time_panel() == {"state": 3, "timeline": "tick"}
    code, _, err = cli("robot", "run", "--port", port, "--rrd", out)  # no overwrite without --force
    assert code == 2 and "exists" in err
