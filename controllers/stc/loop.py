"""Closed-loop ant-like STC coverage: perception -> finite-state controller -> plant, with a
referee and observers watching.

The controller (:mod:`controllers.stc.fsm`) decides from one observation per cell entry; the
loop runs it on a board with honest time and honest marks, from its parts:

* the **plant** (:mod:`controllers.stc.plant`): the physical robot (true motion, clock, motors)
  and the floor it marks;
* the **belief** (:mod:`controllers.stc.belief`): what the robot believes of itself (sub-cell,
  compass heading, turn time, offset), updated by its acts and by perception's results;
* **perception** (:mod:`controllers.stc.perception`): camera, physics-limited camera or oracle;
* the **referee** (:mod:`controllers.stc.referee`): what the oracle would have decided;
* **observers** (:mod:`controllers.stc.observers`, :mod:`controllers.stc.recorder`): trace,
  rerun recording, the floor's picture.

Random streams: one seed, four independent children (``numpy.random.SeedSequence.spawn``), one
per component (:func:`streams`): the robot's motion (its motors, its first turn time, every
move's error), the camera (dark frames, every frame's noise), the oracle's read-out noise (the
pose as the oracle and the physics-limited camera read it) and the board (for callers that draw
a random board from the run's seed: the CLI). An extra frame therefore never reshuffles the
motion, and the camera, physics-limited and oracle runs of one seed drive the same robot.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from controllers.stc.belief import Belief, align_along, drive_forward, finish_turn, lay_row, recentre, turn
from controllers.stc.claims import OutOfSight
from controllers.stc.config import ALIGN_MARK_M, RECENTRE_M, CoverConfig
from controllers.stc.faults import Faults
from controllers.stc.fsm import Action, LookObs, NeighbourObs, StcObservation, StcPhase, decide, initial_state, step
from controllers.stc.geometry import COMPASS_VEC
from controllers.stc.health import CellsEntered, RobotStop, RowsLaid, done_away_from_start, landing_at_start
from controllers.stc.observers import Observers, Reading, Trace
from controllers.stc.oracle import coverage
from controllers.stc.perception import make_perception
from controllers.stc.plant import Floor, Plant
from controllers.stc.referee import Referee
from stcvision.stcgrid import entry_axes

__all__ = ["CoverConfig", "is_complete", "run_cover", "streams"]

STREAMS = ("motion", "camera", "oracle", "board")


def streams(seed: int) -> dict[str, np.random.Generator]:
    """One generator per component, independent children of ``seed``: :data:`STREAMS`."""
    kids = np.random.SeedSequence(seed).spawn(len(STREAMS))
    return {name: np.random.default_rng(k) for name, k in zip(STREAMS, kids, strict=True)}


def is_complete(summary: dict) -> bool:
    """A run of :func:`run_cover` is complete when every reachable sub-cell was covered exactly
    once, the robot finished back in its start cell, and (camera mode) made no decision the
    oracle would not have made."""
    return bool(
        summary["finished"]
        and summary["returned_to_start"]
        and summary["abort_reason"] is None
        and summary["subcells_covered"] == summary["subcells_reachable"]
        and summary["subcells_covered_more_than_once"] == 0
        and summary["decision_errors"] == 0
    )


def run_cover(board, cfg: CoverConfig | None = None, *, observers=(), perception_hook=None) -> dict:
    """Cover ``board`` from its start sub-cell; returns the summary the CLI prints.
    ``observers``: :class:`controllers.stc.observers.Observer` s (None entries are skipped);
    ``perception_hook(perception)`` is handed the run's perception (e.g. to read its frames).
    ``cfg.faults``: hardware faults built into the parts (:mod:`controllers.stc.faults`)."""
    wall0 = time.perf_counter()
    cfg = cfg if cfg is not None else CoverConfig()
    rngs = streams(cfg.seed)
    faults = Faults(cfg.faults, cfg.seed, cfg.perception)  # each fault draws from its own stream
    plant = Plant(board, cfg.robot, rngs["motion"], rate_factor=faults.rate_factor(),
                  disturbances=faults.disturbances())  # fmt: skip
    floor = Floor(board, lay_filter=faults.lay_filter())
    # facing the start heading as well as the turn time set before the run turns a quarter turn
    start_sigma_rad = cfg.robot.initial_turn_error * math.pi / 2
    belief = Belief.at_start(board, plant.calibrated_turn_s, cfg.robot.drive_sigma_m, start_sigma_rad)
    see = make_perception(cfg, board, camera_rng=rngs["camera"], oracle_rng=rngs["oracle"],
                          camera_wrap=faults.camera_wrap(board))  # fmt: skip
    if perception_hook is not None:
        perception_hook(see)
    watch = Observers([*observers, *([Trace()] if cfg.trace else [])])
    referee = Referee(board, active=see.refereed, report=watch.on_referee)
    run = _Run(board.start_subcell, check_rows=cfg.check_rows)
    try:
        _loop(run, cfg, plant, belief, floor, see, watch, referee)
    except RobotStop as stop:  # a part found that the robot cannot go on (controllers.stc.health)
        run.abort = f"{stop} (decision {run.decisions})"
    watch.on_end(plant, floor)
    out = _summary(board, cfg, plant, belief, see, referee, run, wall_s=time.perf_counter() - wall0)
    if faults:
        out["faults"] = faults.labels()
        out["fault_events"] = dict(faults.events)
    return out


class _Run:
    """The loop's counters and its outcome, and the robot's count of its moves from its start
    sub-cell ``start_sub``."""

    decisions = looks = 0
    finished = False
    abort: str | None = None
    moved = (0, 0)  # sub-cells moved from the start, by the robot's own compass (rows, columns)
    recounted = 0  # neighbours read marked that the count never entered, left to the look to read again
    relooked = 0  # looks that read a never-entered cell marked, taken again
    reread = 0  # decisions read again because a box read unlit holds a row the count laid

    def __init__(self, start_sub: tuple[int, int], *, check_rows: bool = True):
        self.entered = CellsEntered(start_sub)  # the cells that count has put the robot in
        self.rows = RowsLaid(start_sub)  # the rows that count says it laid
        self.check_rows = check_rows  # (CoverConfig.check_rows)


def _loop(run: _Run, cfg, plant, belief, floor, see, watch, referee) -> None:
    """Perception -> controller -> plant until the controller is done, the robot stops or
    ``cfg.max_decisions`` is reached; the outcome goes into ``run``."""
    state = initial_state()
    while run.decisions < cfg.max_decisions:
        try:
            obs = _read(state, plant, belief, floor, see, run)
        except OutOfSight as e:  # what the reading must rule out, no frame of its camera can
            run.abort = f"{e} (at sub-cell {belief.sub}, decision {run.decisions + (state.phase is StcPhase.DECIDE)})"
            return
        obs = _landing_by_count(obs, plant.board, belief, run.moved)
        if isinstance(obs, StcObservation):
            obs = _neighbours_by_count(obs, run, belief)
            run.decisions += 1
            if obs.misread:  # no STC tour shows this reading, not even with a longer frame
                run.abort = f"{obs.misread} (at sub-cell {belief.sub}, decision {run.decisions})"
                return
            if obs.start_mark is not None and not state.at_start:  # the start mark lies in the start cell only
                away = done_away_from_start(tuple(plant.board.start_subcell), run.moved)
                if away is not None:
                    run.abort = f"start mark read away from the start ({away.split(': ', 1)[1]})"
                    return
            watch.on_reading(Reading("decision", run.decisions, plant, belief, floor, obs=obs,
                                     decision=decide(obs, at_start=state.at_start), frame=see.last_frame))  # fmt: skip
            referee.decision(plant, belief, floor, obs, state, run.decisions)
        elif obs is not None:
            run.looks += 1
            referee.look(plant, belief, floor, obs.marked, landing=not state.child)
            watch.on_reading(
                Reading("look", run.decisions, plant, belief, floor, marked=obs.marked, frame=see.last_frame)
            )
        prev = state
        state, action = step(state, obs)
        referee.step(prev, state, action, plant, belief, run.decisions)
        watch.on_step(plant, belief, state, action)
        if action is Action.DONE:
            run.abort = done_away_from_start(tuple(plant.board.start_subcell), run.moved)
            run.finished = run.abort is None
            return
        if action is Action.FORWARD:  # the robot's own count of its moves on the grid
            run.rows.laid(run.moved, belief.hc)  # (the row behind it, laid before the move)
            di, dj = COMPASS_VEC[belief.hc]
            run.moved = (run.moved[0] + di, run.moved[1] + dj)
            run.entered.moved_to(run.moved)
        abort = _act(action, plant, belief, floor, see, watch)
        if abort is not None:
            run.abort = f"{abort} (decision {run.decisions})" if abort.startswith("drove") else abort
            return
    run.abort = f"gave up after {cfg.max_decisions} decisions"


def _landing_by_count(obs, board, belief: Belief, moved: tuple[int, int]):
    """A decision's ``landing_marked`` (does a return close the tour?) from the robot's count of
    its moves (:func:`controllers.stc.health.landing_at_start`), not from a mark read 0.2-0.4 m
    away: a row laid askew or a neighbour's row read there closed a tour away from its start.
    The count is sure, so no look before a return is needed for it."""
    if not isinstance(obs, StcObservation):
        return obs
    land = landing_at_start(tuple(board.start_subcell), moved, belief.hc)
    return dataclasses.replace(obs, landing_marked=land, landing_known=(True,) * 4)


def _neighbours_by_count(obs: StcObservation, run: _Run, belief: Belief) -> StcObservation:
    """A decision's neighbours read marked (no red light) that the robot's count of its moves
    never entered hold no mark it laid: the reading is wrong (a row of this cell or of another
    neighbour read into it, a noise peak). Passing such a neighbour by would leave it uncovered,
    so it stays a candidate child and the look from next to it, 2-3x closer, reads it again
    before the robot enters it or moves on (:func:`_look`)."""
    suspect = run.entered.suspect_neighbours(obs.neighbours, run.moved, belief.hc)
    if not suspect:
        return obs
    run.recounted += len(suspect)
    neigh = tuple(NeighbourObs(False, n.has_red) if d in suspect else n for d, n in enumerate(obs.neighbours))
    return dataclasses.replace(obs, neighbours=neigh)


def _boxes_by_count(obs: StcObservation, observe, run: _Run, belief: Belief) -> StcObservation:
    """A decision's boxes against the rows the robot's count of its moves says it laid
    (:class:`controllers.stc.health.RowsLaid`): a box read unlit that holds such a row is a mark
    the frames missed, so the cell is read once more (``observe()``); a second reading that
    still misses one is not decided on (``StcObservation.misread``). A reading the count agrees
    with is returned as it is."""
    if not run.check_rows or obs.misread or not run.rows.missed_boxes(obs.boxes, run.moved, belief.hc):
        return obs
    run.reread += 1
    again = observe()
    still = () if again.misread else run.rows.missed_boxes(again.boxes, run.moved, belief.hc)
    if not still:
        return again
    boxes = ", ".join(map(str, still))
    why = f"misread: box {boxes} read unlit by two readings, though the robot's count of its moves laid its row"
    return dataclasses.replace(again, misread=why)


def _read(state, plant: Plant, belief: Belief, floor: Floor, see, run: _Run) -> StcObservation | LookObs | None:
    """What the controller reads in ``state``: a decision's observation, a look's, or nothing.
    ``run.moved``: the robot's count of its moves, which says whether it is in its start cell."""
    if state.phase is StcPhase.DECIDE and not state.closing:
        start_cell = done_away_from_start(tuple(plant.board.start_subcell), run.moved) is None

        def observe() -> StcObservation:
            return see.observe(plant, belief, floor, fresh=state.fresh, at_start=state.at_start, start_cell=start_cell)

        return _boxes_by_count(observe(), observe, run, belief)
    if state.phase is StcPhase.LOOK:
        return LookObs(_look(state, plant, belief, floor, see, run))
    return None


