"""The STC robot's experiments: the sweep's task (:func:`cover_run`, one whole closed-loop run),
the boards it runs on (map files; random boards of a fixed or a drawn size, obstacle fraction and
start sub-cell) and the dependability table (:func:`summarise`, its CSV, markdown and plot).

One task is one run of :func:`stcvision.controllers.stc.loop.run_cover` (seconds to minutes: far above the
sweep runner's per-task cost), run through :mod:`stcvision.sweep` (local pool or Dask cluster,
results kept in ``OUT/sweep.jsonl`` as each run ends). Every run of a table can be replayed alone
with ``stcvision cover`` (the summary prints the command, ``--rrd`` records it):

* a map's run is ``stcvision cover --map FILE --seed S`` (the map travels inside the task, so a
  Dask worker elsewhere needs no copy of the file, and an edited map is a new task);
* a random board is ``random_board(W, H, F, S)``, drawn from the run's own board stream
  (:func:`stcvision.controllers.stc.loop.streams`), the board of ``stcvision cover --board WxH
  --obstacle-fraction F --seed S``; what a family draws for a seed (W and H from a size range, F
  from a fraction range, a start sub-cell anywhere on the board) comes from a stream of its own
  (:func:`family_rng`), so the drawn values, printed with the run, are all a replay needs.
"""

from __future__ import annotations

import csv
import io
import itertools
import statistics
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from stcvision.errors import BadInputError

__all__ = [
    "OBSTACLE_FRACTION",
    "OUTCOMES",
    "BoardFamily",
    "cover_run",
    "draw_board",
    "first_seeds",
    "family_of",
    "map_family",
    "outcome_of",
    "parse_fraction",
    "parse_seeds",
    "parse_sizes",
    "plan",
    "random_board",
    "stop_kind",
    "summarise",
    "sweep",
    "write_outputs",
]

EXPERIMENT = "stcvision.controllers.stc.experiments:cover_run"
STORE = "sweep.jsonl"
OUTPUTS = ("runs.csv", "table.csv", "summary.md", "dependability.png")
#: obstacle cells of a random board (``stcvision cover --board``, and the sweep's boards)
OBSTACLE_FRACTION = 0.15
#: the random boards of a drawn size are tabled in bands of this many cells per side (the larger
#: side), counted from the range's smallest side: 8-22 gives 8-12, 13-17 and 18-22, small enough
#: that a band's tours are alike in length (what decides whether old marks must be read), large
#: enough that 20 seeds over the range leave several runs in each
SIZE_BAND_CELLS = 5
#: drawn obstacle fractions are rounded to this many decimals, so that the fraction the summary
#: prints is exactly the board's (``--obstacle-fraction`` of the replay)
FRACTION_DECIMALS = 3
#: the family's draws come from ``SeedSequence(seed, spawn_key=(FAMILY_STREAM,))``: a child the
#: run's four streams (``spawn_key`` 0-3) never are, so drawing a size or a start never changes
#: the board, the robot or the camera of that seed
FAMILY_STREAM = 0xB0A2D
#: a run's outcome, for the table: complete (every reachable sub-cell once, back at the start, no
#: wrong decision); safely stopped (the robot stopped with a reason before it decided wrongly or
#: covered anything twice); anything else (a wrong decision, a sub-cell twice, or a run that ended
#: without a reason and without the right coverage) is "unsafe", which the robot must never be
OUTCOMES = ("complete", "safely stopped", "unsafe")
#: run_cover's result fields kept per run (runs.csv and the store hold these)
RUN_FIELDS = (
    "subcells_reachable",
    "subcells_covered",
    "subcells_covered_more_than_once",
    "finished",
    "returned_to_start",
    "abort_reason",
    "decisions",
    "decision_errors",
    "look_errors",
    "max_mark_age_read_s",
    "max_position_error_m",
    "turn_rate_error_pct",
    "sim_time_s",
    "wall_s",
    "frames",
    "neighbours_unproven",
    "relooked",
    "returns_reread",
    "boxes_disputed",
    "start_marks_dropped",
    "start_marks_by_count",
    "offsets_left_out",
    "robot_memory_bytes",
)


# ------------------------------------------------------------------------------------ boards
#: a map whose start reaches less than this share of its free cells is worth a word: a photo or
#: a map read at the wrong scale leaves most of its floor in pieces the robot cannot reach
REACHABLE_WARN_FRACTION = 0.5


