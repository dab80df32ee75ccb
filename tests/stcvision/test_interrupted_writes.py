"""Interrupted writes leave the old file or the new one, never half of one: SIGKILL the process
at random points while it writes a profile, a dataset, a sweep store and a rerun recording.
Afterwards each file is the old complete version or the new complete one; a re-run completes the
work and leaves no temporary file behind (a SIGKILL cannot be caught: the hidden
``.NAME.PID.*.tmp`` of a killed writer is removed by the next write of NAME, whose process sees
that PID is gone).

The kill points are drawn from a fixed seed: after the writer's first temporary file (or output)
appears, a random extra delay. Nothing is timed: the waits only poll for events.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
RNG = np.random.default_rng(17)


def temps(folder: Path) -> list[Path]:
    return list(folder.rglob(".*.tmp"))


def start(argv: list, **kw) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen(
        [sys.executable, *map(str, argv)], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, **kw
    )


def writing(p: subprocess.Popen, folder: Path):
    """A condition: ``p`` has a temporary file of its own in ``folder`` (not a killed one's)."""
    return lambda: any(f".{p.pid}." in t.name for t in temps(folder))


def kill_while_writing(p: subprocess.Popen, started, extra_s: float, timeout_s: float = 300) -> bool:
    """SIGKILL ``p`` ``extra_s`` after ``started()`` first holds; True if it was killed while
    running (False: it had finished first)."""
    t_end = time.monotonic() + timeout_s
    while not started() and p.poll() is None:
        if time.monotonic() > t_end:
            p.kill()
            pytest.fail("the writer never started writing")
        time.sleep(0.01)
    time.sleep(extra_s)
    alive = p.poll() is None
    p.kill()
    p.wait()
    return alive


def stcvision(*argv) -> list:
    return ["-m", "stcvision", *argv]


# ---------------------------------------------------------------------------------- profile
WRITE_PROFILES = """
import sys
from stcvision.calibration.profiles import default_profile
prof, path, n = default_profile(), sys.argv[1], int(sys.argv[2])
for i in range(1, n + 1):
    prof.replace(provenance={"version": i, "pad": "x" * 400000}).save(path, overwrite=True)
"""


def test_profile_killed_while_written_is_old_or_new_complete(tmp_path):
    from stcvision.calibration.profiles import default_profile
    from stcvision.profile import Profile

    path = tmp_path / "p.json"
    default_profile().replace(provenance={"version": 0, "pad": "x" * 400000}).save(path)
    for extra in RNG.uniform(0.0, 0.3, 3):
        p = start(["-c", WRITE_PROFILES, path, 100000])
        assert kill_while_writing(p, writing(p, tmp_path), extra)
        prof = Profile.load(path)  # complete: loads, every field
        assert isinstance(prof.provenance["version"], int) and len(prof.provenance["pad"]) == 400000
    # the re-run (a new process writing p.json) completes and clears the killed writers' temporaries
    assert start(["-c", WRITE_PROFILES, path, 1]).wait(timeout=300) == 0
    assert Profile.load(path).provenance["version"] == 1
    assert temps(tmp_path) == []


# ---------------------------------------------------------------------------------- dataset
def rerun_in_process(argv: list) -> None:
    """The re-run, in this process (``argv`` as given to :func:`start`)."""
    from stcvision.cli import main

    assert main([str(a) for a in argv[2:]]) == 0


def test_dataset_killed_while_generated_resumes_to_a_complete_set(tmp_path):
    from stcvision.datasets import open_dataset

    out = tmp_path / "ds"
    recipe = ROOT / "datasets" / "recipes" / "smoke.json"
    argv = stcvision("dataset", "generate", recipe, "--out", out, "--workers", "1")
    for extra in RNG.uniform(0.0, 1.0, 2):
        p = start(argv)
        kill_while_writing(p, writing(p, tmp_path), extra)
        for f in out.rglob("*.json*"):  # what is there is complete
            if not f.name.startswith("."):
                text = f.read_text()
                [json.loads(line) for line in text.splitlines()] if f.suffix == ".jsonl" else json.loads(text)
    rerun_in_process(argv)
    ds = open_dataset(out)  # checks manifest, labels and that every file is there
    assert len(ds.labels) == 6
    assert temps(tmp_path) == []


# ---------------------------------------------------------------------------------- sweep store
def test_sweep_store_killed_mid_sweep_resumes_and_keeps_whole_records(tmp_path):
    from stcvision.sweep import read_store

    out = tmp_path / "sweep"
    store = out / "sweep.jsonl"
    argv = stcvision(
        "cover", "sweep", "--sizes", "2,3", "--runs", "3", "--perceptions", "oracle", "--exposures", "webcam",
        "--out", out, "--workers", "1",
    )  # fmt: skip
    for extra in RNG.uniform(0.0, 0.5, 2):
        p = start(argv)
        kill_while_writing(p, store.exists, extra)
        records = read_store(store)  # every record whole (a torn last line is not a record)
        assert all(r["status"] in ("ok", "failed") for r in records)
    rerun_in_process(argv)
    records = read_store(store)
    assert {r["status"] for r in records} == {"ok"}
    assert len({r["key"] for r in records}) == 6
    assert (out / "summary.md").exists() and temps(tmp_path) == []


# ---------------------------------------------------------------------------------- recording
def rrd_complete(data: bytes) -> bool:
    """A whole rerun recording: its header, and the footer rerun writes when the stream is closed."""
    return data[:4] == b"RRF2" and data[-12:-4] == b"RRF2FOOT"


@pytest.mark.slow
def test_recording_killed_while_written_keeps_the_old_one(tmp_path):
    rrd = tmp_path / "run.rrd"
    argv = stcvision("cover", "--board", "5x5", "--perception", "oracle", "--rrd", rrd, "--force")
    rerun_in_process(argv)
    old = rrd.read_bytes()
    assert rrd_complete(old)
    for extra in RNG.uniform(0.0, 0.2, 3):
        p = start(argv)
        kill_while_writing(p, writing(p, tmp_path), extra)
        now = rrd.read_bytes()
        # the old recording, or the new one if the run had renamed it into place before the kill
        assert now == old or rrd_complete(now), "a half-written recording"
        old = now
    rerun_in_process(argv)
    assert rrd_complete(rrd.read_bytes()) and rrd.read_bytes() != old
    assert temps(tmp_path) == []
    assert os.stat(rrd).st_mode & 0o777 == 0o666 & ~_umask()


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m


def test_sigkill_temp_of_a_live_writer_is_never_taken(tmp_path):
    """The clean-up only takes temporaries of dead processes: a second writer that is alive keeps
    its temporary file while the first one writes the same target."""
    from stcvision.fileio import discard_temp, new_run, remove_stale_temps, temp_sibling, write_bytes_atomic

    p = start(["-c", "import time; time.sleep(60)"])
    try:
        live = tmp_path / f".x.json.{p.pid}.abc.tmp"
        live.write_text("busy")
        mine = temp_sibling(tmp_path / "x.json")
        assert remove_stale_temps(tmp_path) == []
        assert live.exists() and mine.exists()  # a live writer's, and this process's own
        discard_temp(mine)
    finally:
        p.send_signal(signal.SIGKILL)
        p.wait()
    assert remove_stale_temps(tmp_path) == [live]
    new_run()  # the next run's first write into the folder sweeps it
    dead = tmp_path / f".x.json.{p.pid}.def.tmp"
    dead.write_text("left by a SIGKILL")
    write_bytes_atomic(tmp_path / "x.json", b"{}")
    assert not dead.exists() and temps(tmp_path) == []


def test_a_signal_while_a_temporary_is_made_leaves_it_registered(tmp_path, monkeypatch):
    """A signal (here its exception) that lands once the temporary file exists but before
    temp_sibling returns: the file is already registered, so the run's clean-up removes it."""
    from stcvision import fileio

    def interrupted(fd, mode):
        raise KeyboardInterrupt

    monkeypatch.setattr(fileio.os, "fchmod", interrupted)
    with pytest.raises(KeyboardInterrupt):
        fileio.temp_sibling(tmp_path / "run.rrd")
    assert len(temps(tmp_path)) == 1  # made, and interrupted before it was handed back
    fileio.remove_live_temps()
    assert temps(tmp_path) == []


# ---------------------------------------------------------------------------------- render set
def test_render_killed_leaves_no_partial_set(tmp_path):
    """A killed render leaves its set whole or absent, so the same command run again (without
    --force) completes it."""
    from stcvision.sim_camera.scene import EXAMPLE_SCENE

    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(EXAMPLE_SCENE))
    out = tmp_path / "set"
    argv = stcvision("render", "--scene", scene, "--out", out, "--dark-frames", "4")
    p = start(argv)
    kill_while_writing(p, lambda: True, float(RNG.uniform(0.5, 4.0)))
    names = sorted(q.name for q in out.iterdir()) if out.exists() else []
    assert names in ([], ["dark.png", "frame.png", "lights_on.png", "truth.json"])
    if not names:
        rerun_in_process(argv)
    assert sorted(q.name for q in out.iterdir()) == ["dark.png", "frame.png", "lights_on.png", "truth.json"]
    assert temps(tmp_path) == []
