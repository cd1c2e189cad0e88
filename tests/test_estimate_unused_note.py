"""`--estimate` given to a plain PID changes nothing; the commands used to take it without a word (review hH)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gearctl.cli import main

MODEL = str(Path(__file__).resolve().parent / "data" / "controller_files" / "rack_axis_20x200.toml")
SHORT = {"track": ["--duration", "0.05"],
         "precision": ["--targets", "2", "--cycles", "2", "--travel", "0.05", "--dwell", "0.05"]}


@pytest.mark.parametrize("command", ["track", "precision"])
def test_estimate_on_a_pid_is_noted(capsys, command: str) -> None:  # noqa: ANN001
    assert main([command, MODEL, "pid", "--estimate", "3e-5", *SHORT[command]]) == 0
    assert f"gearctl {command}: note: --estimate 3e-05: a pid has no backlash estimate" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["track", "precision"])
def test_estimate_on_an_inverse_is_taken_silently(capsys, command: str) -> None:  # noqa: ANN001
    assert main([command, MODEL, "deadzone_inverse", "--estimate", "3e-5", *SHORT[command]]) == 0
    assert "no backlash estimate" not in capsys.readouterr().err
