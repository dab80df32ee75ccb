"""Dataset recipes: parsing and checking.

Dataset recipes (``datasets/recipes/*.json``, format in ``datasets/README.md``): parsing and
checking, every problem a one-line :class:`~stcvision.errors.BadInputError`.

The scene parameters a recipe may set are the keyword arguments of the simulator's scene function
(:func:`stcvision.sim_camera.scenarios.cell_scene`), read from its signature (:func:`scene_keys`), so a new
scene parameter needs no second list here (only its range, in ``_SCENE_RANGES``).
"""

from __future__ import annotations

import functools
import inspect
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stcvision.errors import BadInputError
from stcvision.fileio import read_json
from stcvision.limits import MAX_DARK_FRAMES, MAX_DATASET_FRAMES

__all__ = ["RECIPE_SCHEMA_VERSION", "Group", "Recipe", "load_recipe", "parse_recipe", "scene_keys"]

RECIPE_SCHEMA_VERSION = 1


@functools.cache
def scene_keys() -> dict[str, str]:
    """Return the scene parameters a recipe may set, each with the JSON it takes.

    The scene parameters a recipe may set: the keyword-only arguments of
    :func:`stcvision.sim_camera.scenarios.cell_scene`, each with the JSON it takes, from its annotation:
    ``"pair"`` (a tuple: a list of two numbers), ``"number"``, or ``"number_or_pair"`` (either).

    The simulator is imported on the first call (parsing a recipe), not with this module, so that
    reading a dataset does not load it.

    Returns
    -------
    dict
        Parameter name -> kind.
    """
    from stcvision.sim_camera.scenarios import cell_scene

    out = {}
    for name, p in inspect.signature(cell_scene).parameters.items():
        if p.kind is not inspect.Parameter.KEYWORD_ONLY:
            continue
        kinds = {"pair" if part.strip().startswith("tuple") else "number" for part in str(p.annotation).split("|")}
        out[name] = "number_or_pair" if len(kinds) == 2 else kinds.pop()
    return out


_RECIPE_KEYS = {
    "schema_version",
    "name",
    "description",
    "seed",
    "camera",
    "sensor",
    "sensor_profile",
    "pattern_seed",
    "dark_frames",
    "calibration",
    "scene",
    "groups",
}
_GROUP_KEYS = {"name", "n", "scene", "camera", "sensor", "sensor_profile", "pattern_seed", "description"}
_CALIB_KEYS = {"lights_on_frames", "profiles"}


# ---------------------------------------------------------------------------------------- recipes
@dataclass(frozen=True, kw_only=True)
class Group:
    """One group of frames: ``n`` scenes from one camera at one sensor setting."""

    name: str
    n: int
    scene: dict
    camera: dict  # optics overrides (MirrorCameraParams fields)
    sensor: dict  # sensor overrides (SensorParams fields)
    pattern_seed: int
    #: the camera preset (stcvision.sim_camera.hardware.CAMERAS) whose sensor ``sensor`` overrides; None: the webcam
    sensor_profile: str | None = None


@dataclass(frozen=True, kw_only=True)
class Recipe:
    """A validated dataset recipe (``datasets/README.md`` describes each key).

    Attributes
    ----------
    name : str
        The recipe's name (used in the default output folder and in reports).
    seed : int
        The default seed.
    dark_frames : int
        Frames median-stacked into each dark frame.
    lights_on_frames : int
        Lights-on frames of the calibration board per camera.
    profiles : bool
        Make each camera's profile with the calibration workflow.
    groups : tuple of Group
        The groups of frames, each from one camera at one sensor setting.
    raw : dict
        The recipe's JSON as read.
    """

    name: str
    seed: int
    dark_frames: int
    lights_on_frames: int
    profiles: bool
    groups: tuple[Group, ...]
    raw: dict = field(repr=False)

    @property
    def n_frames(self) -> int:
        """The frames of every group together."""
        return sum(g.n for g in self.groups)


