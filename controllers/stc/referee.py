"""The referee: at every decision of a camera (or physics-limited camera) run, what the oracle
would have decided in the same state, from the floor's record; a decision is an error when the
robot commits to something else. Also counts the looks that read the cell ahead wrongly and
the oldest mark a decision had to read. It watches; it never changes what the robot does."""

from __future__ import annotations

import math
from collections.abc import Callable

from stcvision.controllers.stc.belief import Belief
from stcvision.controllers.stc.fsm import Action, Decision, StcObservation, StcPhase, StcState, decide
from stcvision.controllers.stc.grid import cell_of, step_from
from stcvision.controllers.stc.oracle import landing_oracle, look_oracle, observe_oracle
from stcvision.controllers.stc.plant import Floor, Plant

__all__ = ["Referee"]


class Referee:
    """``active``: compare with the oracle (a run on the oracle's own observations is not).
    ``report(kind, text)`` hears of every misread, decision error and look error."""

    def __init__(self, board, *, active: bool, report: Callable[[str, str], None] = lambda kind, text: None):
        self.board = board
        self.active = active
        self.report = report
        self.decision_errors = 0
        self.look_errors = 0
        self.max_age_read = 0.0
        self.first_error: dict | None = None
        self._expected: tuple | None = None  # what the oracle decided at this cell's decision
        self._decided = None  # what the robot decided there (its Decision)
        self._at: dict = {}

    def decision(
        self, plant: Plant, belief: Belief, floor: Floor, obs: StcObservation, state: StcState, k: int, dc: Decision
    ) -> None:
        """The robot decided ``dc`` from ``obs`` at its ``k``-th decision (in state ``state``)."""
        self.max_age_read = max(self.max_age_read, floor.oldest_near(belief.sub, plant.t))
        if not self.active:
            return
        o_obs = observe_oracle(floor.record, self.board, belief.sub, belief.hc, camera_view=True)
        od = decide(o_obs, at_start=state.at_start)
        self._decided = dc
        if (dc.visited, dc.parent, dc.is_start, dc.done) != (od.visited, od.parent, od.is_start, od.done):
            # what the cell says of itself (visited sub-cells, parent, start, end) was misread:
            # no look can mend that
            self._expected = ("misread",)
            self.report("misread", f"misread at {belief.sub}: camera {obs}, oracle {o_obs}, fresh {state.fresh}")
        elif od.done:
            self._expected = ("done",)
        elif od.final:
            self._expected = ("stop", od.target, od.parent)
        else:
            self._expected = ("leave", od.target, od.parent, od.child is None and o_obs.landing_marked[od.target])
        self._at = {"decision": k, "subcell": belief.sub, "camera": obs, "oracle": o_obs}

    def look(self, plant: Plant, belief: Belief, floor: Floor, marked: bool, *, landing: bool = False) -> None:
        """A look read ``marked`` (``landing``: the sub-cell ahead, else the cell ahead)."""
        truth = (landing_oracle if landing else look_oracle)(floor.record, belief.sub, belief.hc).marked
        if not self.active or marked == truth:
            return
        self.look_errors += 1
        ahead = cell_of(step_from(belief.sub, belief.hc))
        seen = [
            (s, e, round(plant.t - t), round(math.dist(self.board.subcell_center_m(*s), (plant.x, plant.y)), 2))
            for (s, e), t in floor.laid_at.items()
            if cell_of(s) == ahead
        ]
        self.report(
            "look error",
            f"{'landing ' if landing else ''}look error at {belief.sub} heading {belief.hc}: camera {marked}, "
            f"t={plant.t:.0f}, marks ahead {seen}",
        )

    def step(self, prev: StcState, state: StcState, action: Action, plant: Plant, belief: Belief, k: int) -> None:
        """The controller went from ``prev`` to ``state`` with ``action``: a decision is
        committed when the robot leaves its cell or stops (the looks before entering a child may
        revise a first reading, as they are meant to)."""
        if action is Action.DONE and prev.phase is StcPhase.DECIDE and not prev.closing:
            # straight from the decision: the tour's end, or a final stop whose target is the
            # sub-cell the robot already stands in (then the stop is scored as a stop, from the
            # robot's own decision: the state after it no longer holds the parent)
            dc = self._decided
            final = dc is not None and dc.final and not dc.done
            self._commit(("stop", dc.target, dc.parent) if final else ("done",), plant, belief, k)
        elif action is Action.DONE and prev.phase is not StcPhase.DECIDE:
            self._commit(("stop", prev.target, prev.parent), plant, belief, k)
        elif action is Action.FORWARD and state.phase is StcPhase.DECIDE:
            self._commit(("leave", prev.target, prev.parent, state.closing), plant, belief, k)

    def _commit(self, outcome: tuple, plant: Plant, belief: Belief, k: int) -> None:
        expected, self._expected = self._expected, None
        if expected is None or expected == outcome:
            return
        self.decision_errors += 1
        self.report("decision error", f"decision error at {belief.sub}: the oracle would {expected}, did {outcome}")
        if self.first_error is None:
            at = self._at
            self.first_error = {
                "decision": k,
                "t_s": round(plant.t, 1),
                "subcell": list(at["subcell"]),
                "position_error_m": round(math.hypot(*plant.true_offset(belief.sub)), 4),
                "heading_error_deg": round(math.degrees(plant.heading_error(belief.hc)), 2),
                **_compare(at["camera"], at["oracle"]),
            }


def _compare(cam: StcObservation, ora: StcObservation) -> dict:
    return {
        "camera_boxes": list(cam.boxes),
        "oracle_boxes": list(ora.boxes),
        "camera_neighbours": [[n.has_marks, n.has_red] for n in cam.neighbours],
        "oracle_neighbours": [[n.has_marks, n.has_red] for n in ora.neighbours],
        "camera_landing": list(cam.landing_marked),
        "oracle_landing": list(ora.landing_marked),
        "camera_start_mark": cam.start_mark,
        "oracle_start_mark": ora.start_mark,
    }
