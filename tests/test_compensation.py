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
pid                         2341 / 888 / 2086       1461 / 1215 / 1215
pid, backlash-free plant    17.7 / 16.9 / 17.2      386 / 369 / 369
deadzone_inverse            3292 / 978 / 2061       224 / 109 / 113
reversal_offset             2473 / 2218 / 2431      386 / 369 / 369
mpc                         327 / 44 / 327          8.4 / 3.5 / 6.8
==========================  ======================  ========================

The ISO runs take 0.5-2.5 s each; the module takes about 25 s. Those that only confirm an unmet claim on
the frictionless servo are marked ``slow``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gearctl import InputError, build_plant, load_model
from gearctl.catalog import load_controller, read_toml, resolve
from gearctl.closedloop import simulate_closed_loop
from gearctl.design.deadzone import DeadzoneInverse, OffsetRamp, ramp_shape
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
        self._cache: dict[tuple[str, str, float], dict[str, float]] = {}
        self._models = {m: load_model(m) for m in (SERVO, FRICTION)}

    def plant(self, model: str, backlash: float | None = None):  # noqa: ANN201 - a Plant
        return build_plant(self._models[model], backlash=backlash)

    def lost_motion(self, model: str) -> float:
        return self.plant(model).lost_motion

    def iso(self, model: str, controller: str, factor: float = 1.0) -> dict[str, float]:
        """``accuracy``, ``reversal_value``, ``repeatability`` [rad]; controller ``"free"``: the catalog PID on
        the backlash-free plant; ``factor``: the backlash estimate over the model's."""
        key = (model, controller, factor)
        if key not in self._cache:
            m = self._models[model]
            if controller == "free":
                plant = self.plant(model, backlash=0.0)
                ctrl = load_controller("pid", plant)
            else:
                plant = self.plant(model)
                b = None if factor == 1.0 else factor * plant.backlash
                ctrl = load_controller(controller, plant, backlash=b)
            st = precision_test(plant, ctrl, sensors=m.sensors).stats
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
        "issue 12 claim not met on the frictionless servo: best ISO accuracy is the MPC's, A = 327 urad against "
        "17.7 urad for the PID on the backlash-free plant (18x, not <= 3x). The MPC ends each move within a few "
        "urad, but the free load (no friction, elastic mesh impacts) leaves its flank at a few 1e-4 rad/s after "
        "some stops and drifts within the standstill deadband; holding a frictionless load needs a preloaded "
        "(anti-backlash) train")),
])
def test_best_compensator_reaches_backlash_free_accuracy(runs: _Runs, model: str) -> None:
    # measured on shing1993_servo_friction: best = mpc, A = 8.4 urad against 386 urad for the PID on the
    # backlash-free plant (ratio 0.022; the PID there is limited by the load's friction, which the MPC's
    # disturbance estimate and the inverse's friction feedforward remove). The issue asks for <= 3; the
    # ratio is kept below 0.5 (a 20x margin on the measurement, 6x on the claim)
    free = runs.iso(model, "free")["accuracy"]
    best = min(runs.iso(model, c)["accuracy"] for c in COMPENSATORS)
    print(f"\n{model}: best A {best * 1e6:.1f} urad, backlash-free PID {free * 1e6:.1f} urad, ratio {best / free:.3f}")
    assert best <= 3.0 * free
    assert best <= 0.5 * free


# --- 2. the dead-zone inverse (motor encoder only) against the lost motion ----------------------------------


@pytest.mark.parametrize("model", [
    FRICTION,
    pytest.param(SERVO, marks=_servo_slow_xfail(
        "issue 12 claim not met on the frictionless servo: the inverse (motor encoder only) gives B = 978, "
        "R = 2061 urad (0.74 and 1.55 L). The inner targets are within +-60 urad; the end targets, reached "
        "after the 0.02 rad ISO overshoot moves, end with the load floating off its flank (a motor encoder "
        "cannot see it), as the PID does")),
])
def test_inverse_cuts_reversal_and_repeatability(runs: _Runs, model: str) -> None:
    # measured on shing1993_servo_friction: B = 109 urad (0.082 L), R = 113 urad (0.085 L) against the PID's
    # 1215 / 1215 urad (0.91 L); the issue asks for <= 0.15 L each (200 urad), kept with that bound
    # (measured 0.55x of it) and an improvement over the PID of at least 5x (measured 11x)
    L = runs.lost_motion(model)
    inv, pid = runs.iso(model, "deadzone_inverse"), runs.iso(model, "pid")
    B, R = inv["reversal_value"], inv["repeatability"]
    print(f"\n{model}: inverse B {B * 1e6:.1f} ({B / L:.3f} L), R {R * 1e6:.1f} ({R / L:.3f} L) urad")
    assert B <= 0.15 * L
    assert R <= 0.15 * L
    assert B <= pid["reversal_value"] / 5.0


# --- 3. a backlash estimate off by +-20 % ---------------------------------------------------------------------


