"""``gearctl COMMAND --help`` as a new user reads it: every default it mentions is stated, with its unit, and agrees
with the code; ranges are printed exactly.

Found by reading each command's help: ``track --duration`` said "default per reference" without the figures,
``--reference`` described ``ramp`` by its name alone, ``precision --plant`` gave no default, ``linearize --step``
said "(s)" for the relative displacement s, and whole-number ranges were rounded (``--seed``'s largest value,
2**63 - 1, printed as 9.22337e+18, below the true bound; a 2**40-count encoder as 1.09951e+12).
"""

from __future__ import annotations

import re

import pytest

from gearctl.cli import main
from gearctl.runs import DEFAULT_DURATION


def _help(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    assert main([*argv, "--help"]) == 0
    return " ".join(capsys.readouterr().out.split())  # argparse wraps anywhere


@pytest.mark.parametrize("command", ["track", "sweep", "bench"])
def test_default_durations_per_reference_are_stated(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    text = _help(capsys, command)
    for kind, seconds in DEFAULT_DURATION.items():
        assert f"{kind} {seconds:g} s" in text, (kind, text)


def test_track_reference_help_describes_every_reference(capsys: pytest.CaptureFixture[str]) -> None:
    from gearctl.references import reference

    text = _help(capsys, "track")
    ramp, move = reference("ramp"), reference("move")
    assert f"ramp: {ramp.rate:g} rad/s to {ramp.amplitude:g} rad" in text
    assert f"move: {move.amplitude:g} rad S-curve, {move.rate:g} rad/s, {move.accel:g} rad/s^2" in text


def test_precision_plant_has_its_default(capsys: pytest.CaptureFixture[str]) -> None:
    assert "--plant {improved,yang-sun,tvms} plant (default improved)" in _help(capsys, "precision")


def test_linearize_step_says_what_it_draws(capsys: pytest.CaptureFixture[str]) -> None:
    text = _help(capsys, "linearize")
    assert "(s)" not in text and "relative displacement s [m]" in text


def test_whole_number_ranges_are_exact(capsys: pytest.CaptureFixture[str]) -> None:
    text = _help(capsys, "track")
    assert f"0 <= value <= {2**63 - 1}" in text and "e+18" not in text
    assert main(["track", "--seed", "-1"]) == 2
    assert f"<= {2**63 - 1}" in capsys.readouterr().err
    # the largest seed the help gives is taken (within the range as printed)
    top = re.search(r"--seed SEED .*?<= (\d+)", text)
    assert top is not None and int(top.group(1)) == 2**63 - 1


def test_bench_takes_sweeps_name_for_its_processes(capsys: pytest.CaptureFixture[str]) -> None:
    # sweep sized its local cluster with --workers and took bench's --jobs too; bench refused --workers
    # ("unrecognized arguments: --workers")
    assert main(["bench", "--workers", "0"]) == 2
    err = capsys.readouterr().err
    assert "--workers" in err and "out of range" in err and "unrecognized" not in err
    assert "--jobs JOBS, --workers JOBS" in _help(capsys, "bench")


def test_one_range_for_a_local_clusters_processes(capsys) -> None:  # noqa: ANN001
    """bench and perf took 1..256 worker processes, sweep 1..1024 (h3's review): one range, one message."""
    from gearctl.cli import main

    for argv in (["bench", "shing1993_servo", "--jobs", "1025"], ["perf", "--jobs", "1025"],
                 ["sweep", "shing1993_servo", "pid", "--vary", "backlash=0.5x:2x", "--workers", "1025"]):
        assert main(argv) == 2
        assert "1025 is out of range: expected a whole number with 1 <= value <= 1024" in capsys.readouterr().err
