"""The ant-like STC robot never decides wrongly: one test per cause of a wrong decision or a
needless stop found on the peer maps, each on a small board that shows it, and a small sweep
that must have no wrong decision; and the library's defaults are the command's."""

import json

from controllers.stc.config import CoverConfig
from controllers.stc.loop import run_cover
from sim_camera.board import Board
from stcvision.cli import main

#: what a summary holds that is not the run itself (its wall time, the command's own keys)
_NOT_THE_RUN = ("wall_s", "rrd", "exit_code")


def test_run_cover_defaults_are_the_commands(tmp_path, capsys):
    """``run_cover(board, CoverConfig())`` is ``stcvision cover --map M`` with no options: one
    default (exposure auto, camera perception, webcam, lego, seed 0), defined in CoverConfig. A
    3x3 map the webcam's exposure alone cannot finish (its marks fade) completes both ways."""
    m = tmp_path / "m.txt"
    m.write_text("......\n......\n..##..\n..##..\n......\nS.....\n")  # 3x3 cells, the middle one blocked
    assert main(["cover", "--map", str(m), "--json"]) == 0
    cli = json.loads(capsys.readouterr().out)
    lib = run_cover(Board.from_file(m), CoverConfig())
    assert CoverConfig().exposure == "auto" and lib["exposure"] == "auto"
    assert {k: v for k, v in cli.items() if k not in _NOT_THE_RUN} == {
        k: v for k, v in lib.items() if k not in _NOT_THE_RUN
    }
    assert lib["complete"], lib


def test_cover_help_names_the_librarys_default_exposure(capsys):
    """--help states CoverConfig's default exposure (the parser does not import it, to stay fast)."""
    try:
        main(["cover", "--help"])
    except SystemExit:
        pass
    assert f"(default: {CoverConfig.exposure})" in " ".join(capsys.readouterr().out.split())
