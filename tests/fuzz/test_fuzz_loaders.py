"""Fuzz every file loader: profiles, scenes, recipes, dataset folders, board maps (text and
image), arenas, nest and search specs, camera and robot files, read_json and read_image.

Inputs are the shipped valid documents with fields dropped, added, retyped, replaced by weird
values or NaN/inf/huge numbers, and files that are truncated, garbage, deeply nested, not UTF-8
or mislabelled. The contract (fuzzlib): a result or a one-line project error, nothing else.
"""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import cv2
import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from stcvision.errors import StcVisionError

from .fuzzlib import examples, json_file_bytes, mutated, numbers, project_call, scalars, weird

ROOT = Path(__file__).resolve().parents[2]


def _tmp_file(name: str, data: bytes) -> tuple[tempfile.TemporaryDirectory, Path]:
    d = tempfile.TemporaryDirectory()
    p = Path(d.name) / name
    p.write_bytes(data)
    return d, p


# ------------------------------------------------------------------------------------ read_json / read_image
@examples(2)
@given(json_file_bytes(st.dictionaries(st.text(max_size=5), weird, max_size=4)))
def test_read_json(data):
    from stcvision.fileio import read_json

    d, p = _tmp_file("x.json", data)
    with d:
        project_call(read_json, p)


def _encoded_image(draw) -> bytes:
    dtype = draw(st.sampled_from([np.uint8, np.uint16]))
    ch = draw(st.sampled_from([1, 3, 4]))
    h, w = draw(st.integers(1, 12)), draw(st.integers(1, 12))
    arr = np.asarray(draw(st.lists(st.integers(0, 65535), min_size=h * w * ch, max_size=h * w * ch)))
    arr = (arr % (256 if dtype is np.uint8 else 65536)).astype(dtype).reshape(h, w, ch)
    ext = draw(st.sampled_from([".png", ".jpg", ".bmp", ".tiff"]))
    if ext in (".jpg", ".bmp") and dtype is np.uint16:
        arr = (arr >> 8).astype(np.uint8)
    ok, buf = cv2.imencode(ext, arr)
    assert ok
    return buf.tobytes()


@st.composite
def image_files(draw):
    """(name, bytes): an image, truncated, garbage, empty, or under another extension."""
    kind = draw(st.sampled_from(["image", "image", "truncated", "garbage", "empty", "text"]))
    if kind in ("image", "truncated"):
        data = _encoded_image(draw)
        if kind == "truncated":
            data = data[: draw(st.integers(0, len(data) - 1))]
    elif kind == "garbage":
        data = draw(st.binary(max_size=80))
    elif kind == "text":
        data = b"..S.\n....\n"
    else:
        data = b""
    return draw(st.sampled_from(["f.png", "f.jpg", "f.txt", "f", "f.tif"])), data


@examples(2)
@given(image_files(), st.booleans())
def test_read_image(named, color):
    from stcvision.fileio import read_image

    d, p = _tmp_file(*named)
    with d:
        img = project_call(read_image, p, color=color)
    if not isinstance(img, StcVisionError):
        assert img.dtype in ((np.uint8, np.uint16) if color else (np.uint8,)) and img.ndim == (3 if color else 2)
        if color:
            assert img.shape[2] == 3


# ------------------------------------------------------------------------------------ profiles
def _profile_dict() -> dict:
    return json.loads((ROOT / "calibration" / "profiles" / "default.json").read_text())


@examples(3)
@given(mutated(_profile_dict(), keys=["center_px", "theta_poly", "ground_size_px", "neighbour_corners_px"]))
def test_profile_from_dict(d):
    from stcvision.profile import Profile

    prof = project_call(Profile.from_dict, d)
    if isinstance(prof, Profile):  # an accepted profile works: maps points both ways without error
        pts = project_call(prof.image_to_robot, [[320.0, 100.0], [0.0, 0.0]])
        assert not isinstance(pts, StcVisionError)
        assert prof.corners_px().shape == (12, 2)
        assert Profile.from_dict(prof.to_dict()) == prof


