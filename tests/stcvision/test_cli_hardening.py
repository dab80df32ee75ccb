"""Bad input through the command line, tried as a new user would: one line on stderr
naming what was wrong and what was expected, exit code 2, never a traceback; nothing of the
user's overwritten without --force; files made with the umask's mode; no temporary file left;
the exit status 3 for 'ran, but the robot did not complete'."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from stcvision.cli import EXIT_INCOMPLETE, main

ROOT = Path(__file__).resolve().parents[2]
RECIPES = ROOT / "datasets" / "recipes"


def run_cli(capsys, *argv) -> tuple[int, str, str]:
    """``stcvision ARGV`` in-process, argparse's own exits included: (code, stdout, stderr)."""
    capsys.readouterr()
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 2
    out = capsys.readouterr()
    return code, out.out, out.err


def assert_one_line(err: str, *needles: str) -> None:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("stcvision"), err
    assert "Traceback" not in err
    for n in needles:
        assert n in lines[0], (n, lines[0])


def no_temps(folder: Path) -> list[Path]:
    return [p for p in folder.rglob(".*.tmp")]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A rendered set (frame, dark, lights-on), malformed files and a user's folder."""
    d = tmp_path_factory.mktemp("files")
    code = main(["render", "--example-scene"])
    assert code == 0
    from stcvision.sim_camera.scene import EXAMPLE_SCENE

    (d / "scene.json").write_text(json.dumps(EXAMPLE_SCENE))
    assert main(["render", "--scene", str(d / "scene.json"), "--out", str(d / "r"), "--dark-frames", "4"]) == 0
    rng = np.random.default_rng(0)
    cv2.imwrite(str(d / "noise.png"), rng.integers(0, 256, (480, 640, 3), dtype=np.uint8))
    board = ((np.indices((480, 640)) // 40).sum(0) % 2 * 255).astype(np.uint8)
    cv2.imwrite(str(d / "checker.png"), np.dstack([board] * 3))
    cv2.imwrite(str(d / "white.png"), np.full((480, 640, 3), 255, np.uint8))
    (d / "afile").write_text("a user's file\n")
    (d / "adir").mkdir()
    scene = dict(EXAMPLE_SCENE)
    (d / "nan_scene.json").write_text(json.dumps({**scene, "time_s": float("nan")}))  # writes NaN
    (d / "big_scene.json").write_text(json.dumps({**scene, "camera": {"width_px": 20000, "height_px": 20000}}))
    prof = json.loads((ROOT / "calibration" / "profiles" / "default.json").read_text())
    (d / "prof.json").write_text(json.dumps(prof))
    (d / "coincident.json").write_text(json.dumps({**prof, "neighbour_corners_px": [[100, 100]] * 12}))
    moved = {**prof, "center_px": [prof["center_px"][0] + 40, prof["center_px"][1]]}
    (d / "other_camera.json").write_text(json.dumps(moved))
    (d / "same_points.json").write_text(json.dumps([[10, 10]] * 12))
    (d / "text_points.json").write_text(json.dumps([["a", "b"]] + [[1, 2]] * 11))
    (d / "map.txt").write_text("....\n.S..\n....\n....\n")
    base = json.loads((RECIPES / "ages.json").read_text())
    for name, change in {
        "neg_age": lambda r: r["groups"][0]["scene"].update(age_range_s=[-5, 10]),
        "reversed": lambda r: r["groups"][0]["scene"].update(age_range_s=[30, 10]),
        "escape": lambda r: r.update(name="../../outside"),
        "huge": lambda r: r["groups"][0].update(n=1_000_000_000),
        "nan": lambda r: r["groups"][0]["scene"].update(box_prob=float("nan")),
    }.items():
        r = json.loads(json.dumps(base))
        change(r)
        (d / f"recipe_{name}.json").write_text(json.dumps(r))
    return d


NEIGHBORS = "calibrate neighbors {d}/r/lights_on.png --profile {d}/prof.json --out {d}/n.json --yes".split()

# (argv with {d} for the files folder, words the one line must hold)
BAD = [
    # outputs that cannot be made
    (["world", "--out", "{d}/afile/sub", "--steps", "10"], ["afile is not a folder"]),
    (["world", "--out", "/proc/stcvision-x", "--steps", "10"], ["cannot write /proc/stcvision-x"]),
    (["demo", "--out", "{d}/afile"], ["afile is a file"]),
    (["render", "--scene", "{d}/scene.json", "--out", "{d}/afile"], ["afile is a file"]),
    (["calibrate", "dark", "{d}/r/dark.png", "--out", "{d}/adir", "--force"], ["is a directory"]),
    (["calibrate", "dark", "{d}/r/dark.png", "--out", "{d}/d.txt"], ["d.txt", ".png"]),
    (["pipeline", "{d}/r/frame.png", "--no-dark", "--rrd", "{d}/adir"], ["is a directory", ".rrd"]),
    (["pipeline", "{d}/r/frame.png", "--no-dark", "--rrd", "{d}/out.txt"], ["does not end in .rrd"]),
    (["cover", "--perception", "oracle", "--rrd", "{d}/adir", "--force"], ["is a directory"]),
    (["cover", "--perception", "oracle", "--rrd", "{d}/afile/x.rrd"], ["afile is not a folder"]),
    # numbers
    (["demo", "--seed", "-1"], ["--seed", ">= 0"]),
    (["world", "--out", "{d}/w", "--seed", "-1"], ["--seed", ">= 0"]),
    (["bench", "--seed", "-1"], ["--seed", ">= 0"]),
    (["cover", "--seed", "-1"], ["--seed", ">= 0"]),
    (["dataset", "generate", "{d}/recipe_neg_age.json", "--seed", "-1"], ["--seed", ">= 0"]),
    (["world", "--out", "{d}/w", "--px-per-m", "inf"], ["--px-per-m", "finite"]),
    (["world", "--out", "{d}/w", "--px-per-m", "nan"], ["--px-per-m", "finite"]),
    (["world", "--out", "{d}/w", "--board", "4by4"], ["WxH", "4x4"]),
    (["cover", "--board", "4by4"], ["WxH"]),
    (["cover", "--start", "a,b"], ["I,J"]),
    (["calibrate", "transform", "{d}/r/lights_on.png", "--out", "{d}/t.json", "--center", "nan,3"], ["U,V"]),
    # caps
    (["render", "--scene", "{d}/scene.json", "--out", "{d}/rx", "--dark-frames", "1000000"], ["cap of 256"]),
    (["world", "--out", "{d}/w", "--board", "100000x100000"], ["10,000 cells"]),
    (["cover", "--board", "100000x100000"], ["10,000 cells"]),
    (["world", "--out", "{d}/w", "--steps", "100000000"], ["cap of 1,000,000"]),
    (["world", "--out", "{d}/w", "--px-per-m", "100000"], ["10,000 px"]),
    (["render", "--scene", "{d}/big_scene.json", "--out", "{d}/rx"], ["20000x20000", "cap of 4096"]),
    (["dataset", "generate", "{d}/recipe_huge.json", "--out", "{d}/ds"], ["cap of 100,000 frames"]),
    # nonsense in files
    (["render", "--scene", "{d}/nan_scene.json", "--out", "{d}/rx"], ["NaN", "finite"]),
    (["dataset", "generate", "{d}/recipe_nan.json", "--out", "{d}/ds"], ["NaN"]),
    (["dataset", "generate", "{d}/recipe_neg_age.json", "--out", "{d}/ds"], ["age_range_s", ">= 0"]),
    (["dataset", "generate", "{d}/recipe_reversed.json", "--out", "{d}/ds"], ["reversed"]),
    (["dataset", "generate", "{d}/recipe_escape.json"], ["'name'", "no '/'"]),
    (["pipeline", "{d}/r/frame.png", "--dark", "{d}/r/dark.png", "--profile", "{d}/coincident.json"], ["corners"]),
    (NEIGHBORS + ["--points", "{d}/same_points.json"], ["coincident"]),
    (NEIGHBORS + ["--points", "{d}/text_points.json"], ["12 [x, y]"]),
    (
        ["calibrate", "neighbors", "{d}/noise.png", "--profile", "{d}/prof.json", "--out", "{d}/n.json", "--yes"],
        ["no mirror rim"],
    ),
    # data that is not what it claims to be
    (["calibrate", "rim", "{d}/noise.png"], ["no mirror rim"]),
    (["calibrate", "rim", "{d}/checker.png"], ["no mirror rim"]),
    (["calibrate", "dark", "{d}/white.png", "--out", "{d}/dw.png"], ["not a dark frame", "lights are on"]),
    (["calibrate", "dark", "{d}/r/frame.png", "--out", "{d}/dw.png"], ["not a dark frame", "bright spots"]),
    (["calibrate", "dark", "{d}/r/dark.png", "--out", "{d}/dw.jpg"], ["losslessly"]),
    (["pipeline", "{d}/r/lights_on.png", "--no-dark", "--profile", "{d}/other_camera.json"], ["another camera"]),
    (["pipeline", "{d}/r/frame.png", "--dark", "{d}/r/dark.png", "--no-dark"], ["not allowed with"]),
    (["cover", "--map", "{d}/map.txt", "--obstacle-fraction", "0.3"], ["--obstacle-fraction", "--map"]),
    (["dataset", "check", "{d}/afile"], ["afile is a file"]),
    (["world", "--out", "", "--steps", "5"], ["--out is an empty string"]),
    (["cover", "--perception", "oracle", "--rrd", ""], ["--rrd is an empty string"]),
    (["calibrate", "transform", "{d}/r/lights_on.png", "--out", "{d}/t.json", "--preview", "{d}/p.jpg"], [".png"]),
    (["calibrate", "transform", "{d}/r/lights_on.png", "--out", "{d}/t.txt", "--yes"], ["does not end in .json"]),
    (["bench", "--frames", "1000000000"], ["cap of 100,000"]),
]


@pytest.mark.parametrize("argv, words", BAD, ids=[" ".join(a[:2]) + f" #{i}" for i, (a, _) in enumerate(BAD)])
def test_bad_input_is_one_line_and_exit_2(capsys, files, argv, words):
    before = sorted(p.name for p in files.iterdir())
    code, _, err = run_cli(capsys, *[a.format(d=files) for a in argv])
    assert code == 2
    assert_one_line(err, *words)
    assert sorted(p.name for p in files.iterdir()) == before  # nothing made, nothing left
    assert not no_temps(files)


def test_wrong_size_dark_frame_is_named_as_the_dark_frame(capsys, files, tmp_path):
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((10, 10, 3), np.uint8))
    code, _, err = run_cli(capsys, "pipeline", files / "r" / "frame.png", "--dark", small)
    assert code == 2
    assert_one_line(err, f"dark frame {small} is 10x10")


def test_spawn_without_a_viewer_is_one_line(capsys, files, monkeypatch, tmp_path):
    monkeypatch.setenv("PATH", str(tmp_path))  # no rerun viewer on it
    monkeypatch.setenv("DISPLAY", ":99")  # a display, so that the missing viewer is what fails
    code, _, err = run_cli(capsys, "pipeline", files / "r" / "frame.png", "--no-dark", "--spawn")
    assert code == 2
    assert_one_line(err, "cannot start the rerun viewer", "--rrd")


@pytest.mark.parametrize(
    "argv", [["pipeline", "{f}", "--no-dark", "--spawn"], ["pipeline", "{f}", "--no-dark", "--spawn", "--rrd", "x.rrd"]]
)
def test_spawn_without_a_display_is_one_line_at_once(capsys, files, monkeypatch, argv):
    """No display: one line and exit 2 before any work, not a viewer that fails 20 s later."""
    import time

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    t0 = time.monotonic()
    code, _, err = run_cli(capsys, *[a.format(f=files / "r" / "frame.png") for a in argv])
    assert code == 2 and time.monotonic() - t0 < 10
    assert_one_line(err, "no display", "--rrd")


def test_a_directory_given_as_the_recording_leaves_nothing_at_the_root(capsys, files):
    before = set(os.listdir("/"))
    code, _, err = run_cli(capsys, "cover", "--perception", "oracle", "--rrd", "/tmp", "--force")
    assert code == 2 and "is a directory" in err
    assert set(os.listdir("/")) == before


# ------------------------------------------------------------------------------ overwrites
@pytest.mark.parametrize(
    "argv, name",
    [
        (["demo", "--out", "{o}"], "coverage.png"),
        (["demo", "--out", "{o}"], "demo.rrd"),
        (["world", "--out", "{o}", "--steps", "10"], "world.png"),
        (["render", "--scene", "{d}/scene.json", "--out", "{o}"], "truth.json"),
    ],
)
def test_existing_outputs_are_refused_without_force(capsys, files, tmp_path, argv, name):
    (tmp_path / name).write_text("mine\n")
    code, _, err = run_cli(capsys, *[a.format(d=files, o=tmp_path) for a in argv])
    assert code == 2
    assert_one_line(err, name, "--force")
    assert (tmp_path / name).read_text() == "mine\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_calibrate_transform_keeps_a_users_preview_and_writes_nothing_when_refused(capsys, files, tmp_path):
    out, preview = tmp_path / "p.json", tmp_path / "p.preview.png"
    preview.write_text("my picture\n")
    code, _, err = run_cli(capsys, "calibrate", "transform", files / "r" / "lights_on.png", "--out", out, "--yes")
    assert code == 2 and "preview" in err and "--force" in err
    assert preview.read_text() == "my picture\n" and not out.exists()
    # the profile exists: refused before anything is written (no preview either)
    preview.unlink()
    out.write_text("{}\n")
    code, _, err = run_cli(capsys, "calibrate", "transform", files / "r" / "lights_on.png", "--out", out, "--yes")
    assert code == 2 and "profile" in err
    assert not preview.exists() and out.read_text() == "{}\n"


def test_calibrate_neighbors_refuses_an_existing_out_and_preview(capsys, files, tmp_path):
    frame, prof = files / "r" / "lights_on.png", files / "prof.json"
    out = tmp_path / "n.json"
    out.write_text("mine\n")
    code, _, err = run_cli(capsys, "calibrate", "neighbors", frame, "--profile", prof, "--out", out, "--yes")
    assert code == 2 and "n.json exists" in err and out.read_text() == "mine\n"
    out.unlink()
    preview = tmp_path / "n.neighbors.png"
    preview.write_text("mine\n")
    code, _, err = run_cli(capsys, "calibrate", "neighbors", frame, "--profile", prof, "--out", out, "--yes")
    assert code == 2 and "preview" in err and preview.read_text() == "mine\n" and not out.exists()
    code, _, _ = run_cli(capsys, "calibrate", "neighbors", frame, "--profile", prof, "--out", out, "--yes", "--force")
    assert code == 0 and out.exists() and preview.read_bytes().startswith(b"\x89PNG")


# ------------------------------------------------------------------------------ the writer
def test_atomic_writer_honours_the_umask_and_keeps_a_replaced_files_mode(tmp_path):
    from stcvision.fileio import discard_temp, temp_sibling, write_bytes_atomic

    old = os.umask(0o027)
    try:
        p = write_bytes_atomic(tmp_path / "a.json", b"{}")
        assert p.stat().st_mode & 0o777 == 0o640
        os.chmod(p, 0o604)
        write_bytes_atomic(p, b"[]", overwrite=True)
        assert p.stat().st_mode & 0o777 == 0o604
        tmp = temp_sibling(tmp_path / "r.rrd")  # what rerun writes into before the rename
        assert tmp.stat().st_mode & 0o777 == 0o640
        discard_temp(tmp)
    finally:
        os.umask(old)
    assert not no_temps(tmp_path)


def test_stale_temporary_files_of_dead_writers_are_removed(tmp_path):
    from stcvision.fileio import new_run, write_bytes_atomic

    new_run()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    pid = int(dead.stdout)  # a process that has exited
    stale = tmp_path / f".out.json.{pid}.abc123.tmp"
    stale.write_text("half")
    live = tmp_path / ".out.json.1.def456.tmp"  # pid 1 is alive: never touched
    live.write_text("busy")
    write_bytes_atomic(tmp_path / "out.json", b"{}")
    assert not stale.exists() and live.exists()


def test_write_set_is_whole_or_marked_incomplete(tmp_path, monkeypatch):
    import stcvision.fileio as fio

    files = {"a.png": b"A", "b.png": b"B", "truth.json": b"{}"}
    fio.write_set(tmp_path / "new", files)  # a new folder appears whole
    assert sorted(p.name for p in (tmp_path / "new").iterdir()) == sorted(files)
    assert not no_temps(tmp_path)
    # into a folder with other files: the marker goes first and comes back last
    user = tmp_path / "user"
    user.mkdir()
    (user / "notes.txt").write_text("mine")
    fio.write_set(user, files)
    real, calls = fio.write_bytes_atomic, []

    def failing(path, data, **kw):
        calls.append(Path(path).name)
        if len(calls) == 2:
            raise fio.OutputError("disk full")
        return real(path, data, **kw)

    monkeypatch.setattr(fio, "write_bytes_atomic", failing)
    with pytest.raises(fio.OutputError):
        fio.write_set(user, {"a.png": b"A2", "b.png": b"B2", "truth.json": b"{2}"}, overwrite=True)
    assert not (user / "truth.json").exists()  # incomplete, and says so
    monkeypatch.setattr(fio, "write_bytes_atomic", real)
    fio.write_set(user, {"a.png": b"A2", "b.png": b"B2", "truth.json": b"{2}"}, overwrite=True)
    assert (user / "truth.json").read_bytes() == b"{2}" and (user / "notes.txt").read_text() == "mine"


# ------------------------------------------------------------------------------ exit statuses
def _stcvision(*argv, **kw):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen([sys.executable, "-m", "stcvision", *map(str, argv)], env=env, **kw)


def test_a_closed_stdout_ends_quietly(files):
    p = _stcvision("cover", "--list-cameras", "--json", stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()  # as '| head -c 5' does, before the command prints
    err = p.stderr.read().decode()
    assert p.wait(timeout=120) == 128 + signal.SIGPIPE
    assert err == ""


def test_sigterm_keeps_the_recording_so_far_and_no_temporary(tmp_path):
    """SIGTERM once the recording's file has its second batch: exit 143, the recording kept
    whole (rerun's footer written: it verifies) as it stood, no temporary. The run is an 8x8
    board (seconds of work after the recording opens; the signal ends it long before): a 3x3
    run, now a fraction of a second, could finish between the poll and the signal."""
    rrd = tmp_path / "run.rrd"
    p = _stcvision("cover", "--board", "8x8", "--rrd", rrd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        # the file's second batch: the first (the layout) is written as the sink starts, where a
        # signal still removes the file (nothing recorded yet); by the next the run is logging
        sizes = set()
        while len(sizes - {0}) < 2 and p.poll() is None:
            sizes.update(t.stat().st_size for t in tmp_path.glob(".*.tmp"))
            time.sleep(0.02)  # polling for an event, not timing anything
        assert p.poll() is None, "the run ended before its recording was opened"
        p.send_signal(signal.SIGTERM)
        assert p.wait(timeout=120) == 128 + signal.SIGTERM
    finally:
        p.kill()
    err = p.stderr.read().decode()
    assert err.count("\n") == 1 and f"interrupted; kept {rrd}" in err
    assert [f.name for f in tmp_path.iterdir()] == ["run.rrd"]
    rerun = Path(sys.executable).parent / "rerun"
    assert subprocess.run([str(rerun), "rrd", "verify", str(rrd)], capture_output=True).returncode == 0


def test_a_signal_a_library_swallowed_still_commits_nothing(tmp_path, capsys, monkeypatch):
    """A SIGTERM whose exception a library swallowed (numba's compiler, a logging wrapper): the
    run goes on, but its outputs are not committed and it ends with 143 (no file, no temp)
    but the recording, kept as an interrupted one is."""
    import stcvision.cli.cmd_cover as cmd_cover
    from stcvision.fileio import signal_received

    real = cmd_cover.run_recorded

    def swallowed(board, cfg, rrd, observers=(), **kw):
        try:
            signal_received(signal.SIGTERM)  # what the CLI's handler notes before it raises
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            pass  # the library's catch-all
        return real(board, cfg, rrd, observers, **kw)

    monkeypatch.setattr(cmd_cover, "run_recorded", swallowed)
    rrd = tmp_path / "run.rrd"
    code = main(["cover", "--board", "2x2", "--perception", "oracle", "--rrd", str(rrd)])
    assert code == 128 + signal.SIGTERM
    assert f"interrupted; kept {rrd}" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == [rrd]
    from stcvision.fileio import write_json

    write_json(tmp_path / "later.json", {})  # the run is over: a later write is not refused


def test_cover_exit_status_3_when_the_robot_did_not_complete(capsys, monkeypatch):
    code, out, _ = run_cli(capsys, "cover", "--board", "2x2", "--perception", "oracle", "--json")
    assert code == 0 and json.loads(out)["complete"] is True
    import stcvision.controllers.stc.loop as loop

    real = loop.run_cover

    def aborted(board, cfg, **kw):
        r = real(board, cfg, **kw)
        return {**r, "complete": False, "abort_reason": "injected: lost the marks"}

    monkeypatch.setattr(loop, "run_cover", aborted)
    code, out, _ = run_cli(capsys, "cover", "--board", "2x2", "--perception", "oracle", "--json")
    assert code == EXIT_INCOMPLETE == 3
    assert json.loads(out)["abort_reason"] == "injected: lost the marks"


def test_unexpected_errors_keep_their_traceback(capsys, monkeypatch):
    """A bug is not dressed up as bad input: only project errors and OSErrors about paths are."""
    import stcvision.cli.cmd_bench as bench

    def bug(args):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(bench, "run", bug)
    with pytest.raises(ZeroDivisionError):
        main(["bench"])


def test_a_signal_wrapped_by_the_code_it_landed_in_still_reads_interrupted(capsys, monkeypatch):
    """SIGTERM raised inside a dataclass's ``__set_name__`` (an import under way) reaches the CLI
    as a RuntimeError caused by :class:`Terminated`: one line and 128 + 15, no traceback."""
    import stcvision.cli.cmd_render as cmd
    from stcvision.errors import Terminated

    def run(args):
        try:
            raise Terminated(15)
        except Terminated as exc:
            raise RuntimeError("Error calling __set_name__ on 'Field' instance") from exc

    monkeypatch.setattr(cmd, "run", run)
    assert main(["render", "--scene", "x.json", "--out", "y.png"]) == 128 + 15
    assert capsys.readouterr().err == "stcvision render: interrupted\n"


def test_every_command_s_help_keeps_its_usage_lines_as_written(capsys):
    """Each command's help shows its docstring's usage lines one per line, as typed."""
    import importlib

    from stcvision.cli import COMMANDS

    with_usage = []
    for name, module, _ in COMMANDS:
        doc = importlib.import_module(module).__doc__
        usage = [ln.rstrip() for ln in doc.splitlines() if ln.strip().startswith(f"stcvision {name}")]
        with pytest.raises(SystemExit):
            main([name, "--help"])
        out = capsys.readouterr().out
        assert all(ln in out.splitlines() for ln in usage), name
        with_usage += [name] * bool(usage)
    assert {"pipeline", "eval", "cover", "dataset", "calibrate"} <= set(with_usage)
