"""Is another controller the Python controller? Checked on every tick of oracle tours (random
boards, any start sub-cell and heading, and map files) and on random (state, reading) pairs
drawn over the whole input space.

:class:`Twin` runs two controllers side by side in a loop and compares every tick (state,
action, decision; a ValueError on both counts as the same); :func:`random_pairs` draws states
and readings as their bytes (:mod:`stcvision.controllers.stc.wire`), every value of every field
equally likely, the reading's kind matching the phase nine times in ten (a DECIDE tick reads a
cell, a LOOK tick a look) and any kind otherwise, so that both the decisions and the refusals
are exercised; :func:`check_random` steps them in one batch call of the C controller and one by
one in Python and compares their bytes.
"""

from __future__ import annotations

import numpy as np

from stcvision.controllers.stc import wire
from stcvision.controllers.stc.fsm import StcPhase, step
from stcvision.controllers.stc.oracle import run_oracle

__all__ = [
    "FIELDS",
    "MATCHING_KIND",
    "Twin",
    "check_boards",
    "check_random",
    "field_values",
    "oracle_boards",
    "python_out",
    "random_pairs",
]

#: a reading's kind is the one the phase reads this often (else any kind)
MATCHING_KIND = 0.9
#: oracle boards' sides in cells (inclusive) and obstacle fractions (the oracle tests' ranges)
BOARD_SIDES = (2, 10)
OBSTACLE_FRACTIONS = (0.0, 0.35)
#: pairs per batch call: bounded memory whatever the count
CHUNK = 65_536
_KIND_OF_PHASE = {StcPhase.DECIDE.value: wire.OBS_CELL, StcPhase.LOOK.value: wire.OBS_LOOK}
#: every input field and the values it takes: (name, values, how to read it from the state's
#: and the reading's bytes side by side, 8 columns)
FIELDS = {
    "phase": (len(StcPhase), lambda a: a[:, 0] & 7),
    "free": (16, lambda a: a[:, 0] >> 4),
    "sub": (4, lambda a: a[:, 1] & 3),
    "heading": (4, lambda a: a[:, 1] >> 2 & 3),
    "target": (4, lambda a: a[:, 1] >> 4 & 3),
    "parent": (4, lambda a: a[:, 1] >> 6),
    **{f: (2, lambda a, k=k: a[:, 2] >> k & 1) for k, f in enumerate(wire.STATE_FLAGS)},
    "kind": (3, lambda a: a[:, 3]),
    "boxes": (32, lambda a: a[:, 4]),
    "neighbours": (256, lambda a: a[:, 5]),
    "start_mark": (wire.NONE + 1, lambda a: a[:, 6]),
    "landing": (256, lambda a: a[:, 7]),
}


