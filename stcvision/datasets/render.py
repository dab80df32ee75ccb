"""Render a recipe into a dataset folder (see :mod:`stcvision.datasets` for the format).

The work is a sweep (:mod:`stcvision.sweep`) of coarse tasks, each writing its files into the
folder: one per camera (calibration frames and profile), one per group (its dark frame) and one
per chunk of up to :data:`FRAMES_PER_TASK` frames of a group (frames and labels). Each task's
result (the labels of its frames) goes to the folder's ``.sweep.jsonl`` as it finishes, so an
interrupted run resumes where it stopped; the store is removed when the dataset is complete.
With ``--scheduler`` the folder must be on a filesystem every worker sees.

A dataset joins the simulator's frames to the profiles the calibration workflow fits on the
simulated cameras, so this module imports both (where it uses them); it is the one part of
``stcvision.datasets`` that does, and reading or scoring a dataset never imports it.
"""

from __future__ import annotations

import functools
import json
import shutil
from pathlib import Path

from stcvision.datasets.layout import DATASET_SCHEMA_VERSION, content_key, frame_name, is_empty_folder, seed_stream
from stcvision.datasets.recipe import Recipe, parse_recipe
from stcvision.errors import BadInputError, FileExistsRefusedError
from stcvision.fileio import dumps, read_json, write_bytes_atomic, write_json

__all__ = ["FRAMES_PER_TASK", "calibrate_camera", "generate", "render_dark", "render_frames"]

#: frames per task: ~1-2 s of rendering, far above the sweep's per-task cost (ms)
FRAMES_PER_TASK = 25
STORE = ".sweep.jsonl"


def _plan(recipe: Recipe, seed: int) -> tuple[dict, list[dict]]:
    """Cameras (by identical optics, pattern seed and sensor profile, in order of first use) and
    groups. The sensor profile is part of a camera: its lights-on calibration frames are rendered
    by that sensor, at its depth (a 12- or 16-bit camera is calibrated on its own frames)."""
    from stcvision.sim_camera.hardware import CAMERAS
    from stcvision.sim_camera.image_sensor import SensorParams
    from stcvision.sim_camera.optics import MirrorCameraParams

    cameras: dict[str, dict] = {}
    by_key: dict[str, str] = {}
    groups = []
    first = 0
    for g in recipe.groups:
        try:
            if g.sensor_profile is not None and g.sensor_profile not in CAMERAS:
                raise BadInputError(
                    f"unknown sensor_profile {g.sensor_profile!r}; expected one of {', '.join(CAMERAS)}"
                )
            base = CAMERAS[g.sensor_profile].sensor.to_dict() if g.sensor_profile else {}
            optics = MirrorCameraParams.from_dict(g.camera).to_dict()
            sensor = SensorParams.from_dict({**base, **g.sensor}).to_dict()
        except BadInputError as exc:
            raise BadInputError(f"recipe {recipe.name}, group {g.name}: {exc}") from None
        k = content_key([optics, g.pattern_seed] + ([g.sensor_profile] if g.sensor_profile else []))
        if k not in by_key:
            cid = f"cam{len(cameras)}"
            by_key[k] = cid
            cameras[cid] = {"optics": optics, "pattern_seed": g.pattern_seed}
            if g.sensor_profile:
                cameras[cid]["sensor_profile"] = g.sensor_profile
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
        cam["calibration_seeds"] = [int(seed_stream(seed, 2, ci, j).integers(2**31)) for j in range(n_seeds)]
        cam["profile"] = f"profiles/{cid}.json" if recipe.profiles else None
    return cameras, groups


