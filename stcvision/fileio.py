"""Atomic file writing and small readers shared by every package.

A file is written to a temporary sibling, flushed and fsync'ed, then renamed over the target, so
a crash or a kill during a write never leaves a half-written file. Existing files are only
replaced when the caller says so (``overwrite=True``): nothing a user made is lost silently.
"""

from __future__ import annotations

import errno
import json
import math
import os
import secrets
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from stcvision.errors import BadInputError, FileExistsRefusedError, OutputError

if TYPE_CHECKING:  # numpy is imported where it is used: the command line's start needs none of it
    import numpy as np

__all__ = [
    "check_output_file",
    "check_same_depth",
    "commit_temp",
    "discard_temp",
    "figure_png",
    "keep_partial",
    "kept_partial",
    "read_image",
    "read_json",
    "remove_live_temps",
    "new_run",
    "remove_stale_temps",
    "temp_sibling",
    "write_bytes_atomic",
    "write_figure",
    "write_image",
    "write_json",
    "write_set",
]


#: what a temporary sibling of TARGET is called: ``.TARGET.PID.RANDOM.tmp`` (hidden, and the
#: writer's process id in it, so a later write can tell a dead writer's leftover from a live one)
_TEMP_SUFFIX = ".tmp"

#: temporary files and folders of this process that are not yet renamed into place; removed by
#: :func:`remove_live_temps` (the CLI calls it on every exit, a signal included)
_LIVE_TEMPS: set[Path] = set()


