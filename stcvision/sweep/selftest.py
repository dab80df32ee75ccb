"""Cheap experiments for the sweep's own tests and its overhead benchmark.

They live in the package (not in ``tests/``) because a spawned pool worker or a Dask worker must
be able to import them by name. ``python -m stcvision.sweep.selftest STORE N`` runs a sweep of
``N`` :func:`draws` tasks into ``STORE`` (the crash test kills it mid-run).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from stcvision.errors import StcVisionError
from stcvision.sweep._run import SweepOptions, add_sweep_arguments, run_sweep, sweep_options_from_args
from stcvision.sweep._task import Task

_MODULE = "stcvision.sweep.selftest"  # not __name__: that is "__main__" under python -m

__all__ = ["draws", "draws_tasks", "fails_until", "measure_overhead", "noop"]


def draws(params: dict, seed: np.random.SeedSequence) -> dict:
    """Random numbers from the task's seed stream (two child streams, as a real experiment
    spawns one per component), after an optional sleep of ``params["sleep_s"]``."""
    time.sleep(float(params.get("sleep_s", 0.0)))
    a, b = (np.random.default_rng(s) for s in seed.spawn(2))
    return {"x": params["x"], "uniform": a.random(3), "integer": int(b.integers(2**62))}


def fails_until(params: dict, seed: np.random.SeedSequence) -> dict:
    """Fails while the file ``params["exists"]`` does not exist (a failure fixed between runs)."""
    if not Path(params["exists"]).exists():
        raise RuntimeError(f"{params['exists']} is missing")
    return draws(params, seed)


def noop(params: dict, seed: np.random.SeedSequence) -> dict:
    """Does nothing: the sweep's own cost per task."""
    return {}


def draws_tasks(n: int, *, sleep_s: float = 0.0, seed: int = 0, fast: int = 0) -> list[Task]:
    """``n`` draws tasks sleeping ``sleep_s`` each, but for the first ``fast`` (no sleep)."""
    return [
        Task(experiment=f"{_MODULE}:draws", params={"x": i, "sleep_s": 0.0 if i < fast else sleep_s}, seed=seed)
        for i in range(n)
    ]


def measure_overhead(opts: SweepOptions, store: Path, n: int = 400) -> dict:
    """Wall time per no-op task through ``opts``'s backend, pool/cluster start-up excluded (a
    first sweep of ``n`` tasks warms the workers; the second, fresh one is timed)."""
    tasks = [Task(experiment=f"{_MODULE}:noop", params={"i": i}, seed=0) for i in range(n)]
    run_sweep(tasks, store, SweepOptions(workers=opts.workers, scheduler=opts.scheduler, fresh=True), desc="warm-up")
    rep = run_sweep(tasks, store, SweepOptions(workers=opts.workers, scheduler=opts.scheduler, fresh=True), desc="noop")
    return {"backend": rep.backend, "tasks": n, "wall_s": rep.wall_s, "ms_per_task": 1e3 * rep.wall_s / n}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="run a sweep of cheap draws tasks (the sweep's crash test)")
    ap.add_argument("store")
    ap.add_argument("n", type=int)
    ap.add_argument("--sleep-s", type=float, default=0.0)
    ap.add_argument("--fast", type=int, default=0, help="the first FAST tasks do not sleep")
    add_sweep_arguments(ap)
    args = ap.parse_args(argv)
    try:
        rep = run_sweep(
            draws_tasks(args.n, sleep_s=args.sleep_s, fast=args.fast),
            args.store,
            sweep_options_from_args(args),
            desc="draws",
        )
    except StcVisionError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    print(rep.summary(), file=sys.stderr)
    return 0 if not rep.failed else 1


if __name__ == "__main__":
    sys.exit(main())