def random_pairs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` (state, reading) pairs as bytes, (n, 3) and (n, 5) uint8, from ``seed``."""
    rng = np.random.default_rng(seed)
    phase = rng.integers(0, len(StcPhase), n)
    states = np.stack([phase | rng.integers(0, 16, n) << 4, rng.integers(0, 256, n), rng.integers(0, 256, n)], 1)
    matching = np.array([_KIND_OF_PHASE.get(p, wire.OBS_NONE) for p in range(len(StcPhase))])[phase]
    kind = np.where(rng.random(n) < MATCHING_KIND, matching, rng.integers(0, 3, n))
    neigh, start, landing = rng.integers(0, 256, n), rng.integers(0, wire.NONE + 1, n), rng.integers(0, 256, n)
    obs = np.stack([kind, rng.integers(0, 32, n), neigh, start, landing], 1)
    return states.astype(np.uint8), obs.astype(np.uint8)


def field_values(states: np.ndarray, obs: np.ndarray) -> dict[str, int]:
    """Per input field, how many of its values the pairs took (all: every value was drawn)."""
    both = np.concatenate([states, obs], 1).astype(np.int64)
    return {name: int(len(np.unique(read(both)))) for name, (_, read) in FIELDS.items()}


def python_out(state_bytes: bytes, obs_bytes: bytes) -> bytes:
    """The Python step's result in the C batch's output layout."""
    state, obs = wire.decode_state(state_bytes), wire.decode_obs(obs_bytes)
    try:
        s, action, dec = step(state, obs)
    except ValueError as e:
        code = next((c for c, why in wire.STATUS_ERRORS.items() if why in str(e)), max(wire.STATUS_ERRORS))
        return bytes((code, 0)) + state_bytes + bytes(wire.DECISION_BYTES)
    return bytes((0, wire.encode_action(action))) + wire.encode_state(s) + wire.encode_decision(dec)


def check_random(n: int, seed: int, controller, *, progress=None) -> dict:
    """Step ``n`` random pairs (:func:`random_pairs`) in ``controller.step_batch`` and in Python;
    returns the counts (pairs, the same, refused by both) and the first difference."""
    same = refused = done = 0
    first = None
    seen = dict.fromkeys(FIELDS, 0)
    for start in range(0, n, CHUNK):
        states, obs = random_pairs(min(CHUNK, n - start), seed + start)
        out = controller.step_batch(states, obs)
        for k, vals in field_values(states, obs).items():
            seen[k] = max(seen[k], vals)
        for i in range(len(states)):
            want = python_out(states[i].tobytes(), obs[i].tobytes())
            got = out[i].tobytes()
            if got[0] and want[0]:  # refused: the same refusal, the state untouched
                ok = got[:1] == want[:1] and got[2 : 2 + wire.STATE_BYTES] == want[2 : 2 + wire.STATE_BYTES]
            else:
                ok = got == want
            same += ok
            refused += ok and bool(want[0])
            if not ok and first is None:
                first = {"state": states[i].tolist(), "reading": obs[i].tolist(), "c": list(got), "python": list(want)}
        done += len(states)
        if progress is not None:
            progress(done)
    return {
        "pairs": done,
        "same": same,
        "refused_by_both": refused,
        "different": done - same,
        "first_difference": first,
        "field_values_seen": seen,
        "field_values_all": {k: v for k, (v, _) in FIELDS.items()},
    }


class Twin:
    """Two controllers side by side: every tick goes to both, the reference's result is used,
    and the ticks, decisions and differences are counted."""

    name = "twin"

    def __init__(self, reference, other):
        self.reference, self.other = reference, other
        self.ticks = self.decisions = self.different = 0
        self.first_difference: dict | None = None

    def step(self, state, obs):
        self.ticks += 1
        try:
            want = self.reference.step(state, obs)
        except ValueError as e:
            want = e
        try:
            got = self.other.step(state, obs)
        except ValueError as e:
            got = e
        if isinstance(want, ValueError) or isinstance(got, ValueError):
            same = type(want) is type(got) and str(want) == str(got)
        else:
            same = want == got
            self.decisions += want.decision is not None
        if not same:
            self.different += 1
            if self.first_difference is None:
                self.first_difference = {"tick": self.ticks, "state": repr(state), "reading": repr(obs),
                                         "reference": repr(want), "other": repr(got)}  # fmt: skip
        if isinstance(want, ValueError):
            raise want
        return want

    def close(self) -> None:
        self.other.close()


def oracle_boards(n: int, seed: int):
    """``n`` random boards (sides 2-10 cells, obstacle fraction 0-0.35) each with a random free
    start sub-cell, so every start heading occurs: (seed, board) pairs."""
    from stcvision.sim_camera.board import Board

    for k in range(seed, seed + n):
        rng = np.random.default_rng(k)
        rows, cols = (int(v) for v in rng.integers(BOARD_SIDES[0], BOARD_SIDES[1] + 1, 2))
        board = Board.random((rows, cols), obstacle_fraction=float(rng.uniform(*OBSTACLE_FRACTIONS)), rng=rng)
        free = np.argwhere(np.repeat(np.repeat(board.cell_free, 2, 0), 2, 1))
        start = tuple(int(v) for v in free[rng.integers(len(free))])
        yield k, Board(board.blocked, start)


def check_boards(boards, controller) -> dict:
    """Oracle tours of ``boards`` ((name, board) pairs) with ``controller`` beside the Python
    step on every tick; the counts, and how many tours were complete."""
    from stcvision.controllers.stc.controller import PythonController

    out = {"boards": 0, "ticks": 0, "decisions": 0, "different": 0, "complete": 0, "first_difference": None}
    for name, board in boards:
        twin = Twin(PythonController(), controller)
        r = run_oracle(board, controller=twin)
        out["boards"] += 1
        out["ticks"] += twin.ticks
        out["decisions"] += twin.decisions
        out["different"] += twin.different
        out["complete"] += bool(r["finished"] and r["subcells_covered"] == r["subcells_reachable"]
                                and r["decision_mismatches"] == 0)  # fmt: skip
        if twin.first_difference and out["first_difference"] is None:
            out["first_difference"] = {"board": str(name), **twin.first_difference}
    return out
