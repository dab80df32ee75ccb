"""The ant-like STC controller's state, readings, actions and decisions as bytes: the layouts of
the portable C controller (``firmware/stc_fsm.h``) and of the serial protocol's payloads
(:mod:`stcvision.controllers.stc.link`).

A state is three bytes (phase and the "looked free" bits; sub-cell, heading, target and parent;
eight flags), a reading five (its kind; the lit boxes or the look's answer; the neighbours'
marks and red lights; the start mark's sub-cell; the landing sub-cells marked and known), a
decision three. :func:`decode_state` of :func:`encode_state` is the identity on every
:class:`~stcvision.controllers.stc.fsm.StcState`; the identity tests hold these layouts to the
C header's on every value of every field.

Two fields of an :class:`~stcvision.controllers.stc.fsm.StcObservation` do not travel:
``other_marks`` (a check the loop counts, never decided on) and ``misread`` (the loop stops
before deciding on a misread reading).
"""

from __future__ import annotations

from stcvision.controllers.stc.fsm import (
    Action,
    Decision,
    LookObs,
    NeighbourObs,
    StcObservation,
    StcPhase,
    StcState,
)

__all__ = [
    "ACTIONS",
    "DECISION_BYTES",
    "NONE",
    "OBS_BYTES",
    "OBS_CELL",
    "OBS_LOOK",
    "OBS_NONE",
    "STATE_BYTES",
    "STATE_FLAGS",
    "STATUS_ERRORS",
    "decode_action",
    "decode_decision",
    "decode_obs",
    "decode_state",
    "encode_action",
    "encode_decision",
    "encode_obs",
    "encode_state",
]

STATE_BYTES, OBS_BYTES, DECISION_BYTES = 3, 5, 3
#: "no such direction or sub-cell": no child, no start mark in this cell
NONE = 4
#: a reading's kind: nothing, a cell's observation, a look ahead
OBS_NONE, OBS_CELL, OBS_LOOK = 0, 1, 2
#: the actions' codes: their order in :class:`~stcvision.controllers.stc.fsm.Action`
ACTIONS = tuple(Action)
#: the state's flag byte, bit k = ``STATE_FLAGS[k]``
STATE_FLAGS = ("final", "closing", "at_start", "is_start", "land_parent", "land_known", "child", "fresh")
#: the C step's status codes other than 0 (done), and what the Python step's ValueError says
STATUS_ERRORS = {
    1: "the DECIDE phase needs an StcObservation",
    2: "the LOOK phase needs a LookObs",
    3: "no step from this state with this reading",
}
_D_IS_START, _D_DONE, _D_FINAL, _D_MADE = 0x08, 0x10, 0x20, 0x80
_PHASES = tuple(StcPhase)


def _bits(flags) -> int:
    return sum(1 << k for k, f in enumerate(flags) if f)


def _flags(byte: int, n: int) -> tuple[bool, ...]:
    return tuple(bool(byte >> k & 1) for k in range(n))


def encode_state(s: StcState) -> bytes:
    mode = s.phase.value | s.free << 4
    where = s.sub | s.heading << 2 | s.target << 4 | s.parent << 6
    return bytes((mode, where, _bits(getattr(s, f) for f in STATE_FLAGS)))


def decode_state(b: bytes) -> StcState:
    mode, where, flags = b[:STATE_BYTES]
    named = dict(zip(STATE_FLAGS, _flags(flags, len(STATE_FLAGS)), strict=True))
    return StcState(phase=StcPhase(mode & 7), free=mode >> 4, sub=where & 3, heading=where >> 2 & 3,
                    target=where >> 4 & 3, parent=where >> 6, **named)  # fmt: skip


def encode_obs(obs: StcObservation | LookObs | None) -> bytes:
    if obs is None:
        return bytes((OBS_NONE, 0, 0, NONE, 0))
    if isinstance(obs, LookObs):
        return bytes((OBS_LOOK, int(obs.marked), 0, NONE, 0))
    neigh = _bits(n.has_marks for n in obs.neighbours) | _bits(n.has_red for n in obs.neighbours) << 4
    landing = _bits(obs.landing_marked) | _bits(obs.landing_known) << 4
    start = NONE if obs.start_mark is None else obs.start_mark
    return bytes((OBS_CELL, _bits(obs.boxes), neigh, start, landing))


def decode_obs(b: bytes) -> StcObservation | LookObs | None:
    kind, boxes, neigh, start, landing = b[:OBS_BYTES]
    if kind == OBS_NONE:
        return None
    if kind == OBS_LOOK:
        return LookObs(bool(boxes & 1))
    nb = tuple(NeighbourObs(bool(neigh >> d & 1), bool(neigh >> (d + 4) & 1)) for d in range(4))
    return StcObservation(_flags(boxes, 5), nb, None if start == NONE else start,
                          landing_marked=_flags(landing, 4), landing_known=_flags(landing >> 4, 4))  # fmt: skip


def encode_action(a: Action) -> int:
    return ACTIONS.index(a)


def decode_action(code: int) -> Action:
    return ACTIONS[code]


def encode_decision(d: Decision | None) -> bytes:
    if d is None:
        return bytes(DECISION_BYTES)
    flags = _bits(d.visited) | _D_MADE
    flags |= _D_IS_START * d.is_start | _D_DONE * d.done | _D_FINAL * d.final
    child = NONE if d.child is None else d.child
    return bytes((flags, d.parent | d.target << 2 | child << 4, _bits(d.free)))


def decode_decision(b: bytes) -> Decision | None:
    flags, dirs, free = b[:DECISION_BYTES]
    if not flags & _D_MADE:
        return None
    child = dirs >> 4
    return Decision(_flags(flags, 3), dirs & 3, None if child == NONE else child, bool(flags & _D_IS_START),
                    bool(flags & _D_DONE), dirs >> 2 & 3, bool(flags & _D_FINAL), _flags(free, 4))  # fmt: skip
