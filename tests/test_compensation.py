"""Compensation close to the backlash-free limit (issue 12): ISO 230-2 figures, disturbances, standstill.

Every figure here is an ISO 230-2 linear cycle (:func:`gearctl.precision.precision_test`, its defaults:
5 targets over 0.5 rad, 5 cycles, 0.3 s dwells) on the improved plant of ``shing1993_servo`` (no load
friction) and ``shing1993_servo_friction`` (0.2 N m of Coulomb friction on the load), with the catalog
controllers designed on the model's nominal plant, as ``gearctl precision MODEL CONTROLLER --json``
runs them. The backlash-free reference is the catalog ``pid`` on ``build_plant(model, backlash=0.0)``
(``gearctl precision MODEL pid --backlash 0``). The lost motion ``L = 2 b / r_b2`` is 1330 urad.

Each acceptance test states the figures measured when it was written and keeps a margin. The runs are
deterministic (quantised encoders, no noise, fixed seed), so the bounds cannot flake; they can only move
when a controller, the plant or the solver changes. Claims of issue 12 that the controllers do not meet
are recorded as strict ``xfail`` tests with the measured figures and the reason: they fail loudly (XPASS)
the day they are met. Measured (urad, A / B / R):

==========================  ======================  ========================
controller                  shing1993_servo         shing1993_servo_friction
==========================  ======================  ========================
pid                         1483 / 1317 / 1348      1691 / 1502 / 1519
pid, backlash-free plant    1.4 / 0.9 / 1.2         7.6 / 4.8 / 5.4
deadzone_inverse            171 / 57 / 96           14.2 / 4.6 / 7.2
reversal_offset             2667 / 2644 / 2664      189 / 88 / 102
mpc                         285 / 111 / 241         9.0 / 4.0 / 8.0
==========================  ======================  ========================

The PID's feedforward (inertia at mid-sample, the reference speed filtered as its measurement is, Coulomb
friction; :class:`gearctl.design.pid.PID`) took the backlash-free figures from 17.7 / 16.9 / 17.2 (servo)
and 386 / 369 / 369 urad (friction) to the ones above: the reference the compensators are held to moved
12x and 50x closer to zero. The loops with impacts are chaotic: these figures are from one machine (numpy 2.4,
SciPy 1.17, CasADi 3.8); an earlier one gave the frictionless MPC 312 / 139 / 241 with the same code.

The ISO runs take 0.5-2.5 s each; the module takes about 50 s. Those that only confirm an unmet claim on
the frictionless servo are marked ``slow``.
"""

from __future__ import annotations

import dataclasses
import math
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from gearctl import InputError, build_plant, load_model
from gearctl.catalog import load_controller, read_toml, resolve
from gearctl.closedloop import simulate_closed_loop
from gearctl.design import deadzone
from gearctl.design.deadzone import DeadzoneInverse, OffsetRamp, ramp_shape
from gearctl.design.pid import PID
from gearctl.design.registry import build_controller
from gearctl.design.reversal import ReversalOffset
from gearctl.precision import precision_test
from gearctl.references import Reference, reference

SERVO, FRICTION = "shing1993_servo", "shing1993_servo_friction"
COMPENSATORS = ("deadzone_inverse", "reversal_offset", "mpc")


# --- the runs, computed once per model and controller -----------------------------------------------------


class _Runs:
    """ISO 230-2 statistics per (model, controller, estimate factor), computed on first use."""

    def __init__(self) -> None:
        self._cache: dict[tuple[str, str, float, int], dict[str, float]] = {}
        self._models = {m: load_model(m) for m in (SERVO, FRICTION)}

    def plant(self, model: str, backlash: float | None = None):  # noqa: ANN201 - a Plant
        return build_plant(self._models[model], backlash=backlash)

    def lost_motion(self, model: str) -> float:
        return self.plant(model).lost_motion

    def iso(self, model: str, controller: str, factor: float = 1.0, seed: int = 0) -> dict[str, float]:
        """``accuracy``, ``reversal_value``, ``repeatability`` [rad]; controller ``"free"``: the catalog PID on
        the backlash-free plant; ``factor``: the backlash estimate over the model's; ``seed``: the test's
        (its targets' offsets)."""
        key = (model, controller, factor, seed)
        if key not in self._cache:
            m = self._models[model]
            if controller == "free":
                plant = self.plant(model, backlash=0.0)
                ctrl = load_controller("pid", plant)
            else:
                plant = self.plant(model)
                b = None if factor == 1.0 else factor * plant.backlash
                ctrl = load_controller(controller, plant, backlash=b)
            st = precision_test(plant, ctrl, sensors=m.sensors, seed=seed).stats
            self._cache[key] = {k: st[k] for k in ("accuracy", "reversal_value", "repeatability")}
        return self._cache[key]


@pytest.fixture(scope="module")
def runs() -> _Runs:
    return _Runs()


def _servo_slow_xfail(reason: str) -> list[pytest.MarkDecorator]:
    return [pytest.mark.slow, pytest.mark.xfail(strict=True, reason=reason)]


# --- 1. the best compensator against the backlash-free PID -------------------------------------------------


@pytest.mark.parametrize("model", [
    FRICTION,
    pytest.param(SERVO, marks=_servo_slow_xfail(
        "issue 12 claim not met on the frictionless servo: best ISO accuracy is the inverse's, A = 171 urad "
        "(the MPC's 285) against 1.4 urad for the PID on the backlash-free plant (122x, not <= 3x; before the "
        "PID's feedforward corrections the backlash-free PID gave 17.7 urad). The inverse stops the load a few "
        "tens of urad past the target (it may not push a coasting load back). The MPC ends each move within a "
        "few urad, but the free load (no friction, elastic mesh impacts, restitution ~0.85, a 2.8 kHz mesh "
        "ringing the rigid plan does not model) leaves its flank at a few 1e-4 rad/s "
        "after some stops and drifts within the standstill deadband: only impacts slower than the kernel's "
        "plastic limit (1e-6 m/s on the line of action, 1.3e-5 rad/s at the load) leave it at rest, below what "
        "a plan on 1.1e-7 m encoder counts can aim in a dwell; holding a frictionless load needs a preloaded "
        "(anti-backlash) train. With 2^28-count encoders the MPC gives 3.5 urad, and the backlash-free PID 0.03 "
        "(test_frictionless_mpc_positioning_is_set_by_the_encoders)")),
])
def test_best_compensator_reaches_backlash_free_accuracy(runs: _Runs, model: str) -> None:
    # measured on shing1993_servo_friction: best = mpc, A = 9.0 urad against 7.6 urad for the PID on the
    # backlash-free plant (ratio 1.18, seeds 0-3 up to 1.41; the inverse gives 14.2 urad). The issue asks for <= 3,
    # kept: a 2x margin on the measurement. The backlash-free PID is now limited by the encoder and friction, not its
    # feedforward
    free = runs.iso(model, "free")["accuracy"]
    best = min(runs.iso(model, c)["accuracy"] for c in COMPENSATORS)
    print(f"\n{model}: best A {best * 1e6:.1f} urad, backlash-free PID {free * 1e6:.1f} urad, ratio {best / free:.3f}")
    assert best <= 3.0 * free


def test_frictionless_mpc_positioning_is_set_by_the_encoders(runs: _Runs) -> None:
    # what keeps the MPC from the claim above on the frictionless servo is the encoders, not its plan: with 2^28-count
    # encoders on both shafts of the true plant (``gearctl precision shing1993_servo mpc --set motor_encoder_cpr=
    # 268435456 --set load_encoder_cpr=268435456``) it measured A = 3.5 urad, against 285 with the catalog's 2^20
    # (2^22: 155, 2^24: 32; the load encoder alone at 2^28: 40, the motor's alone: 251). Kept: A under 10 urad at
    # 2^28, and the catalog's at least 10x that, so that the test says which of the two figures moved
    m = load_model(SERVO)
    plant = runs.plant(SERVO)
    fine = dataclasses.replace(m.sensors, motor_encoder_cpr=2**28, load_encoder_cpr=2**28)
    A = precision_test(plant, load_controller("mpc", plant), sensors=fine).stats["accuracy"]
    A_catalog = runs.iso(SERVO, "mpc")["accuracy"]
    print(f"\n{SERVO}, mpc: A {A * 1e6:.2f} urad with 2^28-count encoders, {A_catalog * 1e6:.1f} with the catalog's")
    assert A <= 10e-6
    assert A_catalog >= 10 * 10e-6


