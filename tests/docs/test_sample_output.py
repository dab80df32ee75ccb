"""The demo's summary the first-10-minutes tutorial shows is the demo's own output, line for line
(the wall time aside, which is the reader's machine's): a change to the demo or to the robot that
changes it fails here instead of leaving the page stale."""

import re
from pathlib import Path

import pytest

from stcvision.cli import main

PAGE = Path(__file__).resolve().parents[2] / "docs" / "tutorials" / "first-10-minutes.md"


def _shown_summary() -> list[str]:
    """The first ``text`` block after ``make demo`` on the page."""
    text = PAGE.read_text(encoding="utf-8")
    after = text[text.index("make demo") :]
    m = re.search(r"```text\n(.*?)```", after, re.S)
    assert m, "the page shows no sample output after make demo"
    return m.group(1).splitlines()


def _untimed(lines: list[str]) -> list[str]:
    return [re.sub(r"/ [0-9.]+ s$", "/ (wall) s", line.rstrip()) for line in lines]


@pytest.mark.slow
def test_the_tutorials_demo_summary_is_the_demos_output(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["demo", "--out", "out"]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert _untimed(printed) == _untimed(_shown_summary())