def _look(state, plant: Plant, belief: Belief, floor: Floor, see, run: _Run) -> bool:
    """The look before leaving a cell: marked or not. A child read marked that the count of
    moves never entered is looked at once more: read unmarked, the robot enters it (where the
    first-entry check reads its floor with longer frames: ``Exposures._settle_fresh``); read
    marked again, no reading explains both the count and the frames, and the robot stops."""
    marked = see.look(plant, belief, floor, landing=not state.child)
    if not (marked and state.child and run.entered.never_entered(run.moved, belief.hc)):
        return marked
    run.relooked += 1
    if see.look(plant, belief, floor, landing=False):
        raise RobotStop(
            f"misread: the cell ahead read marked by two looks at sub-cell {belief.sub}, though the robot's count "
            "of its moves never entered it"
        )
    return False


def _act(action: Action, plant: Plant, belief: Belief, floor: Floor, see, watch) -> str | None:
    """The robot carries out ``action`` with what it believes; after a turn the perception
    measures the heading for the recalibration. Returns why the run must stop, or None."""
    if action is Action.MARK:
        lay_row(plant, belief, floor)
    elif action is Action.FORWARD:
        # a robot this far off its sub-cell centre (pushed, slipped) would lay its mark in the
        # wrong place, where the boxes read it wrongly: back to the centre first
        if np.hypot(*belief.offset_m) > RECENTRE_M:
            recentre(plant, belief)
        elif abs(belief.offset_m @ entry_axes(belief.hc)[1]) > ALIGN_MARK_M:
            # a row lies across the heading: standing behind (or ahead of) the centre lays it
            # off its box line by as much, so the robot drives along its heading to it first
            align_along(plant, belief)
        lay_row(plant, belief, floor)
        return drive_forward(plant, belief)
    elif action in (Action.TURN_LEFT, Action.TURN_RIGHT):
        left = action is Action.TURN_LEFT
        turn(plant, belief, left)
        err = see.heading_after_turn(plant, belief, floor)  # (takes frames, does not turn)
        watch.on_turn(plant, belief, err)
        finish_turn(plant, belief, left, err)
    return None


