"""Involute geometry of a gear pair against closed forms and the report's example (TR 93-28 section 3).

Oracles: textbook involute relations (base circle, base pitch, path of contact, contact ratio written as
``(sqrt(ra1^2-rb1^2) + sqrt(ra2^2-rb2^2) - a sin phi) / p_b``), the report's Figure 4 relations and its
section 3.2 numbers (contact ratio 1.69129, I1 = 1.9604e-5, I2 = 0.0050 kg m^2).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from gearctl import GearPair, InputError, load_model, model_names, pair_geometry
from gearctl.geometry import involute, undercut_limit

DEG = math.pi / 180.0


# --- involute function ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("phi_deg", "table"),
    [
        # involute-function tables (e.g. Machinery's Handbook), printed to 4-5 significant digits
        (14.5, 0.0055448),
        (20.0, 0.014904),
        (25.0, 0.029975),
        (30.0, 0.053751),
    ],
)
def test_involute_matches_table(phi_deg: float, table: float) -> None:
    # rtol 5e-5: half a unit in the 5th significant digit of the printed table
    assert_allclose(involute(phi_deg * DEG), table, rtol=5e-5)


def test_involute_is_polar_angle_of_parametric_involute() -> None:
    """inv(beta) is the polar angle of the involute point at radius r_b / cos(beta) (eq 26's basis)."""
    rb = 0.0187939
    for beta in np.linspace(1.0, 40.0, 9) * DEG:
        t = math.tan(beta)  # roll angle of the involute point whose pressure angle is beta
        x = rb * (math.cos(t) + t * math.sin(t))
        y = rb * (math.sin(t) - t * math.cos(t))
        # rtol 1e-12: both are a few floating-point operations
        assert_allclose(math.hypot(x, y), rb / math.cos(beta), rtol=1e-12)
        assert_allclose(math.atan2(y, x), involute(beta), rtol=1e-12)


def test_undercut_limit_closed_form() -> None:
    # 2 h_a* / sin^2(phi): 17.1 teeth at 20 deg full depth, the textbook "17 teeth" rule
    assert_allclose(undercut_limit(20 * DEG), 2 / math.sin(20 * DEG) ** 2, rtol=1e-12)
    assert 17.0 < undercut_limit(20 * DEG) < 17.2
    assert_allclose(undercut_limit(25 * DEG, 0.8), 1.6 / math.sin(25 * DEG) ** 2, rtol=1e-12)


# --- the report's example pair (TR 93-28 section 3.2) ----------------------------------------------------


def test_report_contact_ratio(shing) -> None:
    # TR 93-28 section 3.2: "the contact ratio is equal to 1.69129"; atol 5e-6 = half a unit in the last
    # printed digit, i.e. agreement to all 6 printed significant digits (>= the 5 asked for)
    assert_allclose(pair_geometry(shing.pair).contact_ratio, 1.69129, rtol=0, atol=5e-6)


def test_report_inertias(shing) -> None:
    I1, I2 = pair_geometry(shing.pair).inertia
    # TR 93-28 section 3.2: I1 = 1.9604e-05 kg m^2 (5 significant digits); atol 5e-10 = half a unit in the last
    # printed digit (gearctl: 1.960354e-5)
    assert_allclose(I1, 1.9604e-5, rtol=0, atol=5e-10)
    # TR 93-28 section 3.2 prints only I2 = 0.0050 kg m^2: the value must round to it ...
    assert f"{I2:.4f}" == "0.0050"
    # ... and be the solid disk of the pitch radius, rho pi f r^4 / 2 (r2 = 0.08 m); rtol 1e-12 (closed form)
    assert_allclose(I2, 7800.0 * math.pi * 0.01 * 0.08**4 / 2, rtol=1e-12)
    assert_allclose(I1, 7800.0 * math.pi * 0.01 * 0.02**4 / 2, rtol=1e-12)


def test_report_pair_by_hand(shing) -> None:
    """Every Figure 4 quantity of the report's pair from its printed data, written out by hand."""
    g = pair_geometry(shing.pair)
    phi = 20 * DEG
    rp1, rp2 = 0.02, 0.08  # section 3.2: pitch radii
    m = 0.002  # 2 rp / N
    rb1, rb2 = rp1 * math.cos(phi), rp2 * math.cos(phi)
    ra1, ra2 = rp1 + m, rp2 + m  # full-depth addendum (assumed in shing1993.toml)
    pb = math.pi * m * math.cos(phi)
    a = rp1 + rp2  # standard centre distance
    # rtol 1e-12 on everything below: closed forms, a few floating-point operations each
    assert_allclose(g.pitch_radius, (rp1, rp2), rtol=1e-12)
    assert_allclose(g.base_radius, (rb1, rb2), rtol=1e-12)
    assert_allclose(g.addendum_radius, (ra1, ra2), rtol=1e-12)
    assert_allclose(g.base_pitch, pb, rtol=1e-12)
    # AB = l = a sin(phi): the common tangent of the base circles (Figure 4)
    assert_allclose(g.AB, a * math.sin(phi), rtol=1e-12)
    assert_allclose(g.AD, math.sqrt(ra1**2 - rb1**2), rtol=1e-12)
    assert_allclose(g.AB - g.AC, math.sqrt(ra2**2 - rb2**2), rtol=1e-12)
    # textbook contact ratio: length of the path of contact / base pitch
    eps = (math.sqrt(ra1**2 - rb1**2) + math.sqrt(ra2**2 - rb2**2) - a * math.sin(phi)) / pb
    assert_allclose(g.contact_ratio, eps, rtol=1e-12)
    assert_allclose(g.gear_ratio, 4.0, rtol=1e-12)
    # one mesh cycle turns gear 1 by one tooth: 2 pi / N1
    assert_allclose(g.mesh_period_angle, 2 * math.pi / 20, rtol=1e-12)


def test_hand_computed_contact_ratio_other_pair() -> None:
    """A 25 deg, 31 x 47, module 3 mm pair with addendum 0.9: contact ratio by the textbook formula."""
    pair = GearPair(
        teeth1=31, teeth2=47, module=0.003, pressure_angle=25 * DEG, face_width=0.02, backlash=1e-4,
        addendum_coefficient=0.9, dedendum_coefficient=1.15, young_modulus=2.07e11, poisson_ratio=0.3,
        density=7850.0,
    )
    rp1, rp2 = 0.0465, 0.0705
    ra1, ra2 = rp1 + 0.0027, rp2 + 0.0027
    rb1, rb2 = rp1 * math.cos(25 * DEG), rp2 * math.cos(25 * DEG)
    eps = (
        math.sqrt(ra1**2 - rb1**2) + math.sqrt(ra2**2 - rb2**2) - (rp1 + rp2) * math.sin(25 * DEG)
    ) / (math.pi * 0.003 * math.cos(25 * DEG))
    # rtol 1e-12: closed form
    assert_allclose(pair_geometry(pair).contact_ratio, eps, rtol=1e-12)


# --- relations of Figure 4 on every catalog entry ------------------------------------------------------


@pytest.mark.parametrize("name", model_names())
def test_line_of_action_relations(name: str) -> None:
    pair = load_model(name).pair
    g = pair_geometry(pair)
    phi, m = pair.pressure_angle, pair.module
    # rtol 1e-12 throughout: closed forms
    assert_allclose(g.base_radius, np.array(g.pitch_radius) * math.cos(phi), rtol=1e-12)
    assert_allclose(g.pitch_radius, (m * pair.teeth1 / 2, m * pair.teeth2 / 2), rtol=1e-12)
    assert_allclose(g.base_pitch, math.pi * m * math.cos(phi), rtol=1e-12)
    # base pitch = base circumference / teeth, for both gears
    assert_allclose(g.base_pitch, 2 * math.pi * g.base_radius[0] / pair.teeth1, rtol=1e-12)
    assert_allclose(g.base_pitch, 2 * math.pi * g.base_radius[1] / pair.teeth2, rtol=1e-12)
    # section 3.1: DE = CF = p_b
    assert_allclose(g.AE, g.AD - g.base_pitch, rtol=1e-12)
    assert_allclose(g.AF, g.AC + g.base_pitch, rtol=1e-12)
    # pitch point P: tangent length of gear 1's base circle to the (operating) pitch point; the operating
    # pressure angle is the nominal one for an unshifted or V-zero pair (x1 + x2 = 0)
    phi_w = g.operating_pressure_angle
    if pair.x1 + pair.x2 == 0.0:
        assert phi_w == phi
    assert_allclose(g.AP, g.base_radius[0] * math.tan(phi_w), rtol=1e-12)
    assert_allclose(g.AB - g.AP, g.base_radius[1] * math.tan(phi_w), rtol=1e-12)
    # the pitch point lies on the path of contact C -> D, which lies on A -> B
    assert 0.0 < g.AC < g.AP < g.AD < g.AB
    assert_allclose(g.contact_ratio, (g.AD - g.AC) / g.base_pitch, rtol=1e-12)


# --- tooth heights and thicknesses (eqs 19, 22-28) ----------------------------------------------------


def test_tooth_heights_both_branches_of_eqs_22_25(shing) -> None:
    """Report pair: gear 1 (20 teeth) has its dedendum circle inside the base circle (eqs 22-23),
    gear 2 (80 teeth: r_d = 77.5 mm > r_b = 75.18 mm) outside it (eqs 24-25)."""
    g = pair_geometry(shing.pair)
    m, phi = 0.002, 20 * DEG
    rb1, rb2 = 0.02 * math.cos(phi), 0.08 * math.cos(phi)
    rd1, rd2 = 0.02 - 1.25 * m, 0.08 - 1.25 * m
    ra1, ra2 = 0.02 + m, 0.08 + m
    assert rd1 < rb1 and rd2 > rb2
    # rtol 1e-12: closed forms
    assert_allclose(g.dedendum_radius, (rd1, rd2), rtol=1e-12)
    assert_allclose(g.h_b[0], rb1 - rd1, rtol=1e-12)  # eq 22
    assert_allclose(g.h_a[0], ra1 - rd1, rtol=1e-12)  # eq 23
    assert g.h_b[1] == 0.0  # eq 24
    assert_allclose(g.h_a[1], ra2 - rb2, rtol=1e-12)  # eq 25


def test_eqs_24_25_at_25_deg_with_many_teeth(shing) -> None:
    # 1 - cos 25 deg = 0.0937: the dedendum circle (1.25 m below pitch) leaves the base circle above
    # 2 * 1.25 / 0.0937 = 26.7 teeth, so a 30 x 60 pair at 25 deg uses eqs 24-25 on both gears
    pair = dataclasses.replace(shing.pair, pressure_angle=25 * DEG, teeth1=30, teeth2=60)
    g = pair_geometry(pair)
    assert g.h_b == (0.0, 0.0)
    # rtol 1e-12: closed form
    assert_allclose(g.h_a, np.array(g.addendum_radius) - np.array(g.base_radius), rtol=1e-12)


@pytest.mark.parametrize(("teeth", "outside"), [(41, False), (42, True)])
def test_branch_switches_where_dedendum_circle_crosses_base_circle(shing, teeth: int, outside: bool) -> None:
    # r_d > r_b  <=>  N (1 - cos phi) / 2 > h_f*  <=>  N > 2.5 / (1 - cos 20 deg) = 41.45 teeth
    assert (teeth > 2.5 / (1 - math.cos(20 * DEG))) is outside
    g = pair_geometry(dataclasses.replace(shing.pair, teeth1=teeth))
    if outside:
        assert g.h_b[0] == 0.0
    else:
        assert g.h_b[0] > 0.0
        # rtol 1e-12: eq 22
        assert_allclose(g.h_b[0], g.base_radius[0] - g.dedendum_radius[0], rtol=1e-12)


@pytest.mark.parametrize("name", model_names())
def test_tooth_thicknesses(name: str) -> None:
    pair = load_model(name).pair
    g = pair_geometry(pair)
    m, phi = pair.module, pair.pressure_angle
    # no backlash thinning: t_p = pi m / 2 (half the circular pitch); rtol 1e-12
    assert_allclose(g.tooth_thickness_pitch, math.pi * m / 2, rtol=1e-12)
    for j in range(2):
        rb, rp, ra = g.base_radius[j], g.pitch_radius[j], g.addendum_radius[j]
        # the reference-circle thickness: pi m / 2, plus 2 x m tan(phi) for a profile-shifted gear (ISO 21771)
        s_ref = g.tooth_thickness_reference[j]
        assert_allclose(s_ref, m * (math.pi / 2 + 2 * g.profile_shift[j] * math.tan(phi)), rtol=1e-12)

        # eq 26 at a radius r, with cos(phi_r) = r_b / r
        def t_at(r: float, rb: float = rb, rp: float = rp, s_ref: float = s_ref) -> float:
            return r * (s_ref / rp + 2 * (involute(phi) - involute(math.acos(rb / r))))

        # eq 26 at the pitch circle returns the reference thickness; eq 27 is eq 26 at the base circle; eq 28
        # at the tip
        assert_allclose(t_at(rp), s_ref, rtol=1e-12)
        assert_allclose(g.tooth_thickness_base[j], t_at(rb), rtol=1e-12)
        assert_allclose(g.tooth_thickness_addendum[j], t_at(ra), rtol=1e-12)
        # the involute tooth narrows outward and is not pointed
        assert g.tooth_thickness_base[j] > s_ref > g.tooth_thickness_addendum[j] > 0
        # eq 19: w is where the flanks of the trapezoid (t_b at h_b, t_a at h_a) meet, beyond the tip
        h_a, h_b, tb, ta = g.h_a[j], g.h_b[j], g.tooth_thickness_base[j], g.tooth_thickness_addendum[j]
        w = g.w[j]
        assert w > h_a
        # similar triangles: t_b / (w - h_b) = t_a / (w - h_a); rtol 1e-12
        assert_allclose(tb * (w - h_a), ta * (w - h_b), rtol=1e-12)


def test_inertia_override(shing) -> None:
    pair = dataclasses.replace(shing.pair, inertia1=1e-4, inertia2=None)
    g = pair_geometry(pair)
    assert g.inertia[0] == 1e-4
    # rtol 1e-12: disk of the pitch radius when not given
    assert_allclose(g.inertia[1], 7800.0 * math.pi * 0.01 * 0.08**4 / 2, rtol=1e-12)


# --- undercut and interference ------------------------------------------------------------------------


def test_undercut_limit_is_the_rack_interference_limit(shing) -> None:
    """A gear at the undercut limit meshed with a near-rack (1000 teeth) is just free of interference.

    The undercut limit ``2 h_a / sin^2 phi`` is the teeth count at which a *rack's* addendum reaches
    the interference point; a 1000-tooth gear is nearly a rack. So the mating tip reaches to within
    0.2 % of the base-circle tangent point B, never past it.
    """
    n = math.ceil(undercut_limit(20 * DEG))  # 18
    g = pair_geometry(dataclasses.replace(shing.pair, teeth1=1000, teeth2=n))
    assert g.AD <= g.AB
    # 0.2 %: the distance left by 18 > 17.1 teeth and 1000 < infinitely many
    assert g.AD > 0.998 * g.AB
    with pytest.raises(InputError, match="teeth2"):
        dataclasses.replace(shing.pair, teeth1=1000, teeth2=n - 1)
