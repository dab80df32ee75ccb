"""Central lens models of other calibration tools, evaluated with their own equations.

Each model maps image pixels to unit rays (:meth:`unproject`) and rays to pixels
(:meth:`project`) in one frame for all: the *image-aligned camera frame*, X along the image's u
(right), Y along v (down), Z = X x Y. For Kalibr and OpenCV that is the camera frame itself;
OCamCalib's frame (x along rows, y along columns, z out of the lens) is turned into it by a proper
rotation (X = y, Y = x, Z = -z), so handedness means the same for every model.

* :class:`OcamModel` -- Scaramuzza's OCamCalib: ``cam2world`` with the direct polynomial ``ss``
  and the affine ``[c d; e 1]`` (Scaramuzza, Martinelli, Siegwart, IROS 2006; the toolbox's
  ``ocam_functions.cpp``), ``world2cam`` with the inverse polynomial.
* :class:`CentralModel` -- a projection of Kalibr's (``pinhole``; ``omni``: Mei's unified model,
  Mei & Rives ICRA 2007, also OpenCV's ``omnidir``; ``ds``: double sphere, Usenko, Demmel & Cremers
  3DV 2018; ``eucm``: extended unified, Khomutenko, Garcia & Martinet RA-L 2016) with a distortion
  of the normalised point (``radtan``: Brown's radial-tangential as in Kalibr's
  ``RadialTangentialDistortion`` and OpenCV; ``equidistant``: Kannala-Brandt on ``atan(r)`` as in
  Kalibr's ``EquidistantDistortion``; ``fov``: Devernay & Faugeras) and the camera matrix
  (``fu, fv, pu, pv`` and OpenCV's skew ``s``).

Inverting a distortion is done to convergence (Newton's method), not with a fixed few iterations:
"the model's own equations" are the forward ones, and their exact inverse.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stcvision.errors import BadInputError

__all__ = ["CentralModel", "OcamModel", "PROJECTIONS", "DISTORTIONS"]

#: projections and the names of their parameters (besides the camera matrix), Kalibr's order
PROJECTIONS = {"pinhole": (), "omni": ("xi",), "ds": ("xi", "alpha"), "eucm": ("alpha", "beta")}
#: distortions of the normalised point and their number of coefficients
DISTORTIONS = {"none": 0, "radtan": 4, "equidistant": 4, "fov": 1}
#: Newton iterations of a distortion's inverse (quadratic convergence: ~6 reach 1e-15 from a lens
#: with k1 = -0.35; the rest is margin for strong ones)
UNDISTORT_ITERATIONS = 30


def _norm_rows(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@dataclass(frozen=True)
class OcamModel:
    """OCamCalib's model. ``ss``: direct polynomial (ascending), ``invpol``: inverse polynomial,
    ``xc``, ``yc``: centre as row, column (0-based), ``c, d, e``: affine, ``width, height``."""

    ss: tuple[float, ...]
    invpol: tuple[float, ...]
    xc: float
    yc: float
    c: float
    d: float
    e: float
    width: int
    height: int

    kind = "ocamcalib"

    @property
    def image_size_px(self) -> tuple[int, int]:
        return (self.width, self.height)

    @property
    def center_px(self) -> tuple[float, float]:
        """(u, v) = (column, row)."""
        return (self.yc, self.xc)

    def linear_part(self) -> np.ndarray:
        """2x2 matrix from the model's normalised (X, Y) to pixel (du, dv) near the centre."""
        # (drow, dcol) = [c d; e 1] (x, y) and (X, Y) = (y, x): swap rows and columns
        return np.array([[1.0, self.e], [self.d, self.c]])

    def unproject(self, uv) -> tuple[np.ndarray, np.ndarray]:
        """cam2world: pixels (N, 2) (u, v) -> unit rays (N, 3) in the image-aligned frame, valid mask."""
        uv = np.asarray(uv, float).reshape(-1, 2)
        row, col = uv[:, 1] - self.xc, uv[:, 0] - self.yc
        invdet = 1.0 / (self.c - self.d * self.e)
        xp = invdet * (row - self.d * col)
        yp = invdet * (-self.e * row + self.c * col)
        r = np.hypot(xp, yp)
        zp = np.polynomial.polynomial.polyval(r, self.ss)
        rays = _norm_rows(np.column_stack([yp, xp, -zp]))
        return rays, np.isfinite(rays).all(axis=1)

    def project(self, rays) -> np.ndarray:
        """world2cam with the inverse polynomial: unit rays (image-aligned frame) -> pixels."""
        v = np.asarray(rays, float).reshape(-1, 3)
        x, y, z = v[:, 1], v[:, 0], -v[:, 2]  # OCamCalib's own frame
        norm = np.hypot(x, y)
        theta = np.arctan(z / np.where(norm > 0, norm, np.nan))
        rho = np.polynomial.polynomial.polyval(theta, self.invpol)
        with np.errstate(invalid="ignore", divide="ignore"):
            xs, ys = np.where(norm > 0, x / norm * rho, 0.0), np.where(norm > 0, y / norm * rho, 0.0)
        row = xs * self.c + ys * self.d + self.xc
        col = xs * self.e + ys + self.yc
        return np.column_stack([col, row])


