"""The TASTI 2 chemical-search robot (Russell, "TASTI 2 Searches for Chemicals in the Presence of
Obstacles").

* :mod:`~controllers.search.patterns` -- the radial flower (equations (1)-(2)) and the
  Archimedes spiral as lists of step headings; the planned sampling points (equations (4)-(5));
* :mod:`~controllers.search.controller` -- the pure state machine (phases of Fig. 5, the
  avoid/unavoid detour of sec. III, policies none / simple / improved);
* :mod:`~controllers.search.run` -- one run in the pymunk world (the move executor);
* :mod:`~controllers.search.beacon` -- camera fixes from a two-light red beacon (beyond the paper);
* :mod:`~controllers.search.metrics` -- odometry errors, shadow area, the summary dict;
* :mod:`~controllers.search.plots`, :mod:`~controllers.search.recorder` -- figures and rerun;
* :mod:`~controllers.search.scenarios`, :mod:`~controllers.search.experiments` -- the paper's
  layouts, ``run_trial`` and ``reproduce``.
"""
