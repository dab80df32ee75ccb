"""The plant of the coverage loop: the robot's true motion and clock, and the floor it marks.

* **Robot** (:class:`stcvision.sim_camera.robot.MarkingRobot`, by default the STC paper's Lego robot built from
  ``stcvision.sim_camera.robot.LEGO_STC``): drives one sub-cell (16 cm) at the cruise speed, turns 90
  degrees by a timed command at a rate that is off nominal by up to ``rate_spread`` per robot
  and fades with the battery (``fade_per_h``), and keeps its rear UV LEDs on for ``led_on_s``
  before every forward move (the STC paper: "for a few seconds"). Moves are kinematic on the floor
  plane: the robot drives straight along its *true* heading, with ``drive_sigma_m`` of distance
  error per move; the pymunk world is not needed for these straight moves between free cells.
* **Rotation-time recalibration** (ant-like STC paper): after a turn, the heading the perception
  measured tells what the turn really did; the robot turns the rest of the way and updates the
  turn time it believes, ``T' = 90/d * T`` (:func:`stcvision.controllers.stc.belief.finish_turn`).
* **Floor**: marks are laid in the phosphor layer at the true LED positions, at the true time;
  they fade by the afterglow law. The floor also keeps the record of which (sub-cell, edge) was
  marked when (:class:`stcvision.controllers.stc.oracle.MarkFloor`): the oracle's and the referee's truth.

The plant is mutable on purpose (it *is* the world's state); what the robot believes of itself is
not here but in :class:`stcvision.controllers.stc.belief.Belief`; nothing here decides.
"""

from __future__ import annotations

import math

import numpy as np

from stcvision.angles import wrap_angle
from stcvision.controllers.stc.grid import behind, cell_of, compass_to_rad, start_heading, step_from
from stcvision.controllers.stc.oracle import MarkFloor
from stcvision.stc_geometry import entry_axes

__all__ = ["Floor", "Plant"]


class Floor:
    """The marks on the board: the phosphor dots (what a camera sees) and their record."""

    def __init__(self, board, *, lay_filter=None):
        from stcvision.sim_camera.phosphor import PhosphorLayer

        #: which of a mark's dots are laid (``xy -> xy``): all, unless an LED is dead (a fault)
        self.lay_filter = lay_filter

        self.phosphor = PhosphorLayer()
        self.record = MarkFloor(board.shape_subcells)
        self.laid: list[tuple[tuple[int, int], int]] = []  # (sub-cell, edge) of every four dots, in order
        self.laid_at: dict[tuple[tuple[int, int], int], float] = {}  # when each mark's LEDs went off
        #: the same times by the cell each mark is in, so that a decision's question of the five
        #: cells around it costs a look at those cells, not one at every mark of the tour
        self._laid_in: dict[tuple[int, int], dict[tuple[tuple[int, int], int], float]] = {}
        #: the mark (index into ``laid``) of every phosphor dot: a mark has four dots, or fewer
        #: when an LED is dead (:mod:`stcvision.controllers.stc.faults`)
        self.dot_mark = np.zeros(0, int)

    def lay(self, xy_m, sub: tuple[int, int], edge: int, t_s: float, duration_s: float) -> None:
        if self.lay_filter is not None:
            xy_m = self.lay_filter(xy_m)
        self.phosphor.charge(xy_m, t_start_s=t_s, duration_s=duration_s)
        self.dot_mark = np.concatenate([self.dot_mark, np.full(len(np.reshape(xy_m, (-1, 2))), len(self.laid))])
        self.record.mark(sub, edge)
        self.laid.append((sub, edge))
        self.laid_at[(sub, edge)] = t_s + duration_s
        self._laid_in.setdefault(cell_of(sub), {})[(sub, edge)] = t_s + duration_s

    def oldest_near(self, sub: tuple[int, int], t_s: float) -> float:
        """The age of the oldest mark in the cell of ``sub`` and its four neighbours (what a
        decision there reads), 0 if none."""
        ci, cj = cell_of(sub)
        near = ((ci, cj), (ci - 1, cj), (ci + 1, cj), (ci, cj - 1), (ci, cj + 1))  # the cell and its 4 neighbours
        ages = [t_s - t for c in near for t in self._laid_in.get(c, {}).values()]
        return max(ages, default=0.0)