def _radtan(m: np.ndarray, k: tuple[float, ...]) -> np.ndarray:
    k1, k2, p1, p2 = k
    x, y = m[:, 0], m[:, 1]
    r2 = x * x + y * y
    rad = k1 * r2 + k2 * r2 * r2
    return np.column_stack(
        [x + x * rad + 2 * p1 * x * y + p2 * (r2 + 2 * x * x), y + y * rad + 2 * p2 * x * y + p1 * (r2 + 2 * y * y)]
    )


def _radtan_jac(m: np.ndarray, k: tuple[float, ...]) -> np.ndarray:
    k1, k2, p1, p2 = k
    x, y = m[:, 0], m[:, 1]
    r2 = x * x + y * y
    rad = 1 + k1 * r2 + k2 * r2 * r2
    drad = 2 * k1 + 4 * k2 * r2  # d(rad)/d(r2) * 2
    j = np.empty((len(m), 2, 2))
    j[:, 0, 0] = rad + x * x * drad + 2 * p1 * y + 6 * p2 * x
    j[:, 0, 1] = x * y * drad + 2 * p1 * x + 2 * p2 * y
    j[:, 1, 0] = x * y * drad + 2 * p2 * y + 2 * p1 * x
    j[:, 1, 1] = rad + y * y * drad + 2 * p2 * x + 6 * p1 * y
    return j


def _radial_scale_equi(r: np.ndarray, k) -> np.ndarray:
    th = np.arctan(r)
    t2 = th * th
    thd = th * (1 + k[0] * t2 + k[1] * t2**2 + k[2] * t2**3 + k[3] * t2**4)
    return np.where(r > 1e-12, thd / np.where(r > 1e-12, r, 1.0), 1.0)


