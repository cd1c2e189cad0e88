"""The sampled closed loop (gearctl/closedloop.py) with the catalog controllers (issue 6).

Benchmark: ``shing1993_servo`` (the report's pair with a motor and a load), the 0.1 rad / 1 Hz sine,
1 ms sample time, on the improved plant (TR 93-28 section 2) and on Yang–Sun's (section 4). Oracles:

1. physics: with motor-side feedback the load trails the motor by half the lost motion ``b / r_b2``
   whichever way it is driven, so the PID's RMS error is about ``b / r_b2``; the dead-zone inverse
   aims the motor half the lost motion ahead and removes most of it; the backlash-free plant is the
   bound; a wrong estimate leaves ``|b_est - b| / r_b2``;
2. invariants: determinism for a seed, quantised encoder readings, the inverse with a zero estimate is
   the PID itself;
3. failures and bad input: honest results (saturation, divergence with a partial result, fallbacks),
   ``InputError`` naming the key, CLI exit code 2 with one line on stderr.

Every run here takes ~0.1 s with the compiled kernel.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from gearctl import GearModel, InputError, Plant, SimulationError, build_plant, load_model
from gearctl.catalog import load_controller
from gearctl.cli import main
from gearctl.closedloop import ClosedLoopResult, Encoder, simulate_closed_loop
from gearctl.design.base import Controller, loop_info
from gearctl.design.deadzone import DeadzoneInverse
from gearctl.design.pid import PID, PIDGains
from gearctl.metrics import tracking_metrics
from gearctl.params import Sensors
from gearctl.references import Reference, reference

DURATION = 3.0  # s: three periods of the sine; the statistics start at 0.5 s (reference("sine").settle)
PLANTS = ("improved", "yang-sun")


@pytest.fixture(scope="module")
def servo() -> GearModel:
    return load_model("shing1993_servo")


@pytest.fixture(scope="module")
def nominal(servo: GearModel) -> Plant:
    """The improved plant every controller is designed on."""
    return build_plant(servo)


@pytest.fixture(scope="module")
def sine() -> Reference:
    return reference("sine")


def run(plant: Plant, ctrl: Controller, ref: Reference, model: GearModel, **kw: object) -> ClosedLoopResult:
    return simulate_closed_loop(plant, ctrl, ref, DURATION, sensors=model.sensors, **kw)  # type: ignore[arg-type]


def rms(res: ClosedLoopResult) -> float:
    return tracking_metrics(res)["rms_error"]


@pytest.fixture(scope="module")
def baseline(servo: GearModel, nominal: Plant, sine: Reference) -> dict[str, dict[str, float]]:
    """RMS load-angle error of the catalog PID and dead-zone inverse on each plant."""
    out: dict[str, dict[str, float]] = {}
    for kind in PLANTS:
        plant = build_plant(servo, kind)
        out[kind] = {c: rms(run(plant, load_controller(c, nominal), sine, servo)) for c in ("pid", "deadzone_inverse")}
    return out


# --- 1. what the inverse buys -----------------------------------------------------------------------------


def test_pid_error_is_half_the_lost_motion(baseline: dict[str, dict[str, float]], nominal: Plant) -> None:
    # motor-side PID: the motor follows the reference, the load trails it by b / r_b2 on whichever flank
    # carries it (6.65e-4 rad), less near the flank changes: we see 0.95 b / r_b2; 0.8-1.1
    half = nominal.backlash / nominal.rb2
    assert 0.8 * half < baseline["improved"]["pid"] < 1.1 * half


@pytest.mark.parametrize(("kind", "bound"), [("improved", 3.0), ("yang-sun", 3.0)])
def test_deadzone_inverse_cuts_rms_error(baseline: dict[str, dict[str, float]], kind: str, bound: float) -> None:
    ratio = baseline[kind]["pid"] / baseline[kind]["deadzone_inverse"]
    print(f"{kind}: PID {baseline[kind]['pid']:.3g} rad, inverse {baseline[kind]['deadzone_inverse']:.3g} rad, "
          f"ratio {ratio:.2f}")
    # improved: PID 6.3e-4, inverse 1.43e-4 rad -> 4.4x (issue 6 asks for >= 3 on both plants).
    # Yang-Sun: PID 5.6e-4, inverse 1.85e-4 rad -> 3.04x: the margin is thin. The controllers are
    # designed on the improved plant; Yang-Sun's stiffer Hertz mesh with its impact-speed damping rattles
    # more at each flank change (~320 impacts against ~180 in 3 s), which the inverse cannot remove.
    # The runs are deterministic (no noise, fixed seed), so the bound cannot flake.
    assert ratio >= bound


# --- 2. the backlash-free bound ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def free_runs(servo: GearModel, sine: Reference) -> dict[str, ClosedLoopResult]:
    """``--backlash 0`` semantics: the plant and the controller's nominal plant without backlash."""
    free = build_plant(servo, backlash=0.0)
    assert free.backlash == 0.0
    return {c: run(free, load_controller(c, free), sine, servo) for c in ("pid", "deadzone_inverse")}


