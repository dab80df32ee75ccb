"""stcvision.sweep: keys, seeds from keys, backends giving identical results, the store surviving
a SIGKILL, failed tasks retried, --fresh, refusals."""

import argparse
import hashlib
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from stcvision.errors import BadInputError, FileExistsRefusedError, StcVisionError
from stcvision.sweep import (
    SweepOptions,
    Task,
    add_sweep_arguments,
    read_store,
    run_sweep,
    seed_sequence,
    sweep_options_from_args,
)
from stcvision.sweep._store import Store
from stcvision.sweep.selftest import draws, draws_tasks

DRAWS = "stcvision.sweep.selftest:draws"


def ok_keys(store) -> list[str]:
    return [r["key"] for r in read_store(store) if r["status"] == "ok"]


def test_key_is_the_sha256_of_the_canonical_json_and_params_are_a_frozen_copy():
    params = {"b": [1, 2.5], "a": {"z": None, "y": "s"}}
    t = Task(experiment=DRAWS, params=params, seed=3)
    text = json.dumps({"experiment": DRAWS, "params": params, "seed": 3}, sort_keys=True, separators=(",", ":"))
    assert t.key == hashlib.sha256(text.encode()).hexdigest()
    assert Task(experiment=DRAWS, params={"a": {"y": "s", "z": None}, "b": [1, 2.5]}, seed=3) == t
    assert (
        len({t.key, Task(experiment=DRAWS, params=params, seed=4).key, Task(experiment=DRAWS, params={}, seed=3).key})
        == 3
    )
    params["b"].append(9)  # the caller's dict changes; the task does not
    assert t.params["b"] == (1, 2.5) and t.key == hashlib.sha256(text.encode()).hexdigest()
    with pytest.raises(TypeError):
        t.params["c"] = 1
    with pytest.raises(BadInputError, match="JSON"):
        Task(experiment=DRAWS, params={"x": object()}, seed=0)
    with pytest.raises(BadInputError, match="JSON"):
        Task(experiment=DRAWS, params={"x": float("nan")}, seed=0)
    with pytest.raises(BadInputError, match="package.module:function"):
        Task(experiment="draws", params={}, seed=0)
    with pytest.raises(BadInputError, match="seed"):
        Task(experiment=DRAWS, params={}, seed=-1)


def test_seed_comes_from_the_key_so_workers_and_order_do_not_matter(tmp_path):
    tasks = draws_tasks(8)
    one = run_sweep(tasks, tmp_path / "a.jsonl", SweepOptions(workers=1))
    two = run_sweep(tasks[::-1], tmp_path / "b.jsonl", SweepOptions(workers=2))
    assert one.backend == "in-process" and two.backend == "local pool of 2"
    assert dict(one.results) == dict(two.results) and len(one.results) == 8 and not one.failed
    assert json.loads(json.dumps(one.results)) == one.results  # plain dicts, ready to save
    assert list(one.results) == [t.key for t in tasks]  # in task order, whatever the finishing order
    t = tasks[5]
    direct = draws(dict(t.params), np.random.SeedSequence(int(t.key, 16)))
    assert one.results[t.key] == {"x": 5, "uniform": direct["uniform"].tolist(), "integer": direct["integer"]}
    assert seed_sequence(t.key).entropy == int(t.key, 16)
    assert len({r["integer"] for r in one.results.values()}) == 8  # every task its own stream


@pytest.fixture(scope="module")
def dask_cluster():
    import distributed  # a dev dependency: its absence is a broken install, not a skip

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        yield cluster.scheduler_address


def test_dask_cluster_gives_the_local_pools_results(tmp_path, dask_cluster):
    tasks = draws_tasks(12) + [
        Task(experiment="stcvision.sweep.selftest:fails_until", params={"exists": "/nonexistent", "x": 0}, seed=0)
    ]
    local = run_sweep(tasks, tmp_path / "local.jsonl", SweepOptions(workers=2))
    remote = run_sweep(tasks, tmp_path / "dask.jsonl", SweepOptions(scheduler=dask_cluster), desc="dask")
    assert remote.backend == f"dask {dask_cluster}"
    assert dict(remote.results) == dict(local.results) and len(remote.results) == 12
    assert dict(remote.failed) == dict(local.failed) and "/nonexistent is missing" in next(iter(remote.failed.values()))
    # the workers really were the cluster's processes
    workers = {r["worker"] for r in read_store(tmp_path / "dask.jsonl")}
    assert all(w.split(":")[1] != str(os.getpid()) for w in workers)


