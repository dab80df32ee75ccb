"""The pipeline's stages, one module each, each a pure function with frozen, documented
parameters.

``front`` (dark frame, background, window sums, unwarp, channel separation), ``dots``, ``rows``,
``red`` and ``heading``; the cell observation is :mod:`stcvision.observation`. Each module holds
its stage's public function, the compiled loops it runs, and chooses between them itself;
``compiled`` holds the helpers those loops share, ``common`` the contracts every stage checks.
Seed 003 sections implemented here: "Noise handling", "Image Transformation and Filtering",
"Finding the green dots", "Angle Detection" and "Rotation and Calibration". Inputs are never
modified; outputs are new arrays or small frozen results. A missing detection is a value
(``ok=False`` with a reason), not an exception.
"""

from stcvision.stages.common import FRAME_DTYPES, SUM_DTYPES, Scratch, check_frame, noise_floor
from stcvision.stages.dots import DotParams, Dots, find_dots, mirror_centroids, noise_gain
from stcvision.stages.front import (
    ChannelParams,
    GatherTables,
    UnwarpMap,
    check_dark_dtype,
    estimate_background,
    filter_channels,
    hot_pixels,
    quantum_dn,
    robust_sigma,
    separate_channels,
    subtract_dark,
    unwarp,
    window_sums,
)
from stcvision.stages.heading import HeadingFit, HeadingParams, Recalibration, fit_heading, recalibrate_turn
from stcvision.stages.red import RedLights, RedParams, find_red
from stcvision.stages.rows import RowParams, find_rows

__all__ = [
    "ChannelParams",
    "DotParams",
    "Dots",
    "RowParams",
    "HeadingFit",
    "HeadingParams",
    "RedLights",
    "RedParams",
    "Recalibration",
    "UnwarpMap",
    "GatherTables",
    "FRAME_DTYPES",
    "SUM_DTYPES",
    "Scratch",
    "check_dark_dtype",
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
    "find_rows",
    "fit_heading",
    "hot_pixels",
    "mirror_centroids",
    "recalibrate_turn",
    "subtract_dark",
    "unwarp",
    "window_sums",
]
