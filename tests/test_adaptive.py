"""Adaptive dead-zone inverse (gearctl/design/adaptive.py, controllers/adaptive_inverse.toml; issue 13).

Oracles:

1. closed loop on the benchmark servo (``shing1993_servo``, 1 Hz sine of 0.1 rad), improved and Yang-Sun
   plants: started with the estimate at 0.5x and 1.5x the true b, the estimate comes within 5 % of b by
   the third reversal of the sine (measured by examples/07_adaptive_inverse.py: improved from 0.5 b after 2
   reversals, t = 1.1 s, the three others after 3, t = 1.6 s) and stays there; from 3 s on the RMS
   load-angle error is within 10 % of that of the same inverse (step crossing) told the true b. Measured
   ratios, before the switch to a ramp crossing once converged / with it: improved 0.998 / 0.385 (0.5 b),
   1.033 / 0.560 (1.5 b); Yang-Sun 0.960 / 0.775, 0.991 / 0.811;
2. once converged it crosses with the ramp (``converged_crossing_time``): after convergence its RMS error on
   the improved plant is that of the fixed ``deadzone_inverse`` (sin^2 crossing) told the true b, and an
   overestimate of 1.2 b, which costs the fixed ramp inverse the whole lost motion every other reversal,
   costs it nothing once converged;
3. the update law on its own: bounded steps, projection on the bounds, the inverse told only changes
   beyond ``apply_threshold``; the crossing switches to the ramp after two agreeing measurements and back
   to the step after one 10 % off;
4. the file: its keys read like the inverse's, an unknown or inconsistent key is one line.

``gearctl track shing1993_servo adaptive_inverse --duration 6 --estimate B`` (RMS / max error from 0.5 s,
urad), before the switch to a ramp (``converged_crossing_time = 0``) -> with it:

==========  ========================  ========================
estimate    improved                  Yang-Sun
==========  ========================  ========================
2.5e-5      68.8 / 187 -> 47.7 / 186  111 / 340 -> 99.3 / 340
5e-5        69.7 / 183 -> 40.9 / 183  121 / 200 -> 88.5 / 199
6e-5        75.0 / 199 -> 45.5 / 199  133 / 384 -> 118 / 384
7.5e-5      124 / 802 -> 114 / 802    162 / 738 -> 154 / 738
==========  ========================  ========================

(the fixed deadzone_inverse told the true b: 21.1 / 96 improved, 84.2 / 191 Yang-Sun). The figures include
the learning second or three; the maxima are those of the start, before the switch. The converged part
alone is in the tests below.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from gearctl import InputError, build_plant, load_model
from gearctl.catalog import load_controller, resolve
from gearctl.closedloop import simulate_closed_loop
from gearctl.design.adaptive import CONVERGED_MEASUREMENTS, AdaptationSettings, AdaptiveInverse
from gearctl.design.registry import build_controller
from gearctl.files import read_toml
from gearctl.references import reference

MODEL = "shing1993_servo"
#: Reversals of the 1 Hz sine by which the estimate is within 5 % (stated; measured: 2 on every case).
REVERSALS_TO_5_PERCENT = 3
DURATION, SETTLE = 6.0, 3.0


@pytest.fixture(scope="module")
def servo() -> tuple:
    model = load_model(MODEL)
    return model, build_plant(model)


def _inverse_spec() -> dict:
    """The adaptive file's inverse, without the adaptation: the same inverse told a fixed b."""
    spec = read_toml(resolve("adaptive_inverse", "controllers"))
    return {**{k: v for k, v in spec.items() if k != "adaptation"}, "kind": "deadzone_inverse"}


@pytest.fixture(scope="module")
def true_b_rms(servo: tuple) -> dict[str, float]:
    model, nominal = servo
    out = {}
    for kind in ("improved", "yang-sun"):
        ctrl = build_controller(_inverse_spec(), nominal, backlash=nominal.backlash)
        run = simulate_closed_loop(build_plant(model, kind), ctrl, reference("sine"), DURATION, sensors=model.sensors)
        out[kind] = float(np.sqrt(np.mean(run.error[run.t >= SETTLE] ** 2)))
    return out


