"""Labelled frame sets: recipes, deterministic resumable generation, reading and validation.

A *recipe* (``datasets/recipes/*.json``, format in ``datasets/README.md``) lists groups of
frames; each group names how many frames, the scene parameters of
:func:`sim_camera.scenarios.cell_scene`, and camera and sensor overrides.
:func:`calibration.dataset_render.generate` renders it into a dataset folder::

    manifest.json          schema_version, recipe, seed, cameras (optics, pattern seed, profile),
                           groups, dark frames, counts, complete
    frames/NNNNNN.png      dark-room frames (640x480 BGR by default)
    dark/GROUP.png         median dark frame of each group's camera and sensor settings
    labels.jsonl           one JSON object per frame: the camera's ground truth plus "frame",
                           "index", "group", "camera", "dark"
    calibration/CAM_J.png  lights-on frames at the calibration pose (if the recipe asks)
    profiles/CAM.json      each camera's profile from the calibration workflow (if asked)

Determinism: frame ``k`` draws its scene and its noise from
``SeedSequence(seed, spawn_key=(0, k))`` alone, so it does not depend on the frames before it;
dark frames use ``(1, group)``, calibration frames ``(2, camera, j)``. Same recipe + seed gives
byte-identical files however the work is split, and a re-run skips every finished chunk of
frames (each file is written atomically; the chunks' labels are kept in the sweep store
``.sweep.jsonl`` until ``labels.jsonl`` is written at the end).

Generation needs the simulator (``sim_camera``) and the calibration workflow, so it lives in
:mod:`calibration.dataset_render`, beside the workflow that fits each camera's profile; this
module reads and checks datasets and recipes and needs neither.
"""

from __future__ import annotations

import hashlib
import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stcvision.errors import BadInputError
from stcvision.fileio import read_json
from stcvision.limits import MAX_DARK_FRAMES, MAX_DATASET_FRAMES

__all__ = [
    "DATASET_SCHEMA_VERSION",
    "RECIPE_SCHEMA_VERSION",
    "Dataset",
    "Group",
    "Recipe",
    "list_images",
    "load_recipe",
    "open_dataset",
    "parse_recipe",
]

RECIPE_SCHEMA_VERSION = 1
DATASET_SCHEMA_VERSION = 1
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")

#: keyword arguments of ``sim_camera.scenarios.cell_scene`` a recipe may set (pairs as lists)
SCENE_KEYS = {
    "cells": "pair",
    "obstacle_fraction": "number",
    "heading_error_deg": "number_or_pair",
    "position_error_m": "number",
    "box_prob": "number",
    "neighbour_mark_prob": "number",
    "age_range_s": "pair",
    "fresh_age_s": "pair",
    "charge_s": "number",
    "subcell_m": "number",
}
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
    #: the camera preset (sim_camera.hardware.CAMERAS) whose sensor ``sensor`` overrides; None: the webcam
    sensor_profile: str | None = None


@dataclass(frozen=True, kw_only=True)
class Recipe:
    name: str
    seed: int
    dark_frames: int
    lights_on_frames: int
    profiles: bool
    groups: tuple[Group, ...]
    raw: dict = field(repr=False)

    @property
    def n_frames(self) -> int:
        return sum(g.n for g in self.groups)


def _int(v: Any, what: str, *, lo: int = 0, hi: int | None = None) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo or (hi is not None and v > hi):
        span = f">= {lo}" if hi is None else f"in {lo}..{hi}"
        raise BadInputError(f"{what} must be an integer {span}, got {v!r}")
    return v


def _plain_name(name: Any) -> bool:
    """A non-empty name of letters, digits, '-' and '_' (safe as a file or folder name)."""
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
        kind = SCENE_KEYS.get(k)
        if kind is None:
            raise BadInputError(f"{where}: unknown scene parameter {k!r}; expected some of {sorted(SCENE_KEYS)}")
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
        raise BadInputError(f"{where}: calibration.profiles must be true or false")
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
    return parse_recipe(read_json(path, what="recipe"), where=f"recipe {path}")


