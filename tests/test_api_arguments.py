"""Argument errors of the Python API a script writer meets: one ``InputError`` naming the argument, not a
``TypeError`` or ``AttributeError`` from deep inside."""

from __future__ import annotations

import pytest

import gearctl
from gearctl import InputError


@pytest.fixture(scope="module")
def servo():  # noqa: ANN201
    model = gearctl.load_model("shing1993_servo")
    plant = gearctl.build_plant(model)
    return model, plant, gearctl.load_controller("pid", plant)


def test_reference_unknown_setting_is_named() -> None:
    with pytest.raises(InputError, match=r"amplitud .*did you mean 'amplitude'") as err:
        gearctl.reference("sine", amplitud=0.1)
    assert err.value.field == "amplitud"
    assert gearctl.reference("move", amplitude=0.3, profile="trapezoid").amplitude == 0.3
