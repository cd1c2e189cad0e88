"""The Yang-Sun plant on a gear pair that is not steel (r1's review).

Its impact damping comes from the restitution ``e = 1 - 0.022 V^0.36`` (eq 37), Goldsmith's impact data for steel
(:func:`gearctl.stiffness.restitution_coefficient`). A review's POM train (E = 2.8 GPa,
``tests/data/r1_pom_train_m04.toml``) ran ``simulate``, ``track``, ``precision``, ``sweep`` and ``bench`` on it with
steel's law and no word; now each says so in a note naming ``young_modulus``, and a steel model is unchanged.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from gearctl import load_model
from gearctl.cli import main
from gearctl.stiffness import STEEL_YOUNG_MODULUS, restitution_note

POM = str(Path(__file__).parent / "data" / "r1_pom_train_m04.toml")


def test_restitution_note_names_a_modulus_outside_steel() -> None:
    pair = load_model(POM).stages[0].pair
    note = restitution_note(pair)
    assert note is not None and "young_modulus = 2.8e+09 Pa" in note and "eq 37" in note
    lo, hi = STEEL_YOUNG_MODULUS
    for E, noted in ((lo, False), (hi, False), (2.068e11, False), (0.99 * lo, True), (1.01 * hi, True)):
        assert (restitution_note(dataclasses.replace(pair, young_modulus=E)) is not None) is noted, E


def cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    code = main(argv)
    _, err = capsys.readouterr()
    assert code == 0, err
    assert "Traceback" not in err
    return err


@pytest.mark.parametrize("argv", [
    ["simulate", POM, "--plant", "yang-sun", "--duration", "0.002"],
    ["track", POM, "pid", "--plant", "yang-sun", "--duration", "0.05"],
])
def test_yang_sun_on_pom_is_noted(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    err = cli(argv, capsys)
    notes = [ln for ln in err.splitlines() if "young_modulus" in ln]
    # one note for the two stages of one material
    assert len(notes) == 1 and ": note: stages 1, 2: young_modulus = 2.8e+09 Pa" in notes[0]


@pytest.mark.parametrize("argv", [
    ["simulate", POM, "--duration", "0.002"],                                   # the improved plant: damping_ratio
    ["simulate", "shing1993", "--plant", "yang-sun", "--duration", "0.002"],    # steel
    ["track", POM, "pid", "--plant", "yang-sun", "--duration", "0.05", "--set", "young_modulus=2.07e11"],
])
def test_no_note_for_steel_or_other_plants(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert "young_modulus" not in cli(argv, capsys)