@pytest.mark.parametrize("ctrl", ["pid", "deadzone_inverse"])
def test_backlash_free_plant_is_the_better_bound(free_runs: dict[str, ClosedLoopResult],
                                                 baseline: dict[str, dict[str, float]], ctrl: str) -> None:
    e_free = rms(free_runs[ctrl])
    # no gap: no impacts, and the error is the PID's own tracking error (we see 8.6e-5 rad)
    assert not free_runs[ctrl].impacts
    for kind in PLANTS:
        assert e_free < baseline[kind][ctrl], kind


def test_zero_backlash_inverse_is_the_pid(free_runs: dict[str, ClosedLoopResult]) -> None:
    # with b = 0 the inverse's offset is zero and it runs the same PID: bit-identical runs
    a, b = free_runs["pid"], free_runs["deadzone_inverse"]
    assert_array_equal(a.x, b.x)
    assert_array_equal(a.torque, b.torque)


# --- 3. a wrong backlash estimate -------------------------------------------------------------------------


def test_wrong_backlash_estimate_degrades_gracefully(servo: GearModel, nominal: Plant, sine: Reference,
                                                     baseline: dict[str, dict[str, float]]) -> None:
    b = nominal.backlash
    factors = (0.5, 0.75, 1.0, 1.25, 1.5)
    err = {}
    for f in factors:
        ctrl = load_controller("deadzone_inverse", nominal, backlash=b * f)
        assert ctrl.describe()["backlash_estimate"] == pytest.approx(b * f, rel=1e-15)
        res = run(nominal, ctrl, sine, servo)  # SimulationError here would fail the test: stays stable
        assert res.success
        err[f] = rms(res)
    pid = baseline["improved"]["pid"]
    print({f: f"{e / pid:.2f} x PID" for f, e in err.items()})
    # the error grows with |estimate error| on either side of the true backlash (we see 0.48, 0.25,
    # 0.23, 0.45, 0.71 x PID)
    assert err[0.5] > err[0.75] > err[1.0] < err[1.25] < err[1.5]
    # a half-wrong estimate leaves ~0.5 b / r_b2 = half the PID's error: the underestimate 0.48 x PID
    # (< 0.6); the overestimate 0.71 x PID (< 0.8): the target then jumps 3 b / r_b2 at each flank
    # change instead of 2 b / r_b2, and the PID's overshoot on that larger jump adds to the constant
    # offset. Both stay well below the uncompensated PID.
    assert err[0.5] < 0.6 * pid
    assert err[1.5] < 0.8 * pid


# --- 4. the flank rule ------------------------------------------------------------------------------------

VELOCITY_FILE = """kind = "deadzone_inverse"
sample_time = 1e-3
feedback = "motor"
rule = "velocity"

[design]
bandwidth_hz = 20.0
phase_margin_deg = 50.0
integral_ratio = 0.1

[source]
notes = "test: the textbook velocity rule"
"""


@pytest.mark.parametrize("kind", PLANTS)
def test_velocity_rule_is_worse_than_torque_rule(servo: GearModel, nominal: Plant, sine: Reference,
                                                 baseline: dict[str, dict[str, float]], kind: str,
                                                 tmp_path: Path) -> None:
    plant = build_plant(servo, kind)
    path = tmp_path / "dz_velocity.toml"
    path.write_text(VELOCITY_FILE)
    from_file = load_controller(path, nominal)
    assert isinstance(from_file, DeadzoneInverse) and from_file.rule == "velocity"
    e_vel = rms(run(plant, from_file, sine, servo))
    # the same controller built directly
    pid = load_controller("deadzone_inverse", nominal).pid
    direct = DeadzoneInverse(pid, backlash=nominal.backlash, rule="velocity")
    assert rms(run(plant, direct, sine, servo)) == e_vel
    # issue 6: "inverse switched on velocity 8.6e-4 rad (worse than none)". On the inertial load the
    # decelerating half of each cycle is carried by the back flank while the velocity still points
    # forward, so the velocity rule offsets the motor the wrong way half the time: worse than the torque
    # rule and worse than no inverse (we see 7.8e-4 against PID 6.3e-4 on improved, 7.4e-4 against
    # 5.6e-4 on Yang-Sun)
    assert e_vel > 2.0 * baseline[kind]["deadzone_inverse"]
    assert e_vel > baseline[kind]["pid"]


# --- 5. the sampled loop against independent computations ------------------------------------------------


