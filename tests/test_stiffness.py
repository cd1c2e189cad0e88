"""Tooth deflections, mesh stiffness and damping (TR 93-28 sections 3-5, eqs 13-21, 36-39, Table 1).

Three kinds of oracle:

1. the report's numbers (Table 1, section 3.2, section 5), each with its tolerance;
2. independent computations: a fine rectangle-rule Fourier integral of ``mesh_stiffness_at`` against
   the Gauss-Legendre integration of ``mesh_stiffness``; eq 21 rebuilt from ``tooth_deflections``;
   the damping of eq 38 written out by hand;
3. invariants on every catalog entry and on seeded random gear pairs (hypothesis, derandomized):
   positive finite stiffness, jumps exactly where the number of teeth in contact changes, the ISO
   6336-1 stiffness band, linearity in the face width.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from gearctl import (
    GearPair,
    InputError,
    build_plant,
    damping_coefficient,
    equivalent_mass,
    load_model,
    mesh_stiffness,
    mesh_stiffness_at,
    model_names,
    pair_geometry,
    tooth_deflections,
    yang_sun_stiffness,
)
from gearctl.geometry import undercut_limit
from gearctl.stiffness import COMPONENTS

DEG = math.pi / 180.0

# Table 1 of TR 93-28 (mesh stiffness of the example pair, N/m)
TABLE1_MEAN, TABLE1_C1, TABLE1_C2 = 1.3868e8, 2.956e7, 1.684e7
# section 5: damping coefficient of the improved model from eq 38, zeta = 0.05
REPORT_C = 237.6651


def rectangle_rule_fourier(pair: GearPair, n_max: int = 2, samples: int = 2**17) -> tuple[float, np.ndarray]:
    """Mean and harmonic magnitudes |c_n| of K over one mesh cycle by the midpoint rule.

    Independent of ``mesh_stiffness``'s Gauss-Legendre segments: uniform midpoints ignore where K
    jumps, so the error is O(jump / samples), ~1e-5 of the mean at 2^17 samples.
    """
    period = 2 * math.pi / pair.teeth1
    th = (np.arange(samples) + 0.5) * period / samples
    K = mesh_stiffness_at(pair, th)
    mean = float(K.mean())
    n = np.arange(1, n_max + 1)[:, None]
    cn = 2.0 * np.mean(K * np.exp(-2j * np.pi * n * th / period), axis=1)
    return mean, np.abs(cn)


# --- 1. the report's numbers ------------------------------------------------------------------------------


def test_table1_mean_and_c2(shing) -> None:
    ms = mesh_stiffness(shing.pair)
    # Table 1 mean 1.3868e8 N/m. gearctl gives -0.10 % (documented readings of eqs 14-18 in
    # stiffness.mesh_stiffness Notes); rtol 2e-3 (0.2 %) leaves room for the report's rounding only.
    assert_allclose(ms.mean, TABLE1_MEAN, rtol=2e-3)
    # Table 1 C2 1.684e7 N/m (-0.07 %); rtol 2e-3 (0.2 %)
    assert_allclose(ms.c2, TABLE1_C2, rtol=2e-3)


def test_table1_c1_does_not_follow_from_the_reports_equations(shing) -> None:
    """Table 1's C1 = 2.956e7 N/m is not what eqs 13-21 give (3.475e7, +17.6 %).

    The same equations reproduce Table 1's mean and C2 within 0.1 %, so the discrepancy is the
    report's: its C1 does not follow from its own equations. gearctl reports what they give. The
    check that the computed C1 is right is the independent rectangle-rule Fourier integral.
    """
    ms = mesh_stiffness(shing.pair)
    assert abs(ms.c1 / TABLE1_C1 - 1) > 0.10
    mean, cn = rectangle_rule_fourier(shing.pair)
    # rtol 1e-3: the midpoint rule's error across the two jumps is ~1e-5 (see rectangle_rule_fourier);
    # the brief's 1 % is met with a factor 10 to spare
    assert_allclose(ms.c1, cn[0], rtol=1e-3)
    assert_allclose(ms.c2, cn[1], rtol=1e-3)
    assert_allclose(ms.mean, mean, rtol=1e-4)
    # and the value is +17.6 % above Table 1: 3.4753e7 N/m (an independent scipy.integrate.quad of eqs 13-21 over
    # the two smooth segments of the cycle gives 3.47533e7, C2 1.68295e7, mean 1.385447e8); rtol 2e-4
    assert_allclose(cn[0], 3.4753e7, rtol=2e-4)
    assert_allclose(ms.c1, 3.4753e7, rtol=2e-4)


def _m_eq_by_hand(I1: float, I2: float) -> float:
    """Equivalent mass of the mesh mode along the line of action, I1 I2 / (I2 rb1^2 + I1 rb2^2) [kg]."""
    rb1, rb2 = 0.02 * math.cos(20 * DEG), 0.08 * math.cos(20 * DEG)
    return I1 * I2 / (I2 * rb1**2 + I1 * rb2**2)


def test_damping_eq38_consistent_form(shing) -> None:
    """Eq 38 in its dimensionally consistent form, c = 2 zeta sqrt(k m_eq), about 269 N s/m.

    Eq 38 as printed has sqrt(k / m_eq), of unit 1/s, not N s/m; gearctl uses sqrt(k m_eq).
    """
    disk = 7800.0 * math.pi * 0.01 / 2  # rho pi f / 2, section 3.2 inertias = disk * r^4
    m_eq = _m_eq_by_hand(disk * 0.02**4, disk * 0.08**4)
    plant = build_plant(shing)
    k = mesh_stiffness(shing.pair).mean
    # rtol 1e-12: the same closed form, from the computed mean stiffness
    assert_allclose(plant.c, 2 * 0.05 * math.sqrt(k * m_eq), rtol=1e-12)
    # with Table 1's k = 1.3868e8 N/m: 269.15 N s/m; the computed k is -0.10 % off, c ~ sqrt(k) so
    # -0.05 %; rtol 1e-3
    assert_allclose(plant.c, 2 * 0.05 * math.sqrt(TABLE1_MEAN * m_eq), rtol=1e-3)
    # gearctl's own helpers agree with the hand formula; rtol 1e-12
    geo = pair_geometry(shing.pair)
    assert_allclose(equivalent_mass(*geo.inertia, *geo.base_radius), m_eq, rtol=1e-12)
    # so the plant's c is NOT the report's 237.6651 (13 % off; see the next test for why)
    assert abs(plant.c / REPORT_C - 1) > 0.10


def test_damping_report_value_from_base_radius_disks() -> None:
    """Section 5's c = 237.6651 N s/m is eq 38 (consistent form) with disks of the *base* radius.

    I ~ r^4, so base-radius disks are the pitch-radius inertias times cos^4(20 deg). With Table 1's
    k = 1.3868e8 N/m this gives the report's value to 2e-7 (asserted: 0.05 %); this is how the report's
    number arises.
    """
    disk = 7800.0 * math.pi * 0.01 / 2
    c4 = math.cos(20 * DEG) ** 4
    m_eq = _m_eq_by_hand(disk * 0.02**4 * c4, disk * 0.08**4 * c4)
    # atol 5e-5: half a unit in the last of the report's 7 printed digits (237.66515 computed, 2e-7 relative)
    assert_allclose(2 * 0.05 * math.sqrt(TABLE1_MEAN * m_eq), REPORT_C, rtol=0, atol=5e-5)
    assert_allclose(damping_coefficient(TABLE1_MEAN, 0.05, m_eq), REPORT_C, rtol=0, atol=5e-5)
    # the other readings do not give it: eq 38 as printed (sqrt(k / m_eq), unit 1/s) 5152.5, pitch-radius disks
    # with pitch radii in m_eq 252.9; so the report took the disks of the base radius
    m_pitch = _m_eq_by_hand(disk * 0.02**4, disk * 0.08**4)
    assert abs(2 * 0.05 * math.sqrt(TABLE1_MEAN / m_pitch) / REPORT_C - 1) > 1.0


def test_yang_sun_stiffness_eq39(shing) -> None:
    # eq 39: k = pi E f / (4 (1 - nu^2)) with E = 2.068e11 Pa, f = 0.01 m, nu = 0.3; rtol 1e-12
    expected = math.pi * 2.068e11 * 0.01 / (4 * (1 - 0.3**2))
    assert_allclose(yang_sun_stiffness(shing.pair), expected, rtol=1e-12)
    # section 5: the improved model's k "is several times smaller" than Yang and Sun's
    assert yang_sun_stiffness(shing.pair) > 3 * mesh_stiffness(shing.pair).mean


# --- 2. eq 21 rebuilt from the tooth deflections ------------------------------------------------------


@pytest.mark.parametrize("name", model_names())
def test_mesh_stiffness_is_pairs_in_parallel(name: str) -> None:
    """Eq 21: K(theta) = sum over the pairs in contact of k1 k2 / (k1 + k2), pairs one base pitch apart."""
    pair = load_model(name).pair
    g = pair_geometry(pair)
    period = g.mesh_period_angle
    path_angle = (g.AD - g.AC) / g.base_radius[0]  # C -> D in gear-1 rotation
    th = np.linspace(0.0, period, 257, endpoint=False)
    expected = np.zeros_like(th)
    for i in range(4):
        t_i = th + i * period  # the i-th following pair is one base pitch further along C -> D
        on = t_i <= path_angle
        expected[on] += tooth_deflections(pair, t_i[on]).pair_stiffness
    # rtol 1e-12: the same sums in another order
    assert_allclose(mesh_stiffness_at(pair, th), expected, rtol=1e-12)
    # K is periodic with the mesh period; rtol 1e-9 (the angle th + 3 period loses ~1e-15 rad)
    assert_allclose(mesh_stiffness_at(pair, th + 3 * period), expected, rtol=1e-9)


# --- 3. physics on the catalog and on random pairs -------------------------------------------------------


def check_mesh_physics(pair: GearPair) -> None:
    """Invariants of K over one mesh cycle that any spur pair must satisfy (see module docstring)."""
    g = pair_geometry(pair)
    ms = mesh_stiffness(pair, points=2001)
    K, n = ms.K, ms.teeth_in_contact
    assert np.all(np.isfinite(K)) and np.all(K > 0)
    assert ms.min <= ms.mean <= ms.max
    assert ms.min <= K.min() and K.max() <= ms.max
    # the number of pairs in contact alternates between floor(eps) and ceil(eps)
    assert set(np.unique(n).tolist()) == {math.floor(g.contact_ratio), math.ceil(g.contact_ratio)}
    # compare each sample with the next one, cyclically (the cycle wraps where a new pair enters at C)
    dK = np.abs(np.roll(K, -1) - K)
    change = np.roll(n, -1) != n
    assert change.sum() == 2  # one pair leaves at D, one enters at C, per mesh cycle
    # a jump of more than 10 % of the mean where a pair enters or leaves ...
    assert np.all(dK[change] > 0.10 * ms.mean), dK[change] / ms.mean
    # ... and continuity elsewhere: < 2 % of the mean between neighbouring samples (2001 per cycle)
    assert np.all(dK[~change] < 0.02 * ms.mean), dK[~change].max() / ms.mean
    # more pairs in contact carry more stiffness
    assert K[n == n.max()].min() > K[n == n.min()].max()
    # linear in the face width: every term of eqs 14-18 is ~1/f. Doubling is exact in binary floating
    # point, so rtol 1e-12
    ms2 = mesh_stiffness(dataclasses.replace(pair, face_width=2 * pair.face_width), points=2001)
    summary = np.array([ms.mean, ms.c1, ms.min, ms.max])
    assert_allclose([ms2.mean, ms2.c1, ms2.min, ms2.max], 2 * summary, rtol=1e-12)
    assert_allclose(ms2.K, 2 * K, rtol=1e-12)
    # the Gauss-Legendre mean agrees with a plain rectangle rule; rtol 1e-4 (midpoint error ~1e-5)
    mean, _ = rectangle_rule_fourier(pair, n_max=1, samples=2**15)
    assert_allclose(ms.mean, mean, rtol=1e-4)


def check_iso_band(pair: GearPair) -> None:
    """Mean mesh stiffness per unit face width in 8-30 N/(mm um).

    ISO 6336-1 (method B): single-pair stiffness c' ~ 14 and mesh stiffness c_gamma ~ 20 N/(mm um) for
    standard steel spur gears; both rise slightly with the number of teeth.
    """
    per_width = mesh_stiffness(pair).mean / pair.face_width * 1e-9  # N/m/m -> N/(mm um)
    assert 8.0 <= per_width <= 30.0, per_width


@pytest.mark.parametrize("name", model_names())
def test_mesh_physics_catalog(name: str) -> None:
    check_mesh_physics(load_model(name).pair)


@pytest.mark.parametrize("name", model_names())
def test_iso_band_catalog(name: str) -> None:
    check_iso_band(load_model(name).pair)


@pytest.mark.parametrize("name", model_names())
def test_teeth_in_contact_catalog(name: str) -> None:
    eps = pair_geometry(load_model(name).pair).contact_ratio
    counts = set(np.unique(mesh_stiffness(load_model(name).pair, points=2001).teeth_in_contact).tolist())
    if name == "liou1992_28x28_hcr":
        assert eps > 2  # the catalog's high-contact-ratio pair
    if eps > 2:
        assert counts == {2, 3}
    else:
        assert counts == {1, 2}


@st.composite
def gear_pairs(draw: st.DrawFn, most_teeth: int = 150) -> GearPair:
    """Valid steel spur pairs: 17-27 deg, module 0.5-6 mm, face 5-50 mm, addendum 0.8-1.2, no undercut."""
    phi = draw(st.floats(17.0, 27.0)) * DEG
    ha = draw(st.floats(0.8, 1.2))
    lowest = math.ceil(undercut_limit(phi, ha) - 1e-9)
    teeth1 = draw(st.integers(lowest, most_teeth))
    teeth2 = draw(st.integers(lowest, most_teeth))
    try:
        return GearPair(
            teeth1=teeth1, teeth2=teeth2, module=draw(st.floats(0.5e-3, 6e-3)), pressure_angle=phi,
            face_width=draw(st.floats(5e-3, 50e-3)), backlash=1e-4, addendum_coefficient=ha,
            dedendum_coefficient=ha + 0.25, young_modulus=2.07e11, poisson_ratio=0.3, density=7850.0,
        )
    except InputError as exc:  # only interference or a contact ratio below 1 may reject a draw
        assume("interference" not in str(exc) and "contact ratio" not in str(exc))
        raise


RANDOM = settings(derandomize=True, database=None, max_examples=40, deadline=None)


@RANDOM
@given(gear_pairs())
def test_mesh_physics_random_pairs(pair: GearPair) -> None:
    check_mesh_physics(pair)


# The report's tooth model (eqs 24-25) starts the beam at the base circle once the dedendum circle lies
# outside it (more than 2 h_f / (1 - cos phi) teeth: 42 at 20 deg, 27 at 25 deg), so for large gears the
# beam is longer than the tooth and the stiffness falls as teeth are added (equal pairs at 20 deg:
# 42 teeth 22.6, 100 teeth 9.3, 150 teeth 6.1 N/(mm um)). gearctl keeps the report's model (Table 1 rests
# on it) and documents the limit in pair_geometry; up to the report's 80 teeth the ISO band holds.
@RANDOM
@given(gear_pairs(most_teeth=80))
def test_iso_band_random_pairs(pair: GearPair) -> None:
    check_iso_band(pair)


def test_large_gears_leave_the_iso_band_as_documented() -> None:
    """The documented limitation: 150 x 150 teeth at 20 deg fall below 8 N/(mm um) (eqs 24-25)."""
    pair = GearPair(teeth1=150, teeth2=150, module=2e-3, pressure_angle=20 * DEG, face_width=0.01, backlash=1e-4,
                    young_modulus=2.07e11, poisson_ratio=0.3, density=7850.0)
    per_width = mesh_stiffness(pair).mean / pair.face_width * 1e-9
    assert per_width < 8.0  # about 6.1


@RANDOM
@given(gear_pairs())
def test_geometry_invariants_random_pairs(pair: GearPair) -> None:
    g = pair_geometry(pair)
    # no interference once both gears are above the undercut limit (same addendum on both)
    assert 0.0 < g.AC < g.AP < g.AD <= g.AB
    assert g.contact_ratio >= 1.0
    # rtol 1e-12: Figure 4 closed forms
    assert_allclose(g.AE, g.AD - g.base_pitch, rtol=1e-12)
    assert_allclose(g.AF, g.AC + g.base_pitch, rtol=1e-12)
    assert_allclose(g.AP, g.base_radius[0] * math.tan(pair.pressure_angle), rtol=1e-12)


# --- 4. tooth deflections (eqs 13-20, Figures 8-10) -------------------------------------------------------


@pytest.mark.parametrize("name", model_names())
def test_tooth_deflection_invariants(name: str) -> None:
    pair = load_model(name).pair
    td = tooth_deflections(pair, points=201)
    E, nu, f = pair.young_modulus, pair.poisson_ratio, pair.face_width
    for d in (td.gear1, td.gear2):
        assert set(d) == {*COMPONENTS, "total"}
        for c in ("bending_cos", "shear", "foundation", "hertz"):
            assert np.all(d[c] > 0), c
        # eq 15 with the sign as printed: the bending by F sin(phi) (the compressive component)
        # comes out negative along the whole path; gearctl keeps the printed sign (documented in
        # stiffness.mesh_stiffness Notes). Its magnitude stays below the total (section 3.2:
        # "insignificant"), so every total is positive.
        assert np.all(d["bending_sin"] < 0)
        assert np.all(np.abs(d["bending_sin"]) < d["total"])
        # eq 13: total = sum of the components; rtol 1e-12
        assert_allclose(d["total"], sum(d[c] for c in COMPONENTS), rtol=1e-12)
        # eq 18: Hertz term constant, 4 (1 - nu^2) / (pi E f); rtol 1e-12
        assert_allclose(d["hertz"], 4 * (1 - nu**2) / (math.pi * E * f), rtol=1e-12)
    # eq 20 and teeth in series (Figure 10); rtol 1e-12
    k1, k2 = 1 / td.gear1["total"], 1 / td.gear2["total"]
    assert_allclose(td.stiffness1, k1, rtol=1e-12)
    assert_allclose(td.stiffness2, k2, rtol=1e-12)
    assert_allclose(td.pair_stiffness, k1 * k2 / (k1 + k2), rtol=1e-12)
    # Figures 8-9: the contact point climbs gear 1's tooth (deflection grows) and descends gear 2's
    assert np.all(np.diff(td.gear1["total"]) > 0)
    assert np.all(np.diff(td.gear2["total"]) < 0)
    # default angles span the path of contact C -> D; rtol 1e-12
    g = pair_geometry(pair)
    assert_allclose(td.theta1[[0, -1]], [0.0, (g.AD - g.AC) / g.base_radius[0]], rtol=1e-12, atol=0)


@pytest.mark.parametrize("name", ["liou1992_28x28_hcr", "servo_2stage_phm09", "detc1992_21x29_25deg"])
def test_the_min_and_max_are_the_curves_not_the_samples(name: str) -> None:
    # they were min(samples, quadrature nodes): liou1992_28x28_hcr's min printed 9.059e+07 or 9.06e+07, and every
    # model's max moved in its 6th digit, with --points; the stiffness command says they do not depend on it
    pair = load_model(name).stages[0].pair
    runs = [mesh_stiffness(pair, points=p) for p in (2, 3, 7, 401, 3001, 100_000)]
    assert len({(ms.min, ms.max) for ms in runs}) == 1
    assert all(runs[0].min <= ms.K.min() and ms.K.max() <= runs[0].max for ms in runs)
