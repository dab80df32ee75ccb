"""The label of one frame: what a person (or the simulator's ground truth) says a frame shows.

A folder of a robot's real frames is scored against a ``labels.jsonl`` beside them, one JSON
object per line and per frame (the format is documented in docs/how-to/label-real-frames.md)::

    {"frame": "frames/0001.png",
     "boxes": {"1": true, "2": false, "3": null},
     "neighbours": {"right": {"red": true, "marks": false}, "forward": {"red": false}},
     "heading_error_deg": -1.5,
     "dots": [{"uv_px": [312.4, 118.0]}, {"xy_m": [0.21, -0.05], "faint": true}],
     "dark": "dark.png", "profile": "profile.json"}

Every field but ``frame`` may be absent, and what is absent (or ``null``) is not scored: a box
left out is neither right nor wrong. ``boxes`` maps the five boxes of the STC geometry (1-5) to
lit or not; ``neighbours`` maps ``right``, ``forward``, ``left``, ``back`` to their red light
and their marks; ``heading_error_deg`` is how far the robot stands turned from the direction it
entered its cell along (the newest row's direction, counter-clockwise positive), which the
pipeline's line fit measures; ``dots``, when given, lists every dot the frame shows, each by its
image position (``uv_px``) or its floor position in the robot's frame (``xy_m``), and marks
with ``faint`` the ones at the edge of visibility: a faint dot need not be found, and a
detection on it is not a false one. ``dark`` and ``profile`` name this frame's dark frame and
calibration profile, relative to the folder.

:func:`label_from_truth` writes the simulator's ground truth of a rendered frame in this form,
so a generated dataset and its exported labels (``stcvision dataset export-labels``) are scored
by the same function (:func:`stcvision.scoring.score_label`) and give the same numbers.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from stcvision.angles import wrap_angle
from stcvision.errors import BadInputError
from stcvision.limits import MAX_DATASET_FRAMES, MAX_SCENE_DOTS
from stcvision.stc_geometry import BOXES, NEIGHBOURS

__all__ = [
    "LABEL_FIELDS",
    "SNR_AMBIGUOUS",
    "SNR_VISIBLE",
    "MIN_DOTS",
    "label_from_truth",
    "parse_label",
    "read_labels",
]

#: every field a label line may hold (anything else is a typing mistake, refused by name)
LABEL_FIELDS = ("frame", "boxes", "neighbours", "heading_error_deg", "dots", "dark", "profile", "exposure", "note")
#: a truth dot should be found if its expected SNR is at least this (the detection threshold is
#: 5, and the expected SNR assumes a perfectly centred window and a noiseless dark frame)
SNR_VISIBLE = 8.0
#: below :data:`SNR_VISIBLE` and at least this, a dot is at the edge of visibility ("faint"):
#: the faint-row search reads a row of four dots whose SNRs average 3 (sum / 2 >= 6), or,
#: through one found dot, 2.5 for the other three, and noise lets it read some a little fainter
SNR_AMBIGUOUS = 1.5
#: a box or a neighbour counts as marked if this many of its dots should be found (the
#: observation needs that many to call a box lit)
MIN_DOTS = 2


def _bool_or_none(v: Any, what: str) -> bool | None:
    if v is None or isinstance(v, bool):
        return v
    raise BadInputError(f"{what} is {v!r}; expected true, false or null")


def _pair(v: Any, what: str) -> list[float]:
    ok = isinstance(v, list) and len(v) == 2
    ok = ok and all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in v)
    if not ok:
        raise BadInputError(f"{what} is {v!r}; expected two finite numbers [a, b]")
    return [float(v[0]), float(v[1])]


def parse_label(d: Any, *, where: str = "label") -> dict:
    """Check one label line and return it normalised (box keys as ints, absent fields absent).

    Parameters
    ----------
    d : Any
        The decoded JSON of one line.
    where : str
        How a problem names the line (file and line number).

    Returns
    -------
    dict
        ``frame`` and whichever of ``boxes`` ({box: bool or None}), ``neighbours``
        ({direction: {"red": ..., "marks": ...}}), ``heading_error_deg``, ``dots`` (a list of
        ``{"uv_px" | "xy_m", "faint", "age_s"}``), ``dark``, ``profile``, ``exposure`` the
        line gave.

    Raises
    ------
    BadInputError
        One line naming the field and what was expected.
    """
    if not isinstance(d, dict) or not isinstance(d.get("frame"), str) or not d["frame"]:
        raise BadInputError(f'{where} has no "frame" (the frame\'s file, relative to the folder)')
    if {"pose", "sensor"} <= set(d):  # a generated dataset's truth line, its manifest gone
        raise BadInputError(
            f"{where} is a generated dataset's ground truth, but its folder has no manifest.json; expected a "
            "folder made by 'stcvision dataset generate', or hand labels (docs/how-to/label-real-frames.md)"
        )
    unknown = sorted(set(d) - set(LABEL_FIELDS))
    if unknown:
        raise BadInputError(f"{where}: unknown field {unknown[0]!r}; expected some of {', '.join(LABEL_FIELDS)}")
    out: dict = {"frame": d["frame"]}
    if d.get("boxes") is not None:
        if not isinstance(d["boxes"], dict):
            raise BadInputError(f'{where}: "boxes" is not an object; expected {{"1": true, "2": false, ...}}')
        boxes = {}
        for k, v in d["boxes"].items():
            if not (isinstance(k, str) and k.isdigit() and int(k) in BOXES):
                raise BadInputError(f"{where}: box {k!r} is not one of {', '.join(map(str, BOXES))}")
            boxes[int(k)] = _bool_or_none(v, f"{where}: box {k}")
        out["boxes"] = boxes
    if d.get("neighbours") is not None:
        if not isinstance(d["neighbours"], dict):
            raise BadInputError(f'{where}: "neighbours" is not an object; expected {{"right": {{"red": true}}, ...}}')
        nb = {}
        for name, v in d["neighbours"].items():
            if name not in NEIGHBOURS:
                raise BadInputError(f"{where}: neighbour {name!r} is not one of {', '.join(NEIGHBOURS)}")
            if not isinstance(v, dict) or set(v) - {"red", "marks"}:
                raise BadInputError(f'{where}: neighbour {name} is {v!r}; expected {{"red": bool, "marks": bool}}')
            nb[name] = {k: _bool_or_none(v.get(k), f"{where}: neighbour {name} {k}") for k in ("red", "marks")}
        out["neighbours"] = nb
    h = d.get("heading_error_deg")
    if h is not None:
        if not isinstance(h, int | float) or isinstance(h, bool) or not math.isfinite(h) or abs(h) > 180:
            raise BadInputError(f"{where}: heading_error_deg is {h!r}; expected degrees in [-180, 180]")
        out["heading_error_deg"] = float(h)
    if d.get("dots") is not None:
        out["dots"] = _parse_dots(d["dots"], where)
    for key in ("dark", "profile", "exposure"):
        if d.get(key) is not None:
            if not isinstance(d[key], str) or not d[key]:
                raise BadInputError(f"{where}: {key} is {d[key]!r}; expected a file name relative to the folder")
            out[key] = d[key]
    return out


def _parse_dots(dots: Any, where: str) -> list[dict]:
    if not isinstance(dots, list):
        raise BadInputError(f'{where}: "dots" is not a list; expected [{{"uv_px": [u, v]}}, ...]')
    if len(dots) > MAX_SCENE_DOTS:
        raise BadInputError(f"{where}: {len(dots)} dots; at most {MAX_SCENE_DOTS}")
    out = []
    for i, t in enumerate(dots):
        what = f"{where}: dot {i}"
        if not isinstance(t, dict) or not ({"uv_px", "xy_m"} & set(t)) or set(t) - {"uv_px", "xy_m", "faint", "age_s"}:
            raise BadInputError(f'{what} is {t!r}; expected {{"uv_px": [u, v]}} or {{"xy_m": [x, y]}}, and "faint"')
        dot = {k: _pair(t[k], f"{what} {k}") for k in ("uv_px", "xy_m") if t.get(k) is not None}
        if not dot:
            raise BadInputError(f"{what} has neither uv_px nor xy_m")
        dot["faint"] = bool(_bool_or_none(t.get("faint", False), f"{what} faint"))
        if t.get("age_s") is not None:
            if not isinstance(t["age_s"], int | float) or isinstance(t["age_s"], bool) or not t["age_s"] >= 0:
                raise BadInputError(f"{what}: age_s is {t['age_s']!r}; expected seconds >= 0")
            dot["age_s"] = float(t["age_s"])
        out.append(dot)
    return out


def read_labels(path: str | Path) -> list[dict]:
    """Read a ``labels.jsonl`` of hand labels (:func:`parse_label` on each line).

    Parameters
    ----------
    path : str or Path
        The file; blank lines are skipped.

    Returns
    -------
    list of dict
        The labels in file order.

    Raises
    ------
    BadInputError
        A line that is not JSON or not a label, a frame labelled twice, more lines than
        :data:`stcvision.limits.MAX_DATASET_FRAMES`.
    """
    from stcvision.fileio import json_lines

    path = Path(path)
    labels, seen = [], set()
    for i, d in json_lines(path, cap=MAX_DATASET_FRAMES, what="label"):
        lab = parse_label(d, where=f"{path} line {i}")
        if lab["frame"] in seen:
            raise BadInputError(f"{path} line {i} labels {lab['frame']} a second time")
        seen.add(lab["frame"])
        labels.append(lab)
    if not labels:
        raise BadInputError(f"{path} has no labels; expected one JSON object per frame")
    return labels


def _status(snrs: list[float]) -> bool | None:
    """Marked (True), unmarked (False) or at the edge of visibility (None) from the SNRs of a
    region's dots: its :data:`MIN_DOTS`-th brightest decides."""
    s = sorted(snrs, reverse=True)
    m = s[MIN_DOTS - 1] if len(s) >= MIN_DOTS else 0.0
    return None if SNR_AMBIGUOUS <= m < SNR_VISIBLE else m >= SNR_VISIBLE


