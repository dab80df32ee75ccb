"""Shared arenas for the sim substrate tests (one of each kind, with barriers and obstacles)."""

import numpy as np
import pytest

from stcvision.sim_camera.arenas import (
    Barrier,
    CircleArena,
    CircleObstacle,
    EllipseArena,
    PolygonArena,
    PolygonObstacle,
    SquareArena,
    arena_from_board,
)


def make_arenas() -> dict:
    circle = CircleArena(radius_m=0.6)
    circle = circle.with_parts(
        barriers=circle.centred_barriers("|", 0.4),
        obstacles=(
            CircleObstacle(center_m=(0.3, -0.2), radius_m=0.06),
            PolygonObstacle(vertices_m=((-0.4, -0.1), (-0.3, -0.1), (-0.35, 0.0))),
        ),
    )
    square = SquareArena(side_m=1.2)
    square = square.with_parts(
        barriers=square.centred_barriers("+", 0.5),
        obstacles=(PolygonObstacle(vertices_m=((0.3, 0.3), (0.45, 0.3), (0.45, 0.45), (0.3, 0.45))),),
    )
    ellipse = EllipseArena(semi_axes_m=(0.9, 0.45))
    ellipse = ellipse.with_parts(
        barriers=ellipse.centred_barriers("|", 0.3),
        obstacles=(CircleObstacle(center_m=(-0.5, 0.0), radius_m=0.05),),
    )
    # non-convex "L" with a barrier and a non-convex obstacle
    poly = PolygonArena(vertices_m=((0, 0), (1.2, 0), (1.2, 0.5), (0.6, 0.5), (0.6, 1.2), (0, 1.2)))
    poly = poly.with_parts(
        barriers=(Barrier(start_m=(0.9, 0.05), end_m=(0.9, 0.3)),),
        obstacles=(
            PolygonObstacle(
                vertices_m=(
                    (0.15, 0.7),
                    (0.4, 0.7),
                    (0.4, 0.95),
                    (0.3, 0.95),
                    (0.3, 0.8),
                    (0.15, 0.8),
                )
            ),
        ),
    )
    from stcvision.sim_camera.board import Board

    board = arena_from_board(Board.random((4, 4), obstacle_fraction=0.25, rng=np.random.default_rng(3)))
    return {"circle": circle, "square": square, "ellipse": ellipse, "polygon": poly, "board": board}


ARENAS = make_arenas()


@pytest.fixture(params=sorted(ARENAS))
def arena(request):
    return ARENAS[request.param]


@pytest.fixture
def arenas():
    """All test arenas by name."""
    return dict(ARENAS)
