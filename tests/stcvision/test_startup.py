"""Start-up: ``stcvision --help`` and every command's ``--help`` import only the standard library
and the command line's own light modules, so they answer in the time Python takes to start.

The test holds the import set (``python -X importtime``), not a time: a time depends on the
machine and its load, the set does not. What would make help slow is a third-party package
(scipy.stats ~1.8 s, numba ~0.25 s, OpenCV, rerun, matplotlib, pymunk) or a module that loads one;
defaults that help shows live in modules that import nothing (``controllers.buffon.defaults``,
``calibration.target_options``, ``stc_geometry``).
"""

import subprocess
import sys

import pytest

from stcvision.cli import COMMANDS

#: names -X importtime lists that are not third-party packages: the site hooks of an editable
#: install, and the standard pickle module's probe for Jython's ``org.python.core`` (it fails, but
#: the attempt is listed)
NOT_THIRD_PARTY = {"__editable___stcvision_0_1_0_finder", "_distutils_hack", "sitecustomize", "usercustomize", "org"}


def imported_modules(*argv: str) -> set[str]:
    """The modules ``python -X importtime -m stcvision ARGV`` imports (read from its stderr)."""
    r = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "stcvision", *argv],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    names = set()
    for line in r.stderr.splitlines():
        if line.startswith("import time:") and "|" in line:
            name = line.rsplit("|", 1)[1].strip()
            if name != "imported package":  # the header line
                names.add(name)
    assert "stcvision.cli" in names  # the listing was read
    return names


def third_party(names: set[str]) -> set[str]:
    tops = {n.split(".")[0] for n in names}
    return tops - set(sys.stdlib_module_names) - NOT_THIRD_PARTY - {"stcvision"}


@pytest.mark.parametrize("argv", [("--help",), ("--version",)] + [(name, "--help") for name, _, _ in COMMANDS])
def test_help_imports_no_third_party_package(argv):
    names = imported_modules(*argv)
    assert third_party(names) == set(), f"stcvision {' '.join(argv)} imports {sorted(third_party(names))}"


def test_help_imports_no_computing_module():
    """Of our own modules, help loads the command line, the ground floor's light modules and the
    defaults modules: no stage, simulator, fit or controller."""
    ours = {n for n in imported_modules("--help") if n.startswith("stcvision")}
    allowed_prefixes = ("stcvision.cli", "stcvision.sweep")
    allowed = {
        "stcvision",
        "stcvision.errors",
        "stcvision.fileio",
        "stcvision.limits",
        "stcvision.stc_geometry",
        "stcvision.calibration",
        "stcvision.calibration.target_options",
        "stcvision.controllers",
        "stcvision.controllers.buffon",
        "stcvision.controllers.buffon.defaults",
        "stcvision.controllers.stc",
        "stcvision.controllers.stc.experiments",
        "stcvision.controllers.stc.fault_sweep",
    }
    extra = {n for n in ours if n not in allowed and not n.startswith(allowed_prefixes)}
    assert extra == set()
