"""The first run is never a silent compile: a numba compile (a cache miss) is announced once on
stderr, a kernel loaded from the cache says nothing, and the install step's warm-up compiles what
the demo and the pipeline use."""

import subprocess
import sys
from pathlib import Path

from stcvision.compiles import NOTICE

ROOT = Path(__file__).resolve().parents[2]

TWO_COMPILES = """
from stcvision.compiles import announce_compiles
announce_compiles(); announce_compiles()  # idempotent
import sys
assert "numba" not in sys.modules  # listening costs no compiler's import
import numba
f = numba.njit(lambda x: x + 1)
g = numba.njit(lambda x: x * 2)
print(f(1) + g(2))
"""


def test_a_compile_is_announced_once_on_stderr():
    r = subprocess.run([sys.executable, "-c", TWO_COMPILES], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "6"
    assert r.stderr.count(NOTICE) == 1 and r.stdout.count(NOTICE) == 0


def test_warm_runs_and_then_the_demo_loads_every_kernel_from_the_cache(tmp_path):
    stc = str(Path(sys.executable).with_name("stcvision"))
    r = subprocess.run([sys.executable, "-m", "stcvision.warm"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0 and "numba kernels compiled and cached" in r.stderr, r.stderr
    r = subprocess.run([stc, "demo", "--out", str(tmp_path / "d")], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0 and NOTICE not in r.stderr, r.stderr  # nothing left to compile


def test_the_install_step_warms_the_cache():
    make = (ROOT / "Makefile").read_text()
    recipe = make.split("$(STAMP): pyproject.toml")[1].split("\n\n")[0]
    assert "-m stcvision.warm" in recipe and recipe.index("pip install") < recipe.index("stcvision.warm")
