"""Where the robot stands off its sub-cell centre, and how sure it is of that: each reading is
weighted by its uncertainty against what the robot already believes, per world axis (a scalar
Kalman filter with a validation gate), instead of the last reading replacing the belief whole.

Why: on open floor, with no red light in view, the offset the marks give
(:func:`stcvision.observation.mark_offset`, the median residual of the rows in view) is right to
~4 mm most of the time, but 4-6 % of readings are 1-2.5 cm off: rows laid at many other times,
each where the robot then stood, and the residual flipping sides beyond the rows' inset. Taken
whole, one such reading moved a robot standing 1.6 mm off its centre 2.3 cm off it
(spiral_stc_test_2, cooled, seed 314, decision 272); there the next cell's exterior row fell
beyond the cell's edge, was taken for a neighbour's, and the robot decided wrongly. A forward
move adds only its own drive error (2 mm, 1 sigma: the robot's
``MarkingRobot.drive_sigma_m``), so the belief carried over from the last reading is worth more
than one marks reading that disagrees with it by centimetres.

The rule, per axis:

* a forward move adds ``drive_sigma_m ** 2`` to the variance (:meth:`Fix.moved`);
* the red lights (absolute: they stand at cell centres) replace the belief when their own
  spread is within :data:`stcvision.controllers.stc.config.LANDMARK_OFFSET_SIGMA`; the variance becomes
  :data:`LIGHTS_SIGMA_M` squared;
* red lights less sure than that, up to :data:`LIGHTS_WIDE_SPREAD` (they were left out
  before, although they are right to ~2.5 mm there), and the marks are each fused
  (:meth:`Fix.fuse`) with the weight ``var / (var + sigma ** 2)`` (``sigma``:
  :data:`LIGHTS_WIDE_SIGMA_M`, :data:`MARKS_SIGMA_M`) when the reading lies within :data:`GATE`
  standard deviations of the belief (``var + sigma ** 2``); beyond that it is left out, and the
  robot becomes as unsure of its belief as it must be to take that same reading next time
  (the variance grows to ``(innovation / GATE) ** 2``): one stray reading moves it nowhere,
  while a robot truly pushed off (a bump, a slip) believes the second reading that agrees;
* an axis a reading did not measure (the marks with no rows across it) is no reading of 0:
  it keeps its belief and its variance. Fused as 0, it held a robot drifting 2-3 cm on open
  floor at "centred" and shrank its variance until the red lights showing the drift were left
  out as outliers (spiral_stc_test_3, lowlight, seed 821).

The heading has the same question (:class:`Bearing`): the red lights say it against the grid;
the lean of all the mark rows in view says it against the rows, which the robot laid, each with
the heading it had then. Where the robot has seen no light, its rows are the best reference it
has (their lean catches a drift no turn's recalibration sees). But once the lights have set the
heading, the rows in view, laid before, carry the error the lights just removed: on a 20x20
board (cooled, seed 532) the robot started 1.2 degrees askew, the lights turned that out 35
times, and the rows' lean, taken whole, turned it back 54 times in 72, so the robot drove 3.6 cm
off its line and later read a row of that stretch as a start mark. So the robot keeps a
variance of its heading: the lights set it from their own spread, each 90-degree turn's
recalibration adds its residual (:data:`TURN_SIGMA_RAD`), and the rows' lean is weighed
against it by the Kalman gain ``var / (var + sigma_rows^2)`` (:data:`ROWS_LEAN_SIGMA_RAD`):
most of it where no light has been seen for many turns, a fifth just after the lights,
all of it where it shows a turn (over :data:`stcvision.controllers.stc.perception.HEADING_CHECK_RAD`)
that no reference's error explains. A lean shared by many rows is not independent from one
reading to the next; the gain is what keeps a run of them from undoing the lights, and the
turns are what gives the rows their weight back.

The numbers were measured on the peer maps' tuning seeds 0-5 (cooled and lowlight, the
pipeline's readings against the simulator's truth), not on the seeds the dependability table
reports.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "GATE",
    "LIGHTS_SIGMA_M",
    "LIGHTS_WIDE_SIGMA_M",
    "LIGHTS_WIDE_SPREAD",
    "MARKS_SIGMA_M",
    "ROWS_LEAN_SIGMA_RAD",
    "TURN_SIGMA_RAD",
    "Bearing",
    "Fix",
]

#: a marks offset's error when it is not an outlier (1 sigma, per axis, m): measured 3.8-4.2 mm
#: (the robust spread of short and long frames' readings against the truth)
MARKS_SIGMA_M = 0.004
#: the red lights' offset error at the spread they are accepted with (1 sigma, per axis, m):
#: measured 1.4 mm RMS at a reported spread of 3-5 mm, 0.5 mm below it
LIGHTS_SIGMA_M = 0.0015
#: the red lights' own spread (sub-cell sides, as the pipeline reports it) up to which a less
#: sure estimate is still fused: measured 1.4-2.4 mm RMS at reported spreads of 3-12 mm (the
#: reported spread overstates the error), 8 mm RMS beyond
LIGHTS_WIDE_SPREAD = 0.075
#: ... and their error there (1 sigma, per axis, m): the measured RMS, rounded up
LIGHTS_WIDE_SIGMA_M = 0.0025
#: a reading further than this many standard deviations from the belief is an outlier
#: (3: a Gaussian reading lies beyond it 0.3 % of the time)
GATE = 3.0
#: the heading error a 90-degree turn's recalibration leaves (1 sigma, rad): measured 0.094
#: degrees RMS over 1,497 turns (the change of the true heading error across each turn; the
#: peer maps' tuning seeds and five random boards, cooled and lowlight)
TURN_SIGMA_RAD = math.radians(0.1)
#: the heading error left by turning out the lean of all the rows in view (1 sigma, rad):
#: measured 0.15 degrees RMS over 209 such trims on the same runs where the rows were laid
#: square, 0.36 over all 281 with the 72 of one run whose rows all carried its 1.2 degree start
#: error (20x20, seed 532). 0.2 between them: at 0.15 that run drifted 2.6 cm, at 0.36 a map
#: run (spiral_stc_test, cooled, seed 810) drifted into a misread between lights
ROWS_LEAN_SIGMA_RAD = math.radians(0.2)


@dataclass(slots=True)
class Fix:
    """The belief's offset uncertainty: a variance per world axis (m^2); ``step_sigma_m`` a
    forward move's own distance error (1 sigma, m: the robot's ``MarkingRobot.drive_sigma_m``);
    and the readings, per axis, the gate left out (counted for the run's summary)."""

    var_m2: np.ndarray
    step_sigma_m: float = 0.0
    rejected: int = 0

    @classmethod
    def placed(cls, sigma_m: float) -> Fix:
        """At the start: placed on the start sub-cell's centre as well as a move of error
        ``sigma_m`` (1 sigma, m) ends on one, which each move adds."""
        return cls(np.full(2, sigma_m**2), sigma_m)

    def moved(self) -> None:
        """A forward move's own error adds to the uncertainty."""
        self.var_m2 = self.var_m2 + self.step_sigma_m**2

    def lights(self, z: np.ndarray) -> np.ndarray:
        """The red lights' offset ``z`` (world, m): the new belief."""
        self.var_m2 = np.full(2, LIGHTS_SIGMA_M**2)
        return np.asarray(z, float).copy()

    def fuse(self, belief: np.ndarray, z: np.ndarray, sigma_m: float, axes=(True, True)) -> np.ndarray:
        """A reading ``z`` (world, m) of error ``sigma_m`` (1 sigma) fused into ``belief`` per
        axis; an axis whose reading lies beyond :data:`GATE` standard deviations keeps the
        belief, and so does one the reading did not measure (``axes``, per world axis: a
        reading of 0 there says nothing). Returns the new belief."""
        r = sigma_m**2
        belief, z = np.asarray(belief, float), np.asarray(z, float)
        measured = np.asarray(axes, bool)
        s = self.var_m2 + r
        inside = np.abs(z - belief) <= GATE * np.sqrt(s)
        k = np.where(inside & measured, self.var_m2 / s, 0.0)
        out = belief + k * (z - belief)
        unsure = np.maximum(self.var_m2 + r, ((z - belief) / GATE) ** 2)
        self.var_m2 = np.where(~measured, self.var_m2, np.where(inside, (1 - k) * self.var_m2, unsure))
        self.rejected += int((measured & ~inside).sum())
        return out


@dataclass(slots=True)
class Bearing:
    """How sure the robot is of its heading against the grid: a variance (rad^2), set by the red
    lights, grown by every turn, and the weight it gives the rows' lean against it."""

    var_rad2: float

    @classmethod
    def placed(cls, sigma_rad: float) -> Bearing:
        """At the start: facing the start heading to within ``sigma_rad`` (1 sigma)."""
        return cls(sigma_rad**2)

    @classmethod
    def unknown(cls) -> Bearing:
        """Facing its compass heading to within what reading the grid at all allows (45 degrees,
        1 sigma): every reference outweighs it."""
        return cls.placed(math.pi / 4)

    def turned(self) -> None:
        """A 90-degree turn, recalibrated on the newest row, adds its residual."""
        self.var_rad2 += TURN_SIGMA_RAD**2

    def lights(self, sigma_rad: float, left_rad: float = 0.0) -> None:
        """The red lights measured the heading to ``sigma_rad`` (1 sigma) and ``left_rad`` of
        what they showed was not turned out (below the correction's threshold)."""
        self.var_rad2 = min(self.var_rad2, sigma_rad**2 + left_rad**2)

    def rows_gain(self, rows_err_rad: float, turned_rad: float) -> float:
        """The weight (0-1) of a heading error of ``rows_err_rad`` measured against the rows'
        lean, against the robot's own heading: the Kalman gain ``var / (var + sigma_rows^2)``;
        1 for an error over ``turned_rad`` (a turn of the robot's own: a slip, a bump), which no
        reference's error explains."""
        if abs(rows_err_rad) > turned_rad:
            return 1.0
        return self.var_rad2 / (self.var_rad2 + ROWS_LEAN_SIGMA_RAD**2)

    def took_rows(self, gain: float) -> None:
        """The heading was corrected by ``gain`` of what the rows said: its variance is the
        fused estimate's (``(1 - k)^2 var + k^2 sigma_rows^2``, right for any gain)."""
        self.var_rad2 = (1 - gain) ** 2 * self.var_rad2 + gain**2 * ROWS_LEAN_SIGMA_RAD**2
