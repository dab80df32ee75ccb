"""Run tasks on a backend (in-process, a local process pool, a Dask cluster) into a store."""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Iterable, Iterator
from contextlib import closing
from dataclasses import dataclass, field
from pathlib import Path

from stcvision.errors import BadInputError, StcVisionError
from stcvision.sweep._store import Store
from stcvision.sweep._task import Task, resolve_experiment, run_task

__all__ = [
    "SweepOptions",
    "SweepReport",
    "add_sweep_arguments",
    "machine_workers",
    "run_sweep",
    "sweep_options_from_args",
]

_DASK_MISSING = "--scheduler needs Dask: pip install 'stcvision[dask]' (dask[distributed])"


def output_folder(out: str | os.PathLike, outputs: Iterable[str], *, store: str, force: bool, what: str) -> Path:
    """Check and create a sweep's output folder.

    The folder may be new, hold none of ``outputs``, hold its ``store`` (an earlier run of the
    same command: it resumes and rewrites its outputs), or be taken with ``force``. Anything
    else is a user's folder, refused in one line naming ``what`` runs there.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise BadInputError(f"{out} is a file; expected a folder for the {what}'s outputs")
    taken = [name for name in outputs if (out / name).exists()]
    if taken and not force and not (out / store).exists():
        from stcvision.errors import FileExistsRefusedError

        raise FileExistsRefusedError(f"{out / taken[0]} exists and {out} holds no {what}; use --force")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise BadInputError(f"cannot create the folder {out}: {e.strerror}") from None
    return out


def machine_workers() -> int:
    """Count the CPUs this process may run on (the default size of the local pool)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@dataclass(frozen=True, slots=True)
class SweepOptions:
    """Where and how a sweep runs (``SweepOptions(workers, scheduler, fresh)``, all optional).

    Attributes
    ----------
    workers : int or None
        Processes of the local pool (None: one per CPU of the machine; 1 runs in this process).
        Ignored with ``scheduler``.
    scheduler : str or None
        Address of an existing Dask scheduler, ``tcp://HOST:PORT`` (None: local pool).
    fresh : bool
        Forget the store's results and run every task again.

    Raises
    ------
    BadInputError
        When ``workers`` is not an integer >= 1 or ``scheduler`` is not an address.
    """

    workers: int | None = None
    scheduler: str | None = None
    fresh: bool = False

    def __post_init__(self) -> None:
        if self.workers is not None and (isinstance(self.workers, bool) or not isinstance(self.workers, int)):
            raise BadInputError(f"workers must be an integer >= 1, got {self.workers!r}")
        if self.workers is not None and self.workers < 1:
            raise BadInputError(f"--workers must be >= 1, got {self.workers}")
        if self.scheduler is not None and "://" not in self.scheduler:
            raise BadInputError(f"--scheduler {self.scheduler!r} is not an address like tcp://HOST:8786")

    @property
    def backend(self) -> str:
        """Where the tasks run, in words: in-process, a local pool of N, or dask and its address."""
        if self.scheduler:
            return f"dask {self.scheduler}"
        n = self.workers or machine_workers()
        return "in-process" if n == 1 else f"local pool of {n}"


@dataclass(kw_only=True, slots=True)
class SweepReport:
    """What a sweep did: a plain record, the caller's to keep or change (the store is the truth).

    ``results``: key -> result of every successful task, in task order, those done by earlier
    runs included; ``failed``: key -> one-line error.
    """

    desc: str
    total: int
    skipped: int  # tasks already done in the store, not run again
    ran: int  # tasks run now (succeeded or failed)
    wall_s: float
    backend: str
    results: dict[str, dict] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)
    skipped_keys: frozenset[str] = frozenset()  # the tasks counted in ``skipped``
    store: str = ""

    def raise_if_failed(self, what: str = "tasks", name=None) -> None:
        """Raise a one-line error (exit 2) if any task failed.

        The line reads ``N of M <what> failed[, e.g. <name(key)>]: <its error>; re-run to retry
        them`` (the store keeps every error; a re-run retries).
        """
        if not self.failed:
            return
        key, err = next(iter(self.failed.items()))
        which = f", e.g. {name(key)}" if name is not None else ""
        raise BadInputError(f"{len(self.failed)} of {self.total} {what} failed{which}: {err}; re-run to retry them")

    @property
    def tasks_per_s(self) -> float | None:
        """Tasks run now per second of wall time (None when none ran)."""
        return self.ran / self.wall_s if self.ran and self.wall_s > 0 else None

    def summary(self, *, max_errors: int = 10) -> str:
        """Say what the sweep did, in lines of text: counts, time, backend, store, the first failures."""
        rate = self.tasks_per_s
        lines = [
            f"{self.desc}: {self.total} tasks, {len(self.results)} done ({self.skipped} skipped as done by an "
            f"earlier run), {len(self.failed)} failed; {self.ran} run in {self.wall_s:.1f} s on {self.backend}"
            + (f" ({rate:.3g} tasks/s)" if rate else "")
            + f"; store {self.store}"
        ]
        for i, (key, err) in enumerate(self.failed.items()):
            if i == max_errors:
                lines.append(f"  ... and {len(self.failed) - max_errors} more failures (see the store)")
                break
            lines.append(f"  failed {key[:12]}: {err}")
        if self.failed:
            lines.append("  failed tasks are retried by the next run with the same store")
        return "\n".join(lines)


