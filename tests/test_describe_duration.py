"""`describe --duration` beyond what the recording holds names the duration and its limit (it named an
``oversample`` the command line does not have, and ``simulate_limit_cycle``, which is what it runs)."""

from __future__ import annotations

import pytest

from gearctl.cli import main


def test_describe_too_long_names_the_duration(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["describe", "shing1993_servo", "pid_load", "--duration", "5000"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("gearctl describe: error: duration = 5000 s at Ts = 0.001 s would record 5,000,000 ")
    assert "200 s at this sample time; lower the duration" in err
    assert "oversample" not in err and "simulate_limit_cycle" not in err


def test_describe_help_states_the_sample_limit(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["describe", "--help"]) == 0
    assert "200 000 controller samples" in " ".join(capsys.readouterr().out.split())
