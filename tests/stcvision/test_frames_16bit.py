"""16-bit frames end to end on disk (sensor-true ADC counts): PNG round trips that keep the ADC counts,
`stcvision render` of a 12/16-bit camera, datasets (generate, check, the evaluation's loader),
and the one-line refusals (greyscale frames, a dark of another depth, JPEG for 16 bits)."""

import json
import shutil

import cv2
import numpy as np
import pytest

from stcvision.errors import BadInputError
from stcvision.fileio import read_image, write_image


def test_png_keeps_16_bit_adc_counts_exactly(tmp_path):
    rng = np.random.default_rng(0)
    for top in (4095, 65535):  # 12-bit counts (LSB-aligned) and the full 16 bits
        img = rng.integers(0, top + 1, (48, 64, 3), dtype=np.uint16)
        img[0, 0] = (top, 0, 1)
        p = write_image(tmp_path / f"f{top}.png", img)
        back = read_image(p, what="frame")
        assert back.dtype == np.uint16 and np.array_equal(back, img)  # never divided by 256
        assert cv2.imread(str(p), cv2.IMREAD_UNCHANGED).dtype == np.uint16  # a real 16-bit PNG
    img8 = rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
    assert np.array_equal(read_image(write_image(tmp_path / "f8.png", img8)), img8)
    with pytest.raises(BadInputError, match="16-bit.*expected .png"):
        write_image(tmp_path / "f.jpg", img)
    assert not (tmp_path / "f.jpg").exists()


def test_greyscale_and_alpha_frames_are_refused_in_one_line(tmp_path, cli):
    grey = tmp_path / "grey.png"
    cv2.imwrite(str(grey), np.zeros((480, 640), np.uint16))
    with pytest.raises(BadInputError, match="greyscale; expected a 3-channel BGR frame"):
        read_image(grey, what="frame")
    bgra = tmp_path / "bgra.png"
    cv2.imwrite(str(bgra), np.zeros((480, 640, 4), np.uint8))
    with pytest.raises(BadInputError, match="4-channel; expected a 3-channel BGR frame"):
        read_image(bgra, what="frame")
    code, _, err = cli("pipeline", grey, "--no-dark")
    assert code == 2 and err.count("\n") == 1 and "expected a 3-channel BGR frame" in err and str(grey) in err
    # a map is read as grey whatever it holds
    assert read_image(bgra, color=False).shape == (480, 640)


@pytest.fixture(scope="module")
def rendered16(tmp_path_factory):
    from stcvision.cli import main
    from stcvision.sim_camera.scene import EXAMPLE_SCENE

    d = tmp_path_factory.mktemp("render16")
    (d / "scene.json").write_text(json.dumps(EXAMPLE_SCENE))
    argv = ["render", "--scene", str(d / "scene.json"), "--out", str(d / "out"), "--seed", "3", "--camera", "cooled"]
    assert main([*argv, "--dark-frames", "4"]) == 0
    return d


def test_render_writes_the_cooled_cameras_16_bit_frames(rendered16):
    """The frame on disk is the frame rendered: the same seed streams in this process give the
    same uint16 counts; the dark and the lights-on frame are 16-bit too."""
    from stcvision.sim_camera.hardware import COOLED
    from stcvision.sim_camera.scene import Scene

    out = rendered16 / "out"
    frame = read_image(out / "frame.png", what="frame")
    assert frame.dtype == np.uint16 and frame.max() > 255
    for name in ("dark.png", "lights_on.png"):
        assert read_image(out / name).dtype == np.uint16
    scene = Scene.from_file(rendered16 / "scene.json", sensor_base=COOLED.sensor)
    assert scene.sensor.adc_bits == 16 and scene.sensor.exposure_s == pytest.approx(0.0333)  # scene overrides kept
    rng = np.random.default_rng(np.random.SeedSequence(3).spawn(3)[0])
    again = scene.camera().render(
        scene.pose, rng=rng, t_s=scene.t_s, phosphor=scene.phosphor, red_lights_m=scene.red_lights_m
    )
    assert np.array_equal(again.image, frame)
    assert json.loads((out / "truth.json").read_text())["sensor"]["adc_bits"] == 16


