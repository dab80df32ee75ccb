"""A scene file that describes something impossible is refused in one line (exit 2), not drawn:
a robot, mark or dot off the board, a negative mark age, a non-positive charge."""

import copy
import json

import pytest

from stcvision.errors import BadInputError
from stcvision.sim_camera.scene import EXAMPLE_SCENE, Scene


def scene(**changes):
    d = copy.deepcopy(EXAMPLE_SCENE)
    d.pop("_doc", None)
    for k, v in changes.items():
        d[k] = v
    return d


def test_the_example_scene_is_accepted():
    Scene.from_dict(scene())


@pytest.mark.parametrize(
    "changes, words",
    [
        (
            {"robot": {"subcell": [99, 99], "heading_deg": 90}},
            "scene robot.subcell [99, 99] is outside the board of 10x10",
        ),
        ({"robot": {"subcell": [-1, 0], "heading_deg": 90}}, "outside the board"),
        ({"robot": {"subcell": [9, 9], "offset_m": [5.0, 0.0]}}, "scene robot (subcell + offset_m) at"),
        ({"robot": {"x_m": 15.0, "y_m": 0.5, "heading_deg": 0}}, "scene robot at (15, 0.5) m is outside the board"),
        ({"marks": [{"subcell": [8, 7], "edge": "S", "age_s": -5}]}, "marks[0]: age_s must be >= 0"),
        ({"marks": [{"subcell": [8, 7], "edge": "S", "age_s": 1, "charge_s": 0}]}, "charge_s must be > 0"),
        ({"marks": [{"subcell": [10, 0], "edge": "S", "age_s": 1}]}, "scene marks[0].subcell [10, 0] is outside"),
        ({"dots": [{"x_m": 0.5, "y_m": 0.5, "age_s": -0.1}]}, "dots[0]: age_s must be >= 0"),
        ({"dots": [{"x_m": -0.5, "y_m": 0.5, "age_s": 1}]}, "scene dots[0] at (-0.5, 0.5) m is outside"),
    ],
)
def test_impossible_scenes_are_refused_with_what_and_where(changes, words):
    with pytest.raises(BadInputError, match=None) as e:
        Scene.from_dict(scene(**changes))
    assert words in str(e.value) and "\n" not in str(e.value)


def test_render_refuses_a_robot_off_the_board_in_one_line(cli, tmp_path):
    path = tmp_path / "s.json"
    path.write_text(json.dumps(scene(robot={"subcell": [99, 99], "heading_deg": 90})))
    code, out, err = cli("render", "--scene", path, "--out", tmp_path / "R")
    assert code == 2 and err.count("\n") == 1 and "outside the board" in err
    assert not (tmp_path / "R").exists()


def test_a_scene_holds_at_most_four_marks_per_sub_cell_and_a_capped_number_of_dots():
    from stcvision import limits

    mark = {"subcell": [0, 0], "edge": "N", "age_s": 1.0}
    with pytest.raises(BadInputError, match="scene marks 401 is over the cap of 400"):
        Scene.from_dict(scene(marks=[mark] * 401))
    dot = {"x_m": 0.5, "y_m": 0.5, "age_s": 1.0}
    with pytest.raises(BadInputError, match="scene dots .* is over the cap"):
        Scene.from_dict(scene(dots=[dot] * (limits.MAX_SCENE_DOTS + 1)))
