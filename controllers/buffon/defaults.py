"""The Buffon room's settings that the command line shows as defaults.

A module that imports nothing, so that ``stcvision buffon --help`` can print the paper's trail
width and the correction's reference nest without loading numba, scipy.stats or the simulator;
the modules that compute with these numbers import them from here.
"""

from __future__ import annotations

__all__ = ["CORRECTION_REFERENCE", "PAPER_TRAIL_WIDTH_U", "PAPER_VISIT_STEPS"]

#: Girgin & Sahin, "Blind Area Measurement with Mobile Robots", sec. 4
PAPER_VISIT_STEPS = 50_000  # "the duration of the first visit is fixed to 50000 steps"
PAPER_TRAIL_WIDTH_U = 0.1  # "the width of the pheromone is taken as 0.1"
#: the nest on which the fixed visit lengths' area correction is measured
#: (``stcvision buffon calibrate``; the standard circle of area 100 body lengths squared)
CORRECTION_REFERENCE = "circle:100"
