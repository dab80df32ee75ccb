"""Fuzz the command line: argv lists for every command and sub-step, built from the parser
itself (every option with a value drawn from a pool of small valid, malformed and hostile
values, positionals from a pool of good and bad files).

Contract: ``main(argv)`` exits 0, 2 or 3 (3: ran, but the robot did not complete), prints at most
one line on stderr when it fails (``stcvision CMD: error: ...``), never a traceback. Cases stay
cheap: the work-heavy runners (sweeps, camera-perception cover runs, cover plan, rendering,
bench and its sweep self-test, Buffon reproduce/compare/calibrate) are replaced by a stub that stops the case once the
arguments were validated; world, search, Buffon measure, oracle cover runs and the pipeline run
for real on tiny sizes (the option pools hold only small valid numbers).
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import io
import json
import os
import tempfile
from pathlib import Path
from unittest import mock

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from .fuzzlib import examples

ROOT = Path(__file__).resolve().parents[2]


class Reached(Exception):
    """A stubbed heavy runner was reached: the arguments passed validation."""


def _reached(*a, **kw):
    raise Reached


def _guarded_cover(real):
    """run_cover for real on oracle runs of at most 4 cells, else check the seed (what the real
    run does first) and stop."""

    def run(board, cfg=None, **kw):
        from stcvision.controllers.stc.loop import streams

        streams(cfg.seed)
        if cfg.perception == "oracle" and board.cell_free.size <= 4 and not kw.get("observers", [None])[0]:
            return real(board, cfg, **kw)
        raise Reached

    return run


@contextlib.contextmanager
def _stubs():
    import stcvision.controllers.buffon.run as buffon_run
    import stcvision.controllers.stc.loop as loop
    import stcvision.controllers.stc.plan  # noqa: F401  (see below)
    import stcvision.sweep as sweep

    # plan binds run_cover when it is first imported: imported first inside the patch below (the
    # patch of plan.plan imports it), it would keep the stub for the rest of the process, and a
    # later test of cover plan in the same worker would meet it

    with contextlib.ExitStack() as stack:
        stack.enter_context(mock.patch.object(loop, "run_cover", _guarded_cover(loop.run_cover)))
        stack.enter_context(mock.patch("stcvision.controllers.stc.plan.plan", _reached))
        stack.enter_context(mock.patch("stcvision.controllers.stc.recorder.CoverRecorder", _reached))
        stack.enter_context(mock.patch.object(sweep, "run_sweep", _reached))
        stack.enter_context(mock.patch("stcvision.sim_camera.scenarios.benchmark_scene", _reached))
        stack.enter_context(mock.patch("stcvision.sweep.selftest.measure_overhead", _reached))
        stack.enter_context(mock.patch("stcvision.sim_camera.scene.Scene.camera", _reached))
        for name in ("reproduce", "compare", "calibrate"):
            stack.enter_context(mock.patch.object(buffon_run, name, _reached))
        # the simulated robot serves a pseudo-terminal until told to stop (a minute without a
        # word), a robot run drives a port, the firmware's checks and build compile and emulate:
        # past their arguments, none is what a fuzz case tests
        stack.enter_context(mock.patch("stcvision.controllers.stc.simrobot.serve_pty", _reached))
        stack.enter_context(mock.patch("stcvision.controllers.stc.robot_link.run_robot", _reached))
        stack.enter_context(mock.patch("stcvision.controllers.stc.firmware_report.identity_report", _reached))
        stack.enter_context(mock.patch("stcvision.controllers.stc.firmware_report.build_firmware", _reached))
        yield


# ------------------------------------------------------------------------------------ the files a case may name
def _write_files(d: Path) -> None:
    from stcvision.calibration.profiles import default_profile_path
    from stcvision.sim_camera.hardware import LEGO_STC_ROBOT, LOWLIGHT, camera_to_dict, robot_to_dict
    from stcvision.sim_camera.scene import EXAMPLE_SCENE

    rng = np.random.default_rng(0)
    cv2.imwrite(str(d / "frame.png"), rng.integers(0, 30, (480, 640, 3), dtype=np.uint8))
    cv2.imwrite(str(d / "tiny.png"), np.zeros((4, 4, 3), np.uint8))
    cv2.imwrite(str(d / "grey.png"), np.zeros((480, 640), np.uint8))
    cv2.imwrite(str(d / "deep.png"), np.zeros((480, 640, 3), np.uint16))
    cv2.imwrite(str(d / "map.png"), np.full((4, 4), 255, np.uint8))
    (d / "garbage.png").write_bytes(b"\x89PNG\r\n\x1a\n garbage")
    (d / "empty.png").write_bytes(b"")
    (d / "map.txt").write_text("S.\n..\n")
    (d / "badmap.txt").write_text("S.x\n...\n")
    (d / "profile.json").write_text(default_profile_path().read_text())
    (d / "garbage.json").write_text("{not json")
    (d / "nan.json").write_text('{"schema_version": 1, "x": NaN}')
    (d / "scene.json").write_text(json.dumps(EXAMPLE_SCENE))
    (d / "recipe.json").write_text((ROOT / "datasets" / "recipes" / "smoke.json").read_text())
    (d / "arena.json").write_text(json.dumps({"kind": "circle", "center_m": [0, 0], "radius_m": 0.3}))
    (d / "cam.json").write_text(json.dumps(camera_to_dict(LOWLIGHT)))
    (d / "robot.json").write_text(json.dumps(robot_to_dict(LEGO_STC_ROBOT)))
    (d / "points.json").write_text(json.dumps([[150, 150]] * 12))
    (d / "points-text.json").write_text(json.dumps([["a", "b"]] * 12))
    (d / "polygon.json").write_text(json.dumps([[0, 0], [30, 0], [30, 30], [0, 30]]))
    (d / "folder").mkdir()
    (d / "frames").mkdir()
    cv2.imwrite(str(d / "frames" / "a.png"), np.zeros((8, 8, 3), np.uint8))


FILES = [
    "frame.png", "tiny.png", "grey.png", "deep.png", "map.png", "garbage.png", "empty.png", "map.txt",
    "badmap.txt", "profile.json", "garbage.json", "nan.json", "scene.json", "recipe.json", "arena.json",
    "cam.json", "robot.json", "points.json", "points-text.json", "polygon.json", "folder", "frames",
    "missing.json", "missing.png",
]  # fmt: skip
OUTPUTS = ["out", "out/new", "o.rrd", "o.png", "o.json", "o.jsonl", "d.txt", "profile-new.json"]

INTS = ["-1", "0", "1", "2", "3", "x", "1.5", "nan", "", "1e3", " 2", "-0", "0x10"]
FLOATS = ["-1", "0", "0.01", "0.15", "0.5", "1", "2", "nan", "inf", "-inf", "x", "1e400", "1,2", "1e-300"]
PAIRS = ["1x1", "2x1", "1,2", "0x0", "-1x2", "axb", "1x", "2,2,2", "100000x100000", "nanx1", "1.5x2", "3,1", "0,1"]
TRIPLES = ["0.5,0.5,0.1", "1,1,0", "0,0,0.1", "x,y,z", "nan,0,1", "1,2", "inf,0,1", "0.3,-0.2,0.05", "1,1,-1"]
SPECS = ["circle:20", "square:10", "ellipse:300:3", "ellipse:20:1000", "circle:-1", "circle:nan",
         "polygon:polygon.json", "polygon:garbage.json", "hexagon:3", "circle", "", "bar:0.5", "plus:0.3",
         "bar:2", "plus:x"]  # fmt: skip
WORDS = ["webcam", "auto", "camera", "ideal", "oracle", "lowlight", "cooled", "cam.json", "robot.json", "lego",
         "webcam,auto", "0.5", "x", "", "tcp://127.0.0.1:1", "garbage.json"]  # fmt: skip


def _value_pool(action) -> list[str]:
    """Values for an option: by its choices, argparse type and metavar/name."""
    if action.choices:
        return [*action.choices, "nope"]
    name = (action.metavar if isinstance(action.metavar, str) else "") + " " + action.dest
    name = name.lower()
    if any(k in name for k in ("out", "rrd", "report", "preview", "plot", "store")):
        return OUTPUTS + ["folder", "frame.png"]
    if any(k in name for k in ("nest", "barrier", "spec")):
        return SPECS
    if "x,y,r" in name or "patch" in name or "obstacle " in name:
        return TRIPLES
    if any(k in name for k in ("wxh", "i,j", "u,v", "start", "center", "board")):
        return PAIRS
    if any(k in name for k in ("json", "png", "file", "map", "profile", "dark", "arena", "points", "scene", "frame")):
        return FILES
    if any(k in name for k in ("camera", "robot", "exposures", "perceptions", "cameras", "scheduler", "sizes")):
        return WORDS + ["2,3", "1", "0,x"]
    tname = getattr(action.type, "__qualname__", "") or ""
    if action.type is int or "positive" in tname or any(k in name for k in ("seed", "steps", "frames", "trials")):
        return INTS
    return FLOATS + INTS


def _good_pool(action) -> list[str]:
    """Well-formed values for an option (half the draws: so that cases get past argparse and
    into the commands' own validation and runs)."""
    if action.choices:
        return list(action.choices)
    name = ((action.metavar if isinstance(action.metavar, str) else "") + " " + action.dest).lower()
    for keys, pool in (
        (("rrd",), ["o.rrd"]),
        (("preview", "plot"), ["o.png"]),
        (("out", "report", "store"), ["out", "o.json", "o.jsonl", "d.png"]),
        (("nest",), ["circle:20", "square:10", "ellipse:300:3"]),
        (("barrier",), ["bar:0.5", "plus:0.3"]),
        (("x,y,r", "patch", "obstacle "), ["0.5,0.5,0.1", "0.3,-0.2,0.05"]),
        (("wxh", "board"), ["1x1", "2x1", "1x2"]),
        (("i,j", "start"), ["1,1", "0,1"]),
        (("u,v", "center"), ["320,240"]),
        (("map",), ["map.txt", "map.png"]),
        (("profile",), ["profile.json"]),
        (("dark",), ["frame.png"]),
        (("arena",), ["arena.json"]),
        (("points",), ["points.json", "points-text.json"]),
        (("scene",), ["scene.json"]),
        (("compare",), ["o.json"]),
        (("camera",), ["webcam", "lowlight", "cam.json"]),
        (("robot",), ["lego", "robot.json"]),
        (("exposures",), ["webcam", "auto"]),
        (("perceptions",), ["oracle", "ideal"]),
        (("sizes",), ["1", "2"]),
        (("scheduler",), ["tcp://127.0.0.1:1"]),
    ):
        if any(k in name for k in keys):
            return pool
    if action.type is float or "subcell" in name or "_m" in action.dest or "fraction" in name:
        return ["0.1", "0.15", "0.5"]
    return ["1", "2", "3"]


POSITIONAL_GOOD = {"frames": ["frame.png"], "frame": ["frame.png"], "recipe": ["recipe.json"], "dir": ["frames"]}


@functools.cache
def _commands() -> dict[tuple[str, ...], object]:
    """Every (sub)command path -> its parser, from the real parser."""
    from stcvision.cli import build_parser

    out = {}

    def walk(p, path):
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        if path:
            out[path] = p
        for s in subs:
            for name, sp in s.choices.items():
                walk(sp, (*path, name))

    walk(build_parser(), ())
    return out


#: options appended first so that a case stays small (a drawn option overrides them: argparse keeps the last)
CHEAP = {
    ("world",): ["--steps", "3"],
    ("search",): ["--max-steps", "2", "--petals", "3", "--steps-per-petal", "3"],
    ("buffon",): ["--visit-steps", "20", "--trials", "1", "--threads", "1"],
}


#: True 9 times in 10 (hypothesis draws small integers and shrinks towards the first element
#: more often than uniformly: an explicit list keeps the odd cases odd)
_usually = st.sampled_from([True] * 9 + [False])


@st.composite
def argvs(draw):
    path = draw(st.sampled_from(sorted(_commands())))
    parser = _commands()[path]
    argv = [*path, *CHEAP.get(path, [])]
    opts = [a for a in parser._actions if a.option_strings and a.dest != "help"]
    chosen = draw(st.lists(st.sampled_from(opts), max_size=5, unique_by=id)) if opts else []
    chosen += [a for a in opts if a.required and a not in chosen and draw(_usually)]

    def value(pool_good, pool_any):
        return draw(st.sampled_from(pool_good if draw(st.booleans()) else pool_any))

    for a in chosen:
        flag = draw(st.sampled_from(a.option_strings))
        if a.nargs == 0:
            argv.append(flag)
            continue
        n = a.nargs if isinstance(a.nargs, int) else (draw(st.integers(1, 2)) if a.nargs in ("+", "*") else 1)
        argv += [flag, *(value(_good_pool(a), _value_pool(a)) for _ in range(n))]
    for a in parser._actions:
        if a.option_strings or isinstance(a, argparse._SubParsersAction):
            continue
        if not draw(_usually):
            continue  # a positional left out
        n = draw(st.integers(1, 2)) if a.nargs in ("+", "*") else 1
        argv += [value(POSITIONAL_GOOD.get(a.dest, FILES), FILES) for _ in range(n)]
    if not draw(_usually):
        argv.insert(draw(st.integers(0, len(argv))), draw(st.sampled_from(["--bogus", "-x", "--", "--json", "-h"])))
    return argv


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``stcvision ARGV`` run in-process."""
    from stcvision.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse: usage errors (2) and --help (0)
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
        except Reached:
            code = 0
    return code, out.getvalue(), err.getvalue()


WARM_UP = (
    ["--version"],
    ["cover", "--board", "1x1", "--perception", "oracle"],
    ["world", "--steps", "2", "--out", "w"],
    ["search", "--max-steps", "1"],
    ["buffon", *CHEAP[("buffon",)], "--nest", "circle:20"],
    ["pipeline", "--no-dark", "frame.png"],
)


@pytest.fixture(scope="module", autouse=True)
def _warm():
    """Import every command and compile what the first case would (not part of a case's time)."""
    _commands()
    with tempfile.TemporaryDirectory() as tmp, _stubs():
        old = os.getcwd()
        os.chdir(tmp)
        try:
            _case_folder(tmp)
            for argv in WARM_UP:
                run_cli(argv)
        finally:
            os.chdir(old)


@functools.cache
def _inputs() -> Path:
    """The input files, written once per process (each case links them into its own folder)."""
    d = Path(tempfile.mkdtemp(prefix="stcvision-fuzz-cli-"))
    _write_files(d)
    return d


def _case_folder(tmp: str) -> None:
    for name in os.listdir(_inputs()):
        os.symlink(_inputs() / name, Path(tmp) / name)


@examples(5)
@given(argvs())
def test_cli(argv):
    with tempfile.TemporaryDirectory() as tmp:
        _case_folder(tmp)
        old = os.getcwd()
        os.chdir(tmp)
        try:
            with _stubs(), mock.patch.dict(os.environ, {"TQDM_DISABLE": "1"}):
                code, out, err = run_cli(argv)
        finally:
            os.chdir(old)
    assert code in (0, 2, 3), (argv, code, err[-500:])
    assert "Traceback" not in err and "Traceback" not in out, (argv, err[-2000:])
    if code != 0:
        lines = [ln for ln in err.replace("\r", "\n").splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("stcvision"), (argv, err[-1000:])