@examples(1)
@given(json_file_bytes(mutated(_profile_dict())))
def test_profile_load(data):
    from stcvision.profile import Profile

    d, p = _tmp_file("p.json", data)
    with d:
        project_call(Profile.load, p)


# ------------------------------------------------------------------------------------ scenes
def _scene_dict() -> dict:
    from stcvision.sim_camera.scene import EXAMPLE_SCENE

    return json.loads(json.dumps(EXAMPLE_SCENE))


_SCENE_BOARDS = st.sampled_from(
    [
        {"random": {"cells": [2, 3], "obstacle_fraction": 0.2, "seed": 1}},
        {"text": ["..", ".S"]},
        {"text": "S.\n.."},
        {"file": "nonexistent.txt"},
        {"file": "map.png"},
    ]
)


@examples(3)
@given(
    mutated(_scene_dict(), keys=["board", "robot", "marks", "dots", "time_s", "red_lights", "camera", "sensor"]),
    st.one_of(st.none(), _SCENE_BOARDS),
)
def test_scene_from_dict(d, board):
    from stcvision.sim_camera.scene import Scene

    if board is not None:
        d["board"] = board
    with tempfile.TemporaryDirectory() as tmp:
        cv2.imwrite(str(Path(tmp) / "map.png"), np.full((4, 4), 255, np.uint8))
        scene = project_call(Scene.from_dict, d, base_dir=Path(tmp))
    if not isinstance(scene, StcVisionError):
        assert np.isfinite(scene.t_s) and all(np.isfinite([scene.pose.x_m, scene.pose.y_m, scene.pose.heading_rad]))
        assert np.isfinite(scene.red_lights_m).all()


# ------------------------------------------------------------------------------------ recipes and datasets
def _recipe_dict() -> dict:
    return json.loads((ROOT / "datasets" / "recipes" / "smoke.json").read_text())


@examples(3)
@given(mutated(_recipe_dict(), keys=["groups", "scene", "camera", "sensor", "dark_frames", "calibration", "n"]))
def test_parse_recipe(d):
    from stcvision.datasets import Recipe, parse_recipe

    r = project_call(parse_recipe, d)
    if isinstance(r, Recipe):
        assert r.n_frames >= 1 and r.dark_frames >= 1
        for g in r.groups:
            for k, v in g.scene.items():
                vals = v if isinstance(v, tuple) else (v,)
                assert all(math.isfinite(x) for x in vals), (k, v)


def _manifest() -> dict:
    return {
        "kind": "stcvision-dataset",
        "schema_version": 1,
        "complete": True,
        "image_size_px": [640, 480],
        "cameras": {"cam0": {"profile": "profiles/cam0.json"}},
        "groups": {"g": {"n": 2}},
        "counts": {"frames": 2},
    }


def _label(k: int) -> dict:
    return {"frame": f"frames/{k:06d}.png", "dots": [], "pose": {}, "sensor": {}, "dark": "dark/g.png"}


@st.composite
def dataset_folders(draw):
    """(manifest, labels lines, files present) of a dataset folder, mutated."""
    manifest = draw(st.one_of(mutated(_manifest(), keys=["counts", "cameras", "complete"]), st.just(_manifest())))
    labels = [draw(st.one_of(st.just(_label(k)), mutated(_label(k), keys=["frame", "dark"]))) for k in range(2)]
    lines = [json.dumps(x, allow_nan=True) for x in labels]
    if draw(st.booleans()):
        i = draw(st.integers(0, 1))
        lines[i] = draw(st.sampled_from(["{", "[]", "null", '"frames/000000.png"', "NaN", lines[i][:-3]]))
    files = ["frames/000000.png", "frames/000001.png", "dark/g.png", "profiles/cam0.json"]
    files = draw(st.lists(st.sampled_from(files + ["frames/extra.png"]), unique=True, max_size=5))
    return manifest, "\n".join(lines), files