def check_map_board(board, source) -> list[str]:
    """Check a board read from a map: within the cap on cells (as ``--board``), and more than its
    start cell reachable. Returns the warnings to print (less than
    :data:`REACHABLE_WARN_FRACTION` of the free cells reachable).

    Raises
    ------
    BadInputError
        Too many cells, or nothing but the start cell reachable (a run would be "complete" after
        covering one cell: a camera photo passed as a map did that).
    """
    import sys

    from stcvision.limits import check_board_cells

    rows, cols = board.shape_cells
    check_board_cells(cols, rows, flag=f"--map {source} (W x H cells)")
    reach = int(board.reachable_cells().sum())
    free = int(board.cell_free.sum())
    if reach <= 1:
        raise BadInputError(
            f"--map {source}: only the start cell of {free} free cells ({cols}x{rows} cells, W x H) is reachable; "
            "expected a map of free floor (light) and obstacles (dark) at its scale (--resolution, --subcell-m)"
        )
    if reach < REACHABLE_WARN_FRACTION * free:
        msg = (
            f"--map {source}: the start reaches {reach} of its {free} free cells; the rest lie in pieces the robot "
            "cannot reach"
        )
        print(f"stcvision cover: warning: {msg}", file=sys.stderr)
        return [msg]
    return []


def random_board(w: int, h: int, obstacle_fraction: float, seed: int, subcell_m: float | None = None):
    """The random board of ``stcvision cover --board WxH --obstacle-fraction F --seed S`` (also
    the sweep's): drawn from the board's own stream of the run's seed
    (:func:`stcvision.controllers.stc.loop.streams`)."""
    from stcvision.controllers.stc.loop import streams
    from stcvision.limits import check_board_cells
    from stcvision.sim_camera.board import Board

    check_board_cells(w, h)
    if not 0 <= obstacle_fraction < 1:
        raise BadInputError(f"--obstacle-fraction must be in [0, 1), got {obstacle_fraction}")
    kw = {} if subcell_m is None else {"subcell_m": subcell_m}
    return Board.random((h, w), obstacle_fraction=obstacle_fraction, rng=streams(seed)["board"], **kw)


@dataclass(frozen=True)
class BoardFamily:
    """Boards of one kind, one per seed: a map file (``map`` its name, ``grid`` the board), or
    random boards of ``width`` x ``height`` cells (inclusive ranges; ``height`` None: square,
    the height is the width drawn) at ``obstacle_fraction`` (an inclusive range)."""

    kind: str  # "map" or "random"
    map: str | None = None
    grid: dict | None = None
    width: tuple[int, int] | None = None
    height: tuple[int, int] | None = None
    obstacle_fraction: tuple[float, float] = (OBSTACLE_FRACTION, OBSTACLE_FRACTION)

    def params(self) -> dict:
        if self.kind == "map":
            return {"board": "map", "map": self.map, "grid": self.grid}
        return {
            "board": "random",
            "width": list(self.width),
            "height": None if self.height is None else list(self.height),
            "obstacle_fraction": list(self.obstacle_fraction),
        }

    def largest_cells(self) -> int:
        """The most cells a board of the family can have (the scheduling order: largest first)."""
        if self.kind == "map":
            return self.grid["rows"] * self.grid["cols"] // 4
        return self.width[1] * (self.height or self.width)[1]


def _span(text: str, kind: type, what: str) -> tuple:
    """``A`` or ``A-B`` (inclusive, A <= B) as a pair of ``kind``."""
    parts = text.split("-")
    try:
        if len(parts) not in (1, 2):
            raise ValueError
        lo, hi = kind(parts[0]), kind(parts[-1])
    except ValueError:
        raise BadInputError(f"{what} {text!r} is not a number or a range A-B") from None
    if lo > hi:
        raise BadInputError(f"{what} {text!r}: the range's start is above its end")
    return lo, hi


def parse_sizes(text: str) -> list[BoardFamily]:
    """``--sizes``: comma-separated random-board families, each ``N`` (N x N cells), ``WxH``,
    ``A-B`` (square, the side drawn from A..B per seed) or ``A-BxC-D`` (width and height drawn
    apart). The obstacle fraction is set later (:func:`with_fraction`)."""
    from stcvision.limits import check_board_cells

    out = []
    for item in (t.strip() for t in text.split(",")):
        if not item:
            raise BadInputError(f"--sizes {text!r} has an empty item; expected e.g. 8,10 or 8-22 or 6x10")
        w_text, _, h_text = item.lower().partition("x")
        w = _span(w_text, int, "--sizes")
        h = _span(h_text, int, "--sizes") if h_text else None
        if min(w[0], (h or w)[0]) < 1:
            raise BadInputError(f"--sizes {item!r}: a board is at least 1x1 cells")
        check_board_cells(w[1], (h or w)[1], flag="--sizes")
        fam = BoardFamily("random", width=w, height=h)
        if fam in out:
            raise BadInputError(f"--sizes lists {item!r} twice")
        out.append(fam)
    return out


