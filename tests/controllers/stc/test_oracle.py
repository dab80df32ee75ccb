"""Ant-like STC controller in ORACLE mode (perfect observations on a grid, no physics/camera)."""

import dataclasses
import enum
from pathlib import Path

import numpy as np
import pytest

from stcvision.controllers.stc.fsm import (
    REENTRY_BOXES,
    Action,
    NeighbourObs,
    StcObservation,
    StcPhase,
    StcState,
    decide,
    initial_state,
    step,
)
from stcvision.controllers.stc.grid import COMPASS_VEC, start_heading
from stcvision.controllers.stc.oracle import MarkFloor, look_oracle, observe_oracle, run_oracle
from stcvision.sim_camera.board import Board

MAPS = Path(__file__).resolve().parents[3] / "datasets" / "peer_data" / "pythonrobotics_maps"


def _assert_full_cover(r, board):
    assert r["collisions"] == 0
    assert r["finished"], r
    assert r["returned_to_start"], r
    assert r["decision_mismatches"] == 0, r["mismatch_examples"]
    assert r["box_table_violations"] == 0
    assert r["subcells_covered"] == r["subcells_reachable"] == 4 * int(board.reachable_cells().sum())
    assert r["subcells_uncovered_reachable"] == 0
    assert r["subcells_covered_more_than_once"] == 0
    assert r["moves"] == r["subcells_reachable"] - 1 + r["closed_loop"]


def _random_boards(n, seed0):
    for seed in range(seed0, seed0 + n):
        rng = np.random.default_rng(seed)
        cr, cc = (int(v) for v in rng.integers(2, 11, 2))
        frac = float(rng.uniform(0.0, 0.35))
        yield seed, rng, Board.random((cr, cc), obstacle_fraction=frac, rng=rng)


def test_random_boards_default_start():
    closed = 0
    for _seed, _, board in _random_boards(250, 1000):
        r = run_oracle(board, max_steps=100_000)
        _assert_full_cover(r, board)
        closed += r["closed_loop"]
    assert closed > 0  # some runs exercise the "virtual parent free" ending


def test_random_boards_random_start_subcell_and_heading():
    """Any free sub-cell as start (so all four start headings), virtual parent often free."""
    closed = 0
    patterns = set()
    for _seed, rng, board in _random_boards(250, 5000):
        free = np.argwhere(np.repeat(np.repeat(board.cell_free, 2, 0), 2, 1))
        start = tuple(int(v) for v in free[rng.integers(len(free))])
        b = Board(board.blocked, start)
        r = run_oracle(b, max_steps=100_000)
        _assert_full_cover(r, b)
        closed += r["closed_loop"]
        patterns |= set(r["box_patterns"])
    assert closed > 10
    # the lit-box sets on (re-)entry: all five boxes occur, nothing else (box_table_violations);
    # the camera's reading of a return is checked against these (stcvision.controllers.stc.claims.check_return)
    assert patterns == {(), *REENTRY_BOXES}


@pytest.mark.parametrize("start", [(0, 0), (0, 1), (1, 0), (1, 1)])
def test_single_cell(start):
    b = Board(np.zeros((2, 2), bool), start)
    r = run_oracle(b, max_steps=100)
    _assert_full_cover(r, b)
    assert r["moves"] == 3 and not r["closed_loop"]


def test_open_rectangle_stops_beside_start():
    # interior start: the virtual parent (north) is reached around the loop first, so it is
    # marked when the start cell finally scans it; the robot stops beside the start sub-cell
    b = Board(np.zeros((8, 10), bool), (5, 5))
    r = run_oracle(b, max_steps=10_000)
    _assert_full_cover(r, b)
    assert not r["closed_loop"] and r["final_subcell"][0] // 2 == 2 and r["final_subcell"][1] // 2 == 2


def test_corridor_closes_loop_on_start_subcell():
    # a 1-cell-wide N-S corridor, start in the middle heading north: north first, then the
    # virtual parent (south) last; the return from it lands on the start sub-cell
    blocked = np.ones((6, 6), bool)
    blocked[:, 2:4] = False
    b = Board(blocked, (3, 3))
    r = run_oracle(b, max_steps=10_000)
    _assert_full_cover(r, b)
    assert r["closed_loop"] and r["final_subcell"] == (3, 3)


@pytest.mark.parametrize("name", ["spiral_stc_test.png", "spiral_stc_test_2.png", "spiral_stc_test_3.png"])
def test_pythonrobotics_maps(name):
    b = Board.from_file(MAPS / name)
    r = run_oracle(b, max_steps=1_000_000)
    _assert_full_cover(r, b)


