"""MkDocs hook: the API reference finds the installed names of the folders beside ``stcvision/``.

The repository keeps ``sim_camera/``, ``controllers/`` and ``calibration/`` at the top and
installs them under ``stcvision`` (pyproject.toml's ``package-dir``). griffe, which reads the
source for mkdocstrings, follows a package's own folder only, so ``stcvision.controllers`` would
not be found (it resolves links to their real folder, so a tree of links would not do either).
Before the build this hook lays out ``build/api-tree/stcvision/`` as the installed package
looks, a copy of the sources (about a megabyte): ``stcvision/`` with each mapped folder under its
installed name; mkdocs.yml's ``paths`` points mkdocstrings there.
"""

from __future__ import annotations

import shutil
import tomllib
from pathlib import Path

from mkdocs.plugins import event_priority


# First of every on_config: mkdocstrings' own on_config sets its handler up and keeps only the
# search paths that exist then, so on a fresh checkout (no build/ yet) the tree must be laid out
# before it, or griffe finds the source folder without the mapped packages.
@event_priority(100)
def on_config(config, **_):
    root = Path(config.config_file_path).resolve().parent
    mapping = tomllib.loads((root / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]["package-dir"]
    tree = root / "build" / "api-tree"
    shutil.rmtree(tree, ignore_errors=True)
    sources = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(root / "stcvision", tree / "stcvision", ignore=sources)
    for name, folder in mapping.items():
        shutil.copytree(root / folder, tree / name.replace(".", "/"), ignore=sources)
    return config