# --- 2. the dead-zone inverse (motor encoder only) against the lost motion ----------------------------------


@pytest.mark.parametrize(("model", "gain"), [(FRICTION, 50.0), pytest.param(SERVO, 10.0, marks=pytest.mark.slow)])
def test_inverse_cuts_reversal_and_repeatability(runs: _Runs, model: str, gain: float) -> None:
    # measured on shing1993_servo_friction: B = 4.6 urad (0.003 L), R = 7.2 urad (0.005 L) against the PID's
    # 1502 / 1519 urad (1.13 L); the issue asks for <= 0.15 L each (200 urad), kept with that bound (measured
    # 0.04x of it) and an improvement over the PID of at least 50x (measured 330x). On the frictionless
    # shing1993_servo: B = 57 urad (0.043 L), R = 96 urad (0.072 L) against the PID's 1317 / 1348 urad (23x
    # on B; kept >= 10x), since the inverse withholds the push-back that launched the stopped load off its
    # braking flank (B = 712, R = 1562 urad before; deadzone.py, "The stop"; 44 / 136 before it also dropped the
    # integral that pushed back)
    L = runs.lost_motion(model)
    inv, pid = runs.iso(model, "deadzone_inverse"), runs.iso(model, "pid")
    B, R = inv["reversal_value"], inv["repeatability"]
    print(f"\n{model}: inverse B {B * 1e6:.1f} ({B / L:.3f} L), R {R * 1e6:.1f} ({R / L:.3f} L) urad")
    assert B <= 0.15 * L
    assert R <= 0.15 * L
    assert B <= pid["reversal_value"] / gain


# --- 3. a backlash estimate off by +-20 % ---------------------------------------------------------------------


@pytest.mark.parametrize("factor", [1.2, 0.8])
def test_wrong_backlash_estimate_keeps_reversal_down(runs: _Runs, factor: float) -> None:
    # measured on shing1993_servo_friction against the PID's B = 1502 urad: with 1.2 b, B = 57 urad (26x: the
    # crossing ends where the motor meets the load, short of the estimate's flank); with 0.8 b, B = 296 urad
    # (5.1x: the offset error 2 x 0.2 b / r_b2 = 266 urad, the motor stops short of the flank). Seeds 0-7 (the
    # targets' offsets) give 53-57 and 293-296 urad. The issue asks for >= 3x; kept, and >= 4x (margins
    # 6.6x and 1.3x on the measurements)
    B = runs.iso(FRICTION, "deadzone_inverse", factor)["reversal_value"]
    B_pid = runs.iso(FRICTION, "pid")["reversal_value"]
    print(f"\n{FRICTION}, estimate {factor} b: inverse B {B * 1e6:.1f} urad, PID {B_pid * 1e6:.1f} urad, "
          f"ratio {B_pid / B:.2f}")
    assert B_pid >= 4.0 * B


#: Seeds of the frictionless servo's test with a wrong estimate: its B moves with the targets' offsets.
WRONG_ESTIMATE_SEEDS = range(16)


def _frictionless_wrong_estimate(runs: _Runs, factor: float) -> tuple[np.ndarray, float]:
    B = np.array([runs.iso(SERVO, "deadzone_inverse", factor, seed)["reversal_value"] for seed in WRONG_ESTIMATE_SEEDS])
    B_pid = runs.iso(SERVO, "pid")["reversal_value"]
    print(f"\n{SERVO}, estimate {factor} b, seeds 0-{len(B) - 1}: inverse B {np.round(B * 1e6, 1)} urad, "
          f"median {np.median(B) * 1e6:.1f}, PID {B_pid * 1e6:.1f} urad")
    return B, B_pid


@pytest.mark.slow
@pytest.mark.parametrize("factor", [0.8, 1.2])
def test_wrong_backlash_estimate_frictionless_median(runs: _Runs, factor: float) -> None:
    # on the frictionless shing1993_servo the inverse's B with a wrong estimate depends on where the targets fall
    # (the load coasts off its flank at each stop and lands where its bounces leave it: chaotic, seed by seed).
    # Seeds 0-15 against the PID's 1317 urad: 0.8 b 283-542 urad, median 343 (3.8x); 1.2 b 175-499 urad, median
    # 329 (4.0x; before the stop rule dropped the push-back integral: 347 and 345; an earlier machine gave 403 at
    # 1.2 b). The median meets the 3x; kept at 3x (margins 1.28x and 1.33x)
    B, B_pid = _frictionless_wrong_estimate(runs, factor)
    assert B_pid >= 3.0 * np.median(B)


@pytest.mark.slow
@pytest.mark.parametrize("factor", [0.8, 1.2])
@pytest.mark.xfail(strict=True, reason=(
    "issue 12 claim not met on every seed of the frictionless servo: with the estimate 20 % off the inverse's B "
    "exceeds a third of the PID's 1317 urad on 4 of 16 seeds at 0.8 b (worst 542 urad, 2.4x) and 1 of 16 at 1.2 b "
    "(499 urad, 2.6x). The frictionless load leaves its flank at each stop and lands where its bounces "
    "leave it; the friction servo meets the claim on every seed, and so does the adaptive inverse started 20 % off "
    "on both servos (the test below)"))
def test_wrong_backlash_estimate_frictionless_every_seed(runs: _Runs, factor: float) -> None:
    B, B_pid = _frictionless_wrong_estimate(runs, factor)
    assert B_pid >= 3.0 * B.max()


@pytest.mark.slow
@pytest.mark.parametrize(("model", "seeds"), [(SERVO, range(8)), (FRICTION, range(4))])
@pytest.mark.parametrize("factor", [0.8, 1.2])
def test_adaptive_inverse_keeps_b_with_a_wrong_start_on_every_seed(runs: _Runs, model: str, seeds: range,
                                                                   factor: float) -> None:
    # the catalog's answer to an uncertain backlash is the adaptive inverse (its estimate learnt from the two
    # encoders). Started 20 % off, its B on every seed stays far below a third of the PID's (the bound):
    # measured over seeds 0-15, frictionless servo 0.8 b: 36-63 urad, 1.2 b: 94-125 urad (the PID's 1317); friction
    # servo 0.8 b: 18-29 urad, 1.2 b: 19-38 urad (the PID's 1502). The fixed inverse misses the bound on 4 and 1 of
    # the 16 frictionless seeds (the strict xfail above). Kept: a third of the PID's on every seed run here
    m = load_model(model)
    plant = build_plant(m)
    B = []
    for seed in seeds:
        ctrl = load_controller("adaptive_inverse", plant, backlash=factor * plant.backlash, sensors=m.sensors)
        B.append(precision_test(plant, ctrl, sensors=m.sensors, seed=seed).stats["reversal_value"])
    B_pid = runs.iso(model, "pid")["reversal_value"]
    print(f"\n{model}, adaptive started at {factor} b: B {np.round(np.array(B) * 1e6)} urad, PID {B_pid * 1e6:.0f}")
    assert max(B) <= B_pid / 3.0


@pytest.mark.parametrize("factor", [0.9, pytest.param(1.1, marks=pytest.mark.xfail(strict=True, reason=(
    "known weakness: with an estimate above the true b the inverse's crossing predicts the far flank 2 (b_est - b) "
    "too far and meets the frictionless load at speed (0.13 rad/s at 1.08 b); the 0.85-restitution mesh kicks the "
    "load off, and only the back flank can catch it up: a spike of the whole lost motion every other reversal "
    "(the contact check resets one flank only). Measured max error 1.46e-3 rad at 1.1 b (0.80-0.98 b: no spike). "
    "With an uncertain b the adaptive inverse learns it: 35-58 urad RMS over 6 s (start-up included) for a "
    "true b of 0.83-1.25 times its 5e-5 m start, max 0.18-0.29 mrad")))])
def test_inverse_with_a_wrong_estimate_tracks_the_sine_without_losing_the_gap(factor: float) -> None:
    # sine on shing1993_servo with the estimate off by 10 %: the tracking error must stay well below the lost
    # motion (1.33e-3 rad) and the RMS well below the PID's (6.47e-4). Measured at 0.9 b: RMS 6.5e-5, max 8.7e-5
    # (after 0.5 s); kept below a third of the lost motion and a third of the PID's RMS
    m = load_model(SERVO)
    plant = build_plant(m)
    ctrl = load_controller("deadzone_inverse", plant, backlash=factor * plant.backlash)
    res = simulate_closed_loop(plant, ctrl, reference("sine"), 3.0, sensors=m.sensors)
    e = np.abs(res.error[res.t >= 0.5])
    lost = 2.0 * plant.backlash / plant.rb2
    rms = np.sqrt(np.mean(e ** 2))
    print(f"\nestimate {factor} b: RMS {rms:.3g} rad, max {e.max():.3g} rad, lost motion {lost:.3g}")
    assert e.max() < lost / 3.0
    assert rms < 6.47e-4 / 3.0


