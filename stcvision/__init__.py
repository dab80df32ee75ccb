"""stcvision: read phosphor marks through a catadioptric camera.

The vision pipeline (dark frame, phi/theta unwarp, channel filters, dot search, heading fit,
rotation-time recalibration, cell observation), the calibration-profile data types and the rerun
logging helpers live here. ``import stcvision`` stays light: the simulator (``sim_camera``), the
controllers and the calibration workflow are separate import packages.
"""

from stcvision.errors import BadInputError, StcVisionError

__version__ = "0.1.0"

__all__ = ["BadInputError", "StcVisionError", "__version__"]