def _umask() -> int:
    """Return the process's umask, without changing it (Linux: /proc; elsewhere set-and-restore)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def output_error(path: str | os.PathLike, exc: OSError) -> OutputError:
    """Return a one-line :class:`OutputError` for an ``OSError`` met while making ``path``."""
    where = (
        exc.filename if exc.filename not in (None, str(path)) and not str(exc.filename).endswith(_TEMP_SUFFIX) else None
    )
    why = exc.strerror or str(exc)
    return OutputError(f"cannot write {path}: {why}" + (f" ({where})" if where else ""))


def check_output_file(path: str | os.PathLike, *, overwrite: bool = False, what: str = "") -> Path:
    """Check, before any work, that ``path`` can be made as a file.

    Not a directory, its parent a folder (or creatable), and not an existing file unless
    ``overwrite``. Returns the path.
    """
    path = Path(path)
    label = f"{what} {path}".strip()
    if path.is_dir():
        raise OutputError(f"{label} is a directory; expected a file name")
    if path.exists() and not overwrite:
        raise FileExistsRefusedError(f"{label} exists; refusing to overwrite it (use --force)")
    for parent in (path.parent, *path.parent.parents):
        if parent.exists():
            if not parent.is_dir():
                raise OutputError(f"cannot write {path}: {parent} is not a folder")
            if not os.access(parent, os.W_OK | os.X_OK) and parent == path.parent:
                raise OutputError(f"cannot write {path}: no permission to write in {parent}")
            break
    return path


def temp_sibling(path: Path, *, directory: bool = False) -> Path:
    """Make a new hidden temporary sibling of ``path``, registered for removal on exit.

    Its name is ``.NAME.PID.RANDOM.tmp``, a file or a folder; the first in a folder in this run
    removes the stale ones.

    The name is registered before the file or folder exists (made with O_EXCL, as mkstemp
    does): a termination signal that lands between making it and registering it would leave an
    unregistered temporary behind, and a run stopped as soon as its recording's file appears
    lands there (seen under load: an ``stcvision cover --rrd`` stopped by SIGTERM kept its
    ``.run.rrd....tmp``).
    """
    _sweep_once(path.parent)
    prefix = f".{path.name}.{os.getpid()}."
    for _ in range(tempfile.TMP_MAX):
        tmp = path.parent / f"{prefix}{secrets.token_hex(4)}{_TEMP_SUFFIX}"
        _LIVE_TEMPS.add(tmp)
        try:
            if directory:
                os.mkdir(tmp, 0o700)
            else:
                fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
                try:
                    os.fchmod(fd, _new_file_mode(path))  # the mode open() would give, not 0600
                finally:
                    os.close(fd)
        except FileExistsError:
            _LIVE_TEMPS.discard(tmp)
            continue
        except OSError:
            _LIVE_TEMPS.discard(tmp)
            raise
        return tmp
    raise FileExistsError(errno.EEXIST, "no free temporary name", str(path.parent))


#: folders already swept for stale temporaries in this run (one directory scan per folder, not
#: per file: a dataset's frames/ may hold 100,000 files); :func:`new_run` forgets them
_SWEPT: set[Path] = set()


def _sweep_once(folder: Path) -> None:
    key = folder.absolute()
    if key not in _SWEPT:
        _SWEPT.add(key)
        remove_stale_temps(folder)


#: termination signals received during this run (the CLI's handler notes them before it raises
#: :class:`~stcvision.errors.Terminated`): if a library swallows that exception (numba's compiler,
#: a logging wrapper), no output is committed after it all the same
_SIGNALS: list[int] = []

#: outputs this run kept as they stood when a signal stopped it (a recording whose every
#: record up to the signal is whole), for the line the CLI ends an interrupted run with
_KEPT: list[Path] = []


#: when this run's Ctrl-Cs came (time.monotonic), for :func:`interrupted_since`
_INTERRUPTS: list[float] = []


def new_run() -> None:
    """Start a new run (the CLI calls it first): folders are swept for stale temporaries again."""
    _SWEPT.clear()
    _SIGNALS.clear()
    _INTERRUPTS.clear()
    _KEPT.clear()


def interrupt_received() -> None:
    """Note a Ctrl-C (its time) for :func:`interrupted_since`.

    A Ctrl-C stays a ``KeyboardInterrupt`` that code may catch on purpose (a live run ends on
    it), so it is not one of :func:`raise_if_signalled`'s signals.
    """
    _INTERRUPTS.append(time.monotonic())


def interrupted_since(t: float) -> bool:
    """Whether a Ctrl-C came after ``t`` (``time.monotonic``) in this run."""
    return bool(_INTERRUPTS) and _INTERRUPTS[-1] >= t


def signal_received(signum: int) -> None:
    """Note a termination signal (SIGTERM, SIGHUP) for :func:`raise_if_signalled`."""
    _SIGNALS.append(signum)


def forget_signals() -> None:
    """End the run (the CLI calls it last): a later write in this process is not refused."""
    _SIGNALS.clear()
    _INTERRUPTS.clear()


def raise_if_signalled() -> None:
    """Raise :class:`~stcvision.errors.Terminated` if a termination signal arrived in this run."""
    if _SIGNALS:
        from stcvision.errors import Terminated

        raise Terminated(_SIGNALS[0])


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _writer_pid(name: str) -> int | None:
    """Return the PID in a temporary's name ``.NAME.PID.RANDOM.tmp`` (None if it is not one of ours)."""
    if not (name.startswith(".") and name.endswith(_TEMP_SUFFIX)):
        return None
    parts = name[1 : -len(_TEMP_SUFFIX)].rsplit(".", 2)  # RANDOM has no dots; NAME may
    return int(parts[1]) if len(parts) == 3 and parts[0] and parts[1].isdigit() else None


def remove_stale_temps(folder: str | os.PathLike) -> list[Path]:
    """Remove the temporaries in ``folder`` left by writers that were killed.

    Killed by SIGKILL or a power loss: ``.NAME.PID.RANDOM.tmp`` whose process is gone. Returns
    what was removed.
    """
    import shutil

    removed = []
    try:
        entries = [e for e in os.scandir(folder) if e.name.endswith(_TEMP_SUFFIX) and e.name.startswith(".")]
    except OSError:
        return removed
    for e in entries:
        pid = _writer_pid(e.name)
        if pid is None or pid == os.getpid() or _alive(pid):
            continue
        try:
            shutil.rmtree(e.path) if e.is_dir(follow_symlinks=False) else os.unlink(e.path)
            removed.append(Path(e.path))
        except OSError:
            pass
    return removed


