"""The MPC's standstill, its independence of the absolute angle, and wild encoder readings (review of the MPC).

1. A long rest holds. Before, the plan hunted across the gap for as long as the reference rested: on
   ``gearctl track shing1993_servo mpc --reference move --duration 20`` about 370 flank changes in the last
   10 s (a sustained limit cycle; 100+ on the friction servo). Mechanism: at rest, a gap drifting towards the
   other flank (the motor backing off a friction-held load as the integral action unwound its push, or
   rebounding from a landing) was met on that flank within the horizon, a full-speed crossing that landed
   hard and rebounded; and the disturbance estimate's quantisation noise, compensated in contact, kicked a
   frictionless load out of the deadband. The tests run a 0.2 rad move and a long rest on the three models.
2. The QP's angles are taken from the reference at ``t``: the controller fed the same readings and reference
   shifted by 1e4 rad gives the same torques to the rounding of the offset (before: up to the torque limit).
3. A finite reading beyond the gate (what the torque limit moves the motor in a sample plus twice the lost
   motion) is rejected and reported as a fallback; a non-finite load reading is a missing one; a reading that
   persists is taken as the truth after 4 samples.

The runs are deterministic (quantised encoders, fixed seed); the module takes about 10 s.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from gearctl import load_model
from gearctl.build import c_compiler
from gearctl.catalog import load_controller
from gearctl.closedloop import simulate_closed_loop
from gearctl.plant import build_plant
from gearctl.references import reference
from gearctl.runs import execute, make_run

SERVO, FRICTION, PINION = "shing1993_servo", "shing1993_servo_friction", "pinion17_shifted_shing1993"
MODELS = (SERVO, FRICTION, PINION)
DATA = Path(__file__).parent / "data"


def _flank_changes(res, after: float) -> int:  # noqa: ANN001 - a ClosedLoopResult
    """Changes of flank between consecutive impacts after time ``after`` (each crossing of the gap is one)."""
    ev = res.event_log
    sides = ev["side"][(ev["kind"] == 1) & (ev["t"] >= after)]
    return int(np.sum(sides[1:] != sides[:-1]))


# --- 1. a long rest holds ---------------------------------------------------------------------------------


@pytest.mark.parametrize(("model", "duration"), [(SERVO, 5.0), (SERVO, 20.0), (SERVO, 30.0), (FRICTION, 20.0),
                                                 (FRICTION, 30.0), (PINION, 20.0)])
def test_a_long_rest_holds(model: str, duration: float) -> None:
    # the move ends at 0.42 s. Measured after 1 s: 0 flank changes on all six runs (0 impacts on the
    # frictionless models, 0-1 on the friction servo); before, 137 / 696 / 1057 (servo 5 / 20 / 30 s), 405 / 474
    # (friction 20 / 30 s) and 753 (pinion 20 s). One change is allowed
    run = make_run(model, "mpc", reference_kind="move", duration=duration)
    out, res = execute(run, keep=True)
    assert res is not None and out.ok, out.message
    changes = _flank_changes(res, 1.0)
    print(f"\n{model} {duration:g} s: {changes} flank changes after 1 s, final error {out.metrics.final_error:.3g} rad")
    assert changes <= 1, changes
    assert not out.metrics.health.limit_cycle
    # the hold keeps the load within its release band, three deadbands (2e-4 rad each); measured 4.9e-4 rad on
    # the frictionless servo after 30 s (a free load coasts on after the move until its viscous friction stops
    # it: 2.3 s time constant), 2.2e-6 rad with load friction
    ctrl = load_controller("mpc", run.design.nominal)
    assert abs(out.metrics.final_error) <= 3.0 * ctrl.settings.standstill_deadband


def test_frictionless_load_at_rest_gets_no_torque() -> None:
    # holding with no load torque to hold against, once the plan has let go, the MPC puts no torque on the
    # free load (each torque the disturbance estimate's quantisation noise asked for pushed it out of the
    # deadband before): exactly zero over the last 5 s of a 10 s rest
    run = make_run(SERVO, "mpc", reference_kind="move", duration=10.0)
    _, res = execute(run, keep=True)
    assert res is not None
    assert np.all(res.torque[res.t >= 5.0] == 0.0)


def test_friction_held_load_is_pushed_to_the_target() -> None:
    # with load friction the hold still corrects what its flank can: the load ends within 3 urad of the target
    # (measured 2.2e-6 rad) and stays there, no impact after 1 s
    run = make_run(FRICTION, "mpc", reference_kind="move", duration=10.0)
    out, res = execute(run, keep=True)
    assert res is not None
    assert abs(out.metrics.final_error) < 5e-6
    ev = res.event_log
    assert np.sum((ev["kind"] == 1) & (ev["t"] >= 1.0)) <= 1


# --- 2. the absolute angle ---------------------------------------------------------------------------------


class _Shifted:
    """A reference shifted by ``offset`` [rad] (its speed, acceleration and load torque unchanged)."""

    def __init__(self, ref, offset: float) -> None:  # noqa: ANN001 - a Reference
        self.ref, self.offset = ref, offset
        self.settle = ref.settle

    def at(self, t):  # noqa: ANN001, ANN202 - as Reference.at
        r, rd, rdd = self.ref.at(t)
        return np.asarray(r) + self.offset, rd, rdd

    def load_disturbance(self, t: float) -> float:
        return self.ref.load_disturbance(t)


def test_torques_do_not_depend_on_the_absolute_angle() -> None:
    # the readings of a 2 s sine run on the servo, fed again to a fresh controller as they are and shifted by
    # 1e4 rad (motor: N x 1e4) and -3.7e4 rad: the torques agree to 1.5e-8 and 8.4e-8 N m (the rounding of the
    # offset: a double's spacing is 1.8e-12 rad at 1e4 rad); before, the QP was fed absolute angles and they
    # differed by up to the 1 N m limit. Bound: 1e-6 N m
    m = load_model(SERVO)
    plant = build_plant(m)
    ref = reference("sine")
    res = simulate_closed_loop(plant, load_controller("mpc", plant), ref, 2.0, sensors=m.sensors)
    N = plant.gear_ratio
    out = {}
    for offset in (0.0, 1e4, -3.7e4):
        ctrl = load_controller("mpc", plant)
        shifted = _Shifted(ref, offset)
        out[offset] = np.array([ctrl.step(float(t), float(ym) + N * offset, float(yl) + offset, shifted)
                                for t, ym, yl in zip(res.t, res.y_motor, res.y_load, strict=True)])
        assert not ctrl.fallbacks
    for offset in (1e4, -3.7e4):
        du = float(np.max(np.abs(out[offset] - out[0.0])))
        assert du < 1e-6, (offset, du)


def test_closed_loop_at_an_offset_tracks_as_at_zero() -> None:
    # the whole loop (plant, controller) offset by 1e4, 3e4 and 1e5 rad on the friction servo, 3 s of the 1 Hz sine,
    # ideal sensors: the same RMS to 1e-6 relative (measured: 2.28434e-4 rad at every offset). With the 2^20-count
    # encoders the counts fall elsewhere relative to the state at a large angle, a different experiment (2.7 % at
    # 1e4 rad, 0.02 % at a count-aligned offset). The frictionless servo is no yardstick: its sine loop is chaotic
    m = load_model(FRICTION)
    plant = build_plant(m)
    rms = {}
    for offset in (0.0, 1e4, 3e4, 1e5):
        x0 = np.zeros(4)
        x0[0], x0[1] = plant.gear_ratio * offset, offset
        ref = _Shifted(reference("sine"), offset)
        res = simulate_closed_loop(plant, load_controller("mpc", plant), ref, 3.0, x0=x0)
        e = (res.reference - res.x[1])[res.t >= ref.settle]
        rms[offset] = float(np.sqrt(np.mean(e**2)))
    for offset in (1e4, 3e4, 1e5):
        assert rms[offset] == pytest.approx(rms[0.0], rel=1e-6), rms


# --- 3. wild and missing readings --------------------------------------------------------------------------


def _glitched_run(model: str, glitch: dict[float, tuple[int, float]], kind: str = "sine", duration: float = 2.0,
                  controller=None):  # noqa: ANN001, ANN202 - a Controller; returns (result, controller)
    """A closed-loop run whose encoder readings are replaced at the given times: ``{t: (0 motor | 1 load, value)}``."""
    m = load_model(model)
    plant = build_plant(m)
    ctrl = controller if controller is not None else load_controller("mpc", plant)
    step = ctrl.step

    def glitched(t, ym, yl, ref):  # noqa: ANN001, ANN202
        for tg, (which, value) in glitch.items():
            if abs(t - tg) < 1e-9:
                ym, yl = (value, yl) if which == 0 else (ym, value)
        return step(t, ym, yl, ref)

    ctrl.step = glitched
    return simulate_closed_loop(plant, ctrl, reference(kind), duration, sensors=m.sensors), ctrl


@pytest.mark.parametrize(("which", "value"), [(0, 1e300), (1, 1e300), (0, 1e6), (1, -1e6)])
def test_one_wild_reading_is_rejected(which: int, value: float) -> None:
    # one reading replaced by 1e300 or 1e6 rad at t = 1 s of the 1 Hz sine on the friction servo: rejected, one
    # fallback reported. Before, the estimate ran away: the load was 116 rad off after 1e300, 0.8-1.3 rad after
    # 1e6. Through the next reversal (to 1.25 s) the run stays within 3 urad of the run without the glitch
    # (measured; bound 1e-5 rad, under 1 % of the 1.3e-3 rad lost motion). The reversals after that are the
    # loop's own: a landing on a friction-held load is chaotic, and a few urad decide how the next one goes
    # (the load's friction in the plan: largest error 1.46e-3 rad at 1.79 s after the 1e300 load reading, 0.89e-3
    # without the glitch; 1.28e-3 on the plain run before that change). Bound: twice the plain run's
    base, _ = _glitched_run(FRICTION, {})
    res, ctrl = _glitched_run(FRICTION, {1.0: (which, value)})
    e0, e = base.reference - base.x[1], res.reference - res.x[1]
    near = (res.t >= 1.0) & (res.t < 1.25)
    if not (which == 0 and abs(value) > 1e12):  # a motor reading beyond the input limit is a missed sample instead:
        # zero torque for that sample (4.3e-4 rad of error over the next 0.1 s on this sine, measured)
        assert np.max(np.abs(e[near] - e0[near])) < 1e-5
    after = res.t >= base.settle
    assert np.max(np.abs(e[after])) <= 2.0 * np.max(np.abs(e0[after]))
    # a reading beyond the input limit (1e12 rad) is a missed sample on the motor, as in the exported API, and a
    # missing reading on the load; a load reading within it that puts the gap beyond any the gear allows is not
    # used (the motor encoder alone); a wild motor reading is rejected by the gate
    said = ("beyond 1e12" if which == 0 else "missing") if abs(value) > 1e12 else (
        "rejected" if which == 0 else "inconsistent")
    assert len(ctrl.fallbacks) == 1 and said in ctrl.fallbacks[0]["reason"], ctrl.fallbacks
    assert ctrl.fallbacks[0]["t"] == pytest.approx(1.0)


@pytest.mark.parametrize("value", [math.nan, math.inf])
def test_a_non_finite_load_reading_is_missing(value: float) -> None:
    # the motor encoder alone updates the estimate on that sample (as with feedback = "motor"), reported
    base, _ = _glitched_run(FRICTION, {})
    res, ctrl = _glitched_run(FRICTION, {1.0: (1, value)})
    assert abs((res.reference - res.x[1])[-1] - (base.reference - base.x[1])[-1]) < 1e-5
    assert len(ctrl.fallbacks) == 1 and "missing" in ctrl.fallbacks[0]["reason"]


def test_a_load_reading_beyond_the_input_limit_is_missing_however_long() -> None:
    # a load encoder that reads 1e13 rad (beyond INPUT_LIMIT, 1e12) for 100 samples is a missing reading, as a NaN:
    # the motor encoder alone updates the estimate, every such step reported, and no fault. Before, the gate
    # rejected it and restarted the estimate from it every few samples: a latched fault within 100 samples
    # (found by a C harness written from the exported API's documentation)
    base, _ = _glitched_run(FRICTION, {})
    res, ctrl = _glitched_run(FRICTION, {1.0 + k * 1e-3: (1, 1e13) for k in range(100)})
    assert not ctrl.fault
    assert len(ctrl.fallbacks) == 100 and all("missing" in f["reason"] for f in ctrl.fallbacks)
    e0, e = base.reference - base.x[1], res.reference - res.x[1]
    near = (res.t >= 1.0) & (res.t < 1.25)
    assert np.max(np.abs(e[near])) <= 2.0 * np.max(np.abs(e0[near])) + 1e-5


def test_a_load_reading_the_gap_cannot_explain_is_not_used() -> None:
    # the load encoder reads 0.1 rad for 50 samples at rest after the move (a C harness written from the exported
    # API's documentation): the gate rejected it 4 times, then restarted the estimate from it, the plan drove the
    # motor at full torque to close a 7.5 mm "gap", and the fault latched after three restarts with the load 0.69
    # rad away. A load reading whose gap from the motor's exceeds gap_limit (2.5 b, the mesh's deflection, the
    # contact tolerance: 1.3e-4 m here) is now a missing one: the motor encoder alone, every step reported, no
    # fault, and the run is the plain run's (measured: the same largest error, 8.62e-5 rad; bound 2x and 1e-5)
    base, _ = _glitched_run(FRICTION, {}, kind="move", duration=1.5)
    res, ctrl = _glitched_run(FRICTION, {0.5 + k * 1e-3: (1, 0.1) for k in range(50)}, kind="move", duration=1.5)
    assert not ctrl.fault
    assert len(ctrl.fallbacks) == 50 and all("inconsistent" in f["reason"] for f in ctrl.fallbacks)
    e0, e = base.reference - base.x[1], res.reference - res.x[1]
    assert np.max(np.abs(e)) <= 2.0 * np.max(np.abs(e0)) + 1e-5


@pytest.mark.parametrize(("model", "bound"), [(SERVO, 2e-3), (FRICTION, 1e-4)])
def test_a_load_encoder_zeroed_off_the_gap_falls_back_to_the_motor_encoder(model: str, bound: float) -> None:
    # the load encoder reads 10 mrad (15x half the lost motion) more than the load's angle over the whole move: the
    # estimate took the encoders' difference for the gap and the load ran away, 0.91 and 0.20 rad RMS. Now every
    # reading is inconsistent with the motor's and the motor encoder alone is used, every step reported. Measured
    # RMS 9.4e-4 (the frictionless load drifting within the deadband: the MPC on the motor encoder) and 5.3e-6 rad
    # (the plain run's 5.8e-6)
    m = load_model(model)
    plant = build_plant(m)
    ctrl = load_controller("mpc", plant, sensors=m.sensors)
    step = ctrl.step
    ctrl.step = lambda t, ym, yl, ref: step(t, ym, yl + 0.01, ref)  # noqa: E731
    res = simulate_closed_loop(plant, ctrl, reference("move"), 3.0, sensors=m.sensors)
    e = res.reference - res.x[1]
    assert not ctrl.fault
    assert len(ctrl.fallbacks) == res.t.size - 1 and "inconsistent" in ctrl.fallbacks[-1]["reason"]  # every step
    assert float(np.sqrt(np.mean(e**2))) < bound


def test_a_non_finite_motor_reading_is_a_missed_sample() -> None:
    # as the exported API's bad input: zero torque, the estimate and plan unchanged, reported
    m = load_model(FRICTION)
    ctrl = load_controller("mpc", build_plant(m))
    ref = reference("sine")
    ctrl.step(0.0, 0.0, 0.0, ref)
    z, plan = ctrl._z.copy(), ctrl._plan.copy()
    assert ctrl.step(1e-3, math.nan, 0.0, ref) == 0.0
    assert np.array_equal(ctrl._z, z) and np.array_equal(ctrl._plan, plan)
    assert len(ctrl.fallbacks) == 1 and "motor reading not finite" in ctrl.fallbacks[0]["reason"]


def test_a_persistent_jump_is_taken_as_the_truth() -> None:
    # both encoders jump by 0.02 rad of the load (a re-homed axis; beyond the 3.8e-3 rad gate of the load
    # encoder on the servo) and stay there: the first 4 readings are rejected, the 5th restarts the estimate
    # from the readings, then no more fallbacks
    m = load_model(FRICTION)
    plant = build_plant(m)
    ctrl = load_controller("mpc", plant)
    assert 0.02 > ctrl.reading_gate[1]
    ref = reference("move")
    N = plant.gear_ratio
    for k in range(100):
        jump = 0.0 if k < 50 else 0.02
        ctrl.step(k * 1e-3, N * jump, jump, ref)
    reasons = [f["reason"] for f in ctrl.fallbacks]
    assert len(reasons) == 5 and all("rejected" in r for r in reasons[:4]) and "restarted" in reasons[4]
    theta2 = ctrl._z[0] / ctrl.model.N - ctrl.model.kappa2 * ctrl._z[2]
    assert theta2 == pytest.approx(0.02, abs=2e-3)


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("kind", ["sine", "step", "ramp", "move"])
def test_the_gate_never_fires_in_normal_running(model: str, kind: str) -> None:
    # impacts, a 0.5 N m load-torque step, start-up: no reading of the catalog runs comes near the gate
    run = make_run(model, "mpc", reference_kind=kind)
    _, res = execute(run, keep=True)
    assert res is not None
    assert not [f for f in res.fallbacks if "reading" in f["reason"]]


def test_the_gate_never_fires_on_the_yang_sun_plant() -> None:
    # the Yang-Sun contact law bounces in long cascades of tiny impacts (about 3000 in 3 s)
    run = make_run(SERVO, "mpc", plant="yang-sun", reference_kind="sine")
    _, res = execute(run, keep=True)
    assert res is not None
    assert not [f for f in res.fallbacks if "reading" in f["reason"]]


@pytest.mark.skipif(c_compiler() is None or shutil.which("make") is None, reason="needs a C compiler and make")
def test_exported_c_rejects_the_wild_reading_as_the_python(tmp_path) -> None:  # noqa: ANN001
    # the review's case, in the exported C: y[0] = 1e300 for one sample made it drift 455 rad in 2 s. Now the C
    # rejects it as the Python does: the same torques to the last bit, the step flagged as a fallback
    from gearctl.export import export_controller, load_exported

    m = load_model(FRICTION)
    plant = build_plant(m)
    export_controller(load_controller("mpc", plant), tmp_path, plant=plant, sensors=m.sensors, vectors=False)
    glitch = {1.0: (0, 1e300), 1.5: (1, 1e6), 1.7: (1, math.inf), **{1.2 + k * 1e-3: (1, 0.5) for k in range(20)}}
    py, _ = _glitched_run(FRICTION, glitch)
    c, sil = _glitched_run(FRICTION, glitch, controller=load_exported(tmp_path))
    np.testing.assert_array_equal(c.torque, py.torque)
    assert [round(f["t"], 6) for f in sil.fallbacks] == sorted(round(t, 6) for t in glitch)


@pytest.mark.parametrize("kind, bound", [("move", 5e-4), ("sine", 2e-3)])
def test_the_motor_friction_the_model_gives_is_planned_with(kind: str, bound: float) -> None:
    """A motor with 1 % of the torque limit of Coulomb friction (tests/data/motor_friction.toml): the plan counts
    with it (*Friction*). Measured RMS 1.25e-4 rad (move) and 4.3e-4 rad (sine); before, 2.3e-2 and 7.2e-3 rad:
    every landing was planned for the next sample and none happened, the friction holding the motor back."""
    out = execute(make_run(DATA / "motor_friction.toml", "mpc", reference_kind=kind))
    assert out.ok, out.message
    assert out.metrics["rms_error"] < bound


def test_a_landing_that_stalls_short_of_the_flank_is_taken_as_contact() -> None:
    """Motor friction the design does not know (2 % of the torque limit on the true plant only): a planned landing
    stops short of the flank, the observer's gap speed biased by the friction; after the crossing's length and five
    samples more, contact is taken where the gap stopped (*Stalled landings*). Measured sine RMS 2.0e-3 rad; before,
    0.11 rad, the load left behind for as long as the reference moved on."""
    out = execute(make_run(FRICTION, "mpc", reference_kind="sine", overrides={"coulomb_friction1": 0.02}))
    assert out.ok, out.message
    assert out.metrics["rms_error"] < 5e-3


# --- the encoders the model declares ---------------------------------------------------------------------------


def test_the_default_measurement_noise_follows_the_encoders(tmp_path: Path) -> None:
    """Without ``measurement_noise`` in the controller file the MPC's observer takes the model's motor encoder's
    reading error (quantisation 2 pi / cpr / sqrt(12), and noise), at least 2e-6 rad; the load encoder's is not
    used (the load reading is never weighed below the motor's); a value the file gives wins."""
    from gearctl import Sensors
    from gearctl.design.mpc import MEASUREMENT_NOISE_FLOOR

    plant = build_plant(load_model("shing1993_servo"))
    q = 2 * math.pi / 4096 / math.sqrt(12)
    coarse = Sensors(motor_encoder_cpr=4096, load_encoder_cpr=65536, load_noise=1e-5)
    assert load_controller("mpc", plant, sensors=coarse).settings.measurement_noise == pytest.approx(q, rel=1e-12)
    noisy = Sensors(motor_encoder_cpr=2**20, motor_noise=1e-4, load_encoder_cpr=2**20)
    assert load_controller("mpc", plant, sensors=noisy).settings.measurement_noise == pytest.approx(
        math.hypot(1e-4, 2 * math.pi / 2**20 / math.sqrt(12)), rel=1e-12)
    coarse_load = Sensors(motor_encoder_cpr=2**20, load_encoder_cpr=65536)
    assert load_controller("mpc", plant, sensors=coarse_load).settings.measurement_noise == MEASUREMENT_NOISE_FLOOR
    fine = load_model("shing1993_servo").sensors  # 2^20 counts: 1.7e-6 rad, below the floor
    assert load_controller("mpc", plant, sensors=fine).settings.measurement_noise == MEASUREMENT_NOISE_FLOOR
    assert load_controller("mpc", plant).settings.measurement_noise == MEASUREMENT_NOISE_FLOOR
    text = (Path(__file__).parents[1] / "controllers" / "mpc.toml").read_text()
    given = tmp_path / "mpc_given.toml"
    given.write_text(text.replace("[observer]\n", "[observer]\nmeasurement_noise = 3e-6\n"))
    assert load_controller(given, plant, sensors=coarse).settings.measurement_noise == 3e-6


def test_a_coarse_motor_encoder_is_positioned_as_well_as_the_pid() -> None:
    """An unseen POM pair with a 4096-count motor encoder (1.5e-3 rad a count, 4.4e-4 rad rms): with the catalog's
    2e-6 rad measurement noise the MPC trusted each count as exact and missed its ISO targets by up to 23 mrad
    (accuracy A), 5x its PID's 4.4 mrad. With the noise of the model's encoders the gap is below what they
    resolve, the plan is the rigid train's, and A is 1.8 mrad (measured; the PID's 4.40 mrad)."""
    from gearctl.precision import precision_test

    m = load_model(DATA / "plastic_pom.toml")
    plant = build_plant(m)
    mpc = load_controller("mpc", plant, sensors=m.sensors)
    assert mpc.rigid_reason.startswith("the measured gap's noise")
    a_mpc = precision_test(plant, mpc, sensors=m.sensors).stats["accuracy"]
    a_pid = precision_test(plant, load_controller("pid", plant), sensors=m.sensors).stats["accuracy"]
    assert a_mpc < 0.6 * a_pid, (a_mpc, a_pid)
    assert a_mpc < 2.5e-3, a_mpc


def _sine_without_refused_readings(name: str) -> tuple[float, float]:
    """The MPC's and the PID's sine RMS on ``tests/data/NAME``, no load reading refused by the MPC."""
    path = str(DATA / name)
    out, res = execute(make_run(path, "mpc"), keep=True)
    pid = execute(make_run(path, "pid"))
    assert res is not None and out.ok and pid.ok
    assert not [f for f in res.fallbacks if "reading" in f["reason"]], res.fallbacks[:3]
    print(f"\nMPC RMS {out.metrics.rms_error:.3g} rad, PID {pid.metrics.rms_error:.3g} rad")
    return out.metrics.rms_error, pid.metrics.rms_error


def test_the_gate_allows_for_coarse_encoders() -> None:
    # tests/data/coarse_encoders_train.toml: a 1024-count load encoder (6.1e-3 rad a count) on a train whose lost
    # motion at the output is 2.3e-4 rad. Before gap_limit and reading_gate allowed for a count and the noise of
    # each encoder, 2967 of 3000 load readings were refused and the sine ran at 7.9e-2 rad RMS on the motor
    # encoder alone. Measured now: no refused reading, RMS 4.6e-4 rad (5.5e-4 before the load reading was weighed
    # by its own error; the PID's 6.8e-4); kept: none refused, and within the PID's RMS
    mpc, pid = _sine_without_refused_readings("coarse_encoders_train.toml")
    assert mpc < pid


def test_the_gate_takes_the_gap_within_the_flanks() -> None:
    # tests/data/load_torque_light_load.toml: a 0.25 N m load torque on a 3.6e-7 kg m^2 load. The gate compared the
    # readings with the free prediction of the gap, which the torque carried 3.3 mm (1000 b) past the flank within a
    # sample: all 2999 readings after the first were refused and the sine ran away (188 rad RMS). Measured now: none
    # refused, RMS 3.46e-4 rad, the PID's 3.49e-4 (the load torque holds the load on its back flank, the lost motion
    # away); kept: none refused and within 1.1x the PID's RMS
    mpc, pid = _sine_without_refused_readings("load_torque_light_load.toml")
    assert mpc < 1.1 * pid


def _flickered_run(counts: int, controller=None):  # noqa: ANN001, ANN202 - a Controller; returns (result, controller)
    """The 1 Hz sine on shing1993_servo with the load encoder one or two counts high on every other sample from 0.5
    to 2 s (a reading at a count's edge that flickers)."""
    m = load_model("shing1993_servo")
    plant = build_plant(m)
    ctrl = controller if controller is not None else load_controller("mpc", plant, sensors=m.sensors)
    step, count = ctrl.step, 2.0 * math.pi / m.sensors.load_encoder_cpr
    k = [0]

    def flickered(t, ym, yl, ref):  # noqa: ANN001, ANN202
        k[0] += 1
        if yl is not None and 0.5 <= t < 2.0 and k[0] % 2:
            yl = yl + counts * count
        return step(t, ym, yl, ref)

    ctrl.step = flickered
    return simulate_closed_loop(plant, ctrl, reference("sine"), 3.0, sensors=m.sensors), ctrl


@pytest.mark.parametrize(("counts", "bound"), [(1, 4e-4), (2, 1e-3), (3, 1.5e-3)])
def test_a_flickering_load_encoder_is_no_impact(counts: int, bound: float) -> None:
    # an external reviewer's harness flickered the load encoder by 2 counts (12 urad) on every other sample: the gap's
    # innovation (0.9 um) alternated above the impact threshold, the impact gain took each for a velocity jump, and
    # the plan hunted across the gap and ran away (0.28 rad RMS, 1 rad largest, every status ok; 3 counts: 0.23 rad).
    # A reading back where it was two samples ago, with the third large innovation in a row of alternating sign, all
    # within 24 reading stds (7 counts), is now a flicker: RMS 1.1e-4, 3.7e-4 and 5.6e-4 rad for 1, 2 and 3 counts
    # (the clean run 2.9e-6, the PID 6.5e-4), and the plain runs of every catalog and tests/data model keep their
    # figures to the bit (`track`, sine and step). Bounds: about 4x, 2.7x and 2.7x those
    res, _ = _flickered_run(counts)
    e = res.error[res.t >= 0.5]
    rms = float(np.sqrt(np.mean(e**2)))
    print(f"\n{counts}-count flicker: RMS {rms:.3g} rad, largest {np.max(np.abs(e)):.3g}")
    assert rms < bound
    assert np.max(np.abs(e)) < 3.0 * res.plant.lost_motion


DATA = Path(__file__).resolve().parent / "data"


def _with_load_encoder(src: Path, cpr: int, tmp_path: Path) -> Path:
    text = src.read_text()
    lines = [ln for ln in text.splitlines() if ln.split("=")[0].strip() == "load_encoder_cpr"]
    assert len(lines) == 1
    out = tmp_path / f"{src.stem}_load{cpr}.toml"
    out.write_text(text.replace(lines[0], f"load_encoder_cpr = {cpr}"))
    return out


def test_a_pair_weighs_a_coarser_load_encoder_by_its_own_error(tmp_path: Path) -> None:
    """On a pair the observer weighs each encoder by its own error; on a train the load reading keeps the motor's
    weight (the motor reads the load through gaps the one-gap model leaves out). A reviewer's pair, 65536-count load
    and 2^18-count motor encoders: weighed as the motor's, the plan's flank came and went at each reversal (step
    1.1e-2 rad RMS, 3.3x the PID's 3.2e-3; ramp 9.8e-4, the PID's 6.4e-4); now 1.2e-3 and 4.8e-4. A gravity arm
    with a 65536-count load encoder ran away (sine 0.18 rad RMS); now 1.2e-5."""
    m = load_model(DATA / "reviewer_pair_24x72.toml")
    mpc = load_controller("mpc", build_plant(m), sensors=m.sensors)
    assert mpc._sigma_load == pytest.approx(m.sensors.reading_std("load"), rel=1e-12)
    assert mpc._sigma_load > 3.0 * mpc.settings.measurement_noise
    train = load_model(_with_load_encoder(Path(__file__).resolve().parents[1] / "models"
                                          / "servo_3stage_quanser_srv02.toml", 65536, tmp_path))
    t_mpc = load_controller("mpc", build_plant(train), sensors=train.sensors)
    assert t_mpc._sigma_load == t_mpc.settings.measurement_noise < train.sensors.reading_std("load")
    model = str(DATA / "reviewer_pair_24x72.toml")
    for ref, share in (("step", 0.5), ("ramp", 0.9)):
        pid = execute(make_run(model, "pid", reference_kind=ref)).metrics
        got = execute(make_run(model, "mpc", reference_kind=ref)).metrics
        assert got.rms_error < share * pid.rms_error, (ref, got.rms_error, pid.rms_error)
    arm = str(_with_load_encoder(DATA / "gravity_arm_17x119.toml", 65536, tmp_path))
    assert execute(make_run(arm, "mpc")).metrics.rms_error < 1e-4
