"""The firmware built for the ATmega328P (Arduino Uno) by avr-gcc and run in QEMU's ``uno``
machine, its USART on the emulator's standard input and output: its sizes, every tick against
the Python step, the closed loop with every decision made in the emulator, and the robot driven
by it over a pseudo-terminal. Needs ``make cross-tools``; ``make test-emulator`` runs these
(``.ci/run`` does both), ``make test`` does not."""

import json
import subprocess
import sys

import pytest

pytestmark = pytest.mark.emulator

MCU = ("--mcu", "atmega328p")


def test_firmware_build_reports_sizes_that_fit(cli, tmp_path):
    out = tmp_path / "fw"
    code, text, _ = cli("firmware", "build", *MCU, "--out", out, "--json")
    r = json.loads(text)
    assert code == 0 and r["identical_to_python"]
    assert r["state_bytes"] == 3 < 16
    assert 0 < r["stack_bytes"] and r["ram_bytes"] == r["data_bytes"] + r["bss_bytes"] + r["stack_bytes"]
    assert r["ram_bytes"] < r["ram_capacity"] // 4  # room to spare in the Uno's 2 KB
    assert 0 < r["flash_bytes"] < r["flash_capacity"] // 4
    assert json.loads((out / "build.json").read_text()) == r
    assert (out / "stc_firmware.hex").read_text().startswith(":")
    code, _, err = cli("firmware", "build", *MCU, "--out", out)  # no overwrite without --force
    assert code == 2 and ("--force" in err or "exists" in err)


def test_firmware_check_in_the_emulator(cli, peer_data):
    spiral = peer_data / "pythonrobotics_maps" / "spiral_stc_test.png"
    code, out, _ = cli("firmware", "check", "--fsm", "firmware", *MCU, "--boards", 6, "--pairs", 3000,
                       "--maps", spiral, "--json")  # fmt: skip
    r = json.loads(out)
    assert code == 0 and r["identical"] and r["oracle_boards"]["complete"] == 6 and r["maps"]["complete"] == 1


@pytest.mark.parametrize("perception,board", [("camera", "3x3"), ("oracle", "6x5")])
def test_cover_fsm_firmware_equals_python(cli, perception, board):
    runs = {}
    for fsm in ("python", "firmware"):
        chip = MCU if fsm == "firmware" else ()
        code, out, _ = cli("cover", "--board", board, "--perception", perception, "--seed", 2, "--fsm", fsm, *chip,
                           "--json")  # fmt: skip
        assert code == 0
        runs[fsm] = json.loads(out)
        runs[fsm].pop("wall_s")
    assert runs["firmware"] == runs["python"] and runs["firmware"]["complete"]


def test_robot_run_with_the_firmware_deciding(cli):
    p = subprocess.Popen([sys.executable, "-m", "stcvision", "robot", "sim", "--board", "3x3", "--json"],
                         stdout=subprocess.PIPE, text=True)  # fmt: skip
    try:
        port = p.stdout.readline().strip()
        code, out, _ = cli("robot", "run", "--port", port, "--fsm", "firmware", *MCU, "--json")
        r = json.loads(out)
        assert code == 0 and r["complete"] and r["subcells_covered"] == r["subcells_reachable"]
        assert json.loads(p.communicate(timeout=10)[0])["ended"] == "stopped"
    finally:
        if p.poll() is None:
            p.terminate()
        p.wait(timeout=10)


def test_the_how_to_commands_that_need_the_emulator_run(tmp_path):
    """The how-to's ``sh-emulator`` blocks (not run by make test), each line as written but the
    check's sizes."""
    import os
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    page = (root / "docs" / "how-to" / "controller-on-your-robot.md").read_text()
    blocks = re.findall(r"^```sh-emulator\n(.*?)^```", page, re.M | re.S)
    assert len(blocks) == 2
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    for block in blocks:
        code = block.replace("--boards 20 --pairs 20000", "--boards 3 --pairs 2000")
        done = subprocess.run(["bash", "-euo", "pipefail", "-c", code], cwd=tmp_path, env=env, capture_output=True,
                              text=True)  # fmt: skip
        assert done.returncode == 0, done.stderr
    assert json.loads((tmp_path / "fw" / "build.json").read_text())["state_bytes"] == 3


def test_the_avr_firmware_links_no_floating_point_or_heap_routine():
    from stcvision.controllers.stc.mcu import compile_firmware

    names = subprocess.run(["avr-nm", str(compile_firmware("atmega328p"))], capture_output=True, text=True,
                           check=True).stdout.split()  # fmt: skip
    assert "stc_step" in names and "main" in names
    soft = [n for n in names if n.endswith(("sf3", "sf2", "sfsi", "sisf", "df3")) or n in ("malloc", "free")]
    assert soft == []
