import pytest


@pytest.fixture(scope="session")
def default_profile():
    from stcvision.calibration.profiles import default_profile

    return default_profile()


@pytest.fixture
def session_pids():
    """``session_pids(sid)``: the live processes of a session (to check none outlived a kill)."""
    from stcvision.sweep import session_processes

    return session_processes