@pytest.mark.parametrize(("model", "rms_max", "pid_rms"), [
    (FRICTION, 1.2e-4, 6.99e-4),
    (str(Path(__file__).parent / "data" / "reviewer_pair_24x72.toml"), 1.3e-4, 5.99e-4),
])
def test_inverse_sees_no_contact_where_the_motor_only_lags_its_ramp(model: str, rms_max: float,
                                                                  pid_rms: float) -> None:
    # on a load with Coulomb friction the flank changes at the sine's reversals, where the load stops; the motor
    # lagged its 10 ms crossing ramp by up to 9 % of half the lost motion with nothing in its way (the loop's
    # bandwidth, the observer's start speed), and the contact check, which compared the motor with the ramp, took
    # that for an early contact: the crossing stopped short and the load was held off its target for the
    # half-cycle. The check compares the motor with its own free motion now. Measured: no contact; sine RMS
    # 8.08e-5 rad on shing1993_servo_friction (1.90e-4 before; the PID 6.99e-4) and 8.57e-5 on a reviewer's
    # 24 x 72 pair (3.43e-4 before, 6 false contacts; the PID 5.99e-4). Kept below 1.2e-4 and 1.3e-4 (margins
    # 1.5x) and at least 4x below the PID
    m = load_model(model)
    plant = build_plant(m)
    ctrl = load_controller("deadzone_inverse", plant, sensors=m.sensors)
    res = simulate_closed_loop(plant, ctrl, reference("sine"), 3.0, sensors=m.sensors)
    e = res.error[res.t >= 0.5]
    rms = float(np.sqrt(np.mean(e ** 2)))
    print(f"\n{Path(model).stem}: inverse sine RMS {rms:.3g} rad, {ctrl.contacts} contacts, PID {pid_rms:.3g}")
    assert ctrl.contacts == 0
    assert rms < rms_max
    assert rms < pid_rms / 4.0


def test_mpc_with_an_underestimated_backlash_keeps_its_accuracy(runs: _Runs) -> None:
    # the MPC measures the gap with both encoders: with 0.8 b on shing1993_servo_friction it gives B = 3.2 urad
    # (4.4 with the right estimate), 480x below the PID's 1502; kept within 30 urad and 30x
    B = runs.iso(FRICTION, "mpc", 0.8)["reversal_value"]
    assert B <= 30e-6
    assert runs.iso(FRICTION, "pid")["reversal_value"] >= 30.0 * B


def test_mpc_finds_the_flanks_of_an_overestimated_backlash() -> None:
    # with 1.2 b the gap never reaches b_est - tol: before the MPC took each flank where the measured gap turns
    # back, it never saw contact and collapsed (A = 14.9 mrad on the ISO test). One ISO cycle on
    # shing1993_servo_friction: both flanks are found within 3 % of the true b (measured 1.016 b and 1.020 b:
    # the furthest gap includes the mesh deflection and half the contact tolerance), and the load ends every
    # approach within 0.6 mrad (measured A = 0.93 mrad over 5 cycles, B = 0.15 mrad: 10x below the PID's B;
    # not yet the right estimate's 7.7 urad: some approaches from below end 0.1-0.5 mrad short)
    m = load_model(FRICTION)
    plant = build_plant(m)
    ctrl = load_controller("mpc", plant, backlash=1.2 * plant.backlash)
    res = precision_test(plant, ctrl, cycles=1, sensors=m.sensors)
    flanks = np.array(ctrl._flanks) / plant.backlash
    print(f"\nflanks found at {flanks} b, A {res.stats['accuracy'] * 1e6:.0f} urad")
    np.testing.assert_allclose(flanks, 1.0, rtol=0.03)
    assert res.stats["accuracy"] <= 1.5e-3


# --- 4. the industrial reversal offset beside them --------------------------------------------------------


def test_reversal_offset_beats_the_pid_on_a_friction_load(runs: _Runs) -> None:
    # measured on shing1993_servo_friction: reversal offset A / B / R = 189 / 88 / 102 urad against the PID's
    # 1690 / 1502 / 1519 (B ratio 0.058): the offset takes up the lost motion, what is left is its reversal
    # transient (the offset moves 10 ms after the command reverses, with the friction fed forward already).
    # The torque-sign inverse is better still (B = 4.8 urad: it crosses on the torque's sign and releases the
    # integrator on the observer's estimate). Kept: B below a tenth of the PID's, and above the inverse's
    rev, pid, inv = (runs.iso(FRICTION, c) for c in ("reversal_offset", "pid", "deadzone_inverse"))
    print(f"\nreversal offset B {rev['reversal_value'] * 1e6:.1f}, PID {pid['reversal_value'] * 1e6:.1f}, "
          f"inverse {inv['reversal_value'] * 1e6:.1f} urad")
    assert rev["reversal_value"] <= 0.1 * pid["reversal_value"]
    assert rev["reversal_value"] > inv["reversal_value"]


@pytest.mark.slow
def test_reversal_offset_loses_on_an_inertial_load(runs: _Runs) -> None:
    # measured on shing1993_servo: the reversal offset's B = 2648 urad, worse than the PID's 1318: every move's
    # deceleration is carried by the back flank while the command still moves forward, so the offset holds
    # the motor on the wrong side of the gap and the load ends a full lost motion from where the offset
    # assumes it. The torque-sign inverse's B = 47 urad. Kept: the offset is worse than the PID by 1.5x
    # (measured 2.0x) and worse than the inverse
    rev, pid, inv = (runs.iso(SERVO, c)["reversal_value"] for c in ("reversal_offset", "pid", "deadzone_inverse"))
    assert rev >= 1.5 * pid
    assert rev > inv


# --- 5. the step with a load disturbance ------------------------------------------------------------------


@pytest.mark.parametrize("model", [SERVO, FRICTION])
def test_inverse_rejects_a_load_disturbance(runs: _Runs, model: str) -> None:
    # `gearctl track MODEL deadzone_inverse --reference step`: 0.05 rad step at 0.1 s, a 0.5 N m load torque
    # against the motion from 1 s; error at 2 s. Measured: inverse 0.32 urad (servo) and 1.9 urad (friction)
    # against the PID's 665 and 667 urad (b / r_b2: the load rests on the far flank). The observer's estimate
    # (-0.5 N m) puts the motor on the front flank. The issue asks for <= 10 % of the PID's; kept at 1 %
    m = load_model(model)
    plant = build_plant(m)
    ref = reference("step")
    err = {c: abs(simulate_closed_loop(plant, load_controller(c, plant), ref, 2.0, sensors=m.sensors).error[-1])
           for c in ("pid", "deadzone_inverse")}
    print(f"\n{model}: steady error inverse {err['deadzone_inverse'] * 1e6:.2f} urad, PID {err['pid'] * 1e6:.1f} urad")
    assert err["deadzone_inverse"] <= 0.1 * err["pid"]
    assert err["deadzone_inverse"] <= 0.01 * err["pid"]


def test_observer_estimates_the_load_torque() -> None:
    # the same run: 0.5 s after the 0.5 N m step the observer (5 Hz) reads -0.5 N m within 5 % (measured
    # -0.4999); before it, zero within its threshold (measured |d| < 2e-3 N m)
    m = load_model(SERVO)
    plant = build_plant(m)
    ctrl = load_controller("deadzone_inverse", plant)
    ref = reference("step")
    seen = {}
    step = ctrl.step

    def record(t: float, ym: float, yl: float | None, r: Reference) -> float:
        u = step(t, ym, yl, r)
        seen[round(t, 6)] = ctrl.disturbance
        return u

    ctrl.step = record  # type: ignore[method-assign]
    simulate_closed_loop(plant, ctrl, ref, 1.6, sensors=m.sensors)
    assert abs(seen[0.9]) < ctrl.disturbance_threshold
    assert seen[1.5] == pytest.approx(-0.5, rel=0.05)


# --- 6. the MPC at standstill, and the preview -------------------------------------------------------------


