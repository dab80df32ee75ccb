"""Ray-traced catadioptric optics: a pinhole camera with radial distortion looking up at a
convex spherical mirror, reflecting each pixel's ray onto the floor.

This is the *renderer's* model. The vision pipeline in ``stcvision`` has its own (fitted) model;
the two must stay independent or their errors would cancel (``docs/architecture.md``, "The
layers").

Frames
------
Robot frame: x forward, y left, z up, origin on the floor under the turning centre. The camera
pinhole sits at ``(0, 0, camera_height_m)`` looking straight up. Camera axes: ``x_cam = +y``
(image u to the right is the robot's left: a mirror view), ``y_cam = -x`` (image v down is the
robot's back, so forward is up in the raw image), ``z_cam = +z``.

The mirror is a sphere of radius ``mirror_radius_m`` whose lowest point (vertex) is
``mirror_distance_m`` above the pinhole, plus a decentre. It is a cap: only points within
``mirror_rim_radius_m`` of the mirror axis reflect; the rim is the cap's edge. Tilt rotates the
mirror about its vertex (its mount), moving the sphere centre sideways and tilting the rim.

Two independent calculations:

* :func:`trace_pixels` (pixel -> floor): undistort, intersect the ray with the sphere, reflect,
  intersect the floor, and mark pixels that miss the mirror, see the sky, or land on the robot.
* :func:`project_floor_points` (floor -> pixel): solve the reflection point on the sphere
  (Alhazen's problem, in the plane of pinhole, sphere centre and floor point) by bisection, then
  project it with the distortion model.
"""

from __future__ import annotations

import hashlib
import io
import os
import platform
from dataclasses import asdict, dataclass, replace
from functools import lru_cache
from pathlib import Path

import numba
import numpy as np

from stcvision.errors import BadInputError
from stcvision.limits import MAX_CAMERA_SIDE_PX

__all__ = [
    "FloorProjector",
    "MirrorCameraParams",
    "RayTable",
    "mirror_geometry",
    "project_floor_points",
    "rim_points_px",
    "trace_pixels",
]


@dataclass(frozen=True, kw_only=True, slots=True)
class MirrorCameraParams:
    """Geometry of the camera, the mirror and the robot body (metres, pixels, radians).

    Defaults describe the default simulated robot: a VGA webcam (6 um pixels, 4.7 mm lens,
    f/2.0; ~44 degree horizontal field) 15 cm above the floor, under a 62 mm wide spherical
    mirror (radius 6 cm) 10 cm above the lens. The mirror fills most of the frame (rim ~225 px)
    and shows the floor out to ~1.3 m, enough for the five cells around the robot.
    """

    width_px: int = 640
    height_px: int = 480
    focal_px: float = 786.0
    principal_px: tuple[float, float] = (319.5, 239.5)
    k1: float = -0.05
    k2: float = 0.0
    camera_height_m: float = 0.15
    mirror_radius_m: float = 0.06
    mirror_distance_m: float = 0.10
    mirror_rim_radius_m: float = 0.031
    mirror_decentre_m: tuple[float, float] = (0.0, 0.0)
    mirror_tilt_rad: float = 0.0
    mirror_tilt_axis_rad: float = 0.0
    body_radius_m: float = 0.065
    body_height_m: float = 0.05
    housing_radius_m: float = 0.02

    def __post_init__(self) -> None:
        positive = (
            "width_px",
            "height_px",
            "focal_px",
            "camera_height_m",
            "mirror_radius_m",
            "mirror_distance_m",
            "mirror_rim_radius_m",
        )
        for name in positive:
            if not getattr(self, name) > 0:
                raise BadInputError(f"camera parameter {name} must be > 0, got {getattr(self, name)}")
        if self.width_px > MAX_CAMERA_SIDE_PX or self.height_px > MAX_CAMERA_SIDE_PX:
            raise BadInputError(
                f"camera image {self.width_px}x{self.height_px} px is over the cap of {MAX_CAMERA_SIDE_PX} px a side "
                "(a frame's float buffers would not fit in memory); expected a webcam-sized sensor"
            )
        if self.mirror_rim_radius_m >= self.mirror_radius_m:
            raise BadInputError(
                f"mirror_rim_radius_m ({self.mirror_rim_radius_m}) must be < mirror_radius_m ({self.mirror_radius_m})"
            )
        if abs(self.mirror_tilt_rad) > np.radians(15):
            raise BadInputError(f"mirror_tilt_rad {self.mirror_tilt_rad} is beyond +-15 degrees")

    def to_dict(self) -> dict:
        d = asdict(self)
        return {k: list(v) if isinstance(v, tuple) else v for k, v in d.items()}

    @classmethod
    def from_dict(cls, d: dict) -> MirrorCameraParams:
        names = set(cls.__dataclass_fields__)
        unknown = set(d) - names
        if unknown:
            raise BadInputError(f"unknown camera parameter(s) {sorted(unknown)}; expected some of {sorted(names)}")
        kw = {}
        for k, v in d.items():
            if isinstance(getattr(cls(), k), tuple):
                try:
                    v = tuple(float(x) for x in v)
                except (TypeError, ValueError):
                    raise BadInputError(f"camera parameter {k} must be a pair of numbers, got {v!r}") from None
                if len(v) != 2:
                    raise BadInputError(f"camera parameter {k} must be a pair of numbers, got {v!r}")
            elif not isinstance(v, int | float) or isinstance(v, bool):
                raise BadInputError(f"camera parameter {k} must be a number, got {v!r}")
            kw[k] = v
        return cls(**kw)

    def replace(self, **kw) -> MirrorCameraParams:
        return replace(self, **kw)


