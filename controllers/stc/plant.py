"""The plant of the coverage loop: the robot's true motion and clock, and the floor it marks.

* **Robot** (:class:`sim_camera.robot.MarkingRobot`, by default the seed's Lego robot built from
  ``sim_camera.robot.LEGO_STC``): drives one sub-cell (16 cm) at the cruise speed, turns 90
  degrees by a timed command at a rate that is off nominal by up to ``rate_spread`` per robot
  and fades with the battery (``fade_per_h``), and keeps its rear UV LEDs on for ``led_on_s``
  before every forward move (seed 003: "for a few seconds"). Moves are kinematic on the floor
  plane: the robot drives straight along its *true* heading, with ``drive_sigma_m`` of distance
  error per move; the pymunk world is not needed for these straight moves between free cells.
* **Rotation-time recalibration** (seed 003): after a turn, the heading the perception measured
  tells what the turn really did; the robot turns the rest of the way (the correction command)
  and updates its turn time ``T' = 90/d * T`` (bounded, :func:`stcvision.stages.recalibrate_turn`).
* **Floor**: marks are laid in the phosphor layer at the true LED positions, at the true time;
  they fade by the afterglow law. The floor also keeps the record of which (sub-cell, edge) was
  marked when (:class:`controllers.stc.oracle.MarkFloor`): the oracle's and the referee's truth.

The plant is mutable on purpose (it *is* the world's state); nothing here decides.
"""

from __future__ import annotations

import math

import numpy as np

from controllers.stc.geometry import COMPASS_VEC, cell_of, compass_to_rad, start_heading, wrap_rad
from controllers.stc.oracle import MarkFloor
from stcvision.stcgrid import entry_axes

__all__ = ["Floor", "Plant"]


