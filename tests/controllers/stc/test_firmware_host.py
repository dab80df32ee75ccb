"""The firmware's own protocol code (``stc_link.c``) built for this machine by ``cc`` and run as
a process whose standard input and output are its serial line: the same firmware the emulator
runs, with only a C compiler installed (the emulator's own tests: tests/emulator)."""

import json
import subprocess
import time

import pytest

from stcvision.controllers.stc import link, wire
from stcvision.controllers.stc.fsm import initial_state
from stcvision.controllers.stc.identity import check_boards, check_random, oracle_boards
from stcvision.controllers.stc.link import FdPort, LinkError, frame, read_frame
from stcvision.controllers.stc.mcu import FirmwareController, compile_firmware


@pytest.fixture
def host_firmware():
    c = FirmwareController("host")
    yield c
    c.close()


def test_the_host_firmware_says_hello_and_equals_python(host_firmware):
    assert host_firmware.state_bytes == wire.STATE_BYTES
    assert host_firmware.held == wire.encode_state(initial_state())
    tours = check_boards(oracle_boards(3, 40), host_firmware)
    assert tours["different"] == 0 and tours["complete"] == 3 and tours["ticks"] > 30
    pairs = check_random(1500, 5, host_firmware)
    assert pairs["different"] == 0 and pairs["refused_by_both"] > 0
    assert host_firmware.stack_bytes() == 0  # the host does not measure its stack


@pytest.fixture
def raw_port():
    p = subprocess.Popen([str(compile_firmware("host"))], stdin=subprocess.PIPE, stdout=subprocess.PIPE)

    class Port(FdPort):
        def write(self, data):
            p.stdin.write(data)
            p.stdin.flush()

    yield Port(p.stdout.fileno())
    p.kill()
    p.wait()


@pytest.mark.parametrize(
    "sent,code",
    [
        (lambda: frame(link.REQUESTS["HELLO"], 9)[:-1] + b"\x00", 1),  # bad checksum
        (lambda: frame(0x33, 9), 2),  # unknown request
        (lambda: frame(link.REQUESTS["STEP"], 9, b"\x01"), 3),  # a STEP without its reading
        (lambda: _other_version(frame(link.REQUESTS["HELLO"], 9)), 4),
    ],
)
def test_the_firmware_refuses_what_it_cannot_answer(raw_port, sent, code):
    raw_port.write(sent())
    kind, _, payload = read_frame(raw_port, 2.0)
    assert kind == link.NAK and payload[0] == code
    raw_port.write(frame(link.REQUESTS["HELLO"], 10))  # and answers the next good frame
    assert read_frame(raw_port, 2.0)[:2] == (link.REQUESTS["HELLO"] | link.REPLY, 10)


def _other_version(f: bytes) -> bytes:
    body = bytes((link.VERSION + 1,)) + f[2:-2]
    return f[:1] + body + link.crc16(body).to_bytes(2, "big")


def test_cover_fsm_firmware_on_the_host_equals_python(cli):
    runs = {}
    for fsm in ("python", "firmware"):
        chip = ("--mcu", "host") if fsm == "firmware" else ()
        code, out, _ = cli("cover", "--board", "3x3", "--perception", "oracle", "--fsm", fsm, *chip, "--json")
        assert code == 0
        runs[fsm] = json.loads(out)
        runs[fsm].pop("wall_s")
    assert runs["firmware"] == runs["python"]


def test_a_firmware_that_dies_mid_run_is_one_line_and_a_stop(monkeypatch):
    from stcvision.controllers.stc import choose as controller_module
    from stcvision.controllers.stc.loop import CoverConfig, run_cover
    from stcvision.sim_camera.board import Board

    made = []
    real = controller_module.make_controller

    def dying(name, **kw):
        made.append(real(name, **kw))
        return made[-1]

    import stcvision.controllers.stc.loop as loop

    monkeypatch.setattr(loop, "make_controller", dying)

    class Killer:
        ticks = 0

        def on_step(self, *a):
            self.ticks += 1
            if self.ticks == 20:
                made[0].proc.kill()
                made[0].proc.wait()

        def __getattr__(self, name):
            return lambda *a, **k: None

    board = Board.random((3, 3), obstacle_fraction=0.0, rng=__import__("numpy").random.default_rng(1))
    t0 = time.monotonic()
    r = run_cover(board, CoverConfig(perception="oracle", fsm="firmware", mcu="host"), observers=[Killer()])
    assert time.monotonic() - t0 < 10 and not r["complete"]
    assert "the host-built firmware is gone" in r["abort_reason"]
    assert "\n" not in r["abort_reason"]


