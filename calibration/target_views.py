"""Views of a planar calibration target: the object points (on the target's plane, z = 0) and
where they appear in the image, read from OpenCV ``FileStorage`` points files or found in a
folder of images of a checkerboard or circle grid.

Points files follow the layout of OpenCV's omnidirectional calibration sample (``objectPoints``,
``imagePoints``, ``imageSize``; the stereo layout's ``imagePoints1`` / ``imagePoints2`` for
camera 1 or 2), XML or YAML. Images are searched with OpenCV's detectors, the corners refined
to sub-pixel; a view whose detection fails a check is refused with its reason and the others
kept.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stcvision.calibration.target_options import PATTERNS
from stcvision.errors import BadInputError

__all__ = [
    "MAX_POINTS_PER_VIEW",
    "MAX_POINTS_FILE_BYTES",
    "MAX_TARGET_IMAGE_SIDE_PX",
    "MAX_VIEWS",
    "MIN_POINTS_PER_VIEW",
    "MIN_VIEWS",
    "TargetViews",
    "detect_views",
    "read_points_file",
    "write_points_file",
]

#: views one calibration takes (each adds six pose parameters to the fit: 200 views are ~1,200)
MAX_VIEWS = 200
#: the fewest views a calibration takes: the nine intrinsics need views at several angles, and
#: the held-out figure needs views to hold out
MIN_VIEWS = 4
#: points one view may hold (a 40 x 25 board is 1,000 corners)
MAX_POINTS_PER_VIEW = 2_000
#: a view with fewer points does not fix its own six pose parameters with margin
MIN_POINTS_PER_VIEW = 8
#: a points file's size (a 200-view, 2,000-point file in XML is ~40 MB)
MAX_POINTS_FILE_BYTES = 64 * 2**20
#: an image's longer side (a 4096 x 4096 frame is 16 megapixels)
MAX_TARGET_IMAGE_SIDE_PX = 8192
#: images read from one folder (the views' cap, with room for refused ones)
MAX_TARGET_IMAGES = 2 * MAX_VIEWS
#: image file suffixes read from a folder
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".pnm")
#: how far the sub-pixel refinement may move a corner from the detector's estimate (px), or half
#: the refinement window's half-side when that is more: further means the window met another
#: corner or the blur, and the view is refused (the detector's estimate on a 1280x1024
#: catadioptric photograph, whose corners are 11-px windows apart, was 3-5 px off: Mei's
#: toolbox sample)
MAX_SUBPIX_SHIFT_PX = 3.0
#: corners nearer the image's border than this (px) are cut by it
BORDER_PX = 3.0
#: how far outside the image (px from the outermost pixel centres) a points file's point may lie:
#: the least spread of a view's image points across their narrowest direction (the smallest
#: singular value of the centred points, px): a grid's image spans tens of pixels each way
MIN_IMAGE_SPREAD_PX = 1.0
#: a detector's sub-pixel estimate at the edge; further means the image size is wrong
OFF_IMAGE_TOLERANCE_PX = 2.0


@dataclass(frozen=True)
class TargetViews:
    """``object_points[i]`` (N_i, 3) on the target's plane, ``image_points[i]`` (N_i, 2) pixels
    (0-based, pixel centres at integers as OpenCV), the image size, each view's name, and the
    refused views with their reasons."""

    object_points: tuple[np.ndarray, ...]
    image_points: tuple[np.ndarray, ...]
    image_size_px: tuple[int, int]
    names: tuple[str, ...]
    refused: tuple[tuple[str, str], ...] = field(default=())

    def __len__(self) -> int:
        return len(self.object_points)

    def subset(self, idx) -> TargetViews:
        idx = [int(i) for i in idx]
        return TargetViews(
            tuple(self.object_points[i] for i in idx),
            tuple(self.image_points[i] for i in idx),
            self.image_size_px,
            tuple(self.names[i] for i in idx),
        )

    @property
    def n_points(self) -> int:
        return int(sum(len(p) for p in self.image_points))


def check_views(views: TargetViews, where: str) -> TargetViews:
    """Refuse a set of views the fit cannot take: too few or too many views, a view with too
    few or too many points, points that are not finite, off the image, or not on a plane z = 0."""
    n = len(views)
    if n < MIN_VIEWS:
        why = "".join(f"; {name}: {reason}" for name, reason in views.refused[:3])
        raise BadInputError(f"{where}: {n} usable view(s); expected at least {MIN_VIEWS}{why}")
    if n > MAX_VIEWS:
        raise BadInputError(f"{where}: {n} views, over the cap of {MAX_VIEWS} (MAX_VIEWS)")
    w, h = views.image_size_px
    if not (1 <= w <= MAX_TARGET_IMAGE_SIDE_PX and 1 <= h <= MAX_TARGET_IMAGE_SIDE_PX):
        raise BadInputError(f"{where}: image size {w}x{h}; expected 1..{MAX_TARGET_IMAGE_SIDE_PX} px a side")
    for name, obj, img in zip(views.names, views.object_points, views.image_points, strict=True):
        if obj.shape[0] != img.shape[0]:
            raise BadInputError(f"{where}: view {name} has {len(obj)} object points but {len(img)} image points")
        if not MIN_POINTS_PER_VIEW <= len(obj) <= MAX_POINTS_PER_VIEW:
            raise BadInputError(
                f"{where}: view {name} has {len(obj)} points; expected {MIN_POINTS_PER_VIEW}..{MAX_POINTS_PER_VIEW}"
            )
        if not (np.isfinite(obj).all() and np.isfinite(img).all()):
            raise BadInputError(f"{where}: view {name} holds a point that is not a finite number")
        if np.abs(obj[:, 2]).max() > 1e-9 * max(1.0, float(np.abs(obj).max())):
            raise BadInputError(f"{where}: view {name}'s object points are not on the plane z = 0 (a planar target)")
        span = np.ptp(obj[:, :2], axis=0)
        if min(span) <= 0:
            raise BadInputError(f"{where}: view {name}'s object points lie on a line; expected a planar grid")
        # the image of a grid spans an area: points on a line or on one pixel fix no camera
        # (found by fuzzing: every image point at one pixel gave a zero RMS and a division by it)
        if np.linalg.svd(img - img.mean(axis=0), compute_uv=False)[-1] < MIN_IMAGE_SPREAD_PX:
            raise BadInputError(
                f"{where}: view {name}'s image points lie on a line or a point; expected the image of a planar grid"
            )
        m = OFF_IMAGE_TOLERANCE_PX
        if (img < -m).any() or (img[:, 0] > w - 1 + m).any() or (img[:, 1] > h - 1 + m).any():
            raise BadInputError(
                f"{where}: view {name} has image points outside the {w}x{h} image (is the image size width x height?)"
            )
    return views


# ---------------------------------------------------------------------------- points files
def _flat_reals(node, budget: int) -> list[float]:
    """The numbers of a (nested) FileStorage sequence, in order; at most ``budget`` of them."""
    out: list[float] = []
    stack = [node]
    while stack:
        n = stack.pop()
        if n.isSeq():
            stack.extend(n.at(i) for i in reversed(range(n.size())))
        elif n.isReal() or n.isInt():
            out.append(n.real())
        else:
            raise ValueError("not a number")
        if len(out) > budget:
            break
    return out


def _node_points(node, k: int, where: str, key: str) -> np.ndarray:
    """One view's points from a FileStorage node: a matrix of k-channel points, or of k columns,
    or a sequence of k-number points (as OpenCV writes a vector of points in YAML)."""
    if node.isSeq():
        try:
            a = np.asarray(_flat_reals(node, k * MAX_POINTS_PER_VIEW), float)
        except ValueError:
            raise BadInputError(f"{where}: {key} holds an entry that is not a list of numbers") from None
    else:
        m = node.mat()
        if m is None:
            raise BadInputError(f"{where}: {key} holds an entry that is not a matrix; expected an OpenCV matrix")
        a = np.asarray(m, float)
    if a.size % k:
        raise BadInputError(f"{where}: {key} holds a matrix of {a.size} numbers; expected {k}-vectors")
    return a.reshape(-1, k)


def _node_list(fs, key: str, k: int, where: str) -> list[np.ndarray]:
    node = fs.getNode(key)
    if node.empty():
        raise BadInputError(f"{where} has no {key}; expected OpenCV's layout (objectPoints, imagePoints, imageSize)")
    if not node.isSeq():
        raise BadInputError(f"{where}: {key} is not a sequence of matrices (one per view)")
    n = node.size()
    if n > MAX_VIEWS:
        raise BadInputError(f"{where}: {key} holds {n} views, over the cap of {MAX_VIEWS} (MAX_VIEWS)")
    out = []
    for i in range(n):
        a = _node_points(node.at(i), k, where, key)
        if len(a) > MAX_POINTS_PER_VIEW:
            raise BadInputError(
                f"{where}: {key} view {i} holds {len(a)} points, over the cap of {MAX_POINTS_PER_VIEW} "
                "(MAX_POINTS_PER_VIEW)"
            )
        out.append(a)
    return out


def _image_size(fs, where: str, given) -> tuple[int, int]:
    node = fs.getNode("imageSize")
    if node.empty():
        if given is None:
            raise BadInputError(f"{where} has no imageSize; give it with --image-size WxH")
        return tuple(int(v) for v in given)
    if node.isSeq():
        vals = [node.at(i).real() for i in range(node.size())]
    else:
        m = node.mat()
        vals = [] if m is None else [float(x) for x in np.ravel(m)]
    if len(vals) != 2 or not all(math.isfinite(v) and v == int(v) and 0 < v <= MAX_TARGET_IMAGE_SIDE_PX for v in vals):
        shown = ", ".join(f"{v:.6g}" for v in vals[:4]) + (", ..." if len(vals) > 4 else "")
        raise BadInputError(
            f"{where}: imageSize must be two integers 1..{MAX_TARGET_IMAGE_SIDE_PX} (width height), got [{shown}]"
        )
    return int(vals[0]), int(vals[1])


def read_points_file(path, *, camera: int | None = None, image_size=None) -> TargetViews:
    """The views of an OpenCV FileStorage points file (XML, YAML or JSON as OpenCV writes them).

    A stereo file (``imagePoints1``, ``imagePoints2``) needs ``camera`` 1 or 2; ``image_size``
    (W, H) stands in for a missing ``imageSize``. Malformed files raise :class:`BadInputError`."""
    import cv2

    from stcvision.fileio import quiet_opencv

    path = Path(path)
    where = f"points file {path}"
    try:
        size = path.stat().st_size
    except FileNotFoundError:
        raise BadInputError(f"{where} does not exist") from None
    except OSError as exc:
        raise BadInputError(f"cannot read {where}: {exc.strerror}") from None
    if not path.is_file():
        raise BadInputError(f"{where} is not a file")
    if size == 0:
        raise BadInputError(f"{where} is empty; expected OpenCV FileStorage XML or YAML")
    if size > MAX_POINTS_FILE_BYTES:
        raise BadInputError(
            f"{where} is {size / 2**20:.0f} MiB, over the cap of {MAX_POINTS_FILE_BYTES // 2**20} MiB "
            "(MAX_POINTS_FILE_BYTES)"
        )
    _check_declared_sizes(path, where)
    try:
        with quiet_opencv():
            fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
            if not fs.isOpened():
                raise BadInputError(f"{where} is not OpenCV FileStorage XML or YAML")
            try:
                views = _read_storage(fs, where, camera, image_size)
            finally:
                fs.release()
    except (cv2.error, SystemError) as exc:  # OpenCV's parser reports some errors as SystemError
        cause = exc.__cause__ if isinstance(exc, SystemError) and exc.__cause__ is not None else exc
        text = str(cause).strip()
        msg = text.splitlines()[-1] if text else "parse error"
        if "error: (" in msg:
            msg = msg[msg.index("error: (") + len("error: ") :]
        raise BadInputError(f"{where} is not readable OpenCV FileStorage: {msg[:140]}") from None
    return check_views(views, where)


#: a matrix's declared rows or columns, as FileStorage XML (``<rows>N</rows>``) and YAML
#: (``rows: N``) write them
_DECLARED = re.compile(rb"(?:<(?:rows|cols)>|\b(?:rows|cols):)\s*(-?\d+)")


def _check_declared_sizes(path: Path, where: str) -> None:
    """Refuse a matrix declared larger than a view may be before OpenCV allocates it.

    OpenCV allocates a matrix by its declared rows and columns before reading its data (found by
    fuzzing: a declared 2e9 rows asked for 48 GB).
    """
    cap = 3 * MAX_POINTS_PER_VIEW
    for m in _DECLARED.finditer(path.read_bytes()):
        if abs(int(m.group(1))) > cap:
            raise BadInputError(
                f"{where} declares a matrix of {int(m.group(1)):,} rows or columns, over the {cap:,} a view may hold"
            )


def _read_storage(fs, where: str, camera: int | None, image_size) -> TargetViews:
    stereo = not fs.getNode("imagePoints1").empty()
    if stereo:
        if camera not in (1, 2):
            raise BadInputError(f"{where} is a stereo file (imagePoints1, imagePoints2); choose one with --camera 1|2")
        key = f"imagePoints{camera}"
    else:
        if camera not in (None, 1):
            raise BadInputError(f"{where} holds one camera's points; --camera {camera} does not apply")
        key = "imagePoints"
    obj = _node_list(fs, "objectPoints", 3, where)
    img = _node_list(fs, key, 2, where)
    if len(obj) != len(img):
        raise BadInputError(f"{where}: {len(obj)} views of objectPoints but {len(img)} of {key}")
    size = _image_size(fs, where, image_size)
    names = tuple(f"view {i}" for i in range(len(obj)))
    return TargetViews(tuple(obj), tuple(img), size, names)


def points_file_text(views: TargetViews) -> str:
    """The views in OpenCV's FileStorage XML layout, as OpenCV's omnidirectional sample has it."""
    import cv2

    fs = cv2.FileStorage(".xml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    for key, pts, k in (("objectPoints", views.object_points, 3), ("imagePoints", views.image_points, 2)):
        fs.startWriteStruct(key, cv2.FileNode_SEQ)
        for p in pts:
            fs.write("", np.asarray(p, np.float64).reshape(-1, 1, k))
        fs.endWriteStruct()
    fs.startWriteStruct("imageSize", cv2.FileNode_SEQ | cv2.FileNode_FLOW)
    for x in views.image_size_px:
        fs.write("", int(x))
    fs.endWriteStruct()
    return fs.releaseAndGetString()


def write_points_file(path, views: TargetViews, *, overwrite: bool = False) -> Path:
    """Write the views as an OpenCV FileStorage XML points file, atomically."""
    from stcvision.fileio import write_bytes_atomic

    return write_bytes_atomic(path, points_file_text(views).encode(), overwrite=overwrite)


# ---------------------------------------------------------------------------- images
def _find(grey: np.ndarray, pattern: str, cols: int, rows: int):
    """Detected centres (N, 2) or None, the refined corners' largest shift (px) and its limit."""
    import cv2

    size = (cols, rows)
    if pattern == "chessboard":
        flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
        ok, pts = cv2.findChessboardCorners(grey, size, flags=flags)
        if not ok:
            return None, 0.0, MAX_SUBPIX_SHIFT_PX
        raw = pts.reshape(-1, 2).astype(np.float32)
        # the window: a third of the nearest corners' spacing (never reaching the next corner)
        d = np.linalg.norm(np.diff(raw.reshape(rows, cols, 2), axis=1), axis=2).min()
        win = int(max(2, min(11, d / 3)))
        crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
        ref = cv2.cornerSubPix(grey, raw.reshape(-1, 1, 2).copy(), (win, win), (-1, -1), crit).reshape(-1, 2)
        shift = float(np.linalg.norm(ref - raw, axis=1).max())
        return ref.astype(float), shift, max(MAX_SUBPIX_SHIFT_PX, win / 2)
    flag = cv2.CALIB_CB_SYMMETRIC_GRID if pattern == "circles" else cv2.CALIB_CB_ASYMMETRIC_GRID
    ok, pts = cv2.findCirclesGrid(grey, size, flags=flag)
    if not ok:
        return None, 0.0, MAX_SUBPIX_SHIFT_PX
    return pts.reshape(-1, 2).astype(float), 0.0, MAX_SUBPIX_SHIFT_PX  # blob centres are sub-pixel already


