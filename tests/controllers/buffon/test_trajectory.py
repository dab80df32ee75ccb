"""buffon --trajectory: trial 0's true paths, a TUM file a visit, which evo reads; evo's path
length of each is the visit's length the measurement uses (L1, L2)."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from stcvision.controllers.buffon.nests import BODY_LENGTH_M
from stcvision.controllers.buffon.trajectory import VISIT_FILES, visit_tum

# evo in a child process with its own home: evo keeps its settings in ~/.evo and makes them on
# first use, which a test must not do in the user's home
EVO_LENGTHS = """
import json, sys
from evo.tools import file_interface
trajs = [file_interface.read_tum_trajectory_file(f) for f in sys.argv[1:]]
print(json.dumps([{"poses": t.num_poses, "path_length_m": float(t.path_length)} for t in trajs]))
"""
STEPS = 2000


def test_evo_path_lengths_are_the_visits_lengths(cli, tmp_path):
    """One trial of fixed visits: the files hold the start and every step, and evo's path
    length of each visit is its L1 / L2 (in body lengths), to the files' 9 decimals over
    2,000 steps (at most 2,000 x 2 x 1e-9 m of rounding)."""
    out = tmp_path / "paths"
    code, text, err = cli("buffon", "--nest", "square:15", "--trials", 1, "--visit-steps", STEPS,
                          "--trajectory", out, "--json")  # fmt: skip
    assert code == 0, err
    r = json.loads(text)
    assert r["trajectory"] == str(out) and r["trajectory_steps"] == [STEPS, STEPS]
    assert sorted(p.name for p in out.iterdir()) == sorted(VISIT_FILES)
    files = [str(out / f) for f in VISIT_FILES]
    env = {**os.environ, "HOME": str(tmp_path)}
    evo = subprocess.run([sys.executable, "-c", EVO_LENGTHS, *files], capture_output=True, text=True, env=env)
    assert evo.returncode == 0, evo.stderr
    v1, v2 = json.loads(evo.stdout)
    assert v1["poses"] == v2["poses"] == STEPS + 1
    assert v1["path_length_m"] / BODY_LENGTH_M == pytest.approx(r["l1_median_u"], abs=STEPS * 4e-9 / BODY_LENGTH_M)
    assert v2["path_length_m"] / BODY_LENGTH_M == pytest.approx(r["l2_median_u"], abs=STEPS * 4e-9 / BODY_LENGTH_M)
    # the same folder again: refused without --force
    code, _, err = cli("buffon", "--nest", "square:15", "--trials", 1, "--visit-steps", 100, "--trajectory", out)
    assert code == 2 and "--force" in err


def test_the_heading_is_the_direction_of_travel():
    """A square walked anticlockwise, with a pause: each sample's heading is that of the step
    leaving it; the pause keeps the heading before it; the last sample that of the step reaching it."""
    path = np.array([[1, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    lines = [list(map(float, ln.split())) for ln in visit_tum((0.0, 0.0), path, 0.5).splitlines()]
    assert [ln[0] for ln in lines] == [0.0, 0.5, 1.0, 1.5, 2.0]
    yaw = [2 * np.arctan2(ln[6], ln[7]) for ln in lines]
    assert yaw == pytest.approx([0.0, 0.0, np.pi / 2, np.pi, np.pi], abs=1e-8)