def remove_live_temps() -> None:
    """Remove this process's temporaries not yet renamed into place.

    Its temporary files and folders go on exit, on an error, on SIGTERM/SIGINT: a run that stops
    leaves no hidden leftovers.
    """
    for tmp in list(_LIVE_TEMPS):
        discard_temp(tmp)


def remove_own_temps(folder: Path) -> None:
    """Remove this process's temporaries in ``folder`` by their name, registered or not.

    The name is ``.NAME.PID.RANDOM.tmp``. A signal that lands between a temporary's creation and its registration
    (:func:`temp_sibling`) leaves it unregistered, and a folder the run made would then stay.
    """
    for tmp in folder.glob(f".*.{os.getpid()}.*{_TEMP_SUFFIX}"):
        discard_temp(tmp)


def commit_temp(tmp: Path, path: Path) -> None:
    """Rename the temporary ``tmp`` over ``path`` and forget it.

    Atomic on one file system; never after a termination signal (:func:`raise_if_signalled`:
    the temporary is then removed).
    """
    raise_if_signalled()
    os.replace(tmp, path)
    _LIVE_TEMPS.discard(tmp)


def keep_partial(tmp: Path, path: Path) -> None:
    """Rename the temporary ``tmp`` over ``path`` after a termination signal, and note it.

    For a stream whose every record up to the signal is whole and whose end has been written
    (a rerun recording closed cleanly): the run stopped, but what it wrote is worth keeping.
    :func:`kept_partial` lists what was kept, for the line that ends the run.
    """
    os.replace(tmp, path)
    _LIVE_TEMPS.discard(tmp)
    _KEPT.append(Path(path))


def kept_partial() -> list[Path]:
    """Return the outputs this run kept as they stood when a signal stopped it (:func:`keep_partial`)."""
    return list(_KEPT)


def discard_temp(tmp: Path | None) -> None:
    """Remove the temporary ``tmp`` (file or folder) instead of committing it."""
    import shutil

    if tmp is None:
        return
    try:
        shutil.rmtree(tmp) if tmp.is_dir() and not tmp.is_symlink() else tmp.unlink(missing_ok=True)
    except OSError:
        pass
    _LIVE_TEMPS.discard(tmp)


def _new_file_mode(path: Path) -> int:
    """Return the mode a new ``path`` gets, as ``open()`` would give it.

    An existing file's own mode (replacing keeps it), else 0o666 less the umask (mkstemp alone
    makes 0600).
    """
    try:
        return os.stat(path).st_mode & 0o7777
    except OSError:
        return 0o666 & ~_umask()


def write_bytes_atomic(path: str | os.PathLike, data: bytes, *, overwrite: bool = False) -> Path:
    """Write ``data`` to ``path`` atomically.

    Temp file + fsync + rename, with the mode ``open()`` would give it (0o666 less the umask; a
    replaced file keeps its mode).

    Raises
    ------
    FileExistsRefusedError
        If ``path`` exists and ``overwrite`` is false.
    OutputError
        If ``path`` cannot be made (a directory, a parent that is a file, no permission, ...).
    """
    path = check_output_file(path, overwrite=overwrite)
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = temp_sibling(path)
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        commit_temp(tmp, path)
    except OSError as exc:
        discard_temp(tmp)
        raise output_error(path, exc) from None
    except BaseException:
        discard_temp(tmp)
        raise
    return path


def _json_default(obj: Any) -> Any:
    import numpy as np  # here, not at the top: the command line's start needs none of numpy

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


def json_lines(path: str | os.PathLike, *, cap: int, what: str = "line"):
    """Yield ``(line number, decoded object)`` for each non-blank line of a JSON-lines file.

    Parameters
    ----------
    path : str or PathLike
        The file.
    cap : int
        At most this many objects; one more is refused.
    what : str
        What a line holds, for the message of the cap.

    Yields
    ------
    (int, object)
        The 1-based line number and the line's JSON value.

    Raises
    ------
    BadInputError
        A line that is not JSON, or more than ``cap`` of them.
    """
    n = 0
    with open(path, encoding="utf-8") as f:
        for i, line in enumerate(f, 1):
            if not line.strip():
                continue
            n += 1
            if n > cap:
                raise BadInputError(f"{path} has more than {cap} {what}s")
            try:
                yield i, json.loads(line)
            except json.JSONDecodeError as exc:
                raise BadInputError(
                    f"{path} line {i} is not valid JSON ({exc.msg}); expected one object per line"
                ) from None


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


