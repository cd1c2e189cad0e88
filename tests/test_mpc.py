"""The backlash-aware MPC (gearctl.design.mpc): model oracles, closed-loop acceptance, fallbacks, bad input.

Oracles
-------
- The gap model against the exact event-located simulator (report eqs 1-12): in separation it is the
  same linear system (exact to rounding); in contact it is the rigid limit of the mesh, off by the
  mesh deflection only.
- The observer against the true state, open loop, with the benchmark's 2^20-count encoders.
- Invariants: front/back mirror symmetry of the closed loop; the compiled and the CasADi-called QP give
  the same torques.
- Closed-loop acceptance on ``shing1993_servo`` (1 Hz, 0.1 rad sine, errors after 0.5 s) against the
  dead-zone inverse (``controllers/deadzone_inverse.toml``) on the improved and on the Yang-Sun plant.
  Each comparison states the ratio measured when the test was written and the margin it keeps.
- The backlash-free limit (``backlash = 0``): only the rigid-train QP, no landing pattern, and the
  backlash-free plant is the better bound: the MPC tracks it more closely than the backlash plant,
  with no impact (also through ``gearctl track --backlash 0``).

The comparisons pin ``max_solve_time = 1 s``: a solve-time overrun (they happen when the machine is
busy) makes the loop fall back for one sample, which changes the trajectory, so with the default the
figures would depend on the machine's load. Overruns and failures are tested on their own below; the
default settings' solve times are recorded and checked in ``test_default_solve_times_are_recorded``.
"""

from __future__ import annotations

import ctypes
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

import gearctl.design.mpc as mpc_module
import gearctl.design.mpc_solvers as mpc_solvers
from gearctl import InputError, build_plant, load_model
from gearctl.catalog import load_controller, read_toml, resolve
from gearctl.cli import main
from gearctl.closedloop import ClosedLoopResult, simulate_closed_loop
from gearctl.design.base import loop_info
from gearctl.design.mpc import MPC, SOLVERS, MPCSettings, build_mpc
from gearctl.design.registry import build_controller
from gearctl.kernel import Kernel
from gearctl.metrics import tracking_metrics
from gearctl.references import reference

DURATION = 3.0  # s: six flank changes of the 1 Hz sine


# --- fixtures ----------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def servo():
    """The benchmark model (shing1993_servo) and its improved plant."""
    model = load_model("shing1993_servo")
    return model, build_plant(model)


@pytest.fixture(scope="module")
def mpc_spec() -> dict:
    """The catalog's controllers/mpc.toml, parsed."""
    return read_toml(resolve("mpc", "controllers"))


def _mpc(plant, spec: dict, **overrides) -> MPC:
    """The catalog MPC on ``plant`` with top-level keys replaced (e.g. ``max_solve_time``)."""
    return build_controller({**spec, **overrides}, plant, path=Path("mpc.toml"))


def _rms_after_settle(res: ClosedLoopResult) -> float:
    e = res.error[res.t >= res.settle]
    return float(np.sqrt(np.mean(e**2)))


def _impact_speeds(res: ClosedLoopResult) -> np.ndarray:
    return np.array([abs(e.velocity) for e in res.impacts] or [0.0])


@pytest.fixture(scope="module")
def sine_runs(servo, mpc_spec) -> dict[str, dict[str, ClosedLoopResult]]:
    """MPC and dead-zone inverse on the sine, improved and Yang-Sun plant (controllers designed on the
    improved plant, as ``gearctl track`` does)."""
    model, nominal = servo
    ref = reference("sine")
    runs: dict[str, dict[str, ClosedLoopResult]] = {}
    for kind in ("improved", "yang-sun"):
        plant = build_plant(model, kind)
        runs[kind] = {
            "mpc": simulate_closed_loop(plant, _mpc(nominal, mpc_spec, max_solve_time=1.0), ref, DURATION,
                                        sensors=model.sensors),
            "deadzone": simulate_closed_loop(plant, load_controller("deadzone_inverse", nominal), ref, DURATION,
                                             sensors=model.sensors),
        }
    return runs


# --- the gap model against the exact simulator ----------------------------------------------------------------


def test_gap_model_is_exact_in_separation(servo) -> None:
    # the flanks start centred and at equal speed along the line of action; torques small enough to stay in
    # the gap for 8 ms: the discrete separation model is the exact ZOH solution of eqs 6-7
    _, plant = servo
    ctrl = MPC(loop_info(plant))
    m = ctrl.model
    x0 = np.array([0.0, 0.0, 1.0, 1.0 / plant.gear_ratio])
    u = [0.01, -0.01, 0.005, -0.005, 0.0, 0.002, -0.002, 0.0]
    kn = Kernel(plant, x0.copy(), dt=ctrl.Ts)
    z = m.T @ x0
    for uk in u:
        kn.advance(uk, 0.0, ctrl.Ts)
        z = m.A_sep @ z + m.B_sep[:, 0] * uk
        assert kn.mode == 0  # still in the gap
        # tolerance: rounding of a few ZOH products, relative to the state's scale
        assert_allclose(z, m.T @ kn.x, rtol=1e-9, atol=1e-12 * np.abs(z).max())


