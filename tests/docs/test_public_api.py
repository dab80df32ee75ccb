"""``from stcvision import Pipeline, Profile, run_cover, ...``: every public name of the package
is the object its home module defines, and ``import stcvision`` alone loads none of them."""

import importlib
import subprocess
import sys

import pytest

import stcvision


@pytest.mark.parametrize("name", sorted(stcvision._LAZY))
def test_public_name_is_its_modules_object(name):
    module, attr = stcvision._LAZY[name]
    home = importlib.import_module(module)
    expected = home if attr is None else getattr(home, attr)
    assert getattr(stcvision, name) is expected
    assert name in stcvision.__all__ and name in dir(stcvision)


def test_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no_such_name"):
        stcvision.no_such_name  # noqa: B018


def test_from_import_of_the_documented_names():
    ns = {}
    exec("from stcvision import Pipeline, Profile, run_cover, CoverConfig, Board, stages", ns)
    assert ns["Pipeline"].__name__ == "Pipeline" and callable(ns["run_cover"])
    assert callable(ns["stages"].subtract_dark)


def test_import_stcvision_stays_light():
    """The lazy names cost nothing until used: no OpenCV, numba, simulator or controller."""
    code = (
        "import sys, stcvision; heavy = [m for m in ('cv2', 'numba', 'stcvision.sim_camera', 'stcvision.controllers', "
        "'stcvision.pipeline') if m in sys.modules]; print(heavy)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_all_lists_exactly_the_public_names():
    assert set(stcvision.__all__) == set(stcvision._LAZY) | {"BadInputError", "StcVisionError", "__version__"}
