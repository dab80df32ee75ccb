"""What a reading rules out, and how far away: the robot never decides on a frame that could not
have shown what it takes for absent.

A decision or a look reads marks as present or absent. *Present* is what a frame saw; *absent*
is only worth what the frame could have seen: a mark older than the frame's visibility horizon
at its distance is invisible to it. The robot knows its clock (no mark can be older), its own
frame settings and the camera's calibrated horizon (:meth:`stcvision.controllers.stc.frames.Exposures.horizon`),
not the true ages of the marks. So every absence a reading relies on is a :class:`Claim` --
what is ruled out, and the distance of the dot that decides it -- and the perception takes
longer frames until each claim is covered by a frame whose horizon there reaches the clock
(:func:`read_until_sure`), or stops with :class:`OutOfSight` saying which claim, where, how old
the marks may be and how far its longest frame sees there.

The distances come from the one STC geometry (:mod:`stcvision.stc_geometry`) and the LED row
(:data:`stcvision.sim_camera.phosphor.LED_OFFSETS_M`, the row's inset from the sub-cell's edge): for a mark,
the distance of the ``n``-th nearest of its four dots, ``n`` being the dots the vision needs
before it counts a mark (:class:`stcvision.observation.ObservationParams`: 2 in a box or a cell,
3 in a landing sub-cell), plus the robot's position margin. Where the mark may lie on any edge of
a sub-cell (a landing sub-cell, the cell ahead) the farthest edge counts.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from stcvision.stc_geometry import BOX_EDGES, DIRECTIONS, START_MARKS, SUBCELLS

__all__ = [
    "Claim",
    "OutOfSight",
    "ahead_claims",
    "decision_claims",
    "distance_m",
    "landing_claim",
    "landing_claims",
    "read_until_sure",
    "return_misread",
]

#: where the robot stands in its cell units (sub-cell sides, cell centre at 0): sub-cell 0's
#: centre, the robot's turning centre (:data:`stcvision.profile.ROBOT_IN_CELL`)
_ROBOT = np.array([0.5, -0.5])


class OutOfSight(Exception):
    """The robot cannot rule out what it must: the ``abort_reason`` of the run."""


@dataclass(frozen=True, slots=True)
class Claim:
    what: str  # what the reading takes for absent, in words
    rho_m: float  # the distance of the dot that decides it (margin included)


def _row_dots(sub_centre, edge: int, side: float) -> np.ndarray:
    """The four dots of a mark along edge ``edge`` (a direction) of the sub-cell centred at
    ``sub_centre`` (cell units: sub-cell sides of ``side`` m)."""
    from stcvision.sim_camera.phosphor import LED_OFFSETS_M, PhosphorLayer

    inset = (0.5 * side + PhosphorLayer().rear_led_x_m) / side  # the LEDs sit behind the centre
    e = np.asarray(DIRECTIONS[edge], float)
    along = np.array([-e[1], e[0]])
    centre = np.asarray(sub_centre, float) + e * (0.5 - inset)
    return centre + np.outer(np.asarray(LED_OFFSETS_M) / side, along)


def _deciding_distance(sub_centre, edges, n_dots: int, side: float) -> float:
    """Sub-cell sides from the robot to the ``n_dots``-th nearest dot of a mark on the farthest
    of ``edges`` of that sub-cell."""
    return max(float(np.sort(np.hypot(*(_row_dots(sub_centre, e, side) - _ROBOT).T))[n_dots - 1]) for e in edges)


def _centre(m: int, shift=(0.0, 0.0)) -> np.ndarray:
    return 0.5 * np.asarray(SUBCELLS[m], float) + np.asarray(shift, float)


@cache
def _distances(side: float) -> dict[str, float]:
    """Metres to the deciding dot of each kind of claim on sub-cells of ``side`` m."""
    from stcvision.observation import LANDING_DOTS, ObservationParams

    # dots the vision needs before it counts a mark: in a box, a neighbour or the cell ahead,
    # and in a landing sub-cell
    box_dots, landing_dots = ObservationParams().min_dots, max(ObservationParams().min_dots, LANDING_DOTS)
    d = {f"box {b}": _deciding_distance(_centre(m), [e], box_dots, side) for b, (m, e) in BOX_EDGES.items()}
    d |= {f"start mark {m}": _deciding_distance(_centre(m), [START_MARKS[m]], box_dots, side) for m in (1, 2, 3)}
    # at a look the robot stands at the same point, facing "up", in the front-right sub-cell of
    # its cell: the cell ahead is centred one sub-cell side up, its landing sub-cell just ahead
    ahead = [_centre(m, (0.0, 1.0)) for m in range(4)]
    d["cell ahead"] = max(_deciding_distance(c, range(4), box_dots, side) for c in ahead)
    d["landing ahead"] = _deciding_distance(_centre(0, (0.0, 1.0)), range(4), landing_dots, side)
    # from the decision's sub-cell: neighbour d's sub-cell next to our sub-cell d (where a move
    # out towards d lands)
    d |= {f"landing {k}": _deciding_distance(_centre(k, DIRECTIONS[k]), range(4), landing_dots, side) for k in range(4)}
    return {k: v * side for k, v in d.items()}


def distance_m(kind: str, subcell_m: float, margin_m: float) -> float:
    """The distance (m) of a claim of ``kind`` ("box 2", "start mark 1", "cell ahead",
    "landing ahead") on sub-cells of ``subcell_m``, the robot's position margin included."""
    return _distances(float(subcell_m))[kind] + margin_m


