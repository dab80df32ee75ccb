"""The STC robot as parts with public seams, so that a real robot can take the simulator's place.

A real robot's camera and motors can stand in for the simulated ones: what the controller's
actions drive (:class:`Motors`, :func:`act`), the
robot in the closed loop (:class:`Robot`: the plant, what it believes, the floor, its
perception, its count of moves), and what it keeps between two decisions
(:func:`robot_memory`).

The controller (:func:`stcvision.controllers.stc.fsm.step`) returns an action; :func:`act` carries it out on
any :class:`Motors`: the simulated robot here, the grid of :func:`stcvision.controllers.stc.oracle.run_oracle`,
a robot behind a serial link. The ant-like robot's memory between decisions is constant: its
controller state, its pose belief, its clock, its camera's settings and its count of moves
(:func:`robot_memory`); never a record of cells.
"""

from __future__ import annotations

import dataclasses
import pickle
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from stcvision.controllers.stc.belief import Belief, align_along, drive_forward, finish_turn, lay_row, recentre, turn
from stcvision.controllers.stc.config import ALIGN_MARK_M, RECENTRE_M
from stcvision.controllers.stc.fsm import Action, LookObs, NeighbourObs, StcObservation, StcPhase, StcState
from stcvision.controllers.stc.health import RobotStop
from stcvision.controllers.stc.movecount import MoveCount, MoveLog
from stcvision.controllers.stc.observers import Observer
from stcvision.stc_geometry import entry_axes

__all__ = ["Motors", "Robot", "act", "robot_memory"]


class Motors(Protocol):
    """What the controller's actions drive: the simulated robot, the oracle's grid, a real robot.

    Any object with these three methods will do (a structural type: no base class needed).
    """

    def mark(self) -> None:
        """Switch the rear LEDs on without moving (the start mark)."""

    def forward(self) -> str | None:
        """Lay a row on the rear edge of the sub-cell, then drive one sub-cell on.

        Returns
        -------
        str or None
            Why the robot cannot go on, or None.
        """

    def turn(self, left: bool) -> None:
        """Make a quarter turn in place.

        Parameters
        ----------
        left : bool
            Turn counter-clockwise; else clockwise.
        """


def act(action: Action, motors: Motors) -> str | None:
    """Carry out a controller action on any motors.

    ``LOOK`` and ``DONE`` move nothing (the look's reading is the next tick's observation).

    Parameters
    ----------
    action : Action
        What the controller asked for.
    motors : Motors
        What carries it out.

    Returns
    -------
    str or None
        Why the robot cannot go on (from ``Motors.forward``), or None.
    """
    if action is Action.MARK:
        motors.mark()
    elif action is Action.FORWARD:
        return motors.forward()
    elif action in (Action.TURN_LEFT, Action.TURN_RIGHT):
        motors.turn(action is Action.TURN_LEFT)
    return None


