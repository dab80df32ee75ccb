"""Make and check labelled frame sets (format: datasets/README.md).

  stcvision dataset generate RECIPE.json --out DIR [--seed S] [--workers N | --scheduler tcp://H:P] [--fresh]
  stcvision dataset check DIR
  stcvision dataset export-labels DIR --out FOLDER [--force]

generate renders a recipe (datasets/recipes/*.json) into DIR: frames/*.png, dark/*.png,
labels.jsonl (ground truth per frame), manifest.json, and the calibration lights-on frames and
profiles where the recipe asks. Same recipe and seed give byte-identical files, whatever the
number of workers or the backend (chunks of frames are tasks of the sweep runner; the
docs' Scaling out); re-running skips finished chunks (resume after an interruption), --fresh renders
everything again; a folder holding another recipe or seed is refused. Generated sets belong in
the git-ignored datasets/generated/.

export-labels writes a generated dataset as a person's labelled frames (the hand-label format of
docs/how-to/label-real-frames.md): its frames, dark frames and profiles, and labels.jsonl made
from the ground truth. 'stcvision eval FOLDER' then gives the numbers 'stcvision eval DIR' gives.
"""

from __future__ import annotations

from stcvision.cli._args import seed

NESTED = True  # --json belongs to each step


def add_parser(p):
    import argparse

    p.formatter_class = argparse.RawDescriptionHelpFormatter  # keep the usage lines of the docstring
    sub = p.add_subparsers(dest="step", metavar="STEP", parser_class=type(p))
    g = sub.add_parser(
        "generate",
        help="render a recipe into a dataset folder",
        description="Render a recipe into a dataset folder (deterministic, resumable).",
    )
    g.add_argument("recipe", metavar="RECIPE.json", help="a recipe, e.g. datasets/recipes/smoke.json")
    g.add_argument(
        "--out",
        metavar="DIR",
        help="dataset folder (default: datasets/generated/NAME-seedS under the current folder)",
    )
    g.add_argument("--seed", type=seed, help="seed (default: the recipe's seed)")
    g.add_argument("--json", action="store_true", help="print the result as one JSON object")
    from stcvision.sweep import add_sweep_arguments

    add_sweep_arguments(g)
    c = sub.add_parser(
        "check",
        help="validate a dataset folder",
        description="Check a dataset folder's manifest, labels and files (frames are not decoded).",
    )
    c.add_argument("dir", metavar="DIR")
    c.add_argument("--json", action="store_true", help="print the result as one JSON object")
    e = sub.add_parser(
        "export-labels",
        help="write a dataset as labelled frames (the hand-label format)",
        description="Write a generated dataset's frames with labels.jsonl in the hand-label format.",
    )
    e.add_argument("dir", metavar="DIR", help="a dataset made by 'dataset generate'")
    e.add_argument("--out", metavar="FOLDER", required=True, help="the folder to write (new or empty)")
    e.add_argument("--force", action="store_true", help="write into a folder that holds files")
    e.add_argument("--json", action="store_true", help="print the result as one JSON object")


def run(args):
    from pathlib import Path

    from stcvision.errors import BadInputError

    if args.step is None:
        raise BadInputError("dataset needs a step: generate, check or export-labels (see stcvision dataset --help)")
    if args.step == "export-labels":
        from stcvision.datasets import open_dataset
        from stcvision.datasets.export import export_labels

        ds = open_dataset(args.dir)
        return {"step": "export-labels", **export_labels(ds, args.out, overwrite=args.force)}
    if args.step == "check":
        from stcvision.datasets import open_dataset

        ds = open_dataset(args.dir)
        m = ds.manifest
        if ds.hand_labelled:
            return {"step": "check", "dir": str(ds.root), "ok": True, "labelled": True, "frames": len(ds.labels)}
        return {
            "step": "check",
            "dir": str(ds.root),
            "ok": True,
            "recipe": m.get("recipe_name"),
            "seed": m.get("seed"),
            "counts": m["counts"],
            "groups": {g["name"]: g["n"] for g in m["groups"]},
        }
    from stcvision.datasets import load_recipe
    from stcvision.datasets.render import generate
    from stcvision.sweep import sweep_options_from_args

    recipe = load_recipe(args.recipe)
    seed = recipe.seed if args.seed is None else args.seed
    out = Path(args.out) if args.out else Path("datasets") / "generated" / f"{recipe.name}-seed{seed}"
    r = generate(recipe, out, seed=seed, options=sweep_options_from_args(args))
    r["step"] = "generate"
    return r


def format_text(r):
    if r["step"] == "export-labels":
        return f"{r['out']}: {r['frames']} frames with their labels in the hand-label format ({r['labels']})"
    if r["step"] == "check" and r.get("labelled"):
        return f"{r['dir']}: ok, {r['frames']} frames labelled by hand"
    if r["step"] == "check":
        c = r["counts"]
        return (
            f"{r['dir']}: ok, recipe {r['recipe']} seed {r['seed']}: {c['frames']} frames in "
            f"{c['groups']} groups, {c['cameras']} camera(s), {c['calibration_frames']} calibration frames, "
            f"{c['profiles']} profiles"
        )
    return (
        f"{r['out']}: recipe {r['recipe']} seed {r['seed']}: {r['frames']} frames "
        f"({r['frames_rendered']} rendered, {r['frames_skipped']} already there), "
        f"{r['darks_rendered']} dark frames, {r['calibration_frames_rendered']} calibration frames and "
        f"{r['profiles_made']} profiles made"
    )
