"""Closed-loop ant-like STC coverage, with a referee and observers watching.

Perception -> finite-state controller -> plant, in turn, until the run ends.

The controller (:mod:`stcvision.controllers.stc.fsm`) decides from one observation per cell entry; the
loop runs it on a board with honest time and honest marks, from its parts:

* the **plant** (:mod:`stcvision.controllers.stc.plant`): the physical robot (true motion, clock, motors)
  and the floor it marks;
* the **belief** (:mod:`stcvision.controllers.stc.belief`): what the robot believes of itself (sub-cell,
  compass heading, turn time, offset), updated by its acts and by perception's results;
* **perception** (:mod:`stcvision.controllers.stc.perception`): camera, physics-limited camera or oracle;
* the **referee** (:mod:`stcvision.controllers.stc.referee`): what the oracle would have decided;
* **observers** (:mod:`stcvision.controllers.stc.observers`, :mod:`stcvision.controllers.stc.recorder`): trace,
  rerun recording, the floor's picture.

Random streams: one seed, four independent children (``numpy.random.SeedSequence.spawn``), one
per component (:func:`streams`): the robot's motion (its motors, its first turn time, every
move's error), the camera (dark frames, every frame's noise), the oracle's read-out noise (the
pose as the oracle and the physics-limited camera read it) and the board (for callers that draw
a random board from the run's seed: the CLI). An extra frame therefore never reshuffles the
motion, and the camera, physics-limited and oracle runs of one seed drive the same robot.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from stcvision.controllers.stc.belief import Belief
from stcvision.controllers.stc.choose import make_controller
from stcvision.controllers.stc.claims import OutOfSight
from stcvision.controllers.stc.config import CoverConfig
from stcvision.controllers.stc.faults import Faults
from stcvision.controllers.stc.fsm import Action, StcObservation, StcPhase, initial_state
from stcvision.controllers.stc.health import RobotStop
from stcvision.controllers.stc.link import LinkError
from stcvision.controllers.stc.movecount import MoveCount, MoveLog
from stcvision.controllers.stc.observers import Observers, Reading, Trace
from stcvision.controllers.stc.oracle import coverage
from stcvision.controllers.stc.perception import make_perception
from stcvision.controllers.stc.plant import Floor, Plant
from stcvision.controllers.stc.referee import Referee
from stcvision.controllers.stc.robot import Robot, act, robot_memory

__all__ = ["CoverConfig", "LoopEnd", "build_parts", "is_complete", "read_tick", "run_cover", "streams", "summarise"]

STREAMS = ("motion", "camera", "oracle", "board")


def streams(seed: int) -> dict[str, np.random.Generator]:
    """One generator per component, independent children of ``seed``: :data:`STREAMS`."""
    kids = np.random.SeedSequence(seed).spawn(len(STREAMS))
    return {name: np.random.default_rng(k) for name, k in zip(STREAMS, kids, strict=True)}


def is_complete(summary: dict) -> bool:
    """Say whether a run of :func:`run_cover` is complete.

    A run of :func:`run_cover` is complete when every reachable sub-cell was covered exactly
    once, the robot finished back in its start cell, and (camera mode) made no decision the
    oracle would not have made.
    """
    return bool(
        summary["finished"]
        and summary["returned_to_start"]
        and summary["abort_reason"] is None
        and summary["subcells_covered"] == summary["subcells_reachable"]
        and summary["subcells_covered_more_than_once"] == 0
        and summary["decision_errors"] == 0
    )


def run_cover(board, cfg: CoverConfig | None = None, *, observers=(), perception_hook=None) -> dict:
    """Cover a board with the ant-like STC robot, from its start sub-cell.

    The robot reads its cell (perception), the controller decides, the motors act, until the
    controller is done, a part stops the robot, or ``cfg.max_decisions`` is reached.

    Parameters
    ----------
    board : Board
        The board to cover (:class:`stcvision.sim_camera.board.Board`).
    cfg : CoverConfig, optional
        The run's robot, camera, perception, seed and limits (the defaults when None).
        ``cfg.faults``: hardware faults built into the parts
        (:mod:`stcvision.controllers.stc.faults`).
    observers : sequence of Observer
        :class:`stcvision.controllers.stc.observers.Observer` s, told of every step (None
        entries are skipped).
    perception_hook : callable, optional
        ``perception_hook(perception)`` is handed the run's perception (e.g. to read its frames).

    Returns
    -------
    dict
        The summary the CLI prints: coverage, whether the robot finished and returned to the
        start, why it stopped, moves, turns, decisions, looks, the referee's errors, times,
        frames and the floor's checks; with faults, the faults and their events.
    """
    wall0 = time.perf_counter()
    cfg = cfg if cfg is not None else CoverConfig()
    robot, referee, watch, faults = build_parts(board, cfg, observers=observers, perception_hook=perception_hook)
    end = LoopEnd()
    controller = make_controller(cfg.fsm, mcu=cfg.mcu)  # the part that decides: Python, host C or the firmware
    try:
        _loop(robot, controller, cfg.max_decisions, watch, referee, end)
    except (RobotStop, LinkError) as stop:  # a part found the robot cannot go on, or the firmware's link failed
        end.abort = f"{stop} (decision {end.decisions})"
    finally:
        controller.close()
    watch.on_end(robot.plant, robot.floor)
    out = summarise(board, cfg, robot, referee, end, wall_s=time.perf_counter() - wall0)
    if faults:
        out["faults"] = faults.labels()
        out["fault_events"] = dict(faults.events)
    return out


def build_parts(board, cfg: CoverConfig, *, observers=(), perception_hook=None):
    """Build the parts of one run of ``board``.

    The robot (plant, belief, floor, perception, count of moves), the referee, the observers
    and the faults built into them; the run's loop, or a simulated robot behind a serial link
    (:mod:`stcvision.controllers.stc.simrobot`), drives them.
    """
    rngs = streams(cfg.seed)
    faults = Faults(cfg.faults, cfg.seed, cfg.perception)  # each fault draws from its own stream
    plant = Plant(board, cfg.robot, rngs["motion"], rate_factor=faults.rate_factor(),
                  disturbances=faults.disturbances())  # fmt: skip
    # facing the start heading as well as the turn time set before the run turns a quarter turn
    start_sigma_rad = cfg.robot.initial_turn_error * math.pi / 2
    belief = Belief.at_start(board, plant.calibrated_turn_s, cfg.robot.drive_sigma_m, start_sigma_rad)
    see = make_perception(cfg, board, camera_rng=rngs["camera"], oracle_rng=rngs["oracle"],
                          camera_wrap=faults.camera_wrap(board))  # fmt: skip
    if perception_hook is not None:
        perception_hook(see)
    watch = Observers([*observers, *([Trace()] if cfg.trace else [])])
    count = MoveCount(tuple(board.start_subcell))
    robot = Robot(plant, belief, Floor(board, lay_filter=faults.lay_filter()), see, count, watch,
                  MoveLog(count) if cfg.move_log else None)  # fmt: skip
    referee = Referee(board, active=see.refereed, report=watch.on_referee)
    return robot, referee, watch, faults


@dataclass(slots=True)
class LoopEnd:
    """How the loop went.

    Its decisions and looks, whether the controller finished, why the robot stopped (None: it
    did not), and the most the robot kept between two decisions
    (:func:`stcvision.controllers.stc.robot.robot_memory`, bytes).
    """

    decisions: int = 0
    looks: int = 0
    finished: bool = False
    abort: str | None = None
    memory_bytes: int = 0


def _loop(robot: Robot, controller, max_decisions: int, watch, referee, end: LoopEnd) -> None:
    """Run perception, ``controller`` and motors in turn until the run ends.

    The controller is :mod:`stcvision.controllers.stc.controller`'s part. The run ends when the
    controller is done, the robot stops or ``max_decisions`` is reached; the outcome goes into
    ``end``.
    """
    state = initial_state()
    while end.decisions < max_decisions:
        obs, why = read_tick(robot, state, end)
        if why is not None:
            end.abort = why
            return
        prev = state
        state, action, decision = controller.step(state, obs)
        _tell(robot, watch, referee, end, prev, state, obs, decision)
        referee.step(prev, state, action, robot.plant, robot.belief, end.decisions)
        watch.on_step(robot.plant, robot.belief, state, action)
        if action is Action.DONE:
            end.abort = robot.count.done_away()
            end.finished = end.abort is None
            return
        why = act(action, robot)
        if why is not None:
            end.abort = f"{why} (decision {end.decisions})" if why.startswith("drove") else why
            return
    end.abort = f"gave up after {max_decisions} decisions"


def read_tick(robot: Robot, state, end: LoopEnd):
    """Read one tick in ``state``, counted in ``end``.

    Returns (reading, why): the reading, and why the robot stops instead of deciding on it
    (None: it goes on).
    """
    try:
        obs = robot.read(state)
    except OutOfSight as e:  # what the reading must rule out, no frame of its camera can
        at = end.decisions + (state.phase is StcPhase.DECIDE)
        return None, f"{e} (at sub-cell {robot.belief.sub}, decision {at})"
    deciding = isinstance(obs, StcObservation)
    end.decisions += deciding
    end.looks += obs is not None and not deciding
    why = robot.refuses(obs, state) if deciding else None
    if why is not None:  # no STC tour shows this reading: stop before deciding on it
        return obs, f"{why} (at sub-cell {robot.belief.sub}, decision {end.decisions})"
    return obs, None


def _tell(robot: Robot, watch, referee, end: LoopEnd, prev, state, obs, decision) -> None:
    """Tell the observers and the referee of a reading and the decision made of it.

    The robot's memory is measured here, between two decisions.
    """
    plant, belief, floor, frame = robot.plant, robot.belief, robot.floor, robot.see.last_frame
    if isinstance(obs, StcObservation):
        watch.on_reading(Reading("decision", end.decisions, plant, belief, floor, obs=obs, decision=decision,
                                 frame=frame))  # fmt: skip
        referee.decision(plant, belief, floor, obs, prev, end.decisions, decision)
        end.memory_bytes = max(end.memory_bytes, len(robot_memory(robot, state)))
    elif obs is not None:
        referee.look(plant, belief, floor, obs.marked, landing=not prev.child)
        watch.on_reading(Reading("look", end.decisions, plant, belief, floor, marked=obs.marked, frame=frame))


def summarise(board, cfg, robot: Robot, referee, end: LoopEnd, *, wall_s: float) -> dict:
    """Sum up a run of ``board``: the result :func:`run_cover` returns (its faults aside).

    The settings, the cover (from where the plant truly went), how the loop went (``end``), the
    robot's counts and the floor's checks, ``wall_s`` the run's wall time (s), and whether the
    run is complete (the referee's verdict: the robot's own ``finished`` says only that it
    believes it is done).
    """
    # the sub-cell the robot ended in: the one it believes, checked within 0.45 sub-cell of the
    # truth after every move (Plant.check_lost), so the two agree
    plant, belief, see = robot.plant, robot.belief, robot.see
    cov = coverage(board, plant.visits, belief.sub, finished=end.finished, moves=plant.moves)
    cam = getattr(see, "cam", None)
    out = {
        "perception": cfg.perception,
        "exposure": cfg.exposure,
        "camera": cfg.camera.name,
        "robot": cfg.robot.name,
        "board_cells": list(reversed(board.shape_cells)),  # width x height, as --board takes it
        **{k: cov[k] for k in ("subcells_reachable", "subcells_covered", "subcells_covered_more_than_once")},
        "returned_to_start": cov["returned_to_start"],
        "finished": end.finished,
        "abort_reason": end.abort,
        "moves": plant.moves,
        "turns": plant.turns,
        "decisions": end.decisions,
        "looks": end.looks,
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
        # the floor's checks (camera): neighbours read marked by dots showing no tour's row,
        # looks taken again for dots in no row, returns read again for a box near its reach,
        # boxes a short frame read lit and a longer one unlit, read again, start marks read
        # where the count puts the robot outside its start cell, dropped
        "neighbours_unproven": getattr(cam, "unproven", 0),
        "relooked": getattr(cam, "relooked", 0),
        "returns_reread": getattr(cam, "reread_old", 0),
        "boxes_disputed": getattr(cam, "disputed", 0),
        "start_marks_dropped": getattr(cam, "starts_dropped", 0),
        "start_marks_by_count": robot.start_marks_by_count,
        "offsets_left_out": belief.fix.rejected,
        "move_log": cfg.move_log,
        "robot_memory_bytes": end.memory_bytes,
    }
    if robot.log is not None:  # the study switch's own checks
        log = robot.log
        out |= {"log_neighbours_recounted": log.recounted, "log_relooked": log.relooked, "log_boxes_reread": log.reread}
    # the referee's verdict: the robot's "finished" says only that it believes it is done
    out["complete"] = is_complete(out)
    if referee.first_error is not None:
        out["first_decision_error"] = referee.first_error
    return out
