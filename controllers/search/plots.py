"""Figures of search runs (matplotlib, Agg): the paths (true, dead-reckoned, planned), sampling
points, obstacles, patch and shadow; phase and tongue reading over the moves; the radial
pattern's sampling density (Fig. 2)."""

from __future__ import annotations

import numpy as np

from stcvision.controllers.search.metrics import footprints, sampling_points_odo, sampling_points_true

__all__ = ["new_figure", "plot_density", "plot_path", "plot_pattern", "plot_timeline", "save_figure"]


def new_figure(*args, **kw):
    """``matplotlib.pyplot.subplots(*args, **kw)`` on the Agg backend (no display needed).

    Returns
    -------
    (Figure, Axes or array of Axes)
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(*args, **kw)


def save_figure(fig, path, *, overwrite: bool = True) -> None:
    from stcvision.fileio import write_figure

    write_figure(path, fig, overwrite=overwrite, bbox_inches="tight")


def _scene(ax, scene) -> None:
    import matplotlib.patches as mp

    for x, y, r in scene.obstacles:
        ax.add_patch(mp.Circle((x, y), r, color="black", zorder=3))
    if scene.patch is not None:
        x, y, r = scene.patch
        ax.add_patch(mp.Circle((x, y), r, color="tab:orange", alpha=0.35, zorder=1, label="chemical patch"))


def plot_path(run, title: str = "", *, shadow: bool = True, ax=None):
    """True and dead-reckoned paths, sampling points, the planned pattern, obstacles, patch and
    (``shadow``) the shadow area in red."""
    own = ax is None
    if own:
        fig, ax = new_figure(figsize=(6.5, 6.5))
    if shadow:
        xs, ys, intended, sampled = footprints(run, grid_m=0.01)
        sh = np.ma.masked_where(~(intended & ~sampled), np.ones_like(intended, float))
        ax.pcolormesh(xs, ys, sh, cmap="autumn", alpha=0.6, shading="auto", zorder=0)
    planned = run.planned()
    ax.plot(*planned.T, ":", color="grey", lw=1, label="planned (eq. 5)")
    ax.plot(*run.true_trail.T, "-", color="tab:blue", lw=1.2, label="true path")
    odo = sampling_points_odo(run)
    ax.plot(*odo.T, "--", color="tab:green", lw=1, label="dead-reckoned")
    tru = sampling_points_true(run)
    ax.plot(*tru.T, "o", ms=3.5, mfc="none", color="black", label="sensing points")
    fixes = np.array([m.fix[:2] for m in run.moves if m.fix is not None]).reshape(-1, 2)
    if len(fixes):
        ax.plot(*fixes.T, "x", color="tab:purple", ms=5, label="beacon fixes")
    _scene(ax, run.scene)
    ax.plot(0, 0, "k*", ms=10, label="start")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="best")
    return fig if own else ax


def plot_timeline(run, title: str = "", threshold: float | None = None):
    """Tongue reading and phase per sensing operation (Figs. 12 and 14)."""
    fig, (a1, a2) = new_figure(2, 1, figsize=(7, 4.5), sharex=True)
    k = np.arange(len(run.moves) + 1)
    a1.plot(k, [run.start_tongue] + [m.tongue for m in run.moves], ".-")
    if threshold is not None:
        a1.axhline(threshold, color="red", lw=0.8, ls="--", label="threshold")
        a1.legend(fontsize=7)
    a1.set_ylabel("tongue reading")
    a2.step(k[1:], [m.phase for m in run.moves], where="mid")
    a2.set_yticks([1, 2, 3, 4])
    a2.set_ylabel("phase (Fig. 5)")
    a2.set_xlabel("move")
    a1.set_title(title, fontsize=9)
    return fig


def plot_pattern(points: np.ndarray, title: str = ""):
    fig, ax = new_figure(figsize=(6, 6))
    ax.plot(*points.T, ".-", ms=3, lw=0.8)
    ax.plot(0, 0, "r*", ms=10)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=9)
    return fig


def plot_density(points: np.ndarray, title: str = "", bins: int = 20):
    """Fig. 2: histogram of the sampling points' distance from the centre."""
    fig, ax = new_figure(figsize=(6, 3.5))
    ax.hist(np.hypot(*points.T), bins=bins)
    ax.set_xlabel("distance from the centre")
    ax.set_ylabel("sampling points")
    ax.set_title(title, fontsize=9)
    return fig
