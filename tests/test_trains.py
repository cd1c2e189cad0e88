"""Gear trains (issue 17): the catalog's trains, the physics of n stages, and every command on a train.

Oracles, each with its tolerance where it is asserted:

1. identity: a one-stage ``[[stage]]`` file written from ``shing1993_servo.toml``'s data is the pair, to the
   last bit (``numpy.array_equal``), open loop and in closed loop with the catalog PID and MPC;
2. an independent integration: :func:`gearctl.oracle.reference_solution` (``solve_ivp`` with terminal events,
   written from the report's equations, rtol 1e-12) for a two-stage train: the same impact sequence per stage
   and the gaps within 1e-6 of each stage's ``b``;
3. closed forms: the lost motion ``sum_i 2 b_i / (r_b2,i prod_(j>i) N_j)`` measured by a slow reversal (2 %),
   the train's resonances as the undamped eigenvalues of ``M^-1 K`` built here, a separated stage's
   two-inertia mode, the ISO 21771 operating pressure angle of the shifted 17-tooth pinion;
4. invariants: energy without damping, the motor-equivalent angular momentum
   ``sum_j J_j omega_j / N_(0->j)`` without friction (mesh damping is internal), zero force in a stage's gap
   while the others carry load, front/back mirror symmetry per stage;
5. closed-loop figures on the three-stage catalog train, with the measured ratios stated and a margin kept.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
import scipy.optimize
from numpy.testing import assert_allclose

from gearctl import InputError, Plant, build_plant, load_model
from gearctl.catalog import load_controller, read_toml, resolve
from gearctl.cli import main
from gearctl.closedloop import simulate_closed_loop
from gearctl.design import deadzone
from gearctl.files import toml_value
from gearctl.geometry import involute, pair_geometry
from gearctl.oracle import reference_solution
from gearctl.references import reference
from gearctl.runs import execute, make_run
from gearctl.simulate import SimulationResult, report_case, simulate

TWO = "servo_2stage_phm09"
THREE = "servo_3stage_quanser_srv02"
PINION = "pinion17_shifted_shing1993"
TRAINS = [TWO, THREE]


@pytest.fixture(scope="module")
def two() -> Plant:
    return build_plant(load_model(TWO))


@pytest.fixture(scope="module")
def three() -> Plant:
    return build_plant(load_model(THREE))


def without(plant: Plant, *, damping: bool = False, friction: bool = False) -> Plant:
    """The plant with every stage's ``c`` and/or every shaft's viscous and Coulomb friction set to 0."""
    stages = tuple(dataclasses.replace(s, c=0.0) for s in plant.stages) if damping else plant.stages
    shafts = tuple(dataclasses.replace(s, d=0.0, tc=0.0) for s in plant.shafts) if friction else plant.shafts
    return dataclasses.replace(plant, stages=stages, shafts=shafts)


def ratio_to(plant: Plant) -> list[float]:
    """``N_(0->j)``: motor angle over shaft ``j``'s angle in a rigid train."""
    return [math.prod(s.ratio for s in plant.stages[:j]) for j in range(plant.n_stages + 1)]


# --- 0. the catalog's trains -------------------------------------------------------------------------------


@pytest.mark.parametrize(("name", "ratios"), [(TWO, (3.0, 80 / 48)), (THREE, (3.5, 4.0, 5.0))])
def test_catalog_trains(name: str, ratios: tuple[float, ...]) -> None:
    model = load_model(name)
    plant = build_plant(model)
    assert model.n_stages == len(ratios)
    assert model.source["citation"].strip() and "ASSUMED" in model.source["notes"]
    # teeth ratios from the sources (PHM09: 96/32 and 80/48, overall 5; SRV02: Kgi 14 = 3.5 x 4, Kge 5,
    # overall 70); rtol 1e-12: exact fractions
    assert_allclose([s.ratio for s in plant.stages], ratios, rtol=1e-12)
    assert_allclose(plant.gear_ratio, {TWO: 5.0, THREE: 70.0}[name], rtol=1e-12)
    for sm in model.stages:  # within the model's range: b <= 0.5 module, b < 0.01 m
        assert 0 < sm.pair.backlash <= 0.5 * sm.pair.module and sm.pair.backlash < 0.01
    assert model.sensors.motor_encoder_cpr == model.sensors.load_encoder_cpr == 2**20
    assert math.isfinite(plant.torque_limit) and plant.torque_limit > 0
    # the lost motion is many encoder counts (2 pi / 2^20 = 6 urad): a controller can see the gap
    assert plant.lost_motion > 100 * 2 * math.pi / 2**20


def test_srv02_numbers_reproduce_the_manual() -> None:
    """SRV02 User Manual Tables 3.1 and 3.2, as cited in the model file."""
    model = load_model(THREE)
    last = pair_geometry(model.stages[-1].pair)
    # Table 3.2 radii of the 24- and 120-tooth gears, 6.35e-3 and 0.032 m (printed to 2-3 digits: rtol 1 %)
    assert_allclose(last.pitch_radius, (6.35e-3, 0.032), rtol=0.01)
    # Table 3.1: rotor 3.90e-7 + tachometer 7.06e-8 kg m^2 on the motor (entered to 3 digits: rtol 2e-3);
    # torque limit kt 7.68e-3 N m/A x Imax 1 A, disc load 0.04 kg of radius 0.05 m (rtol 1e-12: one product)
    assert_allclose(model.servo.motor_inertia, 3.90e-7 + 7.06e-8, rtol=2e-3)
    assert_allclose(model.servo.torque_limit, 7.68e-3 * 1.0, rtol=1e-12)
    assert_allclose(model.servo.load_inertia, 0.5 * 0.04 * 0.05**2, rtol=1e-12)
    # Table 3.2: gear inertias as solid disks of the listed masses and radii (entered to 3-4 digits)
    assert_allclose(last.inertia, (0.5 * 0.005 * 6.35e-3**2, 0.5 * 0.083 * 0.032**2), rtol=2e-3)


def test_phm09_motor_is_about_the_reflected_load(two: Plant) -> None:
    # servo sizing: the motor rotor about the inertia reflected to the motor shaft (within a factor 2)
    reflected = sum(sh.J / n**2 for sh, n in zip(two.shafts[1:], ratio_to(two)[1:], strict=True))
    motor = load_model(TWO).servo.motor_inertia
    assert 0.5 <= motor / reflected <= 2.0


# --- 1. a one-stage train is the pair, to the last bit ----------------------------------------------------


