"""Atomic file writing and small readers shared by every package.

A file is written to a temporary sibling, flushed and fsync'ed, then renamed over the target, so
a crash or a kill during a write never leaves a half-written file. Existing files are only
replaced when the caller says so (``overwrite=True``): nothing a user made is lost silently.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from stcvision.errors import BadInputError, FileExistsRefusedError

__all__ = [
    "check_same_depth",
    "figure_png",
    "read_image",
    "read_json",
    "write_bytes_atomic",
    "write_figure",
    "write_image",
    "write_json",
]


def write_bytes_atomic(path: str | os.PathLike, data: bytes, *, overwrite: bool = False) -> Path:
    """Write ``data`` to ``path`` atomically (temp file + fsync + rename).

    Raises
    ------
    FileExistsRefusedError
        If ``path`` exists and ``overwrite`` is false.
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise FileExistsRefusedError(f"{path} exists; refusing to overwrite it (use --force)")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def dumps(obj: Any, *, indent: int | None = 2) -> str:
    """``json.dumps`` that understands numpy scalars/arrays and paths."""
    return json.dumps(obj, indent=indent, default=_json_default, allow_nan=False)


def write_json(path: str | os.PathLike, obj: Any, *, overwrite: bool = False) -> Path:
    """Write ``obj`` as pretty JSON, atomically."""
    return write_bytes_atomic(path, (dumps(obj) + "\n").encode(), overwrite=overwrite)


def read_json(path: str | os.PathLike, *, what: str = "JSON file") -> Any:
    """Read a JSON file, turning every failure into a one-line :class:`BadInputError`."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise BadInputError(f"{what} {path} does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise BadInputError(f"cannot read {what} {path}: {exc}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise BadInputError(
            f"{what} {path} is not valid JSON ({exc.msg} at line {exc.lineno}); expected a JSON object"
        ) from None


#: what 16-bit frames may be written as (OpenCV writes 16 bits per channel to these); JPEG holds 8
_DEEP_SUFFIXES = (".png", ".tif", ".tiff")


def write_image(path: str | os.PathLike, image: np.ndarray, *, overwrite: bool = False) -> Path:
    """Encode ``image`` (grey or BGR; uint8, or uint16 as 16-bit PNG/TIFF, the ADC counts kept
    as they are) by the file's extension and write it atomically. A uint16 image is refused for
    JPEG (8 bits only): it is never scaled down silently."""
    import cv2

    path = Path(path)
    suffix = path.suffix.lower() or ".png"
    if image.dtype == np.uint16 and suffix not in _DEEP_SUFFIXES:
        raise BadInputError(f"cannot write a 16-bit image as {path.suffix or 'no suffix'!r} ({path}); expected .png")
    if image.dtype not in (np.uint8, np.uint16):
        raise BadInputError(f"cannot write a {image.dtype} image to {path}; expected uint8 or uint16")
    ok, buf = cv2.imencode(suffix, image)
    if not ok:
        raise BadInputError(f"cannot encode an image as {path.suffix!r}; expected .png or .jpg")
    return write_bytes_atomic(path, buf.tobytes(), overwrite=overwrite)


def figure_png(fig, *, dpi: int = 110, **savefig_kw) -> bytes:
    """A matplotlib figure as PNG bytes; the figure is closed (plots are made once, then saved)."""
    import io

    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, **savefig_kw)
    plt.close(fig)
    return buf.getvalue()


def write_figure(path: str | os.PathLike, fig, *, overwrite: bool = False, dpi: int = 110, **savefig_kw) -> Path:
    """Save a matplotlib figure as PNG, atomically (see :func:`figure_png`)."""
    return write_bytes_atomic(path, figure_png(fig, dpi=dpi, **savefig_kw), overwrite=overwrite)


def read_image(path: str | os.PathLike, *, color: bool = True, what: str = "image") -> np.ndarray:
    """Read an image file: with ``color`` a frame, (H, W, 3) BGR as stored -- uint8, or uint16
    for a 16-bit PNG (the sensor's ADC counts, never divided by 256); else (H, W) uint8 grey
    (a map).

    Raises :class:`BadInputError` for a missing, empty or undecodable file, and with ``color``
    for an image that is not 3-channel BGR (greyscale, alpha) or not 8/16-bit.
    """
    import cv2

    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise BadInputError(f"{what} {path} does not exist") from None
    except OSError as exc:
        raise BadInputError(f"cannot read {what} {path}: {exc.strerror}") from None
    if not data:
        raise BadInputError(f"{what} {path} is empty; expected a PNG or JPEG image")
    flag = cv2.IMREAD_UNCHANGED if color else cv2.IMREAD_GRAYSCALE
    img = cv2.imdecode(np.frombuffer(data, np.uint8), flag)
    if img is None:
        raise BadInputError(f"{what} {path} is not a readable image; expected a PNG or JPEG file")
    if color:
        channels = 1 if img.ndim == 2 else img.shape[2]
        if channels != 3:
            kind = "greyscale" if channels == 1 else f"{channels}-channel"
            raise BadInputError(f"{what} {path} is {kind}; expected a 3-channel BGR frame")
        if img.dtype not in (np.uint8, np.uint16):
            raise BadInputError(f"{what} {path} holds {img.dtype} pixels; expected an 8- or 16-bit frame")
    return img


def check_same_depth(frame: np.ndarray, dark: np.ndarray, dark_path, *, frame_path=None) -> None:
    """A dark frame must have the frames' depth (uint8 with uint8, uint16 ADC counts with
    uint16): a one-line :class:`BadInputError` naming the dark frame otherwise."""
    if frame.dtype != dark.dtype:
        of = f" ({frame_path})" if frame_path is not None else ""
        raise BadInputError(
            f"dark frame {dark_path} is {_depth(dark)} but the frame{of} is {_depth(frame)}; "
            "expected a dark frame of the frames' depth, taken with the same camera"
        )


def _depth(img: np.ndarray) -> str:
    return f"{8 * img.dtype.itemsize}-bit"