def mirror_geometry(p: MirrorCameraParams) -> tuple[np.ndarray, np.ndarray, float]:
    """Sphere centre (3,), mirror axis (3,) pointing up, and cos of the cap half-angle."""
    dx, dy = p.mirror_decentre_m
    vertex = np.array([dx, dy, p.camera_height_m + p.mirror_distance_m])
    t, a = p.mirror_tilt_rad, p.mirror_tilt_axis_rad
    # rotate +z by angle t about the horizontal axis (cos a, sin a, 0)
    k = np.array([np.cos(a), np.sin(a), 0.0])
    z = np.array([0.0, 0.0, 1.0])
    axis = z * np.cos(t) + np.cross(k, z) * np.sin(t)
    centre = vertex + p.mirror_radius_m * axis
    cos_cap = np.sqrt(1.0 - (p.mirror_rim_radius_m / p.mirror_radius_m) ** 2)
    return centre, axis, cos_cap


def _cam_to_robot(xc, yc, zc):
    """Camera-frame components -> robot-frame components (x = -y_cam, y = x_cam, z = z_cam)."""
    return -yc, xc, zc


def _distort(xn, yn, p: MirrorCameraParams):
    r2 = xn * xn + yn * yn
    s = 1.0 + p.k1 * r2 + p.k2 * r2 * r2
    return xn * s, yn * s


def _undistort(xd, yd, p: MirrorCameraParams, iters: int = 50):
    """Invert the radial model by fixed-point iteration (converges for the mild k1, k2 used)."""
    if p.k1 == 0.0 and p.k2 == 0.0:
        return xd, yd
    xn, yn = xd, yd
    for _ in range(iters):
        r2 = xn * xn + yn * yn
        s = 1.0 + p.k1 * r2 + p.k2 * r2 * r2
        xn_new, yn_new = xd / s, yd / s
        done = np.max(np.abs(xn_new - xn) + np.abs(yn_new - yn), initial=0.0) < 1e-13
        xn, yn = xn_new, yn_new
        if done:
            break
    return xn, yn


def _body_hit(origin, direction, p: MirrorCameraParams):
    """True where a downward ray from ``origin`` along ``direction`` hits the robot: the body's
    top disc (z = body_height_m, radius body_radius_m) or the camera housing's top
    (z = camera_height_m, radius housing_radius_m)."""
    hit = np.zeros(origin.shape[:-1], bool)
    for z_top, radius in ((p.camera_height_m, p.housing_radius_m), (p.body_height_m, p.body_radius_m)):
        s = (z_top - origin[..., 2]) / direction[..., 2]
        q = origin[..., :2] + s[..., None] * direction[..., :2]
        hit |= (s > 0) & ((q**2).sum(-1) <= radius * radius)
    return hit


