"""Public functions name a bad argument (s4's review). The move functions: a zero velocity or acceleration was a
ZeroDivisionError, and an unknown profile was timed as a trapezoid by move_times and drawn as an S-curve by
move_point, a move that did not end where it was timed to. loop_health(None) and loop_frequency_response("x") were
AttributeErrors."""

from __future__ import annotations

import math

import pytest

from gearctl import InputError
from gearctl.describe import loop_frequency_response
from gearctl.metrics import loop_health
from gearctl.references import move_point, move_times


@pytest.mark.parametrize(("args", "field"), [((1.0, 0.0, 1.0), "velocity"), ((1.0, 1.0, 0.0), "accel"),
                                             ((1.0, -1.0, 1.0), "velocity"), ((1.0, math.nan, 1.0), "velocity"),
                                             ((1.0, 1.0, math.inf), "accel"), ((1.0, "1", 1.0), "velocity")])
def test_bad_velocity_or_accel_is_named(args: tuple, field: str) -> None:
    for fn, a in ((move_times, args), (move_point, (0.1, *args))):
        with pytest.raises(InputError) as exc:
            fn(*a)
        assert exc.value.field == field and "expected a finite number > 0" in str(exc.value)


def test_unknown_profile_is_named() -> None:
    with pytest.raises(InputError, match="profile = 'foo': expected one of s-curve, trapezoid"):
        move_times(1.0, 1.0, 2.0, "foo")
    with pytest.raises(InputError, match="profile"):
        move_point(0.3, 1.0, 1.0, 2.0, "foo")


@pytest.mark.parametrize("profile", ["s-curve", "trapezoid"])
def test_a_move_ends_where_it_is_timed_to(profile: str) -> None:
    ta, tc, v = move_times(1.0, 1.0, 2.0, profile)
    T = 2 * ta + tc
    assert move_point(T * (1 - 1e-12), 1.0, 1.0, 2.0, profile)[0] == pytest.approx(1.0, abs=1e-9)
    assert move_point(0.5 * T, 1.0, 1.0, 2.0, profile)[0] == pytest.approx(0.5, abs=1e-12)  # symmetric


def test_loop_health_and_the_loop_response_name_their_first_argument() -> None:
    with pytest.raises(InputError) as exc:
        loop_health(None)  # type: ignore[arg-type]
    assert exc.value.field == "res"
    with pytest.raises(InputError, match="'x' is not a Plant"):
        loop_frequency_response("x", None, [1.0])  # type: ignore[arg-type]


def test_the_adaptive_inverse_names_what_it_wraps() -> None:
    from gearctl.design.adaptive import AdaptiveInverse

    with pytest.raises(InputError) as exc:
        AdaptiveInverse(object())  # type: ignore[arg-type]
    assert exc.value.field == "inverse"