@pytest.mark.parametrize("kind", ["improved", "yang-sun"])
@pytest.mark.parametrize("start", [0.5, 1.5])
def test_converges_and_tracks_like_the_true_b_inverse(servo: tuple, true_b_rms: dict, kind: str,
                                                      start: float) -> None:
    model, nominal = servo
    b = nominal.backlash
    ctrl = load_controller("adaptive_inverse", nominal, backlash=start * b)
    assert isinstance(ctrl, AdaptiveInverse) and ctrl.uses_load_encoder
    ref = reference("sine")
    run = simulate_closed_loop(build_plant(model, kind), ctrl, ref, DURATION, sensors=model.sensors)
    h = np.array(ctrl.history)
    assert h.shape[0] >= 6  # one measurement per crossing of the gap
    # every measurement after the first is within 2 % of the true gap (measured: improved 0.998-1.003, Yang-Sun
    # 0.99-1.0); the first one sees the start from the middle of the gap as well (measured 0.93-0.97 b)
    assert_allclose(h[1:, 1], b, rtol=0.02)
    assert_allclose(h[0, 1], b, rtol=0.10)
    # within 5 % once the third reversal of the sine (t = 0.25 + 0.5 k) has been measured, and from then on;
    # a crossing's measurement arrives within half a period (the 0.2 s window must see both flanks)
    t_stated = 0.25 + 0.5 * (REVERSALS_TO_5_PERCENT - 1) + 0.5
    held = h[h[:, 0] <= t_stated]
    assert held.size and abs(held[-1, 2] / b - 1) < 0.05, h[:, 2] / b
    later = h[h[:, 0] > t_stated]
    assert np.all(np.abs(later[:, 2] / b - 1) < 0.05), later[:, 2] / b
    assert abs(ctrl.backlash / b - 1) < 0.02
    # then it tracks within 10 % of the inverse told the true b (measured 0.96-1.03)
    rms = float(np.sqrt(np.mean(run.error[run.t >= SETTLE] ** 2)))
    assert rms <= 1.10 * true_b_rms[kind], (rms, true_b_rms[kind])
    d = run.controller
    assert d["kind"] == "adaptive_inverse" and d["backlash_initial"] == start * b
    assert len(d["backlash_history"]) == h.shape[0]


def test_wrong_estimate_without_adaptation_is_worse(servo: tuple, true_b_rms: dict) -> None:
    """The oracle of the test above can fail: the same inverse told 1.5 b tracks far worse."""
    model, nominal = servo
    ctrl = build_controller(_inverse_spec(), nominal, backlash=1.5 * nominal.backlash)
    run = simulate_closed_loop(build_plant(model), ctrl, reference("sine"), DURATION, sensors=model.sensors)
    rms = float(np.sqrt(np.mean(run.error[run.t >= SETTLE] ** 2)))
    assert rms > 2.0 * true_b_rms["improved"]  # measured 3.3x


def _rms_max(run, t0: float) -> tuple[float, float]:
    e = run.error[run.t >= t0]
    return float(np.sqrt(np.mean(e**2))), float(np.max(np.abs(e)))


@pytest.mark.parametrize("start", [0.5, 1.5])
def test_converged_adaptive_tracks_like_the_fixed_ramp_inverse(servo: tuple, start: float) -> None:
    """After convergence the adaptive inverse crosses with the ramp and tracks like the fixed ramp inverse
    (controllers/deadzone_inverse.toml, crossing_time = 0.01) told the true b, improved plant.

    Measured from 3.5 s (the switch comes at 2.6 s from 0.5 b, 3.1 s from 1.5 b): RMS 3.13 and 5.10 urad against
    3.13 for the fixed inverse (ratios 1.00, 1.63; the estimates end 0.45 % above b, and the ramp inverse is
    sensitive to an estimate above b; from 1.2 b, switched at 1.1 s: 28.5 urad, 9x). Without the switch (step
    crossings) it is 70 urad. Stated: at most 2x.
    """
    model, nominal = servo
    b = nominal.backlash
    ref = reference("sine")
    fixed = simulate_closed_loop(build_plant(model), load_controller("deadzone_inverse", nominal, backlash=b), ref,
                                 DURATION, sensors=model.sensors)
    ctrl = load_controller("adaptive_inverse", nominal, backlash=start * b)
    run = simulate_closed_loop(build_plant(model), ctrl, ref, DURATION, sensors=model.sensors)
    assert [w[1] for w in ctrl.switches] == [0.01] and ctrl.switches[0][0] < 3.5, ctrl.switches
    assert ctrl.converged and ctrl.inner.crossing_time == 0.01
    rms, _ = _rms_max(run, 3.5)
    rms_fixed, _ = _rms_max(fixed, 3.5)
    assert rms <= 2.0 * rms_fixed, (rms, rms_fixed)