@dataclass(frozen=True, eq=False)
class RayTable:
    """Per-pixel result of :func:`trace_pixels` (all arrays (H, W)).

    Attributes
    ----------
    floor_xy_m : (H, W, 2) float64
        Floor point of each pixel in the robot frame (NaN where ``~ground``).
    ground : bool
        The pixel sees the floor (hits the mirror cap, reflects down, misses the robot).
    mirror : bool
        The pixel's ray hits the mirror cap (inside the rim).
    body : bool
        The pixel sees the robot's own body or the camera housing.
    footprint_m2 : float64
        Floor area one pixel covers (from the Jacobian of ``floor_xy_m``; NaN off-ground).
    vignetting : float64
        cos^4 of the ray's angle to the optical axis.
    jacobian : (H, W, 2, 2) float64
        Floor step (m, robot frame) per pixel step; columns are d/du and d/dv.
    """

    params: MirrorCameraParams
    floor_xy_m: np.ndarray
    ground: np.ndarray
    mirror: np.ndarray
    body: np.ndarray
    footprint_m2: np.ndarray
    vignetting: np.ndarray
    jacobian: np.ndarray


def _trace_dirs(dirs: np.ndarray, p: MirrorCameraParams, mask: bool = True):
    """Trace rays from the pinhole along ``dirs`` (..., 3, robot frame, unit)."""
    centre, axis, cos_cap = mirror_geometry(p)
    origin = np.array([0.0, 0.0, p.camera_height_m])
    oc = origin - centre
    b = dirs @ oc
    c = oc @ oc - p.mirror_radius_m**2
    disc = b * b - c
    t = -b - np.sqrt(np.maximum(disc, 0.0))
    hit = origin + t[..., None] * dirs
    n = (hit - centre) / p.mirror_radius_m
    in_cap = (disc > 0) & (t > 0) & ((n @ -axis) >= cos_cap)
    refl = dirs - 2.0 * (dirs * n).sum(-1, keepdims=True) * n
    down = refl[..., 2] < -1e-9
    s = np.where(down, -hit[..., 2] / np.where(down, refl[..., 2], -1.0), np.nan)
    floor = hit[..., :2] + s[..., None] * refl[..., :2]
    body = in_cap & down & _body_hit(hit, refl, p)
    ground = in_cap & down & ~body
    if not mask:  # the sphere's geometry continues past the rim: used for finite differences
        return floor, ground, in_cap, body
    floor[~ground] = np.nan
    return floor, ground, in_cap, body


def trace_pixels(p: MirrorCameraParams) -> RayTable:
    """Trace every pixel centre of the image onto the floor (done once per camera)."""
    u, v = np.meshgrid(np.arange(p.width_px, dtype=float), np.arange(p.height_px, dtype=float))
    cx, cy = p.principal_px
    xn, yn = _undistort((u - cx) / p.focal_px, (v - cy) / p.focal_px, p)
    x, y, z = _cam_to_robot(xn, yn, np.ones_like(xn))
    dirs = np.stack([x, y, z], -1)
    norm = np.linalg.norm(dirs, axis=-1, keepdims=True)
    dirs /= norm
    floor, ground, mirror, body = _trace_dirs(dirs, p)
    vignetting = (1.0 / norm[..., 0]) ** 4
    # footprint: |det J| of (u, v) -> floor, by central differences of half-pixel offsets
    fu, fv = _footprint_steps(p, u, v)
    jac = np.stack([fu, fv], axis=-1)
    jac[~ground] = np.nan
    footprint = np.abs(fu[..., 0] * fv[..., 1] - fu[..., 1] * fv[..., 0])
    footprint[~ground] = np.nan
    return RayTable(p, floor, ground, mirror, body, footprint, vignetting, jac)


#: cameras whose geometry :func:`camera_geometry` keeps in memory: a table and its projector
#: are ~45 MB for a 640 x 480 image, and a process rarely uses more than two optics at once
GEOMETRY_CACHE_SIZE = 4
#: ... and on disk (~22 MB each at 640 x 480): the least recently used beyond these are removed
GEOMETRY_FILES_KEPT = 8
#: where the geometry files go; None: ``__pycache__`` beside this module, where numba keeps the
#: compiled kernels (nothing is kept where that folder cannot be written)
GEOMETRY_DIR: Path | None = None
_TABLE_ARRAYS = ("floor_xy_m", "ground", "mirror", "body", "footprint_m2", "vignetting", "jacobian")


