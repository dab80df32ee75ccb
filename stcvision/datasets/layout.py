"""A dataset folder's names and the values every part of it is keyed by: the frame file of
index ``k``, the random stream of a frame, dark frame or calibration frame (spawned from the
dataset seed, so each depends on its own key alone), and the content key of a camera's settings.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

__all__ = [
    "DATASET_SCHEMA_VERSION",
    "IMAGE_SUFFIXES",
    "content_key",
    "frame_name",
    "is_empty_folder",
    "seed_stream",
]

DATASET_SCHEMA_VERSION = 1
#: the image files a folder of frames may hold
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


def seed_stream(seed: int, *key: int):
    """The random generator of the part ``key`` of a dataset of ``seed``.

    Parameters
    ----------
    seed : int
        The dataset's seed.
    *key : int
        The part: ``(0, k)`` frame ``k``, ``(1, group)`` a dark frame, ``(2, camera, j)`` a
        calibration frame.

    Returns
    -------
    numpy.random.Generator
    """
    import numpy as np

    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=key))


def content_key(obj: Any) -> str:
    """The SHA-256 (hex) of ``obj`` as sorted JSON: equal settings, equal keys.

    Parameters
    ----------
    obj : JSON-serialisable value

    Returns
    -------
    str
    """
    return hashlib.sha256(json.dumps(obj, sort_keys=True).encode()).hexdigest()


def frame_name(k: int) -> str:
    """The file of frame ``k`` in the dataset folder (``frames/NNNNNN.png``).

    Parameters
    ----------
    k : int

    Returns
    -------
    str
    """
    return f"frames/{k:06d}.png"


def is_empty_folder(d: Path) -> bool:
    """Whether ``d`` is missing or an empty folder (a place a new dataset may be made).

    Parameters
    ----------
    d : Path

    Returns
    -------
    bool
    """
    return not d.exists() or (d.is_dir() and not any(d.iterdir()))
