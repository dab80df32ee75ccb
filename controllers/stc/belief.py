"""What the STC robot believes of itself, apart from the world: the sub-cell it stands in, its
compass heading, the time its motors take for 90 degrees, and its offset from the sub-cell
centre (:class:`Belief`); and the robot's acts, which command the plant
(:class:`stcvision.controllers.stc.plant.Plant`) with what the robot believes and update the belief with
what it did or measured.

The plant is the physical robot (true pose, clock, motors); perception reads frames taken at
the true pose and its results (the offset it measured, the heading error after a turn) update
the belief, never the plant. Reading the belief against the plant is what the referee and the
observers do (the position error, the heading error).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from stcvision.controllers.stc.grid import start_heading, step_from, turned
from stcvision.controllers.stc.localise import Bearing, Fix
from stcvision.stc_geometry import entry_axes

__all__ = ["Belief", "align_along", "drive_forward", "finish_turn", "lay_row", "recentre", "realign", "turn"]


@dataclass(slots=True)
class Belief:
    """The robot's own state of itself (mutable: it is updated as the robot acts and sees).

    ``sub`` (row, column) the sub-cell it believes it stands in; ``hc`` its compass heading
    (0 N, clockwise); ``turn_s`` its rotation time for 90 degrees; ``offset_m`` where it believes
    it stands off the sub-cell's centre (world, m), from its localisation, ``fix`` how sure
    it is of it and ``bearing`` how sure of its heading (:mod:`stcvision.controllers.stc.localise`);
    ``realigned_rad`` how far it turned towards the grid (:func:`realign`) since it laid its
    newest row, which was laid that much askew of the heading it now has;
    ``unmeasured_turns`` its quarter turns (left +1, right -1) since the last one a row
    measured (:func:`finish_turn`)."""

    sub: tuple[int, int]
    hc: int
    turn_s: float
    offset_m: np.ndarray = field(default_factory=lambda: np.zeros(2))
    fix: Fix = field(default_factory=lambda: Fix.placed(0.0))
    bearing: Bearing = field(default_factory=Bearing.unknown)
    realigned_rad: float = 0.0
    unmeasured_turns: int = 0

    @classmethod
    def at_start(
        cls, board, turn_s: float, step_sigma_m: float = 0.0, heading_sigma_rad: float | None = None
    ) -> Belief:
        """On the start sub-cell, facing the board's start heading to within
        ``heading_sigma_rad`` (None: :meth:`~stcvision.controllers.stc.localise.Bearing.unknown`), turn
        time ``turn_s`` (set before the run: :attr:`stcvision.controllers.stc.plant.Plant.calibrated_turn_s`);
        placed on its centre as well as one move of error ``step_sigma_m`` ends there."""
        return cls(
            tuple(board.start_subcell),
            start_heading(board),
            float(turn_s),
            fix=Fix.placed(step_sigma_m),
            bearing=Bearing.unknown() if heading_sigma_rad is None else Bearing.placed(heading_sigma_rad),
        )


def turn(plant, belief: Belief, left: bool) -> None:
    """A 90-degree timed turn; the robot now believes it faces the next compass heading, as
    surely as the recalibration on its newest row will set it (:func:`finish_turn`)."""
    plant.turn(left, belief.turn_s)
    belief.hc = turned(belief.hc, left)
    belief.bearing.turned()


def finish_turn(plant, belief: Belief, left: bool, heading_err_rad: float | None) -> None:
    """The ant-like STC paper's recalibration after a turn, from the heading error measured after
    it: what the turn really did updates the turn time the robot believes, then the robot turns
    back by the error.

    A turn no row measured (``heading_err_rad`` None: no row in view, as after the start's
    turns, whose start mark lies under the robot) keeps its error, and every row laid after it
    carries that error, which later turns, measured on those rows, keep. Those turns were timed
    like the next measured one and erred as it did (a rate off nominal), so that turn's error
    times the unmeasured turns' net count (left +1, right -1: ``Belief.unmeasured_turns``) is
    taken out too, and the newest row is that much askew of the heading (17x17 board, seed 2708:
    the first three turns unmeasured, 2.6 degrees left in the heading and in every row, which
    pulled it back whenever a red light set it right, until the robot was 7.7 cm off and lost)."""
    from stcvision.stages import recalibrate_turn

    sign = 1 if left else -1
    if heading_err_rad is None:
        belief.unmeasured_turns += sign
        return
    turned = math.pi / 2 + sign * heading_err_rad
    rec = recalibrate_turn(belief.turn_s, turned)
    # a measurement the recalibration clips is a misreading: nothing of it goes to other turns
    bias = belief.unmeasured_turns * sign * heading_err_rad if rec.accepted and not rec.clipped else 0.0
    belief.unmeasured_turns = 0
    if rec.accepted:
        belief.turn_s = rec.turn_time_s
    plant.rotate_by(-heading_err_rad - bias, belief.turn_s)
    belief.realigned_rad -= bias


def realign(plant, belief: Belief, rad: float) -> None:
    """Turn by ``rad`` towards the grid as a reference other than the newest row shows it (the
    red lights, the lean of all rows): the newest row is now that much askew of the heading,
    which the next turn's recalibration on it must not undo."""
    plant.rotate_by(rad, belief.turn_s)
    belief.realigned_rad += rad


def lay_row(plant, belief: Belief, floor) -> None:
    """The rear LEDs' row on the sub-cell's rear edge, laid with the heading the robot now has."""
    plant.lay_mark(floor, belief.sub, belief.hc)
    belief.realigned_rad = 0.0


def recentre(plant, belief: Belief) -> None:
    """Drive back to the sub-cell centre as the robot believes it; it then believes it is there."""
    plant.recentre(belief.offset_m, belief.turn_s)
    belief.offset_m = np.zeros(2)


def align_along(plant, belief: Belief) -> None:
    """Drive along the heading to the sub-cell centre as the robot believes it (the along-heading
    part of the believed offset, no turn), so that the row it lays next lies on its line; the
    lateral part stays for the forward move to take out."""
    ux, uy = entry_axes(belief.hc)[1]
    along = float(belief.offset_m @ (ux, uy))
    plant.drive_along(-along)
    belief.offset_m = belief.offset_m - along * np.array([ux, uy])


def drive_forward(plant, belief: Belief) -> str | None:
    """The drive to the next sub-cell along the believed heading; the robot then believes
    it stands at that sub-cell's centre. Returns why the run must stop, or None."""
    moved, why = plant.forward(belief.sub, belief.hc, belief.offset_m, belief.turn_s)
    if moved:
        belief.sub = step_from(belief.sub, belief.hc)
        belief.offset_m = np.zeros(2)
        belief.fix.moved()
    return why