def _final_state(board):
    """Drive the controller like run_oracle does and return every state it went through."""
    states = []
    state = initial_state()
    s, h = tuple(board.start_subcell), start_heading(board)
    floor = MarkFloor(board.shape_subcells)
    for _ in range(100_000):
        obs = observe_oracle(floor, board, s, h) if state.phase is StcPhase.DECIDE else None
        if state.phase is StcPhase.LOOK:
            obs = look_oracle(floor, s, h)
        state, action, _ = step(state, obs)
        states.append(state)
        if action is Action.DONE:
            break
        if action is Action.FORWARD:
            floor.mark(s, (h + 2) % 4)
            s = (s[0] + COMPASS_VEC[h][0], s[1] + COMPASS_VEC[h][1])
        elif action is Action.TURN_LEFT:
            h = (h + 3) % 4
        elif action is Action.TURN_RIGHT:
            h = (h + 1) % 4
        elif action is Action.MARK:
            floor.mark(s, (h + 2) % 4)
    return states


def test_state_is_constant_size_scalars():
    small = _final_state(Board(np.zeros((4, 4), bool), (1, 1)))
    big = _final_state(Board(np.zeros((40, 40), bool), (21, 21)))
    assert len(big) > 10 * len(small)
    sizes = {len(dataclasses.astuple(st)) for st in small + big}
    assert sizes == {len(dataclasses.fields(StcState))}
    for st in small + big:
        for f in dataclasses.fields(st):
            v = getattr(st, f.name)
            assert isinstance(v, (bool, int, enum.Enum)), (f.name, type(v))
            if isinstance(v, int) and not isinstance(v, bool):
                assert 0 <= v < (16 if f.name == "free" else 4)  # free: four bits
    with pytest.raises(dataclasses.FrozenInstanceError):
        small[0].phase = StcPhase.DONE


def _obs(boxes=(0, 0, 0, 0, 0), marks=(0, 0, 0, 0), red=(0, 0, 0, 0), start=None):
    n = tuple(NeighbourObs(bool(m), bool(r)) for m, r in zip(marks, red, strict=True))
    return StcObservation(tuple(bool(b) for b in boxes), n, start)


def test_decide_table_cases():
    # new cell: parent behind, first free neighbour counter-clockwise after it = right
    d = decide(_obs(marks=(0, 0, 0, 1)))
    assert (d.parent, d.child, d.target, d.final) == (3, 0, 0, False)
    # sub-cells 2, 3 visited (boxes 2 and 4): parent forward; the left and back neighbours look
    # new, but their exits lie beyond visited sub-cells (a tour never leaves so: their marks
    # were missed), so the next one counter-clockwise that can be reached is the right one
    d = decide(_obs(boxes=(0, 1, 0, 1, 0), marks=(0, 1, 0, 0)))
    assert d.visited == (False, True, True) and (d.parent, d.child) == (1, 0)
    # the same cell with the right neighbour taken: back to the parent
    d = decide(_obs(boxes=(0, 1, 0, 1, 0), marks=(1, 1, 0, 0)))
    assert (d.parent, d.child, d.target) == (1, None, 1)
    # sub-cells 1..3 visited via boxes 1 / 3 / 4: parent right, nothing free -> return right
    d = decide(_obs(boxes=(1, 0, 1, 1, 0), marks=(1, 1, 1, 1)))
    assert (d.parent, d.child, d.target, d.final) == (0, None, 0, False)
    # start cell, nothing free: finish the cell's sub-cells and stop in sub-cell 3
    d = decide(_obs(red=(1, 1, 1, 1), start=0))
    assert (d.is_start, d.child, d.target, d.final, d.done) == (True, None, 3, True, False)
    # start cell, virtual parent free and last: go there
    d = decide(_obs(red=(1, 1, 1, 0), start=0))
    assert (d.child, d.target, d.final) == (3, 3, False)
    # back on the start sub-cell with 1..3 visited: done
    d = decide(_obs(boxes=(1, 1, 0, 1, 0), start=0))
    assert d.done
    # start cell re-entered in another sub-cell: 1..3 visited, start sub-cell is 1 -> not done
    d = decide(_obs(boxes=(0, 1, 0, 1, 1), marks=(0, 1, 1, 1), red=(1, 0, 0, 0), start=1))
    assert not d.done and d.parent == 0 and d.child is None and d.final and d.target == 0


def test_step_start_sequence_and_done_is_absorbing():
    s, a1, _ = step(initial_state(), None)
    s, a2, _ = step(s, None)
    s, a3, _ = step(s, None)
    assert (a1, a2, a3) == (Action.TURN_LEFT, Action.MARK, Action.TURN_RIGHT)
    assert s.phase is StcPhase.DECIDE
    s, a, _ = step(s, _obs(red=(1, 1, 1, 1), start=0))
    assert a is Action.FORWARD  # 0 -> 1 straight ahead
    done = StcState(phase=StcPhase.DONE)
    assert step(done, None)[:2] == (done, Action.DONE)


