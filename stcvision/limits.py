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


def check_board_cells(w: int, h: int) -> None:
    """Refuse a ``--board WxH`` under 1x1 or over :data:`MAX_BOARD_CELLS` cells, in one line."""
    from stcvision.errors import BadInputError

    if w < 1 or h < 1 or w * h > MAX_BOARD_CELLS:
        raise BadInputError(
            f"--board {w}x{h}: expected at least 1x1 and at most {MAX_BOARD_CELLS:,} cells in all (W x H)"
        )


# --- video input (stcvision pipeline --video / --device) -----------------------------------
#: frames one --video run reads (--frames, and --start's seek): a day at 30 frames/s; the results
#: stream out as they come, so memory does not grow with it
MAX_VIDEO_FRAMES = 2_600_000
#: --every K: one frame in K (beyond an hour at 30 frames/s between frames, a video is not a run)
MAX_VIDEO_EVERY = 100_000