@examples(3)
@given(dataset_folders(), st.booleans())
def test_open_dataset(folder, with_manifest):
    from stcvision.datasets import Dataset, open_dataset

    manifest, labels, files = folder
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "D"
        for f in files:
            (root / f).parent.mkdir(parents=True, exist_ok=True)
            (root / f).write_bytes(b"x")
        root.mkdir(exist_ok=True)
        if with_manifest:
            (root / "manifest.json").write_text(json.dumps(manifest, allow_nan=True))
        (root / "labels.jsonl").write_text(labels)
        ds = project_call(open_dataset, root)
        if isinstance(ds, Dataset):  # every frame it lists lies inside the folder
            for lab in ds.labels:
                assert (root / lab["frame"]).resolve().is_relative_to(root.resolve())
                assert (root / lab["frame"]).is_file()


# ------------------------------------------------------------------------------------ boards
@examples(3)
@given(st.text(alphabet=".#S;x \n\r\t", max_size=60))
def test_board_from_text(text):
    from stcvision.sim_camera.board import Board

    b = project_call(Board.from_text, text)
    if isinstance(b, Board):
        assert Board.from_text(b.to_text()).to_text() == b.to_text()


_ARRAY_DTYPES = st.sampled_from([np.uint8, np.uint16, np.int8, np.float32, np.float64, np.bool_, np.int64])


@st.composite
def small_arrays(draw, max_side: int = 8):
    """Arrays of any dtype and 0..4 dimensions, NaN/inf included where the dtype allows."""
    ndim = draw(st.integers(0, 4))
    shape = tuple(draw(st.integers(0, max_side)) for _ in range(ndim))
    dtype = draw(_ARRAY_DTYPES)
    if np.issubdtype(dtype, np.floating):
        vals = draw(st.lists(st.floats(allow_nan=True, allow_infinity=True, width=32), min_size=1, max_size=64))
    else:
        vals = draw(st.lists(st.integers(0, 255), min_size=1, max_size=64))
    return np.resize(np.asarray(vals).astype(dtype), shape)  # the drawn values repeated to fill the shape


@examples(3)
@given(small_arrays(), st.one_of(st.none(), st.tuples(st.integers(-2, 9), st.integers(-2, 9))))
def test_board_from_image(img, start):
    from stcvision.sim_camera.board import Board

    project_call(Board.from_image, img, start_subcell=start)


@examples(2)
@given(image_files(), st.one_of(st.none(), st.tuples(st.integers(-1, 5), st.integers(-1, 5))))
def test_board_from_file(named, start):
    from stcvision.sim_camera.board import Board

    d, p = _tmp_file(*named)
    with d:
        project_call(Board.from_file, p, start_subcell=start)


@examples(3)
@given(st.one_of(st.text(alphabet="0123456789x,-.einf ", max_size=12), st.text(max_size=8)))
def test_board_size_argument(text):
    """--board WxH (the argparse type of world and cover): a pair or an argparse error."""
    import argparse

    from stcvision.cli._args import pair

    try:
        w, h = pair(int)(text)
    except argparse.ArgumentTypeError as exc:
        assert str(exc) and "\n" not in str(exc)
    else:
        assert isinstance(w, int) and isinstance(h, int)


