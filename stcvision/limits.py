"""Caps on the work one command line or input file can ask for (README 'Command line').

Each bounds memory or time that would otherwise grow until the machine gives up; going over one
is bad input (one line, exit code 2) that names the cap. One table, used by every command.
"""

from __future__ import annotations

#: cells of a random board (``--board WxH``: W * H); 100 x 100 cells is a 32 x 32 m floor
MAX_BOARD_CELLS = 10_000
#: dark frames median-stacked at once (all held in memory: 256 VGA frames are 236 MB)
MAX_DARK_FRAMES = 256
#: frames in one generated dataset (``n`` summed over a recipe's groups; ~0.5 MB each on disk)
MAX_DATASET_FRAMES = 100_000
#: world steps of one ``stcvision world`` run (~8 minutes at ~2,000 steps/s)
MAX_WORLD_STEPS = 1_000_000
#: frames one ``stcvision bench`` times (each time is kept for the median; ~1 minute at 100,000)
MAX_BENCH_FRAMES = 100_000
#: a drawn picture's side (pixels): 10,000 x 10,000 x 3 bytes is 300 MB
MAX_PICTURE_PX = 10_000
#: a simulated camera image's side (pixels): 4096 x 4096 is ~400 MB per float64 RGB buffer, and
#: the renderer holds a few; the toolkit's cameras are VGA
MAX_CAMERA_SIDE_PX = 4096


def check_board_cells(w: int, h: int, *, flag: str = "--board") -> None:
    """Refuse a ``--board WxH`` under 1x1 or over :data:`MAX_BOARD_CELLS` cells, in one line
    (``flag``: the option that gave the size, e.g. ``--sizes``)."""
    from stcvision.errors import BadInputError

    if w < 1 or h < 1 or w * h > MAX_BOARD_CELLS:
        raise BadInputError(
            f"{flag} {w}x{h}: expected at least 1x1 and at most {MAX_BOARD_CELLS:,} cells in all (W x H)"
        )


# ---- counts and sizes of the command lines' other flags (each refused over its cap in one line)
#: runs per fault level of ``cover faults`` (a 6x6 run takes a few seconds; 13 levels x 1,000
#: runs is about a day on two cores, and every task is held in memory until it is stored)
MAX_FAULT_RUNS = 1_000
#: ``cover sweep --decisions-per-subcell``: a complete tour makes 1-4 decisions per sub-cell, so
#: beyond this a lost robot would only wander longer before the run is called incomplete
MAX_DECISIONS_PER_SUBCELL = 1_000
#: search steps of one ``stcvision search`` run (``--max-steps``, ``--petals`` x
#: ``--steps-per-petal``): each is a sampling stop of the physics world (~200 steps/s), and the
#: path and the readings are kept for the plot and the recording
MAX_SEARCH_STEPS = 100_000
#: round obstacles of one ``stcvision search`` run (``--obstacle``), each a body of the world
MAX_SEARCH_OBSTACLES = 1_000
#: ``search reproduce --seeds``: seeds per row of the paper's tables (8 take 10-20 minutes)
MAX_REPRODUCE_SEEDS = 1_000
#: worst frames ``eval --rrd`` logs (``--worst``): each is a frame with its stage images, ~2 MB
#: in the recording
MAX_EVAL_WORST_FRAMES = 1_000
#: no-op tasks ``bench --sweep --tasks`` times per backend (~5 ms each through a pool)
MAX_BENCH_SWEEP_TASKS = 100_000
#: frames ``bench --labelled-frames`` renders into a temporary dataset (~1.5 MB each on disk)
MAX_BENCH_LABELLED_FRAMES = 2_000


#: single dots of one scene file (``dots``): each is a light source the renderer splats; a full
#: ground view holds a few hundred, and a scene of a whole floor of marks is given as ``marks``
MAX_SCENE_DOTS = 100_000
#: marks of one scene file per sub-cell of its board: one row of dots along each of the four edges
MAX_MARKS_PER_SUBCELL = 4


#: ``calibrate transform --subcell-m``: the fit reads the grid lines out to 1 m, and needs at
#: least two of them on each side of the robot
MAX_CALIBRATION_SUBCELL_M = 0.5
#: and at least 4 cm: the fit samples the lines every centimetre and measures a profile across
#: each; at 2 cm the lines' sampling windows overlap and the measurement fails
MIN_CALIBRATION_SUBCELL_M = 0.04
#: ``calibrate transform --viewpoint-m``: a rough mirror height; above 2 m it is not a robot's
#: camera (the toolkit's robots carry theirs 0.1-0.3 m up), and below 0.1 m the fit's starting
#: model sees no grid line at all (measured: 0 line points at 0.05 m, a good fit at 0.1 m)
MAX_VIEWPOINT_M = 2.0
MIN_VIEWPOINT_M = 0.1


def check_count(flag: str, value: int, cap: int, *, minimum: int = 1, why: str = "") -> int:
    """Refuse ``flag value`` below ``minimum`` or over ``cap`` in one line naming the cap."""
    from stcvision.errors import BadInputError

    if value < minimum:
        raise BadInputError(f"{flag} must be >= {minimum}, got {value}")
    if value > cap:
        raise BadInputError(f"{flag} {value:,} is over the cap of {cap:,}" + (f" ({why})" if why else ""))
    return value
