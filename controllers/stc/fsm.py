"""Ant-like STC as a pure O(1)-memory finite-state machine (no physics, no camera).

The algorithm is Srour & Abboud's ("Optimally Covering an Unknown Environment with Ant-like STC
algorithm"); :mod:`stcvision.controllers.stc.oracle` runs this machine on a grid against the
truth.

The geometry (entry frame, sub-cells 0..3, directions 0 right 1 forward 2 left 3 back) is
:mod:`stcvision.controllers.stc.grid`'s.

Marking: just before every forward move the robot marks the sub-cell it leaves on its rear edge
(the edge opposite the direction of travel). The five-box table of the STC geometry
(``docs/explanation/stc-geometry.md``) is used as is:

====  ======================================  =================================
box   inside sub-cell, along edge             laid when
====  ======================================  =================================
1     sub-cell 1, right edge (exterior)        1 left going left
2     sub-cell 2, top edge (exterior)          2 left going down
3     sub-cell 2, right edge                   2 left going left
4     sub-cell 3, top edge                     3 left going down
5     sub-cell 1, bottom edge                  1 left going up
====  ======================================  =================================

sub-cell 1 visited iff box 1 or 5; 2 iff box 2 or 3; 3 iff box 4. ``run_oracle`` checks the
table against the true visit history at every decision (``decision_mismatches``) and counts
marks of the current cell lying outside the five boxes and the start-mark positions
(``box_table_violations``); the tests find both zero on hundreds of random boards, so the table
and the three visited-rules hold. On re-entry exactly these lit-box sets occur (``box_patterns``):
{4}, {2,4}, {3,4}, {2,4,5}, {3,4,5}, {1,2,4}, {1,3,4}. Note on a remark about the paper:
the paper's "entered from sub-cell 1, takes left: boxes 1, 3 and 4" is *also* right — it is the
path 1 -> 2 -> out to the left child (box 3) -> back into 3 -> out down (box 4); the path
1 -> 2 -> 3 -> out down lights 1, 2 and 4. Both occur; the rules "2 iff box 2 or 3" cover both.

Start mark (this module's choice)
---------------------------------
Before its first move the robot turns left, switches the rear LEDs on without moving (action
``MARK``) and turns back right. This lays a second kind of mark inside the start sub-cell, along
its right edge in the start frame (an exterior edge of the start cell). In any entry frame, the
start sub-cell ``m`` then carries a mark on its exterior edge in direction ``m`` (0: sub-cell 0's
right edge, 1: sub-cell 1's top edge, 2: sub-cell 2's left edge, 3: sub-cell 3's bottom edge).
Ordinary marks never sit there (sub-cell ``m`` is only ever left in directions ``m`` or
``m + 1``, which mark its edges ``m + 2`` and ``m + 3``), so the camera can read the start mark
and *which* sub-cell is the start sub-cell from the floor alone: ``StcObservation.start_mark``.
It also makes the start cell read as visited for its neighbours from the very first step.

Start cell: the cell behind the robot is a virtual parent; the start cell scans all four
neighbours, the virtual parent's direction last. If it is free and unmarked the robot goes there,
and the final return from it lands on the start sub-cell: the controller sees the start mark in
its own sub-cell 0 with sub-cells 1-3 all visited and stops (``DONE``). Otherwise it covers the
start cell's remaining sub-cells and stops beside the start sub-cell.

Neighbour choice
----------------
A neighbour is a candidate child when it shows no red light and no mark *and* its exit can be
reached through unvisited sub-cells (the exit towards ``d`` is from sub-cell ``d``, reached via
``1..d``). A correct tour never needs more (the oracle runs never meet the difference); with a
camera, a neighbour that looks new beyond a visited sub-cell has marks it missed, and walking
there would cover sub-cells twice. Before entering a child the robot looks at it once more
from the sub-cell next to it (:data:`Action.LOOK`); if it is marked after all the exit moves on
to the next candidate, or back to the parent. A mark in the sub-cell a return to the parent
lands on (the start mark, laid at the very beginning) is the tour closing. The decision sees
that sub-cell 0.2-0.4 m away; where its frames could not have seen a mark as old as the tour
there (``StcObservation.landing_known``, :mod:`stcvision.controllers.stc.claims`), the robot looks at it
again before the return, from next to it.

Controller
----------
:func:`step` ``(StcState, StcObservation) -> Step(StcState, Action, Decision)`` is a pure
function over a frozen, constant-size state (phase, current sub-cell index in the entry frame, heading relative
to the entry frame, exit direction, a "stop there" flag). No map, no history: every decision comes
from the observation (:func:`decide`).
"""

