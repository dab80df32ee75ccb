"""The portable C controller against the Python one: its bytes, every tick of oracle tours and
of the peer maps, random (state, reading) pairs over the whole input space, and the cover
command with ``--fsm c`` (the full million pairs and 500 boards: ``stcvision firmware check``,
docs/how-to/controller-on-your-robot.md)."""

import json

import numpy as np
import pytest

from stcvision.controllers.stc import wire
from stcvision.controllers.stc.choose import make_controller
from stcvision.controllers.stc.controller import (
    CONTROLLERS,
    OUT_BYTES,
    HostC,
    PythonController,
    build_host_library,
)
from stcvision.controllers.stc.fsm import Action, StcPhase, StcState, initial_state, step
from stcvision.controllers.stc.identity import (
    FIELDS,
    Twin,
    check_boards,
    check_random,
    field_values,
    oracle_boards,
    random_pairs,
)
from stcvision.sim_camera.board import Board

PEER_MAPS = ("spiral_stc_test.png", "spiral_stc_test_2.png", "spiral_stc_test_3.png")


@pytest.fixture(scope="module")
def host_c():
    return HostC()


def test_the_state_is_three_packed_bytes(host_c):
    assert host_c.state_bytes == wire.STATE_BYTES == 3


def test_wire_round_trips_every_state():
    states, _ = random_pairs(20_000, 7)
    for b in map(bytes, states):
        assert wire.encode_state(wire.decode_state(b)) == b
    # the defaults of a fresh state: the C's fresh_state must agree
    assert wire.decode_state(wire.encode_state(initial_state())) == StcState()


def test_wire_round_trips_readings_and_decisions():
    _, obs = random_pairs(5_000, 8)
    for b in map(bytes, obs):
        o = wire.decode_obs(b)
        assert wire.decode_obs(wire.encode_obs(o)) == o
    for b in map(bytes, obs):
        o = wire.decode_obs(b)
        if o is not None and not hasattr(o, "marked"):
            s, _, d = step(StcState(phase=StcPhase.DECIDE), o)
            assert wire.decode_decision(wire.encode_decision(d)) == d
    assert wire.decode_decision(wire.encode_decision(None)) is None


def test_random_pairs_cover_every_value_of_every_field():
    states, obs = random_pairs(20_000, 0)
    assert field_values(states, obs) == {k: n for k, (n, _) in FIELDS.items()}


def test_c_equals_python_on_random_pairs(host_c):
    r = check_random(20_000, 1, host_c)
    assert r["pairs"] == r["same"] == 20_000 and r["different"] == 0, r["first_difference"]
    assert r["refused_by_both"] > 0  # the refusals are compared too
    assert r["field_values_seen"] == r["field_values_all"]


class _OneWrongByte:
    """The C batch with one output byte changed: the check must see it."""

    def __init__(self, inner, row, col):
        self.inner, self.row, self.col = inner, row, col

    def step_batch(self, states, obs):
        out = self.inner.step_batch(states, obs)
        out[self.row, self.col] ^= 1
        return out


@pytest.mark.parametrize("col", range(OUT_BYTES))
def test_the_random_check_sees_one_wrong_byte(host_c, col):
    r = check_random(500, 2, _OneWrongByte(host_c, 123, col))
    if col == 1:  # the action byte of a refusal is not compared: find a pair that was not refused
        states, obs = random_pairs(500, 2)
        refused = host_c.step_batch(states, obs)[123, 0] != 0
        assert r["different"] == (0 if refused else 1)
    else:
        assert r["different"] == 1 and r["first_difference"] is not None


def test_c_equals_python_on_every_tick_of_oracle_tours_and_the_peer_maps(host_c, peer_data):
    tours = check_boards(oracle_boards(12, 100), host_c)
    assert tours["boards"] == tours["complete"] == 12
    assert tours["different"] == 0 and tours["decisions"] > 12, tours["first_difference"]
    maps = check_boards(((m, Board.from_file(peer_data / "pythonrobotics_maps" / m)) for m in PEER_MAPS), host_c)
    assert maps["boards"] == maps["complete"] == 3 and maps["different"] == 0, maps["first_difference"]


