"""A coverage run's paths and readings as files.

The true and believed paths in the TUM trajectory format (what ``evo`` reads,
:class:`PathLog`) and one JSON line per decision and per look (:class:`JsonTrace`).

Both are observers (:class:`stcvision.controllers.stc.observers.Observer`): they read the plant
and the belief as the loop tells them of a reading or a move and keep copies; the controller
never sees them. Each is held in memory and written in one piece when the run ends
(:meth:`PathLog.tum` through :func:`stcvision.tum.write_tum_files`, :func:`write_trace`): an
interrupted run leaves no half-written file.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from stcvision.controllers.stc.observers import Observer, Reading
from stcvision.stc_geometry import compass_to_rad
from stcvision.tum import tum_files

__all__ = [
    "TRACE_SCHEMA_VERSION",
    "JsonTrace",
    "PathLog",
    "write_trace",
]

#: the trace's schema version (every line carries it): raised when a field changes meaning
TRACE_SCHEMA_VERSION = 1


class PathLog(Observer):
    """The robot's true and believed poses at its start and after every forward move.

    After a move is where the run's position error is defined (``max_position_error_m`` of
    :func:`stcvision.controllers.stc.loop.run_cover`: the true position's distance from the
    centre of the sub-cell the robot believes it reached, where it believes it stands), so the
    largest distance between the two paths' positions is that figure. A push or a slip fault
    moves the robot after the move's own check: the pose before it is not in the paths, and
    their largest distance may then fall short of the figure.

    Parameters
    ----------
    board : Board
        The run's board (the believed position is its sub-cell's centre plus the offset).

    Attributes
    ----------
    true : list of tuple
        (t_s, x_m, y_m, heading_rad) from the plant.
    believed : list of tuple
        (t_s, x_m, y_m, heading_rad) from the belief: its sub-cell's centre plus the offset it
        believes, its compass heading.
    """

    def __init__(self, board) -> None:
        self.board = board
        self.true: list[tuple[float, float, float, float]] = []
        self.believed: list[tuple[float, float, float, float]] = []
        self._moves = -1  # the plant's move count at the last pose kept

    def _keep(self, plant, belief, t_s: float) -> None:
        if plant.moves == self._moves:  # a move refused (blocked) left the robot where it was
            return
        self._moves = plant.moves
        self.true.append((t_s, plant.x, plant.y, plant.heading_rad))
        c = np.asarray(self.board.subcell_center_m(*belief.sub), float) + belief.offset_m
        self.believed.append((t_s, float(c[0]), float(c[1]), compass_to_rad(belief.hc)))

    def on_reading(self, ev: Reading) -> None:
        """Keep the start pose at the first reading.

        Parameters
        ----------
        ev : Reading
            A decision or a look.
        """
        # nothing moves the robot before its first decision: its start pose, at the clock's zero
        if not self.true:
            self._keep(ev.plant, _AtStart(ev.belief), 0.0)

    def on_move(self, plant, belief) -> None:
        """Keep the poses after a forward move.

        Parameters
        ----------
        plant : Plant
            The physical robot: the true pose.
        belief : Belief
            What the robot believes: the believed pose.
        """
        self._keep(plant, belief, plant.t)

    def tum(self) -> dict[str, str]:
        """Return the two TUM files' text.

        Returns
        -------
        dict of str to str
            By file name (:data:`stcvision.tum.TUM_FILES`): the true path's, then the believed path's.
        """
        return tum_files(self.true, self.believed)


@dataclasses.dataclass(frozen=True)
class _AtStart:
    """The belief at the start, before any reading set an offset: on its sub-cell's centre."""

    belief: object

    @property
    def sub(self):
        return self.belief.sub

    @property
    def hc(self):
        return self.belief.hc

    @property
    def offset_m(self):
        return np.zeros(2)


