"""Calibration profiles: the pipeline's model of one robot's camera and mirror.

A profile is versioned JSON with unit-suffixed keys and provenance. Its mirror model is the
pipeline's own -- a *central radial* model fitted by calibration, deliberately not the
renderer's ray-traced spherical mirror -- and it says:

* where the mirror's axis is in the image (``center_px``), the rim (``rim_radius_px``), and the
  rim's ellipticity under a tilted mirror (``ellipse_ratio``, ``ellipse_angle_rad``);
* azimuth ``phi``: robot-forward appears at image angle ``forward_angle_rad``
  (``atan2(v - cv, u - cu)``); ``mirrored`` says the image is a mirror view (robot-left appears
  clockwise of forward, as when looking up into a mirror);
* elevation ``theta``: the depression angle below the horizon, seen from an effective viewpoint
  ``viewpoint_height_m`` above the floor, as a polynomial of the normalised image radius
  ``r / rim_radius_px`` (``theta_poly``, ascending powers). A floor point at distance ``rho``
  from the robot has ``theta = atan2(viewpoint_height_m, rho)`` (the ant-like STC
  paper, "Image Transformation and Filtering": the pixel moves along the axis through the lens
  centre; phi and theta give how far);
* the mirror axis may lean against the floor's normal (a decentred or tilted mirror):
  ``axis_tilt_rad`` = (tilt about the robot's x axis, tilt about its y axis); the rays are
  built in the axis frame and rotated into the floor frame before meeting the floor;
* a non-radial part for imported lens models (Brown's decentering distortion, as in the
  radial-tangential models of Kalibr and OpenCV): ``decentering`` = (p1, p2[, g1, g2, g3]); the
  image point of the radial model's point ``(x, y)`` (ellipse-corrected, in units of the rim
  radius, r^2 = x^2 + y^2) is ``(x, y) + (1 + g1 r^2 + g2 r^4 + g3 r^6) (2 p1 x y + p2 (r^2 + 2
  x^2), p1 (r^2 + 2 y^2) + 2 p2 x y)``; the radial factor carries the lens's radial distortion,
  which such models apply after the tangential terms' point; zero for the toolkit's own
  calibration;
* ``rim_measured``: whether ``rim_radius_px`` is the mirror's rim as seen in a frame (false for
  a profile imported from a lens model without a frame: the radius is then the model's field of
  view, and a frame's rim is checked against the centre only);
* the ground view: top-down, centred on the robot, forward up, ``ground_px_per_m``,
  ``ground_size_px`` square;
* the board's sub-cell side ``subcell_m`` and the neighbours calibration: the 12 corners of the
  five cells (``neighbour_corners_px``, ground-view pixels, order :data:`CORNER_ORDER`);
* for a profile rescaled to another resolution of the same camera, ``pixel_scale``: its pixels
  per pixel of the camera the pipeline's pixel-scale settings (the dot window, the centroid's
  blur) were set for, which the pipeline scales them by; and ``resampling``: how its frames are
  made from that camera's -- ``"none"`` (the camera's own mode: independent pixel noise),
  ``"area"`` (area-averaged, as ``cv2.INTER_AREA`` or binning) or ``"linear"`` (interpolated up,
  as ``cv2.INTER_LINEAR``) -- which says what the resizing did to the noise the dot threshold
  models.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from stcvision.errors import ProfileError
from stcvision.stc_geometry import DEFAULT_SUBCELL_M

__all__ = ["CORNER_ORDER", "PIXEL_SCALE_RANGE", "RESAMPLINGS", "SCHEMA_VERSION", "Profile", "nominal_corners_px"]

SCHEMA_VERSION = 1
MODEL = "radial_central"
#: the decentering coefficients a profile may hold (|p1|, |p2|): real lenses have ~1e-3; at 0.02
#: the image moves by up to 6 % of the radius, where the inverse's fixed point still contracts
MAX_DECENTERING = 0.02
#: ... and its radial factor's coefficients: a lens's radial distortion changes the factor by tens
#: of per cent at the rim; beyond this the product could outgrow the bound above
MAX_DECENTERING_RADIAL = 5.0
#: how a rescaled profile's frames may be made from the calibrated camera's (:class:`Profile`)
RESAMPLINGS = ("none", "area", "linear")
#: the pixel scales a profile may carry: from a quarter to four times the calibrated resolution
#: (outside it the dot window would be under a pixel or the dot search's scales would not fit)
PIXEL_SCALE_RANGE = (0.25, 4.0)
#: fixed-point iterations of the decentering's inverse: the error shrinks by ~6 |p| each, to below
#: 1e-12 px from |p| = 0.02 in 20
DECENTER_ITERATIONS = 20

#: The 12 corners of the plus-shaped union of the current cell and its four neighbours, in the
#: entry frame, in units of the sub-cell side D relative to the current cell's centre
#: ((right, up); the robot stands in sub-cell 0 at (0.5, -0.5)). Counter-clockwise from the
#: current cell's lower-right corner. Corners 0, 3, 6 and 9 are the current cell's.
CORNER_ORDER = (
    (1, -1),
    (3, -1),
    (3, 1),
    (1, 1),
    (1, 3),
    (-1, 3),
    (-1, 1),
    (-3, 1),
    (-3, -1),
    (-1, -1),
    (-1, -3),
    (1, -3),
)
#: The robot's turning centre in the same units (centre of sub-cell 0).
ROBOT_IN_CELL = (0.5, -0.5)


def nominal_corners_px(subcell_m: float, px_per_m: float, size_px: int) -> np.ndarray:
    """Return where the 12 corners fall in an ideal ground view.

    The robot stands exactly at the centre of sub-cell 0, heading exactly up.
    """
    c = (size_px - 1) / 2.0
    pts = []
    for r, u in CORNER_ORDER:
        right_m = (r - ROBOT_IN_CELL[0]) * subcell_m
        fwd_m = (u - ROBOT_IN_CELL[1]) * subcell_m
        pts.append((c + right_m * px_per_m, c - fwd_m * px_per_m))
    return np.array(pts)


def _num(d: dict, key: str, *, positive: bool = False, where: str = "profile") -> float:
    if key not in d:
        raise ProfileError(f"{where} is missing field {key!r}")
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise ProfileError(f"{where} field {key!r} must be a finite number, got {v!r}")
    if positive and v <= 0:
        raise ProfileError(f"{where} field {key!r} must be > 0, got {v!r}")
    return float(v)


def _vec(d: dict, key: str, n: int | None, *, where: str = "profile") -> list[float]:
    if key not in d:
        raise ProfileError(f"{where} is missing field {key!r}")
    v = d[key]
    if not isinstance(v, list) or (n is not None and len(v) != n):
        raise ProfileError(f"{where} field {key!r} must be a list of {n or 'some'} numbers, got {v!r}")
    for x in v:
        if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
            raise ProfileError(f"{where} field {key!r} must hold finite numbers, got {x!r}")
    return [float(x) for x in v]


@dataclass(frozen=True, kw_only=True)
class Profile:
    """A calibration profile: the pipeline's model of one robot's camera and mirror.

    The module docstring tells each part of the model at length.

    Attributes
    ----------
    image_size_px : tuple of int
        (width, height) of the frames the profile was calibrated for.
    center_px : tuple of float
        Where the mirror's axis is in the image (u, v).
    rim_radius_px : float
        The mirror's rim radius (the model's field of view when ``rim_measured`` is false).
    forward_angle_rad : float
        The image angle ``atan2(v - cv, u - cu)`` at which robot-forward appears.
    mirrored : bool
        The image is a mirror view (robot-left appears clockwise of forward).
    ellipse_ratio, ellipse_angle_rad : float
        The rim's ellipticity under a tilted mirror, and the ellipse's angle.
    axis_tilt_rad : tuple of float
        The mirror axis's lean against the floor's normal: (tilt about the robot's x axis, tilt
        about its y axis).
    decentering : tuple of float
        Brown's decentering terms of an imported lens model, (p1, p2[, g1, g2, g3]); zero for
        the toolkit's own calibration.
    rim_measured : bool
        Whether ``rim_radius_px`` is the mirror's rim as seen in a frame.
    viewpoint_height_m : float
        Height of the effective viewpoint above the floor.
    theta_poly : tuple of float
        The depression angle (rad) as a polynomial of ``r / rim_radius_px``, ascending powers.
    ground_px_per_m : float
        The ground view's scale.
    ground_size_px : int
        The ground view's side (square).
    subcell_m : float
        The board's sub-cell side.
    neighbour_corners_px : tuple of (float, float), optional
        The 12 corners of the five cells in ground-view pixels, order :data:`CORNER_ORDER`
        (None: the nominal ones).
    pixel_scale : float
        This profile's pixels per pixel of the camera the pipeline's pixel-scale settings were
        set for (1 unless rescaled).
    resampling : str
        How the frames are made from that camera's: one of :data:`RESAMPLINGS`.
    provenance : dict
        Where the profile came from (the calibration's inputs and settings).
    """

    image_size_px: tuple[int, int]
    center_px: tuple[float, float]
    rim_radius_px: float
    forward_angle_rad: float = -math.pi / 2
    mirrored: bool = True
    ellipse_ratio: float = 1.0
    ellipse_angle_rad: float = 0.0
    axis_tilt_rad: tuple[float, float] = (0.0, 0.0)
    decentering: tuple[float, ...] = (0.0, 0.0)
    rim_measured: bool = True
    viewpoint_height_m: float
    theta_poly: tuple[float, ...]
    ground_px_per_m: float = 260.0
    ground_size_px: int = 300
    subcell_m: float = DEFAULT_SUBCELL_M
    neighbour_corners_px: tuple[tuple[float, float], ...] | None = None
    pixel_scale: float = 1.0
    resampling: str = "none"
    provenance: dict = field(default_factory=dict)

    # ------------------------------------------------------------------ model
    def theta_of_r(self, r_px) -> np.ndarray:
        """Depression angle (rad) of the floor point seen at image radius ``r_px``."""
        x = np.asarray(r_px, float) / self.rim_radius_px
        return np.polynomial.polynomial.polyval(x, self.theta_poly)

    def _tilt(self) -> np.ndarray:
        """Rotation from the mirror-axis frame to the floor frame."""
        ax, ay = self.axis_tilt_rad
        cx, sx, cy, sy = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay)
        rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
        ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        return ry @ rx

    def robot_to_image(self, xy_m) -> np.ndarray:
        """Map (N, 2) robot-frame floor points (x forward, y left) to (N, 2) image points (u, v).

        NaN where the model does not reach.
        """
        xy = np.asarray(xy_m, float).reshape(-1, 2)
        theta, psi = self._floor_to_angles(xy)
        r_tab, th_tab = self._theta_table()
        # theta decreases with r: interpolate on the reversed table
        r = np.interp(theta, th_tab[::-1], r_tab[::-1], left=np.nan, right=np.nan)
        sign = 1.0 if self.mirrored else -1.0
        a = self.forward_angle_rad + sign * psi
        d = np.column_stack([r * np.cos(a), r * np.sin(a)])
        if any(self.decentering):
            d = self._decenter(d)
        return self._ellipse(d) + self.center_px

    def _floor_to_angles(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Depression angle and azimuth (axis frame) of floor points seen from the viewpoint."""
        d = np.column_stack([xy, np.full(len(xy), -self.viewpoint_height_m)])
        if self.axis_tilt_rad != (0.0, 0.0):
            d = d @ self._tilt()  # floor -> axis frame (R^T d, row vectors)
        n = np.linalg.norm(d, axis=1)
        return np.arcsin(np.clip(-d[:, 2] / n, -1, 1)), np.arctan2(d[:, 1], d[:, 0])

    def _theta_table(self, n: int = 4096) -> tuple[np.ndarray, np.ndarray]:
        """(r_px, theta) from the centre to the rim, cut where theta stops decreasing."""
        key = "_theta_tab"
        cached = self.__dict__.get(key)
        if cached is not None:
            return cached
        r = np.linspace(0.0, self.rim_radius_px, n)
        th = self.theta_of_r(r)
        dec = np.concatenate([[True], np.diff(th) < 0])
        stop = n if dec.all() else int(np.argmin(dec))
        out = (r[:stop], th[:stop])
        object.__setattr__(self, key, out)
        return out

    def image_to_robot(self, uv_px) -> np.ndarray:
        """Map (N, 2) image points to (N, 2) robot-frame floor points.

        The inverse of :meth:`robot_to_image`; NaN for rays at or above the horizon.
        """
        uv = np.asarray(uv_px, float).reshape(-1, 2)
        d2 = self._ellipse(uv - self.center_px, inverse=True)
        if any(self.decentering):
            d2 = self._undecenter(d2)
        r = np.hypot(d2[:, 0], d2[:, 1])
        a = np.arctan2(d2[:, 1], d2[:, 0])
        sign = 1.0 if self.mirrored else -1.0
        psi = sign * (a - self.forward_angle_rad)
        th = self.theta_of_r(r)
        d = np.column_stack([np.cos(th) * np.cos(psi), np.cos(th) * np.sin(psi), -np.sin(th)])
        if self.axis_tilt_rad != (0.0, 0.0):
            d = d @ self._tilt().T
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(d[:, 2] < -1e-9, self.viewpoint_height_m / -d[:, 2], np.nan)
        return d[:, :2] * t[:, None]

    def _decenter(self, q: np.ndarray) -> np.ndarray:
        """Move radial-model points (ellipse-corrected px) to where the decentering puts them.

        Brown 1966; the tangential terms of OpenCV's and Kalibr's radial-tangential model.
        """
        p1, p2, *g = self.decentering
        s = self.rim_radius_px
        x, y = q[:, 0] / s, q[:, 1] / s
        r2 = x * x + y * y
        k = s * (1.0 + np.polynomial.polynomial.polyval(r2, [0.0, *g])) if g else s
        t = np.column_stack([2 * p1 * x * y + p2 * (r2 + 2 * x * x), p1 * (r2 + 2 * y * y) + 2 * p2 * x * y])
        return q + t * (k[:, None] if g else k)

    def _undecenter(self, d: np.ndarray) -> np.ndarray:
        """Invert :meth:`_decenter` by fixed-point iteration (as OpenCV's undistortPoints).

        The terms are under a few per cent of the radius (validated), so it converges to ~1e-12 px.
        """
        q = d.copy()
        for _ in range(DECENTER_ITERATIONS):
            q = d - (self._decenter(q) - q)
        return q

    def _ellipse(self, d: np.ndarray, inverse: bool = False) -> np.ndarray:
        if self.ellipse_ratio == 1.0:
            return d
        c, s = math.cos(self.ellipse_angle_rad), math.sin(self.ellipse_angle_rad)
        rot = np.array([[c, -s], [s, c]])
        k = self.ellipse_ratio if not inverse else 1.0 / self.ellipse_ratio
        m = rot @ np.diag([1.0, k]) @ rot.T
        return d @ m.T

    # ------------------------------------------------------------------ ground view
    def ground_to_robot(self, gxy_px) -> np.ndarray:
        """Map ground-view pixels (x right, y down) to robot-frame metres (x forward, y left)."""
        g = np.asarray(gxy_px, float).reshape(-1, 2)
        c = (self.ground_size_px - 1) / 2.0
        out = np.empty((len(g), 2))  # (c - g) / px_per_m per column, without column_stack's copies
        np.subtract(c, g[:, 1], out=out[:, 0])
        np.subtract(c, g[:, 0], out=out[:, 1])
        out /= self.ground_px_per_m
        return out

    def robot_to_ground(self, xy_m) -> np.ndarray:
        """Map robot-frame metres (x forward, y left) to ground-view pixels (x right, y down)."""
        xy = np.asarray(xy_m, float).reshape(-1, 2)
        c = (self.ground_size_px - 1) / 2.0
        return np.column_stack([c - xy[:, 1] * self.ground_px_per_m, c - xy[:, 0] * self.ground_px_per_m])

    def corners_px(self) -> np.ndarray:
        """Return the 12 neighbour corners (ground px): calibrated if present, else nominal."""
        if self.neighbour_corners_px is not None:
            return np.asarray(self.neighbour_corners_px, float)
        return nominal_corners_px(self.subcell_m, self.ground_px_per_m, self.ground_size_px)

    # ------------------------------------------------------------------ I/O
    def to_dict(self) -> dict:
        """Return the profile as the JSON a profile file holds (with its schema version)."""
        d = asdict(self)
        d = {k: (list(v) if isinstance(v, tuple) else v) for k, v in d.items()}
        if self.neighbour_corners_px is not None:
            d["neighbour_corners_px"] = [list(p) for p in self.neighbour_corners_px]
        if self.pixel_scale == 1.0 and self.resampling == "none":  # a profile of its camera's own mode
            del d["pixel_scale"], d["resampling"]
        return {"schema_version": SCHEMA_VERSION, "model": MODEL, **d}

    @classmethod
    def from_dict(cls, d: Any, *, where: str = "profile") -> Profile:
        """Read a profile from its JSON dict, validating every field.

        A bad field raises :class:`ProfileError` naming it.
        """
        if not isinstance(d, dict):
            raise ProfileError(f"{where} must be a JSON object")
        d = _migrate(dict(d), where)
        if d.get("model") != MODEL:
            raise ProfileError(f"{where} field 'model' is {d.get('model')!r}; expected {MODEL!r}")
        size = _vec(d, "image_size_px", 2, where=where)
        if size[0] < 1 or size[1] < 1 or size[0] != int(size[0]) or size[1] != int(size[1]):
            raise ProfileError(f"{where} field 'image_size_px' must be two positive integers, got {size}")
        theta = _vec(d, "theta_poly", None, where=where)
        if not 2 <= len(theta) <= 12:
            raise ProfileError(f"{where} field 'theta_poly' must have 2..12 coefficients, got {len(theta)}")
        mirrored = d.get("mirrored", True)
        if not isinstance(mirrored, bool):
            raise ProfileError(f"{where} field 'mirrored' must be true or false, got {mirrored!r}")
        rim_measured = d.get("rim_measured", True)
        if not isinstance(rim_measured, bool):
            raise ProfileError(f"{where} field 'rim_measured' must be true or false, got {rim_measured!r}")
        dec = tuple(_vec(d, "decentering", None, where=where)) if "decentering" in d else (0.0, 0.0)
        if not 2 <= len(dec) <= 5:
            raise ProfileError(
                f"{where} field 'decentering' must have 2..5 coefficients (p1, p2, g1..g3), got {len(dec)}"
            )
        if max(abs(dec[0]), abs(dec[1])) > MAX_DECENTERING or any(abs(g) > MAX_DECENTERING_RADIAL for g in dec[2:]):
            raise ProfileError(
                f"{where} field 'decentering' must have p1, p2 within +-{MAX_DECENTERING} and g1..g3 within "
                f"+-{MAX_DECENTERING_RADIAL}, got {list(dec)}"
            )
        corners = d.get("neighbour_corners_px")
        if corners is not None:
            if not isinstance(corners, list) or len(corners) != 12:
                raise ProfileError(f"{where} field 'neighbour_corners_px' must be a list of 12 [x, y] points")
            corners = tuple(tuple(_vec({"p": p}, "p", 2, where=f"{where} neighbour_corners_px")) for p in corners)
        prov = d.get("provenance", {})
        if not isinstance(prov, dict):
            raise ProfileError(f"{where} field 'provenance' must be an object")
        known = {"schema_version", "model", *cls.__dataclass_fields__}
        unknown = set(d) - known
        if unknown:
            raise ProfileError(f"{where} has unknown field(s) {sorted(unknown)}")
        gsize = _num(d, "ground_size_px", positive=True, where=where) if "ground_size_px" in d else 300
        if gsize != int(gsize) or not 16 <= gsize <= 4096:
            raise ProfileError(f"{where} field 'ground_size_px' must be an integer in 16..4096, got {gsize}")
        ratio = _num(d, "ellipse_ratio", positive=True, where=where) if "ellipse_ratio" in d else 1.0
        if not 0.8 <= ratio <= 1.25:
            raise ProfileError(f"{where} field 'ellipse_ratio' must be in 0.8..1.25, got {ratio}")
        scale = _num(d, "pixel_scale", positive=True, where=where) if "pixel_scale" in d else 1.0
        if not PIXEL_SCALE_RANGE[0] <= scale <= PIXEL_SCALE_RANGE[1]:
            lo, hi = PIXEL_SCALE_RANGE
            raise ProfileError(f"{where} field 'pixel_scale' must be in {lo}..{hi}, got {scale}")
        resampling = d.get("resampling", "none")
        if resampling not in RESAMPLINGS:
            raise ProfileError(f"{where} field 'resampling' must be one of {list(RESAMPLINGS)}, got {resampling!r}")
        prof = cls(
            image_size_px=(int(size[0]), int(size[1])),
            center_px=tuple(_vec(d, "center_px", 2, where=where)),
            rim_radius_px=_num(d, "rim_radius_px", positive=True, where=where),
            forward_angle_rad=_num(d, "forward_angle_rad", where=where) if "forward_angle_rad" in d else -math.pi / 2,
            mirrored=mirrored,
            ellipse_ratio=ratio,
            ellipse_angle_rad=_num(d, "ellipse_angle_rad", where=where) if "ellipse_angle_rad" in d else 0.0,
            axis_tilt_rad=tuple(_vec(d, "axis_tilt_rad", 2, where=where)) if "axis_tilt_rad" in d else (0.0, 0.0),
            decentering=dec,
            rim_measured=rim_measured,
            viewpoint_height_m=_num(d, "viewpoint_height_m", positive=True, where=where),
            theta_poly=tuple(theta),
            ground_px_per_m=_num(d, "ground_px_per_m", positive=True, where=where) if "ground_px_per_m" in d else 260.0,
            ground_size_px=int(gsize),
            subcell_m=_num(d, "subcell_m", positive=True, where=where) if "subcell_m" in d else DEFAULT_SUBCELL_M,
            neighbour_corners_px=corners,
            pixel_scale=scale,
            resampling=resampling,
            provenance=prov,
        )
        if corners is not None:
            _check_corners(prof, where)
        return prof

    @classmethod
    def load(cls, path: str | Path) -> Profile:
        """Read and validate a profile file.

        Parameters
        ----------
        path : str or Path
            The profile's JSON file.

        Returns
        -------
        Profile
            The profile, every field validated.

        Raises
        ------
        BadInputError
            When the file is missing, unreadable or not JSON.
        ProfileError
            When a field is missing or invalid (the message names it), or the schema version is
            not one this toolkit reads.
        """
        from stcvision.fileio import read_json

        return cls.from_dict(read_json(path, what="profile"), where=f"profile {path}")

    def save(self, path: str | Path, *, overwrite: bool = False) -> Path:
        """Write the profile as JSON, atomically (temp file + rename).

        Parameters
        ----------
        path : str or Path
            Where to write it.
        overwrite : bool
            Replace an existing file; without it an existing file is refused.

        Returns
        -------
        Path
            The path written.

        Raises
        ------
        FileExistsRefusedError
            When ``path`` exists and ``overwrite`` is false.
        OutputError
            When the file cannot be written.
        """
        from stcvision.fileio import write_json

        return write_json(path, self.to_dict(), overwrite=overwrite)

    def replace(self, **kw) -> Profile:
        """Return a copy with some fields changed (:func:`dataclasses.replace`).

        Parameters
        ----------
        **kw
            The fields to change, by name.

        Returns
        -------
        Profile
            The new profile.
        """
        return replace(self, **kw)

    def check_frame(self, shape, *, what: str = "frame") -> None:
        """Raise if a frame's (H, W) does not match the profile's image size.

        Parameters
        ----------
        shape : tuple of int
            The frame's shape, (H, W, ...).
        what : str
            Names the image in the message (e.g. ``"dark frame d.png"``).

        Raises
        ------
        ProfileError
            When the frame's size is not the one the profile was calibrated for.
        """
        h, w = shape[:2]
        if (w, h) != tuple(self.image_size_px):
            raise ProfileError(
                f"{what} is {w}x{h} but the profile was calibrated for "
                f"{self.image_size_px[0]}x{self.image_size_px[1]}; use a profile for this camera"
            )


def _check_corners(prof: Profile, where: str) -> None:
    """Check that the 12 corners outline the five cells.

    They must make a plus shape of at least a tenth of its nominal area (found by fuzzing: 12
    coinciding or collinear corners gave no homography and a numpy error in the pipeline).
    """
    p = np.asarray(prof.neighbour_corners_px, float)
    area = 0.5 * abs(float(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1))))
    side_px = prof.subcell_m * prof.ground_px_per_m
    nominal = 20.0 * side_px * side_px  # five cells of side 2 D (inf, not OverflowError, for absurd scales)
    if not area >= 0.1 * nominal:
        raise ProfileError(
            f"{where} field 'neighbour_corners_px' outlines {area:.3g} px^2, under a tenth of the five cells' "
            f"{nominal:.3g} px^2; expected the 12 corners in the order of CORNER_ORDER (recalibrate neighbours)"
        )


def _migrate(d: dict, where: str) -> dict:
    v = d.get("schema_version")
    if v is None:
        raise ProfileError(f"{where} is missing field 'schema_version'")
    if isinstance(v, bool) or not isinstance(v, int):
        raise ProfileError(f"{where} field 'schema_version' must be an integer, got {v!r}")
    if v > SCHEMA_VERSION:
        raise ProfileError(
            f"{where} has schema_version {v}, newer than this stcvision understands "
            f"({SCHEMA_VERSION}); upgrade stcvision"
        )
    if v < 1:
        raise ProfileError(f"{where} has schema_version {v}; expected 1..{SCHEMA_VERSION}")
    return d
