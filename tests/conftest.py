"""Shared fixtures. Paths to the peer data other projects made (used as users would)."""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
PEER = SHARED / "peer_data"


@pytest.fixture(scope="session")
def peer_data() -> Path:
    if not PEER.is_dir():
        pytest.skip(f"peer data not found at {PEER}")
    return PEER


@pytest.fixture(scope="session")
def default_camera():
    from sim_camera.camera import SyntheticCamera

    return SyntheticCamera()
