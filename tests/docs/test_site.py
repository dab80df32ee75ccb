"""The documentation site builds with ``mkdocs build --strict``: no broken link, no missing page,
no docstring mkdocstrings cannot render, a CLI reference generated from the parsers."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_site_builds_strict(tmp_path):
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-5000:]
    cli = (tmp_path / "site" / "reference" / "cli" / "index.html").read_text()
    # every command's own --help is on the page, as argparse prints it
    for command in ("stcvision cover sweep", "stcvision calibrate transform", "stcvision buffon reproduce"):
        assert command in cli
    assert "--list-cameras" in cli and "<!-- cli-reference -->" not in cli
    api = (tmp_path / "site" / "reference" / "api" / "index.html").read_text()
    assert "Pipeline" in api and "run_cover" in api and "subtract_dark" in api


def test_cli_reference_is_the_parsers_help():
    """The generated page holds exactly what ``stcvision COMMAND --help`` prints (at its width)."""
    sys.path.insert(0, str(ROOT / "docs" / "hooks"))
    try:
        import cli_reference
    finally:
        sys.path.pop(0)
    page = cli_reference.cli_reference_markdown()
    env = {**os.environ, "COLUMNS": cli_reference.WIDTH}
    out = subprocess.run(
        [sys.executable, "-m", "stcvision", "calibrate", "neighbors", "--help"], env=env, capture_output=True, text=True
    ).stdout
    assert out.strip() in page