def test_firmware_build_refuses_the_host(cli, tmp_path):
    code, _, err = cli("firmware", "build", "--mcu", "host", "--out", tmp_path / "fw")
    assert code == 2 and "not a microcontroller" in err


def test_an_unknown_chip_is_one_line(cli, tmp_path):
    code, _, err = cli("cover", "--board", "2x2", "--perception", "oracle", "--fsm", "firmware", "--mcu", "z80")
    assert code == 2 and "unknown microcontroller 'z80'" in err


def test_a_link_error_names_the_firmware(host_firmware):
    host_firmware.proc.kill()
    host_firmware.proc.wait()
    with pytest.raises(LinkError, match="the host-built firmware is gone"):
        host_firmware.step(initial_state(), None)


def test_make_cross_tools_installs_the_packages_the_firmware_names():
    import re
    from pathlib import Path

    from stcvision.controllers.stc.mcu import APT_PACKAGES

    makefile = (Path(__file__).resolve().parents[3] / "Makefile").read_text()
    assert tuple(re.search(r"^CROSS_PACKAGES := (.*)$", makefile, re.M).group(1).split()) == APT_PACKAGES


def test_in_a_run_the_firmware_keeps_its_own_state(monkeypatch):
    import stcvision.controllers.stc.loop as loop
    from stcvision.controllers.stc.choose import make_controller
    from stcvision.controllers.stc.loop import CoverConfig, run_cover
    from stcvision.sim_camera.board import Board

    made = []
    monkeypatch.setattr(
        loop, "make_controller", lambda name, **kw: made.append(make_controller(name, **kw)) or made[-1]
    )
    board = Board.random((3, 4), obstacle_fraction=0.1, rng=__import__("numpy").random.default_rng(2))
    r = run_cover(board, CoverConfig(perception="oracle", fsm="firmware", mcu="host"))
    assert r["complete"] and made[0].sent_state == 0  # every tick a STEP: the state lives in the firmware
    assert made[0].proc.poll() is not None  # and the run ended it