def _summary(board, cfg, plant, belief, see, referee, run: _Run, *, wall_s: float) -> dict:
    # the sub-cell the robot ended in: the one it believes, checked within 0.45 sub-cell of the
    # truth after every move (Plant.check_lost), so the two agree
    cov = coverage(board, plant.visits, belief.sub, finished=run.finished, moves=plant.moves)
    out = {
        "perception": cfg.perception,
        "exposure": cfg.exposure,
        "camera": cfg.camera.name,
        "robot": cfg.robot.name,
        "board_cells": list(board.shape_cells),
        **{k: cov[k] for k in ("subcells_reachable", "subcells_covered", "subcells_covered_more_than_once")},
        "returned_to_start": cov["returned_to_start"],
        "finished": run.finished,
        "abort_reason": run.abort,
        "moves": plant.moves,
        "turns": plant.turns,
        "decisions": run.decisions,
        "looks": run.looks,
        "look_errors": referee.look_errors,
        "reobserved": see.reobserved,
        "sim_time_s": plant.t,
        "wall_s": wall_s,
        "decision_errors": referee.decision_errors,
        "max_mark_age_read_s": referee.max_age_read,
        "max_position_error_m": plant.max_pos_err,
        "recentred": plant.recentred,
        "aligned": plant.aligned,
        "turn_time_s_final": belief.turn_s,
        "turn_rate_error_pct": 100 * (plant.rate_gain - 1),
        "frames": see.frames,
        "long_exposures": see.long_frames,
        "neighbours_recounted": run.recounted,
        "relooked": run.relooked,
        "offsets_left_out": belief.fix.rejected,
        "boxes_reread": run.reread,
    }
    # the referee's verdict: the robot's "finished" says only that it believes it is done
    out["complete"] = is_complete(out)
    if referee.first_error is not None:
        out["first_decision_error"] = referee.first_error
    return out