class Floor:
    """The marks on the board: the phosphor dots (what a camera sees) and their record."""

    def __init__(self, board):
        from sim_camera.phosphor import PhosphorLayer

        self.phosphor = PhosphorLayer()
        self.record = MarkFloor(board.shape_subcells)
        self.laid: list[tuple[tuple[int, int], int]] = []  # (sub-cell, edge) of every four dots, in order
        self.laid_at: dict[tuple[tuple[int, int], int], float] = {}  # when each mark's LEDs went off
        #: the mark (index into ``laid``) of every phosphor dot: a mark has four dots, or fewer
        #: when an LED is dead (:mod:`controllers.stc.faults`)
        self.dot_mark = np.zeros(0, int)

    def lay(self, xy_m, sub: tuple[int, int], edge: int, t_s: float, duration_s: float) -> None:
        self.phosphor.charge(xy_m, t_start_s=t_s, duration_s=duration_s)
        self.dot_mark = np.concatenate([self.dot_mark, np.full(len(np.reshape(xy_m, (-1, 2))), len(self.laid))])
        self.record.mark(sub, edge)
        self.laid.append((sub, edge))
        self.laid_at[(sub, edge)] = t_s + duration_s

    def oldest_near(self, sub: tuple[int, int], t_s: float) -> float:
        """The age of the oldest mark in the cell of ``sub`` and its four neighbours (what a
        decision there reads), 0 if none."""
        ci, cj = cell_of(sub)
        ages = [t_s - t for (s, _), t in self.laid_at.items() if abs(s[0] // 2 - ci) + abs(s[1] // 2 - cj) <= 1]
        return max(ages, default=0.0)


class Plant:
    """The robot's true pose, clock, motors and turn time on ``board``.

    ``rng`` draws this robot's motors (rate off nominal, the first turn time's error) and every
    move's distance error. ``offset_est`` is the robot's own belief of where it stands off its
    sub-cell centre (world, m): the perception sets it, the next forward move takes it out."""

    def __init__(self, board, robot, rng: np.random.Generator):
        self.board = board
        self.robot = robot
        self.rng = rng
        self.sub = tuple(board.start_subcell)
        self.hc = start_heading(board)  # compass heading the robot believes it has (0 N, clockwise)
        c = board.subcell_center_m(*self.sub)
        self.x, self.y, self.hdg = float(c[0]), float(c[1]), compass_to_rad(self.hc)
        self.t = 0.0
        self.rate_gain = 1.0 + rng.uniform(-robot.rate_spread, robot.rate_spread)  # this robot's motors
        self.nominal_rate = (math.pi / 2) / robot.turn_90_s
        # T, the robot's rotation time for 90 degrees: set before the run to what the first
        # rotation needs (seed 003: "We initially set T to a time that let's the robot do the
        # first rotation accurate enough"), to within ``initial_turn_error`` (1 sigma);
        # recalibrated after every turn as the battery fades
        off = 1 + rng.normal(0, robot.initial_turn_error)
        self.turn_s = (math.pi / 2) / (self.nominal_rate * self.rate_gain) * off
        self.offset_est = np.zeros(2)
        self.visits = np.zeros(board.shape_subcells, int)
        self.visits[self.sub] += 1
        self.moves = self.turns = 0
        self.recentred = 0  # moves back to the sub-cell centre before a mark (:meth:`recentre`)
        self.aligned = 0  # moves along the heading to the centre before a row (:meth:`align_along`)
        self.last_move_error_m = 0.0  # the distance error of the last forward move (drawn)
        self.max_pos_err = 0.0

    # ------------------------------------------------------------------ what is true
    @property
    def pose(self) -> tuple[float, float, float]:
        return self.x, self.y, self.hdg

    def true_rate(self, t_s: float) -> float:
        return self.nominal_rate * self.rate_gain * max(0.5, 1.0 - self.robot.fade_per_h * t_s / 3600.0)

    def heading_error(self) -> float:
        """True heading less the compass heading the robot believes it has (rad)."""
        return wrap_rad(self.hdg - compass_to_rad(self.hc))

    def true_offset(self) -> np.ndarray:
        ideal = self.board.subcell_center_m(*self.sub)
        return np.array([self.x - ideal[0], self.y - ideal[1]])

    # ------------------------------------------------------------------ what the robot does
    def wait(self, dt_s: float) -> None:
        self.t += dt_s

    def rotate_by(self, angle_rad: float) -> None:
        """A small correction turn at the robot's estimated rate (the true rate applies)."""
        est_rate = (math.pi / 2) / self.turn_s
        dur = abs(angle_rad) / est_rate
        self.hdg = wrap_rad(self.hdg + math.copysign(1.0, angle_rad) * self.true_rate(self.t) * dur)
        self.t += dur

    def turn(self, left: bool) -> None:
        """A 90-degree timed turn (``turn_s`` at the true rate)."""
        sign = 1.0 if left else -1.0
        self.hdg = wrap_rad(self.hdg + sign * self.true_rate(self.t) * self.turn_s)
        self.t += self.turn_s
        self.hc = (self.hc + (3 if left else 1)) % 4
        self.turns += 1

    def finish_turn(self, left: bool, heading_err_rad: float | None) -> None:
        """Seed 003's recalibration after a turn, from the heading error measured after it: what
        the turn really did updates ``T``, then the robot turns back by the error."""
        from stcvision.stages import recalibrate_turn

        if heading_err_rad is None:
            return
        turned = math.pi / 2 + (1.0 if left else -1.0) * heading_err_rad
        rec = recalibrate_turn(self.turn_s, turned)
        if rec.accepted:
            self.turn_s = rec.turn_time_s
        self.rotate_by(-heading_err_rad)

    def recentre(self) -> None:
        """Drive back to the sub-cell centre as the robot believes it (by ``-offset_est``: a turn
        towards it, the drive, a turn back), so that the next mark is laid where it belongs."""
        d = float(np.hypot(*self.offset_est))
        self.x -= float(self.offset_est[0])
        self.y -= float(self.offset_est[1])
        self.t += 2 * self.turn_s + d / self.robot.drive_speed_m_s
        self.offset_est = np.zeros(2)
        self.recentred += 1

    def align_along(self) -> None:
        """Drive along the heading to the sub-cell centre as the robot believes it (the along-
        heading part of ``-offset_est``, no turn), so that the row it lays next lies on its line;
        the lateral part stays for :meth:`forward` to take out."""
        ux, uy = entry_axes(self.hc)[1]
        along = float(self.offset_est @ (ux, uy))
        self.x -= along * math.cos(self.hdg)
        self.y -= along * math.sin(self.hdg)
        self.t += abs(along) / self.robot.drive_speed_m_s
        self.offset_est = self.offset_est - along * np.array([ux, uy])
        self.aligned += 1

    def lay_mark(self, floor: Floor) -> None:
        """Rear LEDs on for ``led_on_s``: a row of dots inside the sub-cell, on its rear edge."""
        xy = floor.phosphor.led_positions_m(self.pose)
        floor.lay(xy, self.sub, (self.hc + 2) % 4, self.t, self.robot.led_on_s)
        self.t += self.robot.led_on_s

    def forward(self) -> str | None:
        """Drive to the next sub-cell centre as the robot believes it: aim off its heading by
        beta to take out its estimated offset, drive, turn back (turns at the true rate).
        Returns why the run must stop, or None."""
        D = self.board.subcell_m
        di, dj = COMPASS_VEC[self.hc]
        nxt = (self.sub[0] + di, self.sub[1] + dj)
        rows, cols = self.board.shape_subcells
        if not (0 <= nxt[0] < rows and 0 <= nxt[1] < cols) or self.board.blocked[nxt]:
            return f"drove into a blocked sub-cell at {nxt}"
        ux, uy = entry_axes(self.hc)[1]
        want = np.array([D * ux, D * uy]) - self.offset_est
        along = want @ (ux, uy)
        lateral = want @ (-uy, ux)
        beta = math.atan2(lateral, along)
        est_rate = (math.pi / 2) / self.turn_s
        beta_true = math.copysign(self.true_rate(self.t) * abs(beta) / est_rate, beta)
        self.last_move_error_m = self.rng.normal(0, self.robot.drive_sigma_m)
        dist = math.hypot(along, lateral) + self.last_move_error_m
        self.x += dist * math.cos(self.hdg + beta_true)
        self.y += dist * math.sin(self.hdg + beta_true)
        self.t += 2 * abs(beta) / est_rate + dist / self.robot.drive_speed_m_s
        self.offset_est = np.zeros(2)
        self.sub = nxt
        self.visits[nxt] += 1
        self.moves += 1
        return self.check_lost(D)

    def check_lost(self, subcell_m: float) -> str | None:
        """After a move: the true offset from the sub-cell centre; past 0.45 of a sub-cell the
        robot stands in another one (the floor's verdict, not the robot's)."""
        off = math.hypot(*self.true_offset())
        self.max_pos_err = max(self.max_pos_err, off)
        if off > 0.45 * subcell_m:
            return f"lost: {100 * off:.1f} cm off sub-cell {self.sub}"
        return None
