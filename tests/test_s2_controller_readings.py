"""The PID family's step refuses a reading or reference value that is not finite (InputError naming it, state
unchanged); one NaN reading used to make every later torque NaN. The adaptive inverse takes a bad load reading,
which it reads only to measure the gap, as a missing one (as the exported C API: GEARCTL_STEP_FALLBACK)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import gearctl
from gearctl import InputError

FAMILY = ["pid", "reversal_offset", "deadzone_inverse", "adaptive_inverse", "pid_load"]


@pytest.fixture(scope="module")
def servo() -> gearctl.Plant:
    return gearctl.build_plant(gearctl.load_model("shing1993_servo"))


def _readings(k: int) -> tuple[float, float]:
    """Motor and load angles of a loop following the sine roughly (the values only need to vary) [rad]."""
    r = 0.1 * math.sin(2 * math.pi * k * 1e-3)
    return 4.0 * r + 1e-4 * math.cos(k), r - 2e-5 * math.sin(k)


def _torques(ctrl, skip: int | None, bad: float | None, field: str) -> list[float]:  # noqa: ANN001
    ref = gearctl.reference("sine")
    ctrl.reset()
    out = []
    for k in range(40):
        ym, yl = _readings(k)
        yl_arg = yl if ctrl.uses_load_encoder else None
        if k == skip:
            if bad is None:
                continue
            args = (bad, yl_arg) if field == "y_motor" else (ym, bad)
            with pytest.raises(InputError, match=rf"^{field} = nan at t = 0\.01 s: expected a finite number") as err:
                ctrl.step(k * 1e-3, *args, ref)
            assert err.value.field == field
            continue
        out.append(ctrl.step(k * 1e-3, ym, yl_arg, ref))
    return out


@pytest.mark.parametrize("name", FAMILY)
def test_a_nan_motor_reading_is_named_and_changes_nothing(servo, name) -> None:  # noqa: ANN001
    ctrl = gearctl.load_controller(name, servo)
    got = _torques(ctrl, 10, math.nan, "y_motor")
    # oracle: the same controller, fresh, never shown the bad sample
    want = _torques(gearctl.load_controller(name, servo), 10, None, "y_motor")
    assert all(math.isfinite(u) for u in got)  # before: nan from sample 10 on, for good
    np.testing.assert_array_equal(got, want)


def test_load_feedback_names_a_nan_or_absent_load_reading(servo) -> None:  # noqa: ANN001
    ctrl = gearctl.load_controller("pid_load", servo)
    got = _torques(ctrl, 10, math.nan, "y_load")
    np.testing.assert_array_equal(got, _torques(gearctl.load_controller("pid_load", servo), 10, None, "y_load"))
    with pytest.raises(InputError, match=r"^y_load = None at t = 0\.0 s") as err:  # was TypeError from float(None)
        ctrl.step(0.0, 0.0, None, gearctl.reference("sine"))
    assert err.value.field == "y_load"


@pytest.mark.parametrize("bad", [math.nan, math.inf, 1e13])
def test_adaptive_inverse_takes_a_bad_load_reading_as_missing(servo, bad) -> None:  # noqa: ANN001
    # the exported C passes such a y[1] on as missing (no gap measured) and returns GEARCTL_STEP_FALLBACK
    ref = gearctl.reference("sine")
    a, b = (gearctl.load_controller("adaptive_inverse", servo) for _ in range(2))
    a.reset()
    b.reset()
    for k in range(40):
        ym, yl = _readings(k)
        ua = a.step(k * 1e-3, ym, bad if k == 10 else yl, ref)
        ub = b.step(k * 1e-3, ym, None if k == 10 else yl, ref)
        assert ua == ub and math.isfinite(ua)
    assert [f["t"] for f in a.fallbacks] == [0.01] and "load reading missing" in a.fallbacks[0]["reason"]
    assert b.fallbacks == []


class _NanAt:
    """A user's reference that is NaN at one time (its speed)."""

    def __init__(self, t_bad: float) -> None:
        self.t_bad, self.inner = t_bad, gearctl.reference("sine")

    def at(self, t: float) -> tuple[float, float, float]:
        r, rd, rdd = self.inner.at(t)
        return (r, math.nan if abs(t - self.t_bad) < 1e-12 else rd, rdd)

    def load_disturbance(self, t: float) -> float:
        return 0.0


@pytest.mark.parametrize("name", FAMILY)
def test_a_nan_reference_value_is_named(servo, name) -> None:  # noqa: ANN001
    ctrl = gearctl.load_controller(name, servo)
    ctrl.reset()
    ref = _NanAt(0.002)
    for k in range(2):
        ym, yl = _readings(k)
        ctrl.step(k * 1e-3, ym, yl if ctrl.uses_load_encoder else None, ref)
    ym, yl = _readings(2)
    with pytest.raises(InputError, match=r"^ref\.at\(t\)\[1\] = nan at t = 0\.002 s: .*\[rad/s\]") as err:
        ctrl.step(0.002, ym, yl if ctrl.uses_load_encoder else None, ref)
    assert err.value.field == "ref"
