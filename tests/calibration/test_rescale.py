"""A rescaled profile reads a resized frame as the original profile reads the original frame."""

from __future__ import annotations

import json

import numpy as np
import pytest

from stcvision.calibration.rescale import rescale_profile
from stcvision.calibration.rescale_check import compare_rescaled
from stcvision.errors import BadInputError
from stcvision.pipeline import Pipeline, PipelineParams
from stcvision.profile import Profile


@pytest.fixture(scope="module")
def default_profile():
    from stcvision.calibration.profiles import default_profile_path

    return Profile.load(default_profile_path())


def test_the_rescaled_reading_matches_the_original_on_the_smoke_set(smoke):
    """The six smoke frames and their dark frames at half and twice the size: every cell's
    observation (boxes, neighbours' marks and red) as the original's at twice the size and at
    least four of six at half (a dot's window SNR falls there: faint dots drop below the
    threshold), most of the original's dots within 3 mm, and few dots of its own: before the
    pipeline followed the scale, the enlarged frames gave hundreds of noise dots and every one
    was untrusted."""
    r = compare_rescaled(smoke, (0.5, 2.0))
    half, double = r["0.5"], r["2"]
    assert double["same"] == double["frames"] == 6 and double["untrusted"] == 0
    assert half["same"] >= 4 and half["untrusted"] == 0
    assert double["dots_matched_rate"] >= 0.9 and half["dots_matched_rate"] >= 0.8
    assert double["extra"] <= 0.05 * double["dots"] and half["extra"] <= 0.1 * half["dots"]
    assert double["heading_diff_deg_p90"] < 1.0 and half["heading_diff_deg_p90"] < 1.0


def test_the_pipeline_follows_the_profiles_scale(default_profile):
    """The dot window and the mirror-image centroid scale with the profile; ground-view settings
    do not; the noise model of an enlarged frame is the interpolated noise's, larger than
    independent pixels' (a window of interpolated pixels shares their noise)."""
    big = rescale_profile(default_profile, (1280, 960))
    assert big.pixel_scale == 2.0 and big.resampling == "linear"
    assert rescale_profile(big, (640, 480)).resampling == "none"  # back to the calibrated size
    assert rescale_profile(default_profile, (320, 240)).resampling == "area"
    assert rescale_profile(default_profile, (1280, 960), native=True).resampling == "none"
    p = Pipeline(big)
    d0, d = PipelineParams().dots, p.params.dots
    assert d.window_px == 2 * d0.window_px and d.mirror_sigma_px == 2 * d0.mirror_sigma_px
    assert d.blackout_px == d0.blackout_px and d.centroid_px == d0.centroid_px
    inside = p.umap.valid
    ratio = np.median(p.gain_resampled[inside] / p.gain[inside])
    assert 2.0 < ratio < 3.5, ratio  # 2.8: a window of 6 interpolated pixels holds 3 of the camera's
    # the rounding of a resized frame is fresh at every pixel: a frame whose noise is all
    # rounding has the independent pixels' gain
    assert np.allclose(p._gain(0.01, 1), p.gain, rtol=1e-5)
    again = Profile.from_dict(json.loads(json.dumps(big.to_dict())))
    assert again.pixel_scale == 2.0 and again.resampling == "linear"
    assert "pixel_scale" not in default_profile.to_dict()


def test_scales_out_of_range_are_refused(default_profile):
    """A scale under a quarter (the dot window under a pixel) or over four is refused; so is a
    profile file holding one, or an unknown resampling."""
    with pytest.raises(BadInputError, match="calibrated camera's resolution"):
        rescale_profile(default_profile, (120, 90))
    from stcvision.errors import ProfileError

    d = default_profile.to_dict()
    with pytest.raises(ProfileError, match="pixel_scale"):
        Profile.from_dict({**d, "pixel_scale": 10.0})
    with pytest.raises(ProfileError, match="resampling"):
        Profile.from_dict({**d, "resampling": "cubic"})
