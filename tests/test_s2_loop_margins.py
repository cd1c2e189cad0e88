"""loop_margins gives a phase margin in (-180, 180] deg: an unstable type-2 loop reads negative, not ~+355 deg."""

from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest

import gearctl
from gearctl.design.pid import PIDGains


@pytest.mark.parametrize("pole", [3.0, 10.0, 100.0])
def test_type2_loop_past_minus_180_has_a_negative_phase_margin(pole: float) -> None:
    # L = K / (s^2 (s / p + 1)) with |L(j)| = 1: the phase at the crossover w = 1 is -180 - atan(1 / p) deg, so the
    # phase margin is -atan(1 / p) (closed form) and the closed loop is unstable (Routh: s^3 / p + s^2 + K).
    s = ct.tf("s")
    K = math.sqrt(1.0 + 1.0 / pole**2)
    L = K / (s**2 * (s / pole + 1))
    pm = -math.degrees(math.atan(1.0 / pole))
    m = gearctl.loop_margins(L, omega=np.logspace(-2, 3, 20000))
    # 2000 points per decade: within 0.05 deg of the closed form (we see 0.002 deg)
    assert abs(m["phase_margin"] - pm) < 0.05
    assert np.max(ct.feedback(L, 1).poles().real) > 0.0  # the margin's sign says what the closed loop does


def test_sampled_servo_loop_unstable_reads_as_python_control_frd() -> None:
    # a PID whose integral zero sits at 5x the crossover (beyond the design's range 0..1, typed by hand) on the
    # sampled shing1993_servo contact model: the closed loop has a pole outside the unit circle, and the phase
    # margin was reported as +357.75 deg (python-control's frequency-response margins: -2.245 deg)
    servo = gearctl.build_plant(gearctl.load_model("shing1993_servo"))
    Ts = 1e-3
    G = ct.c2d(ct.ss(gearctl.linearize_modes(servo).contact[0, 0]) / servo.gear_ratio, Ts, "zoh")
    gains = PIDGains(kp=52.90, ki=575.93, kd=0.04654, derivative_filter_hz=228.60)
    L = ct.ss(gains.sampled_tf(Ts)) * G
    assert np.max(np.abs(ct.feedback(L, 1).poles())) > 1.0
    frd_pm = ct.stability_margins(ct.frd(L, np.logspace(-2, math.log10(0.999 * math.pi / Ts), 20000)))[1]
    m = gearctl.loop_margins(L)
    assert -180.0 < m["phase_margin"] < 0.0
    assert abs(m["phase_margin"] - frd_pm) < 0.05
