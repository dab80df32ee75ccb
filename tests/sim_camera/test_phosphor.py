"""The afterglow law and the phosphor layer."""

import numpy as np
import pytest

from stcvision.errors import BadInputError
from stcvision.sim_camera.phosphor import LED_OFFSETS_M, MARK_INSET_M, AfterglowLaw, PhosphorLayer, mark_dots_m


def test_afterglow_law_values_and_shape():
    law = AfterglowLaw()
    l0 = law.luminance_cd_m2(0.0, charge_s=3.0)
    assert l0 == pytest.approx(law.l_sat_cd_m2 * (1 - np.exp(-3.0 / law.fill_s)))
    # power-law tail: ratio 10 min -> 60 min matches the ISO 17398 classes' ~7.1
    ratio = law.luminance_cd_m2(600.0) / law.luminance_cd_m2(3600.0)
    assert 6.0 < ratio < 8.0
    # at tau the luminance has fallen by 2**n
    assert law.luminance_cd_m2(law.tau_s) == pytest.approx(l0 / 2**law.n)
    ages = np.linspace(0, 3600, 200)
    assert np.all(np.diff(law.luminance_cd_m2(ages)) < 0)
    # longer charge -> brighter, saturating
    assert law.initial_cd_m2(1.0) < law.initial_cd_m2(3.0) < law.initial_cd_m2(30.0) <= law.l_sat_cd_m2
    # inverse
    assert law.age_at_luminance_s(law.luminance_cd_m2(77.0)) == pytest.approx(77.0)
    # still charging: no glow yet
    assert law.luminance_cd_m2(-1.0) == 0.0


def test_eye_sees_a_dot_after_ten_minutes():
    # DIN 67510 perception limit of the dark-adapted eye: 0.3 mcd/m^2 (ant-like STC paper: "could be
    # still seen by humans until after 10 minutes")
    assert AfterglowLaw().luminance_cd_m2(600.0, 3.0) > 0.3e-3


def test_bad_law_parameters():
    with pytest.raises(BadInputError, match="tau_s"):
        AfterglowLaw(tau_s=0)


def test_layer_ages_and_query():
    layer = PhosphorLayer()
    layer.charge([[0.0, 0.0], [1.0, 0.0]], t_start_s=10.0, duration_s=3.0)
    assert layer.ages_s(20.0).tolist() == [7.0, 7.0]
    lum = layer.query([[0.001, 0.0], [0.5, 0.0]], t_s=20.0)
    assert lum[0] == pytest.approx(layer.law.luminance_cd_m2(7.0, 3.0))
    assert lum[1] == 0.0
    assert layer.luminance_at(11.0).tolist() == [0.0, 0.0]  # still charging


def test_mark_geometry():
    dots = mark_dots_m([1.0, 2.0], (0, -1), 0.16)
    # four dots in a row parallel to the south edge, MARK_INSET_M inside it
    assert np.allclose(dots[:, 1], 2.0 - 0.08 + MARK_INSET_M)
    assert sorted(dots[:, 0] - 1.0) == pytest.approx(sorted(LED_OFFSETS_M))
