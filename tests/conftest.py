"""Shared fixtures. Paths to the peer data other projects made (used as users would).

The peer files are vendored in ``datasets/peer_data/`` (sources and licences in its README), so a
clone anywhere runs every test: a missing file is a failure, never a skip."""

import signal
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PEER = ROOT / "datasets" / "peer_data"


def pytest_configure(config):
    """A test session started in the background of a non-interactive shell (a CI script's
    ``make test &``, ``nohup``) inherits SIGINT ignored, and so would every command the tests
    start: Python then leaves Ctrl-C ignored too, and the tests that check a command stops on
    Ctrl-C would fail for the shell's reason, not the command's. A handler here (it becomes the
    default action across ``exec``) gives the commands the Ctrl-C a user's terminal gives them."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


SMOKE_RECIPE = ROOT / "datasets" / "recipes" / "smoke.json"


@pytest.fixture(scope="session")
def smoke(tmp_path_factory):
    """The tiny shipped 'smoke' recipe generated once per session (read-only: copy it before changing it)."""
    from stcvision.cli import main

    d = tmp_path_factory.mktemp("smoke") / "D"
    assert main(["dataset", "generate", str(SMOKE_RECIPE), "--out", str(d), "--workers", "1"]) == 0
    return d


@pytest.fixture(scope="session")
def peer_data() -> Path:
    assert PEER.is_dir(), f"the vendored peer data is missing: {PEER}"
    return PEER


@pytest.fixture(scope="session")
def default_camera():
    from stcvision.sim_camera.camera import SyntheticCamera

    return SyntheticCamera()


@pytest.fixture
def cli(capsys):
    """Run ``stcvision ARGV...`` in-process; returns (exit code, stdout, stderr)."""
    from stcvision.cli import main

    def run(*argv) -> tuple[int, str, str]:
        capsys.readouterr()
        code = main([str(a) for a in argv])
        out = capsys.readouterr()
        return code, out.out, out.err

    return run
