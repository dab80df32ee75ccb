"""stcvision: read phosphor marks through a catadioptric camera.

The vision pipeline (dark frame, phi/theta unwarp, channel filters, dot search, heading fit,
rotation-time recalibration, cell observation), the calibration-profile data types and the rerun
logging helpers live here. The simulator (``stcvision.sim_camera``), the robots
(``stcvision.controllers``) and the calibration workflow (``stcvision.calibration``) install under
this one name from folders of their own (docs/architecture.md).

The names a user reaches for first are importable from the package itself::

    from stcvision import Pipeline, Profile, read_image, run_cover, CoverConfig, Board

They are loaded lazily, on first use (:pep:`562`), so ``import stcvision`` stays light: it
imports neither OpenCV, numba nor the simulator until one of these names is asked for. This
facade is the one place of the package that names the other packages (the robots' runs, the
board, the shipped profile), and only as strings in :data:`_LAZY`: the pipeline's own modules
never import the simulator, the robots or the calibration workflow (docs/architecture.md).
"""

from __future__ import annotations

import importlib

from stcvision.errors import BadInputError, StcVisionError

__version__ = "0.1.0"

#: public name -> (module, attribute in it); the attribute None means the module itself
_LAZY: dict[str, tuple[str, str | None]] = {
    # the vision pipeline and its stages
    "Pipeline": ("stcvision.pipeline", "Pipeline"),
    "PipelineParams": ("stcvision.pipeline", "PipelineParams"),
    "PipelineResult": ("stcvision.pipeline", "PipelineResult"),
    "Profile": ("stcvision.profile", "Profile"),
    "default_profile": ("stcvision.calibration.profiles", "default_profile"),
    "stages": ("stcvision.stages", None),
    "CellObservation": ("stcvision.observation", "CellObservation"),
    # frames and files
    "read_image": ("stcvision.fileio", "read_image"),
    "write_image": ("stcvision.fileio", "write_image"),
    # scoring, datasets, evaluation
    "score_frame": ("stcvision.scoring", "score_frame"),
    "Dataset": ("stcvision.datasets", "Dataset"),
    "open_dataset": ("stcvision.datasets", "open_dataset"),
    "load_recipe": ("stcvision.datasets", "load_recipe"),
    "evaluate_dataset": ("stcvision.evaluate", "evaluate_dataset"),
    # the sweep runner (local pool or Dask)
    "Task": ("stcvision.sweep", "Task"),
    "SweepOptions": ("stcvision.sweep", "SweepOptions"),
    "run_sweep": ("stcvision.sweep", "run_sweep"),
    # the robots: STC coverage, Buffon's needle, TASTI 2 search
    "Board": ("stcvision.sim_camera.board", "Board"),
    "run_cover": ("stcvision.controllers.stc.loop", "run_cover"),
    "CoverConfig": ("stcvision.controllers.stc.config", "CoverConfig"),
    "measure_nest": ("stcvision.controllers.buffon.run", "measure"),
    "run_search": ("stcvision.controllers.search.run", "run_search"),
    "SearchScene": ("stcvision.controllers.search.run", "SearchScene"),
    "SearchConfig": ("stcvision.controllers.search.controller", "SearchConfig"),
}

#: the public names: the error classes, the version and the lazy names (the keys of _LAZY)
__all__ = ["BadInputError", "StcVisionError", "__version__", *_LAZY]


def __getattr__(name: str):
    """Import a public name's module on first use and keep the name here."""
    try:
        module, attr = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'stcvision' has no attribute {name!r}") from None
    obj = importlib.import_module(module)
    if attr is not None:
        obj = getattr(obj, attr)
    globals()[name] = obj
    return obj


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
