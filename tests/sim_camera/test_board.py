"""Map parsing and board geometry."""

import numpy as np
import pytest

from stcvision.errors import MapError
from stcvision.sim_camera.board import Board

TEXT = """\
......
..##..
..##..
....S.
"""


def test_text_map_parses_cells_and_start():
    b = Board.from_text(TEXT, subcell_m=0.2)
    assert b.shape_subcells == (4, 6)
    assert b.shape_cells == (2, 3)
    # the middle cell of each row holds a blocked sub-cell
    assert b.cell_free.tolist() == [[True, False, True], [True, False, True]]
    assert b.start_subcell == (3, 4)
    assert b.size_m == pytest.approx((1.2, 0.8))
    # row 0 is north: sub-cell (0, 0) is at the top-left
    assert b.subcell_center_m(0, 0) == pytest.approx([0.1, 0.7])
    assert b.subcell_at(b.subcell_center_m(3, 4)) == (3, 4)
    assert Board.from_text(b.to_text(), subcell_m=0.2).blocked.tolist() == b.blocked.tolist()


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("...\n...\n", "even"),  # odd width
        ("....\n....\n....\n", "even"),  # odd height
        ("..S.\n..x.\n", "unknown character 'x'"),
        ("....\n....\n", "no start"),
        ("S...\n...S\n", "2 starts"),
        ("..S.\n...\n", "line 2 has 3"),
        ("", "empty"),
        ("#S..\n....\n", "obstacle cell"),
    ],
)
def test_bad_text_maps_give_clear_errors(text, words):
    with pytest.raises(MapError, match=words):
        Board.from_text(text)


def test_bad_map_files(tmp_path):
    with pytest.raises(MapError, match="does not exist"):
        Board.from_file(tmp_path / "nope.png")
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"this is not a png")
    with pytest.raises(MapError, match="not a readable image"):
        Board.from_file(bad)
    empty = tmp_path / "empty.png"
    empty.write_bytes(b"")
    with pytest.raises(MapError, match="empty"):
        Board.from_file(empty)


@pytest.mark.parametrize(
    ("name", "free_cells"),
    [("spiral_stc_test.png", 256), ("spiral_stc_test_2.png", 252), ("spiral_stc_test_3.png", 252)],
)
def test_pythonrobotics_maps_have_the_published_free_cell_counts(peer_data, name, free_cells):
    # PythonRobotics' Spiral-STC covers 256 / 252 / 252 free cells on these maps
    b = Board.from_file(peer_data / "pythonrobotics_maps" / name)
    assert int(b.cell_free.sum()) == free_cells
    assert int(b.reachable_cells().sum()) == free_cells
    i, j = b.start_subcell
    assert b.cell_free[i // 2, j // 2]


def test_random_board_is_seeded_and_reachability_is_4_connected():
    a = Board.random((8, 8), obstacle_fraction=0.3, rng=np.random.default_rng(5))
    b = Board.random((8, 8), obstacle_fraction=0.3, rng=np.random.default_rng(5))
    assert (a.blocked == b.blocked).all()
    wall = Board.from_text("S.#...\n..#...\n")
    assert wall.reachable_cells().tolist() == [[True, False, False]]


def test_red_lights_cover_obstacles_and_a_ring_outside_the_border():
    b = Board.from_text(TEXT, subcell_m=0.2)
    lights = b.red_lights_m()
    cr, cc = b.shape_cells
    ring = 2 * (cc + 2) + 2 * cr
    assert len(lights) == int((~b.cell_free).sum()) + ring
    for ci, cj in np.argwhere(~b.cell_free):
        assert np.min(np.hypot(*(lights - b.cell_center_m(ci, cj)).T)) < 1e-9
    # every ring light lies outside the board
    w, h = b.size_m
    outside = (lights[:, 0] < 0) | (lights[:, 0] > w) | (lights[:, 1] < 0) | (lights[:, 1] > h)
    assert outside.sum() == ring
