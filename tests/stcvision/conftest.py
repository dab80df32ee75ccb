from pathlib import Path

import pytest

SMOKE_RECIPE = Path(__file__).resolve().parents[2] / "datasets" / "recipes" / "smoke.json"


@pytest.fixture(scope="session")
def default_profile():
    from stcvision.calibration.profiles import default_profile

    return default_profile()


@pytest.fixture(scope="session")
def smoke(tmp_path_factory):
    """The tiny shipped 'smoke' recipe generated once per session (read-only: copy it before changing it)."""
    from stcvision.cli import main

    d = tmp_path_factory.mktemp("smoke") / "D"
    assert main(["dataset", "generate", str(SMOKE_RECIPE), "--out", str(d), "--workers", "1"]) == 0
    return d


@pytest.fixture
def session_pids():
    """``session_pids(sid)``: the live processes of a session (to check none outlived a kill)."""
    from stcvision.sweep import session_processes

    return session_processes
