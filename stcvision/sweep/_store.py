"""The result store: one JSON line per finished task, appended and fsync'ed as it finishes.

Why JSONL and not SQLite or Parquet: the only writer is the process that runs the sweep (results
come back to it from the workers), so there is nothing to arbitrate; one ``write`` of one line
with ``O_APPEND`` followed by ``fsync`` is durable when it returns, and a kill can at worst leave
one torn last line, which the next open cuts off. The file is plain text a person can read,
``grep`` and ``jq``, copy between machines, and it works on network filesystems where SQLite's
locking is unreliable. Parquet would need a new dependency and cannot be appended line by line.

Layout::

    {"kind": "stcvision-sweep-store", "schema_version": 1, "created_utc": "..."}
    {"key": "<sha256>", "status": "ok", "experiment": "pkg.mod:fn", "params": {...}, "seed": 0,
     "result": {...}, "wall_s": 1.23, "worker": "host:pid", "finished_utc": "..."}
    {"key": "<sha256>", "status": "failed", ..., "error": "ValueError: ...", "traceback": "..."}

A key's last line wins: a failed task is retried on the next run and, once it succeeds, its
``ok`` line follows the ``failed`` one. A key never has two ``ok`` lines (a finished key is
skipped).
"""

from __future__ import annotations

import datetime as _dt
import fcntl
import json
import os
from pathlib import Path
from typing import Any

from stcvision.errors import BadInputError, FileExistsRefusedError, StcVisionError

__all__ = ["STORE_KIND", "STORE_SCHEMA_VERSION", "Store", "read_store"]

STORE_KIND = "stcvision-sweep-store"
STORE_SCHEMA_VERSION = 1


def _utc() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def _header() -> bytes:
    return (
        json.dumps({"kind": STORE_KIND, "schema_version": STORE_SCHEMA_VERSION, "created_utc": _utc()}) + "\n"
    ).encode()


def _parse(path: Path, data: bytes) -> tuple[list[dict], int]:
    """Records of a store file and the length of its whole lines (a torn last line is not)."""
    end = data.rfind(b"\n") + 1
    try:
        lines = data[:end].decode("utf-8").splitlines()
    except UnicodeDecodeError:
        lines = ["not a store"]
    if not lines:
        if data:  # text without a single whole line: not something a store ever holds
            raise FileExistsRefusedError(f"{path} is not a sweep store; refusing to write to it (choose another path)")
        return [], end
    try:
        head = json.loads(lines[0])
    except json.JSONDecodeError:
        head = None
    if not isinstance(head, dict) or head.get("kind") != STORE_KIND:
        raise FileExistsRefusedError(f"{path} is not a sweep store; refusing to write to it (choose another path)")
    if head.get("schema_version") != STORE_SCHEMA_VERSION:
        raise BadInputError(
            f"{path}: sweep store schema_version {head.get('schema_version')!r}; expected {STORE_SCHEMA_VERSION}"
        )
    records = []
    for i, line in enumerate(lines[1:], 2):
        try:
            rec = json.loads(line)
        except json.JSONDecodeError as exc:
            raise BadInputError(f"{path} line {i} is not valid JSON ({exc.msg}); the store is damaged") from None
        if (
            not isinstance(rec, dict)
            or not isinstance(rec.get("key"), str)
            or rec.get("status") not in ("ok", "failed")
        ):
            raise BadInputError(f"{path} line {i} is not a task record (key, status ok/failed)")
        records.append(rec)
    return records, end


def read_store(path: str | os.PathLike) -> list[dict]:
    """Every record of a store, in the order written (a torn last line is left out)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise BadInputError(f"sweep store {path} does not exist") from None
    return _parse(path, data)[0]


class Store:
    """An open store: what is done, and an append of one record at a time.

    Open it with ``with Store(path, fresh=False) as store``; it holds an exclusive lock on the
    file (a second sweep on the same store is refused) until closed.
    """

    def __init__(self, path: str | os.PathLike, *, fresh: bool = False) -> None:
        self.path = Path(path)
        self._fd: int | None = None
        self._fresh = fresh

    def __enter__(self) -> Store:
        from stcvision.fileio import write_bytes_atomic

        path = self.path
        if path.exists() and not path.is_file():
            raise BadInputError(f"sweep store {path} is not a file")
        if path.exists():
            records, end = _parse(path, path.read_bytes())  # refuses a file that is not a store
            if path.stat().st_size == 0:
                write_bytes_atomic(path, _header(), overwrite=True)
        else:
            records, end = [], 0
            write_bytes_atomic(path, _header())
        fd = os.open(path, os.O_RDWR | os.O_APPEND)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise StcVisionError(
                f"sweep store {path} is in use by another sweep; wait for it or use another store"
            ) from None
        self._fd = fd
        if self._fresh:
            os.ftruncate(fd, 0)
            self._write(_header())
            records = []
        elif end and os.fstat(fd).st_size > end:  # a torn last line from a kill: cut it off
            os.ftruncate(fd, end)
            os.fsync(fd)
        self._records = records
        return self

    def __exit__(self, *exc: object) -> None:
        if self._fd is not None:
            os.close(self._fd)  # closing releases the lock
            self._fd = None

    def _write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]
        os.fsync(self._fd)

    def done(self) -> dict[str, dict]:
        """key -> result of every task whose last record is ``ok``."""
        last: dict[str, dict] = {}
        for rec in self._records:
            last[rec["key"]] = rec
        return {k: r["result"] for k, r in last.items() if r["status"] == "ok"}

    def append(self, task, outcome: dict[str, Any]) -> dict:
        """Write one finished task (``outcome`` from :func:`stcvision.sweep._task.run_task`)."""
        rec: dict[str, Any] = {
            "key": task.key,
            "status": "ok" if outcome["ok"] else "failed",
            "experiment": task.experiment,
            "params": json.loads(task.params_json()),
            "seed": task.seed,
        }
        if outcome["ok"]:
            rec["result"] = outcome["result"]
        else:
            rec["error"] = outcome["error"]
            rec["traceback"] = outcome.get("traceback", "")
        rec.update(wall_s=outcome.get("wall_s"), worker=outcome.get("worker"), finished_utc=_utc())
        self._write((json.dumps(rec, separators=(",", ":"), allow_nan=False) + "\n").encode())
        self._records.append(rec)
        return rec
