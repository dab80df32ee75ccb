"""Read and write other tools' calibration files: OCamCalib's ``calib_results.txt``, a Kalibr
camera chain (YAML) and an OpenCV ``omnidir`` calibration saved by ``cv::FileStorage`` (YAML or
XML). Every malformed file is one :class:`~stcvision.errors.BadInputError` naming the field and
what was expected.

Layouts:

* OCamCalib (the MATLAB toolbox's export, read by its ``get_ocam_model``): five data lines between
  ``#`` comments -- the direct polynomial (its length, then ``ss`` ascending), the inverse
  polynomial (length, then ``invpol``), the centre as row then column (0-based), the affine
  ``c d e``, the image height then width.
* Kalibr (wiki "YAML formats"): ``camN:`` maps with ``camera_model`` (pinhole, omni, ds, eucm),
  ``intrinsics`` (pinhole ``[fu fv pu pv]``, omni ``[xi fu fv pu pv]``, ds ``[xi alpha fu fv pu
  pv]``, eucm ``[alpha beta fu fv pu pv]``), ``distortion_model`` (none, radtan ``[k1 k2 r1 r2]``,
  equidistant ``[k1 k2 k3 k4]``, fov ``[w]``), ``distortion_coeffs`` and ``resolution [w, h]``.
* OpenCV omnidir (``omni_calibration.cpp``'s ``saveCameraParams``): ``camera_matrix`` (3x3, with
  the skew), ``distortion_coefficients`` ``[k1 k2 p1 p2]``, ``xi``; other writers use ``K``, ``D``.
  The sample stores no image size: ``image_width``/``image_height`` (or ``image_size``) when
  present, otherwise the caller's.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from stcvision.calibration.lens_models import DISTORTIONS, PROJECTIONS, CentralModel, OcamModel
from stcvision.errors import BadInputError

__all__ = ["FORMATS", "detect_format", "read_lens_file", "write_lens_file", "lens_file_text"]

FORMATS = ("ocamcalib", "kalibr", "omnidir")
#: a calibration file is a few kB; a bigger one is not one of these formats (and would be read whole)
MAX_LENS_FILE_BYTES = 4_000_000
#: image sides a lens model may describe (pixels): the toolkit's camera cap
MAX_SIDE_PX = 16_384
#: polynomial lengths OCamCalib files hold (its toolbox writes up to ~35 inverse coefficients)
MAX_OCAM_TERMS = 64


def _finite(v, what: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float | np.floating | np.integer) or not math.isfinite(v):
        raise BadInputError(f"{what} must be a finite number, got {v!r}")
    return float(v)


def _size(w, h, what: str) -> tuple[int, int]:
    w, h = _finite(w, f"{what} width"), _finite(h, f"{what} height")
    if w != int(w) or h != int(h) or not (1 <= w <= MAX_SIDE_PX and 1 <= h <= MAX_SIDE_PX):
        raise BadInputError(f"{what}: expected two whole numbers of pixels in 1..{MAX_SIDE_PX}, got {w:g} x {h:g}")
    return int(w), int(h)


def read_text(path) -> str:
    p = Path(path)
    try:
        data = p.read_bytes()[: MAX_LENS_FILE_BYTES + 1]
    except IsADirectoryError:
        raise BadInputError(f"calibration file {p} is a directory; expected a file") from None
    except FileNotFoundError:
        raise BadInputError(f"calibration file {p} does not exist") from None
    except OSError as e:
        raise BadInputError(f"calibration file {p} cannot be read: {e.strerror or e}") from None
    if len(data) > MAX_LENS_FILE_BYTES:
        raise BadInputError(f"calibration file {p} is over {MAX_LENS_FILE_BYTES:,} bytes; expected a calibration file")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise BadInputError(
            f"calibration file {p} is not text; expected an OCamCalib, Kalibr or omnidir file"
        ) from None


def detect_format(text: str, name: str = "calibration file") -> str:
    """Which of :data:`FORMATS` ``text`` is, from its content."""
    head = text.lstrip()[:4096]
    low = head.lower()
    if head.startswith("%YAML") or head.startswith("<?xml") or "<opencv_storage>" in low:
        return "omnidir"
    if "ocam_model" in low or "cam2world" in low or "polynomial coefficients for the direct" in low:
        return "ocamcalib"
    if "camera_model" in low and "intrinsics" in low:
        return "kalibr"
    if ("camera_matrix" in low or "xi" in low) and ":" in head:
        return "omnidir"
    # OCamCalib's layout without its usual comments: '#' lines between lines of numbers
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    try:
        if "#" in text and lines and all(float(t) is not None for t in lines[0].split()):
            return "ocamcalib"
    except ValueError:
        pass
    raise BadInputError(
        f"{name}: cannot tell its format (expected an OCamCalib calib_results.txt, a Kalibr camchain YAML "
        "or an OpenCV omnidir FileStorage file); name it with --format"
    )


# ---------------------------------------------------------------------------- OCamCalib
OCAM_FIELDS = (
    "direct polynomial 'ss' (its length, then the coefficients)",
    "inverse polynomial 'invpol' (its length, then the coefficients)",
    "centre (row, then column)",
    "affine parameters 'c d e'",
    "image size (height, then width)",
)


def parse_ocamcalib(text: str, name: str) -> OcamModel:
    lines = [(i + 1, ln) for i, ln in enumerate(text.splitlines()) if ln.strip() and not ln.lstrip().startswith("#")]
    if len(lines) < 5:
        missing = OCAM_FIELDS[len(lines)]
        raise BadInputError(f"{name}: OCamCalib file ends before the {missing}; expected five data lines")
    vals = []
    for k, (no, ln) in enumerate(lines[:5]):
        try:
            nums = [float(t) for t in ln.split()]
        except ValueError:
            raise BadInputError(
                f"{name} line {no}: the {OCAM_FIELDS[k]} must be numbers, got {ln.strip()[:60]!r}"
            ) from None
        if not all(math.isfinite(v) for v in nums):
            raise BadInputError(f"{name} line {no}: the {OCAM_FIELDS[k]} must be finite numbers")
        vals.append((no, nums))
    polys = []
    for k in (0, 1):
        no, nums = vals[k]
        n = nums[0] if nums else -1
        if n != int(n) or not 2 <= n <= MAX_OCAM_TERMS or len(nums) != int(n) + 1:
            raise BadInputError(
                f"{name} line {no}: the {OCAM_FIELDS[k]}: expected a length in 2..{MAX_OCAM_TERMS} followed by that "
                f"many numbers, got {len(nums) - 1} numbers after {nums[0] if nums else 'nothing'}"
            )
        polys.append(tuple(nums[1:]))
    for k, n in ((2, 2), (3, 3), (4, 2)):
        no, nums = vals[k]
        if len(nums) != n:
            raise BadInputError(f"{name} line {no}: the {OCAM_FIELDS[k]}: expected {n} numbers, got {len(nums)}")
    if len(lines) > 5:
        raise BadInputError(
            f"{name} line {lines[5][0]}: unexpected data after the image size; expected five data lines"
        )
    (xc, yc), (c, d, e), (hh, ww) = vals[2][1], vals[3][1], vals[4][1]
    w, h = _size(ww, hh, f"{name} image size")
    ss = polys[0]
    if ss[0] == 0:
        raise BadInputError(
            f"{name}: the direct polynomial's constant term ss[0] is 0; the centre pixel would have no ray"
        )
    if abs(c - d * e) < 1e-6:
        raise BadInputError(f"{name}: the affine parameters c d e = {c:g} {d:g} {e:g} are singular (c - d e = 0)")
    if not (0 <= xc < h and 0 <= yc < w):
        raise BadInputError(f"{name}: the centre (row {xc:g}, column {yc:g}) lies outside the {w}x{h} image")
    return OcamModel(ss=ss, invpol=polys[1], xc=xc, yc=yc, c=c, d=d, e=e, width=w, height=h)


def ocamcalib_text(m: OcamModel) -> str:
    def line(v):
        return " ".join(f"{x:.6e}" for x in v)

    return (
        "#polynomial coefficients for the DIRECT mapping function (ocam_model.ss in MATLAB). "
        "These are used by cam2world\n\n"
        f"{len(m.ss)} {line(m.ss)} \n\n"
        "#polynomial coefficients for the inverse mapping function (ocam_model.invpol in MATLAB). "
        "These are used by world2cam\n\n"
        f"{len(m.invpol)} {' '.join(f'{x:.6f}' for x in m.invpol)} \n\n"
        '#center: "row" and "column", starting from 0 (C convention)\n\n'
        f"{m.xc:.6f} {m.yc:.6f}\n\n"
        '#affine parameters "c", "d", "e"\n\n'
        f"{m.c:.6f} {m.d:.6f} {m.e:.6f}\n\n"
        '#image size: "height" and "width"\n\n'
        f"{m.height} {m.width}\n\n"
    )


# ---------------------------------------------------------------------------- Kalibr
def parse_kalibr(text: str, name: str, camera: str | None) -> CentralModel:
    import yaml

    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" line {mark.line + 1}" if mark is not None else ""
        raise BadInputError(
            f"{name}{where}: not valid YAML ({getattr(e, 'problem', None) or 'syntax error'})"
        ) from None
    if not isinstance(doc, dict):
        raise BadInputError(f"{name}: expected a Kalibr camera chain (a map of cam0, cam1, ...)")
    cams = sorted(k for k, v in doc.items() if isinstance(k, str) and isinstance(v, dict) and "camera_model" in v)
    if not cams:
        raise BadInputError(
            f"{name}: no camera with a camera_model; expected cam0: {{camera_model: ..., intrinsics: ...}}"
        )
    if camera is None:
        if len(cams) > 1:
            raise BadInputError(f"{name} holds cameras {', '.join(cams)}: pick one with --camera")
        camera = cams[0]
    if camera not in cams:
        raise BadInputError(f"{name}: no camera {camera!r}; it holds {', '.join(cams)}")
    cam = doc[camera]
    where = f"{name} {camera}"
    proj = cam.get("camera_model")
    if proj not in PROJECTIONS:
        raise BadInputError(f"{where} field 'camera_model' is {proj!r}; expected one of {', '.join(PROJECTIONS)}")
    dist = cam.get("distortion_model", "none")
    if dist in (None, "None"):
        dist = "none"
    if dist == "equi":
        dist = "equidistant"
    if dist not in DISTORTIONS:
        raise BadInputError(f"{where} field 'distortion_model' is {dist!r}; expected one of {', '.join(DISTORTIONS)}")
    n_par = len(PROJECTIONS[proj])
    intr = _list(cam, "intrinsics", n_par + 4, where)
    coeffs = _list(cam, "distortion_coeffs", DISTORTIONS[dist], where) if DISTORTIONS[dist] else []
    if proj in ("ds", "eucm") and dist != "none":
        raise BadInputError(f"{where}: the {proj} model takes no distortion; expected distortion_model: none")
    res = _list(cam, "resolution", 2, where)
    w, h = _size(res[0], res[1], f"{where} field 'resolution'")
    return _central(proj, tuple(intr[:n_par]), dist, tuple(coeffs), *intr[n_par:], w, h, 0.0, where)


def _list(d: dict, key: str, n: int, where: str) -> list[float]:
    if key not in d:
        raise BadInputError(f"{where} is missing field {key!r}")
    v = d[key]
    if not isinstance(v, list | tuple) or len(v) != n:
        got = f"{len(v)} values" if isinstance(v, list | tuple) else repr(v)
        raise BadInputError(f"{where} field {key!r}: expected a list of {n} numbers, got {got}")
    return [_finite(x, f"{where} field {key!r}") for x in v]


def _central(proj, params, dist, coeffs, fu, fv, pu, pv, w, h, skew, where) -> CentralModel:
    if not (fu > 0 and fv > 0):
        raise BadInputError(f"{where}: the focal lengths fu, fv must be > 0, got {fu:g}, {fv:g}")
    if not (0 <= pu < w and 0 <= pv < h):
        raise BadInputError(f"{where}: the principal point ({pu:g}, {pv:g}) lies outside the {w}x{h} image")
    if proj == "omni" and not params[0] >= 0:
        raise BadInputError(f"{where}: the mirror parameter xi must be >= 0, got {params[0]:g}")
    if proj == "ds" and not (0 < params[1] < 1):
        raise BadInputError(f"{where}: the double sphere's alpha must be in (0, 1), got {params[1]:g}")
    if proj == "eucm" and not (0 < params[0] < 1 and params[1] > 0):
        raise BadInputError(f"{where}: EUCM's alpha must be in (0, 1) and beta > 0, got {params[0]:g}, {params[1]:g}")
    if dist == "fov" and not (0 < coeffs[0] < math.pi):
        raise BadInputError(f"{where}: the fov distortion's w must be in (0, pi), got {coeffs[0]:g}")
    return CentralModel(proj, tuple(params), dist, tuple(coeffs), fu, fv, pu, pv, w, h, skew)


def kalibr_text(m: CentralModel, camera: str = "cam0") -> str:
    import yaml

    cam = {
        "camera_model": m.projection,
        "intrinsics": [float(x) for x in (*m.params, m.fu, m.fv, m.pu, m.pv)],
        "distortion_model": m.distortion,
        "distortion_coeffs": [float(x) for x in m.coeffs],
        "resolution": [int(m.width), int(m.height)],
    }
    return yaml.safe_dump({camera: cam}, sort_keys=False)


# ---------------------------------------------------------------------------- OpenCV omnidir
def parse_omnidir(text: str, name: str, image_size: tuple[int, int] | None) -> CentralModel:
    import cv2

    try:
        fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    except (cv2.error, SystemError) as e:  # SystemError: the binding's wrapping of a parser error
        msg = str(e).strip().splitlines()[-1] if str(e).strip() else "parse error"
        raise BadInputError(f"{name}: not a readable OpenCV FileStorage file ({msg[:120]})") from None
    try:
        if not fs.isOpened():
            raise BadInputError(f"{name}: not a readable OpenCV FileStorage file (YAML or XML)")

        def node(*keys):
            for k in keys:
                n = fs.getNode(k)
                if not n.empty() and not n.isNone():
                    return k, n
            return None, None

        def matrix(keys, shape_ok, expect):
            k, n = node(*keys)
            if n is None:
                raise BadInputError(f"{name} is missing field {keys[0]!r} ({expect})")
            m = n.mat() if n.isMap() else None
            if m is None and n.isSeq():
                m = np.array([n.at(i).real() for i in range(n.size())], float)
            if m is None and n.isReal():
                m = np.array([n.real()])
            if m is None or not shape_ok(np.asarray(m)) or not np.isfinite(np.asarray(m, float)).all():
                raise BadInputError(f"{name} field {k!r}: expected {expect}")
            return np.asarray(m, float)

        K = matrix(("camera_matrix", "K", "cameraMatrix"), lambda m: m.shape == (3, 3), "a 3x3 camera matrix")
        D = matrix(
            ("distortion_coefficients", "D", "distCoeffs"),
            lambda m: m.size == 4,
            "4 distortion coefficients k1 k2 p1 p2",
        ).ravel()
        xi = matrix(("xi",), lambda m: m.size == 1, "one number, the mirror parameter").ravel()[0]
        kw, nw = node("image_width")
        kh, nh = node("image_height")
        if nw is not None and nh is not None:
            size = (nw.real(), nh.real())
        else:
            ks, ns = node("image_size", "imageSize")
            if ns is not None:
                v = ns.mat() if ns.isMap() else np.array([ns.at(i).real() for i in range(ns.size())])
                v = np.asarray(v, float).ravel()
                if v.size != 2:
                    raise BadInputError(f"{name} field {ks!r}: expected two numbers, width and height")
                size = (v[0], v[1])
            elif image_size is not None:
                size = image_size
            else:
                raise BadInputError(
                    f"{name} is missing field 'image_width'/'image_height' (OpenCV's sample does not store them): "
                    "give the image size with --image-size WxH"
                )
    finally:
        fs.release()
    w, h = _size(size[0], size[1], f"{name} image size")
    if abs(K[1, 0]) > 1e-9 or abs(K[2, 0]) > 1e-9 or abs(K[2, 1]) > 1e-9 or abs(K[2, 2] - 1) > 1e-9:
        raise BadInputError(f"{name} field 'camera_matrix': expected [fx s cx; 0 fy cy; 0 0 1], got {K.tolist()}")
    return _central(
        "omni",
        (float(xi),),
        "radtan",
        tuple(float(x) for x in D),
        K[0, 0],
        K[1, 1],
        K[0, 2],
        K[1, 2],
        w,
        h,
        float(K[0, 1]),
        name,
    )


def omnidir_text(m: CentralModel, *, xml: bool = False) -> str:
    import cv2

    if m.projection != "omni" or m.distortion not in ("radtan", "none"):
        raise BadInputError(
            f"OpenCV omnidir holds Mei's model with radtan distortion, not {m.projection}-{m.distortion}"
        )
    fs = cv2.FileStorage(".xml" if xml else ".yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    fs.write("calibration_model", "omnidir")
    fs.write("image_width", int(m.width))
    fs.write("image_height", int(m.height))
    fs.write("camera_matrix", np.array([[m.fu, m.skew, m.pu], [0, m.fv, m.pv], [0, 0, 1]], float))
    coeffs = m.coeffs if m.distortion == "radtan" else (0.0, 0.0, 0.0, 0.0)
    fs.write("distortion_coefficients", np.array([coeffs], float))
    fs.write("xi", float(m.params[0]))
    return fs.releaseAndGetString()


# ---------------------------------------------------------------------------- entry points
def read_lens_file(path, *, fmt: str | None = None, camera: str | None = None, image_size=None):
    """The lens model in ``path`` and its format (``fmt`` or detected from the content)."""
    name = f"calibration file {path}"
    text = read_text(path)
    if fmt is None:
        fmt = detect_format(text, name)
    if fmt not in FORMATS:
        raise BadInputError(f"format {fmt!r}: expected one of {', '.join(FORMATS)}")
    if fmt == "ocamcalib":
        model = parse_ocamcalib(text, name)
    elif fmt == "kalibr":
        model = parse_kalibr(text, name, camera)
    else:
        model = parse_omnidir(text, name, image_size)
    if camera is not None and fmt != "kalibr":
        raise BadInputError(f"--camera {camera}: only a Kalibr camera chain holds several cameras, {name} is {fmt}")
    return model, fmt


def lens_file_text(model, fmt: str, path: str = "") -> str:
    if fmt == "ocamcalib":
        return ocamcalib_text(model)
    if fmt == "kalibr":
        return kalibr_text(model)
    return omnidir_text(model, xml=str(path).lower().endswith(".xml"))


def write_lens_file(path, model, fmt: str, *, overwrite: bool = False) -> Path:
    from stcvision.fileio import write_bytes_atomic

    return write_bytes_atomic(path, lens_file_text(model, fmt, str(path)).encode(), overwrite=overwrite)
