"""Random scenes of the ant-like STC situation, with ground truth, for tests and datasets.

:func:`cell_scene` puts the robot in the entry sub-cell (0) of a free cell, heading into the
cell (with a heading error and a small position error), lays marks in a random subset of the
five boxes and in the neighbour cells with random ages, and adds the robot's freshest mark: the
row it laid in the sub-cell it came from, just before driving forward into this cell (that is
the row the heading fit reads).
"""

from __future__ import annotations

import numpy as np

from stcvision.sim_camera.board import DEFAULT_SUBCELL_M, Board
from stcvision.sim_camera.camera import Pose
from stcvision.sim_camera.phosphor import PhosphorLayer, mark_dots_m
from stcvision.sim_camera.truth import BOXES, NEIGHBOURS, SUBCELL_SIGNS, entry_frame

__all__ = ["CellScene", "benchmark_frames", "benchmark_scene", "cell_scene"]


class CellScene:
    """A board, a robot pose, a phosphor layer and the red lights: what a camera needs."""

    def __init__(self, board: Board, pose: Pose, phosphor: PhosphorLayer, marks: list[dict], t_s: float = 0.0):
        self.board = board
        self.pose = pose
        self.phosphor = phosphor
        self.marks = marks
        self.red_lights_m = board.red_lights_m()
        self.t_s = t_s


def _free_cell_with_free_back(board: Board, rng, heading_rad: float):
    """A free cell whose 'back' neighbour (the parent the robot came from) is free too."""
    right, up, _ = entry_frame(heading_rad)
    back = NEIGHBOURS["back"][0] * right + NEIGHBOURS["back"][1] * up  # world (x east, y north)
    di, dj = -round(back[1]), round(back[0])  # board rows run north to south
    cr, cc = board.shape_cells
    cand = [
        (ci, cj)
        for ci in range(cr)
        for cj in range(cc)
        if board.cell_free[ci, cj] and board.is_cell_free(ci + di, cj + dj)
    ]
    if not cand:
        raise ValueError("board has no free cell with a free neighbour")
    return cand[rng.integers(len(cand))]


def cell_scene(
    rng: np.random.Generator,
    *,
    cells: tuple[int, int] = (6, 6),
    obstacle_fraction: float = 0.2,
    heading_error_deg: float | tuple[float, float] = (-3.0, 3.0),
    position_error_m: float = 0.003,
    box_prob: float = 0.4,
    neighbour_mark_prob: float = 0.5,
    age_range_s: tuple[float, float] = (0.0, 60.0),
    fresh_age_s: tuple[float, float] = (1.0, 5.0),
    charge_s: float = 3.0,
    subcell_m: float = DEFAULT_SUBCELL_M,
) -> CellScene:
    """A random STC entry situation (see the module docstring)."""
    board = Board.random(cells, obstacle_fraction=obstacle_fraction, rng=rng, subcell_m=subcell_m)
    heading = int(rng.integers(4)) * np.pi / 2  # a world angle, a multiple of 90 degrees
    ci, cj = _free_cell_with_free_back(board, rng, heading)
    right, up, _ = entry_frame(heading)
    D = board.subcell_m
    centre = board.cell_center_m(ci, cj)
    herr = heading_error_deg if np.isscalar(heading_error_deg) else rng.uniform(*heading_error_deg)
    start = centre + D / 2 * (right - up) + rng.normal(0, position_error_m, 2)
    pose = Pose(float(start[0]), float(start[1]), float(heading + np.radians(herr)))
    layer = PhosphorLayer()
    marks: list[dict] = []

    def lay(sub_centre, edge_ru, age, where):
        e = edge_ru[0] * right + edge_ru[1] * up
        layer.charge(mark_dots_m(sub_centre, e, D), t_start_s=-age - charge_s, duration_s=charge_s)
        marks.append(
            {
                "where": where,
                "age_s": float(age),
                "subcell_centre_m": list(map(float, sub_centre)),
                "edge": [float(v) for v in e],
            }
        )

    for b, (k, edge) in BOXES.items():
        if rng.random() < box_prob:
            sr, su = SUBCELL_SIGNS[k]
            lay(centre + D / 2 * (sr * right + su * up), edge, rng.uniform(*age_range_s), f"box{b}")
    for name, (dr, du) in NEIGHBOURS.items():
        nc = centre + 2 * D * (dr * right + du * up)
        if name == "back":
            # the robot's freshest mark: the sub-cell it left (back cell's sub-cell 1), rear edge
            lay(nc + D / 2 * (right + up), (0, -1), rng.uniform(*fresh_age_s), "fresh")
            continue
        nci, ncj = board.subcell_at(nc)[0] // 2, board.subcell_at(nc)[1] // 2
        if board.is_cell_free(nci, ncj) and rng.random() < neighbour_mark_prob:
            k = int(rng.integers(4))
            sr, su = SUBCELL_SIGNS[k]
            edge = list(NEIGHBOURS.values())[rng.integers(4)]  # any of the four edges
            lay(nc + D / 2 * (sr * right + su * up), edge, rng.uniform(*age_range_s), name)
    return CellScene(board, pose, layer, marks)


# ------------------------------------------------------------------ the bench's scene
def benchmark_scene(seed: int = 0):
    """A representative closed-loop scene: a 22x22-cell board with 10 % obstacle cells, every
    sub-cell marked at a random age up to 3 minutes, the robot inside the board."""
    import numpy as np

    from stcvision.sim_camera.board import Board
    from stcvision.sim_camera.scene import EDGES

    rng = np.random.default_rng(seed)
    board = Board.random((22, 22), obstacle_fraction=0.1, rng=rng)
    layer = PhosphorLayer()
    edges = list(EDGES.values())
    rows, cols = board.shape_subcells
    for i in range(rows):
        for j in range(cols):
            if not board.blocked[i, j]:
                e = edges[rng.integers(4)]
                layer.charge(
                    mark_dots_m(board.subcell_center_m(i, j), e, board.subcell_m),
                    t_start_s=-rng.uniform(0, 180),
                    duration_s=3.0,
                )
    free = np.argwhere(board.cell_free)
    ci, cj = free[len(free) // 2]
    c = board.subcell_center_m(2 * ci + 1, 2 * cj + 1)
    return board, layer, Pose(float(c[0]), float(c[1]), np.pi / 2 + 0.03)


def benchmark_frames(seed: int = 0, n: int = 8):
    """(dark frame, ``n`` frames) of :func:`benchmark_scene` as ``stcvision bench`` renders them:
    a median dark of 8, then the frames, from one stream seeded ``seed``."""
    import numpy as np

    from stcvision.sim_camera.camera import SyntheticCamera

    board, layer, pose = benchmark_scene(seed)
    cam = SyntheticCamera()
    rng = np.random.default_rng(seed)
    dark = cam.median_dark(8, rng=rng)
    lights = board.red_lights_m()
    return dark, [cam.render(pose, rng=rng, phosphor=layer, red_lights_m=lights).image for _ in range(n)]
