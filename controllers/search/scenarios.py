"""The layouts of the paper's experiments as this toolkit reproduces them (metres, relative to
the start, heading 0 = +x). The TASTI 2 paper (Russell) gives the step (141 mm), the
patch (350 mm diameter), the can the ring was tuned on and the move counts (21 without the
obstacle, 30 with it, sec. V); it gives no coordinates, so the places are ours: the patch where
the default spiral (turns 0.25 m apart) first samples it on step 21, the can on the path
before step 13, and a larger obstacle where the spiral turns by more than 45 degrees across it
(the case of Figs. 7 and 8)."""

from __future__ import annotations

from stcvision.controllers.search.patterns import SpiralPattern
from stcvision.sim_camera.layers import TASTI2_SALT_PATCH_DIAMETER_M
from stcvision.sim_camera.robot_sensors import CapacitiveRingParams

__all__ = ["FIG6_OBSTACLE", "FIG7_OBSTACLE", "FIG13_CAN", "PAPER_PATCH", "paper_spiral"]

_R = 0.5 * TASTI2_SALT_PATCH_DIAMETER_M
#: the salt patch, first sampled on the spiral's step 21 (Figs. 11-14)
PAPER_PATCH = (-0.51, 0.306, _R)
#: a steel can (the ring's reference can) in the spiral's path before step 13 (Fig. 13)
FIG13_CAN = (0.40, 0.10, CapacitiveRingParams().reference_can_radius_m)
#: an 8 cm radius obstacle the spiral turns round by more than 45 degrees (Figs. 7 and 8)
FIG7_OBSTACLE = (0.43, 0.06, 0.08)
#: an obstacle on the first petal of the radial flower (Fig. 6)
FIG6_OBSTACLE = (0.75, 0.45, 0.08)


def paper_spiral(max_steps: int = 60) -> SpiralPattern:
    return SpiralPattern(max_steps=max_steps)