def _rest_crossings(res, preview: int) -> list[int]:  # noqa: ANN001 - a ClosedLoopResult
    """Flank changes of the true gap while the reference rests, one count per rest interval.

    A sample counts as at rest when the reference is constant from it over the next ``preview`` samples
    (what the controller reads): the MPC may start the next move ``preview`` samples early.
    """
    r = res.reference
    rest = np.zeros(r.size, dtype=bool)
    rest[1:] = np.diff(r) == 0.0
    ahead = rest.copy()
    for k in range(1, preview):
        ahead[:-k] &= rest[k:]
        ahead[-k:] = False
    mode = np.asarray(res.mode)
    counts, k = [], 0
    while k < r.size:
        if ahead[k]:
            j = k
            while j < r.size and ahead[j]:
                j += 1
            f = mode[k:j]
            f = f[f != 0]
            counts.append(int(np.sum(f[1:] != f[:-1])))
            k = j
        else:
            k += 1
    return counts


def _mpc_rest_crossings(model: str, seeds: range, deadband: float | None = None) -> list[int]:
    """Flank changes at rest over one ISO 230-2 cycle (12 dwells, 2 reversals of the reference), per seed."""
    m = load_model(model)
    plant = build_plant(m)
    spec = read_toml(resolve("mpc", "controllers"))
    if deadband is not None:
        spec = {**spec, "standstill_deadband": deadband}
    out = []
    for seed in seeds:
        ctrl = build_controller({**spec, "max_solve_time": 1.0}, plant, path=Path("mpc.toml"))
        res = precision_test(plant, ctrl, cycles=1, sensors=m.sensors, seed=seed).run
        out.append(sum(_rest_crossings(res, ctrl.preview)))
    return out


def test_mpc_does_not_hunt_at_standstill() -> None:
    # the claim, at most one crossing per reversal of the reference at rest, on the servo whose load
    # friction can hold it on a flank: measured 0 flank changes at rest for each of the seeds 0-3
    counts = _mpc_rest_crossings(FRICTION, range(4))
    print(f"\nflank changes at rest, friction servo, seeds 0-3: {counts}")
    assert all(c <= 2 for c in counts), counts  # one cycle: the two overshoot points


def test_mpc_standstill_deadband_cuts_the_hunting_on_the_free_load() -> None:
    # the frictionless servo: the free load, kicked by each landing of a 0.85-restitution mesh, leaves its flank
    # now and then whatever the plan does. Measured over seeds 0-1: 0 + 0 flank changes at rest with the
    # catalog's standstill_deadband (2e-4 rad; the hold plans no flank change and lets a free load coast to
    # rest), many more without it (the plan then crosses the gap after errors of a few urad). Which dwell loses
    # its flank follows the last bit of the arithmetic, so the claim is on the sum
    held = _mpc_rest_crossings(SERVO, range(2))
    free = _mpc_rest_crossings(SERVO, range(2), deadband=0.0)
    print(f"\nflank changes at rest, frictionless servo: {held} with the deadband, {free} without")
    assert sum(free) >= 4 * max(sum(held), 1)


def test_preview_is_stated() -> None:
    # the PIDs and the PID-based compensators read r(t) only; the MPC reads horizon + 1 samples (21)
    plant = build_plant(load_model(SERVO))
    for name, expected in (("pid", 1), ("deadzone_inverse", 1), ("reversal_offset", 1), ("mpc", 21)):
        ctrl = load_controller(name, plant)
        assert ctrl.preview == expected, name
        assert ctrl.describe().get("preview", 1) == expected, name
    mpc = load_controller("mpc", plant)
    assert mpc.preview == mpc.settings.horizon + 1


# --- 7. the reversal offset's own behaviour ------------------------------------------------------------------


def _reversal(plant, **keys):  # noqa: ANN001, ANN202
    spec = {**read_toml(resolve("reversal_offset", "controllers")), **keys}
    return build_controller(spec, plant, path=Path("reversal_offset.toml"))


@pytest.mark.parametrize("shape", ["sin2", "linear", "step"])
def test_ramp_shapes(shape: str) -> None:
    # exact values of the ramps from 0 to 1 and their derivatives (sin2: sin^2(pi x / 2))
    x = np.linspace(0.0, 1.0, 11)
    vals = np.array([ramp_shape(shape, float(v)) for v in x])
    assert vals[0, 0] == 0.0 and vals[-1, 0] == 1.0
    assert np.all(np.diff(vals[:, 0]) >= 0.0)
    if shape == "sin2":
        np.testing.assert_allclose(vals[1:-1, 0], np.sin(np.pi * x[1:-1] / 2) ** 2, rtol=1e-14)
        np.testing.assert_allclose(vals[1:-1, 1], 0.5 * np.pi * np.sin(np.pi * x[1:-1]), rtol=1e-14)
    elif shape == "linear":
        np.testing.assert_allclose(vals[1:-1, 0], x[1:-1], rtol=0, atol=0)
    else:
        assert np.all(vals[1:, 0] == 1.0)
    # the offset over a full ramp: its speed integrates to its change (trapezoid on a 0.5 us grid: 1e-4 of the
    # span, the linear ramp's speed jumps cost half a grid step each)
    ramp = OffsetRamp(shape, 0.01, 2.0)
    ramp.move_to(0.0, 2.0)
    t = np.linspace(0.0, 0.012, 24001)
    o = np.array([ramp.at(float(v)) for v in t])
    assert o[-1, 0] == 2.0
    if shape != "step":
        assert abs(np.trapezoid(o[:, 1], t) - 2.0) < 2e-4


@pytest.mark.parametrize(("duration", "target"), [(1e-308, 2.0), (0.01, 1e-12), (0.01, 2e-6), (5e-7, 2.0)])
def test_a_ramp_shorter_than_a_microsecond_is_a_step(duration: float, target: float) -> None:
    # a take_up_time of 1e-308 s (then in its 0..1 s range) divided the ramp's acceleration by T^2 = 0
    # (ZeroDivisionError), and a tiny share of a full move read an acceleration d / T^2 that grows as the share
    # shrinks (a 1e-6 share of a 10 ms crossing: 10 ns, 1e11 rad/s^2): below deadzone.MIN_RAMP_TIME, the shortest
    # sample time, the offset steps, as it does within a sample anyway
    ramp = OffsetRamp("sin2", duration, 2.0)
    ramp.move_to(0.0, target)
    assert not ramp.moving(0.0) and ramp.at(0.0) == (target, 0.0, 0.0)
    longer = OffsetRamp("sin2", 0.01, 2.0)
    longer.move_to(0.0, 4e-4)  # a share of 2e-4: a 2 us ramp, above the floor, is still a ramp
    assert longer.moving(0.0) and longer.end == pytest.approx(2e-6, rel=1e-12)


def test_reversal_offset_takes_up_the_value_on_each_reversal() -> None:
    # a ramp reference up then down: the offset goes to +gain L / 2 with the first move, to -gain L / 2 at the
    # reversal, over the take-up time (a half move takes half of it), and nothing changes at rest
    plant = build_plant(load_model(SERVO))
    L = plant.lost_motion
    ctrl = _reversal(plant, gain=0.8, take_up_time=0.02, ramp="linear")
    assert ctrl.value == pytest.approx(0.8 * L, rel=1e-15)
    ref = Reference(kind="sine", amplitude=0.01, frequency=2.0)  # reverses at 0.125 s
    offsets = []
    ctrl.reset()
    for k in range(200):
        t = k * 1e-3
        ctrl.step(t, 0.0, None, ref)
        offsets.append(ctrl._ramp.at(t)[0])
    offsets = np.array(offsets)
    assert offsets[0] == offsets[1] == 0.0  # no direction before the first increment (at 1 ms), ramp from there
    assert offsets[6] == pytest.approx(0.2 * L, rel=1e-9)  # linear: half of the half move after 5 of its 10 ms
    assert offsets[11] == pytest.approx(0.4 * L, rel=1e-12)
    assert offsets[120] == pytest.approx(0.4 * L, rel=1e-12)
    i_rev = int(np.argmax(offsets[100:] < 0.4 * L * (1 - 1e-9))) + 100
    assert 124 <= i_rev <= 127  # the reversal of the command at 0.125 s
    assert offsets[i_rev + 21] == pytest.approx(-0.4 * L, rel=1e-12)  # the full change takes 20 ms
    assert ctrl.direction == -1


