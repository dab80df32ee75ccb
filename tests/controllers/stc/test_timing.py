"""The closed loop's overhead ratio (``stcvision bench``'s tour): every frame timed where the loop
takes it, and the ratio as its definition says; no time is asserted (speed is the bench's)."""

import json

import numpy as np
import pytest

from stcvision.cli import main
from stcvision.controllers.stc.experiments import random_board
from stcvision.controllers.stc.loop import CoverConfig, run_cover
from stcvision.controllers.stc.timing import FrameTimes, bench_loop, profile_loop
from stcvision.sim_camera import hardware
from stcvision.stc_geometry import DEFAULT_SUBCELL_M


@pytest.fixture(scope="module")
def cooled_tour():
    board = random_board(2, 2, 0.0, 1, DEFAULT_SUBCELL_M)
    cfg = CoverConfig(seed=1, camera=hardware.load_camera("cooled"))
    return board, cfg, bench_loop(board, cfg)


def test_every_frame_is_timed_and_the_ratio_is_its_definition(cooled_tour):
    _, _, r = cooled_tour
    assert r["loop_complete"] and r["loop_frames"] > 0
    assert r["loop_timed_frames"] == r["loop_frames"]  # the denominator's frames are the tour's
    per_frame = (r["loop_render_ms_median"] + r["loop_pipeline_ms_median"]) / 1e3
    assert r["loop_overhead_ratio"] == pytest.approx(r["loop_wall_s"] / (r["loop_frames"] * per_frame), rel=1e-12)
    # the frames are part of the tour: their own time cannot exceed it
    assert 0 < r["loop_frame_share"] <= 1 and 0 < r["loop_frame_cpu_share"] <= 1
    assert set(r["loop_stage_ms_median"]) >= {"dark", "window", "unwarp", "red", "observe"}


def test_timing_changes_no_decision(cooled_tour):
    """The timed tour is the tour: the same summary as the same run without the clocks."""
    board, cfg, r = cooled_tour
    plain = run_cover(board, cfg)
    assert (plain["frames"], plain["decisions"], plain["complete"]) == (
        r["loop_frames"],
        r["loop_decisions"],
        r["loop_complete"],
    )


def test_frame_times_keep_each_frame():
    times = FrameTimes()
    t0 = times.now()
    times.add_render(t0)
    times.add_pipeline(t0, {"dark": 0.5})
    assert len(times.render_s) == len(times.render_cpu_s) == len(times.pipeline_s) == 1
    assert np.all(np.asarray(times.render_s + times.pipeline_s) >= 0)


def test_a_tour_without_frames_has_no_ratio():
    board = random_board(2, 2, 0.0, 1, DEFAULT_SUBCELL_M)
    r = bench_loop(board, CoverConfig(seed=1, perception="oracle"))
    assert r["loop_frames"] == 0 and r["loop_overhead_ratio"] is None


def test_profile_table_lists_the_top_functions():
    board = random_board(2, 2, 0.0, 1, DEFAULT_SUBCELL_M)
    text = profile_loop(board, CoverConfig(seed=1, perception="oracle"), top=5)
    assert "tottime" in text and "top 5 by own time" in text


def test_bench_loop_only_from_the_command_line(capsys):
    assert main(["bench", "--loop-only", "--loop-board", "2x2", "--loop-seed", "1", "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["loop_board_cells"] == [2, 2] and r["loop_overhead_ratio"] > 0
    assert "render_ms_per_frame" not in r  # the tour alone
    assert main(["bench", "--loop-only", "--loop-board", "2x2", "--loop-seed", "1"]) == 0
    text = capsys.readouterr().out
    assert "loop overhead ratio" in text and "pipeline stages" in text
