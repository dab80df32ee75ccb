"""The robot's checks of its own hardware: what it does when it cannot trust what it sees or
where it stands, rather than decide on garbage.

* :func:`frame_fault`: a frame that never arrived or arrived black (below the dark frame's black
  level) is not read; :class:`controllers.stc.frames.RobotCamera` takes it again, up to
  :data:`FRAME_RETRIES` times, and then stops.
* :class:`NoiseCheck`: every frame's noise floor against the camera's own figures; a camera
  much noisier than its calibration stops the robot (its frames no longer see as far as the
  exposure ladder assumes).
* :func:`done_away_from_start`: the robot counts its forward moves on the grid (two integers:
  the tour stays O(1) in memory) and refuses to report a finished tour anywhere but in its start
  cell: a start mark misread elsewhere (a mark laid askew after a slip) ends the run aborted,
  never as a success with the wrong coverage.
* :func:`landing_at_start`: by the same count, whether a move lands on the start sub-cell. A
  return to the parent lands on a fresh sub-cell, except the last one, which lands on the start
  sub-cell: the tour closes there. The count says which return that is, where a mark read alone
  (a row laid askew, a neighbour's row, an old row at the edge of a frame's reach) could close
  the tour away from the start or walk past it.
* :class:`CellsEntered`: by the same count, the cells the robot has stood in. A cell it never
  entered holds no mark of its own (a robot marks only the sub-cells it leaves), so a neighbour
  read marked that the count never entered is a misreading (a row of the robot's own cell or of
  another neighbour read into it, a noise peak, a stain): the look from next to it reads it
  again before the robot passes it by. The log is a cross-check of what the camera reads; the
  controller itself keeps deciding from the floor alone (:mod:`controllers.stc.fsm`).
* :class:`RowsLaid`: by the same count, every row the robot laid with a forward move (the
  sub-cell it left, the edge behind it). At a decision in a cell it has been in, a box read unlit
  whose row the count laid is a mark the frames missed (an old row at the edge of a frame's reach:
  a low-light tour of 28 hours read {4} for {2,4} at a return, a set a tour can show, so no other
  check saw it): the cell is read once more, and a second reading that still misses it stops the
  robot before it decides.
* :class:`RobotStop`: raised by a part of the loop that finds the robot cannot go on; the loop
  ends the run with its message as the ``abort_reason``.
"""

from __future__ import annotations

import numpy as np

from controllers.stc.geometry import COMPASS_VEC, cell_of, frame_compass, frame_subcells
from stcvision.stcgrid import BOX_EDGES

__all__ = [
    "CellsEntered",
    "FRAME_RETRIES",
    "NOISE_CHECK",
    "NoiseCheck",
    "RobotStop",
    "RowsLaid",
    "done_away_from_start",
    "frame_fault",
    "landing_at_start",
    "noise_floor_dn",
]

#: a lost or black frame is taken again this many times before the robot stops: at 5 % lost
#: frames, four in a row happen once in 160,000 frames; a dead camera stops it at once
FRAME_RETRIES = 3


#: a frame's measured noise floor this many times what the camera's figures give
#: (:func:`noise_floor_dn`) means the camera is not the one its horizons were computed for:
#: measured on the webcam's ladder, healthy frames read 1.05-1.28x, a noise floor x3 2.4-3.2x
NOISE_CHECK = 1.6
#: ... in this many frames in a row (one frame full of glare or marks is not a faulty camera)
NOISE_CHECK_FRAMES = 3


class RobotStop(Exception):
    """The robot stops: its message is the run's ``abort_reason``."""


def frame_fault(image: np.ndarray | None, dark: np.ndarray | None) -> str | None:
    """Why ``image`` (H, W, 3) uint8 cannot be read, or None: it never arrived, or it is black --
    its mean below half the dark frame's (a real frame of the dark room is never darker than
    the camera's black level and dark signal, which the dark frame holds). Sampled on every
    8th pixel (~0.1 ms)."""
    if image is None:
        return "dropped (no frame arrived)"
    if dark is not None and image.shape == dark.shape:
        level, floor = float(image[::8, ::8].mean()), float(dark[::8, ::8].mean())
        if level < 0.5 * floor:
            return f"black (mean {level:.1f} DN against the dark frame's {floor:.1f})"
    return None


def noise_floor_dn(sensor, *, n_avg: int = 1, n_dark: int = 8) -> float:
    """The noise (DN, 1 sigma) a dark pixel of a dark-subtracted frame should show by the
    camera's own figures (``sensor``: its preset at the frame's exposure and gain): read noise and
    dark-current shot noise, averaged over ``n_avg`` frames, the dark frame's own noise (a median
    or mean of ``n_dark`` frames, ~1.25^2 / n_dark of a frame's variance) and the 8-bit rounding
    of both."""
    e_var = (sensor.read_noise_e**2 + sensor.dark_current_e_s * sensor.exposure_s) / n_avg
    dn_var = e_var * sensor.dn_per_e**2 * (1.0 + 1.25**2 / n_dark)
    return float(np.sqrt(dn_var + 2 / 12))