def test_reversal_offset_with_gain_zero_is_the_pid() -> None:
    # gain 0: no offset, and the same PID, step for step (bit-identical torques on the sine)
    m = load_model(SERVO)
    plant = build_plant(m)
    a = simulate_closed_loop(plant, _reversal(plant, gain=0.0), reference("sine"), 1.0, sensors=m.sensors)
    b = simulate_closed_loop(plant, load_controller("pid", plant), reference("sine"), 1.0, sensors=m.sensors)
    np.testing.assert_array_equal(a.torque, b.torque)


def test_take_up_cycles() -> None:
    plant = build_plant(load_model(SERVO))
    spec = {k: v for k, v in read_toml(resolve("reversal_offset", "controllers")).items() if k != "take_up_time"}
    ctrl = build_controller({**spec, "take_up_cycles": 15}, plant, path=Path("r.toml"))
    assert isinstance(ctrl, ReversalOffset) and ctrl.take_up_time == pytest.approx(0.015, rel=1e-12)
    assert ctrl.describe()["take_up_time"] == pytest.approx(0.015, rel=1e-12)


@pytest.mark.parametrize(("keys", "match"), [
    ({"take_up_cycles": 10}, r"give one of them, not both"),
    ({"ramp": "cosine"}, r"ramp = 'cosine' is not allowed: expected one of 'sin2', 'linear', 'step'"),
    ({"gain": 2.5}, r"gain = 2.5 is out of range: expected 0 <= value <= 2"),
    ({"take_up_time": -0.01}, r"take_up_time = -0.01 is out of range"),
    ({"take_up_time": 2.0}, r"take_up_time = 2.0 is out of range"),
    ({"backlash": 0.02}, r"backlash = 0.02 is out of range"),
    ({"gian": 1.0}, r"unknown key gian .* did you mean 'gain'"),
])
def test_reversal_offset_bad_input(keys: dict, match: str) -> None:
    plant = build_plant(load_model(SERVO))
    with pytest.raises(InputError, match=match) as exc:
        _reversal(plant, **keys)
    assert "reversal_offset.toml" in str(exc.value)


# --- 8. the inverse's settings -------------------------------------------------------------------------------


@pytest.mark.parametrize(("key", "value", "match"), [
    ("crossing_time", -0.001, r"crossing_time = -0.001 is out of range"),
    # below a microsecond: a ramp of 1e-308 s at t = 0 divided by T^2 = 0 (ZeroDivisionError, a traceback)
    ("crossing_time", 1e-308, r"crossing_time = 1e-308 is out of range.*either 0 or at least 1e-06 \[s\]"),
    ("observer_hz", 2000.0, r"observer_hz = 2000.0 is out of range"),
    ("disturbance_threshold", -1.0, r"disturbance_threshold = -1.0 is out of range"),
    ("friction_feedforward", "yes", r"friction_feedforward = 'yes' is not allowed"),
])
def test_inverse_bad_input(key: str, value: object, match: str) -> None:
    plant = build_plant(load_model(SERVO))
    spec = {**read_toml(resolve("deadzone_inverse", "controllers")), key: value}
    with pytest.raises(InputError, match=match) as exc:
        build_controller(spec, plant, path=Path("deadzone_inverse.toml"))
    assert exc.value.field == key


def test_tiny_crossing_times_are_refused_everywhere() -> None:
    """The adaptive inverse's converged crossing time and the API's set_crossing_time share the floor; a track with
    crossing_time = 1e-308 ended in ZeroDivisionError."""
    plant = build_plant(load_model(SERVO))
    spec = read_toml(resolve("adaptive_inverse", "controllers"))
    spec = {**spec, "adaptation": {**spec["adaptation"], "converged_crossing_time": 1e-300}}
    with pytest.raises(InputError, match=r"\[adaptation\] converged_crossing_time = 1e-300 is out of range"):
        build_controller(spec, plant, path=Path("adaptive_inverse.toml"))
    inv = load_controller("deadzone_inverse", plant)
    with pytest.raises(InputError, match="crossing_time = 1e-09 is out of range"):
        inv.set_crossing_time(1e-9)
    inv.set_crossing_time(1e-6)
    inv.set_crossing_time(0.0)


def test_inverse_holds_its_flank_at_rest_unless_friction_is_exceeded() -> None:
    # at rest the flank changes only when the estimated load torque exceeds the static friction plus the
    # threshold: 0.15 N m against 0.2 N m of friction holds, 0.25 N m changes the flank
    plant = build_plant(load_model(FRICTION))
    inv = load_controller("deadzone_inverse", plant)
    assert isinstance(inv, DeadzoneInverse)
    rest = Reference(kind="step", amplitude=0.0)
    for d, expected in ((0.15, 1.0), (-0.15, 1.0), (-0.25, 1.0), (0.25, -1.0)):
        inv.reset()
        inv._sigma = 1.0
        inv._observer.x = [0.0, 0.0, d]
        assert inv.flank(0.5, rest) == expected, d


class _Kinematics:
    """A reference that gives the same ``(r, r', r'')`` at every time."""

    def __init__(self, rd: float, rdd: float) -> None:
        self.value = (0.0, rd, rdd)

    def at(self, t: float) -> tuple[float, float, float]:
        return self.value


def test_inverse_skips_a_crossing_the_reference_would_overtake() -> None:
    # the end of a forward move on a friction load: the braking flank (-1) is held while the deceleration
    # outweighs the friction; as it fades, the torque to transmit turns positive. Where the reference rests
    # (in 2 r' / |r''|) before a crossing could land, the flank is kept; a later rest, or a deceleration that grows
    # (a sine's top), changes it
    plant = build_plant(load_model(FRICTION))
    inv = load_controller("deadzone_inverse", plant)
    assert isinstance(inv, DeadzoneInverse)
    Tc = inv.crossing_time
    rdd = -0.5 * inv._tc2 / inv._J2  # half the friction's deceleration: the driving flank must push
    for rd, rdd_before, expected in (
        (0.2 * abs(rdd) * Tc, 1.1 * abs(rdd), -1.0),  # fading, rests in 0.4 Tc: kept
        (0.45 * abs(rdd) * Tc, 1.1 * abs(rdd), -1.0),  # rests in 0.9 Tc: kept
        (0.55 * abs(rdd) * Tc, 1.1 * abs(rdd), 1.0),  # rests in 1.1 Tc: the crossing lands first
        (0.2 * abs(rdd) * Tc, 0.9 * abs(rdd), 1.0),  # the deceleration grows: a reversal, not a rest
    ):
        inv.reset()
        inv._sigma, inv._rdd_before = -1.0, rdd_before
        assert inv.transmitted_torque(rd, rdd) > inv.width
        assert inv.flank(0.5, _Kinematics(rd, rdd)) == expected, (rd, rdd_before)


def test_inverse_on_a_cnc_table_positions_as_well_as_the_pid() -> None:
    # a reviewer's CNC rotary table (5 N m of table friction, 3 kg m^2, 44.7 urad of lost motion): a crossing
    # decided in the last 10 ms of a move landed after the load had stopped, and the motor held it 30 urad short
    # of the targets reached after the 0.02 rad overshoot moves: ISO A 178 urad against the PID's 86 (3 cycles).
    # Measured now 88 urad against 86 (5 cycles: 83 against 87); kept within 1.3x of the PID
    m = load_model(str(Path(__file__).parent / "data" / "cnc_table_tight.toml"))
    plant = build_plant(m)
    A = {c: precision_test(plant, load_controller(c, plant, sensors=m.sensors), cycles=3,
                           sensors=m.sensors).stats["accuracy"] for c in ("pid", "deadzone_inverse")}
    print(f"\ncnc table ISO A: PID {A['pid'] * 1e6:.1f} urad, inverse {A['deadzone_inverse'] * 1e6:.1f} urad")
    assert A["deadzone_inverse"] <= 1.3 * A["pid"]


@pytest.mark.parametrize("controller", ["deadzone_inverse", "adaptive_inverse"])
def test_inverse_takes_the_load_back_after_a_ramps_dead_stop(controller: str) -> None:
    # the ramp's dead stop (0.5 rad/s to rest within a sample) sends the friction load across the gap onto the braking
    # flank, where static friction holds it, pressed by the motor at the driving flank's target. Before the inverse
    # read that press as the other flank it held the load a whole lost motion off: final error -1.33e-3 rad against the
    # PID's -0.67e-3. Measured now 2.7e-5 rad with either inverse (RMS 8.5e-4 and 6.7e-4 against the PID's 9.1e-4).
    # Kept: a tenth of the PID's final error and of the lost motion
    m = load_model(FRICTION)
    plant = build_plant(m)
    final = {}
    for c in ("pid", controller):
        res = simulate_closed_loop(plant, load_controller(c, plant, sensors=m.sensors), reference("ramp"), 1.5,
                                   sensors=m.sensors)
        final[c] = abs(res.load_angle[-1] - res.reference[-1])
    print(f"\nramp's final error: PID {final['pid']:.3g} rad, {controller} {final[controller]:.3g} rad")
    assert final[controller] <= 0.1 * final["pid"]
    assert final[controller] <= 0.1 * plant.lost_motion


