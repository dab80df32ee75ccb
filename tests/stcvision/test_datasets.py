"""stcvision dataset generate / check: the recipe format, determinism, resuming, refusals."""

import json
import shutil
from pathlib import Path

import pytest

from stcvision.cli import main
from stcvision.datasets import load_recipe, open_dataset, parse_recipe

ROOT = Path(__file__).resolve().parents[2]
RECIPES = ROOT / "datasets" / "recipes"
SMOKE = RECIPES / "smoke.json"  # the recipe behind the conftest `smoke` fixture


def files(d: Path) -> dict[str, bytes]:
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def test_a_recipes_scene_parameters_are_the_scene_functions():
    """The scene parameters a recipe may set are read from ``cell_scene``'s signature, each with
    the JSON its annotation takes, and every one has the range a recipe's values are checked
    against; reading a dataset does not load the simulator that signature comes from."""
    import subprocess
    import sys

    from stcvision.datasets import recipe

    keys = recipe.scene_keys()
    assert keys["cells"] == "pair" and keys["charge_s"] == "number"
    assert keys["heading_error_deg"] == "number_or_pair"
    assert set(keys) == set(recipe._SCENE_RANGES)
    code = "import sys, stcvision.evaluate; assert not any(m.startswith('stcvision.sim_camera') for m in sys.modules)"
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)


def test_every_shipped_recipe_parses():
    names = {p.stem for p in RECIPES.glob("*.json")}
    assert {"smoke", "ages", "rotation", "exposure", "obstacles", "perturbed-camera", "calibration"} <= names
    for p in RECIPES.glob("*.json"):
        r = load_recipe(p)
        assert r.name == p.stem and r.n_frames >= 1
    assert load_recipe(SMOKE).n_frames <= 10  # tiny, for tests
    pc = load_recipe(RECIPES / "perturbed-camera.json")
    assert pc.profiles and len({(json.dumps(g.camera, sort_keys=True), g.pattern_seed) for g in pc.groups}) >= 2


def test_smoke_dataset_layout(smoke, cli):
    m = json.loads((smoke / "manifest.json").read_text())
    assert m["schema_version"] == 1 and m["complete"] and m["recipe_name"] == "smoke" and m["seed"] == 0
    assert m["counts"]["frames"] == 6 and m["cameras"]["cam0"]["optics"]["width_px"] == 640
    assert sorted(p.name for p in (smoke / "frames").iterdir()) == [f"{k:06d}.png" for k in range(6)]
    assert sorted(p.name for p in (smoke / "dark").iterdir()) == ["exp250ms.png", "webcam.png"]
    assert not (smoke / ".parts").exists()
    labels = [json.loads(line) for line in (smoke / "labels.jsonl").read_text().splitlines()]
    assert [lab["frame"] for lab in labels] == [f"frames/{k:06d}.png" for k in range(6)]
    for lab in labels:
        assert {"dots", "pose", "sensor", "optics", "cell", "red_lights", "group", "dark", "camera"} <= set(lab)
    assert labels[3]["sensor"]["exposure_s"] == 0.25 and labels[3]["dark"] == "dark/exp250ms.png"
    code, out, _ = cli("dataset", "check", smoke, "--json")
    assert code == 0 and json.loads(out)["counts"]["frames"] == 6
    code, _, err = cli("dataset", "check", smoke / "frames")
    assert code == 2 and "is not a dataset" in err and err.count("\n") == 1


def test_generation_is_deterministic(smoke, tmp_path):
    # `smoke` was made in-process (--workers 1), this by the default pool (one process per CPU)
    assert main(["dataset", "generate", str(SMOKE), "--out", str(tmp_path / "again")]) == 0
    assert files(tmp_path / "again") == files(smoke)


def test_resume_renders_only_what_is_missing(smoke, tmp_path, cli):
    d = tmp_path / "D"
    shutil.copytree(smoke, d)
    (d / "frames" / "000004.png").unlink()
    (d / "dark" / "webcam.png").unlink()
    code, out, _ = cli("dataset", "generate", SMOKE, "--out", d, "--json", "--workers", "1")
    r = json.loads(out)
    # the chunk of frame 4 (group exp250ms: frames 3-5, one task) is rendered again, and the dark
    assert code == 0 and r["frames_rendered"] == 3 and r["frames_skipped"] == 3 and r["darks_rendered"] == 1
    assert r["tasks"] == 2
    assert files(d) == files(smoke)


