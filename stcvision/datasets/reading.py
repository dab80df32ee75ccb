"""Reading a dataset folder, and the images of a folder of a user's own frames.

A dataset folder's manifest and labels are read and checked: every file they name is there at
the depth its sensor gives (:func:`open_dataset`). A folder of a user's own frames is listed by
:func:`list_images`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from stcvision.datasets.layout import DATASET_SCHEMA_VERSION, IMAGE_SUFFIXES
from stcvision.errors import BadInputError
from stcvision.fileio import read_json
from stcvision.limits import MAX_DATASET_FRAMES

#: a labelled folder's manifest kind (a generated dataset's is "stcvision-dataset")
LABELLED_KIND = "labelled-frames"

__all__ = ["Dataset", "list_images", "open_dataset", "open_labelled_folder"]


@dataclass(frozen=True)
class Dataset:
    """A validated dataset folder: its manifest and its labels (in frame order).

    Made by :func:`open_dataset`; ``datasets/README.md`` describes the folder's files.

    Attributes
    ----------
    root : Path
        The dataset folder.
    manifest : dict
        ``manifest.json``: the image size, the cameras, the dark frames, the frame count.
    labels : list of dict
        The lines of ``labels.jsonl``, one per frame, in frame order.
    """

    root: Path
    manifest: dict
    labels: list[dict]

    @property
    def hand_labelled(self) -> bool:
        """Say whether these are a person's labelled frames.

        True for a folder :func:`open_labelled_folder` read, False for a set the simulator
        rendered with its ground truth.
        """
        return self.manifest["kind"] == LABELLED_KIND

    @property
    def image_size_px(self) -> tuple[int, int]:
        """The frames' (width, height) in pixels."""
        return tuple(self.manifest["image_size_px"])

    def profile_path(self, camera: str) -> Path | None:
        """Return the calibration profile the dataset holds for a camera.

        Parameters
        ----------
        camera : str
            The camera's id, as the manifest names it.

        Returns
        -------
        Path or None
            The profile's file, or None when the dataset holds none for this camera.
        """
        p = self.manifest["cameras"].get(camera, {}).get("profile")
        return self.root / p if p else None


def open_dataset(root: str | Path, *, dark: str | Path | None = None) -> Dataset:
    """Read and check a dataset folder; every problem is a one-line :class:`BadInputError`.

    A folder with ``labels.jsonl`` and no ``manifest.json`` is a person's labelled frames
    (:func:`open_labelled_folder`, which ``dark`` is for).

    Checked: the manifest exists (when labels do) and is a complete dataset of a known schema;
    every line of ``labels.jsonl`` is a JSON object naming a frame; the manifest's frame count
    matches; every labelled frame exists; every frame in ``frames/`` has a label; the dark
    frames and profiles the manifest names exist; every PNG frame and dark frame is 3-channel at
    its sensor's depth (8-bit, or 16-bit for a deeper ADC: from the PNG header). Frames are
    decoded later (by the evaluation), where a corrupt frame is skipped and counted and a wrong
    size is an error.

    Parameters
    ----------
    root : str or Path
        The dataset folder (made by ``stcvision dataset generate``), or a folder of a person's
        labelled frames (``labels.jsonl`` without ``manifest.json``).
    dark : str or Path, optional
        A labelled folder's dark frame for the frames whose label names none.

    Returns
    -------
    Dataset
        The folder's manifest and labels.

    Raises
    ------
    BadInputError
        For every problem the checks find, in one line.
    """
    root = Path(root)
    if not root.is_dir():
        what = "is a file, not a folder" if root.exists() else "does not exist"
        raise BadInputError(f"dataset folder {root} {what}; expected a folder made by 'dataset generate'")
    mpath, lpath = root / "manifest.json", root / "labels.jsonl"
    if not mpath.exists() and not lpath.exists():
        raise BadInputError(f"{root} is not a dataset (no manifest.json); expected a folder made by 'dataset generate'")
    if not mpath.exists():
        return open_labelled_folder(root, dark=dark)
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
    from stcvision.fileio import json_lines

    labels = []
    for i, lab in json_lines(lpath, cap=MAX_DATASET_FRAMES, what="label"):
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


