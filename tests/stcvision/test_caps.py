"""Every count and size flag has a cap (stcvision.limits): over it, or below its minimum, the
command refuses in one line with exit code 2 before doing any work, and the line names the cap."""

import pytest

from stcvision import limits

CASES = [
    (["cover", "sweep", "--sizes", "3,101", "--runs", "1", "--out", "{d}/S"], "--sizes 101x101"),
    (
        ["cover", "sweep", "--sizes", "3", "--runs", "1", "--decisions-per-subcell", "1000000000", "--out", "{d}/S"],
        f"over the cap of {limits.MAX_DECISIONS_PER_SUBCELL:,}",
    ),
    (["cover", "faults", "--runs", "1000000000", "--out", "{d}/F"], f"over the cap of {limits.MAX_FAULT_RUNS:,}"),
    (["cover", "faults", "--cells", "100000", "--out", "{d}/F"], "--cells 100000x100000"),
    (["cover", "faults", "--obstacle-fraction", "-1", "--out", "{d}/F"], "--obstacle-fraction must be in [0, 1)"),
    (["cover", "faults", "--faults", "none,none", "--out", "{d}/F"], "names a fault twice"),
    (["search", "--petals", "1000000000"], f"search steps is over the cap of {limits.MAX_SEARCH_STEPS:,}"),
    (["search", "--steps-per-petal", "1000000000"], "1000000000 steps per petal: 12,000,000,000 search steps is over"),
    (["search", "--petals", "1000", "--steps-per-petal", "1000"], "1,000,000 search steps is over the cap"),
    (["search", "--petals", "0"], "petals must be a positive integer"),
    (["search", "--max-steps", "100000000000"], f"is over the cap of {limits.MAX_SEARCH_STEPS:,}"),
    (
        ["search", "reproduce", "--seeds", "1000000000", "--out", "{d}/R"],
        f"over the cap of {limits.MAX_SEARCH_SEEDS:,}",
    ),
    (["eval", "{d}", "--worst", "100000000000"], f"over the cap of {limits.MAX_EVAL_WORST_FRAMES:,}"),
    (["bench", "--sweep", "--tasks", "1000000000"], f"over the cap of {limits.MAX_BENCH_SWEEP_TASKS:,}"),
    (["bench", "--labelled-frames", "1000000000"], f"over the cap of {limits.MAX_BENCH_LABELLED_FRAMES:,}"),
    (["bench", "--loop-profile", "1000000"], f"over the cap of {limits.MAX_BENCH_PROFILE_ROWS:,}"),
    (["bench", "--loop-only", "--loop-board", "1000x1000"], "--loop-board 1000x1000: expected at least 1x1"),
    (["world", "--board", "10x10", "--steps", "100000000", "--out", "{d}/w.png"], "over the cap"),
    (["render", "--dark-frames", "100000", "--out", "{d}/r"], "over the cap"),
    (["firmware", "check", "--boards", "1000000000"], f"must be 0 to {limits.MAX_CHECK_BOARDS:,}"),
    (["firmware", "check", "--pairs", "1000000000000"], f"must be 0 to {limits.MAX_CHECK_PAIRS:,}"),
    (["robot", "run", "--port", "loop://", "--timeout", "1e9"], f"over the cap of {limits.MAX_LINK_TIMEOUT_S:,}"),
]


@pytest.mark.parametrize("argv, words", CASES, ids=[" ".join(c[0][:3]) for c in CASES])
def test_a_flag_over_its_cap_is_one_line_and_exit_2_before_any_work(cli, capsys, tmp_path, argv, words):
    try:
        code, out, err = cli(*[a.replace("{d}", str(tmp_path)) for a in argv])
    except SystemExit as e:  # an argparse type's refusal
        code, err = e.code, capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and words in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # nothing made


def test_search_obstacles_are_capped(cli):
    code, _, err = cli("search", "--obstacle", *["1,1,0.1"] * (limits.MAX_SEARCH_OBSTACLES + 1))
    assert code == 2 and f"over the cap of {limits.MAX_SEARCH_OBSTACLES:,}" in err


def test_every_cap_says_why():
    import inspect
    import re

    src = inspect.getsource(limits)
    caps = [n for n in dir(limits) if n.startswith("MAX_")]
    documented = set(re.findall(r"#: [^\n]+\n(?:#[^\n]*\n)*(MAX_\w+) =", src))
    assert len(caps) >= 15 and set(caps) == documented


def test_calibrate_transform_refuses_sizes_it_cannot_fit(cli, tmp_path):
    frame = tmp_path / "lit.png"  # never read: the flags are checked first
    frame.write_bytes(b"not read")
    for flag, value, words in (
        ("--subcell-m", "1e9", "--subcell-m must be in [0.04, 0.5] m"),
        ("--subcell-m", "0.02", "--subcell-m must be in [0.04, 0.5] m"),
        ("--viewpoint-m", "-1", "--viewpoint-m must be in [0.1, 2] m"),
        ("--viewpoint-m", "0.05", "--viewpoint-m must be in [0.1, 2] m"),
    ):
        code, _, err = cli("calibrate", "transform", frame, "--out", tmp_path / "p.json", flag, value, "--yes")
        assert code == 2 and words in err and err.count("\n") == 1, err
    assert not (tmp_path / "p.json").exists()