@pytest.mark.parametrize("kind", ["improved", "yang-sun"])
def test_overestimate_loses_no_lost_motion_after_convergence(servo: tuple, kind: str) -> None:
    """Started at 1.2 b (an overestimate), the max error after the switch to the ramp stays well below the lost
    motion 2 b / r_b2 = 1.33e-3 rad: measured 0.124 L (improved, switch at 1.1 s) and 0.140 L (Yang-Sun, 2.6 s);
    stated 0.3 L. The fixed ramp inverse told 1.2 b loses the whole lost motion every other reversal over the same
    stretch (measured max 1.06 L, 1.08 L; checked > 0.8 L: the oracle can fail)."""
    model, nominal = servo
    b = nominal.backlash
    lost = 2.0 * b / nominal.rb2
    ref = reference("sine")
    ctrl = load_controller("adaptive_inverse", nominal, backlash=1.2 * b)
    run = simulate_closed_loop(build_plant(model, kind), ctrl, ref, DURATION, sensors=model.sensors)
    assert len(ctrl.switches) == 1 and ctrl.switches[0][1] == 0.01, ctrl.switches
    t_switch = ctrl.switches[0][0]
    assert t_switch < 3.0
    _, worst = _rms_max(run, t_switch + ctrl.Ts)
    assert worst < 0.3 * lost, (worst / lost, t_switch)
    fixed = simulate_closed_loop(build_plant(model, kind), load_controller("deadzone_inverse", nominal,
                                                                           backlash=1.2 * b),
                                 ref, DURATION, sensors=model.sensors)
    _, worst_fixed = _rms_max(fixed, t_switch + ctrl.Ts)
    assert worst_fixed > 0.8 * lost, worst_fixed / lost


def test_crossing_switches_to_the_ramp_when_converged_and_back(servo: tuple) -> None:
    _, nominal = servo
    b0 = 5e-5
    ad = load_controller("adaptive_inverse", nominal, backlash=b0)
    st = ad.settings
    assert ad.learning_crossing_time == 0.0 == ad.inner.crossing_time and st.converged_crossing_time == 0.01
    # a measurement 3 % off the estimate does not count; then CONVERGED_MEASUREMENTS within 2 % do
    ad.update(0.1, 1.03 * ad.backlash)
    assert not ad.converged and ad.inner.crossing_time == 0.0
    for k in range(CONVERGED_MEASUREMENTS):
        assert not ad.converged
        ad.update(0.2 + 0.1 * k, 1.015 * ad.backlash)
    assert ad.converged and ad.inner.crossing_time == 0.01 and ad.inner._ramp.shape == "sin2"
    # a measurement 5 % off keeps the ramp (within diverged_tolerance), one 12 % off puts the step back
    ad.update(1.0, 1.05 * ad.backlash)
    assert ad.converged and ad.inner.crossing_time == 0.01
    ad.update(1.1, 0.88 * ad.backlash)
    assert not ad.converged and ad.inner.crossing_time == 0.0 and ad.inner._ramp.shape == "step"
    assert [w[1] for w in ad.switches] == [0.01, 0.0]
    ad.reset()
    assert not ad.converged and ad.switches == [] and ad.inner.crossing_time == 0.0
    # converged_crossing_time = 0: never switches
    never = AdaptiveInverse(build_controller(_inverse_spec(), nominal, backlash=b0),
                            AdaptationSettings(converged_crossing_time=0.0))
    for k in range(4):
        never.update(0.1 * k, b0)
    assert never.converged and never.inner.crossing_time == 0.0 and never.switches == []
    with pytest.raises(InputError, match=r"crossing_time = 2.0 is out of range"):
        ad.inner.set_crossing_time(2.0)
    with pytest.raises(InputError, match="diverged_tolerance"):
        AdaptationSettings(converged_tolerance=0.2, diverged_tolerance=0.1)