def _manifest(recipe: Recipe, seed: int, cameras: dict, groups: list) -> dict:
    from stcvision import __version__

    return {
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


# ------------------------------------------------------------------------------ tasks (on workers)
@functools.lru_cache(maxsize=4)
def _camera(optics_json: str, pattern_seed: int):
    """A camera per optics + pattern (building one takes ~1 s: kept for the worker's next task)."""
    from stcvision.sim_camera.camera import SyntheticCamera
    from stcvision.sim_camera.optics import MirrorCameraParams

    return SyntheticCamera(MirrorCameraParams.from_dict(json.loads(optics_json)), pattern_seed=pattern_seed)


def _task_plan(params: dict) -> tuple[Recipe, int, dict, list, Path]:
    recipe = parse_recipe(params["recipe"])
    cameras, groups = _plan(recipe, params["seed"])
    return recipe, params["seed"], cameras, groups, Path(params["out"])


def _cam(cameras: dict, cid: str):
    c = cameras[cid]
    return _camera(json.dumps(c["optics"], sort_keys=True), c["pattern_seed"])


def calibrate_camera(params: dict, seed) -> dict:
    """Task: camera ``params["camera"]``'s lights-on calibration frames and, if the recipe asks,
    its profile from the calibration workflow. The dataset's seed streams are used (not the
    sweep's), so the files do not depend on how the work was split."""
    from stcvision.calibration.defaults import calibrate_simulated, calibration_frame
    from stcvision.fileio import write_image

    recipe, _, cameras, _, out = _task_plan(params)
    cid = params["camera"]
    c, cam = cameras[cid], _cam(cameras, cid)
    if c.get("sensor_profile"):  # lights-on frames by the camera's own sensor, at its depth
        from stcvision.sim_camera.camera import SyntheticCamera
        from stcvision.sim_camera.hardware import CAMERAS

        cam = SyntheticCamera(cam.optics, CAMERAS[c["sensor_profile"]].sensor, pattern_seed=c["pattern_seed"])
    for j, name in enumerate(c["calibration_frames"]):
        write_image(out / name, calibration_frame(cam, seed=c["calibration_seeds"][j]), overwrite=True)
    if c["profile"]:
        prof = calibrate_simulated(cam, seed=c["calibration_seeds"][0])
        prov = {**prof.provenance, "camera": f"dataset camera {cid}", "frame": f"{cid}_0 of the dataset"}
        prof.replace(provenance=prov).save(out / c["profile"], overwrite=True)
    return {"calibration_frames": len(c["calibration_frames"]), "profiles": int(bool(c["profile"]))}


def render_dark(params: dict, seed) -> dict:
    """Task: the median dark frame of group ``params["group"]`` (stream ``(1, group)``)."""
    from stcvision.fileio import write_image
    from stcvision.sim_camera.image_sensor import SensorParams

    recipe, dseed, cameras, groups, out = _task_plan(params)
    gi = params["group"]
    g = groups[gi]
    sensor = SensorParams.from_dict(g["sensor"])
    dark = _cam(cameras, g["camera"]).median_dark(recipe.dark_frames, rng=seed_stream(dseed, 1, gi), sensor=sensor)
    write_image(out / g["dark"], dark, overwrite=True)
    return {"darks": 1}


def render_frames(params: dict, seed) -> dict:
    """Task: frames ``params["first"]`` to ``params["stop"] - 1`` of group ``params["group"]``;
    frame ``k`` draws its scene and noise from ``SeedSequence(dataset seed, spawn_key=(0, k))``
    alone. Returns their label lines."""
    import numpy as np

    from stcvision.fileio import write_image
    from stcvision.sim_camera.image_sensor import SensorParams
    from stcvision.sim_camera.scenarios import cell_scene

    _, dseed, cameras, groups, out = _task_plan(params)
    g = groups[params["group"]]
    sensor = SensorParams.from_dict(g["sensor"])
    scene_kw = {k: tuple(v) if isinstance(v, list) else v for k, v in g["scene"].items()}
    cam = _cam(cameras, g["camera"])
    labels = {}
    for k in range(params["first"], params["stop"]):
        scene_rng, noise_rng = (
            np.random.default_rng(s) for s in np.random.SeedSequence(dseed, spawn_key=(0, k)).spawn(2)
        )
        for _ in range(50):  # a dense random board may have no free cell with a free parent
            try:
                s = cell_scene(scene_rng, **scene_kw)
                break
            except ValueError:
                continue
        else:
            raise BadInputError(f"group {g['name']}: no usable board in 50 tries; lower obstacle_fraction")
        f = cam.render(
            s.pose,
            rng=noise_rng,
            t_s=s.t_s,
            phosphor=s.phosphor,
            red_lights_m=s.red_lights_m,
            board=s.board,
            sensor=sensor,
            truth=True,
        )
        name = frame_name(k)
        label = {"frame": name, "index": k, "group": g["name"], "camera": g["camera"], "dark": g["dark"]}
        label.update(f.truth)
        label["marks"] = s.marks
        write_image(out / name, f.image, overwrite=True)
        labels[name] = dumps(label, indent=None)
    return {"labels": labels}


# ------------------------------------------------------------------------------ the driver
def _check_folder(out: Path, recipe: Recipe, seed: int) -> None:
    if out.exists() and not out.is_dir():
        raise BadInputError(f"{out} is a file; expected a dataset folder")
    mpath = out / "manifest.json"
    if out.is_dir():  # a killed run's leftovers do not make the folder someone else's
        from stcvision.fileio import remove_stale_temps

        remove_stale_temps(out)
    if is_empty_folder(out):
        return
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


def _old_labels(lpath: Path) -> dict[str, str]:
    """Labels of an earlier complete run (a frame deleted since is rendered again)."""
    labels: dict[str, str] = {}
    if lpath.exists():
        for line in lpath.read_text(encoding="utf-8").splitlines():
            try:
                labels[json.loads(line)["frame"]] = line
            except (json.JSONDecodeError, KeyError, TypeError):
                continue
    return labels


def generate(recipe: Recipe, out: str | Path, *, seed: int | None = None, options=None) -> dict:
    """Render ``recipe`` into the dataset folder ``out`` (resuming a partial one).

    Parameters
    ----------
    recipe : Recipe
    out : folder; empty, missing, or a partial/complete dataset of the same recipe and seed
    seed : overrides the recipe's ``seed``
    options : :class:`stcvision.sweep.SweepOptions` (workers, Dask scheduler, fresh); default:
        a local pool sized to the machine. ``fresh`` renders everything again.

    Files already there (an earlier, complete or interrupted run) are kept: a calibration
    camera, dark frame or chunk of frames is rendered only if a file or label of it is missing.
    Returns a summary dict (counts of rendered and skipped frames). A failed task is a one-line
    error naming it; the next run retries it.
    """
    from stcvision.sweep import SweepOptions, Task, run_sweep

    options = options or SweepOptions()
    out = Path(out)
    seed = recipe.seed if seed is None else int(seed)
    if seed < 0:
        raise BadInputError(f"--seed must be >= 0, got {seed}")
    cameras, groups = _plan(recipe, seed)
    sizes = {(c["optics"]["width_px"], c["optics"]["height_px"]) for c in cameras.values()}
    if len(sizes) > 1:
        raise BadInputError(f"recipe {recipe.name}: cameras of different image sizes {sorted(sizes)}; expected one")
    _check_folder(out, recipe, seed)
    manifest = _manifest(recipe, seed, cameras, groups)
    mpath, lpath = out / "manifest.json", out / "labels.jsonl"
    write_json(mpath, manifest, overwrite=True)

    labels = {} if options.fresh else _old_labels(lpath)

    def have(name: str) -> bool:
        return not options.fresh and (out / name).exists()

    base = {"out": str(out.resolve()), "recipe": recipe.raw, "seed": seed}
    tasks = []
    for cid, c in cameras.items():
        if not all(have(n) for n in c["calibration_frames"]) or (c["profile"] and not have(c["profile"])):
            tasks.append(Task(experiment=f"{__name__}:calibrate_camera", params={**base, "camera": cid}, seed=seed))
    for gi, g in enumerate(groups):
        if not have(g["dark"]):
            tasks.append(Task(experiment=f"{__name__}:render_dark", params={**base, "group": gi}, seed=seed))
    for gi, g in enumerate(groups):
        stop = g["first_frame"] + g["n"]
        for first in range(g["first_frame"], stop, FRAMES_PER_TASK):
            ks = range(first, min(first + FRAMES_PER_TASK, stop))
            if all(have(frame_name(k)) and frame_name(k) in labels for k in ks):
                continue
            params = {**base, "group": gi, "first": ks.start, "stop": ks.stop}
            tasks.append(Task(experiment=f"{__name__}:render_frames", params=params, seed=seed))
    report = run_sweep(tasks, out / STORE, options, desc=f"generate {recipe.name}")

    def name(key: str) -> str:
        task = next(t for t in tasks if t.key == key)
        return f"{task.experiment.split(':')[1]} { {k: v for k, v in task.params.items() if k not in base} }"

    report.raise_if_failed("tasks", name)
    made = {"calibration_frames": 0, "profiles": 0, "darks": 0, "frames": 0}
    for t in tasks:
        r = report.results[t.key]
        labels.update(r.get("labels", {}))
        if t.key in report.skipped_keys:  # done by an interrupted earlier run
            continue
        made["frames"] += len(r.get("labels", {}))
        for k in ("calibration_frames", "profiles", "darks"):
            made[k] += r.get(k, 0)
    expected = [frame_name(k) for k in range(recipe.n_frames)] + [g["dark"] for g in groups]
    for c in cameras.values():
        expected += c["calibration_frames"] + ([c["profile"]] if c["profile"] else [])
    missing = [name for name in expected if not (out / name).exists()]
    if missing:  # deleted after its task was recorded as done
        raise BadInputError(f"{out / missing[0]} is missing though its task is done; re-run with --fresh")
    text = "".join(labels[frame_name(k)] + "\n" for k in range(recipe.n_frames))
    write_bytes_atomic(lpath, text.encode(), overwrite=True)
    manifest["complete"] = True
    write_json(mpath, manifest, overwrite=True)
    (out / STORE).unlink(missing_ok=True)
    shutil.rmtree(out / ".parts", ignore_errors=True)  # per-frame labels of versions before the sweep
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
        "tasks": report.total,
        "sweep": report.summary(),
    }