def test_a_dark_of_another_depth_is_refused_naming_it(rendered16, tmp_path, cli):
    out = rendered16 / "out"
    dark8 = tmp_path / "dark8.png"
    cv2.imwrite(str(dark8), np.zeros((480, 640, 3), np.uint8))
    code, _, err = cli("pipeline", out / "frame.png", "--dark", dark8)
    assert code == 2 and err.count("\n") == 1
    assert f"dark frame {dark8} is 8-bit" in err and "16-bit" in err


@pytest.fixture(scope="module")
def deep(tmp_path_factory):
    """Two frames of the shipped deep-adc recipe's 12- and 16-bit groups (one each) and the webcam's."""
    from pathlib import Path

    from stcvision.cli import main

    recipe = json.loads((Path(__file__).resolve().parents[2] / "datasets/recipes/deep-adc.json").read_text())
    recipe["groups"] = [dict(g, n=1) for g in recipe["groups"] if g["name"] in ("webcam", "lowlight-2s", "cooled-2s")]
    recipe["dark_frames"] = 2
    d = tmp_path_factory.mktemp("deep")
    (d / "r.json").write_text(json.dumps(recipe))
    assert main(["dataset", "generate", str(d / "r.json"), "--out", str(d / "D"), "--workers", "1"]) == 0
    return d / "D"


def test_datasets_store_each_sensors_depth_and_check_it(deep, tmp_path, cli):
    from stcvision.datasets import open_dataset

    ds = open_dataset(deep)
    bits = [lab["sensor"]["adc_bits"] for lab in ds.labels]
    assert bits == [8, 12, 16]
    for lab in ds.labels:
        f, d = read_image(deep / lab["frame"]), read_image(deep / lab["dark"])
        want = np.uint8 if lab["sensor"]["adc_bits"] == 8 else np.uint16
        assert f.dtype == d.dtype == want
        assert f.max() <= 2 ** lab["sensor"]["adc_bits"] - 1
    assert read_image(deep / ds.labels[2]["frame"]).max() > 4095  # 16-bit counts, not 12
    # a dark frame written at the wrong depth: `dataset check` names it, from the PNG header
    bad = tmp_path / "bad"
    shutil.copytree(deep, bad)
    dark = bad / ds.labels[1]["dark"]
    cv2.imwrite(str(dark), (cv2.imread(str(dark), cv2.IMREAD_UNCHANGED) // 16).astype(np.uint8))
    code, _, err = cli("dataset", "check", bad)
    assert code == 2 and err.count("\n") == 1 and str(dark) in err and "8-bit PNG" in err and "12-bit ADC" in err


def test_the_evaluations_loader_refuses_a_dark_of_another_depth(deep, tmp_path):
    """Past `dataset check` (a JPEG dark has no PNG header to read), the loader compares the
    decoded frame and dark and names the dark frame."""
    from stcvision.calibration.profiles import default_profile
    from stcvision.datasets import open_dataset
    from stcvision.evaluate import evaluate_frames

    bad = tmp_path / "bad"
    shutil.copytree(deep, bad)
    labels = [json.loads(s) for s in (bad / "labels.jsonl").read_text().splitlines()]
    dark = bad / "dark" / "cooled-2s.jpg"
    cv2.imwrite(str(dark), np.zeros((480, 640, 3), np.uint8))
    labels[2]["dark"] = "dark/cooled-2s.jpg"
    (bad / "labels.jsonl").write_text("".join(json.dumps(lab) + "\n" for lab in labels))
    ds = open_dataset(bad)
    with pytest.raises(BadInputError, match=f"dark frame {dark} is 8-bit but the frame .* is 16-bit"):
        evaluate_frames(ds, [2], default_profile=default_profile())


def test_calibrate_dark_refuses_a_mix_of_depths(tmp_path, cli):
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    write_image(a, np.full((48, 64, 3), 2056, np.uint16))
    write_image(b, np.full((48, 64, 3), 8, np.uint8))
    code, _, err = cli("calibrate", "dark", a, b, "--out", tmp_path / "d.png")
    assert code == 2 and err.count("\n") == 1 and f"dark frame {b} is 8-bit" in err and "16-bit" in err
    assert not (tmp_path / "d.png").exists()
