"""Scenes: a JSON description of what the synthetic camera looks at.

A scene names a board, the robot's pose, marks (rows of four UV dots) with their ages, single
dots, red lights, and overrides of the camera, sensor and afterglow parameters. It is what
``stcvision render --scene`` reads and what dataset recipes generate. See :data:`EXAMPLE_SCENE`
(printed by ``stcvision render --example-scene``).
"""

from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stcvision.errors import BadInputError
from stcvision.sim_camera.board import DEFAULT_SUBCELL_M, Board
from stcvision.sim_camera.camera import Pose, SyntheticCamera
from stcvision.sim_camera.image_sensor import SensorParams
from stcvision.sim_camera.optics import MirrorCameraParams
from stcvision.sim_camera.phosphor import AfterglowLaw, PhosphorLayer, mark_dots_m

__all__ = ["EDGES", "EXAMPLE_SCENE", "Scene"]

#: Edge names (world directions) -> unit vector from a sub-cell's centre towards that edge.
EDGES = {"N": (0.0, 1.0), "E": (1.0, 0.0), "S": (0.0, -1.0), "W": (-1.0, 0.0)}

EXAMPLE_SCENE = {
    "_doc": (
        "stcvision scene. board: one of text (rows of '.', '#', 'S'; one char per sub-cell), "
        "file (a .txt or .png map), random ({cells, obstacle_fraction, seed}). robot: subcell "
        "[row, col] + heading_deg (0 = east, 90 = north) + optional offset_m [dx, dy] and "
        "heading_error_deg, or x_m/y_m/heading_deg. marks: a row of 4 UV dots inside a sub-cell "
        "along one edge (N/E/S/W), age_s seconds after its charge_s-second charge ended. dots: "
        "single dots at x_m/y_m. red_lights: 'board' (obstacle cells + border ring), a list of "
        "[x_m, y_m], or false. camera/sensor/afterglow: overrides of "
        "stcvision.sim_camera.optics.MirrorCameraParams, stcvision.sim_camera.image_sensor.SensorParams, "
        "stcvision.sim_camera.phosphor.AfterglowLaw. pattern_seed: the camera's fixed-pattern noise."
    ),
    "board": {
        "text": [
            "..........",
            "..........",
            "....##....",
            "....##....",
            "..........",
            "..........",
            "..........",
            ".......S..",
            "..........",
            "..........",
        ]
    },
    "subcell_m": DEFAULT_SUBCELL_M,
    "robot": {"subcell": [7, 7], "heading_deg": 90, "heading_error_deg": 3.0},
    "marks": [
        {"subcell": [8, 7], "edge": "S", "age_s": 2.0, "charge_s": 3.0},
        {"subcell": [6, 7], "edge": "S", "age_s": 20.0},
        {"subcell": [6, 6], "edge": "E", "age_s": 40.0},
        {"subcell": [5, 6], "edge": "S", "age_s": 55.0},
    ],
    "dots": [],
    "red_lights": "board",
    "camera": {"mirror_decentre_m": [0.0005, -0.0003]},
    "sensor": {"exposure_s": 0.0333},
    "afterglow": {},
    "pattern_seed": 0,
}

_KEYS = {
    "_doc",
    "board",
    "subcell_m",
    "robot",
    "marks",
    "dots",
    "red_lights",
    "camera",
    "sensor",
    "afterglow",
    "pattern_seed",
    "time_s",
}


def _num(d: dict, key: str, where: str, default=None) -> float:
    if not isinstance(d, dict):
        raise BadInputError(f"{where} must be an object, got {d!r}")
    v = d.get(key, default)
    if v is None:
        raise BadInputError(f"{where}: missing {key!r}")
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise BadInputError(f"{where}: {key!r} must be a finite number, got {v!r}")
    return float(v)


def _pair(v, where: str, kind=float) -> tuple:
    if (
        not isinstance(v, list | tuple)
        or len(v) != 2
        or not all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in v)
    ):
        raise BadInputError(f"{where} must be a list of 2 finite numbers, got {v!r}")
    if kind is int and not all(float(x).is_integer() for x in v):
        raise BadInputError(f"{where} must be a list of 2 integers, got {v!r}")
    return tuple(kind(x) for x in v)


def _list(d: dict, key: str) -> list:
    v = d.get(key, [])
    if not isinstance(v, list):
        raise BadInputError(f"scene {key} must be a list, got {v!r}")
    return v