def test_inverse_positions_a_servo_with_motor_friction_better_than_the_pid() -> None:
    # tests/data/motor_friction.toml: Coulomb friction on both shafts and a load torque. After the 0.02 rad overshoot
    # moves the load stuck on the braking flank while the motor pressed it from the driving flank's target: ISO 230-2
    # A 1089 urad for the inverse against the PID's 451 before the press was read as the other flank; measured now
    # 114 urad (B 37, R 99). Kept: at most half the PID's A
    m = load_model(str(Path(__file__).parent / "data" / "motor_friction.toml"))
    plant = build_plant(m)
    A = {c: precision_test(plant, load_controller(c, plant, sensors=m.sensors), sensors=m.sensors).stats["accuracy"]
         for c in ("pid", "deadzone_inverse")}
    print(f"\nmotor friction ISO A: PID {A['pid'] * 1e6:.1f} urad, inverse {A['deadzone_inverse'] * 1e6:.1f} urad")
    assert A["deadzone_inverse"] <= 0.5 * A["pid"]


def test_inverse_reads_a_press_at_rest_only_when_held_still_long_enough() -> None:
    # the rule behind the two tests above: at rest, a torque against the held flank beyond the motor's friction and
    # the threshold, held PRESS_TIME with the motor still, is the other flank; a motor that moves, or a torque its
    # own friction can hold, is not
    plant = build_plant(load_model(str(Path(__file__).parent / "data" / "motor_friction.toml")))
    inv = load_controller("deadzone_inverse", plant)
    assert isinstance(inv, DeadzoneInverse)
    N, Ts = inv.pid.N, inv.Ts
    limit = plant.tc1 + inv.disturbance_threshold / N
    moved = 2.0 * deadzone.PRESS_TRAVEL * inv._offset * N  # per sample, at the motor

    def first_press(u: float, step: float) -> float | None:
        inv.reset()
        inv._sigma = 1.0
        inv._u_hist = (u, u)
        for k in range(100):
            if inv._presses_other_flank(k * Ts, 1.0 + k * step, 0.0, 0.0):
                return k * Ts
        return None

    t = first_press(-1.01 * limit, 0.0)
    assert t is not None and deadzone.PRESS_TIME - Ts < t < deadzone.PRESS_TIME + Ts
    assert first_press(-0.99 * limit, 0.0) is None  # the motor's own friction may hold it
    assert first_press(-1.01 * limit, moved) is None  # it moves: no flank holds it
    assert first_press(+10.0 * limit, 0.0) is None  # it presses the held flank


# --- 9. the mechanisms behind the figures ---------------------------------------------------------------------


def test_pid_feedforward_tracks_the_backlash_free_plant() -> None:
    # the catalog PID on the backlash-free servo, 1 Hz sine: with its feedforward (inertia at mid-sample, the
    # reference speed filtered as the measurement is) it tracks to 4.4e-7 rad RMS, against 2.0e-4 rad for the
    # same gains without feedforward (450x; 8.6e-5 rad with the uncorrected feedforward of the previous PID,
    # whose derivative term led in every acceleration). Kept: below 2e-6 rad and 100x below the textbook PID
    m = load_model(SERVO)
    free = build_plant(m, backlash=0.0)
    pid = load_controller("pid", free)
    rms = {}
    for ff in (True, False):
        ctrl = PID(pid.info, pid.gains, Ts=pid.Ts, feedforward=ff)
        res = simulate_closed_loop(free, ctrl, reference("sine"), 3.0, sensors=m.sensors)
        rms[ff] = float(np.sqrt(np.mean(res.error[res.t >= 0.5] ** 2)))
    print(f"\nbacklash-free sine RMS: feedforward {rms[True]:.3g} rad, none {rms[False]:.3g} rad")
    assert rms[True] <= 2e-6
    assert rms[False] >= 100.0 * rms[True]


@pytest.mark.parametrize(("model", "profile", "acts"), [
    (SERVO, "s-curve", True),        # a jerk-limited stop on a coasting load: the push-back is withheld
    (SERVO, "trapezoid", False),     # a dead stop launches the load: corrected as in motion
    (FRICTION, "s-curve", False),    # friction stops the load
])
def test_inverse_withholds_the_push_back_only_at_a_fading_stop(monkeypatch: pytest.MonkeyPatch, model: str,
                                                                 profile: str, acts: bool) -> None:
    """A flank pushes one way only (deadzone.py, *The stop*). The guard acts where a stop fades on a load that
    nothing else stops; elsewhere the inverse is, to the last bit, the one without it. Where it acts, the S-curve
    move on shing1993_servo ends at 2.5 urad from the target against 4.9 urad without it."""
    m = load_model(model)
    plant = build_plant(m)
    ref = reference("move", profile=profile)
    runs = {}
    for guard in (True, False):
        inv = load_controller("deadzone_inverse", plant)
        if not guard:
            monkeypatch.setattr(inv, "_one_way", lambda *a: 0.0)
        runs[guard] = simulate_closed_loop(plant, inv, ref, 1.5, sensors=m.sensors)
    same = np.array_equal(runs[True].torque, runs[False].torque)
    assert same is not acts
    if acts:
        final = {g: abs(float(r.error[-1])) for g, r in runs.items()}
        print(f"\nfinal error {final[True] * 1e6:.2f} urad with the guard, {final[False] * 1e6:.2f} without")
        assert final[True] < final[False]


def test_inverse_crossing_stops_where_the_motor_meets_the_load(monkeypatch: pytest.MonkeyPatch) -> None:
    # ISO 230-2 on shing1993_servo_friction with a 1.2 b estimate: the motor meets the load 17 % before its ramp
    # ends and lags the ramp; the crossing then ends there. Measured: B = 56 urad with 5 crossings ended early,
    # against 425 urad when the ramp runs on (the motor pushes the stuck load 0.2 b / r_b2 further at every
    # reversal). Kept: 4x (measured 7.6x); with the right estimate no crossing ends early (no false alarm)
    m = load_model(FRICTION)
    plant = build_plant(m)
    B, contacts = {}, {}
    on = deadzone.CONTACT_LAG
    for lag in (on, math.inf):
        monkeypatch.setattr(deadzone, "CONTACT_LAG", lag)
        inv = load_controller("deadzone_inverse", plant, backlash=1.2 * plant.backlash)
        B[lag] = precision_test(plant, inv, sensors=m.sensors).stats["reversal_value"]
        contacts[lag] = inv.contacts
    print(f"\nB {B[on] * 1e6:.0f} urad with the contact check ({contacts[on]} early ends), "
          f"{B[math.inf] * 1e6:.0f} without")
    assert contacts[on] >= 1 and contacts[math.inf] == 0
    assert B[math.inf] >= 4.0 * B[on]
    monkeypatch.undo()
    inv = load_controller("deadzone_inverse", plant)
    precision_test(plant, inv, cycles=1, sensors=m.sensors)
    assert inv.contacts == 0


