"""Localisation from the red lights: where the robot is in its cell, from lights that stand at
cell centres (absolute landmarks).

Cell units throughout (the entry frame in units of the sub-cell side, origin at the current
cell's centre; :mod:`stcvision.observation`): :func:`rotate_about_robot` turns points about the
robot; :func:`light_sigma_m` is a light's position error by distance; :func:`landmark_fit` is
the weighted least-squares pose fit over lights seen against the cell centres they stand at,
outliers left out; :func:`landmark_pose` picks the lights near a cell centre within reach and
fits them. The cell observation (:func:`stcvision.observation.observe_cell`) calls it.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from stcvision.profile import ROBOT_IN_CELL
from stcvision.stc_geometry import DEFAULT_SUBCELL_M

__all__ = [
    "LIGHT_OUTLIER_CHI2",
    "landmark_fit",
    "landmark_pose",
    "landmark_wls",
    "light_sigma_m",
    "rotate_about_robot",
]


def rotate_about_robot(cell_pts: np.ndarray, angle_rad: float) -> np.ndarray:
    """Rotate cell-unit points about the robot by ``angle_rad`` (counter-clockwise).

    Parameters
    ----------
    cell_pts : (N, 2) float
        Points in cell units.
    angle_rad : float

    Returns
    -------
    (N, 2) float
        The points turned (``cell_pts`` itself when the angle is 0).
    """
    if angle_rad == 0.0:
        return cell_pts
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return rotate_about(np.ascontiguousarray(cell_pts, np.float64), c, s, *ROBOT_IN_CELL)


#: the sub-cell side (m) the light errors are converted with when the caller gives none
_SUBCELL_M = DEFAULT_SUBCELL_M


def light_sigma_m(d_m) -> tuple[np.ndarray, np.ndarray]:
    """A red light's position error (1 sigma, m) at ``d_m`` metres from the robot, along the
    ray from the robot (radial) and across it (tangential). Measured on rendered frames (lights
    at cell centres 0.3-1.2 m away, 440 found): across the ray 0.8-1.3 mm at every distance --
    the mirror keeps the azimuth -- along it 1.5 mm at 0.3 m, 4 mm at 0.7 m, 10 mm (and a bias
    of up to -18 mm) at 1.1-1.2 m, where the mirror squeezes the floor radially. The model is a
    little above both, bias included: 1.5 mm across, ``1.5 mm + 15 mm * d^3`` along."""
    d = np.asarray(d_m, float)
    return 0.0015 + 0.015 * d**3, np.full_like(d, 0.0015)


#: a light whose residual from the fit of the others lies beyond this (its squared Mahalanobis
#: distance under its own error ellipse, :func:`light_sigma_m`; the chi-square 2-d.o.f. point
#: of 0.999, in closed form: -2 ln(1 - p)) is no light at the cell centre the fit assigned it:
#: left out, the rest fitted again
LIGHT_OUTLIER_CHI2 = -2.0 * math.log(1.0 - 0.999)


def landmark_fit(obs_p: np.ndarray, exp_p: np.ndarray, subcell_m: float):
    """Weighted least squares of ``exp = R(-th) (obs - robot) + robot + offset`` (cell units,
    rotation about the robot as :func:`rotate_about_robot`) for lights seen at ``obs_p`` that stand at
    ``exp_p``, each weighted by its error ellipse (:func:`light_sigma_m`); the light furthest
    beyond :data:`LIGHT_OUTLIER_CHI2` is left out and the rest fitted again, until none is.
    Returns (th, offset, sigma of th, sigma of the offset: the larger axis of its ellipse) or
    None if the lights left do not fix all three (fewer than two cell centres).

    Why the outliers: a light seen 8.6 cm off its cell centre at 0.97 m (5.7 sigma along its
    ray; a squared residual of 40 after the fit) pulled a fit of six lights 1.2 cm and 0.5
    degrees off, its reported spread 4.6 mm (spiral_stc_test_2, cooled, seed 918); the robot
    moved by it, laid its rows 2 cm off, and later read one of them as a start mark (a safe
    stop).

    Parameters
    ----------
    obs_p, exp_p : (N, 2) float
        Where the lights are seen, and the cell centres they stand at (cell units).
    subcell_m : float
        The sub-cell side (m) the lights' errors are converted with.

    Returns
    -------
    tuple or None
    """
    keep = np.ones(len(obs_p), bool)
    while len(np.unique(np.round(exp_p[keep] / 2.0), axis=0)) >= 2:
        fit = landmark_wls(obs_p[keep], exp_p[keep], subcell_m)
        if fit is None:
            return None
        th, off, cov, m2 = fit
        worst = int(np.argmax(m2))
        if m2[worst] <= LIGHT_OUTLIER_CHI2:
            sig_off = math.sqrt(float(np.linalg.eigvalsh(cov[1:, 1:]).max()))
            return th, tuple(float(x) for x in off), math.sqrt(float(cov[0, 0])), sig_off
        keep[np.flatnonzero(keep)[worst]] = False
    return None


def landmark_wls(obs_p: np.ndarray, exp_p: np.ndarray, subcell_m: float):
    """One weighted least-squares fit of :func:`landmark_fit`: (th, offset, the covariance of
    (th, offset), each light's squared Mahalanobis residual) or None when ill-conditioned.

    Parameters
    ----------
    obs_p, exp_p : (N, 2) float
        As :func:`landmark_fit`'s.
    subcell_m : float

    Returns
    -------
    tuple or None
    """
    v = obs_p - ROBOT_IN_CELL
    dist = np.hypot(*v.T)
    u = v / np.maximum(dist, 1e-9)[:, None]
    sr, st = light_sigma_m(dist * subcell_m)
    sr, st = sr / subcell_m, st / subcell_m
    uu = u[:, :, None] * u[:, None, :]
    w = uu / (sr**2)[:, None, None] + (np.eye(2) - uu) / (st**2)[:, None, None]  # inverse covariances
    th, off = 0.0, np.zeros(2)
    for _ in range(2):  # once linearised about 0, once about the first answer
        rv = rotate_about_robot(obs_p, -th) - ROBOT_IN_CELL
        r = exp_p - (rv + ROBOT_IN_CELL + off)
        a = np.zeros((len(v), 2, 3))
        a[:, 0, 0], a[:, 1, 0] = rv[:, 1], -rv[:, 0]  # d/d(th) of R(-th) v
        a[:, :, 1:] = np.eye(2)
        at_w = np.einsum("nki,nkl->nil", a, w)
        n = np.einsum("nil,nlj->ij", at_w, a)
        if np.linalg.cond(n) > 1e10:
            return None
        cov = np.linalg.inv(n)
        step = cov @ np.einsum("nil,nl->i", at_w, r)
        th += float(step[0])
        off = off + step[1:]
    r = exp_p - (rotate_about_robot(obs_p, -th) + off)
    return th, off, cov, np.einsum("ni,nij,nj->n", r, w, r)


def landmark_pose(lru: np.ndarray, reach: float, subcell_m: float | None, *, max_sigma_rad: float):
    """The robot's pose in its cell from the red lights ``lru`` (cell units, already turned by
    the heading error): lights within ``reach`` (cell units) of the robot and near a cell
    centre (even coordinates), fitted by :func:`landmark_fit` against those centres.

    Two lights or more at distinct cell centres are needed (with one, a sideways offset and a
    rotation look alike: 1 cm at 40 cm is 1.4 degrees), so both are fitted at once: where the
    lights are against where they should be, ``exp = R(-th) (obs - rob) + rob + offset``,
    linearised in the small rotation ``th`` and weighted by each light's error ellipse (its
    bearing is much surer than its range: :func:`light_sigma_m`).

    Parameters
    ----------
    lru : (N, 2) float
        The lights, cell units.
    reach : float
        How far from the robot (cell units) a light is used.
    subcell_m : float or None
        The sub-cell side (m) the light errors convert with (None: the default side).
    max_sigma_rad : float
        A fit whose rotation is less sure than this is not taken.

    Returns
    -------
    tuple
        (offset, rotation, rotation sigma, offset sigma), each None where not fixed.
    """
    landmark = landmark_rot = landmark_sig = landmark_off_sig = None
    if len(lru):
        resid = lru - 2.0 * np.round(lru / 2.0)
        near = (np.abs(resid) < 0.6).all(axis=1) & (np.hypot(*(lru - ROBOT_IN_CELL).T) < reach)
        obs_p = lru[near]
        exp_p = obs_p - resid[near]
        fit = landmark_fit(obs_p, exp_p, subcell_m or _SUBCELL_M)
        if fit is not None:
            th, off, sig_th, off_sig = fit
            landmark_sig = sig_th
            if sig_th <= max_sigma_rad:
                landmark_rot = th
                landmark = off
                landmark_off_sig = off_sig
    return landmark, landmark_rot, landmark_sig if landmark_rot is not None else None, landmark_off_sig


@numba.njit(cache=True)
def rotate_about(cell_pts, c, s, cx, cy):
    """Points rotated about (cx, cy) by the angle of cosine ``c`` and sine ``s``
    (:func:`rotate_about_robot`), element by element as the numpy version."""
    out = np.empty_like(cell_pts)
    for i in range(len(cell_pts)):
        dx, dy = cell_pts[i, 0] - cx, cell_pts[i, 1] - cy
        out[i, 0] = (c * dx - s * dy) + cx
        out[i, 1] = (s * dx + c * dy) + cy
    return out
