"""A writer killed with SIGKILL leaves its hidden ``.NAME.PID.RANDOM.tmp``; the next write of the
same file (by any later process) removes it. Checked for every writer -- datasets (their frames
folder too), sweeps, profiles, renders, recordings -- with the temporaries of a process that is
really gone, and once end to end with a pool: dataset generate --workers 2, its parent killed."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
STCVISION = str(Path(sys.executable).with_name("stcvision"))


def dead_pid() -> int:
    p = subprocess.Popen(["true"])
    p.wait()
    return p.pid


def plant(folder: Path, name: str, pid: int) -> list[Path]:
    """A killed writer's leftovers of ``name`` in ``folder``: a temporary file and folder."""
    folder.mkdir(parents=True, exist_ok=True)
    f = folder / f".{name}.{pid}.k2j4x9.tmp"
    f.write_bytes(b"half a file")
    d = folder / f".{name}.{pid}.q8w1z0.tmp"
    d.mkdir()
    (d / "part.png").write_bytes(b"x")
    return [f, d]


def temps(folder: Path) -> list[Path]:
    return sorted(folder.rglob(".*.tmp"))


def test_every_writer_removes_a_killed_writers_temporaries_of_its_file(cli, tmp_path):
    from stcvision.calibration.profiles import default_profile
    from stcvision.sim_camera.scene import EXAMPLE_SCENE

    pid = dead_pid()
    left = []
    # profile
    left += plant(tmp_path, "p.json", pid)
    default_profile().save(tmp_path / "p.json")
    # render: the set's folder and its parent
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(EXAMPLE_SCENE))
    left += plant(tmp_path / "R", "frame.png", pid) + plant(tmp_path, "R", pid)
    assert cli("render", "--scene", scene, "--out", tmp_path / "R", "--dark-frames", "2", "--force")[0] == 0
    # dataset: its folder, its frames folder and its parent
    ds = tmp_path / "D"
    recipe = ROOT / "datasets" / "recipes" / "smoke.json"
    left += plant(ds, "manifest.json", pid)  # killed on its first run: the folder is still the dataset's
    assert cli("dataset", "generate", recipe, "--out", ds, "--workers", "1")[0] == 0
    frame = sorted((ds / "frames").iterdir())[0]
    frame.unlink()  # a frame to write again, beside a killed writer's leftovers of it
    left += plant(ds, "labels.jsonl", pid) + plant(ds / "frames", frame.name, pid)
    assert cli("dataset", "generate", recipe, "--out", ds, "--workers", "1")[0] == 0 and frame.exists()
    # sweep: its outputs folder (the store itself is appended in place, never through a temporary)
    sw = tmp_path / "S"
    left += plant(sw, "summary.md", pid) + plant(sw, "table.csv", pid)
    argv = ["cover", "sweep", "--sizes", "2", "--runs", "1", "--perceptions", "oracle", "--exposures", "webcam"]
    assert cli(*argv, "--out", sw, "--workers", "1")[0] == 0
    # recording
    left += plant(tmp_path / "rec", "run.rrd", pid)
    code, _, err = cli("cover", "--board", "3x3", "--perception", "oracle", "--rrd", tmp_path / "rec" / "run.rrd")
    assert code == 0, err
    assert [p for p in left if p.exists()] == [] and temps(tmp_path) == []


@pytest.mark.slow
def test_dataset_generate_with_a_pool_killed_leaves_nothing_after_the_next_run(cli, tmp_path, session_pids):
    ds = tmp_path / "D"
    # The smoke recipe with 60 frames a group: its six frames are written in a few milliseconds,
    # a window a loaded machine's polling can miss, so the run could end before it is killed.
    recipe = json.loads((ROOT / "datasets" / "recipes" / "smoke.json").read_text())
    for group in recipe["groups"]:
        group["n"] = 60
    (tmp_path / "recipe.json").write_text(json.dumps(recipe))
    argv = ["dataset", "generate", str(tmp_path / "recipe.json"), "--out", str(ds), "--workers", "2"]
    p = subprocess.Popen(
        [STCVISION, *argv], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    deadline = time.monotonic() + 180
    while not temps(tmp_path) and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)  # until the run is writing
    assert p.poll() is None, "the run ended before it could be killed while writing"
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    while session_pids(p.pid) and time.monotonic() < deadline:  # its workers die with it
        time.sleep(0.05)
    assert not session_pids(p.pid)
    code, _, err = cli(*argv)
    assert code == 0, err
    assert temps(tmp_path) == []