def test_backlash_free_loop_matches_discretised_contact_model(sine: Reference) -> None:
    # with b = 0 both flanks obey the same linear law, so the plant *is* the contact-mode model; a
    # controller at Ts with zero-order hold is then exactly the loop x+ = Ad x + Bd u with python-control's
    # ZOH discretisation (c2d), driven here by the same controller object, ideal sensors
    import control as ct

    from gearctl.modes import contact_mode_model

    plant = build_plant(load_model("shing1993_servo"), backlash=0.0)
    ctrl = load_controller("deadzone_inverse", plant)
    res = simulate_closed_loop(plant, ctrl, sine, 1.0, sensors=Sensors())
    d = ct.c2d(contact_mode_model(plant), ctrl.Ts, "zoh")
    ctrl.reset()
    x = np.zeros(4)
    xs, us = [x], []
    for t in res.t[:-1]:
        u = min(max(ctrl.step(float(t), x[0], None, sine), -plant.torque_limit), plant.torque_limit)
        x = d.A @ x + d.B @ np.array([u, 0.0])
        xs.append(x)
        us.append(u)
    X = np.array(xs).T
    # both exact (matrix exponentials); 1e-9 of each state's range (we see 2e-12)
    for i in range(4):
        assert_allclose(res.x[i], X[i], rtol=0, atol=1e-9 * np.max(np.abs(X[i])))
    assert_allclose(res.torque[:-1], us, rtol=0, atol=1e-9)


def test_compiled_and_python_kernels_agree_in_the_loop(servo: GearModel, nominal: Plant, sine: Reference) -> None:
    from gearctl.kernel import compiled_available

    if not compiled_available():
        pytest.skip("compiled kernel not available")
    ctrl = load_controller("deadzone_inverse", nominal)
    a = simulate_closed_loop(nominal, ctrl, sine, 1.0, sensors=servo.sensors, compiled=True)
    b = simulate_closed_loop(nominal, ctrl, sine, 1.0, sensors=servo.sensors, compiled=False)  # ~2 s
    # the same events (136 impacts and separations), the same encoder counts, hence the same torques;
    # states to 1e-6 of their range (both locate events to ~1e-12 s; we see 1e-9)
    assert [(e.kind, e.side) for e in a.events] == [(e.kind, e.side) for e in b.events]
    assert_array_equal(a.torque, b.torque)
    for i in range(4):
        assert_allclose(a.x[i], b.x[i], rtol=0, atol=1e-6 * np.max(np.abs(a.x[i])))


# --- 6. determinism and sensors ---------------------------------------------------------------------------


def test_same_seed_identical_results(servo: GearModel, nominal: Plant, sine: Reference) -> None:
    noisy = Sensors(motor_encoder_cpr=2**20, load_encoder_cpr=2**20, motor_noise=2e-5, load_noise=2e-5)
    ctrl = load_controller("deadzone_inverse", nominal)
    a = simulate_closed_loop(nominal, ctrl, sine, 1.0, sensors=noisy, seed=7)
    b = simulate_closed_loop(nominal, ctrl, sine, 1.0, sensors=noisy, seed=7)  # the controller is reset
    for f in ("x", "torque", "command", "y_motor", "mode"):
        assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
    assert [(e.t, e.kind) for e in a.events] == [(e.t, e.kind) for e in b.events]
    # noise enters only through the seed: another seed changes the readings and the run
    c = simulate_closed_loop(nominal, ctrl, sine, 1.0, sensors=noisy, seed=8)
    assert not np.array_equal(a.y_motor, c.y_motor) and not np.array_equal(a.x, c.x)
    # without noise the seed has nothing to act on: bit-identical runs for different seeds
    quiet = Sensors(motor_encoder_cpr=2**20)
    d = simulate_closed_loop(nominal, ctrl, sine, 1.0, sensors=quiet, seed=1)
    e = simulate_closed_loop(nominal, ctrl, sine, 1.0, sensors=quiet, seed=2)
    assert_array_equal(d.x, e.x)


def test_encoder_readings_are_quantised(servo: GearModel, nominal: Plant, sine: Reference) -> None:
    cpr = 4096  # coarse, so the quantum (1.5e-3 rad) is large against rounding
    sensors = Sensors(motor_encoder_cpr=cpr, load_encoder_cpr=cpr)
    ctrl = load_controller("pid", nominal)
    res = simulate_closed_loop(nominal, ctrl, sine, 1.0, sensors=sensors)
    q = 2 * math.pi / cpr
    counts = res.y_motor / q
    # a multiple of 2 pi / cpr (1e-9 count: the division's rounding) and the nearest one to the truth
    assert_allclose(counts, np.round(counts), rtol=0, atol=1e-9)
    assert np.all(np.abs(res.y_motor - res.x[0]) <= q / 2 * (1 + 1e-12))
    assert len(np.unique(np.round(counts))) > 10
    # the motor-side PID does not use the load encoder: NaN there
    assert np.all(np.isnan(res.y_load))