# ------------------------------------------------------------------------------------ arenas
_ARENAS = [
    {"schema_version": 1, "kind": "circle", "center_m": [0, 0], "radius_m": 0.5, "wall_thickness_m": 0.05,
     "barriers": [{"type": "|", "length_fraction": 0.5, "thickness_m": 0.01}, {"start_m": [0, 0], "end_m": [0.2, 0]}],
     "obstacles": [{"kind": "circle", "center_m": [0.3, 0], "radius_m": 0.05},
                   {"kind": "polygon", "vertices_m": [[0, 0], [0.1, 0], [0, 0.1]]}]},
    {"schema_version": 1, "kind": "square", "center_m": [0, 0], "side_m": 1.0,
     "barriers": [{"type": "+", "length_fraction": 0.3}]},
    {"schema_version": 1, "kind": "ellipse", "center_m": [0, 0], "semi_axes_m": [0.6, 0.3]},
    {"kind": "polygon", "vertices_m": [[0, 0], [1, 0], [1, 1], [0, 1]]},
]  # fmt: skip


@examples(4)
@given(st.sampled_from(_ARENAS).flatmap(lambda a: mutated(a, keys=["kind", "barriers", "obstacles", "radius_m"])))
def test_arena_from_dict(d):
    from stcvision.sim_camera.arenas import Arena

    a = project_call(Arena.from_dict, d)
    if isinstance(a, Arena):
        assert math.isfinite(a.area_m2) and a.area_m2 > 0
        assert all(math.isfinite(v) for v in a.bounds_m)
        project_call(a.contains, [[0.0, 0.0], [0.1, 0.2]])


@examples(1)
@given(json_file_bytes(st.sampled_from(_ARENAS).flatmap(mutated)))
def test_arena_from_file(data):
    from stcvision.sim_camera.arenas import Arena

    d, p = _tmp_file("a.json", data)
    with d:
        project_call(Arena.from_file, p)


# ------------------------------------------------------------------------------------ nests (Buffon)
_NUM_TEXT = st.one_of(
    st.sampled_from(["20", "100", "7854", "4", "1", "0", "-3", "nan", "inf", "1e9", "", "x", "0.5", "1e-9"]),
    numbers.map(str),
)
nest_specs = st.one_of(
    st.builds(lambda k, a: f"{k}:{':'.join(a)}", st.sampled_from(["circle", "square", "ellipse", "poly", ""]),
              st.lists(_NUM_TEXT, max_size=3)),
    st.text(max_size=10),
)  # fmt: skip
barriers = st.one_of(
    st.none(),
    st.builds(lambda k, f: f"{k}:{f}", st.sampled_from(["bar", "plus", "|", "+", "x"]), _NUM_TEXT),
    st.text(max_size=6),
)


@examples(4)
@given(nest_specs, barriers)
def test_parse_nest(spec, barrier):
    from stcvision.controllers.buffon.nests import Nest, parse_nest

    n = project_call(parse_nest, spec, barrier)
    if isinstance(n, Nest):
        assert math.isfinite(n.area_u2) and n.area_u2 > 0


polygon_docs = st.one_of(
    st.just([[0, 0], [40, 0], [40, 40], [0, 40]]),
    st.lists(st.lists(numbers, min_size=2, max_size=2), max_size=6),
    st.lists(st.lists(scalars, max_size=3), max_size=5),
    weird,
)


@examples(2)
@given(json_file_bytes(polygon_docs), barriers)
def test_parse_nest_polygon_file(data, barrier):
    from stcvision.controllers.buffon.nests import parse_nest

    d, p = _tmp_file("nest.json", data)
    with d:
        project_call(parse_nest, f"polygon:{p}", barrier)


# ------------------------------------------------------------------------------------ search specs
triples = st.one_of(
    st.tuples(numbers, numbers, numbers),
    st.lists(st.one_of(numbers, scalars), max_size=4).map(tuple),
    st.tuples(st.floats(-2, 2), st.floats(-2, 2), st.floats(0.01, 0.5)),
)


@examples(3)
@given(st.lists(triples, max_size=3), st.one_of(st.none(), triples))
def test_search_scene(obstacles, patch):
    from stcvision.controllers.search.run import SearchScene

    s = project_call(SearchScene, obstacles=tuple(obstacles), patch=patch)
    if isinstance(s, SearchScene):
        for o in s.circle_obstacles():
            assert o.radius_m > 0 and all(math.isfinite(c) for c in o.center_m)