from __future__ import annotations

import dataclasses
import enum
from dataclasses import dataclass
from typing import NamedTuple

from stcvision.stc_geometry import VISITED_BY

__all__ = [
    "Action",
    "REENTRY_BOXES",
    "Decision",
    "LookObs",
    "NeighbourObs",
    "StcObservation",
    "StcPhase",
    "StcState",
    "Step",
    "decide",
    "initial_state",
    "step",
]


#: the lit-box sets a cell shows when the robot comes back into it from a child (every decision
#: but the first and those in a cell just entered as a child): box 4 always -- it left into
#: that child from sub-cell 3 going down, and comes back up into sub-cell 0 (STC goes round a
#: child counter-clockwise) -- and nothing else occurs (``run_oracle``'s ``box_patterns``,
#: tested on random boards and all start headings)
REENTRY_BOXES = frozenset({(4,), (2, 4), (3, 4), (2, 4, 5), (3, 4, 5), (1, 2, 4), (1, 3, 4)})


class Action(enum.Enum):
    """What the controller asks of the robot at one tick.

    Carried out by :func:`stcvision.controllers.stc.robot.act` on any
    :class:`stcvision.controllers.stc.robot.Motors`.

    Attributes
    ----------
    FORWARD
        Mark the rear edge of the current sub-cell, then drive one sub-cell.
    TURN_LEFT
        Turn 90 deg counter-clockwise in place.
    TURN_RIGHT
        Turn 90 deg clockwise in place.
    MARK
        Rear LEDs on without moving (only to lay the start mark).
    LOOK
        Before leaving a cell: look ahead (the next tick gets a :class:`LookObs`).
    DONE
        The tour is over.
    """

    FORWARD = "forward"
    TURN_LEFT = "turn_left"
    TURN_RIGHT = "turn_right"
    MARK = "mark"
    LOOK = "look"
    DONE = "done"


class StcPhase(enum.Enum):
    """Where the controller is in its tour: the start mark, a decision, a walk, a look, the end."""

    INIT = 0  # about to turn left to lay the start mark
    START_MARK = 1  # facing left of the start heading: lay the start mark
    START_FACE = 2  # turn back to the start heading
    DECIDE = 3  # just entered a cell (sub-cell 0, heading up): read the floor and decide
    MOVE = 4  # walking the cell's sub-cells counter-clockwise towards the exit
    DONE = 5
    LOOK = 6  # at the exit, facing it: is the child really unmarked / does the tour close here?


@dataclass(frozen=True, slots=True)
class StcState:
    """Constant-size controller state (no map, no history).

    ``parent`` to ``child`` keep what the decision found, so that a look at the exit can revise
    the exit.

    Attributes
    ----------
    phase : StcPhase
        Where the controller is in its tour.
    sub : int
        Current sub-cell, entry frame (0..3).
    heading : int
        Current heading as an entry-frame direction (0 right, 1 up, 2 left, 3 down).
    target : int
        Exit direction = index of the sub-cell to leave from (0..3).
    final : bool
        Stop in sub-cell ``target`` instead of leaving the cell.
    closing : bool
        This exit lands on a marked sub-cell: the tour closes there.
    at_start : bool
        The first decision, on the start sub-cell.
    parent : int
        Entry-frame direction of the parent.
    free : int
        Bit d: neighbour d looked free (no mark, no red light) at the decision.
    is_start : bool
        This is the start cell (its virtual parent is the last candidate).
    land_parent : bool
        The sub-cell beyond the exit to the parent is marked.
    land_known : bool
        ... and the decision's frames could tell (else: a look at the exit).
    child : bool
        The exit ``target`` leads into a child (not back to the parent).
    fresh : bool
        DECIDE: this cell was just entered as a child the look found unmarked.
    """

    phase: StcPhase = StcPhase.INIT
    sub: int = 0
    heading: int = 1
    target: int = 0
    final: bool = False
    closing: bool = False
    at_start: bool = False
    parent: int = 3
    free: int = 0
    is_start: bool = False
    land_parent: bool = False
    land_known: bool = True
    child: bool = False
    fresh: bool = False