#: the image files the toolkit writes (by suffix); PNG is lossless, JPEG lossy
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff")
#: what 16-bit frames may be written as (OpenCV writes 16 bits per channel to these); JPEG holds 8
_DEEP_SUFFIXES = (".png", ".tif", ".tiff")


def write_image(path: str | os.PathLike, image: np.ndarray, *, overwrite: bool = False) -> Path:
    """Encode an image by the file's extension and write it atomically.

    A uint16 image is refused for JPEG (8 bits only): it is never scaled down silently.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write: .png, .jpg/.jpeg or .tif/.tiff.
    image : numpy.ndarray
        Grey or BGR; uint8, or uint16 as 16-bit PNG/TIFF (the ADC counts kept as they are).
    overwrite : bool
        Replace an existing file; without it an existing file is refused.

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    BadInputError
        For an unknown suffix, a uint16 image for JPEG, another dtype, or an image OpenCV
        cannot encode.
    FileExistsRefusedError
        When ``path`` exists and ``overwrite`` is false.
    OutputError
        When the file cannot be written.
    """
    import cv2
    import numpy as np

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in IMAGE_SUFFIXES:
        raise BadInputError(
            f"cannot write an image as {path} (suffix {path.suffix or 'none'!r}); expected .png or .jpg"
        )
    if image.dtype == np.uint16 and suffix not in _DEEP_SUFFIXES:
        raise BadInputError(f"cannot write a 16-bit image as {path.suffix!r} ({path}); expected .png")
    if image.dtype not in (np.uint8, np.uint16):
        raise BadInputError(f"cannot write a {image.dtype} image to {path}; expected uint8 or uint16")
    ok, buf = cv2.imencode(suffix, image)
    if not ok:
        raise BadInputError(f"cannot encode an image as {path.suffix!r}; expected .png or .jpg")
    return write_bytes_atomic(path, buf.tobytes(), overwrite=overwrite)


def figure_png(fig, *, dpi: int = 110, **savefig_kw) -> bytes:
    """Render a matplotlib figure as PNG bytes; the figure is closed (plots are made once, then saved)."""
    import io

    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, **savefig_kw)
    plt.close(fig)
    return buf.getvalue()


def write_figure(path: str | os.PathLike, fig, *, overwrite: bool = False, dpi: int = 110, **savefig_kw) -> Path:
    """Save a matplotlib figure as PNG, atomically (see :func:`figure_png`)."""
    return write_bytes_atomic(path, figure_png(fig, dpi=dpi, **savefig_kw), overwrite=overwrite)


class quiet_opencv:
    """Silence OpenCV's log and the C libraries' messages within a ``with`` block.

    ``with quiet_opencv():`` OpenCV's own log (``[ WARN:0@...]``, ``[ERROR:...]`` lines) is
    off and the C libraries' messages (libpng's ``libpng error: ...``, written straight to file
    descriptor 2) go to /dev/null; both are back after. The caller reports a failure itself, in
    one line. Only around one decode: stderr is away for about a millisecond.
    """

    def __enter__(self):
        import sys

        import cv2

        self._level = cv2.utils.logging.getLogLevel()
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
        self._saved = None
        try:
            sys.stderr.flush()
            self._saved = os.dup(2)
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, 2)
            os.close(devnull)
        except (OSError, ValueError, AttributeError):  # no file descriptor 2 (embedded): log only
            if self._saved is not None:
                os.close(self._saved)
                self._saved = None
        return self

    def __exit__(self, *exc) -> None:
        import cv2

        if self._saved is not None:
            os.dup2(self._saved, 2)
            os.close(self._saved)
        cv2.utils.logging.setLogLevel(self._level)


