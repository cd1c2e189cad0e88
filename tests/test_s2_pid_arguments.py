"""design_pid, PID and loop_info name a bad argument (InputError) instead of failing deep inside."""

from __future__ import annotations

import pytest

import gearctl
from gearctl import InputError
from gearctl.design import loop_info
from gearctl.design.deadzone import DeadzoneInverse
from gearctl.design.mpc import MPC
from gearctl.design.pid import PID, PIDGains, design_pid
from gearctl.design.reversal import ReversalOffset


@pytest.fixture(scope="module")
def servo() -> gearctl.Plant:
    return gearctl.build_plant(gearctl.load_model("shing1993_servo"))


@pytest.mark.parametrize(("kwargs", "field", "rule"), [
    # Ts = 0 was a ZeroDivisionError; a negative one said "bandwidth_hz ... expected 0 < value < -500"
    ({"Ts": 0.0}, "Ts", r"1e-06 <= value <= 1 \[s\]"),
    ({"Ts": -1e-3}, "Ts", r"1e-06 <= value <= 1 \[s\]"),
    # a string was a TypeError from a comparison
    ({"bandwidth_hz": "20"}, "bandwidth_hz", "not a number"),
    # an integral zero beyond the crossover was designed without a word (5: an unstable loop); -1 blamed ki
    ({"integral_ratio": 5.0}, "integral_ratio", "0 <= value <= 1"),
    ({"integral_ratio": -1.0}, "integral_ratio", "0 <= value <= 1"),
    ({"phase_margin_deg": "50"}, "phase_margin_deg", "not a number"),
])
def test_design_pid_names_a_bad_setting(servo, kwargs, field, rule) -> None:  # noqa: ANN001
    args = {"bandwidth_hz": 20.0, **kwargs}
    with pytest.raises(InputError, match=rf"^{field} = .*{rule}") as err:
        design_pid(loop_info(servo), **args)
    assert err.value.field == field


def test_design_pid_keeps_its_design_for_good_settings(servo) -> None:  # noqa: ANN001
    # the checks change nothing of a valid design: the catalog PID's 20 Hz, 50 deg loop on the sampled model
    gains, margins = design_pid(loop_info(servo), bandwidth_hz=20.0, phase_margin_deg=50.0, Ts=1e-3,
                                integral_ratio=0.1)
    assert gains == gearctl.load_controller("pid", servo).gains
    assert abs(margins["phase_margin"] - 50.0) < 2.0


@pytest.mark.parametrize("what", ["plant", "model"])
def test_design_pid_and_pid_name_info_given_a_plant_or_model(servo, what) -> None:  # noqa: ANN001
    # both were AttributeError: 'Plant' object has no attribute 'N'
    obj = servo if what == "plant" else gearctl.load_model("shing1993_servo")
    with pytest.raises(InputError, match=r"^info = .* is not a LoopInfo: .*loop_info\(") as err:
        design_pid(obj, bandwidth_hz=20.0)
    assert err.value.field == "info"
    gains = PIDGains(kp=10.0)
    with pytest.raises(InputError, match=r"^info = .* is not a LoopInfo") as err:
        PID(obj, gains)
    assert err.value.field == "info"


def test_pid_names_gains_that_are_no_pid_gains(servo) -> None:  # noqa: ANN001
    # a dict of gains was AttributeError: 'dict' object has no attribute 'discrete'
    with pytest.raises(InputError, match=r"^gains = \{'kp': 10.0\} is not a PIDGains") as err:
        PID(loop_info(servo), {"kp": 10.0})
    assert err.value.field == "gains"


def test_loop_info_names_a_gear_model() -> None:
    # was AttributeError: 'GearModel' object has no attribute 'equivalent_pair'
    with pytest.raises(InputError, match=r"^plant = .* is not a Plant: build it first") as err:
        loop_info(gearctl.load_model("shing1993_servo"))
    assert err.value.field == "plant"


@pytest.mark.parametrize(("build", "field"), [
    # the wrappers took anything for their PID: AttributeError 'str' object has no attribute 'info' / 'Ts'
    (lambda info, pid: DeadzoneInverse("pid", backlash=5e-5), "pid"),
    (lambda info, pid: DeadzoneInverse(pid.gains, backlash=5e-5), "pid"),
    (lambda info, pid: ReversalOffset(None, backlash=5e-5), "pid"),
    # a negative rattle-guard floor was taken without a word
    (lambda info, pid: DeadzoneInverse(pid, backlash=5e-5, jump_floor=-1.0), "jump_floor"),
    # the MPC: AttributeError 'Plant' object has no attribute 'plant' / 'dict' object has no attribute 'backlash'
    (lambda info, pid: MPC(info.plant), "info"),
    (lambda info, pid: MPC(info, {"horizon": 10}), "settings"),
    # a string flag was truthy: feedforward="no" ran with feedforward
    (lambda info, pid: PID(info, pid.gains, feedforward="no"), "feedforward"),
    (lambda info, pid: PID(info, pid.gains, friction_feedforward="off"), "friction_feedforward"),
])
def test_controllers_built_in_python_name_a_bad_argument(servo, build, field) -> None:  # noqa: ANN001
    info = loop_info(servo)
    pid = PID(info, design_pid(info, bandwidth_hz=20.0)[0])
    with pytest.raises(InputError, match=rf"^{field} = ") as err:
        build(info, pid)
    assert err.value.field == field