@pytest.mark.parametrize("sig,status", [("SIGTERM", 143), ("SIGINT", 130)])
def test_a_signal_stops_a_firmware_run_and_its_firmware(sig, status):
    import signal

    p = subprocess.Popen(
        [__import__("sys").executable, "-m", "stcvision", "cover", "--board", "30x30", "--perception", "oracle",
         "--fsm", "firmware", "--mcu", "host"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    fw = _child_named(p.pid, "stc_firmware-host")
    time.sleep(0.3)
    t0 = time.monotonic()
    p.send_signal(getattr(signal, sig))
    p.wait(timeout=10)
    assert p.returncode == status and time.monotonic() - t0 < 2
    assert not _alive(fw)


def _child_named(pid: int, name: str, timeout_s: float = 20.0) -> int:
    """The pid of ``pid``'s child whose command line holds ``name``, once it has started."""
    from pathlib import Path

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for d in Path("/proc").iterdir():
            if d.name.isdigit():
                try:
                    stat = (d / "stat").read_text()
                    cmd = (d / "cmdline").read_bytes()
                except OSError:
                    continue
                if int(stat.rsplit(")", 1)[1].split()[1]) == pid and name.encode() in cmd:
                    return int(d.name)
        time.sleep(0.05)
    raise AssertionError(f"no child {name} of {pid}")


def _alive(pid: int) -> bool:
    import os

    deadline = time.monotonic() + 2
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        try:  # a zombie of a child reaped late counts as gone
            if open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[0] == "Z":
                return False
        except OSError:
            return False
        time.sleep(0.05)
    return True


def test_firmware_build_without_the_cross_compiler_is_one_line(cli, tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))  # no avr-gcc, no emulator
    code, _, err = cli("firmware", "build", "--mcu", "atmega328p", "--out", tmp_path / "fw")
    assert code == 2 and "'avr-gcc' is not installed: 'make cross-tools'" in err and err.count("\n") == 1
    assert not (tmp_path / "fw").exists()


def _defines(name: str) -> dict[str, int]:
    """The integer #defines of a firmware source file."""
    import re

    from stcvision.controllers.stc.controller import FIRMWARE_DIR

    text = (FIRMWARE_DIR / name).read_text()
    return {k: int(v, 0) for k, v in re.findall(r"^#define (\w+) \(?(0x[0-9A-Fa-f]+|\d+)[uU]?[lL]{0,2}\b", text, re.M)}


def test_the_c_protocol_constants_are_the_python_ones():
    """Written on both sides of the line: held equal here."""
    from stcvision.controllers.stc.robot_link import BAUD

    d = _defines("stc_link.h")
    assert (d["STC_LINK_SYNC"], d["STC_LINK_VERSION"], d["STC_LINK_MAX_PAYLOAD"]) == (
        link.SYNC, link.VERSION, link.MAX_PAYLOAD)  # fmt: skip
    assert (d["STC_LINK_REPLY"], d["STC_LINK_NAK"]) == (link.REPLY, link.NAK)
    for name in ("HELLO", "STEP", "STEP_FROM", "RESET", "STATS"):
        assert d[f"STC_REQ_{name}"] == link.REQUESTS[name]
    for code, what in link.NAK_CODES.items():
        key = {"bad checksum": "CHECKSUM", "unknown request": "UNKNOWN", "bad length": "LENGTH",
               "wrong version": "VERSION"}.get(what)  # fmt: skip
        assert key is None or d[f"STC_NAK_{key}"] == code
    assert _defines("main_avr.c")["BAUD"] == BAUD
    assert _defines("stc_fsm.h")["STC_NONE"] == wire.NONE


def test_the_command_lines_offer_the_controllers_there_are():
    from stcvision.cli import build_parser
    from stcvision.controllers.stc.controller import CONTROLLERS

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices

    def choices(p, dest):
        return tuple(next(a for a in p._actions if a.dest == dest).choices)

    assert choices(sub["cover"], "fsm") == CONTROLLERS
    robot = next(a for a in sub["robot"]._actions if a.dest == "action").choices
    assert choices(robot["run"], "fsm") == CONTROLLERS
    firmware = next(a for a in sub["firmware"]._actions if a.dest == "action").choices
    assert choices(firmware["check"], "fsm") == CONTROLLERS[1:]  # python against itself is no check


def _functions(text: str) -> dict[str, str]:
    """The function definitions of a C source (name -> body), for one written as these are:
    the return type and name on one line at column 0, the body's braces closing at column 0."""
    import re

    out = {}
    for m in re.finditer(r"^[A-Za-z_][\w \*]*?\b(\w+)\(([^;{]*?)\)\s*\n\{\n(.*?)^\}", text, re.M | re.S):
        out[m.group(1)] = m.group(3)
    return out


def test_the_firmware_has_no_heap_no_floating_point_and_no_recursion():
    import re

    from stcvision.controllers.stc.controller import FIRMWARE_DIR

    sources = {f.name: f.read_text() for f in FIRMWARE_DIR.glob("*.[ch]")}
    code = "\n".join(re.sub(r"/\*.*?\*/", "", t, flags=re.S) for t in sources.values())  # comments out
    assert not re.search(r"\b(float|double)\b|\b(malloc|calloc|realloc|free|alloca)\s*\(", code)
    funcs = {}
    for name in ("stc_fsm.c", "stc_link.c", "main_avr.c"):
        funcs |= _functions(re.sub(r"/\*.*?\*/", "", sources[name], flags=re.S))
    assert {"stc_step", "decide", "walk", "plan", "next_child", "stc_link_feed", "answer", "main"} <= set(funcs)
    calls = {f: {g for g in funcs if re.search(rf"\b{g}\(", body)} for f, body in funcs.items()}

    def reaches(start, target, seen=()):
        return any(g == target or (g not in seen and reaches(g, target, (*seen, g))) for g in calls[start])

    assert [f for f in funcs if reaches(f, f)] == []  # no function calls itself, directly or not
