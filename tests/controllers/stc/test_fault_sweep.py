"""The fault experiment (stcvision.controllers.stc.fault_sweep) end to end on a tiny board: the library
call and ``stcvision cover faults`` give the same table, and its files are written."""

import json

from stcvision.controllers.stc.fault_sweep import OUTCOMES, sweep_faults
from stcvision.sweep import SweepOptions


def test_tiny_fault_sweep_library_and_command_agree(tmp_path, cli):
    r = sweep_faults(tmp_path / "lib", ["none"], 1, cells=2, options=SweepOptions(workers=1))
    assert r["exit_code"] == 0 and r["tasks"] == 1 and r["wrong_success"] == 0
    (row,) = r["table"]
    assert row["fault"] == "none" and row["runs"] == 1 and sum(row[o] for o in OUTCOMES) == 1
    assert row["complete"] == 1  # a 2x2 board without faults is covered
    assert sorted(p.name for p in (tmp_path / "lib").iterdir()) == [
        "faults.png", "runs.csv", "summary.md", "sweep.jsonl"
    ]  # fmt: skip
    assert "| none | — | 1 | 1 |" in (tmp_path / "lib" / "summary.md").read_text()
    code, out, _ = cli("cover", "faults", "--faults", "none", "--runs", "1", "--cells", "2",
                       "--out", tmp_path / "cli", "--workers", "1", "--json")  # fmt: skip
    assert code == 0 and json.loads(out)["table"] == r["table"]