def parse_fraction(text: str) -> tuple[float, float]:
    """``--obstacle-fraction``: ``F`` or a range ``A-B`` drawn per seed, within [0, 1)."""
    lo, hi = _span(text, float, "--obstacle-fraction")
    if not (0 <= lo and hi < 1):
        raise BadInputError(f"--obstacle-fraction {text!r} must be in [0, 1)")
    return round(lo, FRACTION_DECIMALS), round(hi, FRACTION_DECIMALS)


def with_fraction(families: Iterable[BoardFamily], fraction: tuple[float, float]) -> list[BoardFamily]:
    from dataclasses import replace

    return [replace(f, obstacle_fraction=fraction) if f.kind == "random" else f for f in families]


def parse_seeds(text: str) -> list[int]:
    """``--seeds``: comma-separated seeds and inclusive ranges, e.g. ``100-119`` or ``0-4,50``;
    at most :data:`~stcvision.limits.MAX_SWEEP_SEEDS`, each listed once."""
    from stcvision.limits import MAX_SWEEP_SEEDS, check_count

    seeds: list[int] = []
    for item in (t.strip() for t in text.split(",")):
        lo, hi = _span(item, int, "--seeds") if item else (None, None)
        if lo is None or lo < 0:
            raise BadInputError(f"--seeds {text!r}: expected seeds >= 0 and ranges A-B, e.g. 100-119")
        check_count("--seeds", len(seeds) + hi - lo + 1, MAX_SWEEP_SEEDS, "seeds per board family")
        seeds.extend(range(lo, hi + 1))
    if len(set(seeds)) != len(seeds):
        raise BadInputError(f"--seeds {text!r} lists a seed twice")
    return seeds


def first_seeds(runs: int) -> list[int]:
    """``--runs N``: seeds 0..N-1, N from 1 to :data:`~stcvision.limits.MAX_SWEEP_SEEDS`."""
    from stcvision.limits import MAX_SWEEP_SEEDS, check_count

    if runs < 1:
        raise BadInputError(f"--runs must be >= 1, got {runs}")
    check_count("--runs", runs, MAX_SWEEP_SEEDS, "seeds per board family")
    return list(range(runs))


def encode_grid(board) -> dict:
    """A board as a small JSON object (bits of the blocked sub-cells, packed, base64)."""
    import base64

    import numpy as np

    rows, cols = board.shape_subcells
    bits = base64.b64encode(np.packbits(board.blocked.ravel()).tobytes()).decode()
    return {"rows": rows, "cols": cols, "blocked": bits, "start": list(board.start_subcell)}


def decode_grid(grid: dict):
    import base64

    import numpy as np

    from stcvision.sim_camera.board import Board

    n = grid["rows"] * grid["cols"]
    bits = np.unpackbits(np.frombuffer(base64.b64decode(grid["blocked"]), np.uint8), count=n)
    return Board(bits.astype(bool).reshape(grid["rows"], grid["cols"]), tuple(grid["start"]))


def map_family(path: str | Path, name: str | None = None) -> BoardFamily:
    """The family of one map file (a ``.txt`` or an image, :meth:`stcvision.sim_camera.board.Board.from_file`;
    its start as the map gives it or as the loader picks); too big a map is refused as a random
    board of its size would be."""
    from stcvision.limits import check_board_cells
    from stcvision.sim_camera.board import Board

    p = Path(path)
    if p.is_dir():
        raise BadInputError(f"--maps: {p} is a folder; expected a map file (.txt or an image)")
    if not p.exists():
        raise BadInputError(f"--maps: map file {p} does not exist")
    board = Board.from_file(p)
    rows, cols = board.shape_subcells
    check_board_cells(cols // 2, rows // 2)
    return BoardFamily("map", map=name or p.stem, grid=encode_grid(board))


def map_families(paths: Sequence[str]) -> list[BoardFamily]:
    """One family per map; a map is named by its file name without the suffix, or by the path
    as given where two share a name."""
    from stcvision.limits import MAX_SWEEP_MAPS, check_count

    check_count("--maps", len(paths), MAX_SWEEP_MAPS, "maps in one sweep", minimum=0)
    if len({str(Path(p).resolve()) for p in paths}) != len(paths):
        raise BadInputError("--maps lists a map twice")
    stems = [Path(p).stem for p in paths]
    return [map_family(p, s if stems.count(s) == 1 else str(p)) for p, s in zip(paths, stems, strict=True)]


def family_rng(seed: int):
    """The stream a family draws a seed's size, obstacle fraction and start from (never one of
    the run's own four streams: :data:`FAMILY_STREAM`)."""
    import numpy as np

    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(FAMILY_STREAM,)))


