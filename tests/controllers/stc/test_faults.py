"""Hardware faults in the coverage loop (controllers/stc/faults.py): the --fault flag, each fault's
own random stream, the robot's checks of its hardware (controllers/stc/health.py), and per fault
the invariant: complete, or aborted with a specific reason and nothing covered twice -- never
"finished" with the wrong coverage. Camera runs on a 3x3 board (exposure auto, webcam)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from stcvision.cli import main
from stcvision.controllers.stc.experiments import random_board
from stcvision.controllers.stc.fault_sweep import outcome
from stcvision.controllers.stc.faults import FAULTS, Faults, FaultyCamera, fault_stream, parse_fault
from stcvision.controllers.stc.health import FRAME_RETRIES, RobotStop, frame_fault
from stcvision.controllers.stc.loop import CoverConfig, run_cover, streams
from stcvision.errors import BadInputError

#: the abort reasons a fault may end a run with: each says what the robot found
SPECIFIC = ("camera:", "a white light", "lost:", "drove into a blocked", "out of sight")


def _run(fault=None, *, seed=0, cells=3, perception="camera"):
    board = random_board(cells, cells, 0.15, seed)
    faults = () if fault is None else (parse_fault(fault),)
    cfg = CoverConfig(perception=perception, exposure="auto", seed=seed, faults=faults, max_decisions=400)
    return run_cover(board, cfg)


# ---------------------------------------------------------------------------------- the flag
def test_parse_fault_defaults_and_levels():
    assert parse_fault("rate") == ("rate", 0.25)
    assert parse_fault("led:4") == ("led", 4.0)
    assert parse_fault("drop:0") == ("drop", 0.0)
    for bad in ("nope", "rate:0", "rate:0.6", "led:2.5", "led:5", "bump:x", "noise:0.5", "slip:nan"):
        with pytest.raises(BadInputError):
            parse_fault(bad)
    with pytest.raises(BadInputError, match="twice"):
        Faults((("rate", 0.1), ("rate", 0.2)), 0, "camera")
    with pytest.raises(BadInputError, match="perception camera"):
        Faults((("noise", 3.0),), 0, "oracle")


@pytest.mark.parametrize(
    ("flag", "words"),
    [("nope", "unknown fault"), ("rate:2", "must be in (0, 0.5]"), ("led:7", "whole number in [1, 4]")],
)
def test_cli_bad_fault_is_one_line_exit_2(flag, words, capsys):
    assert main(["cover", "--board", "2x2", "--fault", flag]) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and len(err.splitlines()) == 1


def test_cli_list_faults(capsys):
    assert main(["cover", "--list-faults", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert [f["name"] for f in listed] == list(FAULTS) and all("range" in f and "meaning" in f for f in listed)


# ---------------------------------------------------------------------------------- streams
def test_fault_streams_are_their_own():
    """Reproducible per (seed, name), different per name and from the loop's four children."""
    a = fault_stream(3, "rate").random(4)
    assert np.array_equal(a, fault_stream(3, "rate").random(4))
    assert not np.array_equal(a, fault_stream(3, "bump").random(4))
    assert not np.array_equal(a, fault_stream(4, "rate").random(4))
    for g in streams(3).values():
        assert not np.array_equal(a, g.random(4))


def test_a_fault_that_does_nothing_changes_nothing():
    """drop:0 draws from its own stream at every frame but drops none: the camera run is the
    fault-free one, frame for frame (the camera, motion and oracle streams are untouched)."""
    keys = ("subcells_covered", "moves", "turns", "decisions", "frames", "sim_time_s", "max_position_error_m")
    clean, nil = _run(cells=2), _run("drop:0", cells=2)
    assert {k: clean[k] for k in keys} == {k: nil[k] for k in keys}
    assert nil["fault_events"] == {"drop": 0}


def test_a_floor_fault_leaves_the_motion_stream_alone():
    """A dead LED changes the floor's dots, not the record the oracle reads: the oracle robot's
    motion (every move's drawn error, its motors) is the fault-free one."""
    keys = ("moves", "turns", "sim_time_s", "max_position_error_m", "turn_rate_error_pct", "turn_time_s_final")
    clean, led = _run(cells=4, perception="oracle"), _run("led:1", cells=4, perception="oracle")
    assert {k: clean[k] for k in keys} == {k: led[k] for k in keys} and led["fault_events"]["led"] == led["moves"] + 1


# ---------------------------------------------------------------------------------- the robot's checks
def test_frame_fault_names_lost_and_black_frames():
    dark = np.full((48, 64, 3), 9, np.uint8)
    assert "dropped" in frame_fault(None, dark)
    assert "black" in frame_fault(np.zeros_like(dark), dark)
    assert frame_fault(dark + 1, dark) is None


