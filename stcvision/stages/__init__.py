"""The pipeline's stages, one module each, each a pure function with frozen, documented parameters.

``dark`` (dark frame, background and noise), ``window`` (window sums), ``ground_view`` (the
unwarp to the ground view), ``channels`` (red/green separation), ``dots``, ``rows``, ``red`` and
``heading``; the cell observation is :mod:`stcvision.observation`; ``front`` puts the first four together as the
pipeline runs them. Each module holds its stage's public function, the compiled loops it runs
and the OpenCV reference beside them, and chooses between them itself; ``compiled`` holds the
helpers those loops share, ``common`` the contracts every stage checks and the stage timing.
Sections of the ant-like STC paper (Srour & Abboud) implemented here: "Noise handling", "Image
Transformation and Filtering", "Finding the green dots", "Angle Detection" and "Rotation and
Calibration". Inputs are never modified; outputs are new arrays or small frozen results. A missing
detection is a value (``ok=False`` with a reason), not an exception.
"""

from stcvision.stages.channels import ChannelParams, filter_channels, separate_channels
from stcvision.stages.common import FRAME_DTYPES, SUM_DTYPES, Scratch, StageTimes, check_frame, noise_floor
from stcvision.stages.dark import (
    DARK_ROOM_MAX_STRUCTURE,
    check_dark_dtype,
    estimate_background,
    frame_structure,
    hot_pixels,
    quantum_dn,
    robust_sigma,
    subtract_dark,
)
from stcvision.stages.dots import DotParams, Dots, find_dots, mirror_centroids, noise_gain
from stcvision.stages.ground_view import GatherTables, UnwarpMap, unwarp
from stcvision.stages.heading import HeadingFit, HeadingParams, Recalibration, fit_heading, recalibrate_turn
from stcvision.stages.red import RedLights, RedParams, RedReading, find_red, read_red
from stcvision.stages.rows import RowParams, find_rows
from stcvision.stages.window import window_sums

__all__ = [
    "ChannelParams",
    "DotParams",
    "Dots",
    "RowParams",
    "HeadingFit",
    "HeadingParams",
    "RedLights",
    "RedParams",
    "RedReading",
    "Recalibration",
    "UnwarpMap",
    "GatherTables",
    "FRAME_DTYPES",
    "SUM_DTYPES",
    "Scratch",
    "StageTimes",
    "DARK_ROOM_MAX_STRUCTURE",
    "check_dark_dtype",
    "frame_structure",
    "check_frame",
    "estimate_background",
    "noise_floor",
    "quantum_dn",
    "robust_sigma",
    "noise_gain",
    "separate_channels",
    "filter_channels",
    "find_dots",
    "find_red",
    "read_red",
    "find_rows",
    "fit_heading",
    "hot_pixels",
    "mirror_centroids",
    "recalibrate_turn",
    "subtract_dark",
    "unwarp",
    "window_sums",
]
