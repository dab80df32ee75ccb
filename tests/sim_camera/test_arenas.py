import json
import math

import numpy as np
import pytest

from stcvision.errors import BadInputError
from stcvision.sim_camera.arenas import (
    Arena,
    CircleArena,
    EllipseArena,
    PolygonArena,
    SquareArena,
    arena_from_board,
)


def test_areas_closed_form():
    assert CircleArena(radius_m=1.5).area_m2 == pytest.approx(math.pi * 2.25)
    assert SquareArena(side_m=2.0).area_m2 == pytest.approx(4.0)
    assert EllipseArena(semi_axes_m=(2.0, 0.5)).area_m2 == pytest.approx(math.pi)
    tri = PolygonArena(vertices_m=((0, 0), (2, 0), (0, 1)))
    assert tri.area_m2 == pytest.approx(1.0)


def test_area_matches_monte_carlo(arena):
    """Free area by closed form vs. the fraction of uniform points ``contains`` accepts (1 %)."""
    rng = np.random.default_rng(0)
    xmin, ymin, xmax, ymax = arena.bounds_m
    p = rng.uniform((xmin, ymin), (xmax, ymax), size=(400_000, 2))
    mc = arena.contains(p).mean() * (xmax - xmin) * (ymax - ymin)
    assert mc == pytest.approx(arena.area_m2, rel=0.01)


def test_contains_scalar_and_vector_agree(arena):
    rng = np.random.default_rng(1)
    xmin, ymin, xmax, ymax = arena.bounds_m
    p = rng.uniform((xmin - 0.1, ymin - 0.1), (xmax + 0.1, ymax + 0.1), size=(3000, 2))
    vec = arena.contains(p)
    sca = np.array([arena.contains_xy(x, y) for x, y in p])
    assert (vec == sca).mean() > 0.999  # only exact-boundary ties may differ
    # clearance is positive exactly where contains is true (away from the boundary)
    c = arena.clearance_m(p)
    far = np.abs(c) > 1e-3
    assert np.array_equal(vec[far], c[far] > 0)


def test_clearance_circle_and_margin():
    a = CircleArena(radius_m=1.0)
    assert a.clearance_m([[0.0, 0.0], [0.9, 0.0], [1.2, 0.0]]) == pytest.approx([1.0, 0.1, -0.2])
    assert list(a.contains([[0.85, 0], [0.95, 0]], margin_m=0.1)) == [True, False]


def test_buffon_barriers_length_is_fraction_of_diameter():
    a = CircleArena(radius_m=1.0)
    (v,) = a.centred_barriers("|", 0.5)
    assert v.length_m == pytest.approx(1.0) and v.start_m[0] == v.end_m[0] == 0.0
    v2, h = a.centred_barriers("+", 0.3)
    assert v2.length_m == pytest.approx(0.6) and h.length_m == pytest.approx(0.6)
    assert h.start_m[1] == h.end_m[1] == 0.0
    # a point on the barrier is not free, one beside it is
    arena = a.with_parts(barriers=(v,))
    assert list(arena.contains([[0.0, 0.2], [0.02, 0.2], [0.0, 0.6]])) == [False, True, True]


def test_boundary_segments_and_outer_polygon_is_inscribed():
    a = CircleArena(radius_m=2.75)  # the Buffon standard nest: 100 Khepera diameters
    v = a.outer_vertices()
    assert np.allclose(np.hypot(*v.T), 2.75)
    # chord midpoints are inside the circle by at most the curve tolerance
    mid = 0.5 * (v + np.roll(v, -1, axis=0))
    sag = 2.75 - np.hypot(*mid.T)
    assert sag.max() <= a.curve_tolerance_m and sag.min() > 0
    segs = a.with_parts(barriers=a.centred_barriers("+", 0.2)).boundary_segments()
    assert segs.shape == (len(v) + 2, 2, 2)