def decision_claims(obs, *, fresh: bool, at_start: bool, subcell_m: float, margin_m: float) -> list[Claim]:
    """What a decision from ``obs`` (a :class:`stcvision.controllers.stc.fsm.StcObservation`) takes for
    absent: every unlit box (which sub-cells are visited, so the parent), and no start mark in
    sub-cells 1-3 (this is not the start cell). A cell entered as a child the look found
    unmarked (``fresh``) holds no mark: that look ruled them out. The neighbours' marks are
    looked at again before entering one (:func:`ahead_claims`), and the landing sub-cell before
    a return to the parent (:func:`landing_claims`), each from where it is nearest."""
    if fresh:
        return []
    out = [
        Claim(f"box {b} unlit", distance_m(f"box {b}", subcell_m, margin_m))
        for b, lit in enumerate(obs.boxes, 1)
        if not lit
    ]
    if obs.start_mark is None and not at_start:
        out += [
            Claim(f"no start mark in sub-cell {m}", distance_m(f"start mark {m}", subcell_m, margin_m))
            for m in (1, 2, 3)
        ]
    return out


def return_misread(obs) -> str | None:
    """Why ``obs`` (a :class:`stcvision.controllers.stc.fsm.StcObservation` at a decision after a return
    from a child: not the first one, not in a cell just entered as a child) cannot be right, or
    None: the lit boxes of a cell re-entered are one of :data:`stcvision.controllers.stc.fsm.REENTRY_BOXES`
    (box 4 always). A cross-check of the reading against the tour, not against the frames'
    reach: it catches a mark missed *within* the horizon (a pipeline miss), which no claim can."""
    from stcvision.controllers.stc.fsm import REENTRY_BOXES

    def name(boxes) -> str:
        return "{" + ",".join(map(str, boxes)) + "}"

    lit = tuple(b for b, on in enumerate(obs.boxes, 1) if on)
    if lit in REENTRY_BOXES:
        return None
    sets = ", ".join(name(b) for b in sorted(REENTRY_BOXES, key=lambda b: (len(b), b)))
    return f"misread: boxes {name(lit)} lit in a cell re-entered from a child, which shows one of {sets}"


def landing_claim(direction: int, *, subcell_m: float, margin_m: float) -> Claim:
    """At a decision: no mark in the sub-cell a move out towards ``direction`` lands on (the
    return to the parent does not close the tour). Not asked for (no frame is taken for it):
    when the decision's frames happen to cover it, the look before the return is not needed."""
    what = f"no mark in the sub-cell beyond exit {direction}"
    return Claim(what, distance_m(f"landing {direction}", subcell_m, margin_m))


def ahead_claims(marked: bool, *, subcell_m: float, margin_m: float) -> list[Claim]:
    """A look at a child: unmarked means no mark anywhere in the cell ahead (a visited cell may
    hold marks in its farthest sub-cell only)."""
    return [] if marked else [Claim("no mark in the cell ahead", distance_m("cell ahead", subcell_m, margin_m))]


def landing_claims(marked: bool, *, subcell_m: float, margin_m: float) -> list[Claim]:
    """A look before a return to the parent: unmarked means the sub-cell the robot lands on is
    not the start sub-cell (the tour does not close there)."""
    return [] if marked else [Claim("no mark in the sub-cell ahead", distance_m("landing ahead", subcell_m, margin_m))]


def read_until_sure(cam, t_s: float, read, merge, claims, *, strict: bool = True):
    """Frames until every claim of the reading is covered: ``read(k, t) -> (reading, seconds)``
    takes a frame at rung ``k`` of ``cam`` (:class:`stcvision.controllers.stc.frames.Exposures`) at clock
    ``t``; ``merge(a, b)`` is what two frames show together; ``claims(reading)`` what it takes for
    absent. The short frame (rung 0) first; then, while a claim is open (no frame taken so far
    sees marks as old as the clock was at that frame, at the claim's distance), the shortest
    rung that covers the farthest open claim. Returns (reading, seconds, the (rung, clock) of
    each frame taken); raises
    :class:`OutOfSight` when no rung covers it (``strict``; else the longest rung is taken, once,
    and the reading kept as it is)."""
    reading, dt = read(0, t_s)
    taken = [(0, t_s)]
    while True:
        open_ = [c for c in claims(reading) if all(cam.horizon(k, c.rho_m) < tk for k, tk in taken)]
        if not open_:
            return reading, dt, taken
        c = max(open_, key=lambda c: c.rho_m)
        now = t_s + dt
        k = cam.rung_for(now, c.rho_m)
        last = len(cam.ladder) - 1
        if not strict and k is None and last not in [j for j, _ in taken]:
            k = last
        if k is None or k in [j for j, _ in taken]:
            if not strict:
                return reading, dt, taken
            longest = cam.horizon(last, c.rho_m)
            raise OutOfSight(
                f"out of sight: {c.what} ({c.rho_m:.2f} m away) must hold for marks up to {now:.0f} s old; "
                f"the longest frame sees {longest:.0f} s there"
            )
        more, dk = read(k, now)
        reading, dt = merge(reading, more), dt + dk
        taken.append((k, now))