def initial_state() -> StcState:
    """Return the state before the first tick: about to turn left and lay the start mark."""
    return StcState()


@dataclass(frozen=True, slots=True)
class NeighbourObs:
    """A neighbour cell as the camera reads it: marks in it, and a red light.

    Attributes
    ----------
    has_marks : bool
        Any mark inside that cell.
    has_red : bool
        A red light: an obstacle cell, or beyond the board.
    """

    has_marks: bool
    has_red: bool


@dataclass(frozen=True, slots=True)
class StcObservation:
    """What the camera reports in the entry frame (robot heading up, in sub-cell 0).

    Attributes
    ----------
    boxes : tuple of bool
        The five boxes, lit or not (box 1 first).
    neighbours : tuple of NeighbourObs
        Right, forward, left, back.
    start_mark : int or None
        Entry-frame sub-cell holding the start mark, None if not this cell.
    other_marks : int
        Marks of this cell at none of the box / start-mark positions (checks).
    landing_marked : tuple of bool
        Per direction d: the sub-cell the robot lands on when it leaves towards d (neighbour d's
        sub-cell next to our sub-cell d) already carries a mark. A return to the parent normally
        lands on a fresh sub-cell; landing on a marked one is the tour closing on the start
        sub-cell -- read from the floor, before the move, since the start mark under the robot
        is hidden from its own camera.
    landing_known : tuple of bool
        Per direction: ``landing_marked`` is sure -- a mark was seen, or the frames could have
        seen one as old as any can be (:mod:`stcvision.controllers.stc.claims`); where it is
        not, the robot looks at that sub-cell from next to it before it leaves that way.
    misread : str
        Why no STC tour can show this reading ("" when one can:
        :func:`stcvision.controllers.stc.claims.return_misread`); the loop stops before deciding
        on it.
    """

    boxes: tuple[bool, bool, bool, bool, bool]
    neighbours: tuple[NeighbourObs, NeighbourObs, NeighbourObs, NeighbourObs]
    start_mark: int | None
    other_marks: int = 0
    landing_marked: tuple[bool, bool, bool, bool] = (False, False, False, False)
    landing_known: tuple[bool, bool, bool, bool] = (True, True, True, True)
    misread: str = ""


@dataclass(frozen=True, slots=True)
class LookObs:
    """What the look before leaving a cell reports.

    Attributes
    ----------
    marked : bool
        Into a child, any mark in the cell ahead; back to the parent, any mark in the sub-cell
        just ahead (where the robot lands).
    """

    marked: bool


@dataclass(frozen=True, slots=True)
class Decision:
    """What a decision made of one observation (:func:`decide`).

    Attributes
    ----------
    visited : tuple of bool
        Sub-cells 1, 2, 3 visited.
    parent : int
        Entry-frame direction of the parent (the virtual parent in the start cell).
    child : int or None
        Direction of the new neighbour to enter; None: back to the parent, or stop in the start
        cell.
    is_start : bool
        This is the start cell.
    done : bool
        Back on the start sub-cell with the whole cell covered: the tour is done.
    target : int
        Sub-cell to go to (and leave from unless ``final``).
    final : bool
        Stop in sub-cell ``target`` instead of leaving the cell (in the start cell, with no child
        left to enter).
    free : tuple of bool
        Per direction: a candidate child (no red light, no mark, exit reachable); ``child`` is
        the first of them counter-clockwise after the parent, the looks may move on to the next.
    """

    visited: tuple[bool, bool, bool]
    parent: int
    child: int | None
    is_start: bool
    done: bool
    target: int
    final: bool
    free: tuple[bool, bool, bool, bool] = (False, False, False, False)