def add_sweep_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--workers N``, ``--scheduler tcp://HOST:PORT`` and ``--fresh`` to a command."""

    def workers(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if n < 1:
            raise argparse.ArgumentTypeError(f"{text!r} must be >= 1")
        return n

    def address(text: str) -> str:
        if "://" not in text:
            raise argparse.ArgumentTypeError(f"{text!r} is not a scheduler address like tcp://HOST:8786")
        return text

    g = parser.add_argument_group("where the work runs (stcvision.sweep)")
    x = g.add_mutually_exclusive_group()
    x.add_argument(
        "--workers",
        type=workers,
        metavar="N",
        help=f"processes of the local pool (default: one per CPU, here {machine_workers()}; 1 runs in this process)",
    )
    x.add_argument(
        "--scheduler",
        type=address,
        metavar="tcp://HOST:PORT",
        help="run the tasks on an existing Dask cluster (needs the dask extra; see the docs, Scale out on Dask)",
    )
    g.add_argument("--fresh", action="store_true", help="forget finished tasks in the store and run everything again")


def sweep_options_from_args(args: argparse.Namespace) -> SweepOptions:
    return SweepOptions(
        workers=getattr(args, "workers", None),
        scheduler=getattr(args, "scheduler", None),
        fresh=bool(getattr(args, "fresh", False)),
    )


# ------------------------------------------------------------------------------------ backends
def _in_process(tasks: list[Task]) -> Iterator[tuple[Task, dict]]:
    for t in tasks:
        yield t, run_task(t.experiment, t.params_json(), t.key)


#: one thread per worker process: the pool already runs one process per core, and numpy's BLAS
#: and OpenCV would each start a thread per core in every worker (Dask's nanny sets the first
#: three for its workers by default)
ONE_THREAD_ENV = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "OPENCV_FOR_THREADS_NUM": "1",
}


#: how long a worker asked to stop (SIGTERM) gets before it is killed (SIGKILL)
STOP_GRACE_S = 0.5


def _stop_pool(ex) -> None:
    """Stop a pool now.

    Drop the tasks not started and end the workers running one (their tasks are lost; every
    finished one is already in the store). Without this, an interrupted sweep
    would wait for each running task to end (a closed-loop run: tens of seconds) before exiting.
    """
    procs = list((getattr(ex, "_processes", None) or {}).values())  # CPython's own table of workers
    ex.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        if p.is_alive():
            p.terminate()
    deadline = time.monotonic() + STOP_GRACE_S
    for p in procs:
        p.join(max(0.0, deadline - time.monotonic()))
        if p.is_alive():
            p.kill()
            p.join(1.0)


def _local_pool(tasks: list[Task], workers: int) -> Iterator[tuple[Task, dict]]:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    from stcvision.sweep._worker import init_worker

    # spawn: a worker starts clean (no copy of this process's threads, locks or open files)
    ex = ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=init_worker,
        initargs=(os.getpid(), ONE_THREAD_ENV),
    )
    try:
        futs = {ex.submit(run_task, t.experiment, t.params_json(), t.key): t for t in tasks}
        for fut in as_completed(futs):
            try:
                yield futs[fut], fut.result()
            except BrokenProcessPool as exc:
                yield futs[fut], {"ok": False, "error": f"worker process died ({exc})", "traceback": ""}
    except BaseException:  # interrupted (Ctrl-C, SIGTERM, an error in the caller, close()): stop now
        _stop_pool(ex)
        raise
    ex.shutdown(wait=True)