def test_gap_model_in_contact_is_the_rigid_limit(servo) -> None:
    # front contact with a constant 0.05 N m for 20 ms: the rigid train accelerates the load at
    # theta2'' = u / (N J_eq), so the mesh carries F = J2 theta2'' / r_b2 (eq 2) and is compressed by
    # F / k; the model pins s at b, so its load angle is off by kappa2 F / k (measured 4.92e-8 rad against
    # 4.93e-8 rad predicted) plus the mesh ringing the torque step starts (tolerance 10 % of the offset)
    _, plant = servo
    info = loop_info(plant)
    ctrl = MPC(info)
    m = ctrl.model
    x0 = np.array([plant.backlash / plant.rb1, 0.0, 0.0, 0.0])
    kn = Kernel(plant, x0.copy(), dt=ctrl.Ts)
    z = m.T @ x0
    u = 0.05
    for _ in range(20):
        kn.advance(u, 0.0, ctrl.Ts)
        z = m.A_con @ z + m.B_con[:, 0] * u
    assert kn.mode == 1
    theta2_model = z[0] / m.N - m.kappa2 * z[2]
    force = plant.J2 * u / (info.N * info.J_eq) / plant.rb2
    assert_allclose(theta2_model - kn.x[1], m.kappa2 * force / plant.k, rtol=0.1)


def test_observer_tracks_the_true_state_open_loop(servo) -> None:
    # a torque that takes the motor across the gap and drags the load both ways; encoders of 2^20 counts
    # (6 urad): the gap is known to a few % of b, the momentum speed to 1 %, after a 20 ms start-up
    model, plant = servo
    from gearctl.closedloop import Encoder

    ctrl = MPC(loop_info(plant))
    rng = np.random.default_rng(1)
    enc = Encoder(model.sensors.motor_encoder_cpr)
    kn = Kernel(plant, np.zeros(4), dt=ctrl.Ts)
    t = np.arange(400) * ctrl.Ts
    u = 0.05 * np.sin(2 * math.pi * 5 * t) + 0.02
    worst_s, worst_w = 0.0, 0.0
    for k in range(t.size):
        x = kn.x.copy()
        ctrl._observe(enc.read(x[0], rng), enc.read(x[1], rng))
        z_true = ctrl.model.T @ x
        if k >= 20:
            worst_s = max(worst_s, abs(ctrl._z[2] - z_true[2]))
            worst_w = max(worst_w, abs(ctrl._z[1] - z_true[1]) / max(abs(z_true[1]), 1.0))
        ctrl._u = float(u[k])
        kn.advance(ctrl._u, 0.0, ctrl.Ts)
    assert worst_s < 0.05 * plant.backlash  # measured 0.011 b
    assert worst_w < 0.01  # measured 0.002


# --- closed-loop acceptance ----------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["improved", "yang-sun"])
def test_mpc_tracks_better_than_the_deadzone_inverse(sine_runs, kind: str) -> None:
    # measured: improved 2.86e-6 vs 3.74e-6 rad (ratio 0.76: the inverse's gap crossing aimed at the load closes
    # most of the distance); Yang-Sun 6.96e-5 vs 7.60e-5 (0.92). The Yang-Sun loop (about 3000 impacts in 3 s,
    # restitution) is chaotic: the last bit of the arithmetic moves it between 1.42e-5 (0.19, the QP gradient
    # summed by numpy's BLAS), 5.20e-5 (0.68, index order) and 6.96e-5 (0.92, the QP's angles taken from the
    # reference at t), so there the bound is only "not worse". On the improved plant the comparison holds from the
    # centre of the gap only: see test_mpc_sine_from_other_starts
    runs = sine_runs[kind]
    rms_mpc, rms_dz = _rms_after_settle(runs["mpc"]), _rms_after_settle(runs["deadzone"])
    assert rms_mpc <= (0.9 if kind == "improved" else 1.0) * rms_dz, (rms_mpc, rms_dz)


