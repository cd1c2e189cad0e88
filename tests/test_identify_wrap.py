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