class NoiseCheck:
    """Counts frames whose measured noise floor exceeds :data:`NOISE_CHECK` times
    :func:`noise_floor_dn`; :data:`NOISE_CHECK_FRAMES` in a row stop the robot."""

    def __init__(self):
        self.over = 0
        self.worst = 0.0

    def check(self, measured_dn: float, expected_dn: float) -> None:
        ratio = measured_dn / expected_dn
        self.worst = max(self.worst, ratio)
        self.over = self.over + 1 if ratio > NOISE_CHECK else 0
        if self.over >= NOISE_CHECK_FRAMES:
            raise RobotStop(
                f"camera: noise floor {ratio:.1f}x its calibration in {self.over} frames in a row "
                f"(over {NOISE_CHECK}x): its frames no longer see the marks the exposure ladder counts on"
            )


def done_away_from_start(start_sub: tuple[int, int], moved: tuple[int, int]) -> str | None:
    """Why a tour the controller calls done is not, or None: ``moved`` is the robot's count of
    sub-cells moved (rows, columns) since its start sub-cell ``start_sub``, from its own compass
    heading at each forward move. A finished tour ends in the start cell."""
    here = (start_sub[0] + moved[0], start_sub[1] + moved[1])
    if (here[0] // 2, here[1] // 2) == (start_sub[0] // 2, start_sub[1] // 2):
        return None
    return (
        f"done away from the start: the robot has moved {moved[0]:+d}, {moved[1]:+d} sub-cells from its start "
        "sub-cell, so the start mark it read there was not its own"
    )


def _here(start_sub: tuple[int, int], moved: tuple[int, int]) -> tuple[int, int]:
    """The sub-cell the robot's count of its moves puts it in."""
    return start_sub[0] + moved[0], start_sub[1] + moved[1]


def landing_at_start(start_sub: tuple[int, int], moved: tuple[int, int], hc: int) -> tuple[bool, ...]:
    """At a decision (the robot in its entry frame's sub-cell 0, heading ``hc``): per entry-frame
    direction ``d``, the exit towards ``d`` (from sub-cell ``d``) lands on the start sub-cell, by
    the robot's count ``moved``; the sub-cell such a move lands on is marked exactly then
    (:attr:`controllers.stc.fsm.StcObservation.landing_marked`)."""
    subs = frame_subcells(_here(start_sub, moved), hc)
    out = []
    for d in range(4):
        di, dj = COMPASS_VEC[frame_compass(hc, d)]
        out.append((subs[d][0] + di, subs[d][1] + dj) == tuple(start_sub))
    return tuple(out)


class CellsEntered:
    """The cells the robot's count of its moves has put it in: the start cell, then the cell of
    every sub-cell a forward move lands on (one entry per cell, at most the board's). A cell outside
    this log holds no mark the robot laid, so a reading of marks there is checked before the
    robot passes the cell by (:meth:`never_entered`, :meth:`suspect_neighbours`)."""

    def __init__(self, start_sub: tuple[int, int]):
        self.start_sub = tuple(start_sub)
        self.cells: set[tuple[int, int]] = {cell_of(self.start_sub)}

    def moved_to(self, moved: tuple[int, int]) -> None:
        """The robot's count after a forward move: it now stands in that sub-cell's cell."""
        self.cells.add(cell_of(_here(self.start_sub, moved)))

    def never_entered(self, moved: tuple[int, int], hc: int) -> bool:
        """At a look (the robot facing compass ``hc``): the cell just ahead was never entered."""
        i, j = _here(self.start_sub, moved)
        di, dj = COMPASS_VEC[hc]
        return cell_of((i + di, j + dj)) not in self.cells

    def suspect_neighbours(self, neighbours, moved: tuple[int, int], hc: int) -> tuple[int, ...]:
        """At a decision (the robot in its entry frame's sub-cell 0, heading ``hc``): the
        entry-frame directions whose neighbour reads marked without a red light, though the
        count never entered it."""
        ci, cj = cell_of(_here(self.start_sub, moved))
        out = []
        for d, n in enumerate(neighbours):
            di, dj = COMPASS_VEC[frame_compass(hc, d)]
            if n.has_marks and not n.has_red and (ci + di, cj + dj) not in self.cells:
                out.append(d)
        return tuple(out)


class RowsLaid:
    """The rows the robot's count of its moves says it laid: per forward move, the sub-cell it
    left and that sub-cell's edge behind it (compass), as :meth:`controllers.stc.plant.Plant.lay_mark`
    lays them. The start mark is not logged (it lies on a start-mark line, never in a box). At
    most four a sub-cell, so bounded by the board."""

    def __init__(self, start_sub: tuple[int, int]):
        self.start_sub = tuple(start_sub)
        self.rows: set[tuple[tuple[int, int], int]] = set()

    def laid(self, moved: tuple[int, int], hc: int) -> None:
        """A forward move heading compass ``hc`` from where the count ``moved`` puts the robot."""
        self.rows.add((_here(self.start_sub, moved), (hc + 2) % 4))

    def missed_boxes(self, boxes, moved: tuple[int, int], hc: int) -> tuple[int, ...]:
        """At a decision (the robot in its entry frame's sub-cell 0, heading ``hc``): the boxes
        (1-5) read unlit in ``boxes`` whose row the count laid."""
        subs = frame_subcells(_here(self.start_sub, moved), hc)
        return tuple(
            b for b, (k, d) in BOX_EDGES.items() if not boxes[b - 1] and (subs[k], frame_compass(hc, d)) in self.rows
        )