@pytest.mark.parametrize("kind", ["improved", "yang-sun"])
def test_mpc_impacts_are_gentler_than_the_deadzone_inverse(sine_runs, kind: str) -> None:
    # fastest impact, measured: improved 3.2e-3 vs 4.5e-2 m/s (ratio 14); Yang-Sun 5.1e-3 vs 4.5e-2 (8.8).
    # Impact energy (sum of squared impact speeds), measured: improved 5.2e-5 vs 4.5e-3 (ratio 86); Yang-Sun
    # 3.7e-4 vs 9.0e-3 (24). The count is not always lower: on the improved plant 151 vs 181, but the Yang-Sun
    # law is nearly elastic below 1 mm/s (eq 37, clamped at 1 mm/s), so the MPC's gentle landings bounce in
    # long cascades of tiny impacts there (~7000 of them, against 321 for the dead-zone inverse)
    runs = sine_runs[kind]
    v_mpc, v_dz = _impact_speeds(runs["mpc"]), _impact_speeds(runs["deadzone"])
    assert v_mpc.max() < 0.5 * v_dz.max(), (v_mpc.max(), v_dz.max())
    assert np.sum(v_mpc**2) < 0.25 * np.sum(v_dz**2)
    if kind == "improved":
        assert len(runs["mpc"].impacts) < len(runs["deadzone"].impacts)


def test_soft_landing_is_what_makes_impacts_gentle(servo, mpc_spec) -> None:
    # ablation on 1 s of the sine: without the landing bound and penalty the plan lands as hard as it likes
    # (measured fastest impact 0.13 m/s against 3.2e-3 m/s with the default "bound"): a factor 10 is kept
    model, plant = servo
    ref = reference("sine")
    fast = {}
    for mode in ("bound", "off"):
        res = simulate_closed_loop(plant, _mpc(plant, mpc_spec, max_solve_time=1.0, soft_landing=mode), ref, 1.0,
                                   sensors=model.sensors)
        fast[mode] = _impact_speeds(res).max()
    assert fast["bound"] < 0.1 * fast["off"], fast


def test_mpc_rejects_a_load_disturbance(servo, mpc_spec) -> None:
    # step reference with a 0.5 N m load-torque step against the motion at 1 s: the disturbance estimate
    # (integral action) brings the load back; measured final error 1e-6 rad, RMS 1.2e-4 rad against
    # 1.7e-3 rad for the dead-zone inverse
    model, plant = servo
    ref = reference("step")
    res = simulate_closed_loop(plant, _mpc(plant, mpc_spec, max_solve_time=1.0), ref, 2.0, sensors=model.sensors)
    assert abs(res.error[-1]) < 2e-5
    assert _rms_after_settle(res) < 5e-4


def test_front_back_mirror_symmetry(servo) -> None:
    # with ideal sensors the plant, the model and the controller are symmetric in the flanks: the mirrored
    # reference gives the mirrored torques (measured: identical to the last bit over 300 samples)
    _, plant = servo
    ref = reference("sine")
    a = simulate_closed_loop(plant, MPC(loop_info(plant), MPCSettings(max_solve_time=1.0)), ref, 0.3)
    b = simulate_closed_loop(plant, MPC(loop_info(plant), MPCSettings(max_solve_time=1.0)),
                             dataclasses.replace(ref, amplitude=-ref.amplitude), 0.3)
    assert_allclose(b.command, -a.command, rtol=0, atol=1e-12)


@pytest.mark.skipif(mpc_solvers.c_compiler() is None, reason="no C compiler: the compiled QP cannot be built")
def test_compiled_and_casadi_paths_agree(servo) -> None:
    # the same daqp conic, once generated as C and called through ctypes, once called through CasADi
    # (measured: identical torques over 300 samples)
    model, plant = servo
    ref = reference("sine")
    runs = []
    for compiled in (True, False):
        ctrl = MPC(loop_info(plant), MPCSettings(max_solve_time=1.0), compiled=compiled)
        assert ctrl.describe()["compiled"] is compiled
        runs.append(simulate_closed_loop(plant, ctrl, ref, 0.3, sensors=model.sensors))
    assert_allclose(runs[0].command, runs[1].command, rtol=0, atol=1e-10)


# --- solve times and fallbacks -------------------------------------------------------------------------------


def test_default_solve_times_are_recorded(servo) -> None:
    # default settings (the catalog file): one entry per step. Measured on the 2-core benchmark machine:
    # median 14-25 us, p99 60-120 us, max ~250 us (several QPs in the steps that decide a crossing); the
    # performance goal is p99 <= 250 us. Timing is not asserted beyond the sample period (speed is the
    # benchmark's business); a busy machine may still overrun a step, which falls back and is recorded
    model, plant = servo
    ctrl = load_controller("mpc", plant)
    res = simulate_closed_loop(plant, ctrl, reference("sine"), 1.0, sensors=model.sensors)
    n = res.t.size - 1
    assert res.solve_times.shape == (n,) and len(ctrl.step_times) == n and len(ctrl.statuses) == n
    assert np.all(res.solve_times > 0.0) and np.all(np.isfinite(res.solve_times))
    assert all(f["reason"].startswith("solve overran") for f in res.fallbacks)
    if ctrl.describe()["compiled"]:  # without a C compiler (CasADi path, ~0.2-0.5 ms per QP here) it may not
        assert np.percentile(res.solve_times, 99) < ctrl.settings.max_solve_time
        assert len(res.fallbacks) < 0.01 * n
    print(f"\nMPC solve time per step: median {np.median(res.solve_times) * 1e6:.0f} us, "
          f"p99 {np.percentile(res.solve_times, 99) * 1e6:.0f} us, max {res.solve_times.max() * 1e6:.0f} us; "
          f"step (observer, bookkeeping, solves) median {np.median(ctrl.step_times) * 1e6:.0f} us")