def draw_board(params: dict, seed: int):
    """The board of run ``(params, seed)`` and what was drawn for it: ``(board, drawn)``, with
    ``drawn`` = the obstacle fraction (random boards) and the start sub-cell (the size is the
    board's own ``shape_cells``)."""
    import numpy as np

    from stcvision.sim_camera.board import Board

    rng = family_rng(seed)
    drawn: dict = {}
    if params["board"] == "map":
        board = decode_grid(params["grid"])
    else:
        w = int(rng.integers(params["width"][0], params["width"][1] + 1))
        h = w if params["height"] is None else int(rng.integers(params["height"][0], params["height"][1] + 1))
        lo, hi = params["obstacle_fraction"]
        f = lo if lo == hi else round(float(rng.uniform(lo, hi)), FRACTION_DECIMALS)
        board = random_board(w, h, f, seed)
        drawn["obstacle_fraction_drawn"] = f
    if params["start"] == "random":  # any free sub-cell: every start heading and cell
        free = np.argwhere(np.repeat(np.repeat(board.cell_free, 2, axis=0), 2, axis=1))
        board = Board(board.blocked, tuple(int(v) for v in free[rng.integers(len(free))]), board.subcell_m)
    drawn["start_subcell"] = list(board.start_subcell)
    return board, drawn


# ------------------------------------------------------------------------------------ the task
def cover_run(params: dict, seed) -> dict:
    """One run (the sweep's task). ``params``: the board family's (:meth:`BoardFamily.params`),
    seed, start ("board" or "random"), exposure, perception, camera, decisions_per_subcell.
    ``seed`` (the sweep's stream) is not used: the run's own ``params["seed"]`` makes it the same
    run as ``stcvision cover --seed S`` on the same board."""
    from stcvision.controllers.stc.loop import CoverConfig, run_cover
    from stcvision.sim_camera import hardware

    board, drawn = draw_board(params, params["seed"])
    # a complete tour makes a few decisions per sub-cell; a robot lost in its own faded marks can
    # wander for thousands, so it is stopped at decisions_per_subcell per reachable sub-cell
    cap = params["decisions_per_subcell"] * int(board.reachable_cells().sum()) * 4
    cfg = CoverConfig(
        perception=params["perception"],
        exposure=params["exposure"],
        seed=params["seed"],
        max_decisions=cap,
        camera=hardware.load_camera(params["camera"]),
        move_log=params.get("move_log", False),
        fsm=params.get("fsm", "python"),
    )
    r = run_cover(board, cfg)
    keep = {k: v for k, v in params.items() if k != "grid"}  # the map's bits stay in the task
    out = {**keep, **drawn, "board_cells": r["board_cells"], "complete": r["complete"]}
    out.update({k: r[k] for k in RUN_FIELDS})
    if "first_decision_error" in r:
        out["first_decision_error"] = r["first_decision_error"]
    out["outcome"] = outcome_of(out)
    return out


def outcome_of(r: dict) -> str:
    """Which of :data:`OUTCOMES` a run is, from the referee's ground truth (``run_cover``'s
    decision errors and sub-cells covered more than once) and the robot's stop."""
    if r["complete"]:
        return "complete"
    if r["abort_reason"] is not None and r["decision_errors"] == 0 and r["subcells_covered_more_than_once"] == 0:
        return "safely stopped"
    return "unsafe"


def stop_kind(text: str) -> str:
    """An abort reason's kind, without its figures (where, how far, which decision)."""
    head, _, rest = text.partition(":")
    if head == "camera":
        return "camera: noise floor" if "noise floor" in rest else "camera: frames lost or black"
    return text.split(" at (")[0].split(" (")[0].split(":")[0].split(" after ")[0]