@pytest.fixture(scope="module")
def one_stage_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``shing1993_servo.toml`` rewritten as one ``[[stage]]`` (teeth, pair keys; material and dynamics as
    the train's defaults), from the catalog file's parsed data, so the two cannot drift apart."""
    data = read_toml(resolve("shing1993_servo", "models"))
    stage = {"teeth1": data["gear1"]["teeth"], "teeth2": data["gear2"]["teeth"], **data["pair"]}
    lines = []
    for table in ("source", "material", "dynamics", "servo", "sensors"):
        lines.append(f"[{table}]")
        lines += [f"{k} = {toml_value(v)}" for k, v in data[table].items()]
    lines.append("[[stage]]")
    lines += [f"{k} = {toml_value(v)}" for k, v in stage.items()]
    path = tmp_path_factory.mktemp("train") / "shing1993_servo_one_stage.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def pair_and_train(one_stage_file: Path) -> tuple[Plant, Plant]:
    return build_plant(load_model("shing1993_servo")), build_plant(load_model(one_stage_file))


def test_one_stage_train_is_the_pair(one_stage_file: Path, pair_and_train: tuple[Plant, Plant]) -> None:
    text = one_stage_file.read_text()
    assert "[[stage]]" in text and "[gear1]" not in text and "[pair]" not in text
    pair, train = pair_and_train
    assert train.n_stages == 1
    assert pair.shafts == train.shafts
    for a, b in zip(pair.stages, train.stages, strict=True):
        for f in dataclasses.fields(a):
            assert np.array_equal(getattr(a, f.name), getattr(b, f.name)), f.name
    for f in ("kind", "contact_law", "friction_law", "coulomb_velocity", "torque_limit", "load_torque"):
        assert getattr(pair, f) == getattr(train, f), f


def assert_same_run(a: SimulationResult, b: SimulationResult) -> None:
    for f in ("t", "x", "u", "s", "mode", "force", "event_log"):
        assert np.array_equal(getattr(a, f), getattr(b, f)), f
    assert a.counts.keys() == b.counts.keys()
    assert all(np.array_equal(a.counts[k], b.counts[k]) for k in a.counts)
    assert a.max_penetration == b.max_penetration and a.steps == b.steps


@pytest.mark.parametrize("case", ["free", "load"])
def test_one_stage_train_simulates_bit_identically(case: str, pair_and_train: tuple[Plant, Plant]) -> None:
    pair, train = pair_and_train
    a, b = report_case(pair, case, 0.02), report_case(train, case, 0.02)
    assert sum(a.impact_counts().values()) >= 10  # the run has contacts to compare
    assert_same_run(a, b)


@pytest.mark.parametrize("controller", ["pid", "mpc"])
def test_one_stage_train_closed_loop_bit_identical(controller: str, one_stage_file: Path,
                                                   pair_and_train: tuple[Plant, Plant]) -> None:
    pair, train = pair_and_train
    sensors = load_model("shing1993_servo").sensors
    assert load_model(one_stage_file).sensors == sensors
    runs = [simulate_closed_loop(p, load_controller(controller, p), reference("sine"), 1.0, sensors=sensors)
            for p in (pair, train)]
    a, b = runs
    assert a.impact_count >= 10
    for f in ("t", "x", "reference", "torque", "command", "y_motor", "y_load", "mode"):
        assert np.array_equal(getattr(a, f), getattr(b, f), equal_nan=True), f
    assert np.array_equal(a.event_log, b.event_log)
    assert all(np.array_equal(a.counts[k], b.counts[k]) for k in a.counts)
    assert len(a.fallbacks) == len(b.fallbacks)


# --- 2. two stages against solve_ivp with events ---------------------------------------------------------


@pytest.mark.parametrize(("case", "torque"), [("free", (0.0, 0.0)), ("load", (1.0, -1.0))])
def test_two_stage_matches_reference_solution(two: Plant, case: str, torque: tuple[float, float]) -> None:
    res = report_case(two, case, 0.02, dt=1e-5)
    assert res.solver.startswith("exact")
    x_ref, impacts_ref = reference_solution(two, res.x[:, 0], res.t, torque=torque, rtol=1e-12)
    impacts = [e for e in res.impacts if e.kind == "impact"]
    assert len(impacts) == len(res.impacts)  # no plastic (Zeno) landings in these runs
    seq = [(e.stage + 1) * (1 if e.side == "front" else -1) for e in impacts]
    # the same impact sequence, stage by stage and flank by flank (oracle: side x stage number)
    assert seq == [side for _, side in impacts_ref]
    for i in (1, 2):
        assert sum(abs(s) == i for s in seq) >= 10  # both stages impact, on both flanks where the case has them
    # impact times: measured agreement 3.4e-12 s; atol 1e-9 s (2e-6 of the ~0.5 ms between impacts)
    assert_allclose([e.t for e in impacts], [t for t, _ in impacts_ref], rtol=0, atol=1e-9)
    # gaps within 1e-6 of each stage's b at every output (measured 7.3e-10 b)
    ds = np.abs(res.s - two.gaps(x_ref)) / np.array(two.backlashes)[:, None]
    assert ds.max() <= 1e-6


def test_two_stage_energy_conserved_without_damping(two: Plant) -> None:
    undamped = without(two, damping=True, friction=True)
    res = report_case(undamped, "free", 0.02)
    assert all(c["front"] >= 10 and c["back"] >= 10 for c in res.stage_impacts())
    E = undamped.energy(res.x)
    w = two.n_stages + 1
    # all kinetic at t = 0: 0.5 sum J_j omega_j^2 (closed form, rtol 1e-15)
    assert_allclose(E[0], 0.5 * sum(sh.J * res.x[w + j, 0] ** 2 for j, sh in enumerate(undamped.shafts)),
                    rtol=1e-15)
    # conserved to 1e-6 over 20 ms of impacts (measured 1.4e-11)
    assert np.max(np.abs(E - E[0])) <= 1e-6 * E[0]


# --- 3. the lost motion, measured ------------------------------------------------------------------------


def slow_reversal(plant: Plant, *, load_friction: float, speed: float = 0.05,
                  T: float = 0.4) -> tuple[SimulationResult, float]:
    """The motor position-controlled at ``speed`` [rad/s of load angle] forward for ``T`` seconds, then back;
    the load held by ``load_friction`` [N m] of stick-slip Coulomb friction, so it stops where the last flank
    leaves it. Returns the run and the lost motion measured as the jump of ``theta_motor / N - theta_load``
    between the steady forward and the steady backward motion [rad at the output]."""
    q = dataclasses.replace(plant, shafts=(*plant.shafts[:-1], dataclasses.replace(plant.shafts[-1],
                                                                                   tc=load_friction)))
    N, w = q.gear_ratio, q.n_stages + 1
    eq = q.equivalent_pair()
    J = eq.J1 + eq.J2 / N**2
    wc = 2 * math.pi * 30.0  # a 30 Hz position loop on the motor, sampled at 10 kHz
    kp, kd = J * wc**2, 2 * J * wc
    V = speed * N

    def torque(t: float, x: np.ndarray) -> tuple[float, float]:
        r, v = (V * t, V) if t < T else (V * (2 * T - t), -V)
        u = kp * (r - x[0]) + kd * (v - x[w])
        return min(max(u, -q.torque_limit), q.torque_limit), 0.0

    res = simulate(q, np.zeros(q.nx), 2 * T, torque=torque, dt=1e-4)
    offset = res.x[0] / N - res.x[w - 1]
    fwd = (res.t > 0.6 * T) & (res.t < 0.95 * T)
    bwd = (res.t > 1.6 * T) & (res.t < 1.95 * T)
    # a clean experiment: steady motion on the front flanks of every stage, then on the back flanks
    assert np.all(res.mode[:, fwd] == 1) and np.all(res.mode[:, bwd] == -1)
    assert_allclose(res.x[-1, fwd], speed, rtol=1e-6)
    # the load stands still while the motor crosses the gaps (stuck by friction: exactly zero speed)
    assert np.count_nonzero(res.x[-1, (res.t > T) & (res.t < 1.5 * T)] == 0.0) > 50
    return res, float(offset[fwd].mean() - offset[bwd].mean())


@pytest.mark.parametrize(("name", "backlash", "friction"), [
    (TWO, (6e-5, 1.5e-5), 0.01),  # unequal stages: the weights 1 / (r_b2,i prod N_j) are tested
    (THREE, None, 1e-3),
])
def test_lost_motion_measured_by_a_slow_reversal(name: str, backlash: tuple[float, ...] | None,
                                                 friction: float) -> None:
    plant = build_plant(load_model(name), backlash=backlash)
    # closed form, written here from the stages (not from Plant.lost_motion)
    closed = sum(2 * s.backlash / (s.rb2 * math.prod(t.ratio for t in plant.stages[i + 1:]))
                 for i, s in enumerate(plant.stages))
    assert_allclose(plant.lost_motion, closed, rtol=1e-12)
    _, measured = slow_reversal(plant, load_friction=friction, speed=0.05)
    # 2 % (issue 17); measured 5.2e-5 (two stages) and 7.4e-5 (three) above the lost motion
    assert_allclose(measured, plant.lost_motion, rtol=0.02)
    # ... which is the stages' deflection under the torque the flanks carry in steady motion, the load's
    # friction and viscous drag, (T_c + d v) / K at each end, K the stages in series seen at the load:
    # measured agreement 1e-15, rtol 1e-9
    K = 1 / sum(1 / (s.k * (s.rb2 * math.prod(t.ratio for t in plant.stages[i + 1:])) ** 2)
                for i, s in enumerate(plant.stages))
    carried = friction + plant.shafts[-1].d * 0.05
    assert_allclose(measured, closed + 2 * carried / K, rtol=1e-9)


# --- 4. invariants per stage -----------------------------------------------------------------------------


@pytest.mark.parametrize("name", TRAINS)
def test_momentum_conserved_without_friction(name: str) -> None:
    """Mesh forces are internal: ``sum_j J_j omega_j / N_(0->j)`` is constant (mesh damping included)."""
    plant = without(build_plant(load_model(name)), friction=True)
    w = plant.n_stages + 1
    x0 = np.zeros(plant.nx)
    x0[w] = 50.0  # the report's free case with the intermediate shafts at rest: every stage impacts
    res = simulate(plant, x0, 0.02)
    assert all(c["front"] + c["back"] >= 10 for c in res.stage_impacts())
    P = sum(sh.J * res.x[w + j] / n for j, (sh, n) in enumerate(zip(plant.shafts, ratio_to(plant), strict=True)))
    # rtol 1e-10 (measured 6.4e-13 and 4.9e-13); the mesh damping dissipates meanwhile (energy -52 % and -9 %):
    # momentum is kept although energy is not
    assert_allclose(P, P[0], rtol=1e-10)
    E = plant.energy(res.x)
    assert E[-1] < 0.95 * E[0]


@pytest.mark.parametrize("name", TRAINS)
def test_zero_force_in_each_stage_gap(name: str) -> None:
    plant = build_plant(load_model(name))
    res = report_case(plant, "load", 0.02)
    b = np.array(plant.backlashes)[:, None] * np.ones_like(res.s)
    gap = res.mode == 0
    for i in range(plant.n_stages):
        others_loaded = np.any(np.delete(res.mode, i, axis=0) != 0, axis=0)
        # stage i in its gap while another stage carries load: there are such samples, and no force
        assert np.count_nonzero(gap[i] & others_loaded) >= 10
        assert np.all(res.force[i, gap[i]] == 0.0)
    # the mode is the gap's: |s| <= b in separation, sigma s >= b in contact (rtol 1e-9 at the boundary)
    assert np.all(np.abs(res.s[gap]) <= b[gap] * (1 + 1e-9))
    assert np.all((res.mode * res.s)[~gap] >= b[~gap] * (1 - 1e-9))
    # in contact the force is the report's law, eqs 3 and 10, per stage (rtol 1e-12)
    w = plant.n_stages + 1
    for i, st in enumerate(plant.stages):
        on = ~gap[i]
        sig = res.mode[i, on]
        v = st.rb1 * res.x[w + i, on] - st.rb2 * res.x[w + i + 1, on]
        assert_allclose(res.force[i, on], st.k * (res.s[i, on] - sig * st.backlash) + st.c * v, rtol=1e-12,
                        atol=1e-9 * st.k * st.backlash)


@pytest.mark.parametrize("name", TRAINS)
def test_mirror_symmetry_per_stage(name: str) -> None:
    plant = build_plant(load_model(name))
    x0 = np.zeros(plant.nx)
    w = plant.n_stages + 1
    x0[w] = 50.0  # the report's free case with intermediate shafts at rest: every stage impacts
    a, b = simulate(plant, x0, 0.02), simulate(plant, -x0, 0.02)
    # negating every angle and speed swaps front and back: exact (the solver's arithmetic is symmetric)
    assert np.array_equal(b.x, -a.x) and np.array_equal(b.mode, -a.mode) and np.array_equal(b.force, -a.force)
    for sa, sb in zip(a.stage_impacts(), b.stage_impacts(), strict=True):
        assert sa["front"] + sa["back"] >= 5
        assert (sa["front"], sa["back"]) == (sb["back"], sb["front"])
    assert [e.t for e in a.impacts] == [e.t for e in b.impacts]


# --- 5. the 17-tooth shifted pinion ----------------------------------------------------------------------


def test_pinion17_shifted_is_accepted() -> None:
    model = load_model(PINION)
    pair = model.pair
    assert (pair.teeth1, pair.x1, pair.x2) == (17, 0.3, 0.0)
    g = pair_geometry(pair)
    # ISO 21771: inv(alpha_w) = inv(alpha) + 2 (x1 + x2) tan(alpha) / (z1 + z2), solved here by bracketing
    # (independent of gearctl's Newton iteration); rtol 1e-12
    rhs = involute(pair.pressure_angle) + 2 * (pair.x1 + pair.x2) * math.tan(pair.pressure_angle) / (17 + 68)
    alpha_w = scipy.optimize.brentq(lambda a: involute(a) - rhs, 0.1, 1.2, xtol=1e-15)
    assert_allclose(g.operating_pressure_angle, alpha_w, rtol=1e-12)
    a = pair.module * (17 + 68) / 2
    assert_allclose(g.centre_distance, a * math.cos(pair.pressure_angle) / math.cos(alpha_w), rtol=1e-12)
    assert g.contact_ratio > 1.4
    # without the shift the 17-tooth pinion is undercut (limit 17.1 teeth at 20 deg) and refused
    with pytest.raises(InputError, match=r"\[gear1\] teeth = 17 is below the undercut limit"):
        load_model(PINION, x1=0.0)


def test_pinion17_runs_info_and_track(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", PINION]) == 0
    out = capsys.readouterr().out
    assert "17 x 68 teeth" in out and "profile shift" in out
    assert main(["info", PINION, "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["teeth"] == [17, 68] and info["profile_shift"] == [0.3, 0.0]
    assert info["operating_pressure_angle_deg"] > 20.0
    assert main(["track", PINION, "pid", "--json", "--duration", "1.0"]) == 0
    run = json.loads(capsys.readouterr().out)
    lost = build_plant(load_model(PINION)).lost_motion
    # the motor-encoder PID leaves about half the lost motion as error (1.57e-3 rad here): finite, bounded
    assert run["ok"] and 0 < run["rms_error"] < lost


# --- 6. controllers on the three-stage catalog train -----------------------------------------------------


@pytest.fixture(scope="module")
def sine_rms() -> Callable[[str, str], float]:
    """RMS load-angle error of a catalog controller on a catalog model, 1 Hz sine, 3 s (``gearctl track``)."""
    cache: dict[tuple[str, str], float] = {}

    def rms(model: str, controller: str) -> float:
        if (model, controller) not in cache:
            rr = execute(make_run(model, controller))
            assert rr.ok, rr.message
            cache[model, controller] = rr.metrics.rms_error
        return cache[model, controller]

    return rms


def test_three_stage_deadzone_inverse_beats_pid(sine_rms: Callable[[str, str], float], three: Plant) -> None:
    """The dead-zone inverse on the three-stage train (motor encoder, equivalent lost motion at the output).

    Measured: train PID 9.87e-4 rad (about half the 2.02e-3 rad lost motion, as a motor-encoder PID leaves),
    dead-zone inverse 1.04e-4: ratio 9.5 (bound 5; 1.16e-4 and 8.5 before the crossing's feedforward counted only
    the shafts the motor moves).
    """
    assert 0.3 * three.lost_motion < sine_rms(THREE, "pid") < 0.7 * three.lost_motion
    train = sine_rms(THREE, "pid") / sine_rms(THREE, "deadzone_inverse")
    assert train >= 5.0, train
    assert sine_rms(THREE, "deadzone_inverse") < 0.1 * three.lost_motion


def test_crossing_carries_the_shafts_it_has_picked_up(two: Plant) -> None:
    """What the inverse's crossing moves (:func:`gearctl.design.deadzone.carried_by_motor`), from the model's
    shafts written out here: the motor alone until the first stage's gap closes (its share of the lost motion,
    1064 of 3193 urad on ``servo_2stage_phm09``), then the motor and the intermediate shaft reflected through
    the first stage's ratio 3; on a pair one row, the pair's motor side."""
    rows = deadzone.carried_by_motor(two)
    s1, s2 = two.stages
    lost1 = 2 * s1.backlash / (s1.rb2 * s2.ratio)
    lost2 = 2 * s2.backlash / s2.rb2
    assert len(rows) == 2
    assert rows[0][0] == pytest.approx(lost1 / (lost1 + lost2), rel=1e-12)
    assert rows[0][0] == pytest.approx(1 / 3, rel=1e-3)  # equal b on both stages, same centre distance
    assert rows[1][0] == 1.0
    m, mid = two.shafts[0], two.shafts[1]
    assert rows[0][1:] == (m.J, m.d, m.tc)
    assert rows[1][1] == pytest.approx(m.J + mid.J / s1.ratio**2, rel=1e-12)
    assert rows[1][1] == pytest.approx(two.equivalent_pair().J1, rel=1e-12)  # all upstream shafts: the design J1
    pair = build_plant(load_model("shing1993_servo"))
    assert deadzone.carried_by_motor(pair) == ((1.0, pair.J1, pair.d1, pair.tc1),)
    # a stage without backlash: its shaft is always carried (the row before it ends where that stage's starts)
    assert [r[0] for r in deadzone.carried_by_motor(two.with_backlash([0.0, s2.backlash]))] == [0.0, 1.0]
    assert [r[0] for r in deadzone.carried_by_motor(two.with_backlash([s1.backlash, 0.0]))] == [1.0, 1.0]
    assert [r[0] for r in deadzone.carried_by_motor(two.with_backlash(0.0))] == [0.0, 1.0]  # every shaft, always


def test_crossing_share_is_that_of_the_ramps_own_travel(two: Plant) -> None:
    """The inverse picks the row by the share of its ramp's travel: from a settled flank that is the share of the
    lost motion; from the centred start-up (every gap half open) the same shares of the half gaps left. The
    motor is alone at the start of either and carries the intermediate shaft at the end."""
    inv = load_controller("deadzone_inverse", two)
    rows = deadzone.carried_by_motor(two)
    half, end0 = inv._offset, rows[0][0]
    inv._ramp.reset(0.0)  # the start-up: centred
    inv._ramp.move_to(0.0, half)
    assert inv._carried_now(0.5 * end0 * half) == rows[0][1:]
    assert inv._carried_now(1.01 * end0 * half) == rows[1][1:]
    inv._ramp.reset(half)  # from the front flank to the back one
    inv._ramp.move_to(0.0, -half)
    assert inv._carried_now(half - 0.99 * end0 * 2 * half) == rows[0][1:]
    assert inv._carried_now(half - 1.01 * end0 * 2 * half) == rows[1][1:]


def test_two_stage_inverse_crossing_does_not_fling_the_intermediate_shaft(
        sine_rms: Callable[[str, str], float], two: Plant) -> None:
    """On ``servo_2stage_phm09`` (an intermediate shaft half the motor's inertia, reflected) the crossing's
    feedforward counts only what the motor moves. Measured: sine RMS 7.52e-5 rad against the PID's 1.52e-3
    (20x); with the intermediate shaft in the feedforward from the crossing's start the motor ran ahead of its
    ramp into it at 0.2 rad/s, flung it into the load, and the inverse gave 5.32e-4 (2.9x). Kept at 8x."""
    pid, inv = sine_rms(TWO, "pid"), sine_rms(TWO, "deadzone_inverse")
    print(f"\nservo_2stage_phm09 sine: PID {pid:.3g}, inverse {inv:.3g} ({pid / inv:.1f}x)")
    assert inv * 8.0 <= pid
    assert inv < 0.05 * two.lost_motion


def test_inverse_contact_check_is_a_pairs(tmp_path: Path, three: Plant) -> None:
    """On a train the motor meets the intermediate shafts before the load, and their impacts make it lag its ramp
    as a too large estimate would: with the check on, a 5 ms crossing on the three-stage train ended 6 crossings
    early in 3 s, each stopping the offset short (RMS 8.66e-4 rad, the PID's 9.87e-4). With it off on trains:
    6.1e-5 rad (16x below the PID; 4.7e-5 before the crossing's feedforward counted only the shafts the motor
    moves; the 10 ms catalog crossing gives 1.04e-4; 4-7 ms gave 5e-5 to 2.1e-4, the loop is that sensitive). Kept:
    no early end, RMS
    under 2e-4 rad (a quarter of the misfiring check's), and the check still on for a pair."""
    from gearctl.runs import design_controller, execute_controller

    spec = resolve("deadzone_inverse", "controllers").read_text()
    assert "crossing_time = 0.01 " in spec
    path = tmp_path / "inverse_5ms.toml"
    path.write_text(spec.replace("crossing_time = 0.01 ", "crossing_time = 0.005 "))
    run = make_run(THREE, path)
    inv = design_controller(run.design)
    inv.reset()
    res = execute_controller(run, inv)
    assert inv.contacts == 0
    assert res.metrics.rms_error < 2e-4, res.metrics.rms_error
    assert inv.describe()["contact_lag"] is None
    pair = load_controller("deadzone_inverse", build_plant(load_model("shing1993_servo")))
    assert pair.describe()["contact_lag"] == deadzone.CONTACT_LAG


@pytest.mark.parametrize(("name", "factor"), [(THREE, 30.0), (TWO, 150.0)])
def test_inverse_on_a_trains_equivalent_pair(name: str, factor: float) -> None:
    """What the intermediate shafts cost: on the train's one-gap equivalent pair (:meth:`Plant.equivalent_pair`,
    the true plant and the design model) the inverse beats the PID by the pair's kind of factor. Measured (RMS from
    0.5 s, as ``track``): three-stage 9.89e-4 / 1.95e-5 (51x, the train itself 9.5x), two-stage 1.51e-3 / 4.97e-6
    (304x, the train itself 20x). Kept at 30x and 150x."""
    model = load_model(name)
    pair = build_plant(model).equivalent_pair()
    rms = {}
    for ctrl in ("pid", "deadzone_inverse"):
        c = load_controller(ctrl, pair, sensors=model.sensors)
        res = simulate_closed_loop(pair, c, reference("sine"), 3.0, sensors=model.sensors)
        e = res.load_angle - res.reference
        rms[ctrl] = float(np.sqrt(np.mean(e[res.t >= 0.5] ** 2)))
    print(f"\n{name} equivalent pair sine: PID {rms['pid']:.3g}, inverse {rms['deadzone_inverse']:.3g} "
          f"({rms['pid'] / rms['deadzone_inverse']:.0f}x)")
    assert rms["deadzone_inverse"] * factor <= rms["pid"]


@pytest.mark.xfail(strict=True, reason="issue 17 asks for the same kind of factor as on the pair: the inverse beats "
                   "the PID 173x on shing1993_servo (6.47e-4 / 3.74e-6 rad) but 9.5x on the three-stage train "
                   "(9.87e-4 / 1.04e-4; 16x with a 5 ms crossing, 3x worse with 6 ms: chaotic). On the train's "
                   "equivalent one-gap pair (the true plant and the design model) it gives 1.95e-5, 51x: even without "
                   "the intermediate shafts this motor-dominated train would not reach the pair's factor. The "
                   "crossing flings the light intermediate shafts (restitution ~0.85), and through them the load, "
                   "ahead of a motor 24x the reflected load; with the last stage's backlash alone the inverse gives "
                   "32x. The one-gap inverse does not see the intermediate shafts (a per-stage inverse would be "
                   "needed). Traced: the error is a 750 urad peak at every reversal (365 urad RMS over the 50 ms "
                   "around it, 1 urad between), not chaos: the 10 ms crossing meets the first intermediate shaft 1 ms "
                   "in at 0.12 rad/s (load units); it rattles in the first stage's gap and, through the second, kicks "
                   "the load (viscous time constant 6 ms) to 0.2 rad/s before the motor lands. That gap, 6.7 % of the "
                   "lost motion, is what costs the factor: closed, 58x (tests/test_h3_train_crossing.py). Tried: a "
                   "crossing staged per stage (a sin^2 to each stage's flank in turn, the feedforward with the shafts "
                   "picked up) lands on the first shaft within 20 urad at 0.04 rad/s, but a flank can only decelerate "
                   "the shaft it pushes: the shaft leaves it at the next segment's peak relative speed and meets the "
                   "next gear at that speed (1e-4 to 1e-3 rad RMS over 10-30 ms crossings)")
def test_three_stage_inverse_factor_is_that_of_the_pair(sine_rms: Callable[[str, str], float]) -> None:
    train = sine_rms(THREE, "pid") / sine_rms(THREE, "deadzone_inverse")
    pair = sine_rms("shing1993_servo", "pid") / sine_rms("shing1993_servo", "deadzone_inverse")
    assert train >= pair / 3, (train, pair)


@pytest.mark.xfail(strict=True, reason="the MPC plans on the equivalent one-gap pair (Plant.equivalent_pair), contact "
                   "declared within the share of the lost motion of the stages before the last, torques weighed in "
                   "shares of the torque limit: on the three-stage train it beats the PID by 4.8x (RMS 2.06e-4 rad "
                   "against 9.87e-4; 5.2x on an earlier machine, a chaotic loop; 7.5x before its crossings were "
                   "re-decided against staying, which keeps the train's load step from running away), not by half "
                   "the pair's 226x. The intermediate shafts, "
                   "free between two gaps and unmeasured, are hit at the crossing's speed and bounce (986 impacts "
                   "in 3 s against 126 on the pair); on servo_2stage_phm09, whose intermediate shaft, reflected, is "
                   "half the motor shaft's inertia, the MPC gives 1.42e-3 (1.21e-3 on an earlier machine) against "
                   "the PID's 1.52e-3")
def test_three_stage_mpc_beats_pid(sine_rms: Callable[[str, str], float]) -> None:
    """The same kind of factor as on the pair: at least half the pair's PID / MPC ratio, and 2.

    Measured: train PID 9.87e-4 rad, MPC 2.06e-4 (ratio 4.8); on shing1993_servo 6.47e-4 / 2.86e-6 = 226.
    """
    train = sine_rms(THREE, "pid") / sine_rms(THREE, "mpc")
    pair = sine_rms("shing1993_servo", "pid") / sine_rms("shing1993_servo", "mpc")
    assert train >= max(2.0, 0.5 * pair), (train, pair)


GRAVITY_JOINT = str(Path(__file__).parent / "data" / "robot_joint_2stage_gravity.toml")


def _step_rms(model: str, controller: str) -> float:
    rr = execute(make_run(model, controller, reference_kind="step"))
    assert rr.ok, rr.message
    return rr.metrics.rms_error


def test_inverse_on_a_reviewers_gravity_joint(sine_rms: Callable[[str, str], float]) -> None:
    # a reviewer's two-stage robot joint (profile-shifted pinions, a heavy load under gravity and Coulomb friction):
    # measured sine RMS 7.16e-6 rad against the PID's 1.54e-3 (215x; 7.13e-6 before the crossing counted only the
    # shafts the motor moves); kept at 50x
    pid, inv = sine_rms(GRAVITY_JOINT, "pid"), sine_rms(GRAVITY_JOINT, "deadzone_inverse")
    print(f"\ngravity joint sine: PID {pid:.3g}, inverse {inv:.3g} ({pid / inv:.0f}x)")
    assert inv * 50.0 <= pid


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=(
    "the MPC plans on the equivalent one-gap pair and does not see the intermediate shaft: on a reviewer's two-stage "
    "gravity joint, whose intermediate shaft reflects 23 % of the motor shaft's inertia, the step (0.05 rad, then a "
    "0.5 N m load step) rattles, 2067 impacts in 2 s: RMS 5.89e-3 rad against the PID's 2.04e-3 (2.9x worse; "
    "2.88e-3 before a torque at the QP's bound was set to the limit exactly, 9.17e-3 and 4.5x on an earlier "
    "machine and code, a chaotic loop; it ends on the target). With either "
    "stage's backlash 0 the MPC gives 5.6e-5 and 8.0e-5 (8x and 12x below the PID): the two gaps together, one "
    "unmeasured, are the trouble"))
def test_mpc_on_a_reviewers_gravity_joint_is_no_worse_than_the_pid() -> None:
    assert _step_rms(GRAVITY_JOINT, "mpc") <= _step_rms(GRAVITY_JOINT, "pid")


# --- 7. every command on a train -------------------------------------------------------------------------


def run_json(argv: list[str], capsys: pytest.CaptureFixture[str]) -> dict:
    """``main(argv + ['--json'])``: exit 0, one JSON object on stdout."""
    code = main([*argv, "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


def test_cli_info_train(capsys: pytest.CaptureFixture[str], two: Plant) -> None:
    assert main(["info", TWO]) == 0
    out = capsys.readouterr().out
    assert "2-stage train, ratio 5" in out and "stage 2: 48 x 80 teeth" in out
    info = run_json(["info", TWO], capsys)
    pair = run_json(["info", "shing1993_servo"], capsys)
    assert len(info["stages"]) == 2
    assert_allclose(info["lost_motion"], two.lost_motion, rtol=1e-15)
    # each stage carries the keys a pair's info has (less the model-level ones)
    model_level = {"model", "source", "plant", "stages_count", "lost_motion", "equivalent_stiffness", "sensors"}
    for st in info["stages"]:
        assert set(pair) - model_level <= set(st)
    assert [s["teeth"] for s in info["stages"]] == [[32, 96], [48, 80]]
    assert [s["backlash"] for s in info["stages"]] == list(two.backlashes)
    # the mesh mode and resonances are the coupled contact model's, as `linearize` gives them (a reviewer saw info
    # print the uncoupled per-stage estimate, 13608 against linearize's 17035 Hz on a four-stage train)
    lin = run_json(["linearize", TWO], capsys)
    assert info["plant"]["natural_frequency_hz"] == lin["natural_frequency_hz"]
    assert info["plant"]["resonances_hz"] == lin["resonances_hz"]


def test_a_stage_without_backlash_does_not_separate(two: Plant, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    # its contact law is one spring through s = 0: the separation model keeps it in contact (a reviewer's train
    # with a zero-backlash middle stage got every shaft free), and `linearize --mode stageK` refuses it
    from gearctl.modes import linearize_modes, separation_model

    plant = two.with_backlash([two.stages[0].backlash, 0.0])
    sep = separation_model(plant)
    osc = [p for p in sep.poles() if abs(p.imag) > 1.0]
    s2 = plant.stages[1]
    wn = math.sqrt(s2.k * (s2.rb1**2 / plant.shafts[1].J + s2.rb2**2 / plant.shafts[2].J))
    assert len(osc) == 2
    assert_allclose(np.abs(osc), wn, rtol=1e-3)  # stage 2's two-inertia mode
    assert not np.any(sep.C[sep.output_index["force1"]])  # stage 1 is separated
    modes = linearize_modes(plant)
    assert modes.stage_separated[1] is None and modes.stage_separated[0] is not None
    src = Path(resolve(TWO, "models")).read_text()
    f = tmp_path / "zero_stage2.toml"
    head, _, tail = src.partition("[[stage]]")
    second = tail.index("[[stage]]")
    stage2 = tail[second:]
    stage2 = re.sub(r"(?m)^backlash\s*=.*$", "backlash = 0.0", stage2, count=1)
    f.write_text(head + "[[stage]]" + tail[:second] + stage2)
    assert main(["linearize", str(f), "--mode", "stage2"]) == 2
    err = capsys.readouterr().err
    assert "stage 2 has no backlash" in err and len(err.strip().splitlines()) == 1
    assert main(["linearize", str(f), "--mode", "stage1"]) == 0


def test_cli_stiffness_per_stage(capsys: pytest.CaptureFixture[str], two: Plant) -> None:
    assert main(["stiffness", TWO, "--stage", "2"]) == 0
    out = capsys.readouterr().out
    assert "stage 2" in out and f"mean {two.stages[1].k:.4e}" in out
    assert main(["stiffness", TWO, "--stage", "3"]) == 2
    err = capsys.readouterr().err
    assert "stage" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_cli_simulate_train_csv_and_json(tmp_path: Path, capsys: pytest.CaptureFixture[str], three: Plant) -> None:
    path = tmp_path / "run.csv"
    assert main(["simulate", THREE, "--duration", "0.002", "--csv", str(path)]) == 0
    capsys.readouterr()
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    n = 3
    assert rows[0] == (["t"] + [f"theta{j}" for j in range(n + 1)] + [f"omega{j}" for j in range(n + 1)]
                       + [f"s{i}" for i in range(1, n + 1)] + [f"mode{i}" for i in range(1, n + 1)]
                       + [f"force{i}" for i in range(1, n + 1)])
    res = report_case(three, "free", 0.002)
    body = rows[1:]
    assert len(body) == res.t.size
    num = np.array([[float(v) for v in r[: 1 + 2 * (n + 1) + n]] for r in body]).T
    # the CSV is the API's run, printed: rtol 1e-8 (printed digits), atol for the zero crossings
    assert_allclose(num[0], res.t, rtol=1e-8, atol=1e-12)
    assert_allclose(num[1:1 + 2 * (n + 1)], res.x, rtol=1e-8, atol=1e-12)
    assert_allclose(num[1 + 2 * (n + 1):], res.s, rtol=1e-8, atol=1e-15)
    labels = {-1: "back", 0: "separation", 1: "front"}
    assert [[r[1 + 2 * (n + 1) + n + i] for r in body] for i in range(n)] == [
        [labels[int(m)] for m in res.mode[i]] for i in range(n)]
    summary = run_json(["simulate", THREE, "--duration", "0.002"], capsys)
    assert summary["impacts"] == res.stage_impacts()
    assert_allclose(summary["final"]["theta"], res.x[:n + 1, -1], rtol=1e-15)
    assert_allclose(summary["final"]["omega"], res.x[n + 1:, -1], rtol=1e-15)


def test_cli_linearize_train(capsys: pytest.CaptureFixture[str], two: Plant) -> None:
    lin = run_json(["linearize", TWO], capsys)
    assert lin["mode"] == "contact"
    # the train's resonances: the undamped eigenproblem K v = omega^2 M v built here from the stages
    # (rtol 1e-3: the poles are the damped system's; measured 7.5e-5)
    w = two.n_stages + 1
    K = np.zeros((w, w))
    for i, st in enumerate(two.stages):
        v = np.zeros(w)
        v[i], v[i + 1] = st.rb1, -st.rb2
        K += st.k * np.outer(v, v)
    ev = scipy.linalg.eigh(K, np.diag([sh.J for sh in two.shafts]), eigvals_only=True)
    assert_allclose(lin["resonances_hz"], np.sqrt(ev[1:]) / (2 * math.pi), rtol=1e-3)
    assert_allclose(lin["lost_motion"], two.lost_motion, rtol=1e-15)
    sep = run_json(["linearize", TWO, "--mode", "stage2"], capsys)
    assert sep["mode"] == "stage2"
    # stage 2 separated: the only oscillation is stage 1's two-inertia mode, sqrt(k (rb1^2/J0 + rb2^2/J1))
    # (|pole| of the damped pair; rtol 1e-3)
    s1 = two.stages[0]
    wn = math.sqrt(s1.k * (s1.rb1**2 / two.shafts[0].J + s1.rb2**2 / two.shafts[1].J))
    osc = [abs(complex(*p)) for p in sep["poles"] if abs(p[1]) > 1.0]
    assert len(osc) == 2
    assert_allclose(osc, wn, rtol=1e-3)


def test_cli_track_train(capsys: pytest.CaptureFixture[str], two: Plant) -> None:
    run = run_json(["track", TWO, "pid", "--duration", "1.0"], capsys)
    assert run["ok"] and run["model"] == TWO
    per_stage = run["impacts_per_stage"]
    assert len(per_stage) == 2
    assert sum(per_stage) == run["impacts"] and min(per_stage) > 0
    assert 0.3 * two.lost_motion < run["rms_error"] < two.lost_motion


def test_cli_precision_train(capsys: pytest.CaptureFixture[str], two: Plant) -> None:
    out = run_json(["precision", TWO, "pid", "--targets", "2", "--cycles", "1"], capsys)
    assert out["lost_motion"] == pytest.approx(two.lost_motion, rel=1e-15)
    # the motor-encoder PID stops each move within the lost motion of its target (measured at the target
    # 0: +8.4e-4 and -3.8e-4 rad); every deviation below the lost motion
    for row in out["per_target"]:
        assert abs(row["mean_up"]) < two.lost_motion and abs(row["mean_down"]) < two.lost_motion


def test_cli_bench_train(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bench.json"
    code = main(["bench", THREE, "--references", "sine", "--plants", "improved", "--no-precision", "--duration",
                 "0.5", "--jobs", "1", "--quiet", "--json", str(path)])
    capsys.readouterr()
    assert code == 0
    runs = json.loads(path.read_text())["runs"]
    assert {r["plant"] for r in runs} == {"improved", "backlash-free"}
    assert {r["controller"] for r in runs} >= {"pid", "deadzone_inverse", "mpc"}
    assert all(r["ok"] and r["model"] == THREE for r in runs)
    free = {r["controller"]: r for r in runs if r["plant"] == "backlash-free"}
    assert all(r["impacts"] == 0 for r in free.values())  # no gap, no impact


def _random_train(rng: np.random.Generator) -> str:
    """A model file of a random train: 1-4 stages, teeth from 14 (shifted) up, any module, backlash, servo."""
    n = int(rng.integers(1, 5))
    lines = ['[source]', 'citation = "random train (tests/test_trains.py)"', '', '[material]',
             'young_modulus = 2.07e11', 'poisson_ratio = 0.3', 'density = 7850.0', '', '[dynamics]',
             f'damping_ratio = {rng.choice([0.0, 0.02, 0.05, 0.3])}', '']
    for _ in range(n):
        z1 = int(rng.integers(12, 41))
        z2 = int(rng.integers(z1, 121))
        m = float(rng.choice([3e-4, 5e-4, 1e-3, 2e-3, 4e-3]))
        alpha = float(rng.choice([20.0, 25.0]))
        s2 = math.sin(math.radians(alpha)) ** 2
        # profile shift at least what the undercut limit z >= 2 (1 - x) / sin^2(alpha) asks, up to 0.4 more
        x1, x2 = (round(max(1.0 - z * s2 / 2.0 + 0.02, float(rng.uniform(-0.2, 0.4))), 2) for z in (z1, z2))
        lines += ['[[stage]]', f'teeth1 = {z1}', f'teeth2 = {z2}', f'module = {m}',
                  f'pressure_angle_deg = {alpha}',
                  f'face_width = {m * rng.uniform(4, 15):.6g}', f'backlash = {m * rng.uniform(0.0, 0.08):.6g}',
                  f'x1 = {x1}', f'x2 = {x2}', '']
    lines += ['[servo]', f'motor_inertia = {10 ** rng.uniform(-7, -3):.3g}',
              f'load_inertia = {10 ** rng.uniform(-5, 0):.3g}', f'viscous_friction2 = {10 ** rng.uniform(-5, -1):.3g}',
              f'coulomb_friction2 = {rng.choice([0.0, 0.01, 0.1])}',
              f'torque_limit = {rng.choice([0.01, 0.1, 1.0, 10.0])}', '']
    return "\n".join(lines)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_trains_run_every_command_or_refuse_in_one_line(seed: int, tmp_path: Path, capsys) -> None:
    """Trains nobody wrote by hand (the fuzzer draws pairs): every command ends with a result or one line, exit 2.
    27 such trains (1-4 stages, profile shift, 14-tooth pinions) ran clean from the command line when this test
    was written (also `precision` and the adaptive and reversal-offset controllers)."""
    path = tmp_path / f"train{seed}.toml"
    path.write_text(_random_train(np.random.default_rng(seed)))
    cmds = [["info", str(path)], ["linearize", str(path), "--json"],
            ["simulate", str(path), "--duration", "0.005", "--json"]]
    cmds += [["track", str(path), c, "--duration", "0.2", "--json"] for c in ("pid", "deadzone_inverse", "mpc")]
    for argv in cmds:
        rc = main(argv)
        err = capsys.readouterr().err
        assert rc in (0, 2), (argv, err)
        if rc == 2:
            assert err.count("\n") == 1, (argv, err)
        if argv[0] == "info":  # the generator keeps clear of the undercut limit: a valid train
            assert rc == 0, err


def test_plots_draw_a_train(tmp_path: Path) -> None:
    """`simulate --plot` and `track --plot` on a train: the load shaft and every stage's gap over its backlash (the
    pair's plots took x[1] and one s, and a train ended in a matplotlib traceback: a reviewer's battery)."""
    from gearctl.plots import plot_simulation, plot_tracking

    three = build_plant(load_model("servo_3stage_quanser_srv02"))
    sim = report_case(three, "free", 0.005)
    fig = plot_simulation({"improved": sim})
    gap_axis = fig.axes[4]
    assert len(gap_axis.get_lines()) == 3 + 2  # a line per stage and the two +-1 flank lines
    for i, line in enumerate(gap_axis.get_lines()[:3]):
        assert_allclose(line.get_ydata(), sim.s[i] / three.backlashes[i])
    assert_allclose(fig.axes[1].get_lines()[0].get_ydata(), sim.x[3])  # the load shaft, shaft 3
    out, res = execute(make_run("servo_3stage_quanser_srv02", "pid", duration=0.05), keep=True)
    fig = plot_tracking({"pid": res})
    assert_allclose(fig.axes[0].get_lines()[1].get_ydata(), res.x[3])
    assert_allclose(res.reference - fig.axes[0].get_lines()[1].get_ydata(), res.error, atol=1e-15)
    for argv in (["simulate", "servo_2stage_phm09", "--plot", str(tmp_path / "s.png")],
                 ["track", "servo_2stage_phm09", "pid", "--duration", "0.1", "--plot", str(tmp_path / "t.png")]):
        assert main(argv) == 0
    assert (tmp_path / "s.png").stat().st_size > 10_000 and (tmp_path / "t.png").stat().st_size > 10_000


def test_at_rest_take_up_brakes_with_what_follows_on_a_train() -> None:
    # a flank change decided at rest is taken up in contact, braking with at most what holds the load on the flank
    # over the inertia that follows the motor: on a train the load's and every intermediate shaft's (reflected to
    # the load), on a pair the load's alone
    from gearctl.precision import precision_test

    for name in ("shing1993_servo", "servo_2stage_phm09", "servo_3stage_quanser_srv02"):
        plant = build_plant(load_model(name))
        inv = load_controller("deadzone_inverse", plant)
        sh = plant.shafts
        to_load = [math.prod(s.ratio for s in plant.stages[j:]) for j in range(len(sh))]
        follow = sum(sh[j].J * to_load[j] ** 2 for j in range(1, len(sh)))
        assert inv._J_follow == pytest.approx(follow, rel=1e-12), name
    # the featherweight train's load (1.7e-10 kg m^2) is nothing beside its intermediate shaft (6.1e-4): with the
    # load's inertia alone the take-up braked far harder than the load torque could make the shafts follow.
    # ISO 230-2 accuracy over 2 cycles, measured 0.61 mrad (the load's inertia alone: 2.28 mrad; the PID 0.96)
    m = load_model(str(Path(__file__).parent / "data" / "featherweight_friction_train.toml"))
    plant = build_plant(m)
    res = precision_test(plant, load_controller("deadzone_inverse", plant), cycles=2, sensors=m.sensors)
    print(f"\nfeatherweight train, inverse ISO A {res.stats['accuracy'] * 1e3:.3g} mrad")
    assert res.stats["accuracy"] <= 1.0e-3


def test_mpc_notes_the_gaps_its_plan_leaves_to_a_tolerance() -> None:
    # a reviewer's two-stage robot joint under gravity (14-tooth shifted pinion, intermediate shafts 5 % of the motor
    # side): the MPC's sine was 8.4x the PID's RMS with no word (its first stage's gap, 22 % of the lost motion, is
    # inside the plan's contact tolerance; with it closed the MPC gave 4.6e-6 rad, 280x below the PID). On 13 trains
    # with such gaps the MPC ranged from 4.8x better to 8x worse: every train whose stages before the last have a gap
    # gets the note (the three-stage train's 30 %), a pair and a train whose first stage has none do not
    from gearctl.design.mpc import upstream_gap_share

    for name, share in (("servo_3stage_quanser_srv02", 0.30), ("shing1993_servo", 0.0)):
        m = load_model(name)
        plant = build_plant(m)
        assert upstream_gap_share(plant) == pytest.approx(share, abs=0.005), name
        notes = [n for n in load_controller("mpc", plant, sensors=m.sensors).design_notes
                 if n.startswith("upstream gaps:")]
        assert bool(notes) is (share > 0.0), (name, notes)
    closed = without_upstream_gaps(build_plant(load_model("servo_3stage_quanser_srv02")))
    assert upstream_gap_share(closed) == 0.0
    assert not [n for n in load_controller("mpc", closed).design_notes if n.startswith("upstream gaps:")]


def without_upstream_gaps(plant: Plant) -> Plant:
    """The train with every stage but the last made backlash-free."""
    return plant.with_backlash([0.0] * (plant.n_stages - 1) + [plant.stages[-1].backlash])


def test_mpc_notes_a_train_whose_intermediate_shafts_it_does_not_see() -> None:
    # the one-gap plan ignores the intermediate shafts: where they carry over 15 % of the motor side's inertia the
    # MPC gained at most 1.52x over the PID on the sine on the four such trains where it plans the gap
    # (servo_2stage_phm09, 33 %: 1.07x on this machine, 1.25x on an earlier one; train_steel_alu 1.52x;
    # train3_r120_grazing 1.48x (1.33x here); the gravity joint, 19 %: 0.2x, 0.34x here), where the three-stage
    # train (6 %) gives 4.8x. The design says so; a pair and that train get no note
    from gearctl.design.mpc import INTERMEDIATE_SHARE, intermediate_share

    for name, share in (("servo_2stage_phm09", 0.328), (GRAVITY_JOINT, 0.187), ("servo_3stage_quanser_srv02", 0.056),
                        ("shing1993_servo", 0.0)):
        m = load_model(name)
        plant = build_plant(m)
        assert intermediate_share(plant) == pytest.approx(share, abs=1e-3), name
        notes = [n for n in load_controller("mpc", plant, sensors=m.sensors).describe()["design_notes"]
                 if n.startswith("train:")]
        assert bool(notes) is (share > INTERMEDIATE_SHARE), (name, notes)
