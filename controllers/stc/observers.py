"""Observers of a coverage run: they are told what happened (a reading, a controller step, a
turn's measurement, the referee's findings, the end) and never change it. The rerun recording
(:class:`stcvision.controllers.stc.recorder.CoverRecorder`), a text trace (:class:`Trace`), a top view of
the floor (:class:`FloorPicture`, :func:`draw_floor`), the true and believed paths and the JSON
trace (:mod:`stcvision.controllers.stc.paths`) are observers.

Events hand over the live plant (the physical robot), the robot's belief and the floor: an
observer reads them at once and keeps copies of whatever it wants to keep.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import TextIO

import numpy as np

__all__ = ["FloorPicture", "Observer", "Observers", "Reading", "Trace", "draw_floor"]


@dataclass(frozen=True, slots=True)
class Reading:
    """A decision (``kind`` "decision": ``obs`` and the ``decision`` taken from it) or a look
    (``kind`` "look": ``marked``); ``frame`` is (pipeline result, pipeline) when a rendered
    frame was read."""

    kind: str
    k: int  # decisions so far
    plant: object
    belief: object
    floor: object
    obs: object = None
    decision: object = None
    marked: bool | None = None
    frame: tuple | None = None


class Observer:
    """No-op hooks; subclass and override what you watch."""

    def on_reading(self, ev: Reading) -> None: ...

    def on_step(self, plant, belief, state, action) -> None: ...

    def on_turn(self, plant, belief, measured_rad: float | None) -> None: ...

    def on_move(self, plant, belief) -> None: ...

    def on_referee(self, kind: str, text: str) -> None: ...

    def on_end(self, plant, floor) -> None: ...


class Observers(Observer):
    """Fans every event out to a list of observers, in order."""

    def __init__(self, observers=()):
        self.all = [o for o in observers if o is not None]

    def on_reading(self, ev):
        for o in self.all:
            o.on_reading(ev)

    def on_step(self, plant, belief, state, action):
        for o in self.all:
            o.on_step(plant, belief, state, action)

    def on_turn(self, plant, belief, measured_rad):
        for o in self.all:
            o.on_turn(plant, belief, measured_rad)

    def on_move(self, plant, belief):
        for o in self.all:
            o.on_move(plant, belief)

    def on_referee(self, kind, text):
        for o in self.all:
            o.on_referee(kind, text)

    def on_end(self, plant, floor):
        for o in self.all:
            o.on_end(plant, floor)


class Trace(Observer):
    """One line per controller step, per turn measurement and per referee finding."""

    def __init__(self, out: TextIO | None = None):
        self.out = out or sys.stdout

    def on_step(self, plant, belief, state, action):
        herr = math.degrees(plant.heading_error(belief.hc))
        print(
            f"t={plant.t:7.1f} {action.name:10s} sub={belief.sub} hc={belief.hc} {state.phase.name} "
            f"tgt={state.target} par={state.parent} free={state.free:04b} "
            f"herr={herr:+.2f} pos={100 * math.hypot(*plant.true_offset(belief.sub)):.2f}cm "
            f"est={100 * math.hypot(*belief.offset_m):.2f}cm",
            file=self.out,
        )

    def on_turn(self, plant, belief, measured_rad):
        if measured_rad is not None:
            print(
                f"   turn: heading error {math.degrees(plant.heading_error(belief.hc)):+.3f}, "
                f"measured {math.degrees(measured_rad):+.3f}",
                file=self.out,
            )

    def on_referee(self, kind, text):
        print(text, file=self.out)


class FloorPicture(Observer):
    """Keeps :func:`draw_floor` of the floor as the run left it (``image``)."""

    def __init__(self, board):
        self.board = board
        self.image: np.ndarray | None = None

    def on_end(self, plant, floor):
        self.image = draw_floor(self.board, floor.phosphor, plant.visits, plant.pose, plant.t)


def draw_floor(board, phosphor, visits, pose, t_s: float, *, px_per_m: float = 400.0) -> np.ndarray:
    """Top view (north up, BGR uint8) of a run: free and obstacle cells, red lights, covered
    sub-cells, every UV dot drawn with its current luminance, and the robot."""
    import cv2

    w, h = board.size_m
    m = 20
    W, H = int(w * px_per_m) + 2 * m, int(h * px_per_m) + 2 * m
    img = np.full((H, W, 3), 255, np.uint8)

    def px(xy):
        return int(round(m + xy[0] * px_per_m)), int(round(m + (h - xy[1]) * px_per_m))

    D = board.subcell_m
    rows, cols = board.shape_subcells
    for i in range(rows):
        for j in range(cols):
            c = board.subcell_center_m(i, j)
            a, b = px(c - D / 2), px(c + D / 2)
            if not board.cell_free[i // 2, j // 2]:
                cv2.rectangle(img, (a[0], b[1]), (b[0], a[1]), (90, 90, 90), -1)
            elif visits[i, j]:
                cv2.rectangle(img, (a[0], b[1]), (b[0], a[1]), (215, 240, 215), -1)
    for k in range(0, cols + 1, 2):
        cv2.line(img, px((k * D, 0)), px((k * D, h)), (150, 150, 150), 1)
    for k in range(0, rows + 1, 2):
        cv2.line(img, px((0, k * D)), px((w, k * D)), (150, 150, 150), 1)
    for xy in board.red_lights_m():
        if 0 <= xy[0] <= w and 0 <= xy[1] <= h:
            cv2.circle(img, px(xy), 5, (0, 0, 230), -1)
    if len(phosphor):
        lum = phosphor.luminance_at(t_s)
        g = np.sqrt(np.clip(lum / phosphor.law.initial_cd_m2(3.0), 0, 1))
        for xy, v in zip(phosphor.xy_m, g, strict=True):
            cv2.circle(img, px(xy), 2, (int(60 * (1 - v)), int(100 + 155 * v), int(60 * (1 - v))), -1)
    x, y, hd = pose
    cv2.circle(img, px((x, y)), int(0.065 * px_per_m), (200, 90, 40), 2)
    cv2.line(img, px((x, y)), px((x + 0.08 * math.cos(hd), y + 0.08 * math.sin(hd))), (200, 90, 40), 2)
    return img
