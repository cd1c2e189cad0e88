"""The MPC on steps its horizon cannot see the stop of: the reference governor (mpc.py, *Large steps*).

Oracles: the discrete time-optimal profile's closed form (acceleration bound, time to stop, no overshoot); the
closed loop against the step itself (peak and final error); the reference governor leaving a feasible reference
alone (the same torques bit for bit as with the governor off); the exported C against the Python, bit for bit.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from gearctl.build import c_compiler
from gearctl.catalog import load_controller, load_model
from gearctl.closedloop import simulate_closed_loop
from gearctl.design.mpc import _governor_step
from gearctl.plant import build_plant
from gearctl.references import Reference, reference

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).parent / "data"
REVIEWER = DATA / "reviewer_pair_24x72.toml"
needs_cc = pytest.mark.skipif(c_compiler() is None, reason="no C compiler: the exported C cannot be built here")


def _loop(model: str | Path, controller: str | Path = "mpc"):
    m = load_model(model)
    sp = build_plant(m)
    return m, sp, load_controller(controller, sp, sensors=m.sensors)


def _load_angle(run) -> np.ndarray:
    return run.x[len(run.plant.shafts) - 1]


def _short_horizon_file(tmp_path: Path) -> Path:
    """The catalog MPC with a horizon of 13 samples at 0.5 ms (the shortest this pair's crossing allows)."""
    text = (ROOT / "controllers" / "mpc.toml").read_text()
    for old, new in (("sample_time = 1e-3 ", "sample_time = 5e-4 "), ("horizon = 20 ", "horizon = 13 "),
                     ("max_solve_time = 1e-3", "max_solve_time = 5e-4")):
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "mpc_h13.toml"
    path.write_text(text)
    return path


class _SineAndStep:
    """A 0.1 rad 1 Hz sine with a step of ``h`` rad added at ``t0`` (what a ReferenceLike may be)."""

    def __init__(self, h: float = 2.0, t0: float = 0.3) -> None:
        self.h, self.t0, self.w = h, t0, 2.0 * math.pi

    def at(self, t):
        t = np.asarray(t, dtype=float)
        s, c = np.sin(self.w * t), np.cos(self.w * t)
        return 0.1 * s + np.where(t >= self.t0, self.h, 0.0), 0.1 * self.w * c, -0.1 * self.w**2 * s

    def load_disturbance(self, t: float) -> float:
        return 0.0


# --- the profile -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("dist", [2.0, -0.37, 1e-4, *np.random.default_rng(0).uniform(-5.0, 5.0, 20)])
def test_governor_step_is_the_discrete_time_optimal_profile(dist: float) -> None:
    a, Ts = 74.0, 1e-3
    g, w, k = 0.0, 0.0, 0
    speeds = [0.0]
    while not (abs(g - dist) <= a * Ts * Ts and abs(w) <= a * Ts) and k < 10_000:
        g, w = _governor_step(g, w, 0.0, dist, 0.0, a, 4.0 * a, math.inf, Ts)
        speeds.append(w)
        # past the target by at most a Ts^2 / 8, on the last sample (it then steps onto the reference)
        assert math.copysign(1.0, dist) * (g - dist) <= a * Ts * Ts / 8.0 * (1.0 + 1e-9)
        k += 1
    dw = np.abs(np.diff(speeds))
    assert dw.max() <= a * Ts * (1 + 1e-12)  # the acceleration bound
    assert np.abs(speeds).max() <= math.sqrt(a * abs(dist)) + a * Ts  # the triangle's peak speed
    # bang-bang at a: 2 sqrt(d / a); the discrete profile takes at most two samples more
    assert k <= math.ceil(2.0 * math.sqrt(abs(dist) / a) / Ts) + 2


def test_governor_step_keeps_the_speed_limit_and_follows_a_moving_reference() -> None:
    a, Ts, vmax = 50.0, 1e-3, 1.5
    g, w = 0.0, 0.0
    for k in range(3000):  # a reference 1 rad ahead, moving at 1 rad/s
        r1, rd1 = 1.0 + 1.0 * (k + 1) * Ts, 1.0
        w0 = w
        g, w = _governor_step(g, w, 1.0, r1, rd1, a, 4.0 * a, vmax, Ts)
        assert abs(w) <= vmax and abs(w - w0) <= a * Ts * (1 + 1e-12)
    np.testing.assert_allclose(g, 1.0 + 3000 * Ts, atol=a * Ts * Ts)
    np.testing.assert_allclose(w, 1.0, atol=a * Ts)


def test_governor_step_follows_a_reference_accelerating_beyond_its_own_share() -> None:
    # a sine accelerating at up to 3.9 rad/s^2, the profile closing at 1 rad/s^2 (a quarter of what the drive gives):
    # it moves with the sine's own speed change (within the drive's 4 rad/s^2) and closes the 0.5 rad between them
    a, a_max, Ts, om = 1.0, 4.0, 1e-3, 2.0 * math.pi
    g, w = -0.5, 0.0
    for k in range(6000):
        t0, t1 = k * Ts, (k + 1) * Ts
        w0 = w
        g, w = _governor_step(g, w, 0.1 * om * math.cos(om * t0), 0.1 * math.sin(om * t1), 0.1 * om * math.cos(om * t1),
                              a, a_max, math.inf, Ts)
        assert abs(w - w0) <= a_max * Ts * (1 + 1e-12)
    t = 6000 * Ts
    assert abs(g - 0.1 * math.sin(om * t)) <= a_max * Ts * Ts
    assert abs(w - 0.1 * om * math.cos(om * t)) <= a_max * Ts


# --- the closed loop -------------------------------------------------------------------------------------


@pytest.mark.parametrize(("model", "amplitude"), [
    ("shing1993_servo", 2.0),  # 2.97 rad before the governor (48 % over)
    ("shing1993_servo", -20.0),  # -35.5 rad before
    (REVIEWER, 2.0),  # 2.66 rad before
    (DATA / "tight_torque_servo.toml", 2.0),  # 3.10 rad before
])
def test_large_step_stops_on_the_reference(model: str | Path, amplitude: float) -> None:
    _, sp, c = _loop(model)
    run = simulate_closed_loop(sp, c, Reference(kind="step", amplitude=amplitude), 0.5 + 0.06 * abs(amplitude) + 0.5,
                               sensors=load_model(model).sensors)
    y = _load_angle(run) * math.copysign(1.0, amplitude)
    d = abs(amplitude)
    assert y.max() <= 1.01 * d, f"peak {y.max():.4g} rad on a {d:g} rad step"
    assert y.min() >= -0.01 * d
    assert abs(y[-1] - d) <= 1e-3 * d
    assert c.describe()["governor"]["acceleration"] > 0.0


def test_short_horizon_on_the_reviewers_pair_does_not_run_away(tmp_path: Path) -> None:
    # a horizon of 13 samples at 0.5 ms (6.5 ms): a 2 rad step peaked at 3.9 rad before, a 20 rad one at 208 rad
    m, sp, c = _loop(REVIEWER, _short_horizon_file(tmp_path))
    run = simulate_closed_loop(sp, c, Reference(kind="step", amplitude=2.0), 0.8, sensors=m.sensors)
    y = _load_angle(run)
    assert -0.02 <= y.min() and y.max() <= 2.02
    assert abs(y[-1] - 2.0) <= 2e-3


@pytest.mark.parametrize(("model", "duration", "after"), [
    ("shing1993_servo", 1.5, 1e-4),  # 0.97 rad past the reference before
    # a weak drive (a quarter of its 6.7 rad/s^2 at the load is below the sine's 3.9): 0.10 rad past it before; the
    # profile moves with the sine's own acceleration and closes at its quarter
    (DATA / "coarse_encoders_train.toml", 6.0, 1e-3),
])
def test_step_added_to_a_moving_reference_rejoins_it(model, duration: float, after: float) -> None:
    m, sp, c = _loop(model)
    run = simulate_closed_loop(sp, c, _SineAndStep(), duration, sensors=m.sensors)
    e = _load_angle(run) - run.reference
    assert e[run.t >= 0.3].max() <= 1e-3  # never past the reference
    assert np.abs(e[run.t >= duration - 0.5]).max() <= after  # back on it, tracking the sine
    assert c._gov[2]  # the governor is on the reference again


@pytest.mark.parametrize("kind", ["sine", "move", "ramp", "step"])
def test_a_reference_the_plan_can_follow_reaches_it_as_it_is(kind: str) -> None:
    # the catalog's references (the step: 0.05 rad, below what the plan stops within its horizon) are given to the
    # plan unchanged, so the catalog's figures are the same bit for bit
    m, sp, c = _loop("shing1993_servo")
    given = []
    governed = c._governed

    def spy(i, z):
        out = governed(i, z)
        given.append(out is None)
        return out

    c._governed = spy
    ref = reference(kind)
    on = simulate_closed_loop(sp, c, ref, 0.6, sensors=m.sensors)
    assert given and all(given)
    c._gov_on = False
    off = simulate_closed_loop(sp, c, ref, 0.6, sensors=m.sensors)
    np.testing.assert_array_equal(on.command, off.command)


def test_a_ramp_faster_than_the_plan_stops_is_left_to_the_plan() -> None:
    # a jump of the reference's speed alone is the plan's: a profile off the reference would brake a 20 rad/s ramp's
    # end at a quarter of the drive's acceleration (2.6 rad past it) where the plan brakes at the limit (0.37 rad)
    m, sp, c = _loop("shing1993_servo")
    ref = Reference(kind="ramp", amplitude=20.0, rate=20.0)
    on = simulate_closed_loop(sp, c, ref, 1.5, sensors=m.sensors)
    c._gov_on = False
    off = simulate_closed_loop(sp, c, ref, 1.5, sensors=m.sensors)
    np.testing.assert_array_equal(on.command, off.command)
    assert _load_angle(on).max() - 20.0 <= 0.5


def test_a_move_beyond_the_drive_is_governed() -> None:
    # 1e4 rad/s^2 against the 296 the drive gives the load: the plan chased it and went 10.4 rad past its end
    m, sp, c = _loop("shing1993_servo")
    ref = Reference(kind="move", amplitude=20.0, rate=50.0, accel=1e4, profile="trapezoid")
    run = simulate_closed_loop(sp, c, ref, 1.5, sensors=m.sensors)
    y = _load_angle(run)
    assert y.max() <= 20.0 + 1e-3 and abs(y[-1] - 20.0) <= 1e-3


def test_describe_states_the_governor_as_json() -> None:
    d = _loop("shing1993_servo")[2].describe()["governor"]
    json.dumps(d, allow_nan=False)
    # a quarter of what the 1 N m limit gives the train (J_eq 8.46e-4 kg m^2 on the motor, ratio 4) at the load
    np.testing.assert_allclose(d["acceleration"], 0.25 * 1.0 / (8.4576e-4 * 4.0), rtol=1e-4)
    assert d["max_speed"] is not None and d["jump"] > 0.05  # the catalog's step passes


# --- the exported C --------------------------------------------------------------------------------------


@needs_cc
@pytest.mark.parametrize(("model", "controller", "amplitude", "duration"), [
    ("shing1993_servo", "mpc", 2.0, 0.6),
    (REVIEWER, "h13", -2.0, 0.5),
])
def test_exported_c_governs_large_steps_as_python(tmp_path: Path, model, controller, amplitude, duration) -> None:
    from gearctl.export import export_controller, load_exported

    if controller == "h13":
        controller = _short_horizon_file(tmp_path)
    m, sp, c = _loop(model, controller)
    export_controller(c, tmp_path / "ctrl", plant=sp, sensors=m.sensors)
    cc = load_exported(tmp_path / "ctrl")
    ref = Reference(kind="step", amplitude=amplitude)
    a = simulate_closed_loop(sp, c, ref, duration, sensors=m.sensors)
    b = simulate_closed_loop(sp, cc, ref, duration, sensors=m.sensors)
    np.testing.assert_array_equal(a.command, b.command)
    y = _load_angle(b) * math.copysign(1.0, amplitude)
    assert y.max() <= 1.01 * abs(amplitude)
