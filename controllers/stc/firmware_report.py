"""What ``stcvision firmware`` reports: the C controller checked against the Python one tick by
tick (:func:`identity_report`), and the firmware built for a microcontroller and measured
(:func:`build_firmware`)."""

from __future__ import annotations

import os
import re
import subprocess
import tempfile
from pathlib import Path

from stcvision.controllers.stc.choose import make_controller
from stcvision.controllers.stc.identity import check_boards, check_random, oracle_boards
from stcvision.controllers.stc.mcu import MCUS, FirmwareController, Mcu, compile_firmware, mcu_named, need_tool
from stcvision.errors import BadInputError

__all__ = ["MEASURE_BOARDS", "MEASURE_PAIRS", "build_firmware", "identity_report"]

#: oracle tours and random pairs the build runs in the emulator before it reads the stack's
#: high-water mark: every phase, every branch of the step
MEASURE_BOARDS, MEASURE_PAIRS = 4, 3000


def identity_report(fsm: str, *, boards: int, pairs: int, maps=(), seed: int = 0, mcu: str | None = None) -> dict:
    """``stcvision firmware check``: the controller ``fsm`` against the Python step on every tick
    of ``boards`` oracle tours (:func:`oracle_boards` from ``seed``) and of the map files
    ``maps`` (their own start), and on ``pairs`` random pairs (:func:`random_pairs`; the
    firmware answers one tick per frame, so its pairs are stepped one by one)."""
    from stcvision.sim_camera.board import Board

    ctrl = make_controller(fsm, mcu=mcu)
    try:
        tours = check_boards(oracle_boards(boards, seed), ctrl)
        peers = check_boards(((str(m), Board.from_file(m)) for m in maps), ctrl)
        rand = check_random(pairs, seed, ctrl) if pairs else None
    finally:
        ctrl.close()
    same = tours["different"] == 0 and peers["different"] == 0 and (rand is None or rand["different"] == 0)
    # sizeof the C state as the controller's compiler laid it out (cc, or the chip's)
    return {"fsm": fsm, "seed": seed, "state_bytes": ctrl.state_bytes, "identical": same, "oracle_boards": tours,
            "maps": peers, "random_pairs": rand}  # fmt: skip


def _sections(m: Mcu, elf: Path) -> dict[str, int]:
    """The ELF's section sizes (bytes) as the chip's size tool reads them (``size -A``)."""
    r = subprocess.run([need_tool(m.size_tool), "-A", str(elf)], capture_output=True, text=True, check=True)
    return {k: int(v) for k, v in re.findall(r"^\.(\w+)\s+(\d+)", r.stdout, re.M)}


def build_firmware(mcu: str | None, out: str | os.PathLike, *, overwrite: bool = False) -> dict:
    """``stcvision firmware build``: the firmware for ``mcu`` as ELF and Intel hex in ``out``,
    with ``build.json``: flash (text + data), RAM (data + bss + the stack's high-water mark,
    measured in the emulator after :data:`MEASURE_BOARDS` oracle tours and
    :data:`MEASURE_PAIRS` random pairs, all checked against the Python step) and the state's
    size as the chip's compiler laid it out."""
    from stcvision.fileio import check_output_folder, dumps, write_set

    m = mcu_named(mcu)
    if m.flash_bytes is None:
        raise BadInputError(f"--mcu {m.name} is not a microcontroller: build for one of "
                            f"{', '.join(k for k, v in MCUS.items() if v.flash_bytes)}")  # fmt: skip
    names = ("stc_firmware.elf", "stc_firmware.hex", "build.json")
    check_output_folder(out, names, overwrite=overwrite)
    elf = compile_firmware(m.name)
    with tempfile.TemporaryDirectory() as tmp:
        hexfile = Path(tmp) / names[1]
        subprocess.run([need_tool(m.objcopy), "-O", "ihex", "-R", ".eeprom", str(elf), str(hexfile)], check=True)
        hex_bytes = hexfile.read_bytes()
    sec = _sections(m, elf)
    ctrl = FirmwareController(m.name, elf)
    try:
        tours = check_boards(oracle_boards(MEASURE_BOARDS, 0), ctrl)
        pairs = check_random(MEASURE_PAIRS, 0, ctrl)
        stack = ctrl.stack_bytes()
        state_bytes = ctrl.state_bytes
    finally:
        ctrl.close()
    text, data, bss = sec.get("text", 0), sec.get("data", 0), sec.get("bss", 0)
    r = {
        "mcu": m.name,
        "elf": str(Path(out) / names[0]),
        "hex": str(Path(out) / names[1]),
        "flash_bytes": text + data,
        "flash_capacity": m.flash_bytes,
        "text_bytes": text,
        "data_bytes": data,
        "bss_bytes": bss,
        "stack_bytes": stack,
        "ram_bytes": data + bss + stack,
        "ram_capacity": m.ram_bytes,
        "state_bytes": state_bytes,
        "emulator": m.emulator[0],
        "stack_measured_after": {"oracle_ticks": tours["ticks"], "random_pairs": pairs["pairs"]},
        "identical_to_python": tours["different"] == 0 and pairs["different"] == 0,
    }
    write_set(out, {names[0]: elf.read_bytes(), names[1]: hex_bytes, names[2]: (dumps(r) + "\n").encode()},
              overwrite=overwrite)  # fmt: skip
    return r