# ------------------------------------------------------------------------------------ camera and robot files
def _camera_dict() -> dict:
    from stcvision.sim_camera.hardware import LOWLIGHT, camera_to_dict

    return json.loads(json.dumps(camera_to_dict(LOWLIGHT)))


def _robot_dict() -> dict:
    from stcvision.sim_camera.hardware import LEGO_STC_ROBOT, robot_to_dict

    return json.loads(json.dumps(robot_to_dict(LEGO_STC_ROBOT)))


@examples(3)
@given(st.one_of(json_file_bytes(mutated(_camera_dict(), keys=["sensor", "adc_bits"])), st.binary(max_size=20)))
def test_load_camera(data):
    from stcvision.sim_camera.hardware import CameraProfile, load_camera

    d, p = _tmp_file("cam.json", data)
    with d:
        c = project_call(load_camera, str(p))
    if isinstance(c, CameraProfile):
        from stcvision.sim_camera.hardware import CAMERA_FIGURES

        assert all(math.isfinite(getattr(c.sensor, k)) for k in CAMERA_FIGURES)


@examples(3)
@given(st.one_of(json_file_bytes(mutated(_robot_dict(), keys=["drive_speed_m_s"])), st.binary(max_size=20)))
def test_load_robot(data):
    from stcvision.sim_camera.hardware import load_robot

    d, p = _tmp_file("robot.json", data)
    with d:
        project_call(load_robot, str(p))


# ------------------------------------------------------------------------------------ target points files
def _points_text(suffix: str) -> str:
    from stcvision.calibration.target_sim import simulated_views
    from stcvision.calibration.target_views import write_points_file

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / f"good{suffix}"
        write_points_file(p, simulated_views(3, 4))
        return p.read_text()


_POINTS_XML = _points_text(".xml")
_POINTS_YAML = _points_text(".yml")
#: what a fuzzed points file's numbers, keys and sizes may become
_POINT_TOKENS = st.sampled_from(
    ["nan", ".Nan", "inf", "-.Inf", "1e308", "-1e308", "0", "-1", "4000000000", "abc", "", '"3d"', '"u"', "[]", "{}"]
)
_POINT_KEYS = st.sampled_from(["objectPoints", "imagePoints", "imageSize", "rows", "cols", "dt", "data"])


@st.composite
def _mutated_points(draw):
    """A good points file (XML or YAML) with tokens replaced, a key renamed, lines dropped or
    repeated, or cut short."""
    text = draw(st.sampled_from([_POINTS_XML, _POINTS_YAML]))
    suffix = ".xml" if text is _POINTS_XML else ".yml"
    toks = text.split(" ")
    for _ in range(draw(st.integers(0, 4))):
        toks[draw(st.integers(0, len(toks) - 1))] = draw(_POINT_TOKENS)
    text = " ".join(toks)
    if draw(st.booleans()):
        key = draw(_POINT_KEYS)
        text = text.replace(key, draw(st.sampled_from(["", key + "1", key.upper(), "imagePoints2"])), 1)
    lines = text.splitlines(keepends=True)
    for _ in range(draw(st.integers(0, 3))):
        i = draw(st.integers(0, len(lines) - 1))
        lines[i : i + 1] = draw(st.sampled_from([[], [lines[i], lines[i]], [lines[i] * 50]]))
    text = "".join(lines)
    return suffix, text[: draw(st.integers(0, len(text)))] if draw(st.booleans()) else text


@examples(2)
@given(_mutated_points())
def test_read_points_file(named):
    """A fuzzed OpenCV points file: its views, or one line saying what is wrong (never a
    traceback, never an allocation of what a file merely declares)."""
    from stcvision.calibration.target_views import read_points_file

    suffix, text = named
    d, p = _tmp_file("points" + suffix, text.encode())
    with d:
        project_call(read_points_file, p)