@lru_cache(maxsize=GEOMETRY_CACHE_SIZE)
def camera_geometry(p: MirrorCameraParams) -> tuple[RayTable, FloorProjector]:
    """The ray table of ``p`` and its :class:`FloorProjector`, made once per optics: tracing and
    the projector's lookup grid take ~0.9 s, and every simulated camera with the same optics (each
    tour of a sweep, each command a user runs, each camera of a test) would make the same ones
    again. Kept in memory for the process and in a file for the next process (the arrays as
    computed, so a camera renders the same frames either way), under a key of the optics, this
    module's source, numpy's and scipy's versions and the processor: a change to any of them
    traces again.
    Read only: every array is shared by the cameras that asked for it."""
    path = _geometry_path(p)
    kept = _load_geometry(path, p) if path is not None else None
    if kept is None:
        table = trace_pixels(p)
        projector = FloorProjector(table)
        if path is not None:
            _save_geometry(path, table, projector)
    else:
        table, projector = kept
    for name in _TABLE_ARRAYS:
        getattr(table, name).setflags(write=False)
    return table, projector


def _key_value(v):
    """A field of the optics as its key writes it: numbers by their float64 bits (786 and 786.0,
    ``np.float64(0.06)`` and 0.06 are the same optics), sequences element by element."""
    if isinstance(v, (bool, int, float, np.integer, np.floating)):
        return float(v).hex()
    if isinstance(v, (tuple, list, np.ndarray)):
        return [_key_value(x) for x in v]
    return repr(v)


#: this module's source as the process loaded it: a file edited while a process runs must not
#: key that process's tables, traced with the old code, as the new code's
_SOURCE_DIGEST = hashlib.sha256(Path(__file__).read_bytes()).hexdigest()


def _geometry_path(p: MirrorCameraParams) -> Path | None:
    """The file of ``p``'s geometry, or None where none can be kept. The key holds what the arrays
    depend on beyond the optics: this module's code, numpy's and scipy's versions (the lookup
    grid's nearest-cell ties are scipy's) and the processor, by name and features as numba keys
    its own cache (numpy takes other SIMD paths on other processors, and their last bits differ)."""
    import scipy
    from llvmlite import binding

    folder = GEOMETRY_DIR if GEOMETRY_DIR is not None else Path(__file__).resolve().parent / "__pycache__"
    try:
        folder.mkdir(exist_ok=True)
    except OSError:
        return None
    if not os.access(folder, os.W_OK):
        return None
    fields = sorted((k, _key_value(v)) for k, v in asdict(p).items())
    cpu = (binding.get_host_cpu_name(), binding.get_host_cpu_features().flatten())
    key = hashlib.sha256()
    for part in (repr(fields), _SOURCE_DIGEST, np.__version__, scipy.__version__, platform.machine(), repr(cpu)):
        key.update(part.encode() + b"\0")
    return folder / f"raytable-{key.hexdigest()[:32]}.npz"


