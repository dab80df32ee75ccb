"""The TASTI 2 search controller: a pure state machine over a frozen state.

``step(state, obs) -> (state, action)``. The observation is all TASTI 2 has (the
TASTI 2 paper by Russell, sec. IV): its odometric pose, the capacitive ring's verdict, the
tongue reading at the turning centre and the result of its last move ("done" or "blocked": a
move is blocked when the ring halted the drive, or the motor stalled; the executor then drives
back to where the move began -- "must return to a previous point", sec. V). An action is a
:class:`Move` (turn on the spot to an absolute heading of the odometric frame, drive ``distance_m``,
sense) or :class:`Stop`.

Phases (the four circled phases of Fig. 5; Fig. 12 and 14 plot them over time):

1. :attr:`Phase.SEARCH` -- take the next step of the search path (no detour outstanding);
2. :attr:`Phase.AVOID` -- an avoid move, at an absolute avoid heading;
3. :attr:`Phase.DETOUR_STEP` -- during a detour, the next step of the search path, when free;
4. :attr:`Phase.UNAVOID` -- during a detour, an unavoid move (opposite an avoid heading) paying
   back one avoid move.

Detour (sec. III, equations (6)-(8)): on the first blocked search step the avoid heading ``a1``
is chosen 90 degrees right of the search heading. Each avoid move adds ``+1`` to its counter,
each unavoid ``-1``; the search steps go on "where possible" in between. The order of tries (so
that the robot works its way round the obstacle anticlockwise, keeping it on its left):

==========================  ==========================================
last move                   next try
==========================  ==========================================
search step done            unavoid (pay back)
search step blocked         avoid
avoid done                  search step
avoid along a2 blocked      avoid along a1 (improved)
avoid blocked               unavoid if anything is owed, else go round the other way (below)
unavoid done                unavoid again, or the detour is over when every counter is 0
unavoid blocked             the other heading's unavoid if owed (improved), else search step
==========================  ==========================================

The detour ends when the avoid moves sum to zero (equation (8)): the robot is back on the search
path, beyond the obstacle, and the pattern goes on.

**Going round the other way** (our addition). The ring is one signal over the front half: it
says an obstacle is ahead, not on which side. When the obstacle stands to the front *right*, the
paper's avoid moves (to the right) run across its face instead of away from it: the first avoid
move is blocked, or a few avoid and unavoid moves bring the robot back to the very search step
it was blocked at without one search step taken (the counters at zero, so by equation (8) the
detour "ends" where it began, and the next collision would start the same detour again, for
ever; a 0.3 m obstacle beside the radial flower's petal does this). Either way the side is
booked as failed at that step, and the next detour from it chooses ``a1`` 90 degrees *left*
and goes round clockwise, the obstacle on its right; the rest of the machine is the same. When
both sides came back to the same step the robot stops, trapped, saying so.

**Avoid along a2 blocked** (our addition, improved policy): the obstacle is ahead and along
``a2`` too; the remaining way clear of it is along ``a1`` (the next heading round, 90 degrees on
from ``a2``), so that avoid move is tried before paying back. Without it the robot at the far
side of a large obstacle, where the path turns back across it, tried the search step, ``a2`` and
the unavoid, all three toward the obstacle, and stopped "trapped" with a free way behind it.

A detour that does not rejoin the path within ``max_detour_moves`` moves without a search step,
or five blocked moves in a row (the search step and both headings' avoid and unavoid moves,
every direction tried from one point), stops the robot with that reason.

Policies: ``none`` stops at the first blocked step (the baseline); ``simple`` is the above with
one avoid heading; ``improved`` (sec. "B. Improved Obstacle Avoidance") adds a second avoid heading
``a2`` at right angles to ``a1`` whenever the search heading is within +-45 degrees of the avoid
axis (of ``a1`` or of its unavoid heading ``a1 + pi``: moving along the search path is then moving
along the avoid axis, and the detour cannot track round the obstacle). ``a2`` is the right angle
to ``a1`` lying to the right of the search heading (so the robot still keeps the obstacle on its
left; the left of it after the switch above); its moves are counted separately and unwound by
their own unavoid moves, the most recent heading first.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from dataclasses import dataclass

from stcvision.angles import wrap_angle
from stcvision.errors import BadInputError

__all__ = [
    "Move",
    "MoveKind",
    "Phase",
    "Policy",
    "SearchConfig",
    "SearchObs",
    "SearchState",
    "Stop",
    "initial_state",
    "step",
]

ALIGN_RAD = math.radians(45.0)  # TASTI 2 paper sec. III-B: "within +-45 degrees of each other"


class Phase(enum.Enum):
    """The four circled phases of the TASTI 2 paper's Fig. 5 (module docstring), and the end."""

    SEARCH = 1
    AVOID = 2
    DETOUR_STEP = 3
    UNAVOID = 4
    DONE = 5