def test_inverse_rattle_guard_stops_a_rattle(monkeypatch: pytest.MonkeyPatch) -> None:
    # the Yang-Sun mesh is nearly elastic at high impact speeds: with a 15 ms crossing the inverse's motor
    # falls into a rattle between the flanks that its derivative action feeds (2450 impacts in 3 s, RMS 5.4e-4
    # rad, against the PID's 5.8e-4). The guard scales the feedback down while speed jumps the torque cannot
    # explain come in a run, and the error is within twice the lost motion: 420 impacts, RMS 1.2e-4 rad (without
    # the error bound 362 and 2.8e-4). Kept: 3x fewer impacts (measured 5.8x) and 1.5x less error (measured 4.6x);
    # on the improved plant with the catalog settings it never engages
    m = load_model(SERVO)
    nominal = build_plant(m)
    spec = {**read_toml(resolve("deadzone_inverse", "controllers")), "crossing_time": 0.015}
    out = {}
    level_on = deadzone.RATTLE_LEVEL
    for level in (level_on, math.inf):
        monkeypatch.setattr(deadzone, "RATTLE_LEVEL", level)
        ctrl = build_controller(spec, nominal, path=Path("deadzone_inverse.toml"))
        res = simulate_closed_loop(build_plant(m, "yang-sun"), ctrl, reference("sine"), 3.0, sensors=m.sensors)
        out[level] = (len(res.impacts), float(np.sqrt(np.mean(res.error[res.t >= 0.5] ** 2))))
    on, off = out[level_on], out[math.inf]
    print(f"\nYang-Sun, 15 ms crossing: guard {on[0]} impacts, RMS {on[1]:.3g}; "
          f"none {off[0]} impacts, RMS {off[1]:.3g}")
    assert off[0] >= 3 * on[0]
    assert off[1] >= 1.5 * on[1]
    monkeypatch.undo()
    inv = load_controller("deadzone_inverse", nominal)
    engaged = []
    step = inv.step

    def record(t: float, ym: float, yl: float | None, r: Reference) -> float:
        u = step(t, ym, yl, r)
        engaged.append(inv.rattling)
        return u

    inv.step = record  # type: ignore[method-assign]
    simulate_closed_loop(nominal, inv, reference("sine"), 3.0, sensors=m.sensors)
    assert not any(engaged)


@pytest.mark.parametrize("model", ["shing1993_servo", "servo_2stage_phm09", "servo_3stage_quanser_srv02"])
def test_mpc_contact_tolerance_of_a_train(model: str) -> None:
    # 0.02 b for a pair; for a train plus the share of the lost motion of every stage but the last, computed
    # here from the stages' data (2 b_i / (r_b2,i prod_(j>i) N_j) over the lost motion): 0.32 b for the SRV02
    # (stages 1 and 2 hold 0.135 + 0.473 of its 2.02 mrad), 0.35 b for the PHM09
    from gearctl.design.base import loop_info
    from gearctl.design.mpc import contact_tolerance

    plant = build_plant(load_model(model))
    shares = []
    for i, st in enumerate(plant.stages):
        after = float(np.prod([s.ratio for s in plant.stages[i + 1:]]))
        shares.append(2.0 * st.backlash / (st.rb2 * after))
    assert sum(shares) == pytest.approx(plant.lost_motion, rel=1e-12)
    expected = 0.02 + sum(shares[:-1]) / plant.lost_motion
    assert contact_tolerance(loop_info(plant)) == pytest.approx(expected, rel=1e-12)
    mpc = load_controller("mpc", plant)
    assert mpc._tol == pytest.approx(expected * mpc._b, rel=1e-12)


def test_inverse_keeps_its_precision_on_a_long_sine() -> None:
    # the landing sample where (t - t0) / T rounded below 1 fed the ramp's last deceleration forward (a 0.2 N m
    # kick): from t = 4 s the sine's RMS went from 3.5 to 35 urad and stayed there. Measured since the fix:
    # 2.9-3.7 urad in every second from 1 s to 10 s; kept: the RMS of 4-8 s within 1.5x that of 1-3 s
    m = load_model(SERVO)
    plant = build_plant(m)
    res = simulate_closed_loop(plant, load_controller("deadzone_inverse", plant), reference("sine"), 8.0,
                               sensors=m.sensors)

    def rms(t0: float, t1: float) -> float:
        k = (res.t >= t0) & (res.t < t1)
        return float(np.sqrt(np.mean(res.error[k] ** 2)))

    early, late = rms(1.0, 3.0), rms(4.0, 8.0)
    print(f"\nRMS 1-3 s {early:.3g} rad, 4-8 s {late:.3g} rad")
    assert late <= 1.5 * early
    assert late < 1e-5


@pytest.mark.parametrize("controller", ["deadzone_inverse", "adaptive_inverse"])
def test_the_rattle_guard_is_not_fooled_by_a_coarse_noisy_encoder(controller: str) -> None:
    """4096 counts and 2e-4 rad of noise on the motor encoder: one count's flicker changes the second difference by
    1.5 rad/s, above the guard's 1.3 rad/s (half the speed that crosses the gap in two samples), so the guard
    flagged rattling 98 % of the time and cut the inverse's gain to a quarter: sine RMS 4.2e-2 rad, 64x the PID's
    6.6e-4. The guard's threshold is now never below what the encoder's counts and noise give (4.5 rad/s here).
    Measured: 5.5e-4 (inverse), 9.7e-4 (adaptive; 7.4e-4 before it measured the gap only across a flank change,
    which left it fewer windows: with a motor count of 29 um along the line of action, 0.6 b, every measurement
    reads 1.2-1.8 b and the estimate ends at 1.74 b, 1.36 b before); bound 1.5x the PID's, 1.6x for the adaptive."""
    m = load_model(Path(__file__).parent / "data" / "coarse_noisy_4096.toml")
    plant = build_plant(m)
    rms = {}
    for name in ("pid", controller):
        ctrl = load_controller(name, plant, sensors=m.sensors)
        res = simulate_closed_loop(plant, ctrl, reference("sine"), 3.0, sensors=m.sensors)
        e = (res.reference - res.x[1])[res.t >= 0.5]
        rms[name] = float(np.sqrt(np.mean(e**2)))
    assert rms[controller] <= (1.5 if controller == "deadzone_inverse" else 1.6) * rms["pid"], rms


def test_the_inverse_defaults_scale_with_the_servo() -> None:
    """A 1 mN m instrument servo (ratio 4): the catalog inverse's width (5e-4 N m) and disturbance threshold
    (0.02 N m) were absolute, 12 % and 500 % of the torque its motor can put on the load, so the flank never changed
    and the inverse gave its PID's RMS to every digit. The defaults now scale down with the load's own inertial and
    viscous torque on the catalog sine (the benchmark servo's values exactly: its figures are unchanged). Measured:
    1.32e-4 rad against the PID's 1.57e-3 (12x); bound 4x, and the benchmark servo's defaults are the old numbers."""
    m = load_model(Path(__file__).parent / "data" / "instrument_1mNm.toml")
    plant = build_plant(m)
    rms = {}
    for name in ("pid", "deadzone_inverse"):
        res = simulate_closed_loop(plant, load_controller(name, plant, sensors=m.sensors), reference("sine"), 3.0,
                                   sensors=m.sensors)
        e = (res.reference - res.x[1])[res.t >= 0.5]
        rms[name] = float(np.sqrt(np.mean(e**2)))
    assert rms["deadzone_inverse"] <= rms["pid"] / 4, rms
    servo = load_controller("deadzone_inverse", build_plant(load_model("shing1993_servo")))
    assert (servo.width, servo.disturbance_threshold) == (5e-4, 0.02)


def test_the_inverse_predicts_a_light_viscous_load_stably() -> None:
    """The free load's prediction during a crossing took its viscous friction in an explicit step: on a load whose
    viscous time constant J2 / d2 (0.46 ms here) is below half the sample, each step flipped and grew the predicted
    speed (x -1.15), the crossing chased it and the loop diverged (|omega| > 1e6 rad/s after 1.1 s of the sine). The
    speed now decays exactly. Checked: the predicted free load's speed decays monotonically as exp(-d2 t / J2), and
    the sine runs to its end (measured max error 1.6e-2 rad, RMS 5.7e-3; the PID's RMS 1.4e-3: the backlash, 1 um,
    is 3e-5 of this motor encoder's count, so the inverse has nothing to invert; bound: no divergence, max 0.05)."""
    m = load_model(Path(__file__).parent / "data" / "speedup_light_load.toml")
    plant = build_plant(m)
    # the backlash given: the model's alone, a tenth of a motor count, would have the inverse run as its PID
    ctrl = load_controller("deadzone_inverse", plant, sensors=m.sensors, backlash=plant.backlash)
    a = plant.d2 / plant.J2
    assert a * ctrl.Ts > 2.0  # the case: an explicit step is unstable
    ctrl._free = [0.0, 1.0]
    speeds = [ctrl._free_load()[1] for _ in range(6)] + [ctrl._free[1]]
    assert all(0.0 < w1 < w0 for w0, w1 in zip(speeds, speeds[1:], strict=False))
    assert speeds[-1] == pytest.approx(math.exp(-a * 6 * ctrl.Ts), rel=1e-9)
    res = simulate_closed_loop(plant, ctrl, reference("sine"), 3.0, sensors=m.sensors)
    assert res.success, res.message
    assert np.abs(res.error).max() < 0.05