def board_points(pattern: str, cols: int, rows: int, spacing: float) -> np.ndarray:
    """The target's points (N, 3) in OpenCV's detector order, ``spacing`` apart (z = 0)."""
    j, i = np.mgrid[0:rows, 0:cols]
    if pattern == "acircles":  # OpenCV's asymmetric grid: odd rows shifted by half a step
        x, y = (2 * i + j % 2) * spacing, j * spacing
    else:
        x, y = i * spacing, j * spacing
    return np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)]).astype(float)


def view_problem(
    pts: np.ndarray | None, shift: float, size, pattern: str, cols: int, rows: int, limit: float = MAX_SUBPIX_SHIFT_PX
) -> str | None:
    """Why a detection is not taken, or None: not found, cut by the border, refined too far, or
    mis-ordered (a row that repeats a point or turns back: OpenCV's circle-grid search can give
    one dot twice when far dots blur together)."""
    w, h = size
    if pts is None:
        return f"no {cols}x{rows} {pattern} found"
    if shift > limit:
        return f"the sub-pixel refinement moved a corner {shift:.1f} px (over {limit:g}): blurred?"
    if (
        (pts[:, 0] < BORDER_PX).any()
        or (pts[:, 1] < BORDER_PX).any()
        or (pts[:, 0] > w - 1 - BORDER_PX).any()
        or (pts[:, 1] > h - 1 - BORDER_PX).any()
    ):
        return f"a corner lies within {BORDER_PX:g} px of the image border"
    grid = pts.reshape(rows, cols, 2)
    along = np.diff(grid, axis=1)
    if cols > 2 and (np.einsum("rck,rck->rc", along[:, 1:], along[:, :-1]) <= 0).any():
        return "the detected rows repeat a point or fold back (a mis-ordered detection)"
    return None


