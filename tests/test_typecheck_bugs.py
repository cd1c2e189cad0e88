"""Bugs found by the static type check (mypy on gearctl/): each test fails on the code before its fix."""

from __future__ import annotations

import pytest

from gearctl import InputError, build_plant, load_model
from gearctl.design.base import loop_info


def test_design_pid_names_a_derivative_filter_out_of_range() -> None:
    # design/pid.py: the restated error looked the failing gain up in {kp, ki, kd}; a lead pole above the
    # derivative filter's 1 MHz (a 150 kHz crossover at Ts = 1 us) raised KeyError: 'derivative_filter_hz'
    from gearctl.design.pid import design_pid

    info = loop_info(build_plant(load_model("shing1993_servo")))
    with pytest.raises(InputError, match=r"needs derivative_filter_hz = 1\.\d+e\+06, out of range") as err:
        design_pid(info, bandwidth_hz=1.5e5, Ts=1e-6, integral_ratio=0.001)
    assert err.value.field == "bandwidth_hz"


def test_closed_loop_runs_a_reference_without_a_settle_time() -> None:
    # closedloop.py: simulate_closed_loop accepts any reference with at() and load_disturbance() (what it checks)
    # but read ref.settle when it built the result: AttributeError after the whole run
    from gearctl import load_controller, reference
    from gearctl.closedloop import simulate_closed_loop

    plant = build_plant(load_model("shing1993_servo"))
    inner = reference("sine")

    class OwnReference:
        def at(self, t):
            return inner.at(t)

        def load_disturbance(self, t: float) -> float:
            return 0.0

    res = simulate_closed_loop(plant, load_controller("pid", plant), OwnReference(), 0.05)
    ref = simulate_closed_loop(plant, load_controller("pid", plant), inner, 0.05)
    assert res.success and res.settle == 0.0
    assert (res.torque == ref.torque).all()