def test_checker_catches_a_wrong_box_rule(monkeypatch):
    """The ground-truth check is not vacuous: drop box 5 from the 'sub-cell 1 visited' rule (in
    the controller's own decision, which run_oracle checks)."""
    import stcvision.controllers.stc.fsm as fsm
    import stcvision.controllers.stc.oracle as stc

    real = fsm.decide

    def broken(obs, **kw):
        b = list(obs.boxes)
        b[4] = False
        return real(dataclasses.replace(obs, boxes=tuple(b)), **kw)

    monkeypatch.setattr(fsm, "decide", broken)
    bad = 0
    for _seed, _, board in _random_boards(30, 1000):
        r = stc.run_oracle(board, max_steps=100_000)
        bad += r["decision_mismatches"] > 0
    assert bad > 0


@pytest.mark.parametrize("seed", range(4))
def test_camera_view_oracle_closes_the_tour_from_the_floor(seed):
    """With the start mark under the robot hidden (as from its own camera), the tour still
    ends on the start sub-cell: the landing sub-cell of the last return is seen marked."""
    rng = np.random.default_rng(900 + seed)
    for _ in range(40):
        cells = tuple(int(v) for v in rng.integers(2, 9, 2))
        board = Board.random(cells, obstacle_fraction=float(rng.uniform(0, 0.3)), rng=rng)
        r = run_oracle(board, camera_view=True)
        assert r["finished"] and r["returned_to_start"], r
        assert r["subcells_covered"] == r["subcells_reachable"], r
        assert r["subcells_covered_more_than_once"] == 0, r
        assert r["decision_mismatches"] == 0, r["mismatch_examples"]


def test_a_look_that_finds_marks_moves_the_exit_on():
    """The decision took the forward neighbour for new; the look from sub-cell 1 finds marks
    there, so the robot walks on to the left neighbour, looks again and enters it."""
    from stcvision.controllers.stc.fsm import LookObs

    s, a, _ = step(StcState(phase=StcPhase.DECIDE), _obs(marks=(0, 0, 0, 1), red=(1, 0, 0, 0)))
    assert a is Action.FORWARD and s.sub == 1 and s.target == 1  # 0 -> 1, towards the exit forward
    s, a, _ = step(s, None)
    assert a is Action.LOOK and s.phase is StcPhase.LOOK
    s, a, _ = step(s, LookObs(marked=True))  # forward was visited after all: on to the left one
    assert a is Action.TURN_LEFT and s.target == 2 and s.child
    s, a, _ = step(s, None)
    assert a is Action.FORWARD and s.sub == 2
    s, a, _ = step(s, None)
    assert a is Action.LOOK
    s, a, _ = step(s, LookObs(marked=False))
    assert a is Action.FORWARD and s.phase is StcPhase.DECIDE and s.fresh


def test_looks_that_find_every_child_marked_return_to_the_parent():
    from stcvision.controllers.stc.fsm import LookObs

    s, a, _ = step(StcState(phase=StcPhase.DECIDE), _obs(marks=(0, 0, 1, 1)))
    assert a is Action.TURN_RIGHT and s.target == 0  # right looked free: face it
    s, a, _ = step(s, None)
    assert a is Action.LOOK
    s, a, _ = step(s, LookObs(marked=True))  # right: visited; forward looked free
    assert (a, s.target, s.child) == (Action.TURN_LEFT, 1, True)
    s, a, _ = step(s, None)
    assert a is Action.FORWARD and s.sub == 1
    s, a, _ = step(s, None)
    assert a is Action.LOOK
    s, a, _ = step(s, LookObs(marked=True))  # nothing else free: back to the parent (sub-cell 3)
    assert s.target == 3 and not s.child and not s.final
    actions = []
    for _ in range(8):
        s, a, _ = step(s, None)
        actions.append(a)
        if s.phase is StcPhase.DECIDE:
            break
    # the decision's frames could tell the landing sub-cell is unmarked: no look before leaving
    assert Action.LOOK not in actions and actions[-1] is Action.FORWARD and s.phase is StcPhase.DECIDE


@pytest.mark.parametrize("marked", [False, True])
def test_a_landing_the_decision_could_not_see_is_looked_at_before_the_return(marked):
    """The decision's frames could not tell whether the sub-cell a return to the parent lands
    on is marked (``landing_known`` false): at the exit the robot looks at it, from next to it.
    Marked, it is the start sub-cell and the move closes the tour (no decision there)."""
    from stcvision.controllers.stc.fsm import LookObs

    obs = dataclasses.replace(_obs(marks=(1, 1, 1, 0)), landing_known=(True, True, True, False))
    s, a, _ = step(StcState(phase=StcPhase.DECIDE), obs)
    while a is not Action.LOOK:  # no child: walk to sub-cell 3, face the parent
        assert s.phase is not StcPhase.DECIDE
        s, a, _ = step(s, None)
    assert s.sub == 3 and s.heading == 3 and not s.child
    s, a, _ = step(s, LookObs(marked=marked))
    assert a is Action.FORWARD and s.phase is StcPhase.DECIDE and s.closing is marked
    if marked:
        assert step(s, None)[:2] == (StcState(phase=StcPhase.DONE), Action.DONE)
