"""cover --trajectory (TUM files that evo reads) and cover --trace (one JSON line per reading)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from stcvision.cli import main
from stcvision.controllers.stc.paths import TRACE_SCHEMA_VERSION
from stcvision.tum import TUM_FILES

# a camera run that completes in about two seconds: frames, long frames, looks and turns
CAMERA_RUN = ["cover", "--board", "3x3", "--seed", "2"]

# evo in a child process with its own home: evo keeps its settings in ~/.evo and makes them on
# first use, which a test must not do in the user's home
EVO_APE = """
import json, sys
from evo.core import metrics, sync
from evo.tools import file_interface
ref = file_interface.read_tum_trajectory_file(sys.argv[1])
est = file_interface.read_tum_trajectory_file(sys.argv[2])
ref, est = sync.associate_trajectories(ref, est)
ape = metrics.APE(metrics.PoseRelation.translation_part)
ape.process_data((ref, est))
stats = {k: float(v) for k, v in ape.get_all_statistics().items()}
print(json.dumps(stats | {"poses": ref.num_poses, "last": float(ape.error[-1])}))
"""


def _run(argv, capsys) -> tuple[int, dict]:
    code = main([*argv, "--json"])
    return code, json.loads(capsys.readouterr().out)


@pytest.fixture(scope="module")
def camera_run(tmp_path_factory):
    """One camera run with both outputs, and its --json summary."""
    out = tmp_path_factory.mktemp("run")
    argv = [*CAMERA_RUN, "--trajectory", str(out / "paths"), "--trace", str(out / "trace.jsonl"), "--json"]
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(argv)
    assert code == 0
    return out, json.loads(buf.getvalue())


def _evo_env(home: Path) -> dict:
    return {**os.environ, "HOME": str(home)}


def test_evo_ape_max_is_the_runs_max_position_error(camera_run, tmp_path):
    """evo's APE (translation part, no alignment) on true.tum against believed.tum: its max is
    cover --json's max_position_error_m, to the files' 9 decimals."""
    out, summary = camera_run
    paths = out / "paths"
    assert sorted(p.name for p in paths.iterdir()) == sorted(TUM_FILES)
    r = subprocess.run(
        [sys.executable, "-c", EVO_APE, str(paths / "true.tum"), str(paths / "believed.tum")],
        capture_output=True, text=True, env=_evo_env(tmp_path), check=True,
    )  # fmt: skip
    ape = json.loads(r.stdout)
    assert ape["poses"] == summary["moves"] + 1  # the start and every forward move
    assert ape["max"] == pytest.approx(summary["max_position_error_m"], abs=1e-8)
    assert ape["min"] == 0.0  # the start: the robot stands where it believes


@pytest.mark.skipif(shutil.which("evo_ape") is None and not (Path(sys.executable).parent / "evo_ape").exists(),
                    reason="evo's command-line tools are not installed")  # fmt: skip
def test_evo_ape_command_reads_the_files(camera_run, tmp_path):
    """``evo_ape tum true.tum believed.tum`` as a user types it prints the same max (6 decimals)."""
    out, summary = camera_run
    exe = Path(sys.executable).parent / "evo_ape"
    cmd = str(exe) if exe.exists() else "evo_ape"
    r = subprocess.run([cmd, "tum", str(out / "paths" / "true.tum"), str(out / "paths" / "believed.tum")],
                       capture_output=True, text=True, env=_evo_env(tmp_path), check=True)  # fmt: skip
    row = next(line.split() for line in r.stdout.splitlines() if line.strip().startswith("max"))
    assert float(row[1]) == pytest.approx(summary["max_position_error_m"], abs=1e-6)


def test_tum_lines_are_evo_format(camera_run):
    """Eight numbers a line, timestamps rising, z 0, a unit quaternion about z."""
    out, _ = camera_run
    for name in TUM_FILES:
        rows = [list(map(float, line.split())) for line in (out / "paths" / name).read_text().splitlines()]
        assert all(len(r) == 8 for r in rows)
        ts = [r[0] for r in rows]
        assert ts[0] == 0.0 and all(b > a for a, b in zip(ts, ts[1:], strict=False))
        for _, _, _, z, qx, qy, qz, qw in rows:
            assert z == qx == qy == 0.0
            assert qz * qz + qw * qw == pytest.approx(1.0, abs=1e-8)


def test_trace_one_line_per_decision_and_look(camera_run):
    """Every line parses; one per decision and per look, as --json counts them."""
    out, summary = camera_run
    lines = [json.loads(s) for s in (out / "trace.jsonl").read_text().splitlines()]
    kinds = [line["kind"] for line in lines]
    assert kinds.count("decision") == summary["decisions"]
    assert kinds.count("look") == summary["looks"]
    assert [line["decision"] for line in lines if line["kind"] == "decision"] == list(
        range(1, summary["decisions"] + 1)
    )
    for line in lines:
        assert line["schema"] == TRACE_SCHEMA_VERSION
        assert set(line["true_pose"]) == {"x_m", "y_m", "heading_deg"}
        assert line["verdict"] == {"ok": True, "findings": []}  # a complete run: no error found
        assert line["frames"] and all(f["count"] >= 1 for f in line["frames"])
    d = next(line for line in lines if line["kind"] == "decision")
    assert len(d["observation"]["boxes"]) == 5 and "target" in d["decision_taken"]
    assert sum(f["count"] for line in lines for f in line["frames"]) <= summary["frames"]  # turns take the rest


def test_oracle_trace_has_no_frames_nor_verdict(tmp_path, capsys):
    """The oracle takes no frames and the referee does not judge it: null, not made up."""
    trace = tmp_path / "t.jsonl"
    code, summary = _run(["cover", "--board", "3x3", "--perception", "oracle", "--trace", str(trace)], capsys)
    assert code == 0 and summary["trace"] == str(trace)
    lines = [json.loads(s) for s in trace.read_text().splitlines()]
    assert len(lines) == summary["decisions"] + summary["looks"]
    assert all(line["frames"] is None and line["verdict"] is None for line in lines)


def test_existing_files_refused_without_force(tmp_path, capsys):
    """An existing output stops the command before the run (exit 2, one line); --force replaces it."""
    trace = tmp_path / "t.jsonl"
    trace.write_text("mine\n")
    argv = ["cover", "--board", "3x3", "--perception", "oracle", "--trace", str(trace)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "exists" in err and len(err.splitlines()) == 1
    assert trace.read_text() == "mine\n"
    paths = tmp_path / "paths"
    paths.mkdir()
    (paths / "true.tum").write_text("mine\n")
    assert main(["cover", "--board", "3x3", "--perception", "oracle", "--trajectory", str(paths)]) == 2
    assert (paths / "true.tum").read_text() == "mine\n"
    capsys.readouterr()
    assert main([*argv, "--trajectory", str(paths), "--force"]) == 0
    assert trace.read_text() != "mine\n" and (paths / "believed.tum").exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporaries left


def test_search_trajectory_evo_max_is_max_odometry_error(tmp_path, capsys):
    """search --trajectory: the true path and the odometry's at the start and after every move;
    evo's APE max is the run's max_odometry_error_m and its last error the odometry_error_m at
    the end (the results page's two columns; --json rounds them to 4 decimals)."""
    paths = tmp_path / "paths"
    argv = ["search", "--max-steps", "12", "--obstacle", "0.5,0.2,0.1", "--trajectory", str(paths)]
    code, summary = _run(argv, capsys)
    assert code == 0 and summary["trajectory"] == str(paths)
    r = subprocess.run(
        [sys.executable, "-c", EVO_APE, str(paths / "true.tum"), str(paths / "believed.tum")],
        capture_output=True, text=True, env=_evo_env(tmp_path), check=True,
    )  # fmt: skip
    ape = json.loads(r.stdout)
    assert ape["poses"] == summary["moves"] + 1
    assert ape["max"] == pytest.approx(summary["max_odometry_error_m"], abs=5e-5)
    assert ape["last"] == pytest.approx(summary["odometry_error_m"], abs=5e-5) and ape["last"] > 1e-3


def test_recording_draws_the_true_and_believed_paths(tmp_path, capsys):
    """cover --rrd draws the two paths on the floor map (what --trajectory writes)."""
    rrd = tmp_path / "c.rrd"
    code, _ = _run(["cover", "--board", "3x3", "--perception", "oracle", "--rrd", str(rrd)], capsys)
    assert code == 0
    rerun = Path(sys.executable).parent / "rerun"
    text = subprocess.run([str(rerun), "rrd", "print", "-v", str(rrd)], capture_output=True, text=True).stdout
    assert "/world/path/true" in text and "/world/path/believed" in text


def test_recording_holds_the_trace_lines_uncut_and_opens_with_the_runs_layout(tmp_path, capsys, rrd_contents):
    """cover --rrd logs every --trace line whole, as a text log on the decision and sim_time
    timelines (a camera run: its lines carry the frames and run to ~1,000 characters), and opens
    with the floor map, the camera's raw frame and ground view, the decision and trace texts,
    the time panel open on sim_time."""
    rrd, trace = tmp_path / "c.rrd", tmp_path / "t.jsonl"
    code, summary = _run([*CAMERA_RUN, "--rrd", str(rrd), "--trace", str(trace)], capsys)
    assert code == 0 and summary["complete"]
    lines = trace.read_text().splitlines()
    contents = rrd_contents(rrd)
    logged = [text for (text,) in contents.column("/trace", "TextLog:text")]
    assert logged == lines and max(map(len, logged)) > 500
    assert contents.times("/trace", "decision") == sorted(json.loads(line)["decision"] for line in lines)
    views = contents.views()
    for view in [("2D", "world (north up)", "world"), ("2D", "camera: raw frame", "raw"),
                 ("2D", "ground view", "ground"), ("TextDocument", "decision", "decision"),
                 ("TextLog", "trace (the --trace lines)", "trace")]:  # fmt: skip
        assert view in views
    assert contents.time_panel() == {"state": 3, "timeline": "sim_time"}
    assert contents.times("/world/path/believed", "decision") and contents.times("/raw", "decision")


def test_trace_puts_each_finding_on_the_line_it_judges():
    """A misread or a decision error goes on the latest decision's line (a decision is judged
    when the robot leaves its cell, after its looks); a look error, reported before its look's
    reading, on that look's line."""
    from types import SimpleNamespace

    import numpy as np

    from stcvision.controllers.stc.observers import Reading
    from stcvision.controllers.stc.paths import JsonTrace
    from stcvision.sim_camera.board import Board

    board = Board.from_text("S...\n....\n")
    plant = SimpleNamespace(t=1.0, x=0.1, y=0.1, heading_rad=0.0, true_offset=lambda sub: np.zeros(2))
    belief = SimpleNamespace(sub=(0, 0), hc=1, offset_m=np.zeros(2))
    trace = JsonTrace(board)
    trace.attach(SimpleNamespace(refereed=True))
    decision = Reading("decision", 1, plant, belief, None, obs=None, decision=None)
    look = Reading("look", 1, plant, belief, None, marked=True)
    trace.on_reading(decision)
    trace.on_referee("look error", "the cell ahead is unmarked")
    trace.on_reading(look)
    trace.on_reading(look)
    trace.on_referee("decision error", "the oracle would leave")
    verdicts = [line["verdict"] for line in trace.lines]
    assert verdicts[0] == {"ok": False, "findings": [{"kind": "decision error", "text": "the oracle would leave"}]}
    assert verdicts[1] == {"ok": False, "findings": [{"kind": "look error", "text": "the cell ahead is unmarked"}]}
    assert verdicts[2] == {"ok": True, "findings": []}
    assert all(line["frames"] is None for line in trace.lines)  # no camera attached


def test_interrupted_run_writes_neither_file(tmp_path, monkeypatch, capsys):
    """Ctrl-C during the run: no trace, no TUM files, no temporaries."""
    import stcvision.cli.cmd_cover as cmd_cover

    def interrupted(*args, **kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(cmd_cover, "run_recorded", interrupted)
    argv = ["cover", "--board", "3x3", "--perception", "oracle"]
    code = main([*argv, "--trajectory", str(tmp_path / "paths"), "--trace", str(tmp_path / "t.jsonl")])
    assert code != 0 and "interrupted" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