# ------------------------------------------------------------------------------------ planning
def plan(
    families: Sequence[BoardFamily],
    seeds: Sequence[int],
    exposures: Sequence[str | float],
    perceptions: Sequence[str],
    cameras: Sequence[str] = ("webcam",),
    *,
    start: str = "board",
    decisions_per_subcell: int = 10,
    move_log: bool = False,
    fsm: str = "python",
):
    """The tasks, largest boards first (so the pool is not left waiting on one at the end);
    every input checked, and the count capped, before a task is made. ``move_log``: the study
    switch's robot (``CoverConfig.move_log``), tabled apart from the ant-like one. ``fsm``: the
    controller that decides (``CoverConfig.fsm``: python, c or firmware); the same runs, so the
    same table, whichever decides."""
    from stcvision.limits import MAX_SWEEP_SEEDS, MAX_SWEEP_TASKS, check_count
    from stcvision.sim_camera import hardware
    from stcvision.sweep import Task

    if not families:
        raise BadInputError("no boards: give --maps and/or --sizes")
    if not seeds:
        raise BadInputError("no seeds: give --runs N or --seeds A-B")
    check_count("--runs/--seeds", len(seeds), MAX_SWEEP_SEEDS, "seeds per board family")
    if start not in ("board", "random"):
        raise BadInputError(f"--start {start!r} is not board or random")
    for p in perceptions:
        if p not in ("camera", "oracle", "ideal"):
            raise BadInputError(f"perception {p!r} is not camera, oracle or ideal")
    exposures = [_exposure(e) for e in exposures]
    for c in cameras:
        hardware.load_camera(c)  # an unknown preset or a bad file: one line, exit 2
    n = len(families) * len(seeds) * len(exposures) * len(perceptions) * len(cameras)
    what = "runs in one sweep (boards x seeds x exposures x perceptions x cameras)"
    check_count("the sweep", n, MAX_SWEEP_TASKS, what, minimum=0)
    order = sorted(families, key=lambda f: -f.largest_cells())
    common = {"start": start, "decisions_per_subcell": decisions_per_subcell}
    if move_log:  # (absent otherwise: the ant-like robot's tasks keep their parameters)
        common["move_log"] = True
    if fsm != "python":  # (absent for the Python controller: earlier stores' tasks stay the same tasks)
        from stcvision.controllers.stc.choose import make_controller

        make_controller(fsm).close()  # a controller that cannot be built: one line before any task
        common["fsm"] = fsm
    grid = itertools.product(order, exposures, perceptions, cameras, seeds)
    kw = ("exposure", "perception", "camera", "seed")
    return [Task(EXPERIMENT, {**f.params(), **common, **dict(zip(kw, rest, strict=True))}, rest[-1])
            for f, *rest in grid]  # fmt: skip


def _exposure(text) -> str | float:
    if text in ("webcam", "auto"):
        return text
    try:
        v = float(text)
    except ValueError:
        raise BadInputError(f"exposure {text!r} is not webcam, auto or seconds") from None
    if not 0 < v <= 60:
        raise BadInputError(f"exposure {text!r} must be in (0, 60] seconds")
    return v


# ------------------------------------------------------------------------------------ the table
def family_of(r: dict) -> str:
    """The board family a run is tabled under: ``map NAME``; ``random WxH`` for a fixed size;
    ``random A-B`` for a drawn size, by the band (:data:`SIZE_BAND_CELLS`) of its larger side."""
    if r["board"] == "map":
        return f"map {r['map']}"
    w, h = r["width"], r["height"] or r["width"]
    if w[0] == w[1] and h[0] == h[1]:
        return f"random {w[0]}x{h[0]}"
    lo, hi = min(w[0], h[0]), max(w[1], h[1])
    band = lo + (max(r["board_cells"]) - lo) // SIZE_BAND_CELLS * SIZE_BAND_CELLS
    top = min(band + SIZE_BAND_CELLS - 1, hi)
    return f"random {band}-{top}" if top > band else f"random {band}"


def _family_order(name: str) -> tuple:
    if name.startswith("map "):
        return (0, 0, name)
    size = name.split()[1]
    return (1, int(size.split("-")[0].split("x")[0]), name)


def _median(v):
    return statistics.median(v) if v else None


def _counts(items: Iterable[str]) -> str:
    """``"a x3; b x1"``, most frequent first."""
    c: dict[str, int] = {}
    for it in items:
        c[it] = c.get(it, 0) + 1
    return "; ".join(f"{k} x{n}" for k, n in sorted(c.items(), key=lambda kv: (-kv[1], kv[0])))


