"""A servo whose constant ``load_torque`` exceeds what its motor can put on the load (r1's review).

``tests/data/r1_gravity_beyond_motor.toml``: 6 N m of gravity-like load torque on a ratio-5 pair with a 1 N m motor
(5 N m at the load). Every run runs the load away (the sine: 145 rad off); ``track`` warned only that the loop did
not follow, ``info`` said nothing. The step reference's load step was already checked against what the motor holds
(with the model's load torque); the model's torque alone now is too, by ``info``, ``track``, ``precision`` and
``bench``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from gearctl import build_plant, load_model
from gearctl.cli import main
from gearctl.runs import unholdable_load_torque

DATA = Path(__file__).parent / "data"
BEYOND = str(DATA / "r1_gravity_beyond_motor.toml")
WITHIN = str(DATA / "r1_gravity_motor_coulomb.toml")  # 4.5 N m: 0.9 of what the motor holds


def test_unholdable_load_torque_against_ratio_times_limit() -> None:
    plant = build_plant(load_model(BEYOND))
    hold = plant.gear_ratio * plant.torque_limit
    msg = unholdable_load_torque(plant)
    assert msg is not None and "load_torque = -6 N m" in msg and f"{hold:.3g} N m" in msg
    assert unholdable_load_torque(build_plant(load_model(WITHIN))) is None
    # the threshold is the motor's torque at the load, either sign; none without a limit
    for tl, held in ((0.999 * hold, False), (hold, True), (-1.001 * hold, True)):
        assert (unholdable_load_torque(dataclasses.replace(plant, load_torque=tl)) is not None) is held, tl
    assert unholdable_load_torque(dataclasses.replace(plant, torque_limit=float("inf"))) is None


@pytest.mark.parametrize("argv", [["info"], ["track", "pid", "--duration", "0.3"],
                                  ["precision", "pid", "--cycles", "1", "--targets", "2"],
                                  ["bench", "--controllers", "pid", "--plants", "improved", "--references", "step",
                                   "--duration", "0.3", "--no-precision", "--jobs", "1", "--quiet"]])
def test_commands_warn(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    code = main([argv[0], BEYOND, *argv[1:]])
    _, err = capsys.readouterr()
    assert code == 0, err
    name = f"{BEYOND}: " if argv[0] == "bench" else ""  # bench names the model of each warning
    assert f"gearctl {argv[0]}: warning: {name}[servo] load_torque = -6 N m is 1.2 times" in err


def test_info_quiet_within_reach(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", WITHIN]) == 0
    assert "load_torque" not in capsys.readouterr().err