@dataclass(eq=False)
class Robot:
    """The robot in the closed loop: its motors (a :class:`Motors`) and its readings.

    Attributes
    ----------
    plant : object
        Its body, clock and motors: the simulator's
        :class:`stcvision.controllers.stc.plant.Plant`.
    belief : Belief
        What it believes of itself.
    floor : object
        What it marks.
    see : object
        Its perception (:mod:`stcvision.controllers.stc.perception`).
    count : MoveCount
        Its count of moves.
    watch : Observer
        Hears of every turn's measurement and every forward move.
    log : MoveLog or None
        The study switch's map of where it has been (``CoverConfig.move_log``), None in the
        ant-like robot.
    start_marks_by_count : int
        Decisions in the start cell whose frames missed the start mark, taken from the count.
    """

    plant: object
    belief: Belief
    floor: object
    see: object
    count: MoveCount
    watch: Observer = field(default_factory=Observer)
    log: MoveLog | None = None
    start_marks_by_count: int = 0

    # ------------------------------------------------------------------ the motors
    def mark(self) -> None:
        """Lay the start mark: the rear LEDs on without moving."""
        lay_row(self.plant, self.belief, self.floor)

    def forward(self) -> str | None:
        """Lay a row on the rear edge of the sub-cell, then drive one sub-cell on.

        A robot too far off its sub-cell centre drives back to it first, and one standing ahead
        of or behind it along its heading drives to it, so that the row lies on its box line.

        Returns
        -------
        str or None
            Why the robot cannot go on, or None.
        """
        plant, belief = self.plant, self.belief
        if self.log is not None:
            self.log.forward(belief.hc)
        self.count.forward(belief.hc)
        # a robot this far off its sub-cell centre (pushed, slipped) would lay its mark in the
        # wrong place, where the boxes read it wrongly: back to the centre first
        if np.hypot(*belief.offset_m) > RECENTRE_M:
            recentre(plant, belief)
        elif abs(belief.offset_m @ entry_axes(belief.hc)[1]) > ALIGN_MARK_M:
            # a row lies across the heading: standing behind (or ahead of) the centre lays it
            # off its box line by as much, so the robot drives along its heading to it first
            align_along(plant, belief)
        lay_row(plant, belief, self.floor)
        why = drive_forward(plant, belief)
        self.watch.on_move(plant, belief)
        return why

    def turn(self, left: bool) -> None:
        """Make a quarter turn, then measure the heading for the turn-time recalibration.

        Parameters
        ----------
        left : bool
            Turn counter-clockwise; else clockwise.
        """
        turn(self.plant, self.belief, left)
        err = self.see.heading_after_turn(self.plant, self.belief, self.floor)  # (takes frames, does not turn)
        self.watch.on_turn(self.plant, self.belief, err)
        finish_turn(self.plant, self.belief, left, err)

    # ------------------------------------------------------------------ the readings
    def read(self, state: StcState) -> StcObservation | LookObs | None:
        """Read what the controller needs in ``state``: a decision's observation, a look's, or nothing.

        Parameters
        ----------
        state : StcState
            The controller's state: ``DECIDE`` reads the cell, ``LOOK`` looks ahead.

        Returns
        -------
        StcObservation, LookObs or None
            The reading for the controller's next tick.

        Raises
        ------
        OutOfSight
            When no frame of the camera can rule out what the reading must
            (:class:`stcvision.controllers.stc.claims.OutOfSight`).
        RobotStop
            When a part finds the robot cannot go on
            (:class:`stcvision.controllers.stc.health.RobotStop`).
        """
        if state.phase is StcPhase.DECIDE and not state.closing:

            def observe() -> StcObservation:
                obs = self.see.observe(self.plant, self.belief, self.floor, fresh=state.fresh,
                                       at_start=state.at_start, start_cell=self.count.in_start_cell())  # fmt: skip
                # does a return close the tour? The count says, not a mark read 0.2-0.4 m away
                # (a row laid askew or a neighbour's row read there closed a tour away from its
                # start); the count is sure, so no look before a return is needed for it
                land = self.count.landing_at_start(self.belief.hc)
                obs = dataclasses.replace(obs, landing_marked=land, landing_known=(True,) * 4)
                return self._start_by_count(obs, state)

            obs = observe()
            return obs if self.log is None else self._checked_by_log(obs, observe)
        if state.phase is StcPhase.LOOK:
            marked = self.see.look(self.plant, self.belief, self.floor, landing=not state.child)
            if marked and state.child and self.log is not None:
                marked = self._look_by_log()
            return LookObs(marked)
        return None

    def _start_by_count(self, obs: StcObservation, state: StcState) -> StcObservation:
        """Take the start sub-cell from the count of moves, in the start cell.

        In the start cell the count says which sub-cell is the start sub-cell: a start mark the
        frames missed there (the tour's oldest mark) is the count's, and one read in another
        sub-cell is a row read on a start-mark line that is not the start mark: the robot will not
        decide on it. Outside the start cell a start mark read is checked by the frames
        (:meth:`stcvision.controllers.stc.frames.Exposures.decision`) and by :meth:`refuses`.
        """
        m = self.count.start_in_frame(self.belief.hc)
        if m is None or state.at_start or obs.misread or obs.start_mark == m:
            return obs
        if obs.start_mark is None:
            self.start_marks_by_count += m > 0  # (sub-cell 0 is under the robot: no camera sees it)
            return dataclasses.replace(obs, start_mark=m if m > 0 else None)
        why = f"misread: a start mark in sub-cell {obs.start_mark}, where the count of moves puts the start at {m}"
        return dataclasses.replace(obs, misread=why)

    def refuses(self, obs: StcObservation, state: StcState) -> str | None:
        """Say why the robot will not decide on an observation, or None.

        Parameters
        ----------
        obs : StcObservation
            The decision's observation.
        state : StcState
            The controller's state.

        Returns
        -------
        str or None
            Why: no STC tour shows this reading (``obs.misread``), or it shows the start mark
            where the count says the robot is not in its start cell. None when it may decide.
        """
        if obs.misread:
            return obs.misread
        if obs.start_mark is not None and not state.at_start and not self.count.in_start_cell():
            return f"start mark read away from the start ({self.count.done_away().split(': ', 1)[1]})"
        return None

    # ------------------------------------------------------------------ the study switch
    def _checked_by_log(self, obs: StcObservation, observe) -> StcObservation:
        """Check a reading against the map of where the robot has been.

        ``CoverConfig.move_log``: a neighbour read marked that the count never entered holds no
        mark the robot laid, so it stays a candidate child for the look to read again; a box
        read unlit whose row the count laid is a mark the frames missed, so the cell is read
        once more, and a second miss is not decided on.
        """
        log, hc = self.log, self.belief.hc
        suspect = log.suspect_neighbours(obs.neighbours, hc)
        if suspect:
            log.recounted += len(suspect)
            neigh = tuple(NeighbourObs(False, n.has_red) if d in suspect else n for d, n in enumerate(obs.neighbours))
            obs = dataclasses.replace(obs, neighbours=neigh)
        if obs.misread or not log.missed_boxes(obs.boxes, hc):
            return obs
        log.reread += 1
        again = observe()
        still = () if again.misread else log.missed_boxes(again.boxes, hc)
        if not still:
            return again
        boxes = ", ".join(map(str, still))
        why = f"misread: box {boxes} read unlit by two readings, though the robot's count of its moves laid its row"
        return dataclasses.replace(again, misread=why)

    def _look_by_log(self) -> bool:
        """Look again at a child read marked that the count never entered.

        ``CoverConfig.move_log``: a child read marked that the count never entered is looked at
        once more; marked again, no reading explains both the count and the frames.
        """
        if not self.log.never_entered_ahead(self.belief.hc):
            return True
        self.log.relooked += 1
        if self.see.look(self.plant, self.belief, self.floor, landing=False):
            raise RobotStop(
                f"misread: the cell ahead read marked by two looks at sub-cell {self.belief.sub}, though the robot's "
                "count of its moves never entered it"
            )
        return False


def robot_memory(robot: Robot, state: StcState) -> bytes:
    """Serialise everything the robot keeps between two decisions.

    Serialised with :mod:`pickle` (protocol 5): its controller state, its pose belief (the
    sub-cell, the compass heading, the offset from the sub-cell's centre and the heading's drift
    with their variances, the turn time), its clock, its camera's settings (the exposure ladder)
    and its count of moves. Not the floor, the plant or the referee (the world and its judge),
    nor the camera's calibration (dark frames, visibility horizons: measured once before the
    run, the same on any board). The study switch's
    :class:`stcvision.controllers.stc.movecount.MoveLog` is counted when it is on: it is what
    the ant-like robot must not need.

    Parameters
    ----------
    robot : Robot
        The robot in the loop.
    state : StcState
        The controller's state.

    Returns
    -------
    bytes
        The pickle; its ``len()`` is the summary's ``robot_memory_bytes``.
    """
    cam = getattr(robot.see, "cam", None)
    kept = (state, robot.belief, float(robot.plant.t), getattr(cam, "ladder", ()), robot.count, robot.log)
    return pickle.dumps(kept, protocol=5)
