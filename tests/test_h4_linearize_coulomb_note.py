"""``gearctl linearize`` on a model with Coulomb friction says that the linear models leave it out."""

from __future__ import annotations

import json

import pytest

from gearctl.cli import main


def test_linearize_notes_the_coulomb_friction(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["linearize", "shing1993_servo_friction", "--json"]) == 0
    out, err = capsys.readouterr()
    json.loads(out)  # the JSON stays whole on stdout
    assert "gearctl linearize: note: the linear models leave out the Coulomb friction (0, 0.2 N m" in err
    assert "Traceback" not in err


def test_linearize_without_coulomb_friction_has_no_note(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["linearize", "shing1993_servo"]) == 0
    assert capsys.readouterr().err == ""