def _row(key: tuple, rs: list[dict]) -> dict:
    from scipy.stats import binomtest

    camera, perception, exposure, fam = key
    n, k = len(rs), sum(r["complete"] for r in rs)
    ci = binomtest(k, n).proportion_ci(confidence_level=0.95)  # Clopper-Pearson: never too narrow
    stops = [r for r in rs if outcome_of(r) == "safely stopped"]
    return {
        "camera": camera,
        "perception": perception,
        "exposure": exposure,
        "family": fam,
        "runs": n,
        "complete": k,
        "complete_rate": k / n,
        "complete_ci95_low": float(ci.low),
        "complete_ci95_high": float(ci.high),
        "safely_stopped": len(stops),
        "stop_reasons": _counts(stop_kind(r["abort_reason"]) for r in stops),
        "unsafe": sum(outcome_of(r) == "unsafe" for r in rs),
        "wrong_decisions": sum(r["decision_errors"] for r in rs),
        "runs_with_wrong_decisions": sum(r["decision_errors"] > 0 for r in rs),
        "subcells_twice": sum(r["subcells_covered_more_than_once"] for r in rs),
        "runs_with_subcells_twice": sum(r["subcells_covered_more_than_once"] > 0 for r in rs),
        "covered_fraction_mean": statistics.fmean(r["subcells_covered"] / r["subcells_reachable"] for r in rs),
        "seeds": _seed_text(sorted({r["seed"] for r in rs})),
        "sim_time_s_median": _median([r["sim_time_s"] for r in rs]),
        "wall_s_median": _median([r["wall_s"] for r in rs]),
        "wall_s_total": sum(r["wall_s"] for r in rs),
    }


def _seed_text(seeds: list[int]) -> str:
    """``0-19`` or ``0-4,50``: the seeds as ``--seeds`` takes them."""
    out, i = [], 0
    while i < len(seeds):
        j = i
        while j + 1 < len(seeds) and seeds[j + 1] == seeds[j] + 1:
            j += 1
        out.append(str(seeds[i]) if i == j else f"{seeds[i]}-{seeds[j]}")
        i = j + 1
    return ",".join(out)


def perception_label(r: dict) -> str:
    """A run's perception as the table names it: the study switch's robot, which keeps a map of
    where it has been (``CoverConfig.move_log``), is tabled apart from the ant-like robot."""
    return f"{r['perception']} + move log" if r.get("move_log") else r["perception"]


def summarise(runs: list[dict]) -> list[dict]:
    """The dependability table: one row per (camera, perception, exposure, board family), then
    one per (camera, perception, exposure) over all its boards (family ``all``): runs, complete
    with the rate's 95 % interval, safely stopped with their reasons, unsafe runs, wrong
    decisions and sub-cells covered twice (the referee's counts), coverage and times."""
    groups: dict[tuple, list[dict]] = {}
    for r in runs:
        kind = (r["camera"], perception_label(r), str(r["exposure"]))
        groups.setdefault((*kind, family_of(r)), []).append(r)
        groups.setdefault((*kind, "all"), []).append(r)
    order = sorted(groups, key=lambda k: (*k[:3], k[3] == "all", _family_order(k[3]) if k[3] != "all" else ()))
    rows = [_row(k, groups[k]) for k in order]
    # a kind with one family needs no 'all' row: it would repeat that row
    per_kind = {k[:3]: sum(1 for g in groups if g[:3] == k[:3]) for k in groups}
    return [r for r in rows if r["family"] != "all" or per_kind[(r["camera"], r["perception"], r["exposure"])] > 2]


def _pct(v: float) -> str:
    return f"{100 * v:.1f}".rstrip("0").rstrip(".")


