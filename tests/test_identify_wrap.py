"""A single-turn encoder that wraps round (a step of whole revolutions that stays) is named under its own column, with
the sample: a wrapping theta1 was refused as "column theta2: ... (a dead load encoder?)", a wrapping theta2 as a
load encoder off the model's ratio."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from gearctl import InputError
from gearctl.identify import identify, read_log

LOG = Path(__file__).resolve().parent / "data" / "logs" / "other_sim_chirp_5khz.csv"


@pytest.mark.parametrize("column", ["theta1", "theta2"])
def test_a_wrapping_encoder_is_named(column: str) -> None:
    log = read_log(LOG)
    v = getattr(log, column).copy()
    v[1234:] -= 2.0 * math.pi
    with pytest.raises(InputError, match=rf"column {column}: sample 1234 .* jumps -6.283 rad \(1 revolution") as exc:
        identify(dataclasses.replace(log, **{column: v}), "shing1993_servo", encoders="motor+load")
    assert exc.value.field == column
    assert len(str(exc.value).splitlines()) == 1


def test_a_wrapped_angle_unwrapped_is_identified() -> None:
    log = read_log(LOG)
    v = np.unwrap(np.mod(log.theta1 - log.theta1[1234] + 1e-3, 2.0 * math.pi))
    res = identify(dataclasses.replace(log, theta1=v), "shing1993_servo", encoders="motor+load")
    assert res.backlash == pytest.approx(5e-5, rel=0.01)


@pytest.mark.parametrize("speed", [60.0, 100.0])
def test_a_turning_motor_encoder_that_wraps_often_is_named(speed: float) -> None:
    # a motor turning back and forth at up to 60 or 100 rad/s, logged at 500 Hz by a single-turn encoder: it wraps in
    # over 1 % of the samples, which made the 99th percentile of the steps a revolution, and each wrap is a revolution
    # less 0.06 .. 0.2 rad, more than 2 % of one: neither was named as a wrap
    from gearctl.identify import EncoderLog

    n, Ts = 5000, 2e-3
    t = np.arange(n) * Ts
    f = 0.2
    angle = speed / (2.0 * math.pi * f) * (1.0 - np.cos(2.0 * math.pi * f * t))
    log = EncoderLog(t=t, torque=0.1 * np.sin(2.0 * math.pi * f * t), theta1=np.mod(angle, 2.0 * math.pi),
                     sample_time=Ts)
    with pytest.raises(InputError, match=r"column theta1: sample \d+ .* revolution\(s\)\) and stays") as exc:
        identify(log, "shing1993_servo", encoders="motor")
    assert exc.value.field == "theta1"
    # unwrapped, the same angle is no wrap
    from gearctl.identify import _check_readings

    _check_readings(dataclasses.replace(log, theta1=angle))