def test_encoder_unit() -> None:
    rng = np.random.default_rng(0)
    enc = Encoder(cpr=8)  # quantum pi / 4
    # nearest count: 0.5 rad is 0.64 counts -> 1, 0.3 rad is 0.38 counts -> 0, 2.0 rad 2.55 -> 3
    assert enc.read(0.5, rng) == pytest.approx(math.pi / 4, rel=1e-15)
    assert enc.read(-0.5, rng) == pytest.approx(-math.pi / 4, rel=1e-15)
    assert enc.read(0.3, rng) == 0.0
    assert enc.read(2.0, rng) == pytest.approx(3 * math.pi / 4, rel=1e-15)
    assert Encoder(cpr=None).read(0.123, rng) == 0.123  # ideal encoder: the true angle
    noisy = Encoder(cpr=None, noise=1e-3)
    r = np.array([noisy.read(0.0, np.random.default_rng(5)) for _ in range(3)])
    assert r[0] == r[1] == r[2] != 0.0  # the noise is the generator's, reproducible per seed


# --- 7. failures ------------------------------------------------------------------------------------------

WILD_PID = """kind = "pid"
sample_time = 1e-3
[gains]
kp = 1e6
[source]
notes = "test: absurd gain"
"""


def test_absurd_gain_runs_saturated_with_a_torque_limit(servo: GearModel, nominal: Plant, sine: Reference,
                                                        baseline: dict[str, dict[str, float]],
                                                        tmp_path: Path) -> None:
    path = tmp_path / "wild.toml"
    path.write_text(WILD_PID)
    ctrl = load_controller(path, nominal)
    # the honest behaviour with the servo's 1 N m limit: the command is clipped, the loop chatters
    # bang-bang at the limit but the plant cannot diverge (bounded torque, friction): the run succeeds,
    # saturated nearly all the time, with an error far above the designed PID's
    res = run(nominal, ctrl, sine, servo)
    m = tracking_metrics(res)
    assert res.success
    assert m["saturated_fraction"] > 0.9  # we see 0.999
    assert np.all(np.abs(res.torque) <= nominal.torque_limit)
    # the PID clips its own output to the limit it was designed with (and its anti-windup acts), so the
    # recorded command is already the applied torque
    assert_array_equal(res.command, res.torque)
    assert m["rms_error"] > 3 * baseline["improved"]["pid"]  # we see 5e-3 rad, 8x


def test_absurd_gain_without_limit_raises_with_partial_result(servo: GearModel, nominal: Plant,
                                                             sine: Reference, tmp_path: Path) -> None:
    path = tmp_path / "wild.toml"
    path.write_text(WILD_PID)
    unlimited = dataclasses.replace(nominal, torque_limit=math.inf)
    ctrl = load_controller(path, unlimited)
    with pytest.raises(SimulationError, match="diverged") as info:
        run(unlimited, ctrl, sine, servo)
    part = info.value.result
    assert isinstance(part, ClosedLoopResult)
    assert not part.success and "diverged" in part.message
    n = part.t.size
    assert 1 < n < DURATION / ctrl.Ts  # stopped early (we see after 4 samples)
    for f in ("reference", "torque", "command", "y_motor", "mode"):
        assert getattr(part, f).shape == (n,), f
    assert part.x.shape == (4, n)
    assert np.max(np.abs(part.x[2:, -1])) > 1e6  # the divergence it reports is in the record


class _NanController(Controller):
    """Returns NaN between 0.1 and 0.2 s (a failed solve), zero torque otherwise."""

    name = "nan"
    Ts = 1e-3

    def reset(self) -> None:
        self.solve_times, self.fallbacks = [], []

    def step(self, t: float, y_motor: float, y_load: float | None, ref: Reference) -> float:
        return math.nan if 0.1 <= t < 0.2 else 0.01


def test_non_finite_command_falls_back_to_zero_torque(nominal: Plant, sine: Reference) -> None:
    ctrl = _NanController()
    res = simulate_closed_loop(nominal, ctrl, sine, 0.3)
    bad = (res.t >= 0.1 - 1e-12) & (res.t < 0.2 - 1e-12)
    assert res.success
    # the applied torque is the safe zero; `command` keeps what the controller asked for (NaN), and the
    # fallback list says what happened
    assert np.all(res.torque[bad] == 0.0) and np.all(np.isnan(res.command[bad]))
    assert np.all(res.torque[~bad] == 0.01)
    assert len(res.fallbacks) == np.count_nonzero(bad) == 100
    assert all("non-finite" in f["reason"] for f in res.fallbacks)
    assert_allclose([f["t"] for f in res.fallbacks], res.t[bad], rtol=0, atol=1e-12)
    assert tracking_metrics(res)["fallbacks"] == 100
    # a second run starts clean (the controller is reset): the count does not accumulate
    assert len(simulate_closed_loop(nominal, ctrl, sine, 0.3).fallbacks) == 100


