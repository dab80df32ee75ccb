"""A task (experiment, parameters, seed), its stable key, and the call that runs it on a worker."""

from __future__ import annotations

import hashlib
import importlib
import json
import os
import socket
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from stcvision.errors import BadInputError

__all__ = ["Task", "canonical_json", "resolve_experiment", "run_task", "seed_sequence"]


def _plain(obj: Any) -> Any:
    """Frozen containers back to plain JSON types (for ``json.dumps``)."""
    if isinstance(obj, Mapping):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, tuple | list):
        return [_plain(v) for v in obj]
    return obj


def canonical_json(obj: Any) -> str:
    """Return the one JSON text of ``obj``: sorted keys, no spaces, no NaN (the input of every key)."""
    return json.dumps(_plain(obj), sort_keys=True, separators=(",", ":"), allow_nan=False, ensure_ascii=True)


def _freeze(obj: Any) -> Any:
    if isinstance(obj, dict):
        return MappingProxyType({k: _freeze(v) for k, v in obj.items()})
    if isinstance(obj, list):
        return tuple(_freeze(v) for v in obj)
    return obj


def _check_experiment(experiment: Any) -> None:
    ok = isinstance(experiment, str) and experiment.count(":") == 1
    if ok:
        mod, fn = experiment.split(":")
        ok = all(p.isidentifier() for p in mod.split(".")) and fn.isidentifier()
    if not ok:
        raise BadInputError(f"experiment {experiment!r} is not 'package.module:function'")


@dataclass(frozen=True, eq=False, slots=True)
class Task:
    """One unit of work: ``experiment(params, seed_sequence)`` -> a JSON-serialisable dict.

    Tasks are equal when their keys are.

    Attributes
    ----------
    experiment : str
        ``"package.module:function"``, importable on every worker.
    params : Mapping
        A JSON-serialisable dict, kept as a read-only copy: later changes to the caller's dict
        do not reach the task.
    seed : int
        An integer >= 0 that, with the two others, makes the task's key.
    key : str
        The SHA-256 (hex) of the canonical JSON of the experiment, the parameters and the seed.

    Raises
    ------
    BadInputError
        When the experiment is not ``package.module:function``, the seed is not an integer
        >= 0, or the parameters are not a JSON-serialisable dict.
    """

    experiment: str
    params: Mapping[str, Any]
    seed: int
    key: str = field(init=False, repr=False)

    def __post_init__(self) -> None:
        _check_experiment(self.experiment)
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise BadInputError(f"task seed must be an integer >= 0, got {self.seed!r}")
        if not isinstance(self.params, Mapping):
            raise BadInputError(f"task params must be a dict, got {type(self.params).__name__}")
        try:
            text = canonical_json({"experiment": self.experiment, "params": self.params, "seed": self.seed})
        except (TypeError, ValueError) as exc:
            raise BadInputError(f"task params of {self.experiment} are not JSON-serialisable: {exc}") from None
        object.__setattr__(self, "params", _freeze(json.loads(canonical_json(self.params))))
        object.__setattr__(self, "key", hashlib.sha256(text.encode()).hexdigest())

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Task) and other.key == self.key

    def __hash__(self) -> int:
        return hash(self.key)

    def params_json(self) -> str:
        """Return the parameters as canonical JSON (what a worker receives).

        Returns
        -------
        str
            Sorted keys, no spaces, no NaN.
        """
        return canonical_json(self.params)


def seed_sequence(key: str):
    """Return the task's random stream root: ``SeedSequence`` of the key's 256 bits.

    Never of the scheduling order, so every backend and worker count gives the same numbers.
    """
    import numpy as np

    return np.random.SeedSequence(int(key, 16))


def resolve_experiment(experiment: str) -> Callable[[dict, Any], dict]:
    """Import ``package.module:function``; a one-line :class:`BadInputError` if it cannot."""
    _check_experiment(experiment)
    mod_name, fn_name = experiment.split(":")
    try:
        mod = importlib.import_module(mod_name)
    except ImportError as exc:
        raise BadInputError(f"experiment {experiment}: cannot import {mod_name} ({exc})") from None
    fn = getattr(mod, fn_name, None)
    if not callable(fn):
        raise BadInputError(f"experiment {experiment}: {mod_name} has no function {fn_name}")
    return fn


def _jsonable(obj: Any) -> Any:
    """Return the result as it will be stored (numpy scalars/arrays to lists); NaN/inf refused."""
    from stcvision.fileio import dumps

    return json.loads(dumps(obj, indent=None))


def run_task(experiment: str, params_json: str, key: str) -> dict:
    """Run one task on a worker. Never raises for the task's own errors: the outcome says.

    Returns ``{"ok": True, "result": dict, ...}`` or ``{"ok": False, "error": one line,
    "traceback": text, ...}``, with the task's wall time and the worker's host and pid.
    """
    t0 = time.perf_counter()
    out: dict[str, Any] = {"worker": f"{socket.gethostname()}:{os.getpid()}"}
    try:
        fn = resolve_experiment(experiment)
        result = fn(json.loads(params_json), seed_sequence(key))
        if not isinstance(result, dict):
            raise TypeError(f"{experiment} returned {type(result).__name__}; expected a dict")
        try:
            result = _jsonable(result)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"{experiment} returned a dict that is not JSON-serialisable: {exc}") from None
        out.update(ok=True, result=result)
    except Exception as exc:  # noqa: BLE001 - a task's failure is data, recorded and retried
        msg = " ".join(str(exc).split()) or "(no message)"
        out.update(ok=False, error=f"{type(exc).__name__}: {msg}", traceback=traceback.format_exc())
    out["wall_s"] = round(time.perf_counter() - t0, 6)
    return out