def test_update_law_is_bounded(servo: tuple) -> None:
    _, nominal = servo
    b0 = 4e-5
    inv = build_controller(_inverse_spec(), nominal, backlash=b0)
    ad = AdaptiveInverse(inv, AdaptationSettings(gain=0.6, max_step=0.5, min_backlash=2e-5, max_backlash=1e-4))
    # a wild measurement moves the estimate by at most max_step
    assert_allclose(ad.update(0.0, 1e-3), 1.5 * b0, rtol=1e-12)
    assert ad.inner.backlash == ad.backlash  # beyond apply_threshold: the inverse is told
    # then 1.5 x again, then projection on the upper bound
    assert_allclose(ad.update(0.1, 1e-3), 1.5**2 * b0, rtol=1e-12)
    assert_allclose(ad.update(0.15, 1e-3), 1e-4, rtol=1e-12)
    # a step of gain towards a plausible measurement: 1e-4 + 0.6 (8e-5 - 1e-4)
    assert_allclose(ad.update(0.2, 8e-5), 8.8e-5, rtol=1e-12)
    # a tiny change stays inside (apply_threshold 1 %): the inverse keeps its estimate
    held = ad.inner.backlash
    ad.update(0.3, 8.8e-5 * 1.01)
    assert ad.backlash != held and ad.inner.backlash == held
    # the lower bound
    for k in range(20):
        ad.update(1.0 + k, 0.0)
    assert_allclose(ad.backlash, 2e-5, rtol=1e-12)
    assert len(ad.history) == 25 and all(len(row) == 3 for row in ad.history)
    # reset: back to the initial estimate, history cleared
    ad.reset()
    assert ad.backlash == b0 == ad.inner.backlash and ad.history == []


def test_file_errors_are_one_line(servo: tuple, tmp_path: Path) -> None:
    _, nominal = servo
    text = resolve("adaptive_inverse", "controllers").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("gain = 0.6", "gian = 0.6"))
    with pytest.raises(InputError, match=r"unknown key \[adaptation\] gian.*did you mean 'gain'"):
        load_controller(bad, nominal)
    bad.write_text(text.replace("gain = 0.6", "gain = 1.5"))
    with pytest.raises(InputError, match=r"\[adaptation\] gain = 1.5 is out of range"):
        load_controller(bad, nominal)
    bad.write_text(text.replace("# min_backlash = 1e-5", "min_backlash = 1e-4").replace("# max_backlash = 2.5e-4",
                                                                                         "max_backlash = 5e-5"))
    with pytest.raises(InputError, match="min_backlash"):
        load_controller(bad, nominal)
    bad.write_text(text.replace("# max_backlash = 2.5e-4", "max_backlash = 2e-5"))
    with pytest.raises(InputError, match="initial estimate must lie within"):
        load_controller(bad, nominal)  # the model's 5e-5 is above the bound


def test_estimate_override_and_default(servo: tuple) -> None:
    model, nominal = servo
    assert load_controller("adaptive_inverse", nominal).backlash == nominal.backlash
    # the benchmark's backlash-free plant: an estimate of 0 stays 0 and the loop is the PID's
    zero = load_controller("adaptive_inverse", build_plant(model, backlash=0.0))
    run = simulate_closed_loop(build_plant(model, backlash=0.0), zero, reference("sine"), 1.0, sensors=model.sensors)
    assert zero.backlash == 0.0 and run.success and all(row[2] == 0.0 for row in zero.history)
    ad = load_controller("adaptive_inverse", nominal, backlash=3e-5)
    assert ad.backlash == 3e-5 == ad.inner.backlash
    assert math.isclose(ad.min_backlash, 0.2 * 3e-5) and math.isclose(ad.max_backlash, 5 * 3e-5)


def test_example_writes_the_convergence_plot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = Path(__file__).resolve().parents[1] / "examples" / "07_adaptive_inverse.py"
    spec = importlib.util.spec_from_file_location("ex07", path)
    mod = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    spec.loader.exec_module(mod)  # type: ignore[union-attr]
    mod.main(["--out", str(tmp_path), "--duration", "2.0"])
    assert (tmp_path / "adaptive_inverse.png").stat().st_size > 10_000
    out = capsys.readouterr().out
    assert out.count("within 5 % after") == 4


def test_the_law_keeps_the_estimate_above_the_backlash_floor() -> None:
    """Started at 3 nm (a valid estimate) and fed gaps of 0.1 nm, the law stops at the 1 nm floor of every
    estimate instead of handing the inverse a value it refuses mid-run."""
    from gearctl.units import BACKLASH_FLOOR

    plant = build_plant(load_model("shing1993_servo"))
    ctrl = load_controller("adaptive_inverse", plant, backlash=3e-9)
    for i in range(8):
        ctrl.update(0.1 * i, 1e-10)
    assert ctrl.min_backlash == BACKLASH_FLOOR and ctrl.inner.backlash == BACKLASH_FLOOR


