"""Caps on the work one command line or input file can ask for (docs/reference/guarantees.md,
"Caps").

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
#: rows of the table ``stcvision bench --loop-profile N`` prints (a profile lists ~11,000 functions)
MAX_BENCH_PROFILE_ROWS = 1000
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


# ---------------------------------------------------------------- sweeps of the STC robot
# (``stcvision cover sweep`` and ``cover faults``; ``stcvision.controllers.stc.experiments``)

#: seeds per board family (``--runs N``, ``--seeds A-B``): a camera run on a 22x22 board takes
#: ~40 s of one core, so 10,000 seeds of one family are ~4.6 core-days, far beyond any table a
#: person reads; the seeds are listed in memory before the first run starts
MAX_SWEEP_SEEDS = 10_000
#: runs in one sweep (boards x seeds x exposures x perceptions x cameras): each is a task held in
#: memory with its parameters (up to ~7 kB with a map of 100 x 100 cells), a line of the store
#: and a row of runs.csv; at ~25 s a run, 50,000 are two weeks of one core. Without a cap,
#: ``--runs 1000000000`` grew until the machine gave up (listing the tasks)
MAX_SWEEP_TASKS = 50_000
#: ``--decisions-per-subcell``: a complete tour makes 1-2 decisions per sub-cell, so 1,000 lets a
#: lost robot wander ~1,000 tours' worth of decisions before the run is stopped
MAX_DECISIONS_PER_SUBCELL = 1_000
#: map files of one sweep (``--maps``): each is read and checked before the first run
MAX_SWEEP_MAPS = 1_000


def check_count(flag: str, value: int, cap: int, what: str = "", *, minimum: int = 1, why: str = "") -> int:
    """Refuse ``value`` below ``minimum`` or over ``cap`` in one line that names the flag, what it
    counts (``what``) and the cap (``why``: where the cap is, or its reason)."""
    from stcvision.errors import BadInputError

    if value < minimum:
        raise BadInputError(f"{flag} must be >= {minimum}, got {value}")
    if value > cap:
        said = f" {what}" if what else ""
        raise BadInputError(f"{flag} {value:,}{said} is over the cap of {cap:,}" + (f" ({why})" if why else ""))
    return value


# ----------------------------------------------------------------------------- the TASTI 2 search
#: search-path steps of one ``stcvision search`` pattern (radial: petals x steps per petal, or
#: --max-steps): a 12 x 32 flower (384 steps) runs in ~4 s, so 10,000 steps is ~2 minutes
MAX_SEARCH_STEPS = 10_000
#: how far from the start the pattern, an obstacle or the patch may lie (metres): the shadow
#: area is rasterised at 5 mm over the run's bounding box, 4,000 x 4,000 cells at 10 m
MAX_SEARCH_REACH_M = 10.0
#: round obstacles of one search (each is a body in the physics world and a pass over the raster)
MAX_SEARCH_OBSTACLES = 100
#: seeds per row of ``stcvision search reproduce`` (15 rows: 1,000 seeds is ~15,000 runs, a
#: day on one core)
MAX_SEARCH_SEEDS = 1_000
#: the narrowest spiral spacing (m): the chords are found by growing a bracket along the spiral,
#: which at spacings far below the step runs for ever in floating point; 1 cm is 1/14 of
#: TASTI 2's 141 mm step
MIN_SEARCH_SPIRAL_SPACING_M = 0.01
# --- Buffon's needle (`stcvision buffon`, controllers/buffon) ------------------------------------
#: trials of one measurement: each keeps a few numbers and its own seed streams (~1 kB), and
#: 100,000 trials of the standard nest are ~4 hours of one core
MAX_BUFFON_TRIALS = 100_000
#: steps of one visit, fixed or as the most the online rule may take: ~1 minute of one core at
#: 1-2 million steps/s, ~3,000 body lengths of path; the online rule needs ~4 million in the
#: largest nest it is documented for (400 u across)
MAX_BUFFON_VISIT_STEPS = 100_000_000
#: robot-steps of one measurement, all trials and both visits: ~3 hours of one core
MAX_BUFFON_ROBOT_STEPS = 20_000_000_000
#: trail rasters held at once (one per running thread, uint32 cells): beyond this a nest is too
#: large for the trail's width on this toolkit's machines (24 GiB shared by several users)
MAX_BUFFON_RASTER_BYTES = 2 * 1024**3
#: threads of one measurement (each holds a trail raster; more than the cores only costs memory)
MAX_BUFFON_THREADS = 256
#: steps recorded for ``--rrd`` (24 bytes each, and rerun logs thinned frames of them)
MAX_BUFFON_RECORD_STEPS = 20_000_000


def check_buffon_work(
    *, trials: int, visit_steps: int, raster_bytes: int, threads: int, record_steps: int, auto: bool
) -> None:
    """Refuse, in one line naming the cap, a Buffon measurement whose trials, steps or memory
    are over the caps above (before any work; with ``auto`` the steps are the rule's ceiling,
    and only the memory and the trials are checked)."""
    from stcvision.errors import BadInputError

    if threads > MAX_BUFFON_THREADS:
        raise BadInputError(f"--threads {threads:,}: over the cap of {MAX_BUFFON_THREADS:,} (MAX_BUFFON_THREADS)")
    if trials > MAX_BUFFON_TRIALS:
        raise BadInputError(f"--trials {trials:,}: over the cap of {MAX_BUFFON_TRIALS:,} (MAX_BUFFON_TRIALS)")
    if visit_steps > MAX_BUFFON_VISIT_STEPS:
        raise BadInputError(
            f"--visit-steps {visit_steps:,}: over the cap of {MAX_BUFFON_VISIT_STEPS:,} (MAX_BUFFON_VISIT_STEPS)"
        )
    if not auto and 2 * trials * visit_steps > MAX_BUFFON_ROBOT_STEPS:
        raise BadInputError(
            f"{trials:,} trials of 2 x {visit_steps:,} steps: {2 * trials * visit_steps:,} robot-steps, over the cap "
            f"of {MAX_BUFFON_ROBOT_STEPS:,} (MAX_BUFFON_ROBOT_STEPS, ~3 hours of one core)"
        )
    if raster_bytes * threads > MAX_BUFFON_RASTER_BYTES:
        raise BadInputError(
            f"the trail rasters need {raster_bytes * threads / 2**20:,.0f} MiB ({threads} thread(s) x "
            f"{raster_bytes / 2**20:,.0f} MiB), over the cap of {MAX_BUFFON_RASTER_BYTES / 2**20:,.0f} MiB "
            "(MAX_BUFFON_RASTER_BYTES); use fewer threads, a wider trail or a smaller nest"
        )
    if record_steps > MAX_BUFFON_RECORD_STEPS:
        raise BadInputError(
            f"--rrd records up to {record_steps:,} steps a visit, over the cap of {MAX_BUFFON_RECORD_STEPS:,} "
            "(MAX_BUFFON_RECORD_STEPS); record a run with shorter visits"
        )


#: steps of one visit on the pymunk path (``buffon compare``): ~1-3,000 steps/s, so 10^6 is ~10
#: minutes a visit
MAX_PYMUNK_VISIT_STEPS = 1_000_000
# --- video input (stcvision pipeline --video / --device) -----------------------------------
#: frames one --video run reads (--frames, and --start's seek): a day at 30 frames/s; the results
#: stream out as they come, so memory does not grow with it
MAX_VIDEO_FRAMES = 2_600_000
#: --every K: one frame in K (beyond an hour at 30 frames/s between frames, a video is not a run)
MAX_VIDEO_EVERY = 100_000

# ---- counts and sizes of the command lines' other flags (each refused over its cap in one line)
#: runs per fault level of ``cover faults`` (a 6x6 run takes a few seconds; 13 levels x 1,000
#: runs is about a day on two cores, and every task is held in memory until it is stored)
MAX_FAULT_RUNS = 1_000
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


# ---------------------------------------------------------------- the STC controller's firmware
#: oracle tours of one ``stcvision firmware check`` (``--boards``): ~0.1 s each beside the Python
#: step on the host, ~1 s each through the emulator; 100,000 is hours
MAX_CHECK_BOARDS = 100_000
#: random (state, reading) pairs of one check (``--pairs``): ~20 s per million on one core
MAX_CHECK_PAIRS = 100_000_000
#: seconds ``robot run`` waits for one reply (``--timeout``): a reply that never comes must end
#: the run, and a robot that takes longer than ten minutes to answer is not answering
MAX_LINK_TIMEOUT_S = 600
