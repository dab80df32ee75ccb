"""Labelled frame sets: recipes, deterministic resumable generation, reading and validation.

A *recipe* (``datasets/recipes/*.json``, format in ``datasets/README.md``) lists groups of
frames; each group names how many frames, the scene parameters of
:func:`sim_camera.scenarios.cell_scene`, and camera and sensor overrides. :func:`generate`
renders it into a dataset folder::

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
byte-identical files, and a re-run skips every frame whose PNG and label already exist (each
file is written atomically; labels are kept per frame in ``.parts/`` until ``labels.jsonl`` is
written at the end).

Generation needs the simulator (``sim_camera``) and the calibration workflow; they are imported
inside :func:`generate` only, so ``import stcvision.datasets`` stays light.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stcvision.errors import BadInputError, FileExistsRefusedError
from stcvision.fileio import dumps, read_json, write_bytes_atomic, write_json

__all__ = [
    "DATASET_SCHEMA_VERSION",
    "RECIPE_SCHEMA_VERSION",
    "Dataset",
    "Group",
    "Recipe",
    "generate",
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
    "pattern_seed",
    "dark_frames",
    "calibration",
    "scene",
    "groups",
}
_GROUP_KEYS = {"name", "n", "scene", "camera", "sensor", "pattern_seed", "description"}
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


def _int(v: Any, what: str, *, lo: int = 0) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise BadInputError(f"{what} must be an integer >= {lo}, got {v!r}")
    return v


def _obj(v: Any, what: str) -> dict:
    if not isinstance(v, dict):
        raise BadInputError(f"{what} must be a JSON object, got {type(v).__name__}")
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
    if "cells" in out:
        out["cells"] = tuple(int(x) for x in out["cells"])
    return out


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
    if not isinstance(name, str) or not name:
        raise BadInputError(f"{where}: 'name' must be a non-empty string")
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
        if not isinstance(gname, str) or not gname or not gname.replace("-", "").replace("_", "").isalnum():
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
            )
        )
    return Recipe(
        name=name,
        seed=_int(d.get("seed", 0), f"{where}: seed"),
        dark_frames=_int(d.get("dark_frames", 16), f"{where}: dark_frames", lo=1),
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


def _plan(recipe: Recipe, seed: int) -> tuple[dict, list[dict]]:
    """Cameras (by identical optics + pattern seed, in order of first use) and groups."""
    from sim_camera.optics import MirrorCameraParams
    from sim_camera.sensor import SensorParams

    cameras: dict[str, dict] = {}
    by_key: dict[str, str] = {}
    groups = []
    first = 0
    for g in recipe.groups:
        try:
            optics = MirrorCameraParams.from_dict(g.camera).to_dict()
            sensor = SensorParams.from_dict(g.sensor).to_dict()
        except BadInputError as exc:
            raise BadInputError(f"recipe {recipe.name}, group {g.name}: {exc}") from None
        k = _key([optics, g.pattern_seed])
        if k not in by_key:
            cid = f"cam{len(cameras)}"
            by_key[k] = cid
            cameras[cid] = {"optics": optics, "pattern_seed": g.pattern_seed}
        groups.append(
            {
                "name": g.name,
                "n": g.n,
                "first_frame": first,
                "camera": by_key[k],
                "dark": f"dark/{g.name}.png",
                "scene": {k2: list(v) if isinstance(v, tuple) else v for k2, v in g.scene.items()},
                "sensor": sensor,
            }
        )
        first += g.n
    for ci, (cid, cam) in enumerate(cameras.items()):
        cam["calibration_frames"] = [f"calibration/{cid}_{j}.png" for j in range(recipe.lights_on_frames)]
        n_seeds = max(recipe.lights_on_frames, 1 if recipe.profiles else 0)
        cam["calibration_seeds"] = [int(_stream(seed, 2, ci, j).integers(2**31)) for j in range(n_seeds)]
        cam["profile"] = f"profiles/{cid}.json" if recipe.profiles else None
    return cameras, groups


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


def generate(
    recipe: Recipe,
    out: str | Path,
    *,
    seed: int | None = None,
    progress: Callable[[int, str], Any] | None = None,
) -> dict:
    """Render ``recipe`` into the dataset folder ``out`` (resuming a partial one).

    Parameters
    ----------
    recipe : Recipe
    out : folder; empty, missing, or a partial/complete dataset of the same recipe and seed
    seed : overrides the recipe's ``seed``
    progress : called as ``progress(total, label)`` to make a callable that is called once per
        finished item (default: a text bar on stderr when it is a terminal)

    Returns a summary dict (counts of rendered and skipped frames).
    """
    import numpy as np

    from sim_camera.camera import SyntheticCamera
    from sim_camera.optics import MirrorCameraParams
    from sim_camera.scenarios import cell_scene
    from sim_camera.sensor import SensorParams
    from stcvision import __version__
    from stcvision.fileio import write_image

    out = Path(out)
    seed = recipe.seed if seed is None else int(seed)
    if seed < 0:
        raise BadInputError(f"--seed must be >= 0, got {seed}")
    if out.exists() and not out.is_dir():
        raise BadInputError(f"{out} is a file; expected a dataset folder")
    cameras, groups = _plan(recipe, seed)
    manifest = {
        "schema_version": DATASET_SCHEMA_VERSION,
        "kind": "stcvision-dataset",
        "recipe_name": recipe.name,
        "recipe": recipe.raw,
        "seed": seed,
        "generator": f"stcvision {__version__}",
        "complete": False,
        "image_size_px": [cameras["cam0"]["optics"]["width_px"], cameras["cam0"]["optics"]["height_px"]],
        "dark_frames": recipe.dark_frames,
        "cameras": cameras,
        "groups": groups,
        "counts": {
            "frames": recipe.n_frames,
            "groups": len(groups),
            "cameras": len(cameras),
            "darks": len(groups),
            "calibration_frames": recipe.lights_on_frames * len(cameras),
            "profiles": len(cameras) if recipe.profiles else 0,
        },
        "labels": "labels.jsonl",
    }
    sizes = {(c["optics"]["width_px"], c["optics"]["height_px"]) for c in cameras.values()}
    if len(sizes) > 1:
        raise BadInputError(f"recipe {recipe.name}: cameras of different image sizes {sorted(sizes)}; expected one")
    mpath = out / "manifest.json"
    if not _is_empty(out):
        if not mpath.exists():
            raise FileExistsRefusedError(f"{out} is not empty and holds no dataset; choose an empty or new folder")
        old = read_json(mpath, what="dataset manifest")
        if not isinstance(old, dict) or old.get("recipe") != recipe.raw or old.get("seed") != seed:
            name = old.get("recipe_name") if isinstance(old, dict) else None
            oseed = old.get("seed") if isinstance(old, dict) else None
            raise FileExistsRefusedError(
                f"{out} holds a dataset of recipe {name!r} seed {oseed}, not {recipe.name!r} seed {seed}; "
                "choose another folder"
            )
    write_json(mpath, manifest, overwrite=True)

    # labels already made: labels.jsonl of an earlier run, and per-frame parts
    labels: dict[str, str] = {}
    lpath, parts = out / "labels.jsonl", out / ".parts"
    if lpath.exists():
        for line in lpath.read_text(encoding="utf-8").splitlines():
            try:
                labels[json.loads(line)["frame"]] = line
            except (json.JSONDecodeError, KeyError, TypeError):
                continue
    if parts.is_dir():
        for p in sorted(parts.glob("*.json")):
            text = p.read_text(encoding="utf-8").strip()
            try:
                labels[json.loads(text)["frame"]] = text
            except (json.JSONDecodeError, KeyError, TypeError):
                p.unlink()

    cams: dict[str, Any] = {}

    def camera(cid: str):
        if cid not in cams:
            c = cameras[cid]
            cams[cid] = SyntheticCamera(MirrorCameraParams.from_dict(c["optics"]), pattern_seed=c["pattern_seed"])
        return cams[cid]

    todo = [k for k in range(recipe.n_frames) if not ((out / _frame_name(k)).exists() and _frame_name(k) in labels)]
    bar = (progress or (lambda total, label: _Progress(total, label)))(
        len(todo) + len(groups) + len(cameras), f"generate {recipe.name}"
    )
    made = {"calibration_frames": 0, "profiles": 0, "darks": 0, "frames": 0}
    # calibration frames and profiles, per camera
    for cid, c in cameras.items():
        for j, name in enumerate(c["calibration_frames"]):
            if not (out / name).exists():
                from calibration.defaults import calibration_frame

                write_image(out / name, calibration_frame(camera(cid), seed=c["calibration_seeds"][j]), overwrite=True)
                made["calibration_frames"] += 1
        if c["profile"] and not (out / c["profile"]).exists():
            from calibration.defaults import calibrate_simulated

            prof = calibrate_simulated(camera(cid), seed=c["calibration_seeds"][0])
            prov = {**prof.provenance, "camera": f"dataset camera {cid}", "frame": f"{cid}_0 of the dataset"}
            prof.replace(provenance=prov).save(out / c["profile"], overwrite=True)
            made["profiles"] += 1
        bar(1)
    # dark frames, per group
    for gi, g in enumerate(groups):
        if not (out / g["dark"]).exists():
            sensor = SensorParams.from_dict(g["sensor"])
            dark = camera(g["camera"]).median_dark(recipe.dark_frames, rng=_stream(seed, 1, gi), sensor=sensor)
            write_image(out / g["dark"], dark, overwrite=True)
            made["darks"] += 1
        bar(1)
    # frames
    todo_set = set(todo)
    for g in groups:
        sensor = SensorParams.from_dict(g["sensor"])
        scene_kw = {k: tuple(v) if isinstance(v, list) else v for k, v in g["scene"].items()}
        for k in range(g["first_frame"], g["first_frame"] + g["n"]):
            if k not in todo_set:
                continue
            scene_rng, noise_rng = (
                np.random.default_rng(s) for s in np.random.SeedSequence(seed, spawn_key=(0, k)).spawn(2)
            )
            for _ in range(50):  # a dense random board may have no free cell with a free parent
                try:
                    s = cell_scene(scene_rng, **scene_kw)
                    break
                except ValueError:
                    continue
            else:
                raise BadInputError(f"group {g['name']}: no usable board in 50 tries; lower obstacle_fraction")
            f = camera(g["camera"]).render(
                s.pose,
                rng=noise_rng,
                t_s=s.t_s,
                phosphor=s.phosphor,
                red_lights_m=s.red_lights_m,
                board=s.board,
                sensor=sensor,
                truth=True,
            )
            name = _frame_name(k)
            label = {"frame": name, "index": k, "group": g["name"], "camera": g["camera"], "dark": g["dark"]}
            label.update(f.truth)
            label["marks"] = s.marks
            line = dumps(label, indent=None)
            write_image(out / name, f.image, overwrite=True)
            write_bytes_atomic(parts / f"{k:06d}.json", (line + "\n").encode(), overwrite=True)
            labels[name] = line
            made["frames"] += 1
            bar(1)
    close = getattr(bar, "close", None)
    if close:
        close()
    text = "".join(labels[_frame_name(k)] + "\n" for k in range(recipe.n_frames))
    write_bytes_atomic(lpath, text.encode(), overwrite=True)
    shutil.rmtree(parts, ignore_errors=True)
    manifest["complete"] = True
    write_json(mpath, manifest, overwrite=True)
    return {
        "out": str(out),
        "recipe": recipe.name,
        "seed": seed,
        "frames": recipe.n_frames,
        "frames_rendered": made["frames"],
        "frames_skipped": recipe.n_frames - made["frames"],
        "darks_rendered": made["darks"],
        "calibration_frames_rendered": made["calibration_frames"],
        "profiles_made": made["profiles"],
        "cameras": len(cameras),
    }


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
    frames and profiles the manifest names exist. Frames are decoded later (by the evaluation),
    where a corrupt frame is skipped and counted and a wrong size is an error.
    """
    root = Path(root)
    if not root.is_dir():
        raise BadInputError(f"dataset folder {root} does not exist")
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
    for cid, c in m["cameras"].items():
        if c.get("profile") and not (root / c["profile"]).exists():
            raise BadInputError(f"profile {root / c['profile']} of camera {cid} is missing")
    return Dataset(root, m, labels)


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