def label_from_truth(truth: dict) -> dict:
    """The label of a rendered frame, from the simulator's ground truth of it.

    Parameters
    ----------
    truth : dict
        A frame's truth (``stcvision.sim_camera.truth``: its visible dots with their SNR, and,
        when the robot stands in a cell, the cell's boxes and neighbours).

    Returns
    -------
    dict
        A label (:func:`parse_label`'s form): every visible dot (faint below
        :data:`SNR_VISIBLE`), each box and neighbour's marks by :data:`MIN_DOTS` dots' SNR
        (null at the edge of visibility), the neighbours' red lights, and the heading error.
    """
    frame = truth.get("frame", "")
    tdots = [t for t in truth["dots"] if t["visible"] and t["age_s"] >= 0]
    lab: dict = {"frame": frame}
    lab["dots"] = [
        {
            "xy_m": [float(v) for v in t["xy_robot_m"]],
            **({"uv_px": [float(v) for v in t["uv_px"]]} if t.get("uv_px") is not None else {}),
            "faint": t["snr"] < SNR_VISIBLE,
            "age_s": float(t["age_s"]),
        }
        for t in tdots
    ]
    cell = truth.get("cell")
    if cell is not None:
        lab["heading_error_deg"] = math.degrees(wrap_angle(truth["pose"]["heading_rad"] - cell["entry_heading_rad"]))
        lab["boxes"] = {b: _status([t["snr"] for t in tdots if t.get("box") == b]) for b in BOXES}
        lab["neighbours"] = {
            n["direction"]: {
                "red": bool(n["has_red"]),
                "marks": _status([t["snr"] for t in tdots if t.get("neighbour") == n["direction"]])
                if any("neighbour" in t for t in truth["dots"]) or not n.get("has_marks")
                else None,
            }
            for n in cell["neighbours"]
        }
    return lab