class Policy(enum.Enum):
    """How the robot gets round an obstacle: not at all, one avoid heading, or two (module docstring)."""

    NONE = "none"
    SIMPLE = "simple"
    IMPROVED = "improved"


class MoveKind(enum.Enum):
    """A step of the search path, an avoid move, or an unavoid move paying one back."""

    SEARCH = "search"
    AVOID = "avoid"
    UNAVOID = "unavoid"


@dataclass(frozen=True, kw_only=True, slots=True)
class SearchConfig:
    """How the TASTI 2 search runs: its pattern, its detour policy, its stop rule.

    Attributes
    ----------
    pattern : object
        The search pattern (:mod:`stcvision.controllers.search.patterns`): the search path's
        headings and step.
    policy : Policy
        The detour policy: ``none`` stops at the first blocked step (the baseline), ``simple``
        uses one avoid heading, ``improved`` (the paper's "Improved Obstacle Avoidance") a
        second one where the first cannot track round the obstacle.
    threshold : float
        The tongue reading that stops the search (sensor units; the paper's robot stopped
        above 296 Hz, Fig. 12).
    max_detour_moves : int
        The loop guard: moves since the last search step before a detour gives up.

    Raises
    ------
    BadInputError
        When ``policy`` is not a :class:`Policy` or ``max_detour_moves`` is below 1.
    """

    pattern: object
    policy: Policy = Policy.IMPROVED
    threshold: float = 0.5
    max_detour_moves: int = 60

    def __post_init__(self):
        if not isinstance(self.policy, Policy):
            raise BadInputError(f"policy must be one of none, simple, improved; got {self.policy!r}")
        if self.max_detour_moves < 1:
            raise BadInputError("max_detour_moves must be >= 1")


@dataclass(frozen=True, slots=True)
class SearchObs:
    """What TASTI 2 senses after a move (or at the start, ``last_move=None``)."""

    pose_odo: tuple[float, float, float]  # dead-reckoned x m, y m, heading rad
    ring: bool  # the capacitive ring is at its stop threshold now
    tongue: float  # chemical reading at the turning centre
    last_move: str | None  # "done", "blocked" or None before the first move


@dataclass(frozen=True, slots=True)
class Move:
    """An action: turn on the spot to an absolute heading of the odometric frame, drive, sense."""

    heading_rad: float  # absolute heading in the odometric frame
    distance_m: float
    kind: MoveKind
    phase: Phase
    heading_index: int = 0  # 1 or 2 for avoid/unavoid moves: which avoid heading


@dataclass(frozen=True, slots=True)
class Stop:
    """An action: the search is over, and why."""

    reason: str  # "found", "pattern done", "blocked (policy none)", "trapped: ...", "detour did not rejoin ..."


@dataclass(frozen=True, slots=True)
class SearchState:
    """Constant-size state: the search step count, the avoid headings and their counters."""

    config: SearchConfig
    phase: Phase = Phase.SEARCH
    i: int = 0  # search-path steps taken
    a1: float | None = None  # avoid heading 1 (rad, odometric frame)
    a2: float | None = None  # avoid heading 2 (improved policy)
    side: int = -1  # -1: avoid to the right of the search heading (the paper's), +1: to the left
    k1: int = 0  # net avoid moves along a1 (equation (8) wants 0)
    k2: int = 0
    pending: Move | None = None  # the move whose result the next observation reports
    detour_moves: int = 0  # moves since the last search step (loop guard)
    blocked_run: int = 0  # consecutive blocked moves
    tried: int = 0  # the moves blocked from this point (bits of :func:`_bit`), cleared by a move done
    origin_i: int = -1  # the search step the current (or last) detour began at
    failed_i: int = -1  # the search step at which the detours in ``failed_sides`` came to nothing
    failed_sides: int = 0  # bit 1: round to the right (side -1) failed at ``failed_i``; bit 2: to the left
    reason: str = ""

    @property
    def in_detour(self) -> bool:
        """A detour is outstanding: some avoid moves are not paid back."""
        return self.k1 != 0 or self.k2 != 0


