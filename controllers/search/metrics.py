"""Metrics of a search run, computed from :class:`stcvision.controllers.search.run.SearchRun` (observers
of results; nothing here runs the robot).

**Shadow area** (Fig. 7 vs Fig. 8): the part of the pattern's intended sensing footprint that
was never sampled *because of the detour*. The intended footprint is the union of discs of
radius ``step_m / sqrt(2)`` (half the diagonal of a step-sized square: discs of that radius
around a lattice of sampling points one step apart cover the floor, so each sampling point
stands for the floor it shares with its neighbours) around the undisturbed pattern's sampling
points ``p_0 .. p_N`` (equation (5), ``N`` = the search steps the run took), minus the floor the
tongue cannot reach: within one robot radius plus the ring's stop gap (15 mm) of an obstacle,
where the body stands in the way. The sampled footprint is the union of the same discs around
the sensing operations (after each move, blocked ones included) **where the executed moves put
them on paper**: the start plus the commanded step of every move that was done (a blocked move
ends where it began). That is the robot's own account without its errors -- what its odometry
reads, to the encoder count, when nothing disturbs it -- so the shadow is the detour's doing
alone: neither the drift nor a beacon's corrections change it, only the moves the obstacles
blocked. Rasterised on a 5 mm grid.

``unsampled_area_m2`` is the same with the *true* sensing positions: the detour's shadow plus
what the drift moved the sampling away from (on the open floor: ~0.01-0.02 m^2 on the paper's
spiral, ~0.3 m^2 on a whole radial flower without the beacon).
"""

from __future__ import annotations

import collections

import numpy as np

from stcvision.sim_camera.robot import TASTI2

__all__ = [
    "footprints",
    "odometry_errors_m",
    "sampling_points_true",
    "shadow_area_m2",
    "summarise",
    "trajectory_files",
]

GRID_M = 0.005


def sampling_points_true(run) -> np.ndarray:
    """(M + 1, 2) true positions of the sensing operations (the start and after each move)."""
    return np.array([[0.0, 0.0]] + [m.true_pose[:2] for m in run.moves])


def sampling_points_commanded(run) -> np.ndarray:
    """(M + 1, 2) the sensing points as the executed moves put them (start + the commanded step
    of every done move; a blocked one adds nothing)."""
    steps = [
        m.distance_m * np.array([np.cos(m.heading_rad), np.sin(m.heading_rad)]) if m.result == "done" else np.zeros(2)
        for m in run.moves
    ]
    return np.vstack([[0.0, 0.0], np.cumsum(steps, axis=0)]) if steps else np.zeros((1, 2))


def sampling_points_odo(run) -> np.ndarray:
    return np.array([[0.0, 0.0]] + [m.odo_pose[:2] for m in run.moves])


def odometry_errors_m(run) -> np.ndarray:
    """Dead-reckoning position error at each sensing operation (the start's is 0)."""
    return np.hypot(*(sampling_points_true(run) - sampling_points_odo(run)).T)


def trajectory_files(run) -> dict[str, str]:
    """The true path and the odometry's (after a beacon fix) as TUM files' text.

    Sampled where :func:`odometry_errors_m` is measured (the start and after every move), so
    evo's APE max on the two files is ``max_odometry_error_m`` and its last error the end's.

    Parameters
    ----------
    run : SearchRun
        The run.

    Returns
    -------
    dict of str to str
        By file name (:data:`stcvision.tum.TUM_FILES`).
    """
    from stcvision.tum import tum_files

    start = (0.0, 0.0, 0.0, 0.0)  # the odometry's origin is the true start: metres from it
    true = [start, *((m.t_s, *m.true_pose) for m in run.moves)]
    believed = [start, *((m.t_s, *m.odo_pose) for m in run.moves)]
    return tum_files(true, believed)


def _disc_union(points: np.ndarray, radius: float, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    from scipy.spatial import cKDTree

    grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    d, _ = cKDTree(points).query(grid, distance_upper_bound=radius * 1.0000001)
    return np.isfinite(d).reshape(len(ys), len(xs))


def footprints(run, grid_m: float = GRID_M, *, frame: str = "commanded"):
    """(xs, ys, intended, sampled) boolean rasters of the two footprints (see module doc);
    ``frame`` "commanded" (the executed moves) or "true" for the sensing positions."""
    rho = run.config.pattern.step_m / np.sqrt(2.0)
    planned = run.planned()
    sampled_pts = sampling_points_commanded(run) if frame == "commanded" else sampling_points_true(run)
    allp = np.vstack([planned, sampled_pts])
    lo = allp.min(axis=0) - rho - grid_m
    hi = allp.max(axis=0) + rho + grid_m
    xs = np.arange(lo[0], hi[0], grid_m) + 0.5 * grid_m
    ys = np.arange(lo[1], hi[1], grid_m) + 0.5 * grid_m
    intended = _disc_union(planned, rho, xs, ys)
    gx, gy = np.meshgrid(xs, ys)
    keep_out = TASTI2.radius_m + run.ring_stop_gap_m
    for x, y, r in run.scene.obstacles:
        intended &= np.hypot(gx - x, gy - y) >= r + keep_out
    sampled = _disc_union(sampled_pts, rho, xs, ys)
    return xs, ys, intended, sampled


def shadow_area_m2(run, grid_m: float = GRID_M, *, frame: str = "commanded") -> float:
    _, _, intended, sampled = footprints(run, grid_m, frame=frame)
    return float((intended & ~sampled).sum()) * grid_m**2


def summarise(run) -> dict:
    """The metrics the CLI prints (JSON-serialisable)."""
    err = odometry_errors_m(run)
    phases = collections.Counter(m.phase for m in run.moves)
    trail = run.true_trail
    clearance = float("inf")
    for x, y, r in run.scene.obstacles:
        clearance = min(clearance, float((np.hypot(trail[:, 0] - x, trail[:, 1] - y) - r).min()))
    first_block = next((m.index for m in run.moves if m.result == "blocked"), None)
    return {
        "found": run.found,
        "stop_reason": run.reason,
        "steps": run.search_steps,
        "moves": len(run.moves),
        "blocked_moves": sum(m.result == "blocked" for m in run.moves),
        "path_length_m": round(run.path_length_m, 4),
        "odometry_error_m": round(float(err[-1]), 4),
        "max_odometry_error_m": round(float(err.max()), 4),
        # at the sensing point the first blocked move left from (and came back to)
        "odometry_error_before_obstacle_m": None if first_block is None else round(float(err[first_block]), 4),
        "shadow_area_m2": round(shadow_area_m2(run), 5),
        "unsampled_area_m2": round(shadow_area_m2(run, frame="true"), 5),
        "phase_counts": {str(k): phases.get(k, 0) for k in (1, 2, 3, 4)},
        "phases_visited": sorted(phases),
        "beacon_fixes": sum(m.fix is not None for m in run.moves),
        "sim_time_s": round(run.sim_time_s, 2),
        "min_clearance_to_obstacle_m": None if clearance == float("inf") else round(clearance - TASTI2.radius_m, 4),
        "containment_events": run.containment_events,
    }