# --- 8. bad input -----------------------------------------------------------------------------------------

BASE = """kind = "{kind}"
sample_time = {Ts}
{extra}
[design]
bandwidth_hz = {bw}
[source]
notes = "test"
"""


def _write(tmp_path: Path, kind: str = "pid", Ts: str = "1e-3", extra: str = "", bw: str = "20.0") -> Path:
    path = tmp_path / "ctrl.toml"
    path.write_text(BASE.format(kind=kind, Ts=Ts, extra=extra, bw=bw))
    return path


def test_controller_file_valid_template(tmp_path: Path, nominal: Plant) -> None:
    assert isinstance(load_controller(_write(tmp_path), nominal), PID)  # the template itself is fine


def test_controller_file_unknown_key_suggests(tmp_path: Path, nominal: Plant) -> None:
    with pytest.raises(InputError, match="sample_tme.*did you mean 'sample_time'") as info:
        load_controller(_write(tmp_path, extra="sample_tme = 1e-3"), nominal)
    assert info.value.field == "sample_tme"
    path = tmp_path / "d.toml"
    path.write_text(BASE.format(kind="pid", Ts="1e-3", extra="", bw="20.0").replace("bandwidth_hz", "bandwith_hz"))
    with pytest.raises(InputError, match="bandwith_hz.*did you mean 'bandwidth_hz'"):
        load_controller(path, nominal)


def test_controller_file_unknown_kind(tmp_path: Path, nominal: Plant) -> None:
    with pytest.raises(InputError, match="kind = 'pdi'.*did you mean 'pid'") as info:
        load_controller(_write(tmp_path, kind="pdi"), nominal)
    assert info.value.field == "kind"


@pytest.mark.parametrize("kind", ["[1, 2]", "{x = 1}"])
def test_controller_file_kind_not_a_string(tmp_path: Path, nominal: Plant, kind: str) -> None:
    # an array or inline table ended in "TypeError: unhashable type", a traceback at the CLI
    path = tmp_path / "ctrl.toml"
    path.write_text(BASE.format(kind="pid", Ts="1e-3", extra="", bw="20.0").replace('"pid"', kind))
    with pytest.raises(InputError, match="is not a controller kind: expected one of pid") as info:
        load_controller(path, nominal)
    assert info.value.field == "kind"
    assert main(["track", "shing1993_servo", str(path)]) == 2


@pytest.mark.parametrize("Ts", ["0.0", "-1e-3", "2.0"])
def test_controller_file_sample_time_out_of_range(tmp_path: Path, nominal: Plant, Ts: str) -> None:
    with pytest.raises(InputError, match="sample_time") as info:
        load_controller(_write(tmp_path, Ts=Ts), nominal)
    assert info.value.field == "sample_time"


@pytest.mark.parametrize("kind", ["pid", "deadzone_inverse"])
def test_controller_file_bandwidth_above_nyquist(tmp_path: Path, nominal: Plant, kind: str) -> None:
    # Ts = 1 ms: the Nyquist frequency is 500 Hz
    with pytest.raises(InputError, match="bandwidth_hz.*500") as info:
        load_controller(_write(tmp_path, kind=kind, bw="600.0"), nominal)
    assert info.value.field == "bandwidth_hz"


def test_controller_file_bad_rule_and_width(tmp_path: Path, nominal: Plant) -> None:
    with pytest.raises(InputError, match="rule") as info:
        load_controller(_write(tmp_path, kind="deadzone_inverse", extra='rule = "position"'), nominal)
    assert info.value.field == "rule"
    with pytest.raises(InputError, match="width") as info:
        load_controller(_write(tmp_path, kind="deadzone_inverse", extra="width = 0.0"), nominal)
    assert info.value.field == "width"
    with pytest.raises(InputError, match="backlash") as info:
        load_controller(_write(tmp_path, kind="deadzone_inverse", extra="backlash = 0.5"), nominal)
    assert info.value.field == "backlash"


def test_pid_gains_and_duration_validation(nominal: Plant, sine: Reference) -> None:
    with pytest.raises(InputError, match="kp"):
        PIDGains(kp=-1.0)
    pid = PID(loop_info(nominal), PIDGains(kp=10.0))
    with pytest.raises(InputError, match="duration"):
        simulate_closed_loop(nominal, pid, sine, 0.0)
    with pytest.raises(InputError, match="duration"):
        simulate_closed_loop(nominal, pid, sine, 1e-4)  # shorter than one sample


# --- 9. the CLI -------------------------------------------------------------------------------------------


def test_cli_track_unknown_controller(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["track", "shing1993_servo", "no_such_controller"]) == 2
    cap = capsys.readouterr()
    assert cap.err.count("\n") == 1 and cap.err.startswith("gearctl track: error:")
    assert "no_such_controller" in cap.err and "Traceback" not in cap.err
    assert cap.out == ""


