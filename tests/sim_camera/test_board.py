"""Map parsing and board geometry."""

from pathlib import Path

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


# ---------------------------------------------------------------- maps with a scale


def _lab_map(tmp_path, *, m_per_px=0.04, negate=0):
    """A lab's occupancy map as ROS map_server writes one: 100 x 70 px at 4 cm per pixel
    (4.0 x 2.8 m), free floor 254, walls 0, an unknown corner 205, a table and a pillar."""
    import cv2

    img = np.full((70, 100), 254, np.uint8)
    img[:2, :] = img[-2:, :] = 0
    img[:, :2] = img[:, -2:] = 0
    img[20:34, 40:58] = 0  # a table
    img[50:53, 80:83] = 0  # a pillar
    img[2:12, 88:98] = 205  # not yet seen
    if negate:
        img = 255 - img
    cv2.imwrite(str(tmp_path / "lab.pgm"), img)
    (tmp_path / "lab.yaml").write_text(
        f"image: lab.pgm\nresolution: {m_per_px}\norigin: [-1.0, -0.5, 0.0]\nnegate: {negate}\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    return img


def _expected_blocked(free_px, m_per_px, subcell_m):
    """The board a person computes by hand: whole cells from the lower-left corner, a sub-cell
    free iff every pixel it overlaps is free."""
    import math

    h, w = free_px.shape
    rows = 2 * math.floor(h * m_per_px / subcell_m / 2)
    cols = 2 * math.floor(w * m_per_px / subcell_m / 2)
    out = np.zeros((rows, cols), bool)
    for i in range(rows):
        for j in range(cols):
            y_top = (h * m_per_px - rows * subcell_m + i * subcell_m) / m_per_px
            x_left = j * subcell_m / m_per_px
            r0, r1 = math.floor(y_top + 1e-9), math.ceil(y_top + subcell_m / m_per_px - 1e-9)
            c0, c1 = math.floor(x_left + 1e-9), math.ceil(x_left + subcell_m / m_per_px - 1e-9)
            out[i, j] = not free_px[r0:r1, c0:c1].all()
    return out


@pytest.mark.parametrize("subcell_m", [0.16, 0.20, 0.13])
def test_a_map_server_map_covers_the_board_a_person_computes(tmp_path, subcell_m):
    img = _lab_map(tmp_path)
    board = Board.from_map_yaml(tmp_path / "lab.yaml", subcell_m=subcell_m)
    free_px = (1 - img / 255.0) < 0.196
    assert np.array_equal(board.blocked, _expected_blocked(free_px, 0.04, subcell_m))
    assert board.subcell_m == subcell_m
    assert board.size_m[0] <= 4.0 and board.size_m[0] > 4.0 - 2 * 2 * subcell_m


def test_negate_and_a_png_at_its_resolution_give_the_same_board(tmp_path):
    img = _lab_map(tmp_path)
    a = Board.from_file(tmp_path / "lab.yaml")
    neg = tmp_path / "neg"
    neg.mkdir()
    _lab_map(neg, negate=1)
    assert np.array_equal(Board.from_file(neg / "lab.yaml").blocked, a.blocked)
    import cv2

    cv2.imwrite(str(tmp_path / "lab.png"), np.where(img == 254, 255, 0).astype(np.uint8))
    assert np.array_equal(Board.from_file(tmp_path / "lab.png", m_per_px=0.04).blocked, a.blocked)


@pytest.mark.parametrize(
    "yaml_text, says",
    [
        ("image: lab.pgm\nresolution: -1\noccupied_thresh: 0.65\nfree_thresh: 0.196\n", "resolution is -1"),
        ("image: lab.pgm\nresolution: 0.04\nfree_thresh: 0.196\n", "no 'occupied_thresh'"),
        ("image: nope.pgm\nresolution: 0.04\noccupied_thresh: 0.65\nfree_thresh: 0.196\n", "nope.pgm"),
        ("image: lab.pgm\nresolution: 0.04\noccupied_thresh: 0.1\nfree_thresh: 0.5\n", "above occupied_thresh"),
        ("image: lab.pgm\nresolution: 1\noccupied_thresh: 0.65\nfree_thresh: 0.196\n", None),
    ],
)
def test_bad_map_yaml_is_one_named_line(tmp_path, yaml_text, says):
    _lab_map(tmp_path)
    (tmp_path / "lab.yaml").write_text(yaml_text)
    if says is None:  # 1 m per pixel: a board of 100 x 70 m, over the cap of cells, but still a board
        assert Board.from_map_yaml(tmp_path / "lab.yaml").shape_cells == (218, 312)
        return
    with pytest.raises(MapError, match=says):
        Board.from_map_yaml(tmp_path / "lab.yaml")


def test_cover_takes_a_lab_map_at_its_scale_and_refuses_what_does_not_fit(cli, tmp_path):
    import json

    _lab_map(tmp_path)
    code, out, err = cli("cover", "--map", tmp_path / "lab.yaml", "--perception", "oracle", "--json")
    assert code == 0, err
    r = json.loads(out)
    board = Board.from_map_yaml(tmp_path / "lab.yaml")
    assert r["complete"] and r["board_cells"] == [board.shape_cells[1], board.shape_cells[0]]
    assert r["subcells_reachable"] == 4 * int(board.reachable_cells().sum())
    code, _, err = cli("cover", "--map", tmp_path / "lab.yaml", "--subcell-m", "0.2", "--perception", "camera")
    assert code == 2 and "profile reads 0.16 m" in err and err.count("\n") == 1
    code, _, err = cli("cover", "--map", tmp_path / "lab.yaml", "--resolution", "0.04")
    assert code == 2 and "drop --resolution" in err
    photo = (
        Path(__file__).resolve().parents[2] / "datasets" / "peer_data" / "opencv_omnidir" / "catadioptric_sample.jpg"
    )
    code, _, err = cli("cover", "--map", photo, "--perception", "oracle")
    assert code == 2 and "at most 10,000 cells" in err
    code, _, err = cli("cover", "--map", photo, "--resolution", "0.01", "--perception", "oracle")
    assert code == 2 and ("reachable" in err or "no free cell" in err), err