def _plain(obj):
    """Return a dataclass, tuple or numpy value as JSON's plain types."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: _plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, (tuple, list, np.ndarray)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float):
        return round(obj, 6)
    return obj


class JsonTrace(Observer):
    """One JSON object per decision and per look, in the order the robot made them.

    The schema is the reference page's (``docs/reference/cover-trace.md``). The referee's
    verdict on a decision can come after the looks that follow it (a decision is judged when the
    robot leaves its cell), so the lines are kept until the run ends. Their number is bounded by
    the run's own cap (``CoverConfig.max_decisions``, each decision followed by a few looks).

    Parameters
    ----------
    board : Board
        The run's board (the believed position is its sub-cell's centre plus the offset).
    """

    def __init__(self, board) -> None:
        self.board = board
        self.lines: list[dict] = []
        self.refereed: bool | None = None  # unknown until the perception is attached
        self._cam = None  # the perception's frames (per rung), when it takes any
        self._seen: list[int] = []
        self._look_findings: list[dict] = []  # the referee's finding on a look comes before its reading
        self._last_decision: dict | None = None

    def attach(self, perception) -> None:
        """Read a perception's frames and whether the referee judges it.

        Parameters
        ----------
        perception : Perception
            The run's perception (``run_cover``'s ``perception_hook`` hands it over).
        """
        self.refereed = bool(getattr(perception, "refereed", False))
        self._cam = getattr(perception, "cam", None)
        self._seen = self._counts()

    def _counts(self) -> list[int]:
        return list(getattr(self._cam, "per_rung", []))

    def _frames(self) -> list[dict] | None:
        """Return the frames taken since the last reading or turn, by rung (None: no camera)."""
        if self._cam is None or not hasattr(self._cam, "ladder"):
            return None
        now = self._counts()
        used = []
        for k, (n_now, n_then) in enumerate(zip(now, self._seen, strict=True)):
            if n_now > n_then:
                e, g, n = self._cam.ladder[k]
                used.append(
                    {
                        "rung": k,
                        "label": self._cam.frame_label(k),
                        "exposure_s": round(e, 6),
                        "gain": round(float(g), 6),
                        "stacked": self._cam.stack(k),
                        "count": n_now - n_then,
                    }
                )
        self._seen = now
        return used

    def on_turn(self, plant, belief, measured_rad) -> None:
        """Leave a turn's frames out of the next reading's."""
        self._frames()  # a turn's frames measure the heading, not the next reading

    def on_reading(self, ev: Reading) -> None:
        """Keep one line for a decision or a look."""
        p, b = ev.plant, ev.belief
        centre = np.asarray(self.board.subcell_center_m(*b.sub), float)
        line = {
            "schema": TRACE_SCHEMA_VERSION,
            "kind": ev.kind,
            "decision": ev.k,
            "t_s": round(p.t, 6),
            "true_pose": {
                "x_m": round(p.x, 6),
                "y_m": round(p.y, 6),
                "heading_deg": round(math.degrees(p.heading_rad), 4),
            },
            "believed_pose": {
                "subcell": list(b.sub),
                "compass": b.hc,
                "x_m": round(float(centre[0] + b.offset_m[0]), 6),
                "y_m": round(float(centre[1] + b.offset_m[1]), 6),
                "heading_deg": round(math.degrees(compass_to_rad(b.hc)), 4),
            },
            "position_error_m": round(math.hypot(*(p.true_offset(b.sub) - b.offset_m)), 6),
            "frames": self._frames(),
        }
        if ev.kind == "decision":
            line["observation"] = _plain(ev.obs)
            line["decision_taken"] = _plain(ev.decision)
            findings: list[dict] = []
            self._last_decision = line
        else:
            line["marked"] = bool(ev.marked)
            findings, self._look_findings = self._look_findings, []
        line["verdict"] = None if not self.refereed else {"ok": not findings, "findings": findings}
        self.lines.append(line)

    def on_referee(self, kind: str, text: str) -> None:
        """Put the referee's finding on the line it is about."""
        finding = {"kind": kind, "text": text}
        if kind == "look error":
            self._look_findings.append(finding)
        elif self._last_decision is not None and self._last_decision["verdict"] is not None:
            self._last_decision["verdict"]["ok"] = False
            self._last_decision["verdict"]["findings"].append(finding)

    def jsonl(self) -> str:
        """Return the trace's text.

        Returns
        -------
        str
            One compact JSON object a line, in the order of the readings.
        """
        return "".join(json.dumps(line, allow_nan=False) + "\n" for line in self.lines)


def write_trace(path: str | Path, trace: JsonTrace, *, overwrite: bool = False) -> Path:
    """Write the trace to a file atomically (:func:`stcvision.fileio.write_bytes_atomic`).

    Parameters
    ----------
    path : str or Path
        The JSON-lines file.
    trace : JsonTrace
        The run's trace.
    overwrite : bool
        Replace an existing file; else it is refused.

    Returns
    -------
    Path
        The file written.
    """
    from stcvision.fileio import write_bytes_atomic

    return write_bytes_atomic(path, trace.jsonl().encode(), overwrite=overwrite)
