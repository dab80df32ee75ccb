"""The TASTI 2 chemical-search robot (Russell, "TASTI 2 Searches for Chemicals in the Presence of
Obstacles").

* :mod:`~stcvision.controllers.search.patterns` -- the radial flower (equations (1)-(2)) and the
  Archimedes spiral as lists of step headings; the planned sampling points (equations (4)-(5));
* :mod:`~stcvision.controllers.search.controller` -- the pure state machine (phases of Fig. 5, the
  avoid/unavoid detour of sec. III, policies none / simple / improved);
* :mod:`~stcvision.controllers.search.run` -- one run in the pymunk world (the move executor);
* :mod:`~stcvision.controllers.search.beacon` -- camera fixes from a two-light red beacon (beyond the paper);
* :mod:`~stcvision.controllers.search.metrics` -- odometry errors, shadow area, the summary dict;
* :mod:`~stcvision.controllers.search.plots`, :mod:`~stcvision.controllers.search.recorder` -- figures and rerun;
* :mod:`~stcvision.controllers.search.scenarios`, :mod:`~stcvision.controllers.search.experiments` -- the paper's
  layouts, ``run_trial`` and ``reproduce``.
"""
