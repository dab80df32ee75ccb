"""Labelled frame sets: recipes, deterministic resumable generation, reading and validation.

A *recipe* (``datasets/recipes/*.json``, format in ``datasets/README.md``) lists groups of
frames; each group names how many frames, the scene parameters of
:func:`stcvision.sim_camera.scenarios.cell_scene`, and camera and sensor overrides.
:func:`stcvision.datasets.render.generate` renders it into a dataset folder::

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

One package owns datasets: :mod:`~stcvision.datasets.recipe` (parsing and checking recipes),
:mod:`~stcvision.datasets.layout` (the folder's names, the seed streams, the content keys),
:mod:`~stcvision.datasets.render` (generation) and :mod:`~stcvision.datasets.reading` (opening
and checking a dataset folder). Generation needs the simulator (``stcvision.sim_camera``) and the
calibration workflow that fits each camera's profile, and a recipe's scene parameters are those
of the simulator's scene function; reading a dataset needs neither, so the evaluation reads
datasets without loading the simulator (both are imported where they are used).
"""

from stcvision.datasets.layout import DATASET_SCHEMA_VERSION
from stcvision.datasets.reading import Dataset, list_images, open_dataset
from stcvision.datasets.recipe import RECIPE_SCHEMA_VERSION, Group, Recipe, load_recipe, parse_recipe

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
