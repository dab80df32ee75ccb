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


#: what names a frame and its time in a result line (the frame's file, its time, a bag's stamp)
FRAME_IDENTITY = ("frame", "t_s", "stamp_ns")


def _results_only(d):
    if isinstance(d, dict):
        return {k: _results_only(v) for k, v in d.items() if not k.endswith("_ms") and k not in FRAME_IDENTITY}
    if isinstance(d, list):
        return [_results_only(v) for v in d]
    return d


@pytest.fixture
def results_only():
    """A result line without its wall-clock timings (the only part that may differ run to run)
    and without what names its frame and its time: what two sources of the same frames share."""
    return _results_only