def _int(v: Any, what: str, *, lo: int = 0, hi: int | None = None) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo or (hi is not None and v > hi):
        span = f">= {lo}" if hi is None else f"in {lo}..{hi}"
        raise BadInputError(f"{what} must be an integer {span}, got {v!r}")
    return v


def _plain_name(name: Any) -> bool:
    """Say whether a name is non-empty, of letters, digits, '-' and '_' (safe as a file or folder name)."""
    return (
        isinstance(name, str)
        and bool(name)
        and name.replace("-", "").replace("_", "").isascii()
        and (name.replace("-", "").replace("_", "").isalnum())
    )


def _obj(v: Any, what: str) -> dict:
    if not isinstance(v, dict):
        raise BadInputError(f"{what} must be a JSON object, got {type(v).__name__}")
    return v


def _name(v: Any, what: str) -> str | None:
    if v is not None and (not isinstance(v, str) or not v):
        raise BadInputError(f"{what} must be a camera preset's name (e.g. cooled), got {v!r}")
    return v


def _scene(d: dict, where: str) -> dict:
    out = {}
    for k, v in _obj(d, where).items():
        kind = scene_keys().get(k)
        if kind is None:
            raise BadInputError(f"{where}: unknown scene parameter {k!r}; expected some of {sorted(scene_keys())}")
        num = isinstance(v, int | float) and not isinstance(v, bool)
        pair = isinstance(v, list) and len(v) == 2 and all(isinstance(x, int | float) for x in v)
        if kind == "number" and not num:
            raise BadInputError(f"{where}: scene parameter {k} must be a number, got {v!r}")
        if kind == "pair" and not pair:
            raise BadInputError(f"{where}: scene parameter {k} must be a pair [a, b] of numbers, got {v!r}")
        if kind == "number_or_pair" and not (num or pair):
            raise BadInputError(f"{where}: scene parameter {k} must be a number or a pair [a, b], got {v!r}")
        out[k] = tuple(v) if isinstance(v, list) else v
        _check_scene_value(k, out[k], where)
    if "cells" in out:
        out["cells"] = tuple(int(x) for x in out["cells"])
    return out


#: what each scene parameter's values must lie in (closed ranges; None = unbounded); pairs are
#: [low, high] ranges drawn from (``heading_error_deg`` as a pair too), so low <= high
_SCENE_RANGES = {
    "cells": (1, 100),
    "obstacle_fraction": (0.0, 0.9),
    "heading_error_deg": (-180.0, 180.0),
    "position_error_m": (0.0, 0.1),
    "box_prob": (0.0, 1.0),
    "neighbour_mark_prob": (0.0, 1.0),
    "age_range_s": (0.0, None),  # seconds since the mark's charge ended: never negative
    "fresh_age_s": (0.0, None),
    "charge_s": (1e-3, None),
    "subcell_m": (1e-3, None),
}


def _check_scene_value(k: str, v, where: str) -> None:
    """One line for a scene parameter that is not finite, out of its range, or a reversed pair."""
    lo, hi = _SCENE_RANGES[k]
    values = v if isinstance(v, tuple) else (v,)
    span = f"[{lo:g}, {hi:g}]" if hi is not None else f">= {lo:g}"
    for x in values:
        if not math.isfinite(x) or x < lo or (hi is not None and x > hi):
            raise BadInputError(f"{where}: scene parameter {k} = {x!r} is out of range; expected {span}")
    if k == "cells" and not all(float(x).is_integer() for x in values):
        raise BadInputError(f"{where}: scene parameter cells must be two whole numbers, got {list(values)}")
    if isinstance(v, tuple) and k != "cells" and v[0] > v[1]:
        raise BadInputError(f"{where}: scene parameter {k} = {list(v)} is reversed; expected [low, high]")