def _inside(root: Path, name: str, what: str, where: str) -> Path:
    """``root / name`` for a name relative to the folder; one that leaves it is refused."""
    p = Path(name)
    if p.is_absolute() or ".." in p.parts:
        raise BadInputError(f"{where}: {what} {name!r} is not a path inside {root}; expected one relative to it")
    return root / p


def open_labelled_folder(root: str | Path, *, dark: str | Path | None = None) -> Dataset:
    """Open a folder of a robot's own frames with a person's ``labels.jsonl``.

    The labels are in the hand-label format of :mod:`stcvision.labels`.

    Parameters
    ----------
    root : str or Path
        The folder; each label's ``frame``, ``dark`` and ``profile`` are relative to it.
    dark : str or Path, optional
        The dark frame of the frames whose label names none (``eval --dark``).

    Returns
    -------
    Dataset
        Its labels as the evaluation reads them: ``camera`` is the label's profile (or
        ``default``), ``dark`` its dark frame (the label's, else ``dark``, else None); the
        manifest gives the first frame's size, which every frame must have.

    Raises
    ------
    BadInputError
        A label that is not one, a frame, dark frame or profile that is missing, an image that
        cannot be read.
    """
    from stcvision.fileio import read_image
    from stcvision.labels import read_labels

    root = Path(root)
    lpath = root / "labels.jsonl"
    labels = read_labels(lpath)
    cameras: dict[str, dict] = {}
    for i, lab in enumerate(labels, 1):
        where = f"{lpath} label {i} ({lab['frame']})"
        if not _inside(root, lab["frame"], "frame", where).is_file():
            raise BadInputError(f"{where}: the frame {root / lab['frame']} is missing")
        if lab.get("dark") is not None:
            if not _inside(root, lab["dark"], "dark", where).is_file():
                raise BadInputError(f"{where}: its dark frame {root / lab['dark']} is missing")
        elif dark is not None:
            lab["dark"] = str(Path(dark).resolve())
        if lab.get("profile") is not None:
            if not _inside(root, lab["profile"], "profile", where).is_file():
                raise BadInputError(f"{where}: its profile {root / lab['profile']} is missing")
            cameras[lab["profile"]] = {"profile": lab["profile"]}
        lab["camera"] = lab.get("profile", "default")
        lab["group"] = ""
    first = read_image(root / labels[0]["frame"], what="frame")
    manifest = {
        "kind": LABELLED_KIND,
        "cameras": cameras,
        "image_size_px": [int(first.shape[1]), int(first.shape[0])],
        "counts": {"frames": len(labels)},
        "recipe_name": None,
        "seed": None,
    }
    return Dataset(root, manifest, labels)


def _png_header(path: Path) -> tuple[int, int] | None:
    """Read a PNG's bit depth per channel and colour type from its header.

    (bit depth per channel, PNG colour type) from a PNG's IHDR chunk (its first 26 bytes), or
    None if ``path`` is not a PNG file. Colour type 2 is RGB (a BGR frame), 0 grey.
    """
    with open(path, "rb") as f:
        head = f.read(26)
    if len(head) < 26 or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    return head[24], head[25]


def _check_depths(root: Path, labels: list[dict]) -> None:
    """Check that every labelled PNG frame and its dark frame hold 3 channels at their sensor's depth.

    Every labelled PNG frame and its dark frame hold 3 channels at the depth the label's sensor
    digitises (8 bits for an 8-bit ADC, 16 for 9-16 bits: the ADC counts), read from the PNG
    headers (the frames are not decoded).
    """
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
    """List the image files of a folder of the user's own frames.

    Sorted by name; those of ``frames/`` if the folder itself holds none.
    """
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