def decide(obs: StcObservation, *, at_start: bool = False) -> Decision:
    """Make the ant-like STC decision from one observation (pure, no memory).

    Parameters
    ----------
    obs : StcObservation
        The cell read in its entry frame (robot in sub-cell 0, heading up).
    at_start : bool
        The very first decision, standing on the start sub-cell (whose start mark the camera
        cannot see).

    Returns
    -------
    Decision
        Visited sub-cells from the five boxes, the parent (the first unvisited-then-visited
        sub-cell counter-clockwise), and the first candidate child counter-clockwise after it.
    """
    v = (False, *(any(obs.boxes[b - 1] for b in VISITED_BY[m]) for m in (1, 2, 3)))
    is_start = obs.start_mark is not None or at_start
    if is_start and obs.start_mark == 0 and v[1] and v[2] and v[3]:
        return Decision(v[1:], 3, None, True, True, 0, True)
    parent = 3  # nothing visited: we came from behind (or the virtual parent in the start cell)
    for m in (1, 2, 3):
        if not v[m - 1] and v[m]:
            parent = m - 1
            break
    free = _free(obs, v)
    child = _next_child(parent, free, is_start)
    if child is not None:
        return Decision(v[1:], parent, child, is_start, False, child, False, free)
    return Decision(v[1:], parent, None, is_start, False, parent, is_start, free)


def _free(obs: StcObservation, visited) -> tuple[bool, ...]:
    """Tell, per direction, whether the neighbour is a candidate child.

    It is when it shows no red light and no mark, and its exit can be reached through unvisited
    sub-cells only (the exit to direction ``d`` is from sub-cell ``d``, reached
    through sub-cells ``1..d``). In a correct tour every new neighbour is reachable so; one that
    looks new beyond a visited sub-cell has marks the camera missed.
    """
    return tuple(
        not (n.has_red or n.has_marks) and not any(visited[k] for k in range(1, d + 1))
        for d, n in enumerate(obs.neighbours)
    )


def _next_child(parent: int, free, is_start: bool, after: int | None = None) -> int | None:
    """Return the next free neighbour counter-clockwise from the parent (None if there is none).

    The virtual parent comes last in the start cell; with ``after``, the first after it in that
    order.
    """
    order = [(parent + k) % 4 for k in (1, 2, 3)] + ([parent] if is_start else [])
    if after is not None:
        order = order[order.index(after) + 1 :]
    return next((d for d in order if free[d]), None)


def _plan(
    dec_parent: int, free, is_start: bool, land_parent: bool, child: int | None, land_known: bool = True, **kw
) -> StcState:
    """Return the MOVE state towards ``child``, or back to the parent when there is none."""
    mask = sum(1 << d for d in range(4) if free[d])
    if child is not None:
        target, final, closing = child, False, False
    else:  # back to the parent; in the start cell: stop in its sub-cell instead
        target, final = dec_parent, is_start
        closing = not final and land_parent
    return StcState(
        phase=StcPhase.MOVE, target=target, final=final, closing=closing, parent=dec_parent, free=mask,
        is_start=is_start, land_parent=land_parent, land_known=land_known, child=child is not None, **kw,
    )  # fmt: skip


class Step(NamedTuple):
    """One controller tick's result: the next state, the action, and the decision it made.

    The decision is kept so that nothing downstream (the referee, the observers) decides again.

    Attributes
    ----------
    state : StcState
        The next state.
    action : Action
        What the robot does now.
    decision : Decision or None
        The decision of a ``DECIDE`` tick that read an observation; None on every other tick.
    """

    state: StcState
    action: Action
    decision: Decision | None = None


