"""``gearctl simulate`` on a servo whose model carries a constant load torque (r1's review).

The warning that the case's torques exceed what the servo's motor gives compared the case's ``torque2`` alone with
``ratio x torque_limit``; the run applies the model's ``load_torque`` on top of it (the ``torques`` line and the JSON
``torque`` say so). ``tests/data/r1_gravity_motor_coulomb.toml``: 4.5 N m of gravity-like load torque, ratio 5, a
1 N m motor: the load case puts 5.5 N m on the load, more than the 5 N m the motor can hold, and said nothing.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gearctl import build_plant, load_model
from gearctl.cli import main

MODEL = str(Path(__file__).parent / "data" / "r1_gravity_motor_coulomb.toml")


def simulate_json(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[dict, str]:
    code = main(["simulate", MODEL, "--duration", "0.002", *argv, "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "Traceback" not in err
    return json.loads(out), err


def test_load_case_with_the_model_load_torque_beyond_the_motor_is_warned(capsys: pytest.CaptureFixture[str]) -> None:
    plant = build_plant(load_model(MODEL))
    held = plant.gear_ratio * plant.torque_limit
    summary, err = simulate_json(["--case", "load"], capsys)
    on_load = summary["torque"]["load"]
    # the premise, from the model itself: the case's -1 N m alone is within reach, with the load torque it is not
    assert abs(on_load - (-1.0 + plant.load_torque)) < 1e-12
    assert 1.0 < held < abs(on_load)
    assert "exceed what this servo's motor gives" in err
    assert f"{on_load:g} N m with the model's load_torque {plant.load_torque:g}" in err


def test_load_torque_within_reach_is_not_warned(capsys: pytest.CaptureFixture[str]) -> None:
    plant = build_plant(load_model(MODEL))
    # the free case with the load pushed back by 1 N m: 3.5 N m on the load, within the motor's 5
    summary, err = simulate_json(["--case", "free", "--torque2", "1"], capsys)
    assert abs(summary["torque"]["load"]) < plant.gear_ratio * plant.torque_limit
    assert "exceed" not in err
