"""Closed-loop runs of the STC robot decided by the C controller (``--fsm c``) and by the firmware
in its emulator (``--fsm firmware``) against the Python controller: each run's summary, but for
its wall time, must be the Python run's. Random boards in camera mode (default sizes 4, 6 and 8
cells, seeds 101-103; the firmware on the 8x8 boards of seeds 101-102) and the three peer maps
with the oracle's reading:

    python docs/measurements/controller_identity.py [--seeds 101-103] [--sizes 4,6,8]

Used for docs/results/stc.md, "The controller in C and on a microcontroller"; needs
``make cross-tools`` for the firmware's runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MAPS = ROOT / "datasets" / "peer_data" / "pythonrobotics_maps"


def _same(board, **kw) -> dict:
    from stcvision.controllers.stc.loop import CoverConfig, run_cover

    runs = {}
    for fsm in ("python", *kw.pop("others")):
        r = run_cover(board, CoverConfig(fsm=fsm, **kw))
        r.pop("wall_s")
        runs[fsm] = r
    return {fsm: r == runs["python"] for fsm, r in runs.items() if fsm != "python"} | {
        "complete": runs["python"]["complete"]
    }


def main(argv=None) -> int:
    from stcvision.controllers.stc.experiments import OBSTACLE_FRACTION, random_board
    from stcvision.sim_camera.board import Board

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", default="101-103")
    p.add_argument("--sizes", default="4,6,8")
    p.add_argument("--firmware-size", type=int, default=8)
    p.add_argument("--firmware-seeds", type=int, default=2)
    a = p.parse_args(argv)
    lo, hi = (int(v) for v in a.seeds.split("-"))
    for seed in range(lo, hi + 1):
        for n in (int(v) for v in a.sizes.split(",")):
            fw = ("firmware",) if n == a.firmware_size and seed < lo + a.firmware_seeds else ()
            board = random_board(n, n, OBSTACLE_FRACTION, seed)
            print(f"camera {n}x{n} seed {seed}: {_same(board, seed=seed, others=('c', *fw))}", flush=True)
    for m in ("spiral_stc_test", "spiral_stc_test_2", "spiral_stc_test_3"):
        board = Board.from_file(MAPS / f"{m}.png")
        print(f"map {m} oracle: {_same(board, perception='oracle', others=('c', 'firmware'))}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