@pytest.mark.parametrize(("model", "seed"), [("shing1993_servo_friction", 0), ("shing1993_servo", 1)])
def test_only_a_flank_change_is_measured(model: str, seed: int) -> None:
    # two kinds of window passed the span and plateau tests without holding both flanks: the centred start-up
    # (the half gap from the centre to a flank, measured 0.50 b on the friction servo: the estimate fell to 0.70 b
    # and took 17 s of ISO cycles to return) and a frictionless load coasting off its flank at rest (0.29-0.46 b,
    # seed 1: the inverse went back to its learning crossing for a cycle). Only a window with a flank change
    # measures now: every measurement of the ISO run within 5 % of b (measured: within 0.5 % and 1.1 %), but one
    # on the frictionless servo: since the inverse's stop drops an integral that would push the load back (the
    # load no longer launched off its flank at each stop: ISO A 2441 -> 378 urad here), the second window, while
    # the estimate still learns (t = 1.1 s), reads 0.82 b: the load rested off its flank when the crossing began.
    # The estimate steps to 0.89 b for one crossing and is back within 1 % at the next
    from gearctl.precision import precision_test

    m = load_model(model)
    plant = build_plant(m)
    ctrl = load_controller("adaptive_inverse", plant, sensors=m.sensors)
    res = precision_test(plant, ctrl, sensors=m.sensors, seed=seed)
    measured = np.array([h[1] for h in ctrl.history]) / plant.backlash
    print(f"\n{model}: {measured.size} measurements, {measured.min():.3f}-{measured.max():.3f} b, "
          f"ISO A {res.stats['accuracy'] * 1e6:.0f} urad")
    assert measured.size >= 5
    off = np.flatnonzero(np.abs(measured - 1.0) > 0.05)
    assert off.size <= (0 if model == "shing1993_servo_friction" else 1)
    assert np.all(off < 2)  # only while learning, within the first two windows
    assert abs(ctrl.backlash / plant.backlash - 1.0) <= 0.01
    assert res.stats["accuracy"] <= (20e-6 if model == "shing1993_servo_friction" else 600e-6)


def test_adaptive_positions_like_the_fixed_inverse_with_load_friction() -> None:
    # ISO 230-2 on shing1993_servo_friction, estimate right: the adaptive inverse A = 14.4 urad, the fixed inverse
    # 14.2 (the adaptive gave 257 while the start-up's half gap was taken for the gap); kept within 1.5x
    from gearctl.precision import precision_test

    m = load_model("shing1993_servo_friction")
    plant = build_plant(m)
    A = {}
    for name in ("adaptive_inverse", "deadzone_inverse"):
        res = precision_test(plant, load_controller(name, plant, sensors=m.sensors), sensors=m.sensors)
        A[name] = res.stats["accuracy"]
    print(f"\nISO A: adaptive {A['adaptive_inverse'] * 1e6:.1f}, fixed {A['deadzone_inverse'] * 1e6:.1f} urad")
    assert A["adaptive_inverse"] <= 1.5 * A["deadzone_inverse"]


def test_encoders_too_coarse_for_the_gap_are_noted_at_design() -> None:
    # tests/data/coarse_noisy_4096.toml: 4096-count encoders with 2e-4 rad of noise read s to 2.1 b along the line
    # of action (measured readings 1.2-1.8 b, the estimate ending 1.74 b): the design says so; the catalog servo's
    # 2^20-count encoders (0.006 b) give no note
    from gearctl.design.adaptive import READING_SHARE, reading_resolution

    for path, noted in ((Path(__file__).parent / "data" / "coarse_noisy_4096.toml", True), ("shing1993_servo", False)):
        m = load_model(path)
        plant = build_plant(m)
        ctrl = load_controller("adaptive_inverse", plant, sensors=m.sensors)
        info = ctrl.inner.pid.info
        s = m.sensors
        by_hand = sum(rb * (math.pi / cpr + 3.0 * noise) for rb, cpr, noise in (
            (info.plant.rb1, s.motor_encoder_cpr, s.motor_noise), (info.plant.rb2, s.load_encoder_cpr, s.load_noise)))
        assert reading_resolution(info, s) == pytest.approx(by_hand, rel=1e-12)
        notes = [n for n in ctrl.describe()["design_notes"] if n.startswith("adaptation:")]
        assert bool(notes) is noted, notes
        assert (by_hand > READING_SHARE * plant.backlash) is noted