def _dask(tasks: list[Task], address: str) -> Iterator[tuple[Task, dict]]:
    try:
        import distributed
    except ImportError:
        raise StcVisionError(_DASK_MISSING) from None
    try:
        client = distributed.Client(address, timeout="20s", set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise StcVisionError(f"cannot reach the Dask scheduler at {address}: {' '.join(str(exc).split())}") from None
    try:
        futs = {
            client.submit(run_task, t.experiment, t.params_json(), t.key, key=f"stcvision-{t.key}", pure=False): t
            for t in tasks
        }
        for fut in distributed.as_completed(futs, loop=client.loop):
            if fut.status == "error":  # the worker died under it (run_task itself never raises)
                exc = fut.exception()
                yield futs[fut], {"ok": False, "error": f"{type(exc).__name__}: {exc}", "traceback": ""}
            else:
                yield futs[fut], fut.result()
            fut.release()
    finally:
        client.close()


# ------------------------------------------------------------------------------------ runner
def _check(tasks: Iterable[Task]) -> list[Task]:
    out, seen = [], set()
    for t in tasks:
        if not isinstance(t, Task):
            raise BadInputError(f"run_sweep takes Task objects, got {type(t).__name__}")
        if t.key in seen:
            raise BadInputError(f"task {t.experiment} {t.params_json()} seed {t.seed} is listed twice")
        seen.add(t.key)
        out.append(t)
    for exp in {t.experiment for t in out}:
        resolve_experiment(exp)  # a typo fails here, once, not on every worker
    return out


def run_sweep(
    tasks: Iterable[Task], store_path: str | os.PathLike, opts: SweepOptions = SweepOptions(), *, desc: str = "sweep"
) -> SweepReport:
    """Run every task not already done in the store; append each result as it finishes.

    Progress: one tqdm bar on stderr (done/total, failures, ETA; off when stderr is not a
    terminal). A task's failure is recorded with its error and does not stop the others.

    Parameters
    ----------
    tasks : iterable of Task
        The tasks, each listed once.
    store_path : str or os.PathLike
        The store: the results of every task run so far (an earlier run's are not run again).
    opts : SweepOptions
        Where and how the tasks run: in this process, a local pool, or a Dask cluster.
    desc : str
        The progress bar's and the report's label.

    Returns
    -------
    SweepReport
        What the sweep did: every result in task order, the failures, the counts and the time.

    Raises
    ------
    BadInputError
        When an item is not a :class:`Task`, a task is listed twice, or an experiment cannot be
        imported.
    """
    from tqdm import tqdm

    tasks = _check(tasks)
    t0 = time.perf_counter()
    results: dict[str, dict] = {}
    failed: dict[str, str] = {}
    with Store(Path(store_path), fresh=opts.fresh) as store:
        done = store.done()
        todo = [t for t in tasks if t.key not in done]
        skipped = len(tasks) - len(todo)
        n = min(opts.workers or machine_workers(), max(len(todo), 1))  # no idle processes
        label = opts.backend if opts.scheduler else SweepOptions(workers=n).backend
        if not todo:
            backend = _in_process([])
        elif opts.scheduler:
            backend = _dask(todo, opts.scheduler)
        elif n == 1:
            backend = _in_process(todo)
        else:
            backend = _local_pool(todo, n)
        with (
            closing(backend),  # on any exception here the pool stops at once, not when collected
            tqdm(total=len(tasks), initial=skipped, desc=desc, unit="task", disable=None, dynamic_ncols=True) as bar,
        ):
            for task, outcome in backend:
                store.append(task, outcome)
                if outcome["ok"]:
                    results[task.key] = outcome["result"]
                else:
                    failed[task.key] = outcome["error"]
                bar.update(1)
                if failed:
                    bar.set_postfix(failed=len(failed), refresh=False)
    ordered = {
        t.key: (done[t.key] if t.key in done else results[t.key]) for t in tasks if t.key in done or t.key in results
    }
    return SweepReport(
        desc=desc,
        total=len(tasks),
        skipped=skipped,
        ran=len(todo),
        wall_s=time.perf_counter() - t0,
        backend=label,
        results=ordered,
        failed={t.key: failed[t.key] for t in tasks if t.key in failed},
        skipped_keys=frozenset(t.key for t in tasks if t.key in done),
        store=str(store_path),
    )