def test_injected_failures_fall_back_and_are_reported(servo, mpc_spec) -> None:
    # four failed solves, one during a flank change (k = 996-998, the sine's torque changes sign at 1 s):
    # each applies the previous plan's next input, saturated, is reported in the result and the loop stays
    # within the dead-zone inverse's error (measured RMS 2.7e-5 rad with and without the failures)
    model, plant = servo
    ref = reference("sine")
    ctrl = _mpc(plant, mpc_spec, max_solve_time=1.0)
    bad = {300, 996, 997, 998}
    ctrl.inject_failures = bad
    plans = {}
    orig = ctrl.step

    def step(t, y_motor, y_load, r):  # record the plan the fallback must follow
        plans[ctrl._k] = ctrl._plan.copy()
        return orig(t, y_motor, y_load, r)

    ctrl.step = step
    res = simulate_closed_loop(plant, ctrl, ref, 1.5, sensors=model.sensors)
    assert res.success
    assert [round(f["t"] / ctrl.Ts) for f in res.fallbacks] == sorted(bad)
    assert all(f["reason"] == "solve failed: injected failure" for f in res.fallbacks)
    assert [ctrl.statuses[k] for k in sorted(bad)] == ["injected failure"] * 4
    lim = plant.torque_limit
    for k in sorted(bad):
        assert res.command[k] == pytest.approx(min(max(plans[k][1], -lim), lim), abs=1e-15)
    assert _rms_after_settle(res) < 1.45e-4