def initial_state(config: SearchConfig) -> SearchState:
    """Return the state before the first move: searching, no step taken."""
    return SearchState(config=config)


def _search_move(s: SearchState, phase: Phase) -> Move:
    p = s.config.pattern
    return Move(p.headings_rad[s.i], p.step_m, MoveKind.SEARCH, phase)


def _avoid_heading(s: SearchState) -> tuple[SearchState, int]:
    """Which avoid heading the next avoid move takes (and the state with ``a2`` chosen)."""
    if s.config.policy is Policy.IMPROVED:
        th = s.config.pattern.headings_rad[s.i]
        off = abs(wrap_angle(th - s.a1))
        if min(off, math.pi - off) <= ALIGN_RAD:  # search heading along the avoid axis
            if s.a2 is None:
                cands = (s.a1 + 0.5 * math.pi, s.a1 - 0.5 * math.pi)
                a2 = min(cands, key=lambda a: abs(wrap_angle(a - (th + s.side * 0.5 * math.pi))))
                s = dataclasses.replace(s, a2=wrap_angle(a2))
            return s, 2
    return s, 1


def _unavoid(s: SearchState, j: int) -> Move | None:
    """Return the unavoid move paying back one avoid move along heading ``j``.

    It runs opposite the avoid heading; None if nothing is owed along it.
    """
    a, k = (s.a2, s.k2) if j == 2 else (s.a1, s.k1)
    if k <= 0:
        return None
    return Move(wrap_angle(a + math.pi), s.config.pattern.step_m, MoveKind.UNAVOID, Phase.UNAVOID, j)


def _avoid(s: SearchState, j: int) -> Move | None:
    """Return an avoid move along heading ``j`` (None for ``a2`` before the improved policy set it)."""
    a = s.a2 if j == 2 else s.a1
    if a is None:
        return None
    return Move(a, s.config.pattern.step_m, MoveKind.AVOID, Phase.AVOID, j)


def _bit(m: Move) -> int:
    """Return a move's bit in :attr:`SearchState.tried`: search 1, avoid 2 / 4, unavoid 8 / 16 (heading 1 / 2)."""
    if m.kind is MoveKind.SEARCH:
        return 1
    return (2 if m.kind is MoveKind.AVOID else 8) * m.heading_index


def _try(s: SearchState, moves: list[Move | None]) -> tuple[SearchState, Move | Stop]:
    """Take the first of ``moves`` not yet blocked from this point; stop when every one was."""
    for m in moves:
        if m is not None and not s.tried & _bit(m):
            return _go(s, m)
    return _stop(s, "trapped: every move from here is blocked")


def _account(s: SearchState, done: bool) -> SearchState:
    """Book the result of the pending move."""
    m = s.pending
    if m is None or not done:
        return s
    if m.kind is MoveKind.SEARCH:
        return dataclasses.replace(s, i=s.i + 1, detour_moves=0)
    sign = 1 if m.kind is MoveKind.AVOID else -1
    if m.heading_index == 2:
        return dataclasses.replace(s, k2=s.k2 + sign)
    return dataclasses.replace(s, k1=s.k1 + sign)


def _untried_side(s: SearchState) -> int | None:
    """Return the side to go round an obstacle met at search step ``s.i``.

    Right (-1, the paper's) unless a detour that way already came back to this step without
    progress, then left (+1); None when both did.
    """
    tried = s.failed_sides if s.failed_i == s.i else 0
    return next((side for side, bit in ((-1, 1), (1, 2)) if not tried & bit), None)


def _failed(s: SearchState) -> SearchState:
    """Book that the detour on ``s.side`` came to nothing at search step ``s.i``."""
    tried = s.failed_sides if s.failed_i == s.i else 0
    return dataclasses.replace(s, failed_i=s.i, failed_sides=tried | (1 if s.side == -1 else 2))


