"""The ``stcvision world`` and ``stcvision demo`` commands, run in-process."""

import json

import cv2

from stcvision.cli import main


def test_world_default_arena_json(tmp_path, capsys):
    assert main(["world", "--out", str(tmp_path), "--steps", "400", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["steps"] == 400 and res["containment_events"] == 0
    assert res["distance_m"] > 0.3
    img = cv2.imread(res["path"])
    assert img is not None and img.shape[2] == 3


def test_world_arena_file_board_and_map(tmp_path, capsys):
    arena = {
        "kind": "ellipse",
        "center_m": [0, 0],
        "semi_axes_m": [0.6, 0.3],
        "barriers": [{"type": "+", "length_fraction": 0.3}],
        "obstacles": [{"kind": "circle", "center_m": [0.3, 0.0], "radius_m": 0.04}],
    }
    f = tmp_path / "arena.json"
    f.write_text(json.dumps(arena))
    assert main(["world", "--arena", str(f), "--out", str(tmp_path / "a"), "--steps", "300", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["arena_kind"] == "ellipse"
    assert main(["world", "--board", "3x2", "--out", str(tmp_path / "b"), "--steps", "200"]) == 0
    out = capsys.readouterr().out
    assert "random board 3x2" in out and (tmp_path / "b" / "world.png").exists()
    m = tmp_path / "map.txt"
    m.write_text("....\n.S..\n..##\n..##\n")
    assert main(["world", "--map", str(m), "--out", str(tmp_path / "c"), "--steps", "200", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["arena_kind"] == "board"


def test_world_bad_arena_is_exit_2_one_line(tmp_path, capsys):
    f = tmp_path / "bad.json"
    f.write_text(json.dumps({"kind": "circle", "center_m": [0, 0], "radius_m": -2}))
    assert main(["world", "--arena", str(f), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "'radius_m'" in err and "Traceback" not in err
    assert main(["world", "--arena", str(tmp_path / "missing.json"), "--out", str(tmp_path)]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert not (tmp_path / "world.png").exists()


def test_demo_covers_the_default_board_in_camera_mode(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["perception"] == "camera" and res["finished"] and res["returned_to_start"]
    assert res["subcells_covered"] == res["subcells_reachable"] and res["subcells_covered_more_than_once"] == 0
    assert res["decision_errors"] == 0
    assert (tmp_path / "demo.rrd").stat().st_size > 0 and (tmp_path / "coverage.png").exists()