def _fail_every(ctrl: MPC, every: int, status: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Make every ``every``-th QP solve of ``ctrl`` fail with ``status``."""
    calls = {"n": 0}
    orig = ctrl._qp.solve

    def flaky() -> str:
        calls["n"] += 1
        return status if calls["n"] % every == 0 else orig()

    monkeypatch.setattr(ctrl._qp, "solve", flaky)


def test_solver_failure_and_overrun_fall_back(servo, mpc_spec, monkeypatch: pytest.MonkeyPatch) -> None:
    # a solver that fails (the QP object reports a failed KKT check) and a limit no solve can meet: both
    # fall back every time they happen and say why
    model, plant = servo
    ref = reference("sine")
    ctrl = _mpc(plant, mpc_spec, max_solve_time=1.0)
    _fail_every(ctrl, 50, "daqp solution fails the KKT check (1 > 0.0001)", monkeypatch)
    res = simulate_closed_loop(plant, ctrl, ref, 0.3, sensors=model.sensors)
    assert res.fallbacks and all("KKT check" in f["reason"] for f in res.fallbacks)
    # every solve overruns: every step falls back (the plans it follows are one sample late, so a landing
    # can become infeasible too: that is reported as a failure)
    ctrl = _mpc(plant, mpc_spec, max_solve_time=1e-9)
    ctrl.realtime = True  # act on overruns as on the target (the default only counts them)
    res = simulate_closed_loop(plant, ctrl, ref, 0.02, sensors=model.sensors)
    assert len(res.fallbacks) == res.t.size - 1
    reasons = [f["reason"] for f in res.fallbacks]
    assert all(r.startswith(("solve overran", "solve failed")) for r in reasons)
    assert sum(r.startswith("solve overran") for r in reasons) > 0.5 * len(reasons)


def test_a_failed_solve_that_overran_counts_as_an_overrun(servo, mpc_spec, monkeypatch: pytest.MonkeyPatch) -> None:
    # a reviewer's (h4) realtime run with max_solve_time = 1e-9: every step's solves took longer, yet overruns said
    # 817 of 1000 steps, the 183 whose (late) landing QP was infeasible left out. overruns counts the steps over the
    # budget in solve_times, failed or not (as the exported controller's SIL wrapper counts them)
    model, plant = servo
    ctrl = _mpc(plant, mpc_spec, max_solve_time=1e-9)
    _fail_every(ctrl, 7, "gearctl QP: infeasible", monkeypatch)
    res = simulate_closed_loop(plant, ctrl, reference("sine"), 0.1, sensors=model.sensors)
    failed = sum(f["reason"].startswith("solve failed") for f in res.fallbacks)
    assert failed > 0 and len(res.fallbacks) == failed  # realtime off: an overrun alone does not fall back
    assert res.overruns == int(np.sum(res.solve_times > 1e-9)) == res.solve_times.size


def test_osqp_prints_nothing_to_standard_output(servo, mpc_spec, tmp_path: Path, capfd: pytest.CaptureFixture) -> None:
    # a reviewer's (h4) solver = "osqp": OSQP's C code printed "Polishing not needed - no active set detected at
    # optimal point" on stdout at every solve without an active bound (verbose = False does not reach it), which broke
    # `gearctl track ... --json` (not JSON any more). Its solves now run with standard output muted; what gearctl
    # itself prints is kept, in order
    if "osqp" not in mpc_module.installed_solvers():
        pytest.skip("osqp not in this CasADi")
    model, plant = servo
    ctrl = _mpc(plant, mpc_spec, solver="osqp", max_solve_time=1.0)
    print("before", flush=True)
    res = simulate_closed_loop(plant, ctrl, reference("sine"), 0.3, sensors=model.sensors)
    ctypes.CDLL(None).fflush(None)  # C's stdout buffer, which would otherwise reach the descriptor only at exit
    print("after", flush=True)
    assert res.success and not res.fallbacks
    assert capfd.readouterr().out == "before\nafter\n"
    path = tmp_path / "mpc_osqp.toml"
    path.write_text(resolve("mpc", "controllers").read_text().replace('solver = "gearctl"', 'solver = "osqp"'))
    assert 'solver = "osqp"' in path.read_text()
    assert main(["track", "shing1993_servo", str(path), "--duration", "0.3", "--json"]) == 0
    ctypes.CDLL(None).fflush(None)
    out = capfd.readouterr().out
    assert json.loads(out)["controller"]["solver"] == "osqp"


def test_a_reused_osqp_mpc_runs_as_a_new_one(servo, mpc_spec) -> None:
    # h9, a sweep with solver = "osqp" on a running cluster: every row differed from the same sweep with --workers 1
    # (up to 25 % of the RMS error), and from itself when run again. A sweep builds its controllers once per worker
    # thread and resets them before each run; OSQP kept its workspace (its adaptive rho among it) in the CasADi conic,
    # so a reset MPC solved from the last run's state: a run's figures hung on which runs its thread had run before
    if "osqp" not in mpc_module.installed_solvers():
        pytest.skip("osqp not in this CasADi")
    model, plant = servo
    ref = reference("sine")

    def error(ctrl: MPC) -> np.ndarray:
        return simulate_closed_loop(plant, ctrl, ref, 0.3, sensors=model.sensors, seed=3).error

    fresh = error(_mpc(plant, mpc_spec, solver="osqp", max_solve_time=1.0))
    ctrl = _mpc(plant, mpc_spec, solver="osqp", max_solve_time=1.0)
    simulate_closed_loop(plant, ctrl, reference("step"), 0.3, sensors=model.sensors, seed=1)  # another run first
    np.testing.assert_array_equal(error(ctrl), fresh)
    np.testing.assert_array_equal(error(ctrl), fresh)


def test_a_sweep_with_osqp_gives_each_run_the_same_figures_whatever_ran_before(tmp_path: Path) -> None:
    # the same through the sweep's own path (sweep_task: controllers kept per thread): run 1 alone in a fresh thread,
    # after run 0, and again after both, gives the same row
    import threading

    from gearctl.sweep import plan_sweep, sweep_task

    if "osqp" not in mpc_module.installed_solvers():
        pytest.skip("osqp not in this CasADi")
    path = tmp_path / "mpc_osqp.toml"
    path.write_text(resolve("mpc", "controllers").read_text().replace('solver = "gearctl"', 'solver = "osqp"'))
    plan = plan_sweep("shing1993_servo", path, vary=["backlash=0.5x:2x"], runs=2, duration=0.2)

    def in_new_thread(jobs: list) -> list[dict]:
        out: list = []
        t = threading.Thread(target=lambda: out.append(sweep_task(plan.context, jobs)))
        t.start()
        t.join()
        return out[0]

    alone = in_new_thread(plan.jobs[1:])[0]
    rows = in_new_thread(plan.jobs + plan.jobs)  # one thread: run 1 after run 0, then both again
    after, again = rows[1], rows[3]
    for k in ("rms_error", "max_error", "final_error", "torque_rms"):
        assert after[k] == alone[k] and again[k] == alone[k], k


def test_settings_without_a_backlash_take_the_plants() -> None:
    # a reviewer (h4) tuning through the API: MPC(info, MPCSettings(horizon=20)) took MPCSettings' default backlash,
    # the benchmark servo's 5e-5 m, whatever the plant (MPC(info) and a controller file take the plant's): on the
    # Quanser train (3.0e-5 m) the plan's gap was 1.7 times the train's and the load ran off, 1.31 rad RMS on the
    # sine against 2.1e-4 from the catalog file. Now a settings object without a backlash gets the plant's
    plant = build_plant(load_model("servo_3stage_quanser_srv02"))
    info = loop_info(plant)
    assert MPCSettings().backlash is None and MPCSettings(backlash=0.0).backlash == 0.0
    ctrl = MPC(info, MPCSettings(horizon=20, max_solve_time=1.0))
    assert ctrl.settings.backlash == info.plant.backlash == MPC(info).settings.backlash != 5e-5
    assert ctrl.describe()["backlash"] == info.plant.backlash
    res = simulate_closed_loop(plant, ctrl, reference("sine"), 1.0)
    assert res.success and tracking_metrics(res).rms_error < 1e-3


def test_a_solve_budget_over_the_sample_period_is_noted(servo, mpc_spec) -> None:
    # a reviewer (h4) copied the catalog file (max_solve_time = 1e-3) and set sample_time = 5e-4: steps whose solves
    # took 0.5 to 1 ms, late on a 2 kHz target, were reported on time (overruns 0) without a word. A budget over the
    # sample period is now noted (track, precision, bench print it); the catalog's (equal to its period) is not
    model, plant = servo
    ctrl = _mpc(plant, mpc_spec, sample_time=5e-4, horizon=25)
    notes = [n for n in ctrl.design_notes if n.startswith("max_solve_time")]
    assert len(notes) == 1 and "over the sample period (0.0005 s)" in notes[0]
    assert not [n for n in _mpc(plant, mpc_spec).design_notes if n.startswith("max_solve_time")]


# --- bad input -----------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("key", "value", "match"),
    [
        ("solver", "hpipm", r"solver = 'hpipm' is not a QP solver: expected one of 'daqp', 'qrqp'"),
        ("horizon", 0, r"horizon = 0 is out of range"),
        ("horizon", 2.5, r"horizon = 2.5 is not a whole number"),
        ("soft_landing", "hard", r"soft_landing = 'hard' is not allowed"),
        ("feedback", "both", r"feedback = 'both' is not allowed"),
        ("landing_velocity", 0.0, r"landing_velocity = 0.0 is out of range"),
        ("max_solve_time", -1e-3, r"max_solve_time = -0.001 is out of range"),
        ("smoothing", -1.0, r"smoothing = -1.0 is out of range"),
        ("backlash", -1e-6, r"backlash = -1e-06 is out of range"),  # 0 is allowed: the backlash-free MPC
        ("backlash", 0.01, r"backlash = 0.01 is out of range: expected 0 <= value < 0.01"),
    ],
)
def test_bad_top_level_key(servo, mpc_spec, key: str, value: object, match: str) -> None:
    _, plant = servo
    with pytest.raises(InputError, match=match) as exc:
        _mpc(plant, mpc_spec, **{key: value})
    assert "mpc.toml" in str(exc.value) and exc.value.field == key


@pytest.mark.parametrize(
    ("section", "key", "value"),
    [
        ("weights", "torque_rate", -1.0),
        ("weights", "tracking", 0.0),
        ("weights", "relative_velocity", float("nan")),
        ("weights", "terminal", "big"),
        ("observer", "process_noise", 0.0),
        ("observer", "measurement_noise", -2e-6),
    ],
)
def test_bad_weight_or_noise(servo, mpc_spec, section: str, key: str, value: object) -> None:
    _, plant = servo
    spec = {**mpc_spec, section: {**mpc_spec[section], key: value}}
    # a string is named as the wrong type ("is not a number"), a number out of range as such
    with pytest.raises(InputError, match=rf"mpc.toml: \[{section}\] {key} = .* is (out of range|not a number)") as exc:
        build_controller(spec, plant, path="mpc.toml")
    assert exc.value.field == key


def test_unknown_key_and_design_table(servo, mpc_spec) -> None:
    _, plant = servo
    with pytest.raises(InputError, match=r"unknown key horizn .* did you mean 'horizon'"):
        build_controller({**mpc_spec, "horizn": 10}, plant, path="mpc.toml")
    with pytest.raises(InputError, match=r"unknown section \[design\] for kind 'mpc'"):
        build_controller({**mpc_spec, "design": {"bandwidth_hz": 20.0}}, plant, path="mpc.toml")


def test_torque_weights_cannot_both_be_zero(servo, mpc_spec) -> None:
    _, plant = servo
    spec = {**mpc_spec, "weights": {**mpc_spec["weights"], "torque": 0.0, "torque_rate": 0.0}}
    with pytest.raises(InputError, match=r"mpc.toml: \[weights\] torque = 0 and torque_rate = 0"):
        build_controller(spec, plant, path="mpc.toml")


def test_solver_not_installed(servo, mpc_spec, monkeypatch: pytest.MonkeyPatch) -> None:
    # every offered plugin loads in the benchmark's CasADi 3.8.2; pretend one does not
    _, plant = servo
    assert set(mpc_module.installed_solvers()) == set(SOLVERS)
    monkeypatch.setitem(mpc_solvers._PLUGIN_OK, "osqp", False)
    with pytest.raises(InputError, match=r"solver = 'osqp' is not installed in this CasADi: installed are 'daqp'"):
        build_mpc(Path("mpc.toml"), {**mpc_spec, "solver": "osqp"}, loop_info(plant), Ts=1e-3, name="mpc")


def test_settings_validate_directly() -> None:
    with pytest.raises(InputError, match="horizon"):
        MPCSettings(horizon=0)
    with pytest.raises(InputError, match="torque_rate"):
        MPCSettings(torque_rate=-1.0)
    with pytest.raises(InputError, match="solver = 'ipopt'"):
        MPCSettings(solver="ipopt")
    for b in (-1e-6, 0.01, float("nan")):
        with pytest.raises(InputError, match="backlash"):
            MPCSettings(backlash=b)
    assert MPCSettings(backlash=0.0).backlash == 0.0  # the backlash-free train


def test_overruns_are_counted_not_acted_on_by_default(servo, mpc_spec) -> None:
    """Without ``realtime`` a solve over its budget is counted but the plan is applied: deterministic runs."""
    model, plant = servo
    ref = reference("sine")
    ctrl = _mpc(plant, mpc_spec, max_solve_time=1e-9)  # every solve overruns
    a = simulate_closed_loop(plant, ctrl, ref, 0.05, sensors=model.sensors)
    assert a.overruns == a.solve_times.size > 0 and not a.fallbacks
    b = simulate_closed_loop(plant, _mpc(plant, mpc_spec), ref, 0.05, sensors=model.sensors)
    np.testing.assert_array_equal(a.x, b.x)  # the budget does not change the trajectory


# --- the backlash-free limit (backlash = 0) ------------------------------------------------------------------


@pytest.fixture(scope="module")
def free_servo():
    """The benchmark model and its backlash-free plant (plant and nominal plant, as ``gearctl bench``)."""
    model = load_model("shing1993_servo")
    return model, build_plant(model, backlash=0.0)


def test_backlash_free_mpc_solves_only_the_contact_qp(free_servo, mpc_spec) -> None:
    # b = 0: no gap, so no separation, crossing or landing pattern; the mesh torque rows are empty (the mesh
    # pulls as well as pushes) and each step solves the one rigid-train QP, successfully
    model, plant = free_servo
    ctrls = [MPC(loop_info(plant), MPCSettings(backlash=0.0, max_solve_time=1.0)),
             _mpc(plant, mpc_spec, max_solve_time=1.0),  # the model's backlash (0) through the file
             _mpc(build_plant(model), mpc_spec, backlash=0.0),  # the file's key overrides the model's
             build_mpc(Path("mpc.toml"), mpc_spec, loop_info(build_plant(model)), Ts=1e-3, name="mpc", backlash=0.0)]
    for ctrl in ctrls:
        assert ctrl.settings.backlash == 0.0
        assert list(ctrl._patterns) == [ctrl._all_contact]
        (pat,) = ctrl._patterns.values()
        assert not pat.has_landing and pat.land_row == -1 and pat.gap_rows.size == 0
        for sig in (1, -1):
            assert np.all(pat.A[sig] == 0.0) and np.all(np.isfinite(pat.M[sig]))
        d = ctrl.describe()
        assert d["patterns"] == 1 and d["crossing_samples"] == 0
    ctrl = ctrls[0]
    res = simulate_closed_loop(plant, ctrl, reference("sine"), 0.3, sensors=model.sensors)
    assert res.success and not res.fallbacks
    assert ctrl.statuses == ["ok"] * (res.t.size - 1)
    assert np.all(ctrl._qp.lba[:ctrl.N] <= -1e20)  # no bound on the mesh torque
    assert np.all(ctrl._z[2:4] == 0.0)  # the observer's gap: none
    assert np.all(np.isfinite(res.command)) and np.all(np.abs(res.command) <= plant.torque_limit)


@pytest.mark.skipif(mpc_solvers.c_compiler() is None, reason="no C compiler: the compiled QP cannot be built")
def test_backlash_free_compiled_and_casadi_paths_agree(free_servo) -> None:
    # as test_compiled_and_casadi_paths_agree, without backlash (measured: identical torques)
    model, plant = free_servo
    runs = []
    for compiled in (True, False):
        ctrl = MPC(loop_info(plant), MPCSettings(backlash=0.0, max_solve_time=1.0), compiled=compiled)
        assert ctrl.describe()["compiled"] is compiled
        runs.append(simulate_closed_loop(plant, ctrl, reference("sine"), 0.3, sensors=model.sensors))
    assert_allclose(runs[0].command, runs[1].command, rtol=0, atol=1e-10)


def test_backlash_free_plant_is_the_better_bound(servo, free_servo) -> None:
    # the catalog MPC designed on the backlash-free plant and run on it (as the benchmark's backlash-free
    # runs) against the catalog MPC on the backlash plant, 3 s of the 1 Hz sine: measured RMS 8.4e-7 rad
    # against 2.86e-6 rad (ratio 3.4) since the MPC solves its QPs exactly (gearctl's dense active-set solver;
    # with DAQP's approximate solutions it was 2.7e-5, ratio 32), no impact; a factor 2 is kept. The mesh
    # carries torque both ways (its deflection s changes sign): the rigid coupling pulls as well as pushes
    model, free = free_servo
    _, plant = servo
    ref = reference("sine")
    ctrl = load_controller("mpc", free)
    res = simulate_closed_loop(free, ctrl, ref, DURATION, sensors=model.sensors)
    m = tracking_metrics(res)
    m_b = tracking_metrics(simulate_closed_loop(plant, load_controller("mpc", plant), ref, DURATION,
                                                sensors=model.sensors))
    assert res.success and m["impacts"] == 0 and len(res.impacts) == 0
    assert m["rms_error"] < 0.5 * m_b["rms_error"], (m["rms_error"], m_b["rms_error"])
    assert res.s.min() < 0.0 < res.s.max()
    assert not res.fallbacks  # no failed solve (overruns are only counted: realtime is off)


def test_cli_track_with_backlash_zero(capsys: pytest.CaptureFixture[str]) -> None:
    # `gearctl track shing1993_servo mpc --backlash 0` used to fail ("backlash = 0.0 is out of range");
    # measured RMS 8.4e-7 rad against 2.7e-5 rad with the model's backlash
    out = {}
    for args in (["--backlash", "0"], []):
        assert main(["track", "shing1993_servo", "mpc", *args, "--json"]) == 0
        out[bool(args)] = json.loads(capsys.readouterr().out)
    free, with_b = out[True], out[False]
    assert free["backlash"] == 0.0 and free["controller"]["backlash"] == 0.0 and with_b["backlash"] > 0.0
    assert free["impacts"] == 0
    assert free["rms_error"] < with_b["rms_error"], (free["rms_error"], with_b["rms_error"])


@pytest.mark.parametrize("offset", [1e-6, 5e-6, 1e-4])
def test_mpc_sine_from_other_starts(offset: float) -> None:
    # started with motor and load turned together by a few urad (still mid-gap), the MPC's sine on the frictionless
    # servo is not its 2.86e-6 rad RMS from zero: one reversal in a few ends in a 0.1 s train of bounces of up to
    # 2e-4 rad (found by a C harness started off zero). Measured RMS after 0.5 s: 8.1e-6, 2.5e-5, 3.2e-5 rad (the
    # inverse 3.7e-6 from each); kept: at least 15x below the PID's 6.47e-4 (measured 20-80x)
    m = load_model("shing1993_servo")
    plant = build_plant(m)
    x0 = np.zeros(4)
    x0[0], x0[1] = offset * plant.gear_ratio, offset
    res = simulate_closed_loop(plant, load_controller("mpc", plant, sensors=m.sensors), reference("sine"), 3.0,
                               sensors=m.sensors, x0=x0)
    e = res.error[res.t >= 0.5]
    rms = float(np.sqrt(np.mean(e**2)))
    print(f"\nstart {offset:g} rad: MPC sine RMS {rms:.3g} rad")
    assert rms <= 6.47e-4 / 15.0


def test_riccati_fallback_agrees_with_scipy() -> None:
    # the observer's fallback where SciPy's Riccati solver fails (tests/test_fuzz.py, mpc_riccati_pencil): the
    # filter's recursion iterated to its fixed point gives SciPy's solution on a regular plant (measured 4e-11)
    import scipy.linalg

    from gearctl.design.mpc import _riccati_iteration

    A = np.array([[1.0, 1e-3], [0.0, 0.999]])
    G = np.array([[0.0], [1e-3]])
    C = np.array([[1.0, 0.0]])
    R = np.array([[4e-12]])
    Q = G @ np.array([[1e-2]]) @ G.T
    P = _riccati_iteration(A, Q, C, R)
    np.testing.assert_allclose(P, scipy.linalg.solve_discrete_are(A.T, C.T, Q, R), rtol=1e-8)