def _load_geometry(path: Path, p: MirrorCameraParams) -> tuple[RayTable, FloorProjector] | None:
    """The table and projector kept in ``path``, or None if there is none or it is not whole (a
    file cut short, from another writer, of other shapes: traced again)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {name: z[name] for name in (*_TABLE_ARRAYS, "guess")}
    except Exception:  # any file that does not read back as written is traced again
        return None
    try:
        os.utime(path)  # recently used: trimmed last (a file another user owns is still read)
    except OSError:
        pass
    h, w = p.height_px, p.width_px
    shapes = {"floor_xy_m": (h, w, 2), "jacobian": (h, w, 2, 2)}
    for name in _TABLE_ARRAYS:
        want = np.dtype(bool) if name in ("ground", "mirror", "body") else np.dtype(np.float64)
        if arrays[name].shape != shapes.get(name, (h, w)) or arrays[name].dtype != want:
            return None
    guess = arrays.pop("guess")
    table = RayTable(p, **arrays)
    try:
        return table, FloorProjector(table, guess=guess)
    except ValueError:  # a lookup grid not of this table's shape
        return None


def _save_geometry(path: Path, table: RayTable, projector: FloorProjector) -> None:
    """Write the table and the lookup grid to ``path`` (atomically: a reader sees the whole file
    or none), then remove the least recently used files beyond :data:`GEOMETRY_FILES_KEPT`. A
    file that cannot be written leaves the run as it was: it only costs the next one the trace."""
    from stcvision.errors import OutputError
    from stcvision.fileio import write_bytes_atomic

    buf = io.BytesIO()
    np.savez(buf, **{name: getattr(table, name) for name in _TABLE_ARRAYS}, guess=projector.guess)
    try:
        write_bytes_atomic(path, buf.getvalue(), overwrite=True)
        files = sorted(path.parent.glob("raytable-*.npz"), key=lambda f: f.stat().st_mtime, reverse=True)
        for old in files[GEOMETRY_FILES_KEPT:]:
            old.unlink(missing_ok=True)
    except (OSError, OutputError):
        return


def _footprint_steps(p: MirrorCameraParams, u=None, v=None):
    """Floor step (robot frame, m) per one-pixel step along u and along v, per pixel."""
    if u is None:
        u, v = np.meshgrid(np.arange(p.width_px, dtype=float), np.arange(p.height_px, dtype=float))
    cx, cy = p.principal_px

    def floor_at(du, dv):
        xn, yn = _undistort((u + du - cx) / p.focal_px, (v + dv - cy) / p.focal_px, p)
        x, y, z = _cam_to_robot(xn, yn, np.ones_like(xn))
        d = np.stack([x, y, z], -1)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        return _trace_dirs(d, p, mask=False)[0]

    fu = floor_at(0.5, 0) - floor_at(-0.5, 0)  # floor step per pixel along u
    fv = floor_at(0, 0.5) - floor_at(0, -0.5)  # ... and along v
    return fu, fv


def project_floor_points(p: MirrorCameraParams, xy_m, *, iters: int = 60):
    """Image position of floor points (robot frame) via the reflection point on the sphere.

    Parameters
    ----------
    xy_m : (N, 2) floor points in the robot frame (m).

    Returns
    -------
    uv_px : (N, 2) float64
        Sub-pixel image positions (u right, v down); NaN where not visible.
    visible : (N,) bool
        The reflection lies on the mirror cap, the path misses the robot, and the pixel is inside
        the image.
    """
    xy = np.asarray(xy_m, float).reshape(-1, 2)
    centre, axis, cos_cap = mirror_geometry(p)
    R = p.mirror_radius_m
    O = np.array([0.0, 0.0, p.camera_height_m])
    F = np.column_stack([xy, np.zeros(len(xy))])
    # orthonormal basis of the plane through O, C, F: e1 = unit(O - C) (towards the camera),
    # e2 = component of (F - C) perpendicular to e1.
    e1 = (O - centre) / np.linalg.norm(O - centre)
    w = F - centre
    e2 = w - (w @ e1)[:, None] * e1
    n2 = np.linalg.norm(e2, axis=1, keepdims=True)
    degenerate = n2[:, 0] < 1e-12
    e2 = np.where(degenerate[:, None], np.array([1.0, 0.0, 0.0]), e2 / np.maximum(n2, 1e-300))
    # P(phi) = C + R (cos phi e1 + sin phi e2); reflection at P requires the unit vectors to O
    # and to F to make equal angles with the normal: g(phi) = (uO + uF) . tangent = 0.
    lo = np.zeros(len(xy))
    hi = np.full(len(xy), np.pi / 2)

    def g(phi):
        P = centre + R * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
        n = (P - centre) / R
        tang = -np.sin(phi)[:, None] * e1 + np.cos(phi)[:, None] * e2
        uo = O - P
        uo /= np.linalg.norm(uo, axis=1, keepdims=True)
        uf = F - P
        uf /= np.linalg.norm(uf, axis=1, keepdims=True)
        return ((uo + uf) * tang).sum(1), P, n, uo, uf

    # At phi = 0 (P straight towards the camera) uO is the normal and uF leans towards +e2, so
    # g > 0; towards the sphere's equator g < 0. One sign change in (0, pi/2): bisection.
    g_lo = g(lo)[0]
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        gm = g(mid)[0]
        same = np.sign(gm) == np.sign(g_lo)
        lo = np.where(same, mid, lo)
        g_lo = np.where(same, gm, g_lo)
        hi = np.where(same, hi, mid)
    phi = 0.5 * (lo + hi)
    gv, P, n, uo, uf = g(phi)
    ok = np.abs(gv) < 1e-6
    ok &= (n @ -axis) >= cos_cap
    ok &= (uo * n).sum(1) > 0  # camera and floor on the mirror's outer side
    ok &= (uf * n).sum(1) > 0
    # path from P down to F must miss the robot
    ok &= ~_body_hit(P, F - P, p)
    # project P into the camera
    rel = P - O
    xc, yc, zc = rel[:, 1], -rel[:, 0], rel[:, 2]
    xd, yd = _distort(xc / zc, yc / zc, p)
    cx, cy = p.principal_px
    uv = np.column_stack([p.focal_px * xd + cx, p.focal_px * yd + cy])
    ok &= (uv[:, 0] >= -0.5) & (uv[:, 0] <= p.width_px - 0.5)
    ok &= (uv[:, 1] >= -0.5) & (uv[:, 1] <= p.height_px - 0.5)
    uv[~ok] = np.nan
    return uv, ok


def rim_points_px(p: MirrorCameraParams, n: int = 360) -> np.ndarray:
    """(n, 2) image positions of the mirror rim (a circle, an ellipse under tilt)."""
    centre, axis, cos_cap = mirror_geometry(p)
    R = p.mirror_radius_m
    # orthonormal pair perpendicular to the axis
    a = np.array([1.0, 0.0, 0.0])
    b1 = a - (a @ axis) * axis
    b1 /= np.linalg.norm(b1)
    b2 = np.cross(axis, b1)
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    sin_cap = p.mirror_rim_radius_m / R
    pts = centre - R * cos_cap * axis + R * sin_cap * (np.cos(ang)[:, None] * b1 + np.sin(ang)[:, None] * b2)
    rel = pts - np.array([0.0, 0.0, p.camera_height_m])
    xc, yc, zc = rel[:, 1], -rel[:, 0], rel[:, 2]
    xd, yd = _distort(xc / zc, yc / zc, p)
    cx, cy = p.principal_px
    return np.column_stack([p.focal_px * xd + cx, p.focal_px * yd + cy])


def _trace_constants(p: MirrorCameraParams) -> np.ndarray:
    """The scalars :func:`_trace_uv_nb` needs, in its order (see there)."""
    centre, axis, cos_cap = mirror_geometry(p)
    oc = np.array([0.0, 0.0, p.camera_height_m]) - centre
    c = oc @ oc - p.mirror_radius_m**2
    return np.array(
        [
            *p.principal_px,
            p.focal_px,
            p.k1,
            p.k2,
            p.camera_height_m,
            *centre,
            *axis,
            cos_cap,
            p.mirror_radius_m,
            c,
            p.housing_radius_m,
            p.body_height_m,
            p.body_radius_m,
        ]
    )


@numba.njit(cache=True, nogil=True)
def _trace_uv_nb(u, v, k):
    """Floor point (robot frame; NaN if the ray does not go down) and ground flag of one
    continuous pixel position: the pixel trace of :func:`trace_pixels` (undistort, pinhole ray,
    sphere, reflection, floor, robot body) for a single ray. ``k``: :func:`_trace_constants`."""
    cx, cy, f, k1, k2, h = k[0], k[1], k[2], k[3], k[4], k[5]
    c0, c1, c2, a0, a1, a2 = k[6], k[7], k[8], k[9], k[10], k[11]
    cos_cap, R, c = k[12], k[13], k[14]
    xd, yd = (u - cx) / f, (v - cy) / f
    xn, yn = xd, yd
    if k1 != 0.0 or k2 != 0.0:  # the radial model inverted by fixed-point iteration
        for _ in range(50):
            r2 = xn * xn + yn * yn
            inv_s = 1.0 / (1.0 + k1 * r2 + k2 * r2 * r2)
            xn_new, yn_new = xd * inv_s, yd * inv_s
            done = abs(xn_new - xn) + abs(yn_new - yn) < 1e-13
            xn, yn = xn_new, yn_new
            if done:
                break
    x, y = -yn, xn  # camera frame -> robot frame, z = 1
    dz = 1.0 / np.sqrt(x * x + y * y + 1.0)
    dx, dy = x * dz, y * dz
    b = dx * (0.0 - c0) + dy * (0.0 - c1) + dz * (h - c2)
    disc = b * b - c
    t = -b - np.sqrt(max(disc, 0.0))
    hx, hy, hz = t * dx, t * dy, h + t * dz
    inv_r = 1.0 / R
    nx, ny, nz = (hx - c0) * inv_r, (hy - c1) * inv_r, (hz - c2) * inv_r
    in_cap = disc > 0 and t > 0 and (nx * -a0 + ny * -a1 + nz * -a2) >= cos_cap
    dn = dx * nx + dy * ny + dz * nz
    rx, ry, rz = dx - 2.0 * dn * nx, dy - 2.0 * dn * ny, dz - 2.0 * dn * nz
    if not rz < -1e-9:
        return np.nan, np.nan, False
    inv_rz = 1.0 / rz
    s = -hz * inv_rz
    fx, fy = hx + s * rx, hy + s * ry
    if not in_cap:
        return fx, fy, False
    for z_top, radius in ((h, k[15]), (k[16], k[17])):  # camera housing, robot body top
        s = (z_top - hz) * inv_rz
        qx, qy = hx + s * rx, hy + s * ry
        if s > 0 and qx * qx + qy * qy <= radius * radius:
            return fx, fy, False
    return fx, fy, True


@numba.njit(cache=True, nogil=True)
def _nearest_pixel(u, v, h, w):
    return min(max(int(np.rint(v)), 0), h - 1), min(max(int(np.rint(u)), 0), w - 1)


@numba.njit(cache=True, nogil=True)
def _newton_step_nb(u, v, px, py, a, b, c, d, k):
    """(u, v) after one Newton step towards floor point (px, py) with the Jacobian
    [[a, b], [c, d]] (the identity where it is not finite), the step clipped to +-20 px."""
    if not (np.isfinite(a) and np.isfinite(b) and np.isfinite(c) and np.isfinite(d)):
        a, b, c, d = 1.0, 0.0, 0.0, 1.0
    fx, fy, _ = _trace_uv_nb(u, v, k)
    ex, ey = px - fx, py - fy
    # solve [[a, b], [c, d]] (du, dv) = (ex, ey): LU with partial pivoting
    if abs(c) > abs(a):
        a, b, c, d, ex, ey = c, d, a, b, ey, ex
    low = c / a
    dv = (ey - low * ex) / (d - low * b)
    du = (ex - b * dv) / a
    u += min(max(du, -20.0), 20.0) if np.isfinite(du) else 0.0
    v += min(max(dv, -20.0), 20.0) if np.isfinite(dv) else 0.0
    return u, v


@numba.njit(cache=True, nogil=True)
def _project_nb(pts, max_radius, guess, origin, cell, pixels, k, iters, uv, ok):
    """Newton's method per floor point ``pts[m]`` not beyond ``max_radius`` (the others are not
    visible: ``ok`` False, ``uv`` left as it is) from the lookup grid's pixel: ``iters`` steps
    with the pixel->floor Jacobian of the pixel nearest the current guess, then one more trace
    to accept the result (on the ground, within 50 um of the point, a ground pixel, inside the
    image). ``guess``: the lookup grid (n, n, 2); ``pixels``: :attr:`FloorProjector.pixels`.
    The points go in lockstep, table reads apart from the ray traces, so that the reads of
    many points (cache misses: the tables are megabytes) overlap instead of waiting in turn."""
    h, w = pixels.shape[0], pixels.shape[1]
    n = guess.shape[0]
    near = np.empty(pts.shape[0], np.int64)
    cnt = 0
    for m in range(pts.shape[0]):
        ok[m] = False
        if np.hypot(pts[m, 0], pts[m, 1]) <= max_radius:
            near[cnt] = m
            cnt += 1
    u, v, rec = np.empty(cnt), np.empty(cnt), np.empty((cnt, 4))
    for q in range(cnt):
        m = near[q]
        i = min(max(int(np.floor((pts[m, 0] - origin) / cell)), 0), n - 1)
        j = min(max(int(np.floor((pts[m, 1] - origin) / cell)), 0), n - 1)
        u[q], v[q] = guess[j, i, 0], guess[j, i, 1]
    for _ in range(iters):
        for q in range(cnt):
            iv, iu = _nearest_pixel(u[q], v[q], h, w)
            rec[q, 0], rec[q, 1], rec[q, 2], rec[q, 3] = (
                pixels[iv, iu, 0],
                pixels[iv, iu, 1],
                pixels[iv, iu, 2],
                pixels[iv, iu, 3],
            )
        for q in range(cnt):
            m = near[q]
            u[q], v[q] = _newton_step_nb(
                u[q], v[q], pts[m, 0], pts[m, 1], rec[q, 0], rec[q, 1], rec[q, 2], rec[q, 3], k
            )
    for q in range(cnt):
        m = near[q]
        fx, fy, on_ground = _trace_uv_nb(u[q], v[q], k)
        rec[q, 0] = np.hypot(fx - pts[m, 0], fy - pts[m, 1]) if on_ground else np.inf
    for q in range(cnt):
        m = near[q]
        iv, iu = _nearest_pixel(u[q], v[q], h, w)
        good = rec[q, 0] < 5e-5 and pixels[iv, iu, 4] != 0.0
        good = good and -0.5 <= u[q] <= w - 0.5 and -0.5 <= v[q] <= h - 0.5
        ok[m] = good
        if good:
            uv[m, 0], uv[m, 1] = u[q], v[q]


def _aligned_empty(shape, align: int = 64) -> np.ndarray:
    """An uninitialised float64 array whose data starts on an ``align``-byte boundary."""
    n = int(np.prod(shape))
    buf = np.empty(n + align // 8, np.float64)
    skip = (-buf.ctypes.data % align) // 8
    return buf[skip : skip + n].reshape(shape)


def _lookup_grid(table: RayTable, xy: np.ndarray, origin: float, cell_m: float, n: int) -> np.ndarray:
    """:attr:`FloorProjector.guess` of ``table``: ``xy`` its ground pixels' floor points, the
    grid's ``n`` x ``n`` cells of ``cell_m`` from ``origin`` (both axes)."""
    from scipy import ndimage

    ij = np.floor((xy - origin) / cell_m).astype(int)
    v, u = np.nonzero(table.ground)
    flat = ij[:, 1] * n + ij[:, 0]
    cnt = np.bincount(flat, minlength=n * n).astype(float)
    su = np.bincount(flat, weights=u, minlength=n * n)
    sv = np.bincount(flat, weights=v, minlength=n * n)
    filled = cnt > 0
    gu = np.where(filled, su / np.maximum(cnt, 1), 0).reshape(n, n)
    gv = np.where(filled, sv / np.maximum(cnt, 1), 0).reshape(n, n)
    _, (ii, jj) = ndimage.distance_transform_edt(~filled.reshape(n, n), return_indices=True)
    return np.stack([gu[ii, jj], gv[ii, jj]], axis=-1)