class Plant:
    """The physical robot on ``board``: its true pose, clock, motors and what it has done.

    It holds nothing the robot believes: each command takes what the robot believes it needs
    (its sub-cell, compass heading, turn time ``turn_s``, offset from the sub-cell centre) as
    arguments, from :class:`stcvision.controllers.stc.belief.Belief`, and the true rate and the true
    heading apply. ``rng`` draws this robot's motors (rate off nominal, the first turn time's
    error) and every move's distance error. ``rate_factor`` and ``disturbances`` are faults
    (:mod:`stcvision.controllers.stc.faults`) built into the motors and the moves."""

    def __init__(self, board, robot, rng: np.random.Generator, *, rate_factor=None, disturbances=()):
        self.board = board
        #: the turn rate's factor over time (a drifting motor, :mod:`stcvision.controllers.stc.faults`), else 1
        self.rate_factor = rate_factor
        #: what may befall the robot after a forward move (``after_move(plant, start_xy)``): faults
        self.disturbances = tuple(disturbances)
        self.robot = robot
        self.rng = rng
        start = tuple(board.start_subcell)
        c = board.subcell_center_m(*start)
        self.x, self.y, self.heading_rad = float(c[0]), float(c[1]), compass_to_rad(start_heading(board))
        self.t = 0.0
        self.rate_gain = 1.0 + rng.uniform(-robot.rate_spread, robot.rate_spread)  # this robot's motors
        self.nominal_rate = (math.pi / 2) / robot.turn_90_s
        # T, the robot's rotation time for 90 degrees: set before the run to what the first
        # rotation needs (ant-like STC paper: "We initially set T to a time that let's the robot
        # do the first rotation accurate enough"), to within ``initial_turn_error`` (1 sigma);
        # the robot starts believing it (Belief.turn_s) and recalibrates it after every turn
        off = 1 + rng.normal(0, robot.initial_turn_error)
        self.calibrated_turn_s = (math.pi / 2) / (self.nominal_rate * self.rate_gain) * off
        self.visits = np.zeros(board.shape_subcells, int)  # forward moves into each sub-cell
        self.visits[start] += 1
        self.moves = self.turns = 0
        self.recentred = 0  # moves back to the sub-cell centre before a mark (:meth:`recentre`)
        self.aligned = 0  # moves along the heading to the centre before a row (belief.align_along)
        self.last_move_error_m = 0.0  # the distance error of the last forward move (drawn)
        self.max_pos_err = 0.0

    # ------------------------------------------------------------------ what is true
    @property
    def pose(self) -> tuple[float, float, float]:
        return self.x, self.y, self.heading_rad

    def true_rate(self, t_s: float) -> float:
        rate = self.nominal_rate * self.rate_gain * max(0.5, 1.0 - self.robot.fade_per_h * t_s / 3600.0)
        return rate if self.rate_factor is None else rate * self.rate_factor(t_s)

    def heading_error(self, hc: int) -> float:
        """True heading less compass heading ``hc`` (the one the robot believes it has), rad."""
        return wrap_angle(self.heading_rad - compass_to_rad(hc))

    def true_offset(self, sub: tuple[int, int]) -> np.ndarray:
        """Where the robot truly stands off the centre of sub-cell ``sub`` (world, m)."""
        ideal = self.board.subcell_center_m(*sub)
        return np.array([self.x - ideal[0], self.y - ideal[1]])

    # ------------------------------------------------------------------ what the robot does
    def wait(self, dt_s: float) -> None:
        self.t += dt_s

    def rotate_by(self, angle_rad: float, turn_s: float) -> None:
        """A small correction turn timed at the rate ``turn_s`` implies (the true rate applies)."""
        est_rate = (math.pi / 2) / turn_s
        dur = abs(angle_rad) / est_rate
        self.heading_rad = wrap_angle(self.heading_rad + math.copysign(1.0, angle_rad) * self.true_rate(self.t) * dur)
        self.t += dur

    def turn(self, left: bool, turn_s: float) -> None:
        """A 90-degree timed turn: ``turn_s`` at the true rate."""
        sign = 1.0 if left else -1.0
        self.heading_rad = wrap_angle(self.heading_rad + sign * self.true_rate(self.t) * turn_s)
        self.t += turn_s
        self.turns += 1

    def recentre(self, offset_m: np.ndarray, turn_s: float) -> None:
        """Drive by ``-offset_m`` (the offset from the sub-cell centre the robot believes: a turn
        towards it, the drive, a turn back), so that the next mark is laid where it belongs."""
        d = float(np.hypot(*offset_m))
        self.x -= float(offset_m[0])
        self.y -= float(offset_m[1])
        self.t += 2 * turn_s + d / self.robot.drive_speed_m_s
        self.recentred += 1

    def drive_along(self, dist_m: float) -> None:
        """Drive ``dist_m`` straight along the true heading, no turn (backwards when negative)."""
        self.x += dist_m * math.cos(self.heading_rad)
        self.y += dist_m * math.sin(self.heading_rad)
        self.t += abs(dist_m) / self.robot.drive_speed_m_s
        self.aligned += 1

    def lay_mark(self, floor: Floor, sub: tuple[int, int], hc: int) -> None:
        """Rear LEDs on for ``led_on_s``: a row of dots inside sub-cell ``sub``, on its rear edge
        for compass heading ``hc``."""
        xy = floor.phosphor.led_positions_m(self.pose)
        floor.lay(xy, sub, behind(hc), self.t, self.robot.led_on_s)
        self.t += self.robot.led_on_s

    def forward(self, sub: tuple[int, int], hc: int, offset_m: np.ndarray, turn_s: float) -> tuple[bool, str | None]:
        """Drive from sub-cell ``sub`` to the next one along compass heading ``hc``, to its centre
        as the robot believes it: aim off the heading by beta to take out the believed offset
        ``offset_m``, drive, turn back (turns timed by ``turn_s``, at the true rate). Returns
        whether it moved, and why the run must stop (or None)."""
        D = self.board.subcell_m
        nxt = step_from(sub, hc)
        rows, cols = self.board.shape_subcells
        if not (0 <= nxt[0] < rows and 0 <= nxt[1] < cols) or self.board.blocked[nxt]:
            return False, f"drove into a blocked sub-cell at {nxt}"
        ux, uy = entry_axes(hc)[1]
        want = np.array([D * ux, D * uy]) - offset_m
        along = want @ (ux, uy)
        lateral = want @ (-uy, ux)
        beta = math.atan2(lateral, along)
        est_rate = (math.pi / 2) / turn_s
        beta_true = math.copysign(self.true_rate(self.t) * abs(beta) / est_rate, beta)
        self.last_move_error_m = self.rng.normal(0, self.robot.drive_sigma_m)
        dist = math.hypot(along, lateral) + self.last_move_error_m
        start = (self.x, self.y)
        self.x += dist * math.cos(self.heading_rad + beta_true)
        self.y += dist * math.sin(self.heading_rad + beta_true)
        self.t += 2 * abs(beta) / est_rate + dist / self.robot.drive_speed_m_s
        self.visits[nxt] += 1
        self.moves += 1
        why = self.check_lost(nxt)
        if why is not None or not self.disturbances:
            return True, why
        for d in self.disturbances:
            d.after_move(self, start)
        return True, self.check_lost(nxt)

    def check_lost(self, sub: tuple[int, int]) -> str | None:
        """After a move into ``sub``: the true offset from its centre; past 0.45 of a sub-cell
        the robot stands in another one (the floor's verdict, not the robot's)."""
        off = math.hypot(*self.true_offset(sub))
        self.max_pos_err = max(self.max_pos_err, off)
        if off > 0.45 * self.board.subcell_m:
            return f"lost: {100 * off:.1f} cm off sub-cell {sub}"
        return None