def test_a_dead_camera_stops_the_robot():
    """Every frame lost: FRAME_RETRIES re-takes, then a specific stop, never a reading."""
    from stcvision.controllers.stc.frames import RobotCamera
    from stcvision.sim_camera.phosphor import PhosphorLayer

    board = random_board(2, 2, 0.0, 0)
    wrap = Faults((("drop", 0.5),), 0, "camera").camera_wrap(board)
    cam = RobotCamera(board, CoverConfig(exposure="auto"), np.random.default_rng(0), camera_wrap=wrap)
    assert isinstance(cam.cam, FaultyCamera)
    cam.cam.render = lambda *a, **k: None
    with pytest.raises(RobotStop, match=f"{FRAME_RETRIES + 1} frames in a row dropped"):
        cam.shoot((0.2, 0.2, 0.0), 0.0, PhosphorLayer())
    assert cam.bad_frames == FRAME_RETRIES + 1 and cam.frames == FRAME_RETRIES + 1


def test_a_frame_the_pipeline_cannot_trust_stops_the_robot(monkeypatch):
    """A frame the pipeline flags untrusted (more dot candidates than marks can make, or the dot
    cap reached: ``CellObservation.untrusted``) stops the robot with the pipeline's reason
    instead of a decision on it."""
    import dataclasses

    from stcvision.controllers.stc.frames import RobotCamera
    from stcvision.pipeline import Pipeline
    from stcvision.sim_camera.phosphor import PhosphorLayer

    process = Pipeline.process

    def flagged(self, *a, **k):
        res = process(self, *a, **k)
        obs = dataclasses.replace(res.observation, untrusted="8101 dot candidates above 4 sigma")
        return dataclasses.replace(res, observation=obs)

    monkeypatch.setattr(Pipeline, "process", flagged)
    cam = RobotCamera(random_board(2, 2, 0.0, 0), CoverConfig(exposure="auto"), np.random.default_rng(0))
    with pytest.raises(RobotStop, match="cannot trust .8101 dot candidates"):
        cam.shoot((0.2, 0.2, 0.0), 0.0, PhosphorLayer())


# ---------------------------------------------------------------------------------- the invariant
@pytest.mark.parametrize(
    ("fault", "seed", "expect"),
    [
        ("rate", 0, "complete"),
        ("led", 0, "complete"),
        ("drop", 0, "complete"),
        ("stray", 2, "a white light"),
        ("noise", 0, "camera: noise floor"),
        ("bump", 1, "complete"),
        ("slip", 0, "complete"),
    ],
)
def test_each_fault_complete_or_a_specific_stop(fault, seed, expect):
    """At the fault's default level: the run is complete, or the robot stops saying what it
    found with nothing covered twice; "finished" always means the right coverage."""
    r = _run(fault, seed=seed)
    name = fault.split(":")[0]
    if name != "rate" and name != "noise":  # (the rate and the noise floor are always on)
        assert r["fault_events"][name] > 0, r  # the fault did happen
    assert outcome(r) in ("complete", "aborted, none twice"), r
    if r["finished"]:
        assert r["subcells_covered"] == r["subcells_reachable"] and r["subcells_covered_more_than_once"] == 0
    if expect == "complete":
        assert r["complete"], r
    else:
        assert r["abort_reason"].startswith(expect), r
        assert r["abort_reason"].startswith(SPECIFIC)


# ---------------------------------------------------------------------------------- bounded recording
def test_recorder_compresses_and_subsamples(tmp_path):
    """The camera's stages are logged JPEG-compressed (EncodedImage), for one reading in
    ``every`` (plus what the referee flags); every reading's pose and text; the world at the end.
    The budget keeps a 22x22 board's recording to ~300 full readings."""
    import rerun as rr

    from stcvision.controllers.stc.recorder import READINGS_BUDGET, CoverRecorder, readings_every

    assert readings_every(random_board(2, 2, 0.0, 0)) == 1
    big = random_board(22, 22, 0.1, 0)
    assert readings_every(big) > 1 and int(big.reachable_cells().sum()) * 4 / readings_every(big) <= READINGS_BUDGET
    board = random_board(2, 2, 0.0, 4)
    rec = CoverRecorder(tmp_path / "c.rrd", board, every=3)
    logged: list[tuple[str, object]] = []
    real = rec.rec.log
    rec.rec.log = lambda path, entity, *a, **k: (logged.append((path, entity)), real(path, entity, *a, **k))[1]
    r = run_cover(board, CoverConfig(exposure="auto", seed=4), observers=[rec])
    rec.close()
    raws = [e for p, e in logged if p == "raw"]
    texts = [p for p, _ in logged if p == "decision"]
    assert r["complete"] and rec.readings == len(texts) >= 6
    assert len(raws) == rec.full == -(-rec.readings // 3)  # no referee finding on a complete run
    assert all(isinstance(e, rr.EncodedImage) for e in raws)
    assert (tmp_path / "c.rrd").stat().st_size > 10_000 and not list(tmp_path.glob(".*.tmp"))
