"""``identify`` on models with a constant load torque ([servo] load_torque, added to the load shaft's balance).

Oracle: known truth. Logs are recorded by gearctl's own ``excite`` (10 s, the ``identify`` motion) from the model that
is then given to ``identify``, so every quantity has a true value: b inside its 95 % interval with both encoders and
with the motor encoder alone (or named not identified, with the reason), the inertias and frictions inside their
intervals or flagged. The model without a load torque gives the figures it gave before the load torque entered the
balances (measured then, to the last digit).

Two servos:

- ``detc1992_21x29_25deg`` (N = 1.38, b = 100 um, 2^18-count encoders) with a load Coulomb friction of 0.05 N m and a
  load torque close to it (h3's case): the load coasts through the gap one way, hardly decelerating;
- ``shing1993_servo_friction`` (N = 4, 0.2 N m of load friction) with 0.1 N m of load torque.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from gearctl import InputError, build_plant, load_model
from gearctl import identify as ident
from gearctl.catalog import GearModel
from gearctl.excite import record_excitation
from gearctl.identify import Identification, identify, write_log

DETC = dict(backlash=1e-4, motor_inertia=3e-4, load_inertia=2e-3, viscous_friction1=2e-4, viscous_friction2=1e-3,
            coulomb_friction1=0.005, coulomb_friction2=0.05, torque_limit=2.0, motor_encoder_cpr=262144,
            load_encoder_cpr=262144)
TRUTH_KEYS = (("J1", "inertia"), ("J2", "inertia"), ("viscous1", "friction"), ("viscous2", "friction"),
              ("coulomb1", "friction"), ("coulomb2", "friction"))


def _detc(load_torque: float) -> GearModel:
    return load_model("detc1992_21x29_25deg", **DETC, load_torque=load_torque)


@pytest.fixture(scope="module")
def log_of(tmp_path_factory: pytest.TempPathFactory) -> Callable[[str, GearModel], Path]:
    folder = tmp_path_factory.mktemp("tl_logs")
    made: dict[str, Path] = {}

    def get(name: str, model: GearModel) -> Path:
        if name not in made:
            path = folder / f"{name}.csv"
            write_log(path, record_excitation(model, motion="identify", duration=10.0, seed=0).log)
            made[name] = path
        return made[name]

    return get


def _truth(model: GearModel) -> dict[str, float]:
    p = build_plant(model)
    return {"backlash": p.backlash, "J1": p.J1, "J2": p.J2, "viscous1": p.d1, "viscous2": p.d2, "coulomb1": p.tc1,
            "coulomb2": p.tc2}


def _check_honest(res: Identification, truth: dict[str, float]) -> None:
    """Every quantity inside its interval, or named not identified (with a reason)."""
    lo, hi = res.backlash_ci
    assert "backlash" in res.not_identified or lo <= truth["backlash"] <= hi, (lo, truth["backlash"], hi)
    for key, table in TRUTH_KEYS:
        lo, hi = getattr(res, f"{table}_ci")[key]
        ok = lo <= truth[key] <= hi or key in res.not_identified
        assert ok, (key, getattr(res, table)[key], (lo, hi), truth[key], res.not_identified)
    assert all(res.not_identified.values())


@pytest.mark.parametrize("load_torque", [0.045, -0.045])
def test_a_load_torque_near_the_load_friction_with_both_encoders(log_of: Callable[[str, GearModel], Path],
                                                                  load_torque: float) -> None:
    # before the load torque entered the balances: b 97.5 um, J2 and both frictions of the load not identified
    # (T_c2 2e-18 against 0.05 N m), 0.02 rad misfit; with the balances alone the log was refused ("no rest on the
    # front flank") or J2 went to its bound. Measured now: b 98.4 um [95.4, 101.4], T_c2 0.0500 [0.0474, 0.0525]
    model = _detc(load_torque)
    truth = _truth(model)
    res = identify(log_of(f"detc_{load_torque:g}", model), model)
    _check_honest(res, truth)
    assert "backlash" not in res.not_identified and abs(res.backlash / truth["backlash"] - 1) < 0.03
    lo, hi = res.friction_ci["coulomb2"]
    assert "coulomb2" not in res.not_identified and lo <= 0.05 <= hi and hi - lo < 0.01
    assert res.rms_residual < 1e-3  # the re-simulation with the load torque fits (0.02 rad before)


@pytest.mark.parametrize("load_torque", [0.045, -0.045])
def test_a_load_torque_near_the_load_friction_with_the_motor_encoder(log_of: Callable[[str, GearModel], Path],
                                                                      load_torque: float) -> None:
    # the load coasts through the gap one way: how the Coulomb friction splits between the shafts moves the motor's
    # crossings by tens of um, and b from the motor alone is named not identified (measured: 58 and 81 um, with the
    # misfit and the crossings' disagreement as the reasons); whatever is reported is honest
    model = _detc(load_torque)
    res = identify(log_of(f"detc_{load_torque:g}", model), model, encoders="motor")
    _check_honest(res, _truth(model))


def test_a_load_torque_below_the_load_friction_identifies_everything(log_of: Callable[[str, GearModel], Path]) -> None:
    # shing1993_servo_friction with 0.1 N m of load torque: before, J1, J2 and both Coulomb frictions were flagged
    # (the re-simulation missed by 0.7 mrad) with both encoders, and b from the motor alone was not identified
    model = load_model("shing1993_servo_friction", load_torque=0.1)
    truth = _truth(model)
    path = log_of("shing_0.1", model)
    both = identify(path, model)
    _check_honest(both, truth)
    for key, table in (("J1", "inertia"), ("J2", "inertia"), ("coulomb2", "friction")):
        assert key not in both.not_identified
        lo, hi = getattr(both, f"{table}_ci")[key]
        assert lo <= truth[key] <= hi and hi - lo < 0.15 * truth[key]  # (a floor of 5 % for a Coulomb friction)
    motor = identify(path, model, encoders="motor")
    _check_honest(motor, truth)
    assert "backlash" not in motor.not_identified and abs(motor.backlash / truth["backlash"] - 1) < 0.05


def test_a_fitted_inertia_at_its_bound_under_a_load_torque_is_flagged_not_refused(
        log_of: Callable[[str, GearModel], Path], monkeypatch: pytest.MonkeyPatch) -> None:
    # the guard behind the noise floor: without it (the floor switched off here) the load's free flights are met by
    # its friction alone, J2 goes to its bound and J1 takes J1 + J2/N^2; the flank rests are then read with the
    # model's inertias (the log was refused for want of a rest on the front flank), and the load's friction is named
    # not identified (T_c2 came out 0.045, the load torque, against 0.05)
    model = _detc(0.045)
    regress = ident._regress
    monkeypatch.setattr(ident, "_regress",
                        lambda blocks, mean, sd, lower, floors=None: regress(blocks, mean, sd, lower))
    res = identify(log_of("detc_0.045", model), model)
    truth = _truth(model)
    _check_honest(res, truth)
    assert {"J1", "J2", "viscous2", "coulomb2"} <= set(res.not_identified)
    assert "backlash" not in res.not_identified and abs(res.backlash / truth["backlash"] - 1) < 0.05


def test_without_a_load_torque_the_figures_are_unchanged(log_of: Callable[[str, GearModel], Path]) -> None:
    # the same servo with load_torque = 0: the figures identify gave before the load torque entered the balances
    model = _detc(0.0)
    path = log_of("detc_0", model)
    both = identify(path, model)
    assert both.backlash == pytest.approx(9.997027646828469e-05, rel=1e-9)
    # (r4: the difference from b compared at the same load angles, in quadrature, widened it by 0.07 nm)
    assert both.backlash_ci == pytest.approx((9.829949705487312e-05, 0.00010164105588169625), rel=1e-9)
    assert both.inertia["J1"] == pytest.approx(0.0005263894493054344, rel=1e-9)
    assert both.inertia["J2"] == pytest.approx(0.003712190376186762, rel=1e-9)
    assert both.friction["coulomb2"] == pytest.approx(0.04943027986064954, rel=1e-9)
    motor = identify(path, model, encoders="motor")
    assert motor.backlash == pytest.approx(9.780550477140189e-05, rel=1e-9)
    # its interval was [76.2, 119.4] um; the re-simulation's misfit (20.5 um RMS, 21 % of b) now enters as 1.96 times
    # it (h2's review: an RMS against 95 % half-widths), a half-width of 40.8 um, beyond a third of b
    assert "backlash" in motor.not_identified


def test_a_load_torque_above_the_load_friction_is_named_in_the_refusal(
        log_of: Callable[[str, GearModel], Path]) -> None:
    # with 0.1 N m of load torque against 0.05 N m of friction the load stays on one flank wherever the motor does not
    # push it across: too few crossings, and the refusal blamed a loop that hunts or a low sample rate
    model = _detc(0.1)
    with pytest.raises(InputError) as exc:
        identify(log_of("detc_tl100", model), model)
    msg = str(exc.value)
    assert "the model's load_torque (0.1 N m) exceeds the load's Coulomb friction (0.05 N m)" in msg
    assert "never rested on a flank" not in msg
    # the load leaves the flank the load torque holds it on only where the motor runs ahead of it in the load torque's
    # direction faster than the load falls freely, (T_L - T_c2) / J2 (the load's balance J2 theta2'' = T_L - T_c2 at
    # rest or moving with T_L); against T_L the load torque and the friction both brake it and it stays on that flank
    J2 = build_plant(model).J2
    assert f"(|load_torque| - friction) / J2 = {(0.1 - 0.05) / J2:.3g} rad/s^2" in msg
    assert "in the load torque's direction (increasing theta2" in msg


def test_a_negative_load_torque_above_the_load_friction_names_its_direction(
        log_of: Callable[[str, GearModel], Path]) -> None:
    model = _detc(0.1)
    neg = _detc(-0.1)  # the same log, identified against a model whose load torque points the other way
    with pytest.raises(InputError) as exc:
        identify(log_of("detc_tl100", model), neg)
    msg = str(exc.value)
    assert "load_torque (-0.1 N m) exceeds the load's Coulomb friction (0.05 N m) in size" in msg
    assert "in the load torque's direction (decreasing theta2" in msg
