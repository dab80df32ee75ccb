"""The robot's count of its moves: two integers, constant memory whatever the board.

The count holds the sub-cells the robot has moved (rows, columns) from its start sub-cell by its
own compass heading at each forward move. An ant integrates its path too; a count is constant
memory, whatever the board.

:class:`MoveCount` holds the count and what the tour takes from it:

* :meth:`MoveCount.done_away`: the robot refuses to report a finished tour anywhere but in its
  start cell; a start mark misread elsewhere (a mark laid askew after a slip) ends the run
  aborted, never as a success with the wrong coverage.
* :meth:`MoveCount.landing_at_start`: whether a move lands on the start sub-cell. A return to the
  parent lands on a fresh sub-cell, except the last one, which lands on the start sub-cell: the
  tour closes there. The count says which return that is, where a mark read alone (a row laid
  askew, a neighbour's row, an old row at the edge of a frame's reach) could close the tour away
  from the start or walk past it.
* :meth:`MoveCount.in_start_cell`: a start mark read elsewhere is not the robot's own
  (:meth:`stcvision.controllers.stc.frames.Exposures.decision` reads such a cell again).
* :meth:`MoveCount.start_in_frame`: in the start cell, which of its sub-cells is the start
  sub-cell. The start mark laid there at the very beginning is the tour's oldest mark; a frame
  sized for each dot at ``CoverConfig.sizing_snr`` misses it now and then, and a start cell
  read without it is read as any other cell, with the wrong parent. The count says it.

:class:`MoveLog` is not part of the ant-like robot: a study switch (``CoverConfig.move_log``,
``stcvision cover --move-log``) that keeps, beside the count, every cell the count has put the
robot in and every row it laid -- a map of where the robot has been, which grows with the board
-- and checks the camera's readings against it. With it, the cost of the ant's constraint
(deciding from the floor and a constant memory alone) is one command away.
"""

from __future__ import annotations

from dataclasses import dataclass

from stcvision.controllers.stc.grid import COMPASS_VEC, behind, cell_of, frame_compass, frame_subcells, step_from
from stcvision.stc_geometry import BOX_EDGES

__all__ = ["MoveCount", "MoveLog"]


@dataclass(slots=True)
class MoveCount:
    """Sub-cells moved from the start sub-cell, counted at every forward move by the robot's own compass heading.

    Attributes
    ----------
    start_sub : tuple of int
        The start sub-cell (row, column) on the board.
    moved : tuple of int
        Sub-cells moved (rows, columns) from it.
    """

    start_sub: tuple[int, int]
    moved: tuple[int, int] = (0, 0)

    def forward(self, hc: int) -> None:
        """Count a forward move.

        Parameters
        ----------
        hc : int
            The compass heading of the move (clockwise: 0 N, 1 E, 2 S, 3 W).
        """
        self.moved = step_from(self.moved, hc)

    def here(self) -> tuple[int, int]:
        """Return the sub-cell the count puts the robot in.

        Returns
        -------
        tuple of int
            (row, column) on the board.
        """
        return self.start_sub[0] + self.moved[0], self.start_sub[1] + self.moved[1]

    def in_start_cell(self) -> bool:
        """Say whether the count puts the robot in its start cell.

        Returns
        -------
        bool
            The robot's sub-cell lies in the start sub-cell's cell.
        """
        return cell_of(self.here()) == cell_of(self.start_sub)

    def done_away(self) -> str | None:
        """Say why a tour the controller calls done is not, or None.

        A finished tour ends in the start cell.

        Returns
        -------
        str or None
            Why the tour is not done (the robot is away from its start cell), or None.
        """
        if self.in_start_cell():
            return None
        return (
            f"done away from the start: the robot has moved {self.moved[0]:+d}, {self.moved[1]:+d} sub-cells from its "
            "start sub-cell, so the start mark it read there was not its own"
        )

    def start_in_frame(self, hc: int) -> int | None:
        """Return which entry-frame sub-cell is the start sub-cell, at a decision.

        Parameters
        ----------
        hc : int
            The robot's compass heading, in its entry frame's sub-cell 0.

        Returns
        -------
        int or None
            The entry-frame sub-cell (0-3) that is the start sub-cell, or None outside the start
            cell (:attr:`stcvision.controllers.stc.fsm.StcObservation.start_mark`).
        """
        subs = frame_subcells(self.here(), hc)
        start = tuple(self.start_sub)
        return next((m for m, s in enumerate(subs) if tuple(s) == start), None)

    def landing_at_start(self, hc: int) -> tuple[bool, bool, bool, bool]:
        """Tell, per exit, whether it lands on the start sub-cell, at a decision.

        Parameters
        ----------
        hc : int
            The robot's compass heading, in its entry frame's sub-cell 0.

        Returns
        -------
        tuple of bool
            Per entry-frame direction ``d``: the exit towards ``d`` (from sub-cell ``d``) lands
            on the start sub-cell; the sub-cell such a move lands on is marked exactly then
            (:attr:`stcvision.controllers.stc.fsm.StcObservation.landing_marked`).
        """
        subs = frame_subcells(self.here(), hc)
        start = tuple(self.start_sub)
        return tuple(step_from(subs[d], frame_compass(hc, d)) == start for d in range(4))  # type: ignore[return-value]


class MoveLog:
    """The study switch's map of where the robot has been (``CoverConfig.move_log``).

    It holds the cells the count has put the robot in and the rows it says the robot laid (per
    forward move, the sub-cell left and that sub-cell's edge behind it, as
    :meth:`stcvision.controllers.stc.plant.Plant.lay_mark` lays them), and the three checks of
    the camera's readings against them. Both grow with the board.
    """

    def __init__(self, count: MoveCount):
        self.count = count
        self.cells: set[tuple[int, int]] = {cell_of(count.here())}
        self.rows: set[tuple[tuple[int, int], int]] = set()
        self.recounted = 0  # neighbours read marked that the count never entered
        self.relooked = 0  # looks that read a never-entered cell marked, taken again
        self.reread = 0  # decisions read again because a box read unlit holds a row the count laid

    def forward(self, hc: int) -> None:
        """Log the row laid behind and the cell entered, before the count's forward move heading ``hc``."""
        self.rows.add((self.count.here(), behind(hc)))
        self.cells.add(cell_of(step_from(self.count.here(), hc)))

    def never_entered_ahead(self, hc: int) -> bool:
        """Say whether the cell just ahead was never entered, at a look (the robot facing compass ``hc``)."""
        return cell_of(step_from(self.count.here(), hc)) not in self.cells

    def suspect_neighbours(self, neighbours, hc: int) -> tuple[int, ...]:
        """Return the neighbours read marked that the count never entered, at a decision.

        At a decision (heading ``hc``): the entry-frame directions whose neighbour reads marked
        without a red light, though the count never entered it.
        """
        ci, cj = cell_of(self.count.here())
        out = []
        for d, n in enumerate(neighbours):
            di, dj = COMPASS_VEC[frame_compass(hc, d)]
            if n.has_marks and not n.has_red and (ci + di, cj + dj) not in self.cells:
                out.append(d)
        return tuple(out)

    def missed_boxes(self, boxes, hc: int) -> tuple[int, ...]:
        """Return the boxes (1-5) read unlit whose row the count laid, at a decision (heading ``hc``)."""
        subs = frame_subcells(self.count.here(), hc)
        return tuple(
            b for b, (k, d) in BOX_EDGES.items() if not boxes[b - 1] and (subs[k], frame_compass(hc, d)) in self.rows
        )
