"""A generated dataset written as a person's labelled frames (:mod:`stcvision.labels`): the
frames, dark frames and profiles it names, and a ``labels.jsonl`` of hand labels made from the
simulator's truth (:func:`stcvision.labels.label_from_truth`). ``stcvision eval`` scores the two
folders with the same function, so they give the same numbers: the check that the hand-label
path measures what the truth path does.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from stcvision.datasets.reading import Dataset
from stcvision.errors import BadInputError, OutputError

__all__ = ["export_labels"]


def _place(src: Path, dst: Path) -> None:
    """``dst`` as a copy of ``src``, written whole: a hard link where the file system allows
    (a dataset's frames are many), else a copy; either through a temporary, renamed at the end."""
    from stcvision.fileio import commit_temp, discard_temp, temp_sibling

    dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_sibling(dst)
    try:
        tmp.unlink()
        try:
            os.link(src, tmp)
        except OSError:
            shutil.copyfile(src, tmp)
        commit_temp(tmp, dst)
    except BaseException:
        discard_temp(tmp)
        raise


def export_labels(ds: Dataset, out: str | Path, *, overwrite: bool = False, on_frame=None) -> dict:
    """Write dataset ``ds`` into folder ``out`` in the hand-label format.

    Parameters
    ----------
    ds : Dataset
        A generated dataset (:func:`stcvision.datasets.open_dataset`).
    out : str or Path
        The folder to write: ``labels.jsonl`` and the frames, dark frames and profiles under the
        names the dataset gives them. ``labels.jsonl`` is written last, so a folder that has it
        is complete.
    overwrite : bool
        Replace what ``out`` already holds; without it a folder that is not empty is refused.
    on_frame : callable, optional
        Called with 1 after each frame (progress).

    Returns
    -------
    dict
        ``out``, the number of ``frames`` and the ``labels`` file.

    Raises
    ------
    BadInputError
        ``ds`` is already a labelled folder, or ``out`` is the dataset itself.
    stcvision.errors.OutputError
        ``out`` holds files and ``overwrite`` is not set.
    """
    from stcvision.datasets.layout import is_empty_folder
    from stcvision.fileio import check_output_folder, write_bytes_atomic
    from stcvision.labels import label_from_truth

    if ds.hand_labelled:
        raise BadInputError(f"{ds.root} is already labelled frames; expected a dataset made by 'dataset generate'")
    out = Path(out)
    if out.resolve() == ds.root.resolve():
        raise BadInputError(f"{out} is the dataset itself; expected another folder")
    check_output_folder(out, ["labels.jsonl"], overwrite=overwrite)
    if out.is_dir() and not overwrite and not is_empty_folder(out):
        raise OutputError(f"{out} is not empty; refusing to write into it (use --force)")
    bar = on_frame or (lambda n=1: None)
    placed: set[str] = set()
    lines = []
    for lab in ds.labels:
        hand = label_from_truth(lab)
        hand["frame"] = lab["frame"]
        named = [lab["frame"]]
        if lab.get("dark") is not None:
            hand["dark"] = lab["dark"]
            named.append(lab["dark"])
        prof = ds.profile_path(lab.get("camera", "cam0"))
        if prof is not None:
            hand["profile"] = str(prof.relative_to(ds.root))
            named.append(hand["profile"])
        for name in named:
            if name not in placed:
                _place(ds.root / name, out / name)
                placed.add(name)
        lines.append(json.dumps(hand, separators=(",", ":")))
        bar(1)
    write_bytes_atomic(out / "labels.jsonl", ("\n".join(lines) + "\n").encode(), overwrite=True)
    return {"out": str(out), "frames": len(lines), "labels": str(out / "labels.jsonl")}