# ---------------------------------------------------------------------------------------- generation
def _stream(seed: int, *key: int):
    import numpy as np

    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=key))


def _key(obj: Any) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True).encode()).hexdigest()


def _frame_name(k: int) -> str:
    return f"frames/{k:06d}.png"


def _is_empty(d: Path) -> bool:
    return not d.exists() or (d.is_dir() and not any(d.iterdir()))


class _Progress:
    """A one-line text progress bar on stderr (only on a terminal)."""

    def __init__(self, total: int, label: str, stream=None) -> None:
        self.total, self.label = total, label
        self.stream = stream or sys.stderr
        self.on = bool(getattr(self.stream, "isatty", lambda: False)())
        self.done = 0

    def __call__(self, n: int = 1) -> None:
        self.done += n
        if self.on:
            w = 30
            k = int(w * self.done / max(self.total, 1))
            self.stream.write(f"\r{self.label} [{'#' * k}{'.' * (w - k)}] {self.done}/{self.total}")
            self.stream.flush()

    def close(self) -> None:
        if self.on:
            self.stream.write("\n")
            self.stream.flush()


# ---------------------------------------------------------------------------------------- reading
@dataclass(frozen=True)
class Dataset:
    """A validated dataset folder: its manifest and its labels (in frame order)."""

    root: Path
    manifest: dict
    labels: list[dict]

    @property
    def image_size_px(self) -> tuple[int, int]:
        return tuple(self.manifest["image_size_px"])

    def profile_path(self, camera: str) -> Path | None:
        p = self.manifest["cameras"].get(camera, {}).get("profile")
        return self.root / p if p else None