def _go(s: SearchState, move: Move) -> tuple[SearchState, Move]:
    return dataclasses.replace(s, phase=move.phase, pending=move, detour_moves=s.detour_moves + 1), move


def _stop(s: SearchState, reason: str) -> tuple[SearchState, Stop]:
    return dataclasses.replace(s, phase=Phase.DONE, pending=None, reason=reason), Stop(reason)


def step(state: SearchState, obs: SearchObs) -> tuple[SearchState, Move | Stop]:
    """Make one decision after a move (or at the start). Pure: ``state`` is not changed."""
    if state.phase is Phase.DONE:
        return state, Stop(state.reason)
    cfg = state.config
    done = obs.last_move == "done"
    s = _account(state, done)
    if done or state.pending is None:
        s = dataclasses.replace(s, blocked_run=0, tried=0)
    else:
        s = dataclasses.replace(s, blocked_run=s.blocked_run + 1, tried=s.tried | _bit(state.pending))
    last = state.pending
    if obs.tongue >= cfg.threshold:
        return _stop(s, "found")
    if s.i >= cfg.pattern.n_steps:
        return _stop(s, "pattern done")
    if s.blocked_run >= 5:  # the search step, both avoid and both unavoid headings blocked from here
        return _stop(s, "trapped: every move from here is blocked")
    if s.detour_moves >= cfg.max_detour_moves:
        return _stop(s, "detour did not rejoin the search path")
    if last is None:
        return _go(s, _search_move(s, Phase.SEARCH))

    if last.kind is MoveKind.SEARCH and not done:
        if cfg.policy is Policy.NONE:
            return _stop(s, "blocked (policy none)")
        if not s.in_detour and not s.tried & ~_bit(last):  # first collision: a new detour
            side = _untried_side(s)
            if side is None:
                return _stop(s, f"trapped: the detours both ways round the obstacle came back to search step {s.i}")
            th = cfg.pattern.headings_rad[s.i]
            s = dataclasses.replace(s, a1=wrap_angle(th + side * 0.5 * math.pi), a2=None, side=side, origin_i=s.i)
        s, j = _avoid_heading(s)
        return _try(s, [_avoid(s, j), _avoid(s, 3 - j), _unavoid(s, 2), _unavoid(s, 1)])
    if last.kind is MoveKind.AVOID and not done:
        if s.in_detour or s.a2 is not None:
            # the other avoid heading first (beside a large obstacle the one tried may point
            # into it while the other leads clear), then pay back
            s, _ = _avoid_heading(s)
            later = [_unavoid(s, 2), _unavoid(s, 1), _search_move(s, Phase.DETOUR_STEP)]
            return _try(s, [_avoid(s, 3 - last.heading_index), *later])
        s = _failed(s)
        side = _untried_side(s)
        if side is not None:  # the obstacle is to the front right: go round it the other way
            s = dataclasses.replace(s, a1=wrap_angle(s.a1 + math.pi), a2=None, side=side, tried=0)
            return _go(s, Move(s.a1, cfg.pattern.step_m, MoveKind.AVOID, Phase.AVOID, 1))
        return _stop(s, "trapped: search step and avoid move both blocked")
    if last.kind is MoveKind.UNAVOID and not done:  # the other heading's unavoid, then the search step
        s, j = _avoid_heading(s)
        return _try(
            s, [_unavoid(s, 2), _unavoid(s, 1), _search_move(s, Phase.DETOUR_STEP), _avoid(s, j), _avoid(s, 3 - j)]
        )
    if not s.in_detour:
        if state.in_detour and s.i == s.origin_i:  # back where it began without a search step
            s = _failed(s)
        return _go(s, _search_move(s, Phase.SEARCH))  # the detour is over (equation (8))
    if last.kind is MoveKind.SEARCH:  # done, in a detour: pay back
        return _go(s, _unavoid(s, 2) or _unavoid(s, 1))
    if last.kind is MoveKind.AVOID:  # done
        return _go(s, _search_move(s, Phase.DETOUR_STEP))
    nxt = _unavoid(s, 2) or _unavoid(s, 1)  # unavoid done: again while it works
    return _go(s, nxt if nxt is not None else _search_move(s, Phase.DETOUR_STEP))
