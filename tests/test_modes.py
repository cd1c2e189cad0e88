"""Linear models per contact mode (gearctl/modes.py) against closed forms and the nonlinear plant.

Oracles (TR 93-28 section 2):

1. closed forms: in contact, eqs 1-5 / 8-12 with a linear law split into a rigid-body mode and the
   mesh mode ``m_eq s'' + c s' + k s = ...`` with ``m_eq = J1 J2 / (J2 rb1^2 + J1 rb2^2)``, so the
   resonance is ``sqrt(k / m_eq)`` and the damping ratio ``c / (2 sqrt(k m_eq))`` (eq 38, consistent
   form); holding the motor, the load rings on the mesh spring at ``sqrt(k rb2^2 / J2)`` (the
   anti-resonance of motor torque to motor angle); DC gains and steady forces of the rigid train
   ``J_eq theta1'' + d_eq theta1' = xi1 + xi2 / N`` derived by hand; textbook loops with known margins;
2. independent computation: the exact event-locating simulator (gearctl.simulate) at small amplitude
   about a loaded contact, and in the gap, against python-control's responses of the linear models;
3. limits: the contact model tends to the rigid model as ``k -> inf``.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import control as ct
import numpy as np
import pytest
import scipy.optimize
from numpy.testing import assert_allclose

from gearctl import Plant, build_plant, load_model
from gearctl.cli import main
from gearctl.modes import (
    OUTPUTS,
    contact_mode_model,
    linearize_modes,
    loop_margins,
    rigid_model,
    separation_model,
)
from gearctl.plant import INPUTS, STATES
from gearctl.simulate import simulate

MODELS = ("shing1993", "shing1993_servo")


@pytest.fixture(scope="module")
def plants() -> dict[str, Plant]:
    """Improved plants of the bare pair and of the benchmark servo."""
    return {name: build_plant(load_model(name)) for name in MODELS}


def m_eq(p: Plant) -> float:
    """Equivalent mass along the line of action, written out (not Plant.m_eq) [kg]."""
    return p.J1 * p.J2 / (p.J2 * p.rb1**2 + p.J1 * p.rb2**2)


def bare(p: Plant) -> Plant:
    """The plant without mesh damping and without shaft friction."""
    return dataclasses.replace(p, c=0.0, d1=0.0, d2=0.0, tc1=0.0, tc2=0.0)


# --- 1. the mesh mode against its closed form ------------------------------------------------------------


@pytest.mark.parametrize(("name", "approx_hz"), [("shing1993", 8196.5), ("shing1993_servo", 2761.2)])
def test_natural_frequency_closed_form(plants: dict[str, Plant], name: str, approx_hz: float) -> None:
    p = bare(plants[name])
    mesh = linearize_modes(p).mesh
    # the undamped mesh mode is exactly sqrt(k / m_eq): the contact model's characteristic polynomial is
    # s^2 (s^2 + k / m_eq) without damping or friction; 1e-9 leaves room for the eigenvalue solver only
    # (we see 1e-15)
    wn = math.sqrt(p.k / m_eq(p))
    assert_allclose(mesh.natural_frequency, wn, rtol=1e-9)
    assert_allclose(mesh.natural_frequency_hz, wn / (2 * math.pi), rtol=1e-9)
    # the catalog figures (bare pair ~8.2 kHz, servo with motor and load ~2.76 kHz): 1e-4, a sanity
    # check that the right inertias went in (the closed form above is the real oracle)
    assert_allclose(mesh.natural_frequency_hz, approx_hz, rtol=1e-4)
    # undamped: damping ratio exactly zero (the poles sit on the imaginary axis to rounding)
    assert abs(mesh.damping_ratio) < 1e-9


@pytest.mark.parametrize("name", MODELS)
def test_damping_ratio_is_the_models(plants: dict[str, Plant], name: str) -> None:
    p = plants[name]
    zeta = load_model(name).dynamics.damping_ratio
    assert zeta == 0.05
    # c = 2 zeta sqrt(k m_eq) with m_eq of the total shaft inertias (eq 38, consistent form): without
    # shaft friction the mesh mode is exactly second order, so its damping ratio is zeta to rounding
    # (1e-9; we see 1e-15)
    no_friction = dataclasses.replace(p, d1=0.0, d2=0.0)
    assert_allclose(linearize_modes(no_friction).mesh.damping_ratio, zeta, rtol=1e-9)
    assert_allclose(p.c, 2 * zeta * math.sqrt(p.k * m_eq(p)), rtol=1e-12)
    # with the servo's viscous friction (d2 / J2 = 0.2 1/s against 2 zeta omega_n = 1700 1/s) the modal
    # damping moves by ~2e-4 relative (we see 0.050011): 1e-3
    assert_allclose(linearize_modes(p).mesh.damping_ratio, zeta, rtol=1e-3)
    # and the frequency with damping is still |lambda| = sqrt(k / m_eq) up to that coupling (1e-6)
    assert_allclose(linearize_modes(p).mesh.natural_frequency, math.sqrt(p.k / m_eq(p)), rtol=1e-6)


@pytest.mark.parametrize("zeta", [1.0 + 1e-6, 1.5, 2.0])
def test_overdamped_mesh_mode_closed_form(plants: dict[str, Plant], zeta: float) -> None:
    # damping_ratio above 1 (the schema allows up to 2): no oscillating pole. Without shaft friction the contact
    # model's polynomial is s^2 (s^2 + 2 zeta wn s + wn^2), wn = sqrt(k / m_eq): the mesh poles are
    # -wn (zeta -+ sqrt(zeta^2 - 1)), and the mesh mode must report wn and zeta (product and sum of the pair),
    # not the frequency of one real pole; 1e-9 for the eigenvalue solver (we see 1e-15)
    p = build_plant(load_model("shing1993_servo", damping_ratio=zeta))
    still = dataclasses.replace(p, d1=0.0, d2=0.0)
    mesh = linearize_modes(still).mesh
    wn = math.sqrt(p.k / m_eq(p))
    assert_allclose(mesh.natural_frequency, wn, rtol=1e-9)
    assert_allclose(mesh.damping_ratio, zeta, rtol=1e-9)
    assert mesh.overdamped
    root = math.sqrt(zeta**2 - 1)
    poles = np.sort(contact_mode_model(still).poles().real)
    assert_allclose(poles[:2], [-wn * (zeta + root), -wn * (zeta - root)], rtol=1e-9)  # we see 3e-14
    # zeros of motor torque -> motor angle: J2 s^2 + c rb2^2 s + k rb2^2 (the motor held), by the same rule
    # (1e-9 for the polynomial root finder: we see 3e-11)
    wz = math.sqrt(p.k * p.rb2**2 / p.J2)
    assert_allclose(mesh.antiresonance, wz, rtol=1e-9)
    assert_allclose(mesh.antiresonance_damping, p.c * p.rb2**2 / (2 * p.J2 * wz), rtol=1e-9)
    # with the servo's viscous friction the pair moves (we see 1e-5 on zeta, 2e-11 on wn): 1e-3, as for 0.05
    with_friction = linearize_modes(p).mesh
    assert_allclose(with_friction.damping_ratio, zeta, rtol=1e-3)
    assert_allclose(with_friction.natural_frequency, wn, rtol=1e-3)
    assert linearize_modes(plants["shing1993_servo"]).mesh.overdamped is False


def test_overdamped_mesh_designs_and_reports(capsys: pytest.CaptureFixture[str]) -> None:
    # every caller of the mesh mode copes: the PID designs (via sampled_margins -> linearize_modes), linearize
    # reports the mode as overdamped in text and JSON
    from gearctl.catalog import load_controller

    path = Path(__file__).parent / "data" / "fuzz" / "overdamped_mesh.toml"
    plant = build_plant(load_model(path))
    for name in ("pid", "deadzone_inverse", "reversal_offset"):
        assert load_controller(name, plant).Ts == 1e-3
    assert main(["linearize", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["overdamped"] is True and out["resonances_hz"] == []
    assert_allclose(out["damping_ratio"], 1.5, rtol=1e-3)
    assert_allclose(out["natural_frequency_hz"], 2761.2, rtol=1e-4)  # the servo's mesh mode, as with zeta 0.05
    assert main(["linearize", str(path)]) == 0
    assert "damping ratio 1.5 (overdamped" in capsys.readouterr().out
    assert main(["linearize", "shing1993_servo", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["overdamped"] is False


@pytest.mark.parametrize("name", MODELS)
def test_antiresonance_closed_form(plants: dict[str, Plant], name: str) -> None:
    p = bare(plants[name])
    mesh = linearize_modes(p).mesh
    # motor held (theta1 = 0): J2 theta2'' = -k rb2^2 theta2, so theta1/xi1 has its zeros at
    # +-j sqrt(k rb2^2 / J2); 1e-9 for the polynomial root finder (we see 3e-11)
    assert_allclose(mesh.antiresonance, math.sqrt(p.k * p.rb2**2 / p.J2), rtol=1e-9)
    assert mesh.antiresonance < mesh.natural_frequency  # the zero pair lies below the pole pair


def test_modes_structure_and_names(plants: dict[str, Plant]) -> None:
    m = linearize_modes(plants["shing1993_servo"])
    for sys in (m.contact, m.separation):
        assert list(sys.state_labels) == list(STATES)
        assert list(sys.input_labels) == list(INPUTS)
        assert list(sys.output_labels) == list(OUTPUTS)
    assert list(m.rigid.state_labels) == ["theta1", "omega1"]
    assert m.mode("rigid") is m.rigid
    # the contact model's poles: the rigid-body pair (0 and about -d_eq/J_eq with friction) and the mesh
    # pair; every pole in the closed left half plane
    assert np.all(m.contact.poles().real <= 1e-9 * m.mesh.natural_frequency)


# --- 2. DC gains and steady forces ------------------------------------------------------------------------


def _reduced_contact(sys: ct.StateSpace, p: Plant) -> ct.StateSpace:
    """The contact model in coordinates ``[s, theta2, omega1, omega2]`` with ``theta2`` dropped.

    The dynamics depend on the angles only through ``s = rb1 theta1 - rb2 theta2``, so after this
    similarity transform the ``theta2`` column of A is zero (checked) and ``theta2`` is a pure
    integrator that feeds nothing: the remaining 3-state model has a regular A and a finite DC gain.
    """
    T = np.array([[p.rb1, -p.rb2, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], float)
    Ti = np.linalg.inv(T)
    A, B, C = T @ sys.A @ Ti, T @ sys.B, sys.C @ Ti
    scale = np.max(np.abs(A))
    assert_allclose(A[:, 1], 0.0, atol=1e-12 * scale)  # theta2 feeds nothing (to rounding)
    keep = [0, 2, 3]
    return ct.ss(A[np.ix_(keep, keep)], B[keep], C[:, keep], sys.D)


def test_rigid_velocity_dc_gain_is_one_over_d_eq(plants: dict[str, Plant]) -> None:
    p = plants["shing1993_servo"]
    assert p.d1 > 0 and p.d2 > 0
    N = p.rb2 / p.rb1
    d_eq = p.d1 + p.d2 / N**2
    r = rigid_model(p)
    assert r.A[1, 0] == 0.0  # theta1 does not feed omega1: the velocity subsystem stands alone
    vel = ct.ss(r.A[1:, 1:], r.B[1:], [[1.0]], [[0.0, 0.0]])
    # J_eq omega1' = xi1 + xi2 / N - d_eq omega1: omega1 / xi1 -> 1 / d_eq, omega1 / xi2 -> 1 / (N d_eq);
    # a 2x2 solve: 1e-12
    assert_allclose(np.squeeze(vel.dcgain()), [1.0 / d_eq, 1.0 / (N * d_eq)], rtol=1e-12)


@pytest.mark.parametrize("name", MODELS)
def test_rigid_force_under_constant_acceleration(plants: dict[str, Plant], name: str) -> None:
    # without friction a constant motor torque gives a constant acceleration xi1 / J_eq, and the mesh
    # must push the load with F = J2 theta2'' / rb2 = J2 xi1 / (N J_eq rb2) (gear 2's equation, eq 9)
    p = bare(plants[name])
    N = p.rb2 / p.rb1
    J_eq = p.J1 + p.J2 / N**2
    F_hand = p.J2 / (N * J_eq * p.rb2)
    r = rigid_model(p)
    iF = list(OUTPUTS).index("force")
    # rigid model: at rest (x = 0) the force is D's row alone; 1e-12
    assert_allclose(r.D[iF, 0], F_hand, rtol=1e-12)
    # contact model (damping c of the model, still no friction): the same force once the mesh vibration
    # has decayed, i.e. the low-frequency limit of force/xi1. Without friction both integrators cancel
    # in that transfer, so it is read at 1 rad/s, where it is (k + c s) / (m_eq s^2 + c s + k) of the
    # limit: off by m_eq / k < 1e-8, plus rounding in (sI - A)^-1 (we see 3e-8 in all): 1e-6
    pc = dataclasses.replace(plants[name], d1=0.0, d2=0.0, tc1=0.0, tc2=0.0)
    con = contact_mode_model(pc)
    assert_allclose(complex(con[iF, 0](1j)), F_hand, rtol=1e-6)
    # and a load torque xi2 is shared the same way: F = (J2 xi2 / (N J_eq) - xi2) / rb2 (same tolerances)
    F2_hand = (p.J2 / (N**2 * J_eq) - 1.0) / p.rb2
    assert_allclose(r.D[iF, 1], F2_hand, rtol=1e-12)
    assert_allclose(complex(con[iF, 1](1j)), F2_hand, rtol=1e-6)


def test_force_at_steady_velocity_with_viscous_friction(plants: dict[str, Plant]) -> None:
    # with viscous friction a constant xi1 ends at omega1 = xi1 / d_eq; then gear 2's equation gives
    # rb2 F = d2 omega2 = d2 omega1 / N, i.e. F = d2 xi1 / (N rb2 d_eq) (hand-derived)
    p = plants["shing1993_servo"]
    N = p.rb2 / p.rb1
    d_eq = p.d1 + p.d2 / N**2
    F_hand = p.d2 / (N * p.rb2 * d_eq)
    iF = list(OUTPUTS).index("force")
    # rigid model in its steady state x = [., 1/d_eq] (theta1 does not enter the force): 1e-12
    r = rigid_model(p)
    assert_allclose(r.C[iF] @ [0.0, 1.0 / d_eq] + r.D[iF, 0], F_hand, rtol=1e-12)
    # contact model: DC gain of the reduced model (1e-9)
    red = _reduced_contact(contact_mode_model(p), p)
    assert_allclose(np.squeeze(red[iF, 0].dcgain()), F_hand, rtol=1e-9)
    # and its steady deflection is F / k along the line of action (s output), same tolerance
    iS = list(OUTPUTS).index("s")
    assert_allclose(np.squeeze(red[iS, 0].dcgain()), F_hand / p.k, rtol=1e-9)


def test_separation_has_no_coupling(plants: dict[str, Plant]) -> None:
    p = plants["shing1993_servo"]
    sep = separation_model(p)
    # eqs 6-7: two free inertias; xi1 reaches only theta1 / omega1, xi2 only theta2 / omega2 (exact zeros)
    A, B = sep.A, sep.B
    assert np.all(A[np.ix_([0, 2], [1, 3])] == 0.0) and np.all(A[np.ix_([1, 3], [0, 2])] == 0.0)
    assert np.all(B[[1, 3], 0] == 0.0) and np.all(B[[0, 2], 1] == 0.0)
    # so theta2 / xi1 is identically zero at every frequency, and the force output is zero
    w = np.logspace(0, 5, 50)
    assert np.all(np.abs(sep[1, 0].frequency_response(w).magnitude) == 0.0)
    assert np.all(sep.C[3] == 0.0) and np.all(sep.D == 0.0)
    # theta1 / xi1 is the free motor 1 / (J1 s^2 + d1 s): at 100 rad/s, 1e-12
    s = 100j
    assert_allclose(complex(sep[0, 0](s)), 1.0 / (p.J1 * s**2 + p.d1 * s), rtol=1e-12)


# --- 3. the rigid-body limit ------------------------------------------------------------------------------


@pytest.mark.parametrize("name", MODELS)
def test_contact_tends_to_rigid_as_k_grows(plants: dict[str, Plant], name: str) -> None:
    p = plants[name]
    stiff = dataclasses.replace(p, k=p.k * 1e4, c=p.c * 1e2)  # c ~ sqrt(k): the same damping ratio
    w = 2 * math.pi * np.logspace(-1, 2, 40)  # 0.1-100 Hz, far below the mesh mode (>= 1.4 kHz anti-res.)
    rig = rigid_model(p)
    g_rig = np.squeeze(rig[0, 0].frequency_response(w).complex)
    g_stiff = np.squeeze(contact_mode_model(stiff)[0, 0].frequency_response(w).complex)
    # relative deviation ~ (omega / omega_antiresonance)^2 = (100 Hz / 140 kHz)^2 ~ 5e-7 with k x 1e4: 1e-3
    assert_allclose(g_stiff, g_rig, rtol=1e-3)
    # theta2 / xi1 tends to theta1 / (N xi1) the same way
    g_rig2 = np.squeeze(rig[1, 0].frequency_response(w).complex)
    g_stiff2 = np.squeeze(contact_mode_model(stiff)[1, 0].frequency_response(w).complex)
    assert_allclose(g_stiff2, g_rig2, rtol=1e-3)
    # the check discriminates: with the real k the servo at 100 Hz is already (100/1407)^2 ~ 0.5 % off
    if name == "shing1993_servo":
        g_soft = np.squeeze(contact_mode_model(p)[0, 0].frequency_response(w).complex)
        assert np.max(np.abs(g_soft / g_rig - 1)) > 1e-3


# --- 4. small amplitude: the nonlinear plant against the linear models ------------------------------------


def _preloaded(p: Plant, xi1: float) -> tuple[np.ndarray, float]:
    """Static equilibrium in front contact under ``xi1`` and the opposing load ``xi2 = -N xi1``."""
    F = xi1 / p.rb1  # motor shaft at rest: xi1 = rb1 F
    theta1 = (p.backlash + F / p.k) / p.rb1  # s = b + F / k with theta2 = 0
    return np.array([theta1, 0.0, 0.0, 0.0]), -p.gear_ratio * xi1


@pytest.mark.parametrize("name", MODELS)
def test_preloaded_contact_matches_contact_model_step(plants: dict[str, Plant], name: str) -> None:
    p = plants[name]
    assert p.is_piecewise_linear  # exact solver: the comparison is of two exact solutions
    x_eq, xi2 = _preloaded(p, 0.1)
    dt, n = 1e-5, 3000
    # the equilibrium holds: no perturbation, no motion (the solver's static residual, 1e-12 of b)
    still = simulate(p, x_eq, dt * 200, torque=(0.1, xi2), dt=dt)
    assert np.max(np.abs(still.s - still.s[0])) < 1e-12 * p.backlash
    du = 1e-3  # a 1 % torque step on top of the 0.1 N m preload
    res = simulate(p, x_eq, dt * n, torque=(0.1 + du, xi2), dt=dt)
    assert np.all(res.mode == 1) and not res.impacts  # stays in front contact throughout
    lin = ct.step_response(contact_mode_model(p) * du, T=res.t, input=0)
    y = np.squeeze(lin.outputs)  # (outputs, time)
    dev = {"theta1": res.x[0] - x_eq[0], "theta2": res.x[1], "s": res.s - res.s[0],
           "force": res.force - res.force[0]}
    for i, out in enumerate(OUTPUTS):
        amp = np.max(np.abs(y[i]))
        assert amp > 0
        # 1e-6 of the response amplitude: both are exact solutions (matrix exponentials) of the same
        # linear ODE; what is left is rounding of the ~3e-3 rad preload offset (we see 1e-10)
        assert_allclose(dev[out], y[i], rtol=0, atol=1e-6 * amp, err_msg=out)


@pytest.mark.parametrize("name", MODELS)
def test_preloaded_contact_matches_sampled_contact_model_sine(plants: dict[str, Plant], name: str) -> None:
    p = plants[name]
    x_eq, xi2 = _preloaded(p, 0.1)
    dt, n = 2e-5, 2500
    f = 300.0  # Hz: between the rigid-body range and the mesh mode
    du = 1e-3

    def torque(t: float, x: np.ndarray) -> tuple[float, float]:
        return 0.1 + du * math.sin(2 * math.pi * f * t), xi2

    res = simulate(p, x_eq, dt * n, torque=torque, dt=dt)
    assert np.all(res.mode == 1)
    # simulate holds the torque from each output time to the next (ZOH), so the oracle is the
    # contact model discretised with a ZOH at the same interval, driven by the same samples
    sysd = ct.c2d(contact_mode_model(p), dt, "zoh")
    U = np.zeros((2, res.t.size))
    U[0] = du * np.sin(2 * math.pi * f * res.t)
    y = np.squeeze(ct.forced_response(sysd, T=res.t, U=U).outputs)
    dev = {"theta1": res.x[0] - x_eq[0], "theta2": res.x[1], "s": res.s - res.s[0],
           "force": res.force - res.force[0]}
    for i, out in enumerate(OUTPUTS):
        amp = np.max(np.abs(y[i]))
        # 1e-6 of the amplitude, as above (ZOH discretisation is exact for held inputs)
        assert_allclose(dev[out], y[i], rtol=0, atol=1e-6 * amp, err_msg=out)


@pytest.mark.parametrize("name", MODELS)
def test_gap_matches_separation_model_until_first_contact(plants: dict[str, Plant], name: str) -> None:
    p = plants[name]
    x0 = np.zeros(4)  # mid-gap, s = 0, at rest
    du = (1e-3, -5e-4)  # small torques; the motor closes the gap in tens of ms
    dt = 1e-5
    res = simulate(p, x0, 0.1, torque=du, dt=dt)
    assert res.impacts, "the run must reach a contact for the comparison to end somewhere"
    t_hit = res.impacts[0].t
    lin = ct.forced_response(separation_model(p), T=res.t, U=np.outer(du, np.ones(res.t.size)))
    y = np.squeeze(lin.outputs)
    before = res.t < t_hit
    assert np.count_nonzero(before) > 100 and np.all(res.mode[before] == 0)
    for i, out in zip((0, 1, 2), ("theta1", "theta2", "s"), strict=True):
        sim = {"theta1": res.x[0], "theta2": res.x[1], "s": res.s}[out][before]
        amp = np.max(np.abs(y[i][before]))
        # exact solutions of eqs 6-7 (free inertias with viscous friction): 1e-6 of the amplitude (we see 1e-13)
        assert_allclose(sim, y[i][before], rtol=0, atol=1e-6 * amp, err_msg=out)
    assert np.all(res.force[before] == 0.0)
    # after the contact the separation model no longer describes the plant: the load is dragged along
    after = res.t > t_hit + 5e-3
    assert np.max(np.abs(res.x[1][after] - y[1][after])) > 1e-2 * np.max(np.abs(y[1][after]))


# --- 5. loop margins on textbook loops --------------------------------------------------------------------


def _phase_margin_of(mag_fn, phase_fn) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    wc = scipy.optimize.brentq(lambda w: mag_fn(w) - 1.0, 1e-4, 1e4, xtol=1e-14)
    return 180.0 + phase_fn(wc), wc


@pytest.mark.parametrize("K", [0.5, 1.0, 1.5])
def test_loop_margins_type1_textbook(K: float) -> None:
    s = ct.tf("s")
    L = K / (s * (s + 1) ** 2)
    # phase -90 - 2 atan(w) = -180 at w = 1, where |L| = K / 2: GM = 2 / K
    gm_db = 20 * math.log10(2.0 / K)
    pm, wc = _phase_margin_of(lambda w: K / (w * (1 + w**2)), lambda w: -90.0 - 2 * math.degrees(math.atan(w)))
    m = loop_margins(L)
    # the default grid has 2500 points per decade: 0.5 deg / 0.1 dB (we see < 0.05 deg, < 0.001 dB)
    assert abs(m["phase_margin"] - pm) < 0.5
    assert abs(m["gain_margin_db"] - gm_db) < 0.1
    assert_allclose(m["gain_crossover_hz"], wc / (2 * math.pi), rtol=1e-3)
    assert_allclose(m["phase_crossover_hz"], 1.0 / (2 * math.pi), rtol=1e-3)


def test_loop_margins_third_order_lag() -> None:
    s = ct.tf("s")
    L = 2.0 / (s + 1) ** 3
    # phase -3 atan(w) = -180 at w = sqrt(3), |L| = 2 / 8: GM = 4 (12.04 dB);
    # |L| = 1 at w = sqrt(2^(2/3) - 1): PM = 180 - 3 atan(w)
    wc = math.sqrt(2 ** (2 / 3) - 1)
    pm = 180.0 - 3 * math.degrees(math.atan(wc))
    m = loop_margins(L)
    assert abs(m["phase_margin"] - pm) < 0.5  # 0.5 deg / 0.1 dB, as above
    assert abs(m["gain_margin_db"] - 20 * math.log10(4.0)) < 0.1
    assert_allclose(m["phase_crossover_hz"], math.sqrt(3) / (2 * math.pi), rtol=1e-3)


def test_loop_margins_first_order_has_no_gain_margin() -> None:
    s = ct.tf("s")
    m = loop_margins(2.0 / (s + 1))
    # |L| = 1 at w = sqrt(3): PM = 180 - 60 = 120 deg; the phase never reaches -180: GM infinite
    assert abs(m["phase_margin"] - 120.0) < 0.5
    assert math.isinf(m["gain_margin"]) and math.isinf(m["gain_margin_db"])


def test_loop_margins_discrete_matches_continuous_with_hold_delay() -> None:
    s = ct.tf("s")
    K, Ts = 0.5, 1e-3
    G = K / (s * (s + 1) ** 2)
    Ld = ct.c2d(G, Ts, "zoh")
    pm, wc = _phase_margin_of(lambda w: K / (w * (1 + w**2)), lambda w: -90.0 - 2 * math.degrees(math.atan(w)))
    m = loop_margins(Ld)
    # the ZOH adds a delay of Ts/2: phase -wc Ts/2 (0.02 deg here) and next to nothing in gain; the
    # same 0.5 deg / 0.1 dB
    assert abs(m["phase_margin"] - (pm - math.degrees(wc * Ts / 2))) < 0.5
    assert abs(m["gain_margin_db"] - 20 * math.log10(2.0 / K)) < 0.1


def test_loop_margins_of_the_sampled_servo_loop() -> None:
    # the loop gearctl designs (catalog PID, 20 Hz, on shing1993_servo; ZOH plant, Tustin PID): a type-2
    # loop with a mesh resonance, the case loop_margins exists for. Oracle: L(z) evaluated here at
    # z = exp(j w Ts) on a 10x denser grid, crossings located by sign changes of |L| - 1 and Im L
    from gearctl.design.base import loop_info
    from gearctl.design.pid import design_pid

    info = loop_info(build_plant(load_model("shing1993_servo")))
    Ts = 1e-3
    gains, m = design_pid(info, bandwidth_hz=20.0, phase_margin_deg=50.0, Ts=Ts)
    G = ct.c2d(ct.ss(info.modes.contact[0, 0]) * (1.0 / info.N), Ts, "zoh")
    L = ct.c2d(gains.tf(), Ts, "tustin") * G
    w = np.logspace(-1, np.log10(math.pi / Ts * 0.999), 200_000)
    H = np.squeeze(L(np.exp(1j * w * Ts)))
    mag = np.abs(H)
    cross = np.nonzero((mag[:-1] >= 1.0) & (mag[1:] < 1.0))[0]
    pm = 180.0 + math.degrees(np.angle(H[cross[-1]]))
    real_axis = [j for j in np.nonzero(np.diff(np.sign(H.imag)) != 0)[0] if H[j].real < 0]
    above = [j for j in real_axis if j > cross[-1]]
    below = [j for j in real_axis if j < cross[-1]]
    gm_db = min(-20 * math.log10(abs(H[j].real)) for j in above)
    lower_db = min(20 * math.log10(abs(H[j].real)) for j in below)
    # 0.5 deg / 0.1 dB, as for the textbook loops (we see 0.001 deg, 0.01 dB: ~50 deg, ~23 dB, ~22 dB)
    assert abs(m["phase_margin"] - pm) < 0.5
    assert abs(m["gain_margin_db"] - gm_db) < 0.1
    assert abs(m["lower_gain_margin_db"] - lower_db) < 0.1
    assert abs(m["phase_margin"] - 50.0) < 2.0  # the design meets its target on the sampled contact model


# --- 6. the CLI ---------------------------------------------------------------------------------------------


def test_cli_linearize_json(capsys: pytest.CaptureFixture[str], plants: dict[str, Plant]) -> None:
    assert main(["linearize", "shing1993", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("mode", "states", "inputs", "outputs", "A", "B", "C", "D", "poles", "natural_frequency_hz",
                "damping_ratio"):
        assert key in out, key
    assert out["mode"] == "contact"
    assert out["states"] == list(STATES) and out["inputs"] == list(INPUTS) and out["outputs"] == list(OUTPUTS)
    # the report's pair: mesh mode 8196 Hz (the closed form of test_natural_frequency_closed_form, with
    # the damped poles' modulus: the same to 1e-9), zeta 0.05
    assert_allclose(out["natural_frequency_hz"], 8196.49, rtol=1e-5)
    assert_allclose(out["damping_ratio"], 0.05, rtol=1e-9)
    sys = contact_mode_model(plants["shing1993"])
    for key in ("A", "B", "C", "D"):
        assert_allclose(np.array(out[key]), getattr(sys, key), rtol=1e-15, err_msg=key)
    poles = np.array(out["poles"])
    assert poles.shape == (4, 2)
    # the free rotation's poles are exactly 0 (the eigenvalue solver gave 2e-8 on one machine, 7e-9 on another: two
    # here, without friction); the others are the model's
    model_poles = sys.poles()
    tiny = np.abs(model_poles) <= 1e-10 * np.abs(model_poles).max()
    got = poles[:, 0] + 1j * poles[:, 1]
    assert np.count_nonzero(got == 0) == np.count_nonzero(tiny) >= 1
    assert_allclose(np.sort_complex(got[got != 0]), np.sort_complex(model_poles[~tiny]), rtol=1e-12)


def test_cli_linearize_separation_has_no_mesh_mode(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["linearize", "shing1993", "--mode", "separation", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["mode"] == "separation"
    assert out["natural_frequency_hz"] is None and out["damping_ratio"] is None
    assert np.all(np.array(out["C"])[3] == 0.0)


def test_cli_linearize_rigid(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["linearize", "shing1993_servo", "--mode", "rigid", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["states"] == ["theta1", "omega1"]
    assert np.array(out["A"]).shape == (2, 2)


def test_cli_linearize_writes_bode_and_step(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bode, step = tmp_path / "bode.png", tmp_path / "sub" / "step.png"
    step.parent.mkdir()
    assert main(["linearize", "shing1993", "--bode", str(bode), "--step", str(step)]) == 0
    text = capsys.readouterr().out
    for f in (bode, step):
        assert f.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", f
        assert str(f) in text
    assert "8196" in text  # the human-readable summary names the mesh mode


def test_cli_linearize_bad_input(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["linearize", "no_such_model"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert main(["linearize", "shing1993", "--mode", "gap"]) == 2  # argparse choice
    assert "Traceback" not in capsys.readouterr().err


def test_pid_transfer_functions_connect_to_the_mode_models_by_name() -> None:
    # the designed PID's transfer functions name their signals as the mode models do (error e, motor torque xi1): a
    # python-control user's interconnect closes the loop by name, and gives the poles of the loop closed by hand
    # (before, the PID came back as u[0] -> y[0] and interconnect left it unconnected)
    from gearctl import load_controller

    plant = build_plant(load_model("shing1993_servo"))
    pid = load_controller("pid", plant)
    C, Cd = pid.gains.tf(), pid.gains.sampled_tf(1e-3)
    assert (C.input_labels, C.output_labels) == (Cd.input_labels, Cd.output_labels) == (["e"], ["xi1"])
    assert Cd.dt == 1e-3
    P = linearize_modes(plant).contact
    N = plant.gear_ratio
    scale = ct.ss([], [], [], [[1.0 / N]], inputs="theta1", outputs="y", name="scale")
    err = ct.summing_junction(inputs=["r", "-y"], output="e")
    T = ct.interconnect([P, C, scale, err], inputs=["r", "xi2"], outputs="theta2", ignore_outputs=["s", "force"])
    by_hand = ct.feedback(ct.ss(C) * ct.ss(P["theta1", "xi1"]) / N)

    def key(z: complex) -> tuple[float, float]:
        return z.real, z.imag

    assert_allclose(sorted(T.poles(), key=key), sorted(by_hand.poles(), key=key), rtol=1e-8)


def test_pid_transfer_functions_connect_to_a_trains_mode_models_by_name() -> None:
    # a train's mode models name the motor torque xi0 (xi1 is the first intermediate shaft's, not an input): with the
    # default xi1 interconnect warned of an unused output pid.xi1 and left the loop open (its poles: the plant's 0 and
    # the PID's own); output="xi0" closes it as by hand
    import warnings

    from gearctl import InputError, load_controller

    plant = build_plant(load_model("servo_2stage_phm09"))
    pid = load_controller("pid", plant)
    P = linearize_modes(plant).contact
    assert P.input_labels[0] == "xi0" and "xi1" not in P.input_labels
    C = pid.gains.tf(output=P.input_labels[0])
    assert (C.input_labels, C.output_labels) == (["e"], ["xi0"])
    assert pid.gains.sampled_tf(1e-3, output="xi0").output_labels == ["xi0"]
    err = ct.summing_junction(inputs=["r", "-theta2"], output="e")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no unused signal
        T = ct.interconnect([P, C, err], inputs=["r", "xi2"], outputs="theta2",
                            ignore_outputs=["theta0", "s1", "s2", "force1", "force2"])
    by_hand = ct.feedback(ct.ss(C) * ct.ss(P["theta2", "xi0"]))

    def key(z: complex) -> tuple[float, float]:
        return z.real, z.imag

    assert_allclose(sorted(T.poles(), key=key), sorted(by_hand.poles(), key=key), rtol=1e-8)
    assert max(T.poles().real) < 0  # the loop is closed and stable
    for bad in ("", 1):
        with pytest.raises(InputError, match="is not a signal name") as exc:
            pid.gains.tf(output=bad)  # type: ignore[arg-type]
        assert exc.value.field == "output"
