"""Hand labels of real frames (stcvision.labels): a generated set and the same set written as
hand labels (``dataset export-labels``) score the same to the last digit; labels made wrong on
purpose move the scores by exactly what they imply; absent fields are not scored; bad label
files are one line and exit 2."""

import json
import shutil

import pytest

from stcvision.errors import BadInputError
from stcvision.labels import parse_label

#: every accuracy the two ways of scoring share
SHARED = (
    "frames",
    "dot_recall",
    "dot_precision",
    "dot_loc_err_mm_median",
    "dot_loc_err_mm_p95",
    "dot_loc_err_px_median",
    "heading_err_deg_rms",
    "heading_fits",
    "box_accuracy",
    "boxes_scored",
    "box_recall",
    "box_precision",
    "obstacle_accuracy",
    "obstacles_scored",
    "obstacle_recall",
    "obstacle_precision",
    "neighbour_marks_accuracy",
    "neighbour_marks_scored",
    "neighbour_marks_recall",
    "neighbour_marks_precision",
)


@pytest.fixture(scope="module")
def exported(smoke, tmp_path_factory):
    from stcvision.cli import main

    out = tmp_path_factory.mktemp("exported") / "L"
    assert main(["dataset", "export-labels", str(smoke), "--out", str(out)]) == 0
    return out


def _eval(cli, folder, *extra):
    code, out, err = cli("eval", folder, "--json", *extra)
    assert code == 0, err
    return json.loads(out)


def test_a_dataset_and_its_exported_labels_score_the_same(cli, smoke, exported):
    a, b = _eval(cli, smoke), _eval(cli, exported)
    assert b["mode"] == "labelled" and a["mode"] == "dataset"
    assert {k: a[k] for k in SHARED} == {k: b[k] for k in SHARED}
    assert a["boxes_scored"] > 10 and a["neighbour_marks_scored"] > 10 and a["heading_fits"] > 0


def _copy(exported, tmp_path):
    d = tmp_path / "L"
    shutil.copytree(exported, d)
    return d, [json.loads(line) for line in (d / "labels.jsonl").read_text().splitlines()]


def _write(d, labels):
    (d / "labels.jsonl").write_text("".join(json.dumps(lab) + "\n" for lab in labels))


def test_wrong_labels_move_the_scores_by_what_they_imply(cli, exported, tmp_path, default_profile):
    """Flip three box labels and one red light: the box and obstacle accuracy fall (or rise,
    where the pipeline was wrong) by exactly those labels, frame by frame."""
    from stcvision.datasets import open_dataset
    from stcvision.evaluate import evaluate_dataset

    good = evaluate_dataset(open_dataset(exported), default_profile=default_profile)
    d, labels = _copy(exported, tmp_path)
    flipped = 0
    for lab in labels:
        for k, v in lab.get("boxes", {}).items():
            if v is not None and flipped < 3:
                lab["boxes"][k] = not v
                flipped += 1
    labels[0]["neighbours"]["right"]["red"] = not labels[0]["neighbours"]["right"]["red"]
    _write(d, labels)
    bad = evaluate_dataset(open_dataset(d), default_profile=default_profile)
    assert flipped == 3
    g, b = good.summary, bad.summary
    right = round(g["box_accuracy"] * g["boxes_scored"])
    reads = [r for rec in good.records for r in rec.boxes]
    changed = [reads[i] for i in range(len(reads))][:3]  # the first three scored boxes, in frame order
    delta = sum(-1 if t == r else 1 for t, r in changed)
    assert b["boxes_scored"] == g["boxes_scored"]
    assert b["box_accuracy"] == pytest.approx((right + delta) / g["boxes_scored"], abs=1e-12)
    first = good.records[0].obstacles
    right_red = dict(zip(("right", "forward", "left", "back"), first, strict=False))["right"]
    red_delta = -1 if right_red[0] == right_red[1] else 1
    assert b["obstacle_accuracy"] == pytest.approx(
        (round(g["obstacle_accuracy"] * g["obstacles_scored"]) + red_delta) / g["obstacles_scored"], abs=1e-12
    )


def test_dots_labelled_in_pixels_score_as_on_the_floor(cli, exported, tmp_path):
    d, labels = _copy(exported, tmp_path)
    for lab in labels:
        for dot in lab.get("dots", []):
            dot.pop("xy_m")
    _write(d, labels)
    a, b = _eval(cli, exported), _eval(cli, d)
    assert b["dot_recall"] == a["dot_recall"] and b["dot_precision"] == a["dot_precision"]


def test_absent_fields_are_not_scored(cli, exported, tmp_path):
    d, labels = _copy(exported, tmp_path)
    _write(d, [{"frame": lab["frame"], "dark": lab["dark"]} for lab in labels])
    r = _eval(cli, d)
    assert r["boxes_scored"] == r["obstacles_scored"] == r["neighbour_marks_scored"] == r["heading_fits"] == 0
    assert r["box_accuracy"] is None and r["dot_recall"] is None and r["frames"] == len(labels)


@pytest.mark.parametrize(
    "line, says",
    [
        ({"frame": "f.png", "box": {}}, "unknown field 'box'"),
        ({"frame": "f.png", "boxes": {"7": True}}, "box '7' is not one of"),
        ({"frame": "f.png", "neighbours": {"up": {"red": True}}}, "neighbour 'up'"),
        ({"frame": "f.png", "heading_error_deg": 400}, "heading_error_deg"),
        ({"frame": "f.png", "dots": [{"uv_px": [1]}]}, "two finite numbers"),
        ({"boxes": {}}, 'no "frame"'),
    ],
)
def test_a_bad_label_is_one_named_line(line, says):
    with pytest.raises(BadInputError, match=says):
        parse_label(line)


def test_bad_label_folders_are_one_line_and_exit_2(cli, exported, tmp_path):
    d, labels = _copy(exported, tmp_path)
    (d / labels[0]["frame"]).unlink()
    code, _, err = cli("eval", d)
    assert code == 2 and "is missing" in err and err.count("\n") == 1
    d2, labels = _copy(exported, tmp_path / "b")
    _write(d2, [{k: v for k, v in lab.items() if k != "dark"} for lab in labels])
    code, _, err = cli("eval", d2)
    assert code == 2 and "--dark DARK.png" in err and err.count("\n") == 1
    r = _eval(cli, d2, "--dark", str(d2 / labels[0]["dark"]))
    assert r["frames"] == len(labels)
