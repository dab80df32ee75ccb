"""The STC robot's parts: the action dispatch over any motors, and what the robot keeps between
two decisions (constant, whatever the board)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from stcvision.controllers.stc.experiments import random_board
from stcvision.controllers.stc.fsm import Action
from stcvision.controllers.stc.loop import CoverConfig, run_cover
from stcvision.controllers.stc.robot import act

ROOM = Path(__file__).resolve().parents[3] / "controllers" / "stc"


class _Recorder:
    def __init__(self):
        self.did = []

    def mark(self):
        self.did.append("mark")

    def forward(self):
        self.did.append("forward")
        return "blocked" if len(self.did) > 3 else None

    def turn(self, left):
        self.did.append("left" if left else "right")


def test_act_drives_any_motors():
    motors = _Recorder()
    assert [act(a, motors) for a in (Action.MARK, Action.TURN_LEFT, Action.LOOK, Action.FORWARD)] == [None] * 4
    assert act(Action.TURN_RIGHT, motors) is None and act(Action.DONE, motors) is None
    assert act(Action.FORWARD, motors) == "blocked"
    assert motors.did == ["mark", "left", "forward", "right", "forward"]


def test_the_robots_memory_is_the_same_on_a_small_and_a_large_board():
    """What the robot keeps between two decisions (``robot_memory_bytes``, the largest over the
    tour), on an 8x8 and a 60x60 board: equal within 16 bytes (a pickled integer grows by a byte
    past 255); the study switch's map grows with the board."""
    small = run_cover(random_board(8, 8, 0.1, 3), CoverConfig(perception="oracle", seed=3))
    large = run_cover(random_board(60, 60, 0.1, 3), CoverConfig(perception="oracle", seed=3))
    assert small["complete"] and large["complete"]
    assert abs(small["robot_memory_bytes"] - large["robot_memory_bytes"]) <= 16
    assert 0 < small["robot_memory_bytes"] < 2048
    logged = run_cover(random_board(8, 8, 0.1, 3), CoverConfig(perception="oracle", seed=3, move_log=True))
    assert logged["complete"] and logged["robot_memory_bytes"] > small["robot_memory_bytes"] + 500


@pytest.mark.parametrize("name", ["robot.py", "loop.py", "fsm.py", "movecount.py", "belief.py", "localise.py"])
def test_the_ant_like_robot_holds_no_container_that_grows_with_the_board(name):
    """The robot's own modules keep no set, dict or list across decisions, apart from the study
    switch's :class:`stcvision.controllers.stc.movecount.MoveLog`: no attribute is assigned a container
    display or constructor outside it."""
    tree = ast.parse((ROOM / name).read_text())
    grown = []
    for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef) and n.name != "MoveLog"):
        for node in ast.walk(cls):
            if isinstance(node, (ast.Assign, ast.AnnAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                value = node.value
                containers = (ast.Set, ast.Dict, ast.List, ast.SetComp, ast.DictComp, ast.ListComp)
                built = isinstance(value, ast.Call) and getattr(value.func, "id", "") in ("set", "dict", "list")
                if any(isinstance(t, ast.Attribute) for t in targets) and (isinstance(value, containers) or built):
                    grown.append(f"{cls.name}: line {node.lineno}")
    assert not grown, grown


class _Reads:
    """A perception whose decisions read ``obs`` (and nothing else of the robot)."""

    last_frame = None

    def __init__(self, obs):
        self.obs = obs

    def observe(self, plant, belief, floor, *, fresh, at_start, start_cell):
        return self.obs


def test_the_start_cell_takes_its_start_mark_from_the_count_when_the_frames_miss_it():
    """In the start cell the count of moves says which sub-cell is the start sub-cell: a reading
    that missed the start mark (the tour's oldest mark) gets it from the count; one that reads it
    in another sub-cell is not decided on; outside the start cell the reading stands."""
    from stcvision.controllers.stc.belief import Belief
    from stcvision.controllers.stc.fsm import NeighbourObs, StcObservation, StcPhase, StcState
    from stcvision.controllers.stc.movecount import MoveCount
    from stcvision.controllers.stc.robot import Robot

    def read(start_mark, moved):
        obs = StcObservation(boxes=(False,) * 5, neighbours=(NeighbourObs(False, False),) * 4, start_mark=start_mark)
        # start sub-cell (5, 5); facing south from (4, 4), the start sub-cell is entry-frame sub-cell 2
        robot = Robot(None, Belief((5 + moved[0], 5 + moved[1]), 2, 1.5), None, _Reads(obs), MoveCount((5, 5), moved))
        return robot.read(StcState(phase=StcPhase.DECIDE)), robot.start_marks_by_count

    assert MoveCount((5, 5), (-1, -1)).start_in_frame(2) == 2
    got, n = read(None, (-1, -1))
    assert got.start_mark == 2 and not got.misread and n == 1
    got, n = read(2, (-1, -1))
    assert got.start_mark == 2 and n == 0
    got, _ = read(1, (-1, -1))
    assert got.misread.startswith("misread: a start mark in sub-cell 1, where the count of moves puts the start at 2")
    got, n = read(None, (-3, -1))  # two sub-cells on: another cell
    assert got.start_mark is None and not got.misread and n == 0


@pytest.mark.parametrize("turns", [(True, False, False), (False,), (True, True), ()])
def test_turns_no_row_measured_are_taken_out_at_the_first_measured_turn(turns):
    """Turns timed with a turn time 3 % short, none measured (no row in view), then a right turn
    measured against the newest row, laid after them: the heading ends on the grid, not on that
    row, and the row is known to be askew by what the
    unmeasured turns left (``realigned_rad``)."""
    import math

    import numpy as np

    from stcvision.angles import wrap_angle
    from stcvision.controllers.stc.belief import Belief, finish_turn, turn
    from stcvision.controllers.stc.plant import Plant
    from stcvision.sim_camera.board import Board
    from stcvision.sim_camera.robot import LEGO_STC_ROBOT

    board = Board(np.zeros((4, 4), bool), (3, 1))
    plant = Plant(board, LEGO_STC_ROBOT, np.random.default_rng(0))
    belief = Belief.at_start(board, 0.97 * (math.pi / 2) / plant.true_rate(0.0))
    for left in turns:
        turn(plant, belief, left)
        finish_turn(plant, belief, left, None)
    left_over = plant.heading_error(belief.hc)  # what the unmeasured turns left, in every row laid now
    assert abs(left_over) == pytest.approx(abs(sum(1 if x else -1 for x in turns)) * 0.03 * math.pi / 2, rel=0.01)
    row = plant.heading_rad  # a row laid here
    turn(plant, belief, False)
    finish_turn(plant, belief, False, wrap_angle(plant.heading_rad + math.pi / 2 - row))  # measured against the row
    # (to 0.05 degrees: the motors' rate fades a little from turn to turn)
    assert plant.heading_error(belief.hc) == pytest.approx(0.0, abs=math.radians(0.05))
    assert belief.realigned_rad == pytest.approx(-left_over, abs=math.radians(0.05))
    assert belief.unmeasured_turns == 0