def test_a_free_load_predicted_outside_the_gap_ends_the_crossing() -> None:
    """tests/data/featherweight_load_train.toml: a load of 1.7e-10 kg m^2. The observer's disturbance estimate on
    that inertia predicted the free load 6.6 rad away within a sample of the first crossing; the motor chased it at
    the torque limit and the sine ran at 154 rad RMS (max 457). Now the crossing ends where the prediction leaves the
    gap. Measured: RMS 6.7e-3 rad, the PID's 6.7e-3 (its lost motion, 2.5e-3 rad, is below the load's rattle in the
    gap); kept within 1.5x the PID's, the exit taken, and never taken on the catalog pair's sine."""
    m = load_model(Path(__file__).parent / "data" / "featherweight_load_train.toml")
    plant = build_plant(m)
    rms = {}
    for name in ("pid", "deadzone_inverse"):
        ctrl = load_controller(name, plant, sensors=m.sensors)
        res = simulate_closed_loop(plant, ctrl, reference("sine"), 3.0, sensors=m.sensors)
        assert res.success, res.message
        rms[name] = float(np.sqrt(np.mean(res.error[res.t >= 0.5] ** 2)))
    print(f"\nRMS {rms}, crossings ended outside the gap {ctrl.free_load_exits}")
    assert ctrl.free_load_exits >= 1
    assert rms["deadzone_inverse"] <= 1.5 * rms["pid"], rms
    pair = load_model("shing1993_servo")
    inv = load_controller("deadzone_inverse", build_plant(pair), sensors=pair.sensors)
    res = simulate_closed_loop(build_plant(pair), inv, reference("sine"), 3.0, sensors=pair.sensors)
    assert inv.free_load_exits == 0 and res.success


def test_a_backlash_under_a_motor_count_is_not_inverted() -> None:
    """tests/data/speedup_light_load.toml: the lost motion, 5.7e-4 rad at the motor, is a tenth of a count of its
    1024-count motor encoder. The inverse moved the motor by less than the loop resolves and its crossings only
    disturbed it: sine RMS 1.85e-3 rad against the PID's 1.43e-3. It now runs as its PID (the same torques, said in
    its design notes); the catalog servo's lost motion is 220 counts and is inverted."""
    m = load_model(Path(__file__).parent / "data" / "speedup_light_load.toml")
    plant = build_plant(m)
    inv = load_controller("deadzone_inverse", plant, sensors=m.sensors)
    pid = load_controller("pid", plant, sensors=m.sensors)
    assert inv.backlash == 0.0 and any("under one count" in n for n in inv.design_notes)
    runs = [simulate_closed_loop(plant, c, reference("sine"), 1.0, sensors=m.sensors) for c in (inv, pid)]
    np.testing.assert_array_equal(runs[0].torque, runs[1].torque)
    servo = load_model("shing1993_servo")
    assert load_controller("deadzone_inverse", build_plant(servo), sensors=servo.sensors).backlash > 0.0


def test_the_reversal_offset_notes_a_load_torque_that_holds_one_flank(tmp_path: Path) -> None:
    """A constant load torque (gravity) presses the load onto one flank; the reversal offset, acting on the command's
    reversals, then takes up a lost motion the load does not cross (a review's gravity-loaded arm: B 1125 urad
    against the PID's 1.4). The design says so; without a load torque it says nothing."""
    from gearctl.catalog import resolve

    text = resolve(SERVO, "models").read_text().replace("load_torque = 0.0 ", "load_torque = -0.5 ")
    assert "load_torque = -0.5 " in text
    path = tmp_path / "gravity.toml"
    path.write_text(text)
    notes = load_controller("reversal_offset", build_plant(load_model(path))).design_notes
    assert any(n.startswith("load_torque: the model's -0.5 N m presses the load onto one flank") for n in notes), notes
    assert not any("load_torque" in n for n in load_controller("reversal_offset", build_plant(load_model(SERVO)))
                   .design_notes)


def test_the_reversal_offset_notes_an_inertia_dominated_load() -> None:
    """Where the load's friction decelerates it more slowly than a move does, the load reaches the braking flank before
    the command reverses, and the offset at the reversal takes up a lost motion already crossed (frictionless servo:
    ISO B 2644 urad against the PID's 1317; a review's heavy turntable: 3915 against 1984). The design says so; on
    the friction servo (0.2 N m on 0.01 kg m^2: 20 rad/s^2) it does not."""
    free = load_controller("reversal_offset", build_plant(load_model(SERVO))).design_notes
    assert any(n.startswith("coulomb_friction2: the load's 0 N m of friction") for n in free), free
    held = load_controller("reversal_offset", build_plant(load_model(FRICTION))).design_notes
    assert not any("coulomb_friction2" in n for n in held), held


HEAVY_TURNTABLE = str(Path(__file__).parent / "data" / "heavy_turntable_m8.toml")


def test_a_flank_change_at_rest_is_no_crossing() -> None:
    """A reviewer's heavy turntable (40 kg m^2, 60 N m of Coulomb friction, motor encoder only): on the step the
    inverse's first flank decision came at rest, while the motor dragged the overshot load back on the back flank;
    run as a half-gap crossing it fed the free motor's ramp torque (-296 N m, then +277) to the whole train, the load
    slid back and rested one lost motion short: final error 1.93e-3 rad, the PID's -0.97e-3, no warning. A change
    decided at rest is now taken up in contact: 9.1e-5 rad (bound 2e-4, a tenth of the 1.9e-3 rad lost motion); the
    exported C does the same to the bit."""
    from gearctl.export import export_controller, load_exported

    m = load_model(HEAVY_TURNTABLE)
    plant = build_plant(m)
    ctrl = load_controller("deadzone_inverse", plant, sensors=m.sensors)
    res = simulate_closed_loop(plant, ctrl, reference("step"), 2.0, sensors=m.sensors)
    final = float(res.reference[-1] - res.x[1, -1])
    print(f"\nheavy turntable step: final error {final:.3g} rad (lost motion {plant.lost_motion:.3g})")
    assert abs(final) < 2e-4
    if shutil.which(os.environ.get("CC", "cc")):
        import tempfile

        with tempfile.TemporaryDirectory() as d:
            export_controller(ctrl, d, plant=plant, sensors=m.sensors, model=m.name)
            c = simulate_closed_loop(plant, load_exported(d), reference("step"), 2.0, sensors=m.sensors)
        np.testing.assert_array_equal(c.torque, res.torque)


def test_the_inverse_catches_a_gravity_load_at_start_up() -> None:
    """A reviewer's 17 x 119 arm under 2.5 N m of gravity: the first flank decision comes at rest, from the model's load
    torque. As a half-gap crossing it let the load fall 2.06 mrad before catching it (the move's largest error 3.4x
    the PID's 0.61 mrad); taken up in contact, 0.30 mrad. Bound: the PID's largest error."""
    m = load_model(str(Path(__file__).parent / "data" / "gravity_arm_17x119.toml"))
    plant = build_plant(m)
    worst = {}
    for name in ("pid", "deadzone_inverse"):
        res = simulate_closed_loop(plant, load_controller(name, plant, sensors=m.sensors), reference("move"), 2.0,
                                   sensors=m.sensors)
        worst[name] = float(np.max(np.abs(res.reference - res.x[1])))
    print(f"\ngravity arm, move: largest error {worst}")
    assert worst["deadzone_inverse"] < worst["pid"]


def test_inverse_stop_drops_the_integral_that_pushes_back() -> None:
    # a small gap on the frictionless servo (b = 10 um, lost motion 266 urad): the stop rule withheld the
    # proportional push-back but the integral built while a late landing was corrected kept pushing, and launched
    # the load off its braking flank after the short overshoot moves, across the whole gap: ISO A 500 urad against
    # the PID's 282. With the integral dropped as well: 131 urad (2 cycles: 104 against 283). Kept: below 0.6x the
    # PID's, over 2 cycles
    m = load_model(SERVO)
    plant = build_plant(m, backlash=1e-5)
    A = {name: precision_test(plant, load_controller(name, plant), cycles=2, sensors=m.sensors).stats["accuracy"]
         for name in ("pid", "deadzone_inverse")}
    print(f"\nb = 10 um, ISO A: PID {A['pid'] * 1e6:.0f} urad, inverse {A['deadzone_inverse'] * 1e6:.0f} urad")
    assert A["deadzone_inverse"] <= 0.6 * A["pid"]
