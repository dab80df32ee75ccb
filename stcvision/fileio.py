"""Atomic file writing and small readers shared by every package.

A file is written to a temporary sibling, flushed and fsync'ed, then renamed over the target, so
a crash or a kill during a write never leaves a half-written file. Existing files are only
replaced when the caller says so (``overwrite=True``): nothing a user made is lost silently.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from stcvision.errors import BadInputError, FileExistsRefusedError

__all__ = ["figure_png", "read_image", "read_json", "write_bytes_atomic", "write_figure", "write_image", "write_json"]


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
        return json.loads(text, parse_constant=_refuse_constant, parse_float=_finite_float)
    except json.JSONDecodeError as exc:
        raise BadInputError(
            f"{what} {path} is not valid JSON ({exc.msg} at line {exc.lineno}); expected a JSON object"
        ) from None
    except _NotFinite as exc:
        raise BadInputError(f"{what} {path} holds the number {exc}; expected finite numbers only") from None
    except RecursionError:  # found by fuzzing: '[' * 100000
        raise BadInputError(f"{what} {path} is nested too deeply to read; expected a JSON object") from None
    except ValueError:  # found by fuzzing: an integer of more than sys.get_int_max_str_digits() digits
        raise BadInputError(f"{what} {path} holds an integer too long to read; expected ordinary numbers") from None


class _NotFinite(ValueError):
    pass


def _refuse_constant(name: str):
    raise _NotFinite(name)  # NaN, Infinity, -Infinity: not JSON, and never a valid field value


def _finite_float(text: str) -> float:
    v = float(text)
    if not math.isfinite(v):  # 1e999
        raise _NotFinite(text)
    return v


def write_image(path: str | os.PathLike, image: np.ndarray, *, overwrite: bool = False) -> Path:
    """Encode ``image`` (uint8, grey or BGR) by the file's extension and write it atomically."""
    import cv2

    path = Path(path)
    ok, buf = cv2.imencode(path.suffix or ".png", image)
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
    """Read an image file into a uint8 array ((H, W, 3) BGR if ``color`` else (H, W)).

    Raises :class:`BadInputError` for a missing, empty or undecodable file.
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
    flag = cv2.IMREAD_COLOR if color else cv2.IMREAD_GRAYSCALE
    img = cv2.imdecode(np.frombuffer(data, np.uint8), flag)
    if img is None:
        raise BadInputError(f"{what} {path} is not a readable image; expected a PNG or JPEG file")
    return img
