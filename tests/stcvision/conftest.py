import pytest


@pytest.fixture(scope="session")
def default_profile():
    from calibration.profiles import default_profile

    return default_profile()