def test_cli_track_json(capsys: pytest.CaptureFixture[str], servo: GearModel, nominal: Plant,
                        sine: Reference) -> None:
    assert main(["track", "shing1993_servo", "pid", "--duration", "1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("rms_error", "max_error", "final_error", "impacts", "max_impact_velocity", "fallbacks",
                "solve_time"):
        assert key in out, key
    assert out["solve_time"] is None  # the PID solves no optimisation
    assert out["fallbacks"] == 0
    # the same run through the API: identical figures (deterministic, seed 0)
    res = simulate_closed_loop(nominal, load_controller("pid", nominal), sine, 1.0, sensors=servo.sensors)
    m = tracking_metrics(res)
    for key in ("rms_error", "max_error", "final_error", "impacts"):
        assert out[key] == m[key], key


def test_cli_track_backlash_zero(capsys: pytest.CaptureFixture[str],
                                 free_runs: dict[str, ClosedLoopResult]) -> None:
    assert main(["track", "shing1993_servo", "deadzone_inverse", "--backlash", "0", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["backlash"] == 0.0 and out["impacts"] == 0
    assert out["rms_error"] == rms(free_runs["deadzone_inverse"])  # --backlash 0 = build_plant(backlash=0)


# --- the PID design keeps the motor alone stable in the gap ---------------------------------------------------------

def _light_motor_servo(tmp_path: Path) -> Path:
    """shing1993_servo with a motor ten times lighter (2e-5 kg m^2): the rigid train is 17x the motor shaft."""
    path = Path(__file__).parent / "data" / "light_motor_servo.toml"
    assert load_model(path).servo.motor_inertia == 2e-5
    assert load_model(path).pair == load_model("shing1993_servo").pair
    return path


def _free_motor_poles(info, gains: PIDGains, Ts: float) -> float:
    """Independent oracle (python-control): the largest |z| of the motor alone under the sampled PID."""
    import control as ct

    shaft = info.nominal.shafts[0]
    s = ct.tf("s")
    G = ct.c2d(ct.ss(1 / (info.N * (shaft.J * s**2 + shaft.d * s))), Ts, "zoh")
    return float(np.max(np.abs(ct.feedback(gains.sampled_tf(Ts) * G, 1).poles())))


def test_pid_design_keeps_the_motor_alone_stable_in_the_gap(tmp_path: Path) -> None:
    from gearctl.design.pid import design_pid, gap_limited_bandwidth, gap_loop_stable

    info = loop_info(build_plant(load_model(_light_motor_servo(tmp_path))))
    assert info.J_eq / info.nominal.shafts[0].J == pytest.approx(16.8, rel=0.01)
    # at the catalog's 20 Hz the motor alone is unstable (python-control's poles, not gearctl's polynomial)
    g20, _ = design_pid(info, bandwidth_hz=20.0, Ts=1e-3)
    assert _free_motor_poles(info, g20, 1e-3) > 1.0 and not gap_loop_stable(info, g20, 1e-3)
    # the search: 8.4 Hz measured; stable there with the gain 6 dB up, not both a step above
    bw = gap_limited_bandwidth(info, bandwidth_hz=20.0, Ts=1e-3, gain_margin_db=6.0)
    assert 7.0 < bw < 10.0
    g, _ = design_pid(info, bandwidth_hz=bw, Ts=1e-3)
    k = 10 ** (6 / 20)  # 6 dB
    g2 = dataclasses.replace(g, kp=k * g.kp, ki=k * g.ki, kd=k * g.kd)
    assert _free_motor_poles(info, g, 1e-3) < 1.0 and _free_motor_poles(info, g2, 1e-3) < 1.0
    g_up, _ = design_pid(info, bandwidth_hz=1.01 * bw, Ts=1e-3)
    assert not (gap_loop_stable(info, g_up, 1e-3) and gap_loop_stable(info, g_up, 1e-3, gain=k))
    # the catalog files say so and design at that bandwidth; gap_gain_margin_db = 0 keeps the file's 20 Hz
    pid = load_controller("pid", build_plant(load_model(_light_motor_servo(tmp_path))))
    assert pid.gains == g and len(pid.design_notes) == 1
    assert "bandwidth_hz = 20 lowered to 8.4 Hz" in pid.design_notes[0]
    assert pid.describe()["design_notes"] == list(pid.design_notes)
    light = build_plant(load_model(_light_motor_servo(tmp_path)))
    for kind in ("deadzone_inverse", "reversal_offset", "adaptive_inverse"):  # the wrappers carry their PID's note
        ctrl = load_controller(kind, light)
        # (the reversal offset adds its own on this frictionless load: see test_compensation)
        own = ctrl.design_notes[len(pid.design_notes):]
        assert ctrl.design_notes[:len(pid.design_notes)] == pid.design_notes
        assert all(n.startswith("coulomb_friction2:") for n in own) and len(own) == (kind == "reversal_offset")
        assert ctrl.describe()["design_notes"] == list(ctrl.design_notes)
    mpc = load_controller("mpc", light)
    # no PID bandwidth note (its plan is rigid here, 1.8 samples to cross: that one note, test_mpc_rigid_note.py)
    assert [n for n in mpc.design_notes if not n.startswith("gap model off:")] == []
    assert mpc.describe()["design_notes"] == list(mpc.design_notes)
    # the benchmark servo (motor shaft 0.26 of the train) keeps its design to the last bit, and says nothing
    bench = load_controller("pid", build_plant(load_model("shing1993_servo")))
    info_b = loop_info(build_plant(load_model("shing1993_servo")))
    assert bench.gains == design_pid(info_b, bandwidth_hz=20.0, Ts=1e-3)[0] and bench.design_notes == ()
    assert gap_limited_bandwidth(info_b, bandwidth_hz=20.0) == 20.0


def test_light_motor_loop_does_not_rattle_and_the_inverse_beats_the_pid(tmp_path: Path) -> None:
    from gearctl.catalog import resolve
    from gearctl.runs import execute, make_run

    model = _light_motor_servo(tmp_path)
    off = tmp_path / "pid_20hz.toml"
    off.write_text(resolve("pid", "controllers").read_text().replace(
        "bandwidth_hz = 20.0", "bandwidth_hz = 20.0\ngap_gain_margin_db = 0.0"))
    m = {}
    for name, ctrl, ref in (("pid", "pid", "sine"), ("pid_20hz", off, "sine"), ("inverse", "deadzone_inverse", "sine"),
                            ("pid_move", "pid", "move"), ("inverse_move", "deadzone_inverse", "move")):
        res = execute(make_run(model, ctrl, reference_kind=ref))
        assert res.ok
        m[name] = res.metrics
    # at 20 Hz the motor hammers the flanks every sample (measured 2968 impacts in 3 s): a limit cycle at the
    # Nyquist frequency, whose dither happens to centre the load (RMS 2.9e-5 rad)
    assert m["pid_20hz"].health.limit_cycle and m["pid_20hz"].impacts > 2000
    # the lowered design rests on a flank (measured 176 impacts in 3 s, no limit cycle; RMS 6.8e-4 rad, half the
    # lost motion), and the inverse compensates it: measured 3.9x on the sine, 88x on the move
    assert not m["pid"].health.limit_cycle and m["pid"].impacts < 400
    assert not m["inverse"].health.limit_cycle
    assert m["pid"].rms_error / m["inverse"].rms_error > 2.0
    assert m["pid_move"].rms_error / m["inverse_move"].rms_error > 20.0


def test_cli_prints_the_design_note(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    model = _light_motor_servo(tmp_path)
    assert main(["track", str(model), "pid", "--duration", "0.2", "--json"]) == 0
    out = capsys.readouterr()
    notes = [line for line in out.err.splitlines() if line.startswith("gearctl track: note: ")]
    assert len(notes) == 1 and "lowered to 8.4 Hz" in notes[0] and "gap_gain_margin_db = 0" in notes[0]
    assert json.loads(out.out)["controller"]["design_notes"] == [notes[0].removeprefix("gearctl track: note: pid: ")]
    bad = tmp_path / "bad.toml"
    bad.write_text('kind = "pid"\n[design]\ngap_gain_margin_db = 50\n[source]\nnotes = "x"\n')
    assert main(["track", str(model), str(bad), "--duration", "0.2"]) == 2
    err = capsys.readouterr().err
    assert "gap_gain_margin_db = 50 is out of range: expected 0 <= value <= 40 [dB]" in err


def test_gap_check_judges_slow_loops_exactly_and_refuses_a_motor_too_light(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    from gearctl.design.pid import design_pid, gap_limited_bandwidth, gap_loop_stable

    # a slow design at a fast sample rate: its eigenvalues crowd near z = 1, where the characteristic polynomial's
    # roots judged this stable loop unstable (and cut 0.3 Hz to 0.003 Hz); the benchmark servo's motor alone holds it
    info = loop_info(build_plant(load_model("shing1993_servo")))
    for bw, Ts in ((0.3, 1e-4), (0.1, 1e-4), (0.03, 1e-3), (0.01, 1e-3)):
        g, _ = design_pid(info, bandwidth_hz=bw, Ts=Ts)
        assert gap_loop_stable(info, g, Ts) and gap_loop_stable(info, g, Ts, gain=2.0)
        assert gap_limited_bandwidth(info, bandwidth_hz=bw, Ts=Ts) == bw
    # a motor 1/79 000 of its train: not even a hundredth of the bandwidth holds it in the gap; refused by name
    text = (Path(__file__).parent / "data" / "light_motor_servo.toml").read_text()
    assert "load_inertia = 5e-3 " in text
    heavy = tmp_path / "heavy_load.toml"
    heavy.write_text(text.replace("load_inertia = 5e-3 ", "load_inertia = 50.0 "))
    assert main(["track", str(heavy), "pid", "--duration", "0.2"]) == 2
    err = capsys.readouterr().err
    assert "no crossover down to 0.2 Hz leaves the motor shaft alone" in err and "gap_gain_margin_db" in err
    assert "Traceback" not in err and "viscous time constant" not in err
    # a motor heavier than the rest of the train, but a load whose viscous friction (7.2e-3 N m s/rad on 1.5e-7
    # kg m^2, through a speed-up) makes the rigid train's time constant 0.15 ms: the gains follow that damping,
    # which the motor alone lacks. The refusal says so (a fuzzed model: "a heavier motor" alone misled)
    damped = tmp_path / "damped.toml"
    damped.write_text("""
[source]
citation = "drawn by tests/test_fuzz.py (issue 11)"
[gear1]
teeth = 46
[gear2]
teeth = 20
[pair]
module = 0.0005544147528434302
pressure_angle_deg = 25.0
face_width = 0.1
backlash = 1.4945636241603612e-06
addendum_coefficient = 1.1290772685150599
dedendum_coefficient = 1.2735665642327385
[material]
young_modulus = 74684264832.4174
poisson_ratio = 0.2691416958517084
density = 1005.3581843444107
[dynamics]
damping_ratio = 0.023671561777889278
mesh_stiffness = 10163928.72365215
[servo]
load_inertia = 1.4920377374531587e-07
viscous_friction2 = 0.007180091056286156
coulomb_friction2 = 0.31087076004164665
torque_limit = 2.051907625495541
""")
    assert main(["track", str(damped), "pid", "--duration", "0.2"]) == 2
    err = capsys.readouterr().err
    assert "1/1.38 of the rigid train" in err and "viscous time constant J_eq / d_eq = 0.151 ms" in err, err


def test_rattle_guard_never_softens_the_loop_against_an_error_beyond_the_gap() -> None:
    """A reviewer's CNC table (tests/data/cnc_table_tight.toml): 5 um of backlash, a 3 kg m^2 load with 5 N m of
    friction. The sine starts at full speed, the start-up saturates the motor, and the mesh's ringing passes the
    rattle guard's threshold (b / (2 r_b1 Ts), 0.08 rad/s for so small a gap): the guard cut the feedback to 2 % while
    the load was mrad behind, and the loop swung for a second (RMS 2.87e-4 rad against the PID's 2.5e-5). The guard
    now softens the loop only while the error is within twice the lost motion: measured 7.1e-6 rad, 3.5x below the
    PID; the catalog servos are unchanged to the bit (their guard never met such an error)."""
    from gearctl.runs import execute, make_run

    model = Path(__file__).parent / "data" / "cnc_table_tight.toml"
    pid = execute(make_run(model, "pid")).metrics
    inv = execute(make_run(model, "deadzone_inverse")).metrics
    assert pid.rms_error == pytest.approx(2.5e-5, rel=0.1)
    assert inv.rms_error < 1.5e-5 and pid.rms_error / inv.rms_error > 2.0
    assert inv.max_error < 1e-4  # the start-up's mrad swing (1.7e-3 rad) is gone from the window after 0.5 s


def test_rattle_guard_does_not_read_a_held_load_step_as_impacts() -> None:
    """tests/data/light_train_load_step.toml: a 2e-5 kg m^2 train on the catalog step, whose 0.5 N m load step the
    model does not give. Held at rest, the motor's 0.28 N m explains a 14 rad/s speed change per sample that the
    train does not make; the rattle guard took that for impacts, stayed on, and its softened loop dropped the load
    every few tens of ms: a 0.1 rad limit cycle (final error -0.094 rad, the PID's 1.0e-3; only a 'runaway'
    warning). The guard now explains the speed change by the torque less what holds the load (the observer's
    disturbance): measured final error 2.0e-5 rad and 5.3e-3 rad at most after 1.5 s, the PID's 1.0e-3 and 6.2e-3."""
    from gearctl.runs import execute, make_run

    model = Path(__file__).parent / "data" / "light_train_load_step.toml"
    pid = execute(make_run(model, "pid", reference_kind="step"))
    inv = execute(make_run(model, "deadzone_inverse", reference_kind="step"))
    late = inv.trace_t > 1.5
    assert not inv.metrics.health.warnings
    assert np.abs(inv.trace_error[late]).max() < np.abs(pid.trace_error[pid.trace_t > 1.5]).max()
    assert abs(inv.metrics.final_error) < 0.1 * abs(pid.metrics.final_error)
    assert pid.metrics.final_error == pytest.approx(1.05e-3, rel=0.05)
