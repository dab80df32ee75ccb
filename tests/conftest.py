"""Shared fixtures. Paths to the peer data other projects made (used as users would).

The peer files are vendored in ``datasets/peer_data/`` (sources and licences in its README), so a
clone anywhere runs every test: a missing file is a failure, never a skip."""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PEER = ROOT / "datasets" / "peer_data"


@pytest.fixture(scope="session")
def peer_data() -> Path:
    assert PEER.is_dir(), f"the vendored peer data is missing: {PEER}"
    return PEER


@pytest.fixture(scope="session")
def default_camera():
    from sim_camera.camera import SyntheticCamera

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
