"""One sweep runner for every big job (knows nothing of robots).

A :class:`Task` is ``(experiment, params, seed)``: ``experiment`` names a function
``"package.module:function"`` called on a worker as ``fn(params: dict, seed:
numpy.random.SeedSequence) -> dict``; the task's ``key`` is the sha256 of the canonical JSON of
the three, and ``seed`` is ``SeedSequence(int(key, 16))``: the numbers a task draws depend on what
it is, never on which worker runs it or when, so every backend and worker count gives the same
results. The function should spawn one child stream per component (``seed.spawn(n)``).

:func:`run_sweep` runs the tasks not already done in a store (JSONL, one fsync'ed line per
finished task: see :mod:`stcvision.sweep._store`), on a local process pool sized to the machine
(``--workers N``; 1 runs in this process) or on an existing Dask cluster (``--scheduler
tcp://HOST:PORT``, the optional ``dask`` extra), with one tqdm bar, and returns a
:class:`SweepReport`. A failed task is recorded with its error and retried by the next run;
``--fresh`` starts over. :mod:`stcvision.sweep.selftest` holds cheap experiments for trying a
backend and measuring the runner's own cost. Commands add the three options with :func:`add_sweep_arguments` and
read them with :func:`sweep_options_from_args`::

    from stcvision.sweep import Task, SweepOptions, run_sweep
    tasks = [Task(experiment="mypkg.exp:trial", params={"n": n}, seed=s) for n in (8, 16) for s in range(4)]
    report = run_sweep(tasks, "out/sweep.jsonl", SweepOptions(workers=2), desc="trials")
    print(report.summary()); rows = list(report.results.values())
"""

from stcvision.sweep._run import (
    SweepOptions,
    SweepReport,
    add_sweep_arguments,
    machine_workers,
    output_folder,
    run_sweep,
    sweep_options_from_args,
)
from stcvision.sweep._store import read_store
from stcvision.sweep._task import Task, seed_sequence
from stcvision.sweep._worker import session_processes

__all__ = [
    "SweepOptions",
    "SweepReport",
    "Task",
    "add_sweep_arguments",
    "machine_workers",
    "output_folder",
    "read_store",
    "run_sweep",
    "seed_sequence",
    "session_processes",
    "sweep_options_from_args",
]
