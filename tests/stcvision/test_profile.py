"""Calibration profiles: round trip, validation naming the bad field, atomic writes."""

import json
import os

import numpy as np
import pytest

from stcvision.errors import FileExistsRefusedError, ProfileError
from stcvision.profile import Profile


def test_round_trip_and_model_inverse(tmp_path, default_profile):
    path = default_profile.save(tmp_path / "p.json")
    again = Profile.load(path)
    assert again.to_dict() == default_profile.to_dict()
    rng = np.random.default_rng(0)
    r = rng.uniform(0.1, 0.9, 500)
    a = rng.uniform(-np.pi, np.pi, 500)
    xy = np.column_stack([r * np.cos(a), r * np.sin(a)])
    back = again.image_to_robot(again.robot_to_image(xy))
    assert np.abs(back - xy).max() < 1e-4  # the model's own inverse (tabulated) to 0.1 mm
    g = again.robot_to_ground(xy)
    assert np.allclose(again.ground_to_robot(g), xy)


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d.pop("center_px"), "center_px"),
        (lambda d: d.update(rim_radius_px="big"), "rim_radius_px"),
        (lambda d: d.update(rim_radius_px=-3), "rim_radius_px"),
        (lambda d: d.update(image_size_px=[640]), "image_size_px"),
        (lambda d: d.update(theta_poly=[1.0]), "theta_poly"),
        (lambda d: d.update(mirrored="yes"), "mirrored"),
        (lambda d: d.update(schema_version=99), "schema_version"),
        (lambda d: d.pop("schema_version"), "schema_version"),
        (lambda d: d.update(model="fisheye"), "model"),
        (lambda d: d.update(neighbour_corners_px=[[1, 2]] * 11), "neighbour_corners_px"),
        (lambda d: d.update(ellipse_ratio=3.0), "ellipse_ratio"),
        (lambda d: d.update(extra_field_m=1), "extra_field_m"),
    ],
)
def test_bad_profiles_name_the_field(tmp_path, default_profile, edit, field):
    d = default_profile.to_dict()
    edit(d)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(d))
    with pytest.raises(ProfileError, match=field):
        Profile.load(path)


def test_truncated_and_missing_files(tmp_path, default_profile):
    from stcvision.errors import BadInputError

    path = tmp_path / "p.json"
    text = json.dumps(default_profile.to_dict())
    path.write_text(text[: len(text) // 2])
    with pytest.raises(BadInputError, match="not valid JSON"):
        Profile.load(path)
    with pytest.raises(BadInputError, match="does not exist"):
        Profile.load(tmp_path / "nope.json")


def test_save_never_overwrites_silently_and_is_atomic(tmp_path, default_profile, monkeypatch):
    path = default_profile.save(tmp_path / "p.json")
    before = path.read_bytes()
    with pytest.raises(FileExistsRefusedError):
        default_profile.save(path)

    # a crash between writing the temporary file and renaming it leaves the old file intact
    def boom(src, dst):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(KeyboardInterrupt):
        default_profile.replace(rim_radius_px=200.0).save(path, overwrite=True)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["p.json"]  # no temp file left behind


def test_frame_size_is_checked(default_profile):
    with pytest.raises(ProfileError, match="calibrated for 640x480"):
        default_profile.check_frame((240, 320, 3))


def test_killing_a_writer_never_leaves_a_half_written_profile(tmp_path, default_profile):
    """SIGKILL a process that keeps rewriting a profile, at several moments: the file on disk
    is always a whole, valid profile (temp file + fsync + rename)."""
    import signal
    import subprocess
    import sys
    import time

    path = tmp_path / "p.json"
    default_profile.save(path)
    code = (
        "import sys\n"
        "from stcvision.profile import Profile\n"
        "p = Profile.load(sys.argv[1])\n"
        "big = p.replace(provenance={'padding': 'x' * 2_000_000})\n"
        "while True:\n"
        "    big.save(sys.argv[1], overwrite=True)\n"
        "    p.save(sys.argv[1], overwrite=True)\n"
    )
    for delay in (0.3, 0.45, 0.6, 0.8):
        proc = subprocess.Popen([sys.executable, "-c", code, str(path)])
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        Profile.load(path)  # parses and validates: never truncated
