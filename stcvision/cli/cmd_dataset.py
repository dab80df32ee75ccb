"""Make and check labelled frame sets (format: datasets/README.md).

  stcvision dataset generate RECIPE.json --out DIR [--seed S] [--workers N | --scheduler tcp://H:P] [--fresh]
  stcvision dataset check DIR

generate renders a recipe (datasets/recipes/*.json) into DIR: frames/*.png, dark/*.png,
labels.jsonl (ground truth per frame), manifest.json, and the calibration lights-on frames and
profiles where the recipe asks. Same recipe and seed give byte-identical files, whatever the
number of workers or the backend (chunks of frames are tasks of the sweep runner; the
docs' Scaling out); re-running skips finished chunks (resume after an interruption), --fresh renders
everything again; a folder holding another recipe or seed is refused. Generated sets belong in
the git-ignored datasets/generated/.
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


def run(args):
    from pathlib import Path

    from stcvision.errors import BadInputError

    if args.step is None:
        raise BadInputError("dataset needs a step: generate or check (see stcvision dataset --help)")
    if args.step == "check":
        from stcvision.datasets import open_dataset

        ds = open_dataset(args.dir)
        m = ds.manifest
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