def test_a_failed_chunk_leaves_an_incomplete_dataset_that_the_next_run_finishes(smoke, tmp_path, cli, monkeypatch):
    import stcvision.datasets.render as dg

    real = dg.render_frames

    def broken(params, seed):
        if params["group"] == 1:
            raise OSError("disk full")
        return real(params, seed)

    d = tmp_path / "D"
    monkeypatch.setattr(dg, "render_frames", broken)  # in-process (--workers 1) tasks see the patch
    code, _, err = cli("dataset", "generate", SMOKE, "--out", d, "--workers", "1")
    assert code == 2 and "1 of 4 tasks failed" in err and "OSError: disk full" in err and err.count("\n") == 1
    assert not (d / "labels.jsonl").exists() and (d / ".sweep.jsonl").exists()
    code, _, err = cli("eval", d)
    assert code == 2 and "incomplete" in err and err.count("\n") == 1
    monkeypatch.setattr(dg, "render_frames", real)
    code, out, _ = cli("dataset", "generate", SMOKE, "--out", d, "--workers", "1", "--json")
    r = json.loads(out)
    # the three finished tasks (calibration-free smoke: 2 darks, group 0's chunk) are not run again
    assert code == 0 and r["frames_rendered"] == 3 and r["frames_skipped"] == 3 and r["darks_rendered"] == 0
    assert files(d) == files(smoke)  # the store is gone, the files are those of an uninterrupted run
    code, out, _ = cli("dataset", "generate", SMOKE, "--out", d, "--workers", "1", "--fresh", "--json")
    assert code == 0 and json.loads(out)["frames_rendered"] == 6 and files(d) == files(smoke)


def test_frame_k_does_not_depend_on_earlier_frames(tmp_path):
    base = {"schema_version": 1, "name": "indep", "dark_frames": 1, "seed": 9}
    a = parse_recipe({**base, "groups": [{"name": "g", "n": 3}]})
    b = parse_recipe({**base, "groups": [{"name": "first", "n": 1}, {"name": "g", "n": 3}]})
    from stcvision.datasets.render import generate
    from stcvision.sweep import SweepOptions

    generate(a, tmp_path / "a", options=SweepOptions(workers=1))
    generate(b, tmp_path / "b", options=SweepOptions(workers=2))
    # frame index k has the same scene and noise whatever the groups before it
    for k in (1, 2):
        assert (tmp_path / "a" / "frames" / f"{k:06d}.png").read_bytes() == (
            tmp_path / "b" / "frames" / f"{k:06d}.png"
        ).read_bytes()


def test_refuses_a_folder_of_another_recipe_or_seed(smoke, tmp_path, cli):
    code, _, err = cli("dataset", "generate", SMOKE, "--out", smoke, "--seed", "1")
    assert code == 2 and "seed 0" in err and err.count("\n") == 1
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    code, _, err = cli("dataset", "generate", SMOKE, "--out", other)
    assert code == 2 and "not empty" in err
    assert (other / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize(
    ("patch", "words"),
    [
        ({"schema_version": 2}, "schema_version"),
        ({"groups": []}, "groups"),
        ({"groups": [{"name": "g", "n": 1, "scene": {"colour": 1}}]}, "colour"),
        ({"groups": [{"name": "g", "n": 0}]}, "n must be"),
        ({"groups": [{"name": "g", "n": 1, "scene": {"age_range_s": 5}}]}, "age_range_s"),
        ({"groups": [{"name": "g", "n": 1}, {"name": "g", "n": 1}]}, "twice"),
        ({"groups": [{"name": "g", "n": 1, "sensor": {"exposure_ms": 3}}]}, "exposure_ms"),
    ],
)
def test_bad_recipes_are_one_line_errors(tmp_path, cli, patch, words):
    r = {"schema_version": 1, "name": "bad", "groups": [{"name": "g", "n": 1}], **patch}
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(r))
    code, _, err = cli("dataset", "generate", p, "--out", tmp_path / "out")
    assert code == 2 and words in err and err.count("\n") == 1, err
    assert not (tmp_path / "out").exists()


def test_open_dataset_reads_labels_in_order(smoke):
    ds = open_dataset(smoke)
    assert len(ds.labels) == 6 and ds.image_size_px == (640, 480) and ds.profile_path("cam0") is None