def parse_recipe(d: Any, *, where: str = "recipe") -> Recipe:
    """Validate a recipe dict (see ``datasets/README.md``) and return a :class:`Recipe`."""
    d = _obj(d, where)
    v = d.get("schema_version")
    if v != RECIPE_SCHEMA_VERSION:
        raise BadInputError(f"{where}: schema_version is {v!r}; expected {RECIPE_SCHEMA_VERSION}")
    unknown = set(d) - _RECIPE_KEYS
    if unknown:
        raise BadInputError(f"{where}: unknown key(s) {sorted(unknown)}; expected some of {sorted(_RECIPE_KEYS)}")
    name = d.get("name")
    if not isinstance(name, str) or not _plain_name(name.replace(".", "")) or name.startswith("."):
        raise BadInputError(
            f"{where}: 'name' must be a non-empty string of letters, digits, '-', '_' and '.' (no '/', not "
            f"starting with '.': it names the folder under datasets/generated/), got {name!r}"
        )
    calib = _obj(d.get("calibration", {}), f"{where}: calibration")
    unknown = set(calib) - _CALIB_KEYS
    if unknown:
        raise BadInputError(f"{where}: unknown calibration key(s) {sorted(unknown)}; expected {sorted(_CALIB_KEYS)}")
    if not isinstance(calib.get("profiles", False), bool):
        raise BadInputError(f"{where}: stcvision.calibration.profiles must be true or false")
    base_cam = _obj(d.get("camera", {}), f"{where}: camera")
    base_sensor = _obj(d.get("sensor", {}), f"{where}: sensor")
    base_scene = _scene(d.get("scene", {}), f"{where}: scene")
    groups_raw = d.get("groups")
    if not isinstance(groups_raw, list) or not groups_raw:
        raise BadInputError(f"{where}: 'groups' must be a non-empty list of groups")
    groups, names = [], set()
    for i, g in enumerate(groups_raw):
        gw = f"{where}: groups[{i}]"
        g = _obj(g, gw)
        unknown = set(g) - _GROUP_KEYS
        if unknown:
            raise BadInputError(f"{gw}: unknown key(s) {sorted(unknown)}; expected some of {sorted(_GROUP_KEYS)}")
        gname = g.get("name")
        if not isinstance(gname, str) or not _plain_name(gname):
            raise BadInputError(f"{gw}: 'name' must be a non-empty string of letters, digits, '-' and '_'")
        if gname in names:
            raise BadInputError(f"{gw}: group name {gname!r} is used twice")
        names.add(gname)
        groups.append(
            Group(
                name=gname,
                n=_int(g.get("n"), f"{gw}.n", lo=1),
                scene={**base_scene, **_scene(g.get("scene", {}), f"{gw}.scene")},
                camera={**base_cam, **_obj(g.get("camera", {}), f"{gw}.camera")},
                sensor={**base_sensor, **_obj(g.get("sensor", {}), f"{gw}.sensor")},
                pattern_seed=_int(g.get("pattern_seed", d.get("pattern_seed", 0)), f"{gw}.pattern_seed"),
                sensor_profile=_name(g.get("sensor_profile", d.get("sensor_profile")), f"{gw}.sensor_profile"),
            )
        )
    total = sum(g.n for g in groups)
    if total > MAX_DATASET_FRAMES:
        raise BadInputError(
            f"{where}: {total:,} frames in all is over the cap of {MAX_DATASET_FRAMES:,} frames per dataset; "
            "split it into several recipes"
        )
    return Recipe(
        name=name,
        seed=_int(d.get("seed", 0), f"{where}: seed"),
        dark_frames=_int(d.get("dark_frames", 16), f"{where}: dark_frames", lo=1, hi=MAX_DARK_FRAMES),
        lights_on_frames=_int(calib.get("lights_on_frames", 0), f"{where}: calibration.lights_on_frames"),
        profiles=bool(calib.get("profiles", False)),
        groups=tuple(groups),
        raw=d,
    )


def load_recipe(path: str | Path) -> Recipe:
    """Read and validate a dataset recipe file.

    Parameters
    ----------
    path : str or Path
        The recipe's JSON file (``datasets/recipes/*.json``).

    Returns
    -------
    Recipe
        The recipe, every key checked.

    Raises
    ------
    BadInputError
        For a missing or unreadable file and for every problem of its content, in one line.
    """
    return parse_recipe(read_json(path, what="recipe"), where=f"recipe {path}")