def read_image(path: str | os.PathLike, *, color: bool = True, what: str = "image") -> np.ndarray:
    """Read an image file: a frame, or with ``color=False`` a grey map.

    Parameters
    ----------
    path : str or os.PathLike
        The image file (PNG or JPEG; 16-bit PNG for ADC counts).
    color : bool
        Read a frame, (H, W, 3) BGR as stored; else (H, W) uint8 grey (a map).
    what : str
        Names the file in error messages (e.g. ``"dark frame"``).

    Returns
    -------
    numpy.ndarray
        With ``color``, (H, W, 3) BGR -- uint8, or uint16 for a 16-bit PNG (the sensor's ADC
        counts, never divided by 256); else (H, W) uint8.

    Raises
    ------
    BadInputError
        For a missing, empty or undecodable file, and with ``color`` for an image that is not
        3-channel BGR (greyscale, alpha) or not 8/16-bit.
    """
    import cv2
    import numpy as np

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
    with quiet_opencv():  # a damaged file is our one-line error, not OpenCV's WARN/ERROR lines first
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
    """Check that a dark frame has the frames' depth.

    A dark frame must have the frames' depth (uint8 with uint8, uint16 ADC counts with
    uint16): a one-line :class:`BadInputError` naming the dark frame otherwise.
    """
    if frame.dtype != dark.dtype:
        of = f" ({frame_path})" if frame_path is not None else ""
        raise BadInputError(
            f"dark frame {dark_path} is {_depth(dark)} but the frame{of} is {_depth(frame)}; "
            "expected a dark frame of the frames' depth, taken with the same camera"
        )


def _depth(img: np.ndarray) -> str:
    return f"{8 * img.dtype.itemsize}-bit"


def check_output_folder(folder: str | os.PathLike, names, *, overwrite: bool = False) -> Path:
    """Check, before any work, that ``folder`` can hold the files ``names``.

    A folder or creatable (no file in the way), and none of ``names`` already there unless
    ``overwrite``.
    """
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"{folder} is a file; expected a folder for the outputs")
    for name in names:
        check_output_file(folder / name, overwrite=overwrite)
    if not folder.exists():
        check_output_file(folder, overwrite=False)  # its parents: folders or creatable
    return folder


def write_set(folder: str | os.PathLike, files: dict[str, bytes], *, overwrite: bool = False) -> list[Path]:
    """Write a set of files into ``folder`` as one unit.

    The last entry of ``files`` is the set's marker (e.g. its ground truth).

    A new or empty ``folder`` is made whole in a temporary sibling folder and renamed into place:
    the set appears complete or not at all. Into a folder that holds other files, each file is
    replaced atomically, the marker removed first and written last: the set is complete when its
    marker is there, and re-running the same command completes it.
    """
    folder = check_output_folder(folder, files, overwrite=overwrite)
    names = list(files)
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        _sweep_once(folder.parent)  # a killed write of this set, either way it was being written
        if folder.is_dir():
            _sweep_once(folder)
        if not folder.exists() or not any(folder.iterdir()):
            tmp = temp_sibling(folder, directory=True)
            try:
                os.chmod(tmp, 0o777 & ~_umask())
                for name, data in files.items():
                    with open(tmp / name, "wb") as f:
                        os.fchmod(f.fileno(), 0o666 & ~_umask())
                        f.write(data)
                        f.flush()
                        os.fsync(f.fileno())
                commit_temp(tmp, folder)  # rename(2) replaces an empty folder
            except BaseException:
                discard_temp(tmp)
                raise
        else:
            (folder / names[-1]).unlink(missing_ok=True)
            for name in names:
                write_bytes_atomic(folder / name, files[name], overwrite=True)
    except OSError as exc:
        raise output_error(folder, exc) from None
    return [folder / n for n in names]


def image_bytes(image: np.ndarray, suffix: str = ".png") -> bytes:
    """``image`` encoded as ``suffix`` (see :func:`write_image`), for :func:`write_set`."""
    import cv2

    ok, buf = cv2.imencode(suffix, image)
    if not ok:
        raise BadInputError(f"cannot encode an image as {suffix!r}")
    return buf.tobytes()
