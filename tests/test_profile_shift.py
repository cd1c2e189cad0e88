"""Profile shift (ISO 21771 / DIN 3960) in the pair geometry and the mesh stiffness.

Oracles:

1. ISO 21771 closed forms: ``inv(alpha_w) = inv(alpha) + 2 (x1 + x2) tan(alpha) / (z1 + z2)``,
   ``a_w = a cos(alpha) / cos(alpha_w)``, tip clearance ``a_w - r_a1 - r_f2 = c* m`` with the tip alteration
   ``k* m = a_w - a - (x1 + x2) m``, reference tooth thickness ``s = m (pi/2 + 2 x tan(alpha))``, contact ratio
   ``(sqrt(r_a1^2 - r_b1^2) + sqrt(r_a2^2 - r_b2^2) - a_w sin(alpha_w)) / p_b``, undercut limit
   ``2 (h_a* - x) / sin^2(alpha)``.
2. Published worked examples: KHK's profile-shifted spur pair (m 3 mm, 12 + 24 teeth, x 0.6 + 0.36) and an
   ISO 21771:2007 helical pair checked in its transverse section (31 + 30 teeth, a_w = 116.5 mm).
3. ISO 6336-1's stiffness band for the 17-tooth shifted pinion, and invariants: a V-zero pair keeps the standard
   centre distance exactly, an unshifted pair is bit-identical to the pair without the new fields.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from gearctl import GearPair, InputError, load_model, model_names, pair_geometry
from gearctl.geometry import (
    inverse_involute,
    involute,
    minimum_profile_shift,
    operating_pressure_angle,
    undercut_limit,
)
from gearctl.stiffness import COMPONENTS, mesh_stiffness, mesh_stiffness_at, tooth_deflections

DEG = math.pi / 180.0
STEEL = dict(face_width=0.01, backlash=1e-4, young_modulus=2.07e11, poisson_ratio=0.3, density=7850.0)


def steel_pair(teeth1: int, teeth2: int, x1: float = 0.0, x2: float = 0.0, module: float = 1e-3,
               pressure_angle: float = 20 * DEG, **kw: float) -> GearPair:
    return GearPair(teeth1=teeth1, teeth2=teeth2, module=module, pressure_angle=pressure_angle, x1=x1, x2=x2,
                    **{**STEEL, **kw})


# --- inverse involute -----------------------------------------------------------------------------------


def test_inverse_involute_round_trip() -> None:
    for phi in np.linspace(0.5, 70.0, 140) * DEG:
        # tan(phi) - phi cancels for small angles: inv(phi) carries a relative round-off ~ 3 eps / phi^2, i.e.
        # eps / phi^2 in phi (2e-12 at 0.5 deg); rtol 1e-15 / phi^2 (at least 1e-14) covers that
        assert_allclose(inverse_involute(involute(phi)), phi, rtol=max(1e-14, 1e-15 / phi**2))
    # involute-function table (Machinery's Handbook): inv(25 deg) = 0.029975; rtol 2e-5 = the table's rounding
    assert_allclose(inverse_involute(0.029975), 25 * DEG, rtol=2e-5)
    for bad in (0.0, -1e-3, math.nan, math.inf):
        with pytest.raises(ValueError):
            inverse_involute(bad)


def test_operating_pressure_angle_is_exact_without_a_shift_sum() -> None:
    phi = 20 * DEG
    assert operating_pressure_angle(phi, 17, 40) == phi
    assert operating_pressure_angle(phi, 17, 40, 0.3, -0.3) == phi  # V-zero pair: no round-off at all


# --- (a) ISO 21771 closed forms on seeded random shifted pairs ---------------------------------------------


@st.composite
def shifted_pairs(draw: st.DrawFn) -> GearPair:
    """Valid profile-shifted steel pairs: 17-27 deg, 8-120 teeth, each shift between its undercut limit and +1."""
    phi = draw(st.floats(17.0, 27.0)) * DEG
    ha = draw(st.floats(0.8, 1.2))
    teeth1, teeth2 = draw(st.integers(8, 120)), draw(st.integers(8, 120))
    x1 = draw(st.floats(max(-1.0, minimum_profile_shift(teeth1, phi, ha)), 1.0))
    x2 = draw(st.floats(max(-1.0, minimum_profile_shift(teeth2, phi, ha)), 1.0))
    try:
        return steel_pair(teeth1, teeth2, x1, x2, module=draw(st.floats(0.3e-3, 4e-3)), pressure_angle=phi,
                          addendum_coefficient=ha, dedendum_coefficient=ha + 0.25)
    except InputError as exc:  # the pair-level checks may refuse a draw; nothing else may
        assume(not any(s in str(exc) for s in ("interference", "pointed", "contact ratio", "undercut")))
        raise


RANDOM = settings(derandomize=True, database=None, max_examples=60, deadline=None)


@RANDOM
@given(shifted_pairs())
def test_iso_21771_closed_forms(pair: GearPair) -> None:
    g = pair_geometry(pair)
    m, phi = pair.module, pair.pressure_angle
    z1, z2, x1, x2 = pair.teeth1, pair.teeth2, pair.x1, pair.x2
    ha, hf = pair.addendum_coefficient, pair.dedendum_coefficient
    aw = g.operating_pressure_angle
    # ISO 21771 zero-backlash meshing condition; rtol 1e-12 (Newton to round-off, inv is well conditioned)
    assert_allclose(involute(aw), involute(phi) + 2 * (x1 + x2) * math.tan(phi) / (z1 + z2), rtol=1e-12)
    a = m * (z1 + z2) / 2
    # rtol 1e-13 throughout: closed forms, a few floating-point operations each
    assert_allclose(g.reference_centre_distance, a, rtol=1e-13)
    assert_allclose(g.centre_distance, a * math.cos(phi) / math.cos(aw), rtol=1e-13)
    assert_allclose(sum(g.operating_pitch_radius), g.centre_distance, rtol=1e-13)
    assert_allclose(g.operating_pitch_radius, np.array(g.base_radius) / math.cos(aw), rtol=1e-13)
    assert g.profile_shift == (x1, x2)
    # tip alteration k* (ISO 21771): both tips keep the clearance (h_f* - h_a*) m to the mating root circle;
    # atol 1e-12 m (differences of radii ~ 0.1 m)
    for j in range(2):
        clearance = g.centre_distance - g.addendum_radius[j] - g.dedendum_radius[1 - j]
        assert_allclose(clearance, (hf - ha) * m, rtol=0, atol=1e-12)
    k = (g.centre_distance - a) / m - (x1 + x2)
    assert k <= 1e-12  # never lengthens a tip
    assert_allclose(g.addendum_radius, (m * z1 / 2 + (ha + x1 + k) * m, m * z2 / 2 + (ha + x2 + k) * m), rtol=1e-13)
    assert_allclose(g.dedendum_radius, (m * z1 / 2 - (hf - x1) * m, m * z2 / 2 - (hf - x2) * m), rtol=1e-13)
    # reference-circle tooth thickness
    assert_allclose(g.tooth_thickness_reference, (m * (math.pi / 2 + 2 * x1 * math.tan(phi)),
                                                  m * (math.pi / 2 + 2 * x2 * math.tan(phi))), rtol=1e-13)
    # Figure 4 on the operating line of action: AB = a_w sin(alpha_w), P where the operating pitch circles touch
    assert_allclose(g.AB, g.centre_distance * math.sin(aw), rtol=1e-13)
    assert_allclose(g.AP, g.operating_pitch_radius[0] * math.sin(aw), rtol=1e-13)
    # textbook (DIN 3960) transverse contact ratio
    rb, ra = g.base_radius, g.addendum_radius
    eps = (math.sqrt(ra[0] ** 2 - rb[0] ** 2) + math.sqrt(ra[1] ** 2 - rb[1] ** 2)
           - g.centre_distance * math.sin(aw)) / (math.pi * m * math.cos(phi))
    assert_allclose(g.contact_ratio, eps, rtol=1e-12)
    assert g.contact_ratio >= 1.0
    assert 0.0 <= g.AC < g.AD <= g.AB
    # eq 26 at the base and tip circles, started from the reference circle (r, s, alpha)
    for j in range(2):
        r, s = g.pitch_radius[j], g.tooth_thickness_reference[j]

        def t_at(radius: float, r: float = r, s: float = s, rbj: float = rb[j]) -> float:
            return radius * (s / r + 2 * (involute(phi) - involute(math.acos(rbj / radius))))

        assert_allclose(g.tooth_thickness_base[j], t_at(rb[j]), rtol=1e-12)
        assert_allclose(g.tooth_thickness_addendum[j], t_at(ra[j]), rtol=1e-12)
        assert g.tooth_thickness_addendum[j] > 0.0  # no pointed tip is accepted


# --- (a) published worked examples ----------------------------------------------------------------------


def test_khk_worked_example() -> None:
    """KHK Gear Technical Reference, profile-shifted spur gears (x1 + x2 > 0) calculation example.

    Data: m = 3 mm, alpha = 20 deg, z = 12 / 24, x = 0.6 / 0.36, standard full-depth rack (h_a* 1, h_f* 1.25).
    Numbers as tabulated at http://bolsover.com/utilitiesforalibre/profile-shifted-external-spur-gears.html
    (which reproduces KHK's example and evaluates it from the working centre distance rounded to 56.500 mm):
    inv(alpha) 0.014904, inv(alpha_w) 0.034317, alpha_w 26.0888 deg, centre distance increment factor y 0.83333,
    base diameters 33.8289 / 67.6579, working pitch diameters 37.667 / 75.333, addenda 4.420 / 3.700,
    outside diameters 44.840 / 79.400, root diameters 32.100 / 66.660, contact ratio 1.202 (also
    bolsover/GearCalculator, UnitTests/GearTests/ProfileShiftExtPairTests.cs: 26.08883 deg, 1.20211).
    KHK's own table, from the shifts, prints alpha_w = 26.0886 deg and a_x = 56.4999 mm.
    """
    m = 3e-3
    pair = steel_pair(12, 24, 0.6, 0.36, module=m)
    g = pair_geometry(pair)
    mm = 1e3
    # inv(20 deg) to the 6 printed decimals
    assert_allclose(involute(pair.pressure_angle), 0.014904, atol=5e-7)
    # The page starts from a_w = 56.500 mm, 0.13 um more than the shifts give (KHK: 56.4999): that moves alpha_w
    # by cot(alpha_w) da / a = 2.7e-4 deg, y by 4e-5 and d_w by 4e-4 mm. Tolerances: that offset plus half a unit
    # in the last printed digit.
    assert_allclose(g.centre_distance * mm, 56.500, atol=5e-4)
    assert_allclose(g.centre_distance * mm, 56.4999, atol=5e-5)  # KHK's own a_x, 4 decimals
    assert_allclose(math.degrees(g.operating_pressure_angle), 26.0888, atol=3.5e-4)
    assert_allclose(math.degrees(g.operating_pressure_angle), 26.0886, atol=5e-5)  # KHK's own, from the shifts
    assert_allclose(involute(g.operating_pressure_angle), 0.034317, atol=1.5e-6)
    assert_allclose((g.centre_distance - g.reference_centre_distance) / m, 0.83333, atol=1e-4)
    assert_allclose(np.array(g.base_radius) * 2 * mm, (33.8289, 67.6579), atol=5e-5)
    assert_allclose(np.array(g.operating_pitch_radius) * 2 * mm, (37.667, 75.333), atol=1e-3)
    # addenda with KHK's tip shortening h_a1 = (1 + y - x2) m, h_a2 = (1 + y - x1) m
    assert_allclose((np.array(g.addendum_radius) - g.pitch_radius) * mm, (4.420, 3.700), atol=5e-4)
    assert_allclose(np.array(g.addendum_radius) * 2 * mm, (44.840, 79.400), atol=1e-3)
    assert_allclose(np.array(g.dedendum_radius) * 2 * mm, (32.100, 66.660), atol=5e-4)
    assert_allclose(g.contact_ratio, 1.202, atol=5e-4)


def test_iso_21771_worked_example_transverse_section() -> None:
    """ISO 21771:2007 example (eq 62 of the standard), as worked in 'Gear Generating Profile Shift Calculations'
    (scribd document 376176518): z = 31 / 30, m_n = 3.5 mm, alpha_n = 20 deg, working centre distance 116.5 mm;
    printed: reference centre distance 114.3447280708 mm, transverse pressure angle 21.2990642859 deg, working
    transverse pressure angle 23.8707609654 deg, inv 0.0259052382 and 0.0181260949, zero-backlash shift sum
    x1 + x2 = 0.651877131252, x1 = 0.291.

    The transverse section of a helical pair is a spur pair with module m_t = 2 a / (z1 + z2), pressure angle
    alpha_t and radial shift x m_n, i.e. transverse coefficient x m_n / m_t (then x_t tan(alpha_t) = x tan(alpha_n),
    the same meshing condition). gearctl's spur geometry must give the printed working angle and centre distance.
    """
    a = 114.3447280708e-3
    m_t = 2 * a / 61
    to_transverse = 3.5e-3 / m_t  # m_n / m_t = cos(beta)
    x1 = 0.291 * to_transverse
    x2 = 0.651877131252 * to_transverse - x1
    pair = steel_pair(31, 30, x1, x2, module=m_t, pressure_angle=21.2990642859 * DEG)
    g = pair_geometry(pair)
    # rtol 2e-10: the example prints 10-12 significant digits
    assert_allclose(involute(pair.pressure_angle), 0.0181260949, rtol=2e-9)
    assert_allclose(involute(g.operating_pressure_angle), 0.0259052382, rtol=2e-9)
    assert_allclose(math.degrees(g.operating_pressure_angle), 23.8707609654, rtol=2e-10)
    assert_allclose(g.centre_distance, 116.5e-3, rtol=2e-10)
    assert_allclose(g.reference_centre_distance, a, rtol=1e-13)


# --- (b) undercut limit with profile shift --------------------------------------------------------------


def test_undercut_limit_with_shift_closed_form() -> None:
    phi = 20 * DEG
    # rtol 1e-13: closed form 2 (h_a* - x) / sin^2(alpha)
    assert_allclose(undercut_limit(phi, 1.0, 0.3), 2 * 0.7 / math.sin(phi) ** 2, rtol=1e-13)
    assert undercut_limit(phi, 0.8) == undercut_limit(phi, 0.8, 0.0)  # the old positional signature
    assert_allclose(minimum_profile_shift(12, phi), 1 - 6 * math.sin(phi) ** 2, rtol=1e-13)
    for z in (5, 12, 17, 30):  # the two are inverses of each other
        assert_allclose(undercut_limit(phi, 1.0, minimum_profile_shift(z, phi)), z, rtol=1e-13)


@pytest.mark.parametrize(("teeth", "x_min"), [
    (17, 0.005689),  # 1 - 17 sin^2(20 deg) / 2 = 0.0056889: "17 teeth need a hair of positive shift"
    (12, 0.298133),  # 1 - 6 sin^2(20 deg) = 0.2981333
])
def test_undercut_with_shift(teeth: int, x_min: float) -> None:
    # x_min from the closed form, to 6 decimals; the pair's acceptance flips between x_min -/+ 1e-5
    assert_allclose(minimum_profile_shift(teeth, 20 * DEG), x_min, atol=5e-7)
    with pytest.raises(InputError, match="teeth1") as info:
        steel_pair(teeth, 40, x_min - 1e-5)
    message = str(info.value)
    assert info.value.field == "teeth1"
    assert message.startswith(f"teeth1 = {teeth} is below the undercut limit")
    assert "expected a whole number >= " in message and "\n" not in message
    suggested = float(re.search(r"a profile shift x1 >= ([0-9.]+)", message).group(1))
    assert x_min <= suggested <= x_min + 1e-4  # rounded up to 4 decimals
    steel_pair(teeth, 40, suggested)  # the suggested shift is accepted
    steel_pair(teeth, 40, x_min + 1e-5)
    with pytest.raises(InputError, match="teeth2.*profile shift x2 >= "):
        steel_pair(40, teeth, 0.0, x_min - 1e-5)


def test_unshifted_undercut_message_keeps_its_shape(shing) -> None:
    with pytest.raises(InputError) as info:
        dataclasses.replace(shing.pair, teeth1=12)
    assert str(info.value) == (
        "teeth1 = 12 is below the undercut limit for a pressure angle of 20 deg and addendum 1: expected a whole "
        "number >= 18 or a profile shift x1 >= 0.2982 (the tooth model does not cover undercut teeth)"
    )


# --- (c) a 17-tooth pinion with positive shift ----------------------------------------------------------


@pytest.mark.parametrize("x2", [0.0, -0.3])
def test_17_tooth_pinion_with_positive_shift(x2: float) -> None:
    """A 17-tooth pinion (below the 17.1-tooth limit unshifted) with x1 = +0.3 against 40 teeth.

    ISO 6336-1 (method B) puts the single-pair stiffness c' of solid steel spur gears near 14 N/(mm um) and the
    mesh stiffness c_gamma = c' (0.75 eps + 0.25) near 20 N/(mm um) for eps ~ 1.5: the largest single-pair
    stiffness along the path must fall in 8-20, the mean over the mesh cycle in the band tests/test_stiffness.py
    uses for c_gamma, 8-30 N/(mm um).
    """
    with pytest.raises(InputError, match="teeth1"):
        steel_pair(17, 40)
    pair = steel_pair(17, 40, 0.3, x2)
    ms = mesh_stiffness(pair, points=2001)
    td = tooth_deflections(pair)
    per_width = 1e-9 / pair.face_width  # N/m -> N/(mm um) per face width
    single = td.pair_stiffness.max() * per_width
    assert 8.0 <= single <= 20.0, single
    assert 8.0 <= ms.mean * per_width <= 30.0, ms.mean * per_width
    # a 0.3 m shift changes the mesh stiffness little: within 10 % of the unshifted 18-tooth neighbour
    neighbour = mesh_stiffness(steel_pair(18, 40)).mean
    assert_allclose(ms.mean, neighbour, rtol=0.10)
    # the mesh cycle: one or two pairs in contact (contact ratio ~1.5), K > 0, jumps where a pair enters/leaves
    g = pair_geometry(pair)
    assert 1.0 < g.contact_ratio < 2.0
    assert set(np.unique(ms.teeth_in_contact).tolist()) == {1, 2}
    assert np.all(ms.K > 0) and ms.min <= ms.mean <= ms.max
    assert ms.K[ms.teeth_in_contact == 2].min() > ms.K[ms.teeth_in_contact == 1].max()


def test_mesh_stiffness_of_a_shifted_pair_is_assembled_from_its_tooth_pairs() -> None:
    """Eq 21 on a shifted pair: in the single-contact zone K is the pair stiffness of tooth_deflections."""
    pair = steel_pair(17, 40, 0.3, 0.0)
    g = pair_geometry(pair)
    rb1 = g.base_radius[0]
    th = np.linspace(g.AF - g.AC, g.AE - g.AC, 7)[1:-1] / rb1  # strictly inside F -> E (one pair)
    # rtol 1e-12: the same sums in another order
    assert_allclose(mesh_stiffness_at(pair, th, g), tooth_deflections(pair, th).pair_stiffness, rtol=1e-12)
    td = tooth_deflections(pair, points=101)
    for d in (td.gear1, td.gear2):
        assert_allclose(d["total"], sum(d[c] for c in COMPONENTS), rtol=1e-12)  # eq 13
        for c in ("bending_cos", "shear", "foundation", "hertz"):
            assert np.all(d[c] > 0), c
    # Figures 8-9: the contact point climbs gear 1's tooth and descends gear 2's
    assert np.all(np.diff(td.gear1["total"]) > 0) and np.all(np.diff(td.gear2["total"]) < 0)


def test_positive_shift_stiffens_the_tooth_it_thickens() -> None:
    """At the pitch point, a pinion tooth with x1 = +0.3 (thicker root) is stiffer, the x2 = -0.3 gear tooth softer."""
    plain, shifted = steel_pair(20, 80), steel_pair(20, 80, 0.3, -0.3)
    k = []
    for pair in (plain, shifted):
        g = pair_geometry(pair)
        td = tooth_deflections(pair, [(g.AP - g.AC) / g.base_radius[0]])
        k.append((td.stiffness1[0], td.stiffness2[0]))
    assert k[1][0] > k[0][0]
    assert k[1][1] < k[0][1]


# --- (d) V-zero pairs -----------------------------------------------------------------------------------


@pytest.mark.parametrize(("teeth1", "teeth2", "x1"), [(17, 40, 0.3), (12, 80, 0.5), (30, 80, -0.2)])
def test_v_zero_pair_keeps_the_standard_centre_distance_exactly(teeth1: int, teeth2: int, x1: float) -> None:
    pair = steel_pair(teeth1, teeth2, x1, -x1)
    g = pair_geometry(pair)
    m, phi = pair.module, pair.pressure_angle
    # exact: V-zero ("S0") pairs mesh at the standard centre distance and pressure angle
    assert g.operating_pressure_angle == phi
    assert g.centre_distance == g.reference_centre_distance == m * (teeth1 + teeth2) / 2
    assert g.operating_pitch_radius == g.pitch_radius
    # the standard line of action; rtol 1e-15 (the same closed forms)
    assert_allclose(g.AB, g.reference_centre_distance * math.sin(phi), rtol=1e-15)
    assert_allclose(g.AP, g.pitch_radius[0] * math.sin(phi), rtol=1e-15)
    # no tip shortening: tips and roots move by exactly +-x m from the standard ones; rtol 1e-15
    r = np.array(g.pitch_radius)
    assert_allclose(g.addendum_radius, r + (1.0 + np.array([x1, -x1])) * m, rtol=1e-15)
    assert_allclose(g.dedendum_radius, r - (1.25 - np.array([x1, -x1])) * m, rtol=1e-15)


# --- (e) rejected shifts --------------------------------------------------------------------------------


@pytest.mark.parametrize(("kw", "field", "words"), [
    # pointed tip: 12 teeth with x = +1 (V-zero against 80 teeth): s_a = -0.18 m (eq 28)
    (dict(teeth1=12, teeth2=80, x1=1.0, x2=-1.0), "x1", "pointed"),
    (dict(teeth1=80, teeth2=12, x1=-1.0, x2=1.0), "x2", "pointed"),
    # contact ratio 0.936: 12 + 12 teeth with x = 0.8 + 0.8 (alpha_w = 30.3 deg, tips shortened by 0.19 m)
    (dict(teeth1=12, teeth2=12, x1=0.8, x2=0.8), "x1", "contact ratio"),
    # x1 = 1.2 > h_a*: the pinion's generated involute starts above its reference circle and the 24-tooth tip
    # meets the pinion in its fillet
    (dict(teeth1=12, teeth2=24, x1=1.2), "x1", "interference"),
    # inv(alpha) + 2 (x1 + x2) tan(alpha) / 70 = 0.0149 - 0.0208 < 0: no operating pressure angle
    (dict(teeth1=35, teeth2=35, x1=-1.0, x2=-1.0), "x1", "operating pressure angle"),
    # out of the declared ranges
    (dict(teeth1=20, teeth2=40, x1=2.0), "x1", "out of range"),
    (dict(teeth1=20, teeth2=40, x2=-1.5), "x2", "out of range"),
])
def test_bad_shift_is_rejected_naming_the_field(kw: dict[str, float], field: str, words: str) -> None:
    with pytest.raises(InputError, match=field) as info:
        steel_pair(**kw)
    message = str(info.value)
    assert info.value.field == field
    assert message.startswith(f"{field} = {kw[field]:g}")
    assert words in message and "\n" not in message


def test_pointed_tip_message_states_the_tip_thickness() -> None:
    with pytest.raises(InputError) as info:
        steel_pair(12, 80, 1.0, -1.0)
    # eq 28 for the 12-tooth pinion: s_a = -0.18333 m with m = 1 mm
    assert "-0.1833 mm" in str(info.value)


# --- (f) the unshifted pair is bit-identical ------------------------------------------------------------


@pytest.mark.parametrize("name", [n for n in model_names() if not any(
    s.pair.x1 or s.pair.x2 for s in load_model(n).stages)])
def test_unshifted_catalog_pairs_are_bit_identical(name: str) -> None:
    pair = load_model(name).pair
    explicit = dataclasses.replace(pair, x1=0.0, x2=0.0)
    g, ge = pair_geometry(pair), pair_geometry(explicit)
    for f in dataclasses.fields(g):
        assert getattr(g, f.name) == getattr(ge, f.name), f.name
    assert g.profile_shift == (0.0, 0.0)
    # no round-off anywhere: alpha_w is the nominal angle, a_w the standard centre distance, s_j = pi m / 2
    assert g.operating_pressure_angle == pair.pressure_angle
    assert g.centre_distance == g.reference_centre_distance
    assert g.operating_pitch_radius == g.pitch_radius
    assert g.tooth_thickness_reference == (g.tooth_thickness_pitch, g.tooth_thickness_pitch)
    # the closed forms of tests/test_geometry.py: AB = a sin(phi), textbook contact ratio; rtol 1e-12
    phi, m = pair.pressure_angle, pair.module
    a = m * (pair.teeth1 + pair.teeth2) / 2
    assert_allclose(g.AB, a * math.sin(phi), rtol=1e-12)
    rb, ra = g.base_radius, g.addendum_radius
    eps = (math.sqrt(ra[0] ** 2 - rb[0] ** 2) + math.sqrt(ra[1] ** 2 - rb[1] ** 2) - a * math.sin(phi)) / (
        math.pi * m * math.cos(phi))
    assert_allclose(g.contact_ratio, eps, rtol=1e-12)
    assert_allclose(g.addendum_radius, np.array(g.pitch_radius) + pair.addendum_coefficient * m, rtol=1e-12)
    ms, mse = mesh_stiffness(pair, points=101), mesh_stiffness(explicit, points=101)
    assert ms.mean == mse.mean and np.array_equal(ms.K, mse.K) and np.array_equal(ms.harmonics, mse.harmonics)


def test_report_pair_numbers_unchanged(shing) -> None:
    g = pair_geometry(shing.pair)
    # TR 93-28 section 3.2: contact ratio 1.69129 (atol: half a unit in the last printed digit)
    assert_allclose(g.contact_ratio, 1.69129, rtol=0, atol=5e-6)
    # Table 1 mean 1.3868e8 N/m; gearctl's documented reading gives 1.3854e8 (-0.10 %), see mesh_stiffness Notes
    assert_allclose(mesh_stiffness(shing.pair).mean, 1.3868e8, rtol=1.5e-3)


def test_a_shift_refused_names_the_range_that_passes() -> None:
    """A reviewer's 17-tooth CNC pinion with x1 = 1.4 is refused for interference; the message gives the largest
    shift that passes with the other keys as given (1.0613, found by bisection on the whole validation, rounded
    towards the passing side): that value is accepted, the next 1e-4 refused."""
    base = dict(teeth1=17, teeth2=119, module=0.004, pressure_angle=math.radians(20.0), face_width=0.03,
                backlash=5e-6, young_modulus=2.07e11, poisson_ratio=0.3, density=7850.0)
    with pytest.raises(InputError, match="interference") as err:
        GearPair(**base, x1=1.4)
    assert err.value.field == "x1"
    limit = float(re.search(r"with the other keys as given: at most ([0-9.]+)\)", str(err.value)).group(1))
    assert limit == pytest.approx(1.0613, abs=1e-4)
    GearPair(**base, x1=limit)
    with pytest.raises(InputError):
        GearPair(**base, x1=limit + 1e-4)


def test_info_json_gives_the_shifted_reference_thickness() -> None:
    """``info --json`` gave a shifted gear's tooth thickness only as ``pitch`` = pi m / 2, the unshifted value
    (1.571 mm for a 12-tooth pinion with x = 1.0, whose reference thickness is 2.299 mm; review hA); it now gives
    each gear's reference thickness m (pi/2 + 2 x tan(alpha)) too."""
    from gearctl.summary import model_summary

    model = load_model("pinion17_shifted_shing1993")
    pair = model.stages[0].pair
    info = model_summary(model)
    m, phi = pair.module, pair.pressure_angle
    assert_allclose(info["tooth_thickness"]["pitch"], math.pi * m / 2, rtol=1e-15)
    assert_allclose(info["tooth_thickness"]["reference"],
                    [m * (math.pi / 2 + 2 * x * math.tan(phi)) for x in (pair.x1, pair.x2)], rtol=1e-12)
    assert info["tooth_thickness"]["reference"][0] > info["tooth_thickness"]["pitch"]  # x1 = +0.3 thickens it
