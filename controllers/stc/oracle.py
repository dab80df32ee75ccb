"""The STC controller on a grid with perfect observations: the floor's record of marks
(:class:`MarkFloor`), what a perfect camera would report (:func:`observe_oracle`,
:func:`look_oracle`) and :func:`run_oracle`, which runs :func:`stcvision.controllers.stc.fsm.step` against
them and checks every decision with the true visit history (no physics, no camera).

``run_oracle`` checks the five-box table against the true visit history at every decision
(``decision_mismatches``) and counts marks of the current cell lying outside the five boxes and
the start-mark positions (``box_table_violations``); the tests find both zero on hundreds of
random boards.
"""

from __future__ import annotations

import numpy as np

from stcvision.controllers.stc.fsm import Action, LookObs, NeighbourObs, StcObservation, StcPhase, initial_state, step
from stcvision.controllers.stc.grid import (
    BOXES,
    COMPASS_NAMES,
    COMPASS_VEC,
    behind,
    cell_of,
    frame_compass,
    frame_subcells,
    start_heading,
    step_from,
    turned,
)
from stcvision.controllers.stc.robot import act
from stcvision.stc_geometry import START_MARKS

__all__ = ["MarkFloor", "coverage", "landing_oracle", "look_oracle", "observe_oracle", "run_oracle"]


