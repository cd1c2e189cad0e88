"""h6's review of the session's changes: each test failed before its fix.

Oracles: the same run with the reference given two equivalent ways; the documented behaviour of the functions.
"""

from __future__ import annotations

import numpy as np
import pytest

from gearctl.catalog import load_controller, load_model
from gearctl.closedloop import simulate_closed_loop
from gearctl.plant import build_plant


class _Step:
    """A 2 rad step at 50 ms; ``scalar``: its (zero) speed and acceleration given as scalars."""

    def __init__(self, scalar: bool) -> None:
        self.scalar = scalar

    def at(self, t):
        t = np.asarray(t, dtype=float)
        r = np.where(t >= 0.05, 2.0, 0.0)
        if self.scalar:
            return r, 0.0, 0.0
        return r, np.zeros_like(t), np.zeros_like(t)

    def load_disturbance(self, t: float) -> float:
        return 0.0


def test_mpc_takes_a_reference_whose_constant_parts_are_scalars() -> None:
    # the governor's test indexed r'' sample by sample: a ReferenceLike whose at() gives 0.0 for a resting
    # reference's speed and acceleration (as PID and inverse take it, and the MPC did before the governor) raised
    # IndexError: too many indices for array
    m = load_model("shing1993_servo")
    sp = build_plant(m)
    c = load_controller("mpc", sp, sensors=m.sensors)
    a = simulate_closed_loop(sp, c, _Step(scalar=False), 0.15, sensors=m.sensors)
    b = simulate_closed_loop(sp, c, _Step(scalar=True), 0.15, sensors=m.sensors)
    np.testing.assert_array_equal(a.command, b.command)


def test_chattering_warning_without_a_torque_limit_names_the_scale_it_used() -> None:
    # torque_chatter measures a plant without a torque limit against the run's largest torque, but the warning read
    # "by more than 5% of its inf N m limit each way"
    import dataclasses

    from gearctl.metrics import loop_health
    from gearctl.references import reference

    m = load_model("shing1993_servo")
    sp = build_plant(m)
    run = simulate_closed_loop(sp, load_controller("pid", sp, sensors=m.sensors), reference("sine"), 0.2,
                               sensors=m.sensors)
    saw = run.torque + 0.3 * (-1.0) ** np.arange(run.torque.size)
    unlimited = dataclasses.replace(sp, torque_limit=np.inf)
    health = loop_health(dataclasses.replace(run, torque=saw, plant=unlimited))
    assert health.chattering
    (line,) = [w for w in health.warnings if w.startswith("chattering")]
    assert "inf" not in line
    assert f"{np.max(np.abs(saw)):.3g} N m (no torque limit)" in line


def test_mpc_names_a_reference_whose_parts_have_the_wrong_shape() -> None:
    # a column (n, 1) where the times are (n,): numpy's 'operands could not be broadcast' escaped from the preview
    import pytest

    from gearctl.errors import InputError

    class Column(_Step):
        def at(self, t):
            r, rd, rdd = super().at(t)
            return r, rd[:, None], rdd

    m = load_model("shing1993_servo")
    sp = build_plant(m)
    c = load_controller("mpc", sp, sensors=m.sensors)
    with pytest.raises(InputError, match=r"reference: at\(t\) of \d+ times gave .* shapes .*\(\d+, 1\)"):
        simulate_closed_loop(sp, c, Column(scalar=False), 0.05, sensors=m.sensors)


@pytest.mark.parametrize("ctrl", ["pid", "mpc"])
def test_a_reference_not_finite_is_named_before_the_run(ctrl: str) -> None:
    """A user's reference with NaN from 0.3 s on: the PID ran on NaN commands (zero torque, each a fallback) and the
    MPC stopped on "QP data rejected", neither naming the reference (h6's review). Now an InputError naming it, the
    first time and the values, before the run."""
    from gearctl import InputError, build_plant, load_model
    from gearctl.catalog import load_controller
    from gearctl.closedloop import simulate_closed_loop
    from gearctl.references import reference

    plant = build_plant(load_model("shing1993_servo"))
    base = reference("sine")

    class Holed:
        settle = 0.0

        def at(self, t):  # noqa: ANN001, ANN202
            r, rd, rdd = base.at(t)
            return np.where(np.asarray(t) > 0.3, np.nan, r), rd, rdd

        def load_disturbance(self, t: float) -> float:
            return 0.0

    with pytest.raises(InputError, match=r"^reference: not finite at t = 0\.301 s: \(r, r', r''\) = \(nan, ") as err:
        simulate_closed_loop(plant, load_controller(ctrl, plant), Holed(), 0.5)
    assert err.value.field == "reference" and "and at 199 more samples" in str(err.value)
