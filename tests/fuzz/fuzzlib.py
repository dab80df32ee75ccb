"""Strategies and checks shared by the fuzz tests (``tests/fuzz`` is a package: they import
it as ``.fuzzlib``).

The contract every fuzz test checks (bad input is refused in one line, never a traceback):
for every input a function returns a result or raises a project error
(:class:`stcvision.errors.StcVisionError`) whose message is one non-empty line; any other
exception fails the test, and hypothesis' deadline bounds the time of each input."""

from __future__ import annotations

import copy
import json
import math
import os

from hypothesis import settings
from hypothesis import strategies as st

from stcvision.errors import StcVisionError

PROFILE = os.environ.get("HYPOTHESIS_PROFILE", "ci")


def examples(weight: float = 1.0, **kw) -> settings:
    """Settings of one test: ``weight`` times the loaded profile's example count (and ``kw``)."""
    return settings(max_examples=max(1, int(weight * settings.get_profile(PROFILE).max_examples)), **kw)


def project_call(fn, *args, **kwargs):
    """``fn(*args, **kwargs)``; a project error is checked (one clear line) and returned, any
    other exception propagates and fails the test."""
    try:
        return fn(*args, **kwargs)
    except StcVisionError as exc:
        check_message(str(exc))
        return exc


def check_message(msg: str) -> None:
    assert msg.strip(), "a project error without a message"
    assert "\n" not in msg.strip(), f"a project error of several lines: {msg!r}"
    assert "Traceback" not in msg, msg


# ------------------------------------------------------------------------------------ values
SPECIAL_FLOATS = st.sampled_from([math.nan, math.inf, -math.inf, 0.0, -0.0, -1.0, 1e-300, 1e300, -1e300])
numbers = st.one_of(
    st.integers(-10, 10),
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    SPECIAL_FLOATS,
)
scalars = st.one_of(st.none(), st.booleans(), numbers, st.text(max_size=8), st.sampled_from(["", "1", "nan", "S", "N"]))
json_values = st.recursive(
    scalars,
    lambda kids: st.one_of(st.lists(kids, max_size=4), st.dictionaries(st.text(max_size=6), kids, max_size=3)),
    max_leaves=8,
)
#: a wrongly-typed or out-of-range value for any field
weird = st.one_of(
    scalars,
    json_values,
    st.lists(numbers, max_size=5),
    st.lists(st.lists(numbers, max_size=3), max_size=13),
)


def _paths(node, prefix=()):
    """(container, key) of every dict entry and list item under ``node``, depth first."""
    if isinstance(node, dict):
        items = list(node.items())
    elif isinstance(node, list):
        items = list(enumerate(node))
    else:
        return
    for k, v in items:
        yield node, k
        yield from _paths(v, (*prefix, k))


def _retyped(v):
    """A value of another JSON type that a sloppy reader might take for ``v``."""
    if isinstance(v, bool):
        return int(v)
    if isinstance(v, int | float):
        return [v] if isinstance(v, int) else str(v)
    if isinstance(v, list):
        return v[0] if v else {}
    if isinstance(v, dict):
        return list(v.values())
    if isinstance(v, str):
        return [v]
    return 0


@st.composite
def mutated(draw, base, max_edits: int = 3, keys=()):
    """``base`` (a JSON object) with a few edits: a field dropped, an unknown field added, a
    value replaced by a weird or special one, retyped, or a number made NaN/inf/huge."""
    d = copy.deepcopy(base)
    extra_keys = st.one_of(st.text(max_size=8), st.sampled_from(list(keys) or ["x"]))
    for _ in range(draw(st.integers(1, max_edits))):
        paths = list(_paths(d))
        op = draw(st.sampled_from(["drop", "add", "replace", "retype", "special", "special"]))
        if op == "add" or not paths:
            target = draw(st.sampled_from([d] + [c[k] for c, k in paths if isinstance(c[k], dict)]))
            target[draw(extra_keys)] = draw(weird)
            continue
        container, key = draw(st.sampled_from(paths))
        if op == "drop":
            container.pop(key) if isinstance(container, dict) else container.pop(key)
        elif op == "replace":
            container[key] = draw(weird)
        elif op == "retype":
            container[key] = _retyped(container[key])
        else:
            container[key] = draw(numbers)
    return d


@st.composite
def json_file_bytes(draw, base_strategy):
    """The bytes of a JSON file: a (mutated) object, possibly truncated, with NaN written as
    JSON's non-standard NaN; or garbage, deep nesting, a huge integer, not UTF-8."""
    kind = draw(st.sampled_from(["doc", "doc", "doc", "truncated", "garbage", "deep", "bigint", "latin1", "empty"]))
    if kind in ("doc", "truncated", "latin1"):
        text = json.dumps(draw(base_strategy), allow_nan=True)
        if kind == "truncated":
            text = text[: draw(st.integers(0, max(0, len(text) - 1)))]
        return text.encode("latin-1", "replace") + (b"\xff" if kind == "latin1" else b"")
    if kind == "garbage":
        return draw(st.binary(max_size=64))
    if kind == "deep":
        n = draw(st.integers(100, 100_000))
        return b"[" * n + b"]" * n
    if kind == "bigint":
        return b'{"schema_version": ' + b"9" * draw(st.integers(4000, 6000)) + b"}"
    return b""