@dataclass(frozen=True)
class CentralModel:
    """A projection (``PROJECTIONS``) with its ``params``, a distortion (``DISTORTIONS``) with
    ``coeffs``, and the camera matrix ``fu, fv, pu, pv`` with OpenCV's ``skew``."""

    projection: str
    params: tuple[float, ...]
    distortion: str
    coeffs: tuple[float, ...]
    fu: float
    fv: float
    pu: float
    pv: float
    width: int
    height: int
    skew: float = 0.0

    kind = "central"

    def __post_init__(self) -> None:
        if self.projection not in PROJECTIONS:
            raise BadInputError(f"projection {self.projection!r}: expected one of {sorted(PROJECTIONS)}")
        if self.distortion not in DISTORTIONS:
            raise BadInputError(f"distortion {self.distortion!r}: expected one of {sorted(DISTORTIONS)}")
        if len(self.params) != len(PROJECTIONS[self.projection]):
            raise BadInputError(f"{self.projection} takes {len(PROJECTIONS[self.projection])} parameters")
        if len(self.coeffs) != DISTORTIONS[self.distortion]:
            raise BadInputError(f"{self.distortion} takes {DISTORTIONS[self.distortion]} coefficients")
        if self.projection in ("ds", "eucm") and self.distortion != "none":
            raise BadInputError(f"the {self.projection} model takes no distortion, got {self.distortion!r}")

    @property
    def image_size_px(self) -> tuple[int, int]:
        return (self.width, self.height)

    @property
    def center_px(self) -> tuple[float, float]:
        return (self.pu, self.pv)

    def linear_part(self) -> np.ndarray:
        return np.array([[self.fu, self.skew], [0.0, self.fv]])

    # ---------------------------------------------------------------- distortion
    def _distort(self, m: np.ndarray) -> np.ndarray:
        if self.distortion == "none":
            return m
        if self.distortion == "radtan":
            return _radtan(m, self.coeffs)
        r = np.hypot(m[:, 0], m[:, 1])
        if self.distortion == "equidistant":
            return m * _radial_scale_equi(r, self.coeffs)[:, None]
        w = self.coeffs[0]  # fov
        rd = np.arctan(2 * r * math.tan(w / 2)) / w
        return m * np.where(r > 1e-12, rd / np.where(r > 1e-12, r, 1.0), 1.0)[:, None]

    def _undistort(self, md: np.ndarray) -> np.ndarray:
        if self.distortion == "none":
            return md
        if self.distortion == "radtan":
            m = md.copy()
            for _ in range(UNDISTORT_ITERATIONS):
                e = _radtan(m, self.coeffs) - md
                j = _radtan_jac(m, self.coeffs)  # 2x2 Newton step by Cramer's rule
                det = j[:, 0, 0] * j[:, 1, 1] - j[:, 0, 1] * j[:, 1, 0]
                m = m - np.column_stack(
                    [
                        (j[:, 1, 1] * e[:, 0] - j[:, 0, 1] * e[:, 1]) / det,
                        (j[:, 0, 0] * e[:, 1] - j[:, 1, 0] * e[:, 0]) / det,
                    ]
                )
                if not np.nanmax(np.abs(e), initial=0.0) > 1e-15:
                    break
            return m
        rd = np.hypot(md[:, 0], md[:, 1])
        if self.distortion == "fov":
            w = self.coeffs[0]
            r = np.tan(rd * w) / (2 * math.tan(w / 2))
        else:  # equidistant: solve theta_d = theta (1 + k1 theta^2 + ...) for theta, r = tan(theta)
            k = self.coeffs
            th = rd.copy()
            for _ in range(UNDISTORT_ITERATIONS):
                t2 = th * th
                f = th * (1 + k[0] * t2 + k[1] * t2**2 + k[2] * t2**3 + k[3] * t2**4) - rd
                df = 1 + 3 * k[0] * t2 + 5 * k[1] * t2**2 + 7 * k[2] * t2**3 + 9 * k[3] * t2**4
                th = th - f / df
            r = np.tan(th)
        return md * np.where(rd > 1e-12, r / np.where(rd > 1e-12, rd, 1.0), 1.0)[:, None]

    # ---------------------------------------------------------------- projection
    def project(self, rays) -> np.ndarray:
        """Rays (N, 3) (any length) -> pixels (N, 2); NaN where the model does not reach."""
        p = np.asarray(rays, float).reshape(-1, 3)
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        d = np.linalg.norm(p, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            if self.projection == "pinhole":
                den, ok = z, z > 0
            elif self.projection == "omni":
                (xi,) = self.params
                den = z + xi * d
                ok = den > 0
            elif self.projection == "ds":
                xi, al = self.params
                d2 = np.sqrt(x * x + y * y + (xi * d + z) ** 2)
                den = al * d2 + (1 - al) * (xi * d + z)
                w1 = al / (1 - al) if al <= 0.5 else (1 - al) / al
                w2 = (w1 + xi) / math.sqrt(2 * w1 * xi + xi * xi + 1)
                ok = z > -w2 * d
            else:  # eucm
                al, be = self.params
                dd = np.sqrt(be * (x * x + y * y) + z * z)
                den = al * dd + (1 - al) * z
                ok = den > 0
            m = np.column_stack([x / den, y / den])
        md = self._distort(m)
        u = self.fu * md[:, 0] + self.skew * md[:, 1] + self.pu
        v = self.fv * md[:, 1] + self.pv
        out = np.column_stack([u, v])
        out[~ok] = np.nan
        return out

    def unproject(self, uv) -> tuple[np.ndarray, np.ndarray]:
        """Pixels (N, 2) -> unit rays (N, 3) and the mask of pixels the model defines."""
        uv = np.asarray(uv, float).reshape(-1, 2)
        my = (uv[:, 1] - self.pv) / self.fv
        mx = (uv[:, 0] - self.pu - self.skew * my) / self.fu
        md = np.column_stack([mx, my])
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            m = self._undistort(md)
            mx, my = m[:, 0], m[:, 1]
            r2 = mx * mx + my * my
            if self.projection == "pinhole":
                rays = np.column_stack([mx, my, np.ones_like(mx)])
                ok = np.ones(len(mx), bool)
            elif self.projection == "omni":  # Mei & Rives: lift to the unit sphere
                (xi,) = self.params
                disc = 1 + (1 - xi * xi) * r2
                ok = disc >= 0
                fac = (xi + np.sqrt(np.maximum(disc, 0))) / (r2 + 1)
                rays = np.column_stack([fac * mx, fac * my, fac - xi])
            elif self.projection == "ds":  # Usenko et al. eq. 50-52
                xi, al = self.params
                disc = 1 - (2 * al - 1) * r2
                ok = disc >= 0
                mz = (1 - al * al * r2) / (al * np.sqrt(np.maximum(disc, 0)) + 1 - al)
                fac = (mz * xi + np.sqrt(mz * mz + (1 - xi * xi) * r2)) / (mz * mz + r2)
                rays = np.column_stack([fac * mx, fac * my, fac * mz - xi])
            else:  # eucm: Khomutenko et al. eq. 9-11
                al, be = self.params
                disc = 1 - (2 * al - 1) * be * r2
                ok = disc >= 0
                mz = (1 - be * al * al * r2) / (al * np.sqrt(np.maximum(disc, 0)) + 1 - al)
                rays = np.column_stack([mx, my, mz])
            rays = _norm_rows(rays)
        ok &= np.isfinite(rays).all(axis=1) & np.isfinite(m).all(axis=1)
        return rays, ok