@pytest.mark.slow
def test_a_sigkilled_sweep_resumes_with_every_key_once_and_equal_to_an_uninterrupted_run(tmp_path):
    store, n = tmp_path / "killed.jsonl", 40
    proc = subprocess.Popen(
        [sys.executable, "-m", "stcvision.sweep.selftest", str(store), str(n), "--workers", "2", "--sleep-s", "0.1"],
        start_new_session=True,  # its own process group: the kill takes the pool workers too
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and (not store.exists() or len(store.read_bytes().splitlines()) < 7):
            time.sleep(0.02)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    before = ok_keys(store)
    assert proc.returncode == -signal.SIGKILL and 6 <= len(before) < n  # killed mid-sweep
    with open(store, "ab") as f:  # and as if the kill had torn a line in half
        f.write(b'{"key": "0123", "status": "o')
    resumed = run_sweep(draws_tasks(n, sleep_s=0.1), store, SweepOptions(workers=2))
    assert resumed.skipped == len(before) and resumed.ran == n - len(before) and not resumed.failed
    keys = ok_keys(store)
    assert sorted(keys) == sorted(t.key for t in draws_tasks(n, sleep_s=0.1)) and len(keys) == len(set(keys)) == n
    clean = run_sweep(draws_tasks(n, sleep_s=0.1), tmp_path / "clean.jsonl", SweepOptions(workers=2))
    assert dict(resumed.results) == dict(clean.results)
    assert {r["key"]: r["result"] for r in read_store(store)} == dict(clean.results)


def test_a_failed_task_is_recorded_with_its_error_and_retried_next_run(tmp_path):
    flag = tmp_path / "fixed"
    bad = Task(experiment="stcvision.sweep.selftest:fails_until", params={"exists": str(flag), "x": 99}, seed=1)
    tasks = [*draws_tasks(3), bad]
    first = run_sweep(tasks, tmp_path / "s.jsonl", SweepOptions(workers=1))
    assert list(first.failed) == [bad.key] and first.failed[bad.key] == f"RuntimeError: {flag} is missing"
    assert len(first.results) == 3 and bad.key not in first.results
    assert "1 failed" in first.summary() and f"failed {bad.key[:12]}: RuntimeError" in first.summary()
    rec = read_store(tmp_path / "s.jsonl")[-1]
    assert rec["status"] == "failed" and "Traceback" in rec["traceback"] and rec["params"]["x"] == 99
    flag.touch()
    second = run_sweep(tasks, tmp_path / "s.jsonl", SweepOptions(workers=1))
    assert second.skipped == 3 and second.ran == 1 and not second.failed and len(second.results) == 4
    assert second.results[bad.key]["x"] == 99
    third = run_sweep(tasks, tmp_path / "s.jsonl", SweepOptions(workers=1))
    assert third.ran == 0 and third.skipped == 4 and dict(third.results) == dict(second.results)


def test_fresh_runs_everything_again(tmp_path):
    s = tmp_path / "s.jsonl"
    run_sweep(draws_tasks(4), s, SweepOptions(workers=1))
    again = run_sweep(draws_tasks(4), s, SweepOptions(workers=1, fresh=True))
    assert again.skipped == 0 and again.ran == 4 and len(read_store(s)) == 4


def test_refusals_are_one_line_errors(tmp_path, monkeypatch):
    mine = tmp_path / "notes.txt"
    mine.write_text("my notes\n")
    with pytest.raises(FileExistsRefusedError, match="not a sweep store"):
        run_sweep(draws_tasks(1), mine, SweepOptions(workers=1, fresh=True))
    assert mine.read_text() == "my notes\n"
    with Store(tmp_path / "busy.jsonl"), pytest.raises(StcVisionError, match="in use by another sweep"):
        run_sweep(draws_tasks(1), tmp_path / "busy.jsonl", SweepOptions(workers=1))
    with pytest.raises(BadInputError, match="cannot import"):
        run_sweep([Task(experiment="no_such_pkg.mod:fn", params={}, seed=0)], tmp_path / "x.jsonl")
    with pytest.raises(BadInputError, match="twice"):
        run_sweep(draws_tasks(2) * 2, tmp_path / "x.jsonl")
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if dask were not installed
    with pytest.raises(StcVisionError, match=r"pip install 'stcvision\[dask\]'"):
        run_sweep(draws_tasks(1), tmp_path / "y.jsonl", SweepOptions(scheduler="tcp://127.0.0.1:8786"))


def test_command_line_options(capsys):
    p = argparse.ArgumentParser()
    add_sweep_arguments(p)
    assert sweep_options_from_args(p.parse_args([])) == SweepOptions()
    o = sweep_options_from_args(p.parse_args(["--workers", "3", "--fresh"]))
    assert (o.workers, o.scheduler, o.fresh) == (3, None, True)
    assert sweep_options_from_args(p.parse_args(["--scheduler", "tcp://h:8786"])).scheduler == "tcp://h:8786"
    for bad in (["--workers", "0"], ["--scheduler", "h:8786"], ["--workers", "2", "--scheduler", "tcp://h:1"]):
        with pytest.raises(SystemExit):
            p.parse_args(bad)
    assert "--workers" in capsys.readouterr().err