class MarkFloor:
    """The marks on the floor: per sub-cell, the set of marked edges (compass 0..3)."""

    def __init__(self, shape_subcells: tuple[int, int]):
        rows, cols = shape_subcells
        self.shape = (int(rows), int(cols))
        self.edges: dict[tuple[int, int], set[int]] = {}
        self.cell_count = np.zeros((rows // 2, cols // 2), int)

    def mark(self, sub: tuple[int, int], edge: int) -> None:
        s = self.edges.setdefault((int(sub[0]), int(sub[1])), set())
        if edge % 4 not in s:
            s.add(edge % 4)
            self.cell_count[sub[0] // 2, sub[1] // 2] += 1

    def has(self, sub: tuple[int, int], edge: int) -> bool:
        return edge % 4 in self.edges.get((sub[0], sub[1]), ())

    def cell_has_marks(self, ci: int, cj: int) -> bool:
        cr, cc = self.cell_count.shape
        return bool(0 <= ci < cr and 0 <= cj < cc and self.cell_count[ci, cj] > 0)


def observe_oracle(
    floor: MarkFloor, board, robot_subcell: tuple[int, int], heading: int, *, camera_view: bool = False
) -> StcObservation:
    """The perfect camera: what the vision should report with the robot in ``robot_subcell``
    heading ``heading`` (compass), taking that pose as the entry frame. ``camera_view``: what a
    real camera can see -- marks in the robot's own sub-cell are under its body, so a start mark
    there is not reported."""
    subs = frame_subcells(robot_subcell, heading)
    boxes = tuple(floor.has(subs[m], frame_compass(heading, d)) for m, d in BOXES)
    start = None
    for m in range(1 if camera_view else 0, 4):
        if floor.has(subs[m], frame_compass(heading, START_MARKS[m])):
            start = m
            break
    ci, cj = robot_subcell[0] // 2, robot_subcell[1] // 2
    total = int(floor.cell_count[ci, cj])
    other = total - sum(boxes) - (start is not None)
    neigh = []
    landing = []
    for d in range(4):
        di, dj = COMPASS_VEC[frame_compass(heading, d)]
        a, b = ci + di, cj + dj
        neigh.append(NeighbourObs(has_marks=floor.cell_has_marks(a, b), has_red=not board.is_cell_free(a, b)))
        land = (subs[d][0] + di, subs[d][1] + dj)
        landing.append(bool(floor.edges.get(land)))
    return StcObservation(boxes, tuple(neigh), start, other, tuple(landing))


def look_oracle(floor: MarkFloor, robot_subcell: tuple[int, int], heading: int) -> LookObs:
    """The perfect look at the cell ahead of a robot in ``robot_subcell`` heading ``heading``."""
    return LookObs(floor.cell_has_marks(*cell_of(step_from(robot_subcell, heading))))


def landing_oracle(floor: MarkFloor, robot_subcell: tuple[int, int], heading: int) -> LookObs:
    """The perfect look before a return to the parent: any mark in the sub-cell just ahead (the
    one the robot lands on; marked only when the tour closes there, on the start sub-cell)."""
    return LookObs(bool(floor.edges.get(step_from(robot_subcell, heading))))


def run_oracle(
    board, *, max_steps: int = 1_000_000, keep_mismatches: int = 20, camera_view: bool = False, controller=None
) -> dict:
    """Run :func:`step` (or ``controller.step``: a part of
    :mod:`stcvision.controllers.stc.controller`) against :func:`observe_oracle` on ``board``.

    The true visit history and spanning tree are kept here, outside the controller, only to
    check every decision (box inference, parent, chosen neighbour, start/done recognition).

    ``subcells_covered_more_than_once`` does not count the last move that closes the tour onto
    the start sub-cell (``closed_loop`` is then ``True``); every other re-entry counts.
    """
    rows, cols = board.shape_subcells
    s = tuple(board.start_subcell)
    h = start_heading(board)
    start_cell = board.start_cell
    floor = MarkFloor((rows, cols))
    visits = np.zeros((rows, cols), int)
    visits[s] += 1
    vh = COMPASS_VEC[h]
    parent_of = {start_cell: (start_cell[0] - vh[0], start_cell[1] - vh[1])}  # virtual parent
    cell_visited = np.zeros(board.shape_cells, bool)
    cell_visited[start_cell] = True
    state = initial_state()
    tick = step if controller is None else controller.step
    grid = _GridMotors(board, floor, s, h, visits, parent_of, cell_visited)
    steps = decisions = box_violations = looks = 0
    mismatches: list[dict] = []
    box_patterns: dict[tuple[int, ...], int] = {}
    n_mismatch = 0
    finished = False
    while steps < max_steps:
        steps += 1
        s, h = grid.sub, grid.hc
        deciding = state.phase is StcPhase.DECIDE and not state.closing  # closing: DONE without looking
        obs = observe_oracle(floor, board, s, h, camera_view=camera_view) if deciding else None
        if state.phase is StcPhase.LOOK:
            obs = (look_oracle if state.child else landing_oracle)(floor, s, h)
        state, action, dec = tick(state, obs)
        if deciding:
            decisions += 1
            bad = _check_decision(dec, obs, board, s, h, visits, parent_of, cell_visited, start_cell, grid.moves)
            if not dec.done:
                box_violations += obs.other_marks > 0
                key = tuple(k + 1 for k, lit in enumerate(obs.boxes) if lit)
                box_patterns[key] = box_patterns.get(key, 0) + 1
            if bad:
                n_mismatch += 1
                if len(mismatches) < keep_mismatches:
                    mismatches.append({"subcell": s, "heading": COMPASS_NAMES[h], **bad})
        looks += action is Action.LOOK
        if action is Action.DONE:
            finished = True
            break
        if act(action, grid) is not None:  # drove off the board or into an obstacle
            break
    s = grid.sub
    return {
        **coverage(board, visits, s, finished=finished, moves=grid.moves),
        "moves": grid.moves,
        "turns": grid.turns,
        "marks": grid.marks,
        "looks": looks,
        "steps": steps,
        "decisions": decisions,
        "collisions": grid.collisions,
        "box_table_violations": box_violations,
        "box_patterns": box_patterns,
        "decision_mismatches": n_mismatch,
        "mismatch_examples": mismatches,
        "final_subcell": s,
    }


class _GridMotors:
    """:class:`stcvision.controllers.stc.robot.Motors` on the grid: exact moves and turns, marks in the
    floor's record, and the true visit history and spanning tree that ``run_oracle`` checks every
    decision against."""

    def __init__(self, board, floor: MarkFloor, sub, hc: int, visits, parent_of, cell_visited):
        self.board, self.floor, self.sub, self.hc = board, floor, tuple(sub), hc
        self.visits, self.parent_of, self.cell_visited = visits, parent_of, cell_visited
        self.moves = self.turns = self.marks = self.collisions = 0

    def mark(self) -> None:
        self.floor.mark(self.sub, behind(self.hc))
        self.marks += 1

    def forward(self) -> str | None:
        self.floor.mark(self.sub, behind(self.hc))
        n = step_from(self.sub, self.hc)
        rows, cols = self.board.shape_subcells
        if not (0 <= n[0] < rows and 0 <= n[1] < cols) or self.board.blocked[n]:
            self.collisions += 1
            return f"drove into an obstacle or off the board at {n}"
        c_old, c_new = cell_of(self.sub), cell_of(n)
        if c_new != c_old and c_new not in self.parent_of:
            self.parent_of[c_new] = c_old
        self.cell_visited[c_new] = True
        self.visits[n] += 1
        self.sub = n
        self.moves += 1
        return None

    def turn(self, left: bool) -> None:
        self.hc = turned(self.hc, left)
        self.turns += 1


def coverage(board, visits: np.ndarray, final_sub: tuple[int, int], *, finished: bool, moves: int) -> dict:
    """What a tour covered (``visits``: per sub-cell) and where it ended. The tour closes on the
    start sub-cell: that last arrival is not a second coverage (``closed_loop``); every other
    re-entry counts."""
    reachable = board.reachable_cells()
    closed_loop = finished and tuple(final_sub) == tuple(board.start_subcell) and moves > 0
    repeat = visits.copy()
    if closed_loop:
        repeat[final_sub] -= 1
    return {
        "subcells_reachable": int(4 * reachable.sum()),
        "subcells_covered": int((visits > 0).sum()),
        "subcells_covered_more_than_once": int((repeat > 1).sum()),
        "closed_loop": closed_loop,
        "subcells_uncovered_reachable": int((~(visits > 0) & np.repeat(np.repeat(reachable, 2, 0), 2, 1)).sum()),
        "returned_to_start": (final_sub[0] // 2, final_sub[1] // 2) == board.start_cell,
        "finished": finished,
    }


def _check_decision(dec, obs, board, s, h, visits, parent_of, cell_visited, start_cell, moves) -> dict:
    """Differences between ``dec`` and the ground truth from the true history ({} if none)."""
    subs = frame_subcells(s, h)
    cell = (s[0] // 2, s[1] // 2)
    bad = {}
    true_start = cell == start_cell
    if dec.is_start != true_start:
        bad["is_start"] = (dec.is_start, true_start)
    true_done = s == tuple(board.start_subcell) and moves > 0
    if dec.done != true_done:
        bad["done"] = (dec.done, true_done)
    if true_done:
        return bad
    # sub-cell 0 is never visited on entry; 1..3 visited iff the robot has stood there
    true_v = tuple(bool(visits[subs[m]] > 0) for m in (1, 2, 3))
    if visits[subs[0]] != 1:
        bad["entry_subcell_visits"] = int(visits[subs[0]])
    if dec.visited != true_v:
        bad["visited"] = (dec.visited, true_v)
    p = parent_of[cell]
    pc = {COMPASS_VEC[c]: c for c in range(4)}[(p[0] - cell[0], p[1] - cell[1])]
    true_parent = (h + 1 - pc) % 4
    if dec.parent != true_parent:
        bad["parent"] = (dec.parent, true_parent)

    def truly_new(d):
        di, dj = COMPASS_VEC[frame_compass(h, d)]
        a, b = cell[0] + di, cell[1] + dj
        return board.is_cell_free(a, b) and not cell_visited[a, b]

    order = [(true_parent + k) % 4 for k in (1, 2, 3)] + ([true_parent] if true_start else [])
    true_child = next((d for d in order if truly_new(d)), None)
    if dec.child != true_child:
        bad["child"] = (dec.child, true_child)
    return bad