@dataclass(frozen=True, eq=False)
class Scene:
    """A parsed scene: everything needed to render one frame."""

    board: Board
    pose: Pose
    phosphor: PhosphorLayer
    red_lights_m: np.ndarray
    optics: MirrorCameraParams
    sensor: SensorParams
    pattern_seed: int
    t_s: float = 0.0

    def camera(self) -> SyntheticCamera:
        return SyntheticCamera(self.optics, self.sensor, pattern_seed=self.pattern_seed)

    @classmethod
    def from_file(cls, path: str | Path, *, sensor_base: SensorParams | None = None) -> Scene:
        from stcvision.fileio import read_json

        return cls.from_dict(read_json(path, what="scene"), base_dir=Path(path).parent, sensor_base=sensor_base)

    @classmethod
    def from_dict(cls, d: dict, *, base_dir: Path | None = None, sensor_base: SensorParams | None = None) -> Scene:
        """``sensor_base``: the sensor the scene's ``sensor`` overrides apply to (a camera
        profile's, :mod:`stcvision.sim_camera.hardware`); default the webcam's."""
        if not isinstance(d, dict):
            raise BadInputError("scene must be a JSON object")
        unknown = set(d) - _KEYS
        if unknown:
            raise BadInputError(f"scene has unknown key(s) {sorted(unknown)}; expected some of {sorted(_KEYS)}")
        D = _num(d, "subcell_m", "scene", DEFAULT_SUBCELL_M)
        board = _board(d.get("board"), D, base_dir)
        pose = _pose(d.get("robot"), board)
        t_s = _num(d, "time_s", "scene", 0.0)
        law = _afterglow(d.get("afterglow", {}))
        layer = PhosphorLayer(law)
        from stcvision.limits import MAX_MARKS_PER_SUBCELL, MAX_SCENE_DOTS, check_count

        rows, cols = board.shape_subcells
        cap = MAX_MARKS_PER_SUBCELL * rows * cols
        why = f"4 per sub-cell of the {rows}x{cols} board"
        check_count("scene marks", len(_list(d, "marks")), cap, minimum=0, why=why)
        check_count("scene dots", len(_list(d, "dots")), MAX_SCENE_DOTS, minimum=0)
        for k, m in enumerate(_list(d, "marks")):
            where = f"scene marks[{k}]"
            if not isinstance(m, dict):
                raise BadInputError(f"{where} must be an object")
            ij = _subcell(m.get("subcell"), f"{where}.subcell", board)
            edge = m.get("edge")
            if not isinstance(edge, str) or edge not in EDGES:
                raise BadInputError(f"{where}.edge is {edge!r}; expected one of N, E, S, W")
            age, charge = _age_charge(m, where)
            xy = mark_dots_m(board.subcell_center_m(*ij), EDGES[edge], board.subcell_m)
            layer.charge(xy, t_start_s=t_s - age - charge, duration_s=charge)
        for k, dot in enumerate(_list(d, "dots")):
            where = f"scene dots[{k}]"
            xy = _on_board(_num(dot, "x_m", where), _num(dot, "y_m", where), where, board)
            age, charge = _age_charge(dot, where)
            layer.charge([xy], t_start_s=t_s - age - charge, duration_s=charge)
        rl = d.get("red_lights", "board")
        if rl == "board":
            lights = board.red_lights_m()
        elif rl is False or rl is None:
            lights = np.zeros((0, 2))
        elif isinstance(rl, list):
            lights = np.array([_pair(p, f"scene red_lights[{k}]") for k, p in enumerate(rl)]).reshape(-1, 2)
        else:
            raise BadInputError(f"scene red_lights is {rl!r}; expected 'board', false or a list of [x_m, y_m]")
        optics = MirrorCameraParams.from_dict(_overrides(d.get("camera", {}), "camera"))
        base = {} if sensor_base is None else sensor_base.to_dict()
        sensor = SensorParams.from_dict({**base, **_overrides(d.get("sensor", {}), "sensor")})
        seed = d.get("pattern_seed", 0)
        if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
            raise BadInputError(f"scene pattern_seed must be a non-negative integer, got {seed!r}")
        return cls(board, pose, layer, lights, optics, sensor, seed, t_s)


def _subcell(v, where: str, board: Board) -> tuple[int, int]:
    """A sub-cell ``[row, col]`` of ``board``; one off the board is refused (it would be drawn
    metres away from the floor, out of every view, and the frame would look merely empty)."""
    i, j = _pair(v, where, int)
    rows, cols = board.shape_subcells
    if not (0 <= i < rows and 0 <= j < cols):
        raise BadInputError(
            f"{where} [{i}, {j}] is outside the board of {rows}x{cols} sub-cells "
            f"(rows 0..{rows - 1}, columns 0..{cols - 1})"
        )
    return i, j