@pytest.mark.parametrize(("model", "factor"), [
    (FRICTION, 1.2),
    pytest.param(FRICTION, 0.8, marks=pytest.mark.xfail(strict=True, reason=(
        "at the bound, not below: with 0.8 b the inverse's B is 406 urad against the PID's 1215 / 3 = 405 urad "
        "(ratio 2.99). The offset error alone is 2 x 0.2 b / r_b2 = 266 urad, and the end targets' residual "
        "(the load stops 125 urad short after the overshoot moves) has the same sign"))),
    pytest.param(SERVO, 0.8, marks=_servo_slow_xfail(
        "not met on the frictionless servo: B = 723 urad with 0.8 b against the PID's 888 / 3 = 296 urad")),
    pytest.param(SERVO, 1.2, marks=_servo_slow_xfail(
        "not met on the frictionless servo: B = 1290 urad with 1.2 b against the PID's 888 / 3 = 296 urad")),
])
def test_wrong_backlash_estimate_keeps_reversal_down(runs: _Runs, model: str, factor: float) -> None:
    # measured on shing1993_servo_friction with 1.2 b: B = 265 urad against the PID's 1215 urad (4.6x; the
    # issue asks for >= 3x). An overestimate puts the load 0.2 b / r_b2 = 133 urad past the target from each
    # side, so B is about 2 x 133 urad plus the end targets' residual of the other sign
    B = runs.iso(model, "deadzone_inverse", factor)["reversal_value"]
    B_pid = runs.iso(model, "pid")["reversal_value"]
    print(f"\n{model}, estimate {factor} b: inverse B {B * 1e6:.1f} urad, PID {B_pid * 1e6:.1f} urad, "
          f"ratio {B_pid / B:.2f}")
    assert B_pid >= 3.0 * B


def test_mpc_with_an_underestimated_backlash_keeps_its_accuracy(runs: _Runs) -> None:
    # the MPC measures the gap with both encoders: with 0.8 b on shing1993_servo_friction it gives B = 4.0 urad
    # (3.5 with the right estimate), 300x below the PID's 1215; kept within 30 urad and 30x. (With 1.2 b it
    # never sees contact, |s| <= b < 1.2 b - tol, and fails: A = 15 mrad; reported, not tested here.)
    B = runs.iso(FRICTION, "mpc", 0.8)["reversal_value"]
    assert B <= 30e-6
    assert runs.iso(FRICTION, "pid")["reversal_value"] >= 30.0 * B


# --- 4. the industrial reversal offset beside them --------------------------------------------------------


def test_reversal_offset_beats_the_pid_on_a_friction_load(runs: _Runs) -> None:
    # measured on shing1993_servo_friction: reversal offset A / B / R = 386 / 369 / 369 urad against the PID's
    # 1461 / 1215 / 1215 (B ratio 0.30) and the backlash-free PID's 386 / 369 / 369: the offset takes up the
    # whole lost motion, what is left is the PID's own friction lag. Kept: B below half the PID's, and within
    # 10 % of the backlash-free PID's. The torque-sign inverse is better still (B = 109 urad): it also feeds
    # the load's friction forward
    rev, pid, free = (runs.iso(FRICTION, c) for c in ("reversal_offset", "pid", "free"))
    print(f"\nreversal offset B {rev['reversal_value'] * 1e6:.1f}, PID {pid['reversal_value'] * 1e6:.1f}, "
          f"backlash-free PID {free['reversal_value'] * 1e6:.1f} urad")
    assert rev["reversal_value"] <= 0.5 * pid["reversal_value"]
    assert rev["reversal_value"] == pytest.approx(free["reversal_value"], rel=0.1)


@pytest.mark.slow
def test_reversal_offset_loses_on_an_inertial_load(runs: _Runs) -> None:
    # measured on shing1993_servo: the reversal offset's B = 2218 urad, worse than the PID's 888: every move's
    # deceleration is carried by the back flank while the command still moves forward, so the offset holds
    # the motor on the wrong side of the gap and the load ends a full lost motion from where the offset
    # assumes it. The torque-sign inverse's B = 978 urad. Kept: the offset is worse than the PID by 1.5x
    # (measured 2.5x) and worse than the inverse
    rev, pid, inv = (runs.iso(SERVO, c)["reversal_value"] for c in ("reversal_offset", "pid", "deadzone_inverse"))
    assert rev >= 1.5 * pid
    assert rev > inv


# --- 5. the step with a load disturbance ------------------------------------------------------------------


@pytest.mark.parametrize("model", [SERVO, FRICTION])
def test_inverse_rejects_a_load_disturbance(runs: _Runs, model: str) -> None:
    # `gearctl track MODEL deadzone_inverse --reference step`: 0.05 rad step at 0.1 s, a 0.5 N m load torque
    # against the motion from 1 s; error at 2 s. Measured: inverse 0.28 urad (servo) and 1.8 urad (friction)
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


def test_mpc_does_not_hunt_at_standstill() -> None:
    # one ISO 230-2 cycle on the frictionless servo (12 dwells, 2 reversals of the reference): measured 1 flank
    # change at rest with the catalog's standstill_deadband (2e-4 rad), 25 without it (the plan then crosses
    # the gap after errors of a few urad, and every landing kicks the free load). The issue asks for at most
    # one crossing per reversal at rest; kept, and the deadband must cut the count at least 4x
    m = load_model(SERVO)
    plant = build_plant(m)
    spec = read_toml(resolve("mpc", "controllers"))
    counts = {}
    for db in (spec["standstill_deadband"], 0.0):
        ctrl = build_controller({**spec, "standstill_deadband": db, "max_solve_time": 1.0}, plant,
                                path=Path("mpc.toml"))
        res = precision_test(plant, ctrl, cycles=1, sensors=m.sensors).run
        counts[db] = _rest_crossings(res, ctrl.preview)
    held, free = counts[spec["standstill_deadband"]], counts[0.0]
    print(f"\nflank changes at rest: {sum(held)} with the deadband ({held}), {sum(free)} without ({free})")
    reversals = 2  # one cycle: the two overshoot points
    assert sum(held) <= reversals
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
