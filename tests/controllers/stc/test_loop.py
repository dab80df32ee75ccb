"""Closed-loop coverage: camera -> pipeline -> STC controller -> robot, with fading marks."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stcvision.cli import main
from stcvision.controllers.stc.frames import AUTO_LONG
from stcvision.controllers.stc.loop import CoverConfig, run_cover
from stcvision.controllers.stc.loop import is_complete as complete
from stcvision.controllers.stc.observers import Observer
from stcvision.sim_camera.board import Board
from stcvision.sim_camera.camera import SyntheticCamera, visibility_horizon_s


def small_board(seed):
    rng = np.random.default_rng(200 + seed)
    cells = (int(rng.integers(2, 5)), int(rng.integers(2, 5)))
    return Board.random(cells, obstacle_fraction=float(rng.uniform(0, 0.25)), rng=rng)


@pytest.mark.slow
@pytest.mark.parametrize("chunk", range(4))
def test_camera_mode_covers_random_boards_with_exposure_control(chunk):
    """20 random boards of 2x2..4x4 cells: every decision from rendered frames."""
    for seed in range(5 * chunk, 5 * chunk + 5):
        r = run_cover(small_board(seed), CoverConfig(perception="camera", exposure="auto", seed=seed))
        assert complete(r), (
            seed,
            {k: v for k, v in r.items() if k != "first_decision_error"},
            r.get("first_decision_error"),
        )


def test_webcam_exposure_fails_where_exposure_control_succeeds():
    """The ant-like STC paper's limitation: at webcam settings marks fade (~67 s at 0.25 m, less
    farther out) before the robot comes back to read them; a long second frame removes it."""
    board = Board.random((4, 4), obstacle_fraction=0.1, rng=np.random.default_rng(7))
    web = run_cover(board, CoverConfig(perception="camera", exposure="webcam", seed=3))
    auto = run_cover(board, CoverConfig(perception="camera", exposure="auto", seed=3))
    assert complete(auto), auto
    assert not complete(web)
    assert web["decision_errors"] > 0
    horizon = visibility_horizon_s(SyntheticCamera())
    assert auto["max_mark_age_read_s"] > 2 * horizon  # it had to read marks the webcam cannot see


@pytest.mark.slow
def test_red_light_landmarks_keep_the_robot_on_its_sub_cells():
    """On 5x5 boards the robot's own marks show its heading drift only as the lean of old
    rows; the red lights show it absolutely. Without them it strays 1.6-2.8 cm from its
    sub-cells on four boards (mean 2.1 cm); with them it stays within 1.1 cm (mean 0.8 cm) and
    covers every board. With the dots centred on the mirror image, the row-lean check, and rows
    aligned on their line before they are laid (which keeps the blind robot on its own marks'
    lines), the blind robot strays 0.92-1.43 cm (mean 1.22 cm) against 0.58-0.86 cm (mean
    0.70 cm) with the lights, so the test asks for 1.5x the mean error and the worst one
    without the lights."""
    blind, seeing = [], []
    for seed in range(1, 5):
        board = Board.random((5, 5), obstacle_fraction=0.15, rng=np.random.default_rng(seed))
        r = run_cover(board, CoverConfig(perception="camera", exposure="auto", seed=seed, use_landmarks=False))
        blind.append(r["max_position_error_m"])
        r = run_cover(board, CoverConfig(perception="camera", exposure="auto", seed=seed))
        assert complete(r), r
        seeing.append(r["max_position_error_m"])
    assert max(seeing) < 0.012 and max(blind) > 1.5 * max(seeing), (blind, seeing)
    assert np.mean(blind) > 1.5 * np.mean(seeing), (blind, seeing)


def test_oracle_mode_closed_loop_on_random_and_pythonrobotics_boards(peer_data):
    for seed in range(10):
        rng = np.random.default_rng(300 + seed)
        board = Board.random((int(rng.integers(2, 9)), int(rng.integers(2, 9))), obstacle_fraction=0.2, rng=rng)
        assert complete(run_cover(board, CoverConfig(perception="oracle", seed=seed)))
    for name in ("spiral_stc_test.png", "spiral_stc_test_2.png", "spiral_stc_test_3.png"):
        board = Board.from_file(peer_data / "pythonrobotics_maps" / name)
        r = run_cover(board, CoverConfig(perception="oracle", seed=1))
        assert complete(r), (name, r)
        assert r["subcells_reachable"] in (1024, 1008)


def test_cover_cli_json_and_rerun_recording(tmp_path, capsys):
    rrd = tmp_path / "cover.rrd"
    assert (
        main(["cover", "--board", "2x2", "--seed", "4", "--obstacle-fraction", "0", "--rrd", str(rrd), "--json"]) == 0
    )
    r = json.loads(capsys.readouterr().out)
    for key in (
        "subcells_reachable",
        "subcells_covered",
        "subcells_covered_more_than_once",
        "returned_to_start",
        "finished",
        "abort_reason",
        "moves",
        "turns",
        "sim_time_s",
        "wall_s",
        "decision_errors",
        "max_mark_age_read_s",
        "complete",
    ):
        assert key in r
    assert complete(r) and r["complete"]
    rerun = shutil.which("rerun", path=str(Path(sys.executable).parent))
    assert subprocess.run([rerun, "rrd", "verify", str(rrd)], capture_output=True).returncode == 0
    text = subprocess.run([rerun, "rrd", "print", "-v", str(rrd)], capture_output=True, text=True).stdout
    for path in (
        "/world/robot",
        "/world/marks",
        "/world/covered",
        "/world/red_lights",
        "/decision",
        "/raw",
        "/ground/dots",
        "/observation",
    ):
        assert path in text, path


def test_cover_cli_move_log_is_the_study_switch(capsys):
    """``cover --move-log`` runs the robot with the map of where it has been and reports the map's
    own checks; without it the ant-like robot keeps its constant memory."""
    argv = ["cover", "--board", "4x3", "--seed", "2", "--perception", "oracle", "--json"]
    assert main(argv) == 0
    ant = json.loads(capsys.readouterr().out)
    assert main([*argv, "--move-log"]) == 0
    logged = json.loads(capsys.readouterr().out)
    assert ant["move_log"] is False and "log_relooked" not in ant and ant["complete"]
    assert logged["move_log"] is True and logged["log_relooked"] == 0 and logged["complete"]
    assert logged["robot_memory_bytes"] > ant["robot_memory_bytes"] > 0


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["cover", "--map", "nope.png"], "does not exist"),
        (["cover", "--board", "0x3"], "at least 1x1"),
        (["cover", "--board", "3x3", "--exposure-s", "-1"], "exposure-s"),
    ],
)
def test_cover_cli_bad_input(capsys, argv, words):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1


def _look_frame(marks, *, age_s, exposure_s=2.0, gain=4.0, seed=0):
    """A robot about to leave its cell northwards (front-right sub-cell, heading north) on a
    free 6x6 board, with marks ``(sub-cell, edge direction)`` of age ``age_s``: what
    ``marks_ahead`` counts on one frame."""
    from stcvision.calibration.profiles import default_profile
    from stcvision.observation import marks_ahead
    from stcvision.pipeline import Pipeline
    from stcvision.sim_camera.camera import Pose
    from stcvision.sim_camera.phosphor import PhosphorLayer, mark_dots_m

    board = Board(np.zeros((12, 12), bool), (7, 5))
    cam = SyntheticCamera()
    rng = np.random.default_rng(seed)
    sensor = cam.sensor.replace(exposure_s=exposure_s, gain=gain)
    layer = PhosphorLayer()
    for sub, edge in marks:
        layer.charge(
            mark_dots_m(board.subcell_center_m(*sub), edge, board.subcell_m), t_start_s=-age_s - 3, duration_s=3
        )
    x, y = board.subcell_center_m(6, 5)
    pipe = Pipeline(default_profile(), dark=cam.median_dark(8, rng=rng, sensor=sensor))
    img = cam.render(
        Pose(float(x), float(y), np.pi / 2), rng=rng, phosphor=layer, red_lights_m=board.red_lights_m(), sensor=sensor
    ).image
    res = pipe.process(img)
    herr = res.heading.heading_error_rad if res.heading.ok else 0.0
    return marks_ahead(res.dots, pipe.geometry, heading_error_rad=herr, offset=res.observation.position_offset)


def test_the_look_reads_the_cell_ahead_and_only_it():
    # the far corner of the cell ahead (its upper-left sub-cell's top edge, ~0.4 m away) at an
    # age where the 2 s frame's single-dot horizon there (~700 s) has passed
    assert _look_frame([((4, 4), (0, 1))], age_s=900.0) >= 2
    # marks of the robot's own cell on the border with the cell ahead, of the cell to the left
    # and of the cell beyond: none of them is in the cell ahead
    own = [((6, 4), (0, 1)), ((6, 5), (-1, 0)), ((7, 4), (0, 1))]
    others = [((5, 3), (1, 0)), ((3, 5), (0, -1))]
    assert _look_frame(own + others, age_s=30.0) == 0


def test_exposure_rungs_follow_the_clock():
    """Auto exposure: the frame taken for a claim is the shortest whose horizon at the claim's
    distance covers the oldest mark there can be (the clock); the horizons grow with the rung
    and shrink with the distance."""
    from stcvision.controllers.stc.frames import RobotCamera as _Camera

    board = Board.random((3, 3), obstacle_fraction=0.0, rng=np.random.default_rng(0))
    cam = _Camera(board, CoverConfig(exposure="auto"), np.random.default_rng(0))
    assert len(cam.horizons()) == len(AUTO_LONG) and all(np.diff(cam.horizons()) > 0)
    assert all(np.array(cam.horizons(0.25)) > cam.horizons())  # nearer marks stay visible longer
    assert cam.rung_for(0.0, 0.45) == 0  # a fresh mark: the short frame sees it
    assert cam.rung_for(cam.horizon(0, 0.45) + 1, 0.45) == 1
    assert cam.rung_for(cam.horizons()[0] + 1, 0.45) == 2
    assert cam.rung_for(1e9, 0.45) is None  # beyond the longest frame
    # beyond the 30 s frame, 30 s frames stacked, from 2 to 64 of them
    stacks = [cam.stack(k) for k in range(len(cam.ladder))]
    assert stacks[5:7] == [1, 2] and stacks[-1] == 64 and all(np.diff(stacks[5:]) > 0)
    assert cam.frame_s(len(AUTO_LONG)) == 64 * 30.0
    assert not _Camera(board, CoverConfig(exposure="webcam"), np.random.default_rng(0)).controlled


@pytest.mark.slow
def test_far_red_lights_keep_the_robot_on_its_sub_cells_on_open_floor():
    """The newest row's heading random-walks (each row was laid with the error the robot had
    then) and the marks' offset follows the trail: only the red lights are absolute. Their
    bearings stay within ~1 mm out to 1.2 m, so the lights of obstacles and the border hold the
    robot even where none is near. On a 10x10 board, first 110 decisions (~1,900-2,300 s):
    without the lights the robot strays 2.8 cm from its sub-cells (over the whole tour 4.1 cm,
    and one wrong decision); with them it stays within 1.2 cm (0.9 cm with the 2 s frame's
    lean of all rows after each turn, 1.15 cm without)."""
    board = Board.random((10, 10), obstacle_fraction=0.15, rng=np.random.default_rng(3))
    cfg = dict(perception="camera", exposure="auto", seed=3, max_decisions=110)
    blind = run_cover(board, CoverConfig(use_landmarks=False, **cfg))
    assert blind["max_position_error_m"] > 0.02
    for kw in ({}, {"consensus_frame": False}):
        r = run_cover(board, CoverConfig(**kw, **cfg))
        assert r["max_position_error_m"] < 0.016 and r["decision_errors"] == 0, kw
        assert r["subcells_covered_more_than_once"] == 0 and r["subcells_covered"] >= 200, kw


def test_ideal_camera_sees_exactly_the_marks_within_the_horizon():
    """--perception ideal: a mark is seen iff one of its dots is younger than the frame's
    horizon at its distance (the Rose criterion), so a webcam frame sees a 30 s old mark 0.25 m
    away, not a 200 s old one, and nothing under the robot's body (inside the mirror's blind
    circle); a 30 s frame sees the 200 s old one too."""
    from stcvision.controllers.stc.frames import IdealCamera as _Ideal
    from stcvision.sim_camera.phosphor import PhosphorLayer

    board = Board.random((3, 3), obstacle_fraction=0.0, rng=np.random.default_rng(0))
    ph = PhosphorLayer()
    marks = []
    # rows of four dots across the x axis at 0.25 m (laid at t = -30 s and -200 s) and at 0.02 m
    for (sub, edge), y, t_end in ((((0, 0), 0), 0.25, -30.0), (((1, 1), 1), -0.25, -200.0), (((2, 2), 2), 0.02, -5.0)):
        ph.charge([[x, y] for x in (-0.045, -0.015, 0.015, 0.045)], t_start_s=t_end - 3.0, duration_s=3.0)
        marks.append((sub, edge))
    web = _Ideal(CoverConfig(exposure="webcam"), board, rows=False)
    seen = web.floor_seen((0.0, 0.0), 0.0, ph, marks, [0])
    assert seen.has((0, 0), 0) and not seen.has((1, 1), 1) and not seen.has((2, 2), 2)
    auto = _Ideal(CoverConfig(exposure="auto"), board, rows=False)
    seen = auto.floor_seen((0.0, 0.0), 0.0, ph, marks, [0, len(AUTO_LONG)])
    assert seen.has((0, 0), 0) and seen.has((1, 1), 1) and not seen.has((2, 2), 2)


@pytest.mark.slow
def test_ideal_camera_bounds_what_any_pipeline_can_do():
    """The physics-limited camera spends the camera's time and sees what its frames could show
    at all. On six 10x10 boards it reproduces the paper's limitation (at webcam settings the
    first wrong decision within 15 minutes) and, with exposure control, covers every board."""
    for seed in range(6):
        board = Board.random((10, 10), obstacle_fraction=0.15, rng=np.random.default_rng(seed))
        auto = run_cover(board, CoverConfig(perception="ideal", exposure="auto", seed=seed))
        assert complete(auto), (seed, auto)
        if auto["subcells_reachable"] < 100:
            continue  # a walled-in start: nothing to forget
        web = run_cover(board, CoverConfig(perception="ideal", exposure="webcam", seed=seed, max_decisions=400))
        assert web["decision_errors"] > 0 and web["first_decision_error"]["t_s"] < 900, (seed, web)
        assert auto["long_exposures"] > 0 and auto["sim_time_s"] > web["first_decision_error"]["t_s"]


def test_on_a_map_the_webcam_tour_outruns_its_marks_and_stops_before_deciding(peer_data):
    """spiral_stc_test.png by the physics-limited camera with the paper's webcam sensor. Each
    return to a cell reads marks as old as the tour so far, and each look at a child must rule
    out a mark as old as the tour in the child's far sub-cell (0.41 m away), so a longer tour
    needs longer frames, which lengthen the tour: it runs away. Frames sized one sigma above the
    dot threshold (SNR 6.5, the default) stop "out of sight" at ~20,800 s with 282 of 1,024
    sub-cells; even sized at the row search's threshold (a row of four at a mean SNR of 3, which
    a detector finds half the time) with the thriftiest settings, at ~51,500 s with 663. Either
    way the robot stops before deciding: nothing covered twice, no wrong decision. (Before issue
    16.7's claims, which ruled out the cell ahead only 0.35 m away, SNR 3 converged in ~21,100 s.)"""
    board = Board.from_file(peer_data / "pythonrobotics_maps" / "spiral_stc_test.png")
    thrift = dict(perception="ideal", exposure="auto", consensus_frame=False, position_margin_m=0.0)
    default = run_cover(board, CoverConfig(perception="ideal", exposure="auto"))
    edge = run_cover(board, CoverConfig(sizing_snr=3.0, **thrift))
    for r in (default, edge):
        assert r["abort_reason"].startswith("out of sight: no mark in the cell ahead"), r["abort_reason"]
        assert r["subcells_covered_more_than_once"] == 0 and r["decision_errors"] == 0
    assert default["subcells_covered"] < 400 < 600 < edge["subcells_covered"] < 1000
    assert edge["sim_time_s"] > 2 * default["sim_time_s"]


@pytest.mark.slow
def test_camera_mode_covers_a_12x12_board_with_the_cooled_camera():
    """A 12x12 board from rendered 16-bit frames of the cooled camera: every sub-cell once, back
    at the start, 0 wrong decisions, in ~3,700 s of robot time (the webcam, exposure control
    on, stops "out of sight" before deciding on its 12x12 boards: it never takes for absent a
    mark its frames could not have shown)."""
    from stcvision.sim_camera import hardware

    board = Board.random((12, 12), obstacle_fraction=0.15, rng=np.random.default_rng(0))
    r = run_cover(
        board, CoverConfig(perception="camera", exposure="auto", seed=0, camera=hardware.load_camera("cooled"))
    )
    assert complete(r), {k: v for k, v in r.items() if k != "first_decision_error"}
    assert r["subcells_reachable"] > 480 and r["max_mark_age_read_s"] > 3000


class _MoveErrors(Observer):
    """An observer keeping each forward move's drawn distance error."""

    def __init__(self):
        self.by_move = {}

    def on_step(self, plant, belief, state, action):
        if plant.moves:
            self.by_move[plant.moves] = plant.last_move_error_m


def test_closed_loop_is_deterministic_and_perceptions_share_the_motion_noise():
    """Same seed, same run (camera mode: every frame's noise included); camera,
    physics-limited and oracle runs of one seed drive the same robot (motors, first turn time,
    each move's error), although the camera draws thousands of noise values the others do not."""
    board = Board.random((3, 3), obstacle_fraction=0.1, rng=np.random.default_rng(11))
    runs = {}
    for perception in ("camera", "camera", "ideal", "oracle"):
        errs = _MoveErrors()
        r = run_cover(board, CoverConfig(perception=perception, exposure="auto", seed=5), observers=[errs])
        assert complete(r), (perception, r)
        r.pop("wall_s")
        runs.setdefault(perception, []).append((r, errs.by_move))
    (a, ea), (b, eb) = runs["camera"]
    assert a == b and ea == eb  # same seed, same result
    for other in ("ideal", "oracle"):
        r, e = runs[other][0]
        assert r["moves"] == a["moves"] and e == ea  # the same tour, the same move errors
        assert r["turn_rate_error_pct"] == a["turn_rate_error_pct"]
    assert len(set(ea.values())) == a["moves"]  # each move its own draw
    other_seed = run_cover(board, CoverConfig(perception="oracle", seed=6))
    assert other_seed["turn_rate_error_pct"] != a["turn_rate_error_pct"]


def test_cover_plan_says_which_camera_a_map_needs(peer_data, capsys):
    """`stcvision cover plan` (the physics-limited camera): on spiral_stc_test.png at
    the Lego defaults the webcam's tour runs past its longest frame (64 x 30 s), the low-light
    camera's converges with frames of at most 30 s."""
    spiral = str(peer_data / "pythonrobotics_maps" / "spiral_stc_test.png")
    out = {}
    for camera in ("webcam", "lowlight"):
        assert main(["cover", "plan", "--map", spiral, "--camera", camera, "--json"]) == 0
        out[camera] = json.loads(capsys.readouterr().out)
    web, low = out["webcam"], out["lowlight"]
    assert not web["converges"] and web["abort_reason"].startswith("out of sight")
    assert web["longest_frame_s"] == 64 * 30.0 and web["tour_s"] > web["horizon_limit_s"]
    assert low["converges"] and low["subcells_covered"] == low["subcells_reachable"] == 1024
    assert low["longest_frame_s"] <= 30.0 and low["oldest_mark_read_s"] < low["tour_s"] < 20_000
    assert sum(f["frame_s"] * f["count"] for f in low["frames"]) < low["tour_s"]
    # the camera-mode robot's limit (frames sized by the noise they will have): on the webcam's
    # 8-bit stacks about half the idealised one (64 x 30 s is worth ~15 frames, not 64: the
    # horizon grows as ~n^(1/2.2)), on the 12-bit camera within 10 % of it
    assert 0.4 < web["camera_horizon_limit_s"] / web["horizon_limit_s"] < 0.65
    assert 0.9 < low["camera_horizon_limit_s"] / low["horizon_limit_s"] < 1.0
