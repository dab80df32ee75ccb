"""The batched path's results to the last digit: a speed-up of the compiled loop must not move one.

The digests below were recorded on the loop as it stood before its rework for speed; each
covers, for every trial, both visits' path lengths, the counts, the blind shares, the
batch-means error and the recorded paths, as exact float64 bytes. A change of any of them, in
any digit, fails the test. (The area estimates follow from these by numpy's vectorised exp and
power, whose last bit may differ between CPUs, so they are left out.)
"""

import hashlib

import numpy as np
import pytest

from stcvision.controllers.buffon.batched import VisitConfig, run_trials
from stcvision.controllers.buffon.nests import parse_nest

# (nest, barrier, config, seed, recorded trial): fixed and online visits, barriers, the
# trail-aware turn (its extra draw), a wide trail, and a first visit that gives up
CASES = {
    "circle": ("circle:30", None, {"visit_steps": 4000}, 0, 1),
    "plus": ("square:20", "plus:0.8", {"visit_steps": 3000}, 7, 0),
    "ellipse": ("ellipse:300:6", None, {"visit_steps": 3000}, 3, None),
    "bar, turn": ("circle:30", "bar:0.9", {"visit_steps": 3000, "trail_turn": 0.5}, 5, 1),
    "wide trail": ("circle:20", None, {"visit_steps": 3000, "trail_width_u": 0.2}, 9, None),
    "online, gives up": ("circle:10", None, {"visit_steps": "auto", "max_visit_steps": 6000}, 11, 0),
    "online, turn": ("circle:20", None, {"visit_steps": "auto", "max_visit_steps": 8000, "trail_turn": 0.5}, 2, 1),
}
# per case: (crossings, self-encounters, robot-steps per trial, sha256 of every float)
GOLDEN = {
    "circle": ([18, 13], [7, 4], [8000, 8000], "a7e50bfc926f12fbdf6d3232cff442bdb0e59c10664c40b09fb9c1fd5c5cd7f7"),
    "plus": ([40, 37], [19, 3], [6000, 6000], "7a37005cb53b29e8b8b3cd3da880d6352bbd7cebd5ad3377e85256e620947504"),
    "ellipse": ([39, 25], [8, 7], [6000, 6000], "65907c094a8c1e920b93060f1d1e981984b7778df48bfdc2b0e358a54f34d1a2"),
    "bar, turn": ([17, 31], [9, 4], [6000, 6000], "5b6763a7612eb53407c167122a41ec4d3f6d026037c6c8286414babdee949bb0"),
    "wide trail": ([29, 25], [5, 10], [6000, 6000], "8bd33d295775f538eb6210b5463fa08d0f6bb4249880f113d7926aff6afc8ef3"),
    "online, gives up": (
        [107, 56],
        [40, 73],
        [8432, 12000],
        "2a32e2b28dfc5343badc04c7fb3458490667911bad8afa72f4fef306fc50286f",
    ),
    "online, turn": (
        [145, 138],
        [108, 80],
        [16000, 16000],
        "5a0d98b170a85a11cad45d1e4756b237ba4aa65db6710c3eea559d093d98e80b",
    ),
}


def _digest(ts) -> str:
    h = hashlib.sha256()
    for a in (ts.l1_u, ts.l2_u, ts.blind_fraction, ts.rate_rel_se, ts.self_blind, ts.converged):
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    h.update(np.int64(ts.escapes).tobytes())
    for k in sorted(ts.trails):
        h.update(k.encode())
        h.update(np.ascontiguousarray(ts.trails[k], dtype=np.float64).tobytes())
    return h.hexdigest()


def _run(name):
    spec, barrier, cfg, seed, record = CASES[name]
    ts = run_trials(parse_nest(spec, barrier), VisitConfig(**cfg), trials=2, seed=seed, record_trial=record)
    return ([int(v) for v in ts.crossings], [int(v) for v in ts.n_self], [int(v) for v in ts.steps], _digest(ts))


@pytest.mark.parametrize("name", CASES)
def test_results_unchanged_to_the_last_digit(name):
    assert _run(name) == GOLDEN[name]
