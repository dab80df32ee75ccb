"""The Buffon's-needle explorer (Girgin & Sahin, "Blind Area Measurement with Mobile Robots",
CMU-RI-TR-03-42, 2003): blind area measurement by two visits and a pheromone trail.

* :mod:`~controllers.buffon.behaviour` -- the exploration behaviour of sec. 3.2 (scalar and
  batched, one source of the equations);
* :mod:`~controllers.buffon.counter` -- the leaky integrator and crossing counter of sec. 4;
* :mod:`~controllers.buffon.nests` -- nests in body lengths, spec parsing, the consistent scale;
* :mod:`~controllers.buffon.batched` -- the fast Monte-Carlo path (numba) of the two visits;
* :mod:`~controllers.buffon.pymunk_path` -- the same trial on the pymunk world (the reference);
* :mod:`~controllers.buffon.estimate` -- nBC, the absolute area 2 L1 L2 / (pi N), intervals;
* :mod:`~controllers.buffon.experiments` -- the paper's experiment sets and ``reproduce``;
* :mod:`~controllers.buffon.rr` -- one trial in rerun (an observer).
"""

from controllers.buffon.behaviour import Explorer, ExplorerParams, ExplorerState, explorer_step, explorer_step_batch
from controllers.buffon.counter import CounterParams, LeakyIntegrator, count_crossings
from controllers.buffon.nests import BODY_LENGTH_M, Nest, parse_nest

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