def _on_board(x: float, y: float, where: str, board: Board) -> list[float]:
    """A floor point ``(x, y)`` in metres, refused unless it lies on ``board``."""
    w, h = board.size_m
    if not (0.0 <= x <= w and 0.0 <= y <= h):
        raise BadInputError(f"{where} at ({x:g}, {y:g}) m is outside the board, which spans 0..{w:g} x 0..{h:g} m")
    return [x, y]


def _age_charge(d: dict, where: str) -> tuple[float, float]:
    """A mark's ``age_s`` (>= 0: a mark whose charge ends in the future does not glow yet) and
    ``charge_s`` (> 0), as the recipes require."""
    age, charge = _num(d, "age_s", where), _num(d, "charge_s", where, 3.0)
    if age < 0:
        raise BadInputError(f"{where}: age_s must be >= 0 seconds since the charge ended, got {age:g}")
    if charge <= 0:
        raise BadInputError(f"{where}: charge_s must be > 0 seconds, got {charge:g}")
    return age, charge


def _overrides(v, name: str) -> dict:
    if not isinstance(v, dict):
        raise BadInputError(f"scene {name} must be an object of parameter overrides, got {v!r}")
    return copy.deepcopy(v)


def _afterglow(v) -> AfterglowLaw:
    """The afterglow law with the scene's overrides (unknown or non-numeric ones refused: found
    by fuzzing, they were a TypeError)."""
    d = _overrides(v, "afterglow")
    names = {f.name for f in dataclasses.fields(AfterglowLaw)}
    unknown = set(d) - names
    if unknown:
        raise BadInputError(f"scene afterglow has unknown key(s) {sorted(unknown)}; expected some of {sorted(names)}")
    return AfterglowLaw(**{k: _num(d, k, "scene afterglow") for k in d})


def _board(b, D: float, base_dir: Path | None) -> Board:
    if not isinstance(b, dict) or len(b) != 1:
        raise BadInputError("scene board must be an object with exactly one of: text, file, random")
    ((kind, v),) = b.items()
    if kind == "text":
        if isinstance(v, list) and all(isinstance(row, str) for row in v):
            v = "\n".join(v)
        if not isinstance(v, str):
            raise BadInputError("scene board.text must be a list of strings")
        text = v
        return Board.from_text(text, subcell_m=D, source="scene board.text")
    if kind == "file":
        if not isinstance(v, str) or not v:
            raise BadInputError(f"scene board.file must be the path of a .txt or .png map, got {v!r}")
        path = Path(v)
        if base_dir is not None and not path.is_absolute():
            path = base_dir / path
        return Board.from_file(path, subcell_m=D)
    if kind == "random":
        if not isinstance(v, dict):
            raise BadInputError("scene board.random must be an object {cells, obstacle_fraction, seed}")
        cells = _pair(v.get("cells"), "scene board.random.cells", int)
        frac = _num(v, "obstacle_fraction", "scene board.random", 0.1)
        seed = _num(v, "seed", "scene board.random", 0)
        if seed < 0 or not seed.is_integer():
            raise BadInputError(f"scene board.random seed must be a non-negative integer, got {v.get('seed')!r}")
        seed = int(seed)
        return Board.random(cells, obstacle_fraction=frac, rng=np.random.default_rng(seed), subcell_m=D)
    raise BadInputError(f"scene board kind {kind!r} unknown; expected text, file or random")


def _pose(r, board: Board) -> Pose:
    if r is None:
        i, j = board.start_subcell
        c = board.subcell_center_m(i, j)
        return Pose(float(c[0]), float(c[1]), np.pi / 2)
    if not isinstance(r, dict):
        raise BadInputError("scene robot must be an object")
    heading = np.radians(_num(r, "heading_deg", "scene robot", 90.0) + _num(r, "heading_error_deg", "scene robot", 0.0))
    if "subcell" in r:
        ij = _subcell(r["subcell"], "scene robot.subcell", board)
        c = board.subcell_center_m(*ij) + np.asarray(_pair(r.get("offset_m", [0, 0]), "scene robot.offset_m"))
        x, y = _on_board(float(c[0]), float(c[1]), "scene robot (subcell + offset_m)", board)
        return Pose(x, y, float(heading))
    x, y = _on_board(_num(r, "x_m", "scene robot"), _num(r, "y_m", "scene robot"), "scene robot", board)
    return Pose(x, y, float(heading))
