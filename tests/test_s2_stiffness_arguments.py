"""The stiffness module's small public functions name a bad argument (InputError) instead of a ZeroDivisionError,
a math domain error, an AttributeError or a silent NaN."""

from __future__ import annotations

import math

import pytest

import gearctl
from gearctl import InputError


@pytest.mark.parametrize(("call", "field"), [
    (lambda: gearctl.equivalent_mass(0.0, 0.0, 0.01, 0.04), "inertia1"),  # was ZeroDivisionError
    (lambda: gearctl.equivalent_mass(-1.0, 1.0, 0.01, 0.04), "inertia1"),  # was a negative mass, 3333 kg
    (lambda: gearctl.equivalent_mass(1.0, 1.0, 0.01, -0.04), "rb2"),
    (lambda: gearctl.damping_coefficient(-1.0, 0.05, 1.0), "k"),  # was ValueError: math domain error
    (lambda: gearctl.damping_coefficient("1e8", 0.05, 1.0), "k"),  # was TypeError
    (lambda: gearctl.damping_coefficient(1e8, -0.05, 1.0), "damping_ratio"),  # was a negative damping
    (lambda: gearctl.damping_coefficient(1e8, 0.05, 0.0), "m_eq"),
    (lambda: gearctl.yang_sun_damping_factor(-1e9, 0.1), "k"),  # was a negative factor
    (lambda: gearctl.yang_sun_damping_factor(1e9, math.nan), "impact_velocity"),  # was nan
    (lambda: gearctl.yang_sun_stiffness(gearctl.load_model("shing1993")), "pair"),  # was AttributeError
    (lambda: gearctl.tooth_deflections(gearctl.load_model("shing1993").pair, [0.0, math.nan]), "theta1"),  # was nan
    (lambda: gearctl.mesh_stiffness_at(gearctl.load_model("shing1993").pair, 0.1, geo=3), "geo"),  # AttributeError
])
def test_a_bad_argument_is_named(call, field) -> None:  # noqa: ANN001
    with pytest.raises(InputError, match=rf"^{field} = ") as err:
        call()
    assert err.value.field == field


def test_good_arguments_keep_their_values() -> None:
    # the checks change nothing: closed forms of the documented formulas
    I1, I2, r1, r2 = 2e-4, 5e-3, 0.0188, 0.0752
    m_eq = gearctl.equivalent_mass(I1, I2, r1, r2)
    assert m_eq == I1 * I2 / (I2 * r1**2 + I1 * r2**2)
    assert gearctl.damping_coefficient(1.4e8, 0.05, m_eq) == 2 * 0.05 * math.sqrt(1.4e8 * m_eq)
    pair = gearctl.load_model("shing1993").pair
    assert gearctl.yang_sun_stiffness(pair) == math.pi * pair.young_modulus * pair.face_width / (
        4 * (1 - pair.poisson_ratio**2))
    # eq 36 at a grazing impact: the 1 mm/s floor, and V_i's sign does not matter
    assert gearctl.yang_sun_damping_factor(1e9, 0.0) == gearctl.yang_sun_damping_factor(1e9, -1e-3)
