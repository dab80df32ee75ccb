"""Measure what a command costs before it works, and what the first run costs.

    python docs/measurements/first_run.py [--runs 15] [--demo]

Prints, side by side, the wall time of ``stcvision --help`` against ``python -c "import numpy"``
(the two taking turns, medians of ``--runs`` each). With ``--demo``: ``stcvision demo`` on an
empty numba cache (a folder of its own, ``NUMBA_CACHE_DIR``) as a user's first run, and then
again on the cache it filled; then where a cold compile's time goes, with the whole compile in
one process (the demo's second process switched off, on another empty cache): the time inside
numba's compiler lock, the part of it in LLVM, the number of functions compiled and the ten that
took longest on their own (numba's compile events; a function's time leaves out the functions
it compiled inside it).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

STC = str(Path(sys.executable).with_name("stcvision"))

#: run in the cold demo's process: the demo with numba's compile events timed
PROFILED_DEMO = """
import collections, sys, time
from numba.core import event
own, stack = collections.Counter(), []
class Per(event.Listener):
    def on_start(self, ev):
        f = ev.data["dispatcher"].py_func
        stack.append([f"{f.__module__}.{f.__qualname__}", time.perf_counter(), 0.0])
    def on_end(self, ev):
        name, t0, inner = stack.pop()
        took = time.perf_counter() - t0
        own[name] += took - inner
        if stack:
            stack[-1][2] += took
event.register("numba:compile", Per())
locks = {}
def timer(kind):
    return event.install_timer(kind, lambda s: locks.__setitem__(kind, locks.get(kind, 0.0) + s))
import stcvision.warm
stcvision.warm.start_compiling_from_the_end = lambda: None  # the whole compile, in this process
from stcvision.cli import main
with timer("numba:compiler_lock"), timer("numba:llvm_lock"):
    code = main(sys.argv[1:])
print(f"compile {locks.get('numba:compiler_lock', 0):.1f} s, of which LLVM {locks.get('numba:llvm_lock', 0):.1f} s; "
      f"{len(own)} functions compiled", file=sys.stderr)
for name, s in own.most_common(10):
    print(f"  {s:5.2f} s  {name}", file=sys.stderr)
sys.exit(code)
"""


def timed(cmd: list[str], env=None) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, check=True)
    return time.perf_counter() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=15, help="runs of each start-up command (default 15)")
    ap.add_argument("--demo", action="store_true", help="also time the demo on an empty and a filled cache")
    args = ap.parse_args()
    runs = max(1, min(args.runs, 100))
    helps, numpys = [], []
    for _ in range(runs):
        helps.append(timed([STC, "--help"]))
        numpys.append(timed([sys.executable, "-c", "import numpy"]))
    h, n = statistics.median(helps), statistics.median(numpys)
    print(f"stcvision --help {h:.3f} s, python -c 'import numpy' {n:.3f} s (medians of {runs}): {h - n:+.3f} s")
    if not args.demo:
        return 0
    with tempfile.TemporaryDirectory(prefix="first-run-") as tmp:
        env = {**os.environ, "NUMBA_CACHE_DIR": str(Path(tmp) / "numba")}
        out = str(Path(tmp) / "demo")
        cold_s = timed([STC, "demo", "--out", out, "--force"], env=env)  # as a user's first run
        warm_s = timed([STC, "demo", "--out", out, "--force"], env=env)
        ratio = cold_s / warm_s
        print(f"demo on an empty numba cache {cold_s:.1f} s, on the cache it filled {warm_s:.1f} s ({ratio:.1f}x)")
        env = {**os.environ, "NUMBA_CACHE_DIR": str(Path(tmp) / "numba-profiled")}
        cold = subprocess.run(
            [sys.executable, "-c", PROFILED_DEMO, "demo", "--out", out, "--force"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        if cold.returncode != 0:
            print(cold.stderr, file=sys.stderr)
            return 1
        print("the whole compile in one process (the second process the demo starts switched off):")
        print("\n".join(line for line in cold.stderr.splitlines() if not line.startswith("stcvision")))
    return 0


if __name__ == "__main__":
    sys.exit(main())