def markdown_table(rows: list[dict]) -> str:
    def num(v, fmt):
        return "—" if v is None else format(v, fmt)

    def with_runs(total, runs):
        return "0" if total == 0 else f"**{total}** ({runs} run{'s' * (runs != 1)})"

    out = [
        "| camera | perception | exposure | boards | runs | complete | complete rate (95 % CI) "
        "| safely stopped (reasons) | unsafe | wrong decisions | sub-cells twice | covered (mean) "
        "| robot time (median) | wall per run (median) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        stops = str(r["safely_stopped"]) + (f" ({r['stop_reasons']})" if r["stop_reasons"] else "")
        fam = "**all**" if r["family"] == "all" else r["family"]
        out.append(
            f"| {r['camera']} | {r['perception']} | {r['exposure']} | {fam} | {r['runs']} | {r['complete']} "
            f"| {_pct(r['complete_rate'])} % ({_pct(r['complete_ci95_low'])}–{_pct(r['complete_ci95_high'])}) "
            f"| {stops} | {r['unsafe']} | {with_runs(r['wrong_decisions'], r['runs_with_wrong_decisions'])} "
            f"| {with_runs(r['subcells_twice'], r['runs_with_subcells_twice'])} "
            f"| {_pct(r['covered_fraction_mean'])} % | {num(r['sim_time_s_median'], ',.0f')} s "
            f"| {num(r['wall_s_median'], '.1f')} s |"
        )
    return "\n".join(out)


def replay_command(r: dict) -> str:
    """The ``stcvision cover`` command that makes run ``r`` alone, recorded."""
    if r["board"] == "map":
        board = f"--map MAP_{r['map']}"
    else:
        board = f"--board {r['board_cells'][0]}x{r['board_cells'][1]} --obstacle-fraction "
        board += f"{r.get('obstacle_fraction_drawn', r['obstacle_fraction'][0]):g}"
    start = f" --start {r['start_subcell'][0]},{r['start_subcell'][1]}" if r["start"] == "random" else ""
    exposure = f"--exposure {r['exposure']}" if isinstance(r["exposure"], str) else f"--exposure-s {r['exposure']}"
    return (
        f"stcvision cover {board}{start} --seed {r['seed']} --perception {r['perception']} {exposure} "
        f"--camera {r['camera']}{' --move-log' if r.get('move_log') else ''} --rrd run.rrd"
    )


def plot(rows: list[dict]) -> bytes:
    """PNG: per board family, the complete rate with its 95 % interval (one marker per camera,
    perception and exposure), and the runs in each outcome (stacked bars)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from matplotlib.ticker import MaxNLocator

    from stcvision.fileio import figure_png

    fams = sorted({r["family"] for r in rows}, key=lambda f: (f == "all", _family_order(f) if f != "all" else ()))
    kinds = sorted({(r["camera"], r["perception"], r["exposure"]) for r in rows})
    width = max(7.0, 0.9 * len(fams) * max(1, len(kinds)) ** 0.5 + 3)
    fig, (a, b) = plt.subplots(2, 1, figsize=(width, 7.5), constrained_layout=True, sharex=True)
    x = np.arange(len(fams))
    step = 0.8 / max(len(kinds), 1)
    colours = ("#3a9a4a", "#8fb3d9", "#d03030")
    for i, kind in enumerate(kinds):
        rs = {r["family"]: r for r in rows if (r["camera"], r["perception"], r["exposure"]) == kind}
        xs = np.array([j for j, f in enumerate(fams) if f in rs]) + (i - (len(kinds) - 1) / 2) * step
        sel = [rs[f] for f in fams if f in rs]
        p = np.array([r["complete_rate"] for r in sel])
        err = np.array([[r["complete_rate"] - r["complete_ci95_low"] for r in sel],
                        [r["complete_ci95_high"] - r["complete_rate"] for r in sel]])  # fmt: skip
        label = f"{kind[0]}, {kind[1]}, exposure {kind[2]}"
        a.errorbar(xs, p, yerr=err, fmt="os^Dv<>"[i % 7], capsize=4, label=label)
        base = np.zeros(len(sel))
        for o, col, key in zip(OUTCOMES, colours, ("complete", "safely_stopped", "unsafe"), strict=True):
            v = np.array([r[key] for r in sel], float)
            b.bar(xs, v, width=step * 0.9, bottom=base, color=col, edgecolor="k", lw=0.3,
                  label=o if i == 0 else None)  # fmt: skip
            base += v
    a.set(ylabel="complete runs (fraction, 95 % CI)", ylim=(-0.05, 1.05))
    a.set_title("STC dependability: complete tours per board family")
    a.grid(alpha=0.3)
    a.legend(fontsize=8, loc="lower left")
    b.set(ylabel="runs")
    b.yaxis.set_major_locator(MaxNLocator(integer=True))
    b.set_title("outcome of every run (bars left to right in the order of the legend above)")
    b.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    b.set_xticks(x, fams, rotation=30, ha="right")
    return figure_png(fig)


def write_csv(rows: list[dict], fields: Sequence[str]) -> bytes:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(fields), extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue().encode()


def write_files(out: Path, files: dict[str, bytes]) -> list[str]:
    """Each of ``files`` (name -> bytes) into ``out``, atomically; returns their paths."""
    from stcvision.fileio import write_bytes_atomic

    for name, data in files.items():
        write_bytes_atomic(out / name, data, overwrite=True)
    return [str(out / name) for name in files]


RUN_CSV_FIELDS = ("family", "board", "map", "seed", "start", "exposure", "perception", "camera", "board_cells",
                  "obstacle_fraction_drawn", "start_subcell", "outcome", "complete",
                  *RUN_FIELDS)  # fmt: skip


def write_outputs(out: Path, runs: list[dict], rows: list[dict], report_summary: str, maps: dict) -> list[str]:
    """runs.csv, table.csv (``rows``: :func:`summarise` of ``runs``), summary.md, dependability.png.
    ``maps``: map name -> the path it was read from (for the replay commands)."""
    bad = [r for r in runs if not r["complete"]]
    md = [
        "# STC dependability sweep",
        "",
        "A run is **complete** when every reachable sub-cell was covered exactly once, the robot finished "
        "back in its start cell and made no decision the oracle would not have made in its place "
        "(`stcvision.controllers.stc.loop.is_complete`, the referee's ground truth). **Safely stopped**: not complete, "
        "but the robot stopped with a reason before any wrong decision or sub-cell covered twice. **Unsafe**: "
        "anything else. The interval is Clopper-Pearson's (`scipy.stats.binomtest(k, n).proportion_ci()`). "
        "Random boards: `random_board(W, H, F, seed)`; a drawn size is tabled by the band of its larger side.",
        "",
        markdown_table(rows),
        "",
        "![complete rate and outcomes per board family](dependability.png)",
        "",
        f"Sweep: {report_summary.splitlines()[0]}",
        "",
    ]
    if bad:
        md += ["## Runs not complete (replay one with its command)", ""]
        for r in bad:
            cmd = replay_command(r).replace(f"MAP_{r.get('map')}", maps.get(r.get("map"), str(r.get("map"))))
            md.append(f"- {family_of(r)} seed {r['seed']} {r['camera']} {r['perception']}: {r['outcome']}, "
                      f"{r['subcells_covered']} / {r['subcells_reachable']}, {r['decision_errors']} wrong decisions, "
                      f"{r['subcells_covered_more_than_once']} twice, {r['abort_reason'] or 'no stop reason'} "
                      f"-- `{cmd}`")  # fmt: skip
        md.append("")
    runs_rows = [{**r, "family": family_of(r)} for r in runs]
    files = {
        "runs.csv": write_csv(runs_rows, RUN_CSV_FIELDS),
        "table.csv": write_csv(rows, list(rows[0]) if rows else ["family"]),
        "summary.md": "\n".join(md).encode(),
        "dependability.png": plot(rows),
    }
    return write_files(out, files)


def sweep(
    out: str | Path,
    *,
    maps: Sequence[str] = (),
    sizes: Sequence[BoardFamily] = (),
    seeds: Sequence[int],
    exposures: Sequence[str] = ("auto",),
    perceptions: Sequence[str] = ("camera",),
    cameras: Sequence[str] = ("webcam",),
    obstacle_fraction: tuple[float, float] = (OBSTACLE_FRACTION, OBSTACLE_FRACTION),
    start: str = "board",
    decisions_per_subcell: int = 10,
    move_log: bool = False,
    options=None,
    force: bool = False,
    fsm: str = "python",
) -> dict:
    """Plan the runs (every input checked first), run them through the sweep runner into
    ``out/sweep.jsonl`` (resumable), and write the table, the runs, the summary and the plot."""
    from stcvision.sweep import SweepOptions, output_folder, run_sweep

    families = [*map_families(maps), *with_fraction(sizes, obstacle_fraction)]
    tasks = plan(families, seeds, exposures, perceptions, cameras, start=start,
                 decisions_per_subcell=decisions_per_subcell, move_log=move_log, fsm=fsm)  # fmt: skip
    out = output_folder(out, OUTPUTS, store=STORE, force=force, what="cover sweep")
    report = run_sweep(tasks, out / STORE, options or SweepOptions(), desc="cover sweep")
    runs = list(report.results.values())
    rows = summarise(runs)
    names = {f.map: str(p) for f, p in zip(families, maps, strict=False)}
    files = write_outputs(out, runs, rows, report.summary(), names) if runs else []
    return {
        "action": "sweep",
        "out": str(out),
        "files": files,
        "table": rows,
        "tasks": report.total,
        "skipped": report.skipped,
        "failed": dict(report.failed),
        "wall_s": report.wall_s,
        "summary": report.summary(),
        "exit_code": 1 if report.failed else 0,
    }