def step(state: StcState, obs: StcObservation | LookObs | None) -> Step:
    """Run one controller tick.

    ``obs`` is read in the ``DECIDE`` phase (a :class:`StcObservation`) and the ``LOOK`` phase
    (a :class:`LookObs`).

    Before leaving into a child the robot looks at it once more, from the sub-cell next to it
    (``Action.LOOK``): from there a visited neighbour's marks are 2-3x closer than from the
    decision's sub-cell, so an old mark the decision missed is still read. If the child turns
    out marked, the exit moves on to the next free neighbour counter-clockwise (or the parent).
    The state stays constant-size: the four "looked free" bits and the parent direction.

    Parameters
    ----------
    state : StcState
        The controller's state (frozen, constant size).
    obs : StcObservation, LookObs or None
        What the robot read for this tick: an observation in ``DECIDE``, a look in ``LOOK``,
        nothing in the other phases.

    Returns
    -------
    Step
        The next state, the action, and the :class:`Decision` when this tick decided.

    Raises
    ------
    ValueError
        When the ``DECIDE`` phase gets no :class:`StcObservation`, or the ``LOOK`` phase no
        :class:`LookObs`.

    Examples
    --------
    >>> from stcvision.controllers.stc.fsm import Action, initial_state, step
    >>> state, action, decision = step(initial_state(), None)
    >>> action is Action.TURN_LEFT and decision is None
    True
    """
    ph = state.phase
    if ph is StcPhase.INIT:
        return Step(dataclasses.replace(state, phase=StcPhase.START_MARK), Action.TURN_LEFT)
    if ph is StcPhase.START_MARK:
        return Step(dataclasses.replace(state, phase=StcPhase.START_FACE), Action.MARK)
    if ph is StcPhase.START_FACE:
        return Step(StcState(phase=StcPhase.DECIDE, at_start=True), Action.TURN_RIGHT)
    if ph is StcPhase.DONE:
        return Step(state, Action.DONE)
    if ph is StcPhase.DECIDE:
        if state.closing:  # we just drove onto the marked start sub-cell: the tour is closed
            return Step(StcState(phase=StcPhase.DONE), Action.DONE)
        if not isinstance(obs, StcObservation):
            raise ValueError("the DECIDE phase needs an StcObservation")
        dec = decide(obs, at_start=state.at_start)
        if dec.done:
            return Step(StcState(phase=StcPhase.DONE), Action.DONE, dec)
        land = bool(obs.landing_marked[dec.parent])
        known = land or bool(obs.landing_known[dec.parent])
        return Step(*_walk(_plan(dec.parent, dec.free, dec.is_start, land, dec.child, known)), dec)
    if ph is StcPhase.LOOK:
        if not isinstance(obs, LookObs):
            raise ValueError("the LOOK phase needs a LookObs")
        if not state.child:  # the look at the parent's sub-cell ahead: marked, the tour closes there
            return Step(StcState(phase=StcPhase.DECIDE, closing=obs.marked), Action.FORWARD)
        if not obs.marked:  # a new cell indeed: enter it
            return Step(StcState(phase=StcPhase.DECIDE, fresh=True), Action.FORWARD)
        free = [bool(state.free >> d & 1) and d != state.target for d in range(4)]
        nxt = _next_child(state.parent, free, state.is_start, after=state.target)
        state = _plan(
            state.parent, free, state.is_start, state.land_parent, nxt, state.land_known,
            sub=state.sub, heading=state.heading,
        )  # fmt: skip
    return Step(*_walk(state))


def _walk(state: StcState) -> tuple[StcState, Action]:
    """Run the ``MOVE`` phase's tick.

    Turn towards the next sub-cell on the way to the exit (counter-clockwise), drive there, look
    before leaving, leave, or stop in the final sub-cell.
    """
    m, r, j = state.sub, state.heading, state.target
    if state.final and m == j:
        return StcState(phase=StcPhase.DONE, sub=m, heading=r, target=j, final=True), Action.DONE
    want = j if m == j else (m + 1) % 4
    if r == want:
        if m == j and (state.child or not (state.closing or state.land_known)):
            # look at the child before entering it; before a return to the parent, at the
            # sub-cell it lands on, now just ahead, unless the decision's frames could tell
            return dataclasses.replace(state, phase=StcPhase.LOOK), Action.LOOK
        if m == j:  # leave the cell: new entry frame in the next cell
            return StcState(phase=StcPhase.DECIDE, closing=state.closing), Action.FORWARD
        return dataclasses.replace(state, sub=(m + 1) % 4), Action.FORWARD
    if (want - r) % 4 in (1, 2):
        return dataclasses.replace(state, heading=(r + 1) % 4), Action.TURN_LEFT
    return dataclasses.replace(state, heading=(r - 1) % 4), Action.TURN_RIGHT