class FloorProjector:
    """Fast floor -> pixel projection for rendering, built once from a :class:`RayTable`.

    An inverse lookup grid (floor cell -> mean pixel of the rays landing there, holes filled
    from the nearest filled cell) gives a first guess; two Newton steps on the exact pixel ray
    trace, with the table's Jacobian, refine it to far below 0.01 px. Agrees with the
    independent :func:`project_floor_points` (checked in the tests). Points beyond the farthest
    floor point any pixel sees are not visible and are not solved; the rest are solved one by
    one in a compiled loop (:func:`_project_nb`), so a point's position does not depend on which
    other points share the call.
    """

    def __init__(self, table: RayTable, *, cell_m: float = 0.01, guess: np.ndarray | None = None) -> None:
        """``guess``: the lookup grid (:attr:`guess`) of an earlier projector of the same table
        and ``cell_m``, which is then not built again (it is most of the set-up's time)."""
        self.table = table
        g = table.ground
        xy = table.floor_xy_m[g]
        self.max_radius_m = float(np.hypot(xy[:, 0], xy[:, 1]).max())
        r = self.max_radius_m + cell_m
        n = int(np.ceil(2 * r / cell_m))
        self._origin, self._cell, self._n = -r, cell_m, n
        if guess is None:
            guess = _lookup_grid(table, xy, -r, cell_m, n)
        elif guess.shape != (n, n, 2) or guess.dtype != np.float64:
            raise ValueError(f"a lookup grid of shape {guess.shape} for a table that needs {(n, n, 2)}")
        #: (n, n, 2) float64: the mean pixel (u, v) of the rays landing in each floor cell, holes
        #: filled from the nearest filled cell: the first guess of a projection
        self.guess = np.ascontiguousarray(guess)
        self._k = _trace_constants(table.params)
        #: (H, W, 8) float64, one 64-byte record per pixel (a cache line: a projected point's
        #: lookups cost one memory access, not one per table): the pixel->floor Jacobian
        #: (fields 0-3, row-major), ground (4: 1.0 or 0.0), footprint (5, m^2), vignetting (6)
        #: of the ray table, copied as they are.
        self.pixels = _aligned_empty((*g.shape, 8))
        self.pixels[..., :4] = table.jacobian.reshape(*g.shape, 4)
        self.pixels[..., 4] = g
        self.pixels[..., 5] = table.footprint_m2
        self.pixels[..., 6] = table.vignetting
        self.pixels[..., 7] = 0.0
        self.pixels.setflags(write=False)

    def project(self, xy_m, *, iters: int = 2):
        """(N, 2) robot-frame floor points -> ((N, 2) sub-pixel (u, v), (N,) visible)."""
        xy = np.ascontiguousarray(np.asarray(xy_m, float).reshape(-1, 2))
        uv = np.full((len(xy), 2), np.nan)
        vis = np.empty(len(xy), bool)
        _project_nb(
            xy,
            self.max_radius_m,
            self.guess,
            float(self._origin),
            float(self._cell),
            self.pixels,
            self._k,
            int(iters),
            uv,
            vis,
        )
        return uv, vis
