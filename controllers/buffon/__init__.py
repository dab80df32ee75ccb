"""The Buffon's-needle explorer (Girgin & Sahin, "Blind Area Measurement with Mobile Robots",
CMU-RI-TR-03-42, 2003): blind area measurement by two visits and a pheromone trail.

* :mod:`~stcvision.controllers.buffon.behaviour` -- the exploration behaviour of sec. 3.2 (scalar and
  batched, one source of the equations);
* :mod:`~stcvision.controllers.buffon.counter` -- the leaky integrator and crossing counter of sec. 4;
* :mod:`~stcvision.controllers.buffon.nests` -- nests in body lengths, spec parsing, the consistent scale;
* :mod:`~stcvision.controllers.buffon.batched` -- the fast Monte-Carlo path (numba) of the two visits;
* :mod:`~stcvision.controllers.buffon.pymunk_path` -- the same trial on the pymunk world (the reference);
* :mod:`~stcvision.controllers.buffon.estimate` -- nBC, the absolute area 2 L1 L2 / (pi N), intervals;
* :mod:`~stcvision.controllers.buffon.experiments` -- the paper's experiment sets and ``reproduce``;
* :mod:`~stcvision.controllers.buffon.rr` -- one trial in rerun (an observer).
"""

from stcvision.controllers.buffon.behaviour import (
    Explorer,
    ExplorerParams,
    ExplorerState,
    explorer_step,
    explorer_step_batch,
)
from stcvision.controllers.buffon.counter import CounterParams, LeakyIntegrator, count_crossings
from stcvision.controllers.buffon.nests import BODY_LENGTH_M, Nest, parse_nest

__all__ = [
    "BODY_LENGTH_M",
    "CounterParams",
    "Explorer",
    "ExplorerParams",
    "ExplorerState",
    "LeakyIntegrator",
    "Nest",
    "count_crossings",
    "explorer_step",
    "explorer_step_batch",
    "parse_nest",
]
