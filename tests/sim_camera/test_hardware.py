"""Camera and robot profiles: presets with a source for every figure, versioned JSON."""

import json

import pytest

from stcvision.cli import main
from stcvision.errors import BadInputError
from stcvision.sim_camera import hardware
from stcvision.sim_camera.robot import LEGO_STC, LEGO_STC_ROBOT


def test_every_preset_figure_has_a_source_and_the_webcam_is_the_default_sensor():
    from stcvision.sim_camera.image_sensor import SensorParams

    assert hardware.CAMERAS["webcam"].sensor == SensorParams()
    for cam in hardware.CAMERAS.values():
        d = hardware.camera_to_dict(cam)
        assert set(d["sensor"]) == set(hardware.CAMERA_FIGURES) <= set(d["sources"]), cam.name
    for robot in hardware.ROBOTS.values():
        d = hardware.robot_to_dict(robot)
        figures = set(d) - {"schema_version", "kind", "name", "sources"}
        assert figures <= set(d["sources"]), robot.name
    # the Lego robot's motion is LEGO_STC's, not a copy
    assert LEGO_STC_ROBOT.drive_speed_m_s == LEGO_STC.cruise_speed_m_s
    assert LEGO_STC_ROBOT.turn_90_s == pytest.approx(1.5, abs=1e-12)
    assert LEGO_STC_ROBOT.rate_spread == LEGO_STC.speed_gain_spread
    # ... and follows it: a faster body gives a faster marking robot
    import dataclasses

    from stcvision.sim_camera.robot import MarkingRobot

    fast = dataclasses.replace(LEGO_STC, cruise_speed_m_s=0.1, turn_wheel_speed_m_s=2 * LEGO_STC.turn_wheel_speed_m_s)
    from_body = {"drive_speed_m_s", "turn_90_s", "rate_spread", "fade_per_h"}
    rest = {f.name: getattr(LEGO_STC_ROBOT, f.name) for f in dataclasses.fields(MarkingRobot)}
    moved = MarkingRobot.from_body(fast, **{k: v for k, v in rest.items() if k not in from_body})
    assert moved.drive_speed_m_s == 0.1 and moved.turn_90_s == pytest.approx(0.75, abs=1e-12)
    # the better cameras collect more electrons per second of a faint mark and add less noise
    web, cooled = hardware.CAMERAS["webcam"].sensor, hardware.CAMERAS["cooled"].sensor
    assert cooled.e_per_cd_m2_s > web.e_per_cd_m2_s and cooled.dark_current_e_s < web.dark_current_e_s


def test_profiles_round_trip_through_json(tmp_path):
    for cam in hardware.CAMERAS.values():
        p = tmp_path / f"{cam.name}.json"
        p.write_text(json.dumps(hardware.camera_to_dict(cam)))
        back = hardware.load_camera(str(p))
        assert back.sensor == cam.sensor and dict(back.sources) == dict(cam.sources)
    p = tmp_path / "robot.json"
    p.write_text(json.dumps(hardware.robot_to_dict(LEGO_STC_ROBOT)))
    assert hardware.load_robot(str(p)) == LEGO_STC_ROBOT


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ('{"schema_version": 2, "kind": "camera"}', "schema_version must be 1"),
        ("[1, 2]", "one JSON object"),
        ("{not json", "not valid JSON"),
        ('{"schema_version": 1, "kind": "camera", "sensor": {"read_noise_e": 1}}', "at least"),
        ('{"schema_version": 1, "kind": "robot"}', "is a 'robot' profile"),
    ],
)
def test_bad_camera_files_are_refused_with_a_reason(tmp_path, text, words):
    p = tmp_path / "cam.json"
    p.write_text(text)
    with pytest.raises(BadInputError, match=words):
        hardware.load_camera(str(p))


def test_cli_lists_presets_and_refuses_unknown_ones(capsys, tmp_path):
    assert main(["cover", "--list-cameras", "--json"]) == 0
    cams = json.loads(capsys.readouterr().out)
    assert [c["name"] for c in cams][:3] == ["webcam", "lowlight", "cooled"]
    assert all({"name", "sensor", "sources"} <= set(c) for c in cams)
    assert main(["cover", "--list-robots", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)[0]["name"] == "lego"
    bad = tmp_path / "r.json"
    bad.write_text('{"schema_version": 1, "kind": "robot", "name": "x"}')
    for argv, words in (
        (["cover", "--camera", "nope"], "unknown camera"),
        (["cover", "--robot", str(bad)], "missing"),
        (["cover", "--camera", str(tmp_path / "none.json")], "does not exist"),
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1


def test_cover_runs_with_profiles_from_files(capsys, tmp_path):
    cam = hardware.camera_to_dict(hardware.CAMERAS["cooled"]) | {"name": "mine"}
    (tmp_path / "cam.json").write_text(json.dumps(cam))
    robot = hardware.robot_to_dict(LEGO_STC_ROBOT) | {"name": "slow", "drive_speed_m_s": 0.04}
    (tmp_path / "robot.json").write_text(json.dumps(robot))
    argv = ["cover", "--board", "2x2", "--obstacle-fraction", "0", "--perception", "ideal", "--json"]
    assert main([*argv, "--camera", str(tmp_path / "cam.json"), "--robot", str(tmp_path / "robot.json")]) == 0
    slow = json.loads(capsys.readouterr().out)
    # the same camera with the default robot: which frames a reading needs depends on the camera
    # (the long-frame claims measured on it), so only the robot may differ between the two
    assert main([*argv, "--camera", str(tmp_path / "cam.json")]) == 0
    lego = json.loads(capsys.readouterr().out)
    assert main(argv) == 0
    default = json.loads(capsys.readouterr().out)
    assert (slow["camera"], slow["robot"], lego["robot"]) == ("mine", "slow", "lego")
    assert (default["camera"], default["robot"]) == ("webcam", "lego")
    n = slow["subcells_reachable"]
    assert slow["subcells_covered"] == lego["subcells_covered"] == default["subcells_covered"] == n
    # the same tour at half the speed: 4 s instead of 2 s per sub-cell driven, the rest as before
    assert slow["sim_time_s"] - lego["sim_time_s"] == pytest.approx(lego["moves"] * 2.0, rel=0.02)
