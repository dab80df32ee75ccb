"""The closed loop's decisions and results, held to a recording of the reference loop.

Speed work on the loop (rendering, the pipeline, perception, the referee and observers) must not
change one decision or one result. ``data/loop_tours.json`` holds, for a few small tours (seeds,
boards, cameras, exposures and perceptions chosen to pass through every path the speed work
touches: the cooled and low-light cameras' 16-bit frames, the webcam's 8-bit frames, long frames,
a stray lamp, the oracle), every line of the run's JSON trace (each decision and look: the
observation, the decision, the true and believed pose, the frames by rung, the referee's verdict)
and the run's summary but its wall time, as the loop gave them before it was made faster.

Recorded by running this file: ``python tests/controllers/stc/test_loop_determinism.py`` (it
refuses to overwrite the recording without ``--force``). The same comparison on 22x22 boards is
the ``stcvision cover --json --trace`` pair of commands in the reference page of ``bench``.
"""

import json
import sys
from pathlib import Path

import pytest

from stcvision.controllers.stc.loop import CoverConfig, run_cover
from stcvision.stc_geometry import DEFAULT_SUBCELL_M

RECORDING = Path(__file__).parent / "data" / "loop_tours.json"

#: (name, board WxH, obstacle fraction, seed, camera, exposure, perception, faults)
TOURS = (
    ("cooled_4x4", (4, 4), 0.15, 0, "cooled", "auto", "camera", ()),
    ("lowlight_4x3", (4, 3), 0.1, 2, "lowlight", "auto", "camera", ()),
    ("webcam_3x3", (3, 3), 0.0, 1, "webcam", "auto", "camera", ()),
    ("cooled_stray_4x4", (4, 4), 0.1, 6, "cooled", "auto", "camera", ("stray:0.5",)),
    ("oracle_5x5", (5, 5), 0.15, 3, "webcam", "auto", "oracle", ()),
)
#: the summary's keys that measure the machine, not the run
MACHINE_KEYS = ("wall_s",)


def tour(spec) -> dict:
    """Run one tour of :data:`TOURS`: its trace lines and its summary (without the wall time)."""
    from stcvision.controllers.stc.experiments import random_board
    from stcvision.controllers.stc.faults import parse_fault
    from stcvision.controllers.stc.paths import JsonTrace
    from stcvision.sim_camera import hardware

    _, (w, h), fraction, seed, camera, exposure, perception, faults = spec
    board = random_board(w, h, fraction, seed, DEFAULT_SUBCELL_M)
    cfg = CoverConfig(
        perception=perception,
        exposure=exposure,
        seed=seed,
        camera=hardware.load_camera(camera),
        faults=tuple(parse_fault(f) for f in faults),
    )
    trace = JsonTrace(board)
    summary = run_cover(board, cfg, observers=[trace], perception_hook=trace.attach)
    # the recording is JSON: the comparison is of what JSON keeps (tuples as lists)
    summary = json.loads(json.dumps({k: v for k, v in summary.items() if k not in MACHINE_KEYS}))
    return {"summary": summary, "trace": json.loads(json.dumps(trace.lines))}


@pytest.fixture(scope="module")
def recording() -> dict:
    return json.loads(RECORDING.read_text())


@pytest.mark.parametrize("spec", TOURS, ids=[t[0] for t in TOURS])
def test_tour_decides_as_recorded(spec, recording):
    """Every decision and look (the trace, line by line) and every result (the summary, to the
    last digit) as the reference loop gave them."""
    want = recording["tours"][spec[0]]
    got = tour(spec)
    assert len(got["trace"]) == len(want["trace"])
    for i, (a, b) in enumerate(zip(got["trace"], want["trace"], strict=True)):
        assert a == b, f"trace line {i} differs"
    assert got["summary"] == want["summary"]


def test_recording_covers_what_the_speed_work_touches(recording):
    """The recorded tours take long frames besides the short ones, see a stray lamp, and look
    and decide: a recording of tours that take none would hold nothing to those paths."""
    tours = recording["tours"]
    assert set(tours) == {t[0] for t in TOURS}
    frames = [f for t in tours.values() for line in t["trace"] for f in (line.get("frames") or [])]
    assert {f["rung"] > 0 for f in frames} == {False, True}
    assert {line["kind"] for t in tours.values() for line in t["trace"]} == {"decision", "look"}
    assert tours["cooled_stray_4x4"]["summary"]["fault_events"]["stray"] > 0


def _record(force: bool) -> None:
    from stcvision.errors import StcVisionError
    from stcvision.fileio import write_bytes_atomic

    RECORDING.parent.mkdir(exist_ok=True)
    tours = {spec[0]: tour(spec) for spec in TOURS}
    text = json.dumps({"tours": tours}, separators=(",", ":")) + "\n"
    try:
        write_bytes_atomic(RECORDING, text.encode(), overwrite=force)
    except StcVisionError as e:
        sys.exit(f"{e} (--force records it again)")
    print(f"wrote {RECORDING}")


if __name__ == "__main__":
    _record("--force" in sys.argv[1:])
