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
* :mod:`~stcvision.controllers.buffon.rr` -- one trial in rerun (an observer);
* :mod:`~stcvision.controllers.buffon.defaults` -- the settings the command line shows.
"""

from __future__ import annotations

import importlib

# name -> module; loaded on first use (PEP 562) so that importing one of the room's modules (the
# command line's defaults, say) does not compile the behaviour's numba kernels
_HOMES = {
    "BODY_LENGTH_M": "nests",
    "CounterParams": "counter",
    "Explorer": "behaviour",
    "ExplorerParams": "behaviour",
    "ExplorerState": "behaviour",
    "LeakyIntegrator": "counter",
    "Nest": "nests",
    "count_crossings": "counter",
    "explorer_step": "behaviour",
    "explorer_step_batch": "behaviour",
    "parse_nest": "nests",
}
__all__ = sorted(_HOMES)


def __getattr__(name: str):
    if name in _HOMES:
        return getattr(importlib.import_module(f"{__name__}.{_HOMES[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
