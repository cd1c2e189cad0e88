"""What ``linearize_modes`` gives on the three plant kinds, as README and its Notes say."""

from __future__ import annotations

import math

import numpy as np

import gearctl


def test_linear_models_per_plant_kind() -> None:
    model = gearctl.load_model("shing1993_servo")
    kinds = ("improved", "tvms", "yang-sun")
    modes = {kind: gearctl.linearize_modes(gearctl.build_plant(model, kind)) for kind in kinds}
    # tvms: the mean stiffness, the improved plant's models exactly
    np.testing.assert_array_equal(modes["tvms"].contact.A, modes["improved"].contact.A)
    # yang-sun: the Hertz stiffness of eq 39 with the eq 38 damping c (independent two-inertia figures)
    p = gearctl.build_plant(model, "yang-sun")
    k_hertz = gearctl.yang_sun_stiffness(model.pair)
    assert p.k == k_hertz
    wn = math.sqrt(k_hertz * (p.rb1**2 / p.J1 + p.rb2**2 / p.J2))
    np.testing.assert_allclose(modes["yang-sun"].mesh.natural_frequency, wn, rtol=1e-3)
    assert round(modes["yang-sun"].mesh.natural_frequency_hz) == 9911  # the README's figure
    c = gearctl.build_plant(model).c
    zeta = c / (2 * math.sqrt(k_hertz * p.m_eq))
    np.testing.assert_allclose(modes["yang-sun"].mesh.damping_ratio, zeta, rtol=0.01)
