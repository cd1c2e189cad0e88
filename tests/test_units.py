"""The parameter schema (gearctl/units.py): physical floors, and one range per quantity wherever it is checked.

Oracles: the rule each spec states (its text is what the user reads: the range, the unit, the floor), and
the identity of the checks (the Python API and the CLI refuse the same values with the same words).
"""

from __future__ import annotations

import dataclasses
import math

import pytest

from gearctl import InputError, load_model, mesh_stiffness, tooth_deflections
from gearctl.cli import main
from gearctl.cli.common import POINTS as CLI_POINTS
from gearctl.params import Servo
from gearctl.units import (
    BACKLASH,
    BACKLASH_FLOOR,
    FACE_WIDTH,
    MODULE,
    POINTS,
    TORQUE_LIMIT,
    Spec,
    describe_rule,
)


@pytest.fixture(scope="module")
def pair():
    return load_model("shing1993").pair


# --- floors: 0 means none, anything else is at least the floor ---------------------------------------------


def test_backlash_is_zero_or_at_least_a_nanometre() -> None:
    assert BACKLASH_FLOOR == 1e-9
    assert BACKLASH.check("backlash", 0.0) == 0.0  # the backlash-free train
    assert BACKLASH.check("backlash", 1e-9) == 1e-9
    for bad in (1e-124, 5e-324, 0.999e-9, -1e-9, 0.01, math.nan):
        with pytest.raises(InputError) as exc:
            BACKLASH.check("backlash", bad)
        assert exc.value.field == "backlash"
        assert str(exc.value) == f"backlash = {bad!r} is out of range: expected {BACKLASH.rule()}"
    # the rule keeps the range first (as before the floor), then says the floor, with its unit
    assert BACKLASH.rule() == "0 <= value < 0.01 [m], either 0 or at least 1e-09 [m]"


def test_gear_pair_backlash_has_the_floor(pair) -> None:
    assert dataclasses.replace(pair, backlash=0.0).backlash == 0.0
    with pytest.raises(InputError, match=r"backlash = 1e-124 is out of range: expected 0 <= value < 0\.01 \[m\], "
                                         r"either 0 or at least 1e-09 \[m\]"):
        dataclasses.replace(pair, backlash=1e-124)
    with pytest.raises(InputError, match="backlash"):
        load_model("shing1993", backlash=1e-12)


def test_floors_of_module_face_width_and_torque_limit(pair) -> None:
    # 10 um modules and face widths (micro gears), 1 uN m torque limits (below the smallest micro motors)
    assert (MODULE.low, FACE_WIDTH.low, TORQUE_LIMIT.low) == (1e-5, 1e-5, 1e-6)
    for field, bad in (("module", 1e-300), ("face_width", 1e-300), ("module", 9e-6), ("face_width", 5e-324)):
        with pytest.raises(InputError) as exc:
            dataclasses.replace(pair, **{field: bad})
        assert exc.value.field == field and "1e-05 <= value" in str(exc.value)
    assert Servo(torque_limit=1e-6).torque_limit == 1e-6
    assert Servo(torque_limit=math.inf).torque_limit == math.inf  # none
    with pytest.raises(InputError, match=r"torque_limit = 1e-300 is out of range: expected 1e-06 <= value <= "
                                         r"1e\+06 \(or inf: none\) \[N m\]"):
        Servo(torque_limit=1e-300)


def test_rule_without_a_floor_is_unchanged() -> None:
    spec = Spec(unit="m", doc="x", low=0.0, high=0.01)
    assert spec.rule() == "0 <= value <= 0.01 [m]"
    assert describe_rule(spec.meta()) == spec.rule()
    assert Spec(unit="1", doc="n", low=2, high=10, integer=True).rule() == "a whole number with 2 <= value <= 10"


# --- points: one range for the CLI's --points and the Python API --------------------------------------------


def test_points_is_one_spec() -> None:
    assert CLI_POINTS is POINTS
    assert (POINTS.low, POINTS.high, POINTS.integer) == (2, 1_000_000, True)


@pytest.mark.parametrize("fn", [mesh_stiffness, tooth_deflections])
@pytest.mark.parametrize("bad", [1, 0, -5, 2.5, 1_000_001, 10**8, math.inf, "401", True])
def test_points_refused_before_any_work(pair, fn, bad) -> None:
    with pytest.raises(InputError) as exc:
        fn(pair, points=bad)
    assert exc.value.field == "points"
    assert POINTS.rule() in str(exc.value)


def test_points_in_range_are_used(pair) -> None:
    assert mesh_stiffness(pair, points=2).K.size == 2
    assert mesh_stiffness(pair, points=1_000).K.size == 1_000
    assert tooth_deflections(pair, points=7).theta1.size == 7


@pytest.mark.parametrize(("key", "bad"), [("harmonics", 0), ("harmonics", 1001), ("order", 1), ("order", 10**6)])
def test_mesh_stiffness_harmonics_and_order_checked(pair, key: str, bad: int) -> None:
    with pytest.raises(InputError) as exc:
        mesh_stiffness(pair, **{key: bad})
    assert exc.value.field == key


def test_cli_and_api_refuse_points_alike(pair, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["stiffness", "shing1993", "--points", "1"]) == 2
    err = capsys.readouterr().err
    with pytest.raises(InputError) as exc:
        mesh_stiffness(pair, points=1)
    assert exc.value.rule in err  # "is out of range: expected a whole number with 2 <= value <= 1e+06"
