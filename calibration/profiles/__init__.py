"""Shipped calibration profiles (JSON package data).

``default.json`` is the profile of the default simulated robot (``sim_camera`` defaults). It is
produced by :func:`stcvision.calibration.defaults.build_default_profile` -- the calibration workflow run
on rendered frames -- and a test regenerates it and compares.
"""

from __future__ import annotations

from importlib import resources

from stcvision.profile import Profile

__all__ = ["default_profile", "default_profile_path"]


def default_profile_path():
    return resources.files(__package__) / "default.json"


def default_profile() -> Profile:
    """The shipped profile of the default simulated camera."""
    import json

    data = json.loads(default_profile_path().read_text(encoding="utf-8"))
    return Profile.from_dict(data, where="shipped default profile")