def open_dataset(root: str | Path) -> Dataset:
    """Read and check a dataset folder; every problem is a one-line :class:`BadInputError`.

    Checked: the manifest exists (when labels do) and is a complete dataset of a known schema;
    every line of ``labels.jsonl`` is a JSON object naming a frame; the manifest's frame count
    matches; every labelled frame exists; every frame in ``frames/`` has a label; the dark
    frames and profiles the manifest names exist; every PNG frame and dark frame is 3-channel at
    its sensor's depth (8-bit, or 16-bit for a deeper ADC: from the PNG header). Frames are
    decoded later (by the evaluation), where a corrupt frame is skipped and counted and a wrong
    size is an error.
    """
    root = Path(root)
    if not root.is_dir():
        what = "is a file, not a folder" if root.exists() else "does not exist"
        raise BadInputError(f"dataset folder {root} {what}; expected a folder made by 'dataset generate'")
    mpath, lpath = root / "manifest.json", root / "labels.jsonl"
    if not mpath.exists() and not lpath.exists():
        raise BadInputError(f"{root} is not a dataset (no manifest.json); expected a folder made by 'dataset generate'")
    if not mpath.exists():
        raise BadInputError(
            f"dataset {root} has labels.jsonl but no manifest.json; expected a folder made by "
            "'stcvision dataset generate' (or remove labels.jsonl to run on the images without labels)"
        )
    m = read_json(mpath, what="dataset manifest")
    if not isinstance(m, dict) or m.get("kind") != "stcvision-dataset":
        raise BadInputError(f'{mpath} is not a dataset manifest (no "kind": "stcvision-dataset")')
    v = m.get("schema_version")
    if not isinstance(v, int) or v > DATASET_SCHEMA_VERSION:
        raise BadInputError(
            f"{mpath}: schema_version {v!r} is not supported; expected <= {DATASET_SCHEMA_VERSION} (upgrade stcvision)"
        )
    for key in ("cameras", "groups", "counts", "image_size_px"):
        if key not in m:
            raise BadInputError(f"{mpath} has no {key!r}; expected a complete dataset manifest")
    if not m.get("complete"):
        raise BadInputError(
            f"dataset {root} is incomplete (generation was interrupted); "
            "re-run 'stcvision dataset generate' to finish it"
        )
    if not lpath.exists():
        raise BadInputError(f"dataset {root} has a manifest but no labels.jsonl")
    labels = []
    for i, line in enumerate(lpath.read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip():
            continue
        try:
            lab = json.loads(line)
        except json.JSONDecodeError as exc:
            raise BadInputError(
                f"{lpath} line {i} is not valid JSON ({exc.msg}); expected one object per line"
            ) from None
        if not isinstance(lab, dict) or not isinstance(lab.get("frame"), str):
            raise BadInputError(f'{lpath} line {i} has no "frame" (the frame\'s file name)')
        for key in ("dots", "pose", "sensor"):
            if key not in lab:
                raise BadInputError(f"{lpath} line {i} ({lab['frame']}) has no {key!r}; expected a camera truth dict")
        if not (root / lab["frame"]).exists():
            raise BadInputError(f"{lpath} line {i} labels {lab['frame']}, but that frame is missing from {root}")
        labels.append(lab)
    n = m["counts"].get("frames")
    if n != len(labels):
        raise BadInputError(f"{mpath} lists {n} frames but {lpath} has {len(labels)} labels")
    named = {lab["frame"] for lab in labels}
    if len(named) != len(labels):
        raise BadInputError(f"{lpath} labels the same frame twice")
    frames_dir = root / "frames"
    if frames_dir.is_dir():
        for p in sorted(frames_dir.iterdir()):
            rel = f"frames/{p.name}"
            if p.suffix.lower() in IMAGE_SUFFIXES and rel not in named:
                raise BadInputError(f"{root / rel} has no label in {lpath}; expected every frame to be labelled")
    for lab in labels:
        dark = lab.get("dark")
        if dark is not None and not (root / dark).exists():
            raise BadInputError(f"dark frame {root / dark} (for {lab['frame']}) is missing")
    _check_depths(root, labels)
    for cid, c in m["cameras"].items():
        if c.get("profile") and not (root / c["profile"]).exists():
            raise BadInputError(f"profile {root / c['profile']} of camera {cid} is missing")
    return Dataset(root, m, labels)


def _png_header(path: Path) -> tuple[int, int] | None:
    """(bit depth per channel, PNG colour type) from a PNG's IHDR chunk (its first 26 bytes), or
    None if ``path`` is not a PNG file. Colour type 2 is RGB (a BGR frame), 0 grey."""
    with open(path, "rb") as f:
        head = f.read(26)
    if len(head) < 26 or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    return head[24], head[25]


def _check_depths(root: Path, labels: list[dict]) -> None:
    """Every labelled PNG frame and its dark frame hold 3 channels at the depth the label's sensor
    digitises (8 bits for an 8-bit ADC, 16 for 9-16 bits: the ADC counts), read from the PNG
    headers (the frames are not decoded)."""
    seen: dict[str, int] = {}
    for lab in labels:
        bits = lab["sensor"].get("adc_bits", 8) if isinstance(lab["sensor"], dict) else 8
        want = 8 if bits == 8 else 16
        for name in (lab["frame"], lab.get("dark")):
            if name is None or seen.get(name) == want:
                continue
            head = _png_header(root / name)
            if head is None:
                continue  # not a PNG: decoded (and checked) by the evaluation
            depth, colour = head
            if colour != 2:
                raise BadInputError(f"{root / name} is not a 3-channel BGR PNG (colour type {colour}); expected BGR")
            if depth != want:
                raise BadInputError(
                    f"{root / name} is a {depth}-bit PNG but {lab['frame']}'s sensor has a {bits}-bit ADC; "
                    f"expected a {want}-bit PNG"
                )
            seen[name] = want


def list_images(root: str | Path) -> list[Path]:
    """The image files of a folder of the user's own frames (sorted by name; ``frames/`` if the
    folder itself holds none)."""
    root = Path(root)
    if not root.is_dir():
        raise BadInputError(f"frame folder {root} does not exist")
    for d in (root, root / "frames"):
        if d.is_dir():
            imgs = sorted(p for p in d.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
            if imgs:
                return imgs
    raise BadInputError(
        f"{root} holds no images; expected PNG or JPEG frames (or a dataset made by 'dataset generate')"
    )
