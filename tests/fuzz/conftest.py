"""Hypothesis profiles and the case counter of the fuzz tests (tests/fuzz).

Two profiles, chosen by the environment variable ``HYPOTHESIS_PROFILE``:

* ``ci`` (default, what ``make test`` runs): few examples per test, derandomized (the same
  inputs on every run), no example database, so the suite stays deterministic and fast;
* ``fuzz`` (``make fuzz``): many examples per test (>= 10,000 cases in all), still
  derandomized so that a pass or a failure reproduces; a failure prints the falsifying input.

Every fuzz test is marked ``fuzz`` (``pytest -m fuzz``). The number of cases each test ran is
counted (by wrapping hypothesis' documented ``inner_test`` hook) and printed at the end of the
run, also across xdist workers, so the case count of ``make fuzz`` can be checked.
"""

from __future__ import annotations

import collections
import functools
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

#: a test's example count is ``weight`` x the profile's (``fuzzlib.examples``): cheap tests get more.
#: The deadline (10 s per input) is far above the measured per-input times (milliseconds to a few
#: hundred) so that a loaded machine does not fail it, and still catches a hang (a thin nest once
#: took 35 s to reject)
_COMMON = dict(
    derandomize=True,
    database=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
)
settings.register_profile("ci", max_examples=12, deadline=10_000, **_COMMON)
settings.register_profile("fuzz", max_examples=220, deadline=10_000, **_COMMON)
PROFILE = os.environ.get("HYPOTHESIS_PROFILE", "ci")
settings.load_profile(PROFILE)

CASES: collections.Counter = collections.Counter()


def pytest_collection_modifyitems(config, items):
    for item in items:
        if Path(str(item.fspath)).resolve().parent != Path(__file__).resolve().parent:
            continue
        item.add_marker(pytest.mark.fuzz)
        hyp = getattr(getattr(item, "obj", None), "hypothesis", None)
        if hyp is None or getattr(hyp.inner_test, "_fuzz_counted", False):
            continue
        inner, name = hyp.inner_test, item.nodeid

        @functools.wraps(inner)
        def counted(*a, _inner=inner, _name=name, **kw):
            CASES[_name] += 1
            return _inner(*a, **kw)

        counted._fuzz_counted = True
        hyp.inner_test = counted


def pytest_sessionfinish(session):
    if hasattr(session.config, "workeroutput"):  # an xdist worker: hand the counts to the controller
        session.config.workeroutput["fuzz_cases"] = dict(CASES)


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    CASES.update(getattr(node, "workeroutput", {}).get("fuzz_cases", {}))


def pytest_terminal_summary(terminalreporter):
    if CASES:
        terminalreporter.write_line(
            f"fuzz: {sum(CASES.values())} cases in {len(CASES)} tests (hypothesis profile {PROFILE!r})"
        )
