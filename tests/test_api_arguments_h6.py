"""Argument errors a script writer met (review h6): each one an ``InputError`` naming the argument, where it was an
``IndexError``, ``TypeError``, ``ZeroDivisionError``, ``AttributeError`` or a bare ``KeyError`` from inside, or a
silently wrong answer."""

from __future__ import annotations

import numpy as np
import pytest

import gearctl
from gearctl import InputError


@pytest.fixture(scope="module")
def servo():  # noqa: ANN201
    model = gearctl.load_model("shing1993_servo")
    plant = gearctl.build_plant(model)
    return model, plant, gearctl.load_controller("pid", plant)


@pytest.fixture(scope="module")
def train():  # noqa: ANN201
    return gearctl.build_plant(gearctl.load_model("servo_3stage_quanser_srv02"))


@pytest.mark.parametrize("i", [3, -1, 1.0, True])
def test_stage_m_eq_and_stiffness_at_refuse_a_stage_that_is_none(train, i) -> None:  # noqa: ANN001
    # -1 paired the last stage with the motor shaft (shafts[0]) and returned a wrong mass without a word
    with pytest.raises(InputError, match=r"^i = .* expected a stage index from 0 to 2") as err:
        train.stage_m_eq(i)
    assert err.value.field == "i"
    with pytest.raises(InputError, match=r"^stage = .* expected a stage index from 0 to 2") as err:
        train.stiffness_at(0.0, stage=i)
    assert err.value.field == "stage"
    assert train.stage_m_eq(2) > 0 and train.stiffness_at(0.0, stage=2) == train.stages[2].k


@pytest.mark.parametrize("method", ["gaps", "gap_rates", "relative_displacement", "energy"])
def test_state_methods_refuse_a_state_of_another_shape(servo, method) -> None:  # noqa: ANN001
    _, plant, _ = servo
    for x in (np.zeros(2), np.zeros(3), np.zeros((6, 5)), 0.0, ["a", "b", "c", "d"]):
        with pytest.raises(InputError, match=r"^x has .*expected states of shape \(4, \.\.\.\)") as err:
            getattr(plant, method)(x)
        assert err.value.field == "x"
    assert np.shape(getattr(plant, method)(np.zeros((4, 7))))[-1] == 7


def test_mode_of_on_a_train_needs_one_row_per_stage(train) -> None:  # noqa: ANN001
    with pytest.raises(InputError, match=r"^s has shape \(2,\): expected one row per stage \(3, \.\.\.\)"):
        train.mode_of(np.zeros(2))
    assert train.mode_of(np.zeros((3, 4))).shape == (3, 4)


def test_report_case_names_a_speed_that_is_not_a_number(servo) -> None:  # noqa: ANN001
    from gearctl.simulate import report_case

    _, plant, _ = servo
    for key in ("omega1", "omega2", "torque1", "torque2"):
        with pytest.raises(InputError, match=rf"^{key} = 'x' must be a finite number") as err:
            report_case(plant, "free", 0.001, **{key: "x"})
        assert err.value.field == key


@pytest.mark.parametrize("rtol", [-1.0, 0.0, 1.0, "1e-9"])
def test_simulate_refuses_a_tolerance_out_of_range(servo, rtol) -> None:  # noqa: ANN001
    from gearctl.simulate import simulate

    _, plant, _ = servo
    with pytest.raises(InputError, match=r"^rtol = ") as err:
        simulate(plant, np.zeros(4), 0.001, rtol=rtol)
    assert err.value.field == "rtol"


def test_progress_that_is_not_callable_is_named(servo) -> None:  # noqa: ANN001
    from gearctl.simulate import simulate

    _, plant, ctrl = servo
    with pytest.raises(InputError, match=r"^progress = 5 is not callable") as err:
        gearctl.simulate_closed_loop(plant, ctrl, gearctl.reference("sine"), 0.01, progress=5)
    assert err.value.field == "progress"
    with pytest.raises(InputError, match=r"^progress = 'bar' is not callable"):
        simulate(plant, np.zeros(4), 0.001, progress="bar")


def test_closed_loop_names_an_initial_state_that_is_not_numbers(servo) -> None:  # noqa: ANN001
    _, plant, ctrl = servo
    with pytest.raises(InputError, match=r"^x0 = .* is not an initial state") as err:
        gearctl.simulate_closed_loop(plant, ctrl, gearctl.reference("sine"), 0.01, x0="abcd")
    assert err.value.field == "x0"
    run = gearctl.simulate_closed_loop(plant, ctrl, gearctl.reference("sine"), 0.01, x0=[1e-5, 0, 0, 0])
    assert run.x[0, 0] == 1e-5


@pytest.mark.parametrize("Ts", [0, -1e-3, 2.0, "1e-3"])
def test_pid_sampled_tf_refuses_a_sample_period_out_of_range(servo, Ts) -> None:  # noqa: ANN001
    _, _, ctrl = servo
    with pytest.raises(InputError, match=r"^Ts = ") as err:
        ctrl.gains.sampled_tf(Ts)
    assert err.value.field == "Ts"
    assert ctrl.gains.sampled_tf(1e-3).dt == 1e-3


def test_execute_refuses_what_is_not_a_run() -> None:
    with pytest.raises(InputError, match=r"^run = None is not a Run: expected gearctl.make_run") as err:
        gearctl.execute(None)
    assert err.value.field == "run"


def test_metrics_unknown_key_is_named_and_still_a_key_error(servo) -> None:  # noqa: ANN001
    _, plant, ctrl = servo
    m = gearctl.tracking_metrics(gearctl.simulate_closed_loop(plant, ctrl, gearctl.reference("sine"), 0.05))
    with pytest.raises(InputError, match=r"^'rms' is not a figure of TrackingMetrics: .*did you mean 'rms_error'\?$"):
        m["rms"]
    with pytest.raises(KeyError):
        m["rms"]
    assert m.get("rms") is None and m["rms_error"] == m.rms_error and "rms" not in m.keys()


@pytest.mark.parametrize("key", ["backlash", "stage1.backlash"])
def test_make_run_refuses_backlash_beside_a_backlash_override(key: str) -> None:
    """``make_run(backlash=1e-5, overrides={"backlash": 2e-5})`` built the 10 um plant: the backlash, applied after the
    overrides, dropped theirs without a word (the command line refuses the same pair of options)."""
    from gearctl.runs import make_run

    with pytest.raises(InputError, match=r"backlash = 1e-05 and overrides\[.*backlash"):
        make_run("shing1993_servo", "pid", backlash=1e-5, overrides={key: 2e-5})
    # either alone is taken
    assert make_run("shing1993_servo", "pid", backlash=1e-5).plant.backlash == 1e-5
    assert make_run("shing1993_servo", "pid", overrides={"backlash": 2e-5}).plant.backlash == 2e-5