def test_the_twin_sees_a_different_controller():
    class Flip:
        def step(self, state, obs):
            s, a, d = step(state, obs)
            return s, (Action.TURN_RIGHT if a is Action.TURN_LEFT else a), d

        def close(self):
            pass

    t = Twin(PythonController(), Flip())
    r = check_boards([("b", next(oracle_boards(1, 3))[1])], Flip())
    assert r["different"] > 0 and r["first_difference"]["board"] == "b"
    state = initial_state()
    t.step(state, None)
    assert t.different == 1


def test_a_refusal_is_the_same_refusal(host_c):
    state = StcState(phase=StcPhase.DECIDE)
    with pytest.raises(ValueError, match="needs an StcObservation"):
        host_c.step(state, None)
    with pytest.raises(ValueError, match="needs an StcObservation"):
        step(state, None)


def test_make_controller_names_each_part():
    assert CONTROLLERS == ("python", "c", "firmware")
    assert make_controller("python").name == "python" and make_controller("c").name == "c"


def test_no_compiler_is_one_clear_error(monkeypatch):
    from stcvision.errors import BadInputError

    with pytest.raises(BadInputError, match="no C compiler 'no-such-cc'"):
        build_host_library("no-such-cc")


def test_the_batch_checks_its_shapes(host_c):
    with pytest.raises(ValueError, match="need"):
        host_c.step_batch(np.zeros((2, 3), np.uint8), np.zeros((3, 5), np.uint8))


def _without_timing(text: str) -> dict:
    r = json.loads(text)
    r.pop("wall_s")
    return r


@pytest.mark.parametrize("perception,board", [("oracle", "4x3"), ("camera", "2x2")])
def test_cover_fsm_c_json_equals_python(cli, perception, board):
    runs = {}
    for fsm in ("python", "c"):
        code, out, _ = cli("cover", "--board", board, "--perception", perception, "--seed", 3, "--fsm", fsm, "--json")
        assert code == 0
        runs[fsm] = _without_timing(out)
    assert runs["c"] == runs["python"] and runs["c"]["complete"]


def test_firmware_check_command(cli, peer_data):
    spiral = peer_data / "pythonrobotics_maps" / PEER_MAPS[0]
    code, out, _ = cli("firmware", "check", "--boards", 3, "--pairs", 2000, "--maps", spiral, "--json")
    r = json.loads(out)
    assert code == 0 and r["identical"] and r["random_pairs"]["pairs"] == 2000 and r["state_bytes"] == 3
    assert r["oracle_boards"]["boards"] == 3 and r["maps"]["boards"] == 1
    code, out, _ = cli("firmware", "check", "--boards", 1, "--pairs", 10)
    assert code == 0 and "identical (the C state: 3 bytes)" in out


def test_firmware_check_refuses_a_count_over_its_cap(cli, capsys):
    with pytest.raises(SystemExit) as e:
        cli("firmware", "check", "--pairs", 10**12)
    assert e.value.code == 2 and "MAX_CHECK_PAIRS" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv",
    [
        ("cover", "--board", "2x2", "--mcu", "host"),
        ("firmware", "check", "--mcu", "host", "--boards", "0", "--pairs", "0"),
        ("robot", "run", "--port", "loop://", "--mcu", "host"),
    ],
)
def test_mcu_without_the_firmware_is_one_line(cli, argv):
    code, _, err = cli(*argv)
    assert code == 2 and "--mcu names the chip of --fsm firmware" in err


def test_an_unwritable_build_cache_is_one_line(cli, tmp_path, monkeypatch):
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "file"))  # a file where the folder would be
    code, _, err = cli("cover", "--board", "2x2", "--perception", "oracle", "--fsm", "c")
    assert code == 2 and "cannot write the build cache" in err and err.count("\n") == 1