def test_json_round_trip_every_kind(tmp_path, arenas):
    for name, arena in arenas.items():
        if name == "board":
            continue
        d = json.loads(json.dumps(arena.to_dict()))
        again = Arena.from_dict(d)
        assert again == arena, name
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(d))
        assert Arena.from_file(path) == arena


def test_json_typed_barriers():
    a = Arena.from_dict(
        {
            "kind": "square",
            "center_m": [1, 1],
            "side_m": 2,
            "barriers": [{"type": "+", "length_fraction": 0.5, "thickness_m": 0.02}],
        }
    )
    assert len(a.barriers) == 2 and all(b.thickness_m == 0.02 for b in a.barriers)
    assert a.barriers[0].start_m == (1.0, 0.5)


@pytest.mark.parametrize(
    "d, key",
    [
        ({"kind": "hexagon"}, "'kind'"),
        ({"kind": "circle", "center_m": [0, 0]}, "'radius_m'"),
        ({"kind": "circle", "center_m": [0, 0], "radius_m": "big"}, "'radius_m'"),
        ({"kind": "circle", "center_m": [0], "radius_m": 1}, "'center_m'"),
        ({"kind": "square", "center_m": [0, 0], "side_m": 0}, "'side_m'"),
        ({"kind": "ellipse", "center_m": [0, 0], "semi_axes_m": [1]}, "'semi_axes_m'"),
        ({"kind": "polygon", "vertices_m": [[0, 0], [1, 0]]}, "'vertices_m'"),
        ({"kind": "polygon", "vertices_m": [[0, 0], [1, 0], [2, 0]]}, "'vertices_m'"),
        (
            {
                "kind": "circle",
                "center_m": [0, 0],
                "radius_m": 1,
                "barriers": [{"type": "|", "length_fraction": 2}],
            },
            "'length_fraction'",
        ),
        (
            {
                "kind": "circle",
                "center_m": [0, 0],
                "radius_m": 1,
                "barriers": [{"start_m": [0, 0]}],
            },
            "'end_m'",
        ),
        (
            {
                "kind": "circle",
                "center_m": [0, 0],
                "radius_m": 1,
                "obstacles": [{"kind": "circle", "center_m": [0, 0]}],
            },
            "'radius_m'",
        ),
        ({"kind": "circle", "center_m": [0, 0], "radius_m": 1, "obstacles": "none"}, "'obstacles'"),
        (
            {"kind": "circle", "center_m": [0, 0], "radius_m": 1, "schema_version": 7},
            "'schema_version'",
        ),
    ],
)
def test_bad_arena_dicts_name_the_key(d, key):
    with pytest.raises(BadInputError) as ei:
        Arena.from_dict(d)
    msg = str(ei.value)
    assert key in msg and "\n" not in msg


def test_from_file_errors(tmp_path):
    with pytest.raises(BadInputError, match="does not exist"):
        Arena.from_file(tmp_path / "nope.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(BadInputError, match="not valid JSON"):
        Arena.from_file(bad)


def test_board_arena_matches_board():
    from stcvision.sim_camera.board import Board

    b = Board.from_text("....\n.S##\n..##\n....\n", subcell_m=0.2)
    a = arena_from_board(b)
    assert a.size_m == pytest.approx((0.8, 0.8))
    assert a.area_m2 == pytest.approx(12 * 0.04)
    # blocked sub-cell (1, 2) -> centre x = 0.5, y = 0.8 - 0.3 = 0.5
    assert not a.contains_xy(0.5, 0.5) and not a.contains([[0.7, 0.3]])[0]
    assert a.contains_xy(0.1, 0.1) and a.contains([[0.5, 0.7]])[0]
    # the blocked 2x2 block became two merged row rectangles
    assert len(a.obstacles) == 2
    x, y, th = a.start_pose(0.05)
    assert (x, y) == pytest.approx(tuple(b.subcell_center_m(*b.start_subcell)))
    assert len(a.red_lights) == len(b.red_lights_m())