def detect_views(folder, *, pattern: str, cols: int, rows: int, spacing: float, should_stop=None) -> TargetViews:
    """Find the target in each image of ``folder`` (sorted by name). ``cols`` x ``rows`` inner
    corners (or circles), ``spacing`` between neighbours in the unit the result is to be in.
    ``should_stop()`` is called between images (for Ctrl-C)."""

    from stcvision.fileio import read_image

    folder = Path(folder)
    if pattern not in PATTERNS:
        raise BadInputError(f"--pattern {pattern!r}: expected one of {', '.join(PATTERNS)}")
    if not (2 <= cols <= 100 and 2 <= rows <= 100 and cols * rows <= MAX_POINTS_PER_VIEW):
        raise BadInputError(f"--board {cols}x{rows}: expected 2..100 a side and at most {MAX_POINTS_PER_VIEW} points")
    if not (spacing > 0 and math.isfinite(spacing)):
        raise BadInputError(f"--spacing must be a number > 0, got {spacing}")
    if not folder.is_dir():
        raise BadInputError(f"target folder {folder} is not a folder of images")
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file())
    if not files:
        raise BadInputError(f"target folder {folder} holds no images ({', '.join(IMAGE_SUFFIXES)})")
    if len(files) > MAX_TARGET_IMAGES:
        raise BadInputError(f"target folder {folder} holds {len(files)} images, over the cap of {MAX_TARGET_IMAGES}")
    obj = board_points(pattern, cols, rows, spacing)
    objs, imgs, names, refused, size = [], [], [], [], None
    for f in files:
        if should_stop is not None:
            should_stop()
        # a target's photographs are often grey (calibration toolboxes' samples): read as grey
        img = read_image(f, color=False, what="target image")
        h, w = img.shape[:2]
        if max(w, h) > MAX_TARGET_IMAGE_SIDE_PX:
            raise BadInputError(f"target image {f} is {w}x{h}, over the cap of {MAX_TARGET_IMAGE_SIDE_PX} px a side")
        if size is None:
            size = (w, h)
        elif (w, h) != size:  # another camera's, or not a view (a map written beside them): refused
            refused.append((f.name, f"{w}x{h}, not the {size[0]}x{size[1]} of the first view: another camera?"))
            continue
        grey = img if img.dtype == np.uint8 else (img / 257).astype(np.uint8)
        pts, shift, limit = _find(grey, pattern, cols, rows)
        why = view_problem(pts, shift, size, pattern, cols, rows, limit)
        if why is not None:
            refused.append((f.name, why))
            continue
        objs.append(obj.copy())
        imgs.append(pts)
        names.append(f.name)
    views = TargetViews(tuple(objs), tuple(imgs), size, tuple(names), tuple(refused))
    return check_views(views, f"target folder {folder}")
