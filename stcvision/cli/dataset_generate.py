"""Render a recipe into a dataset folder (see :mod:`stcvision.datasets` for the format).

Here, under the CLI, because it needs the simulator (``sim_camera``) and the calibration
workflow (``calibration``): DESIGN.md lets only ``stcvision/cli/`` reach across packages.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

from stcvision.datasets import (  # noqa: F401
    DATASET_SCHEMA_VERSION,
    Recipe,
    _frame_name,
    _is_empty,
    _key,
    _Progress,
    _stream,
)
from stcvision.errors import BadInputError, FileExistsRefusedError  # noqa: F401
from stcvision.fileio import dumps, read_json, write_bytes_atomic, write_json  # noqa: F401

__all__ = ["generate"]


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
