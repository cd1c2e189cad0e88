"""`gearctl precision --cycles 1`: one approach per target and direction has no spread; the figures that need one
(R+, R-, the s_i in R and A) are zeros nobody measured, and the command says so (review hH)."""

from __future__ import annotations

import json
from pathlib import Path

from gearctl.cli import main

MODEL = str(Path(__file__).resolve().parent / "data" / "controller_files" / "rack_axis_20x200.toml")
ARGV = ["precision", MODEL, "pid", "--targets", "2", "--cycles", "1", "--travel", "0.2", "--dwell", "0.2"]


def test_one_cycle_warns_that_repeatability_is_not_estimated(capsys) -> None:  # noqa: ANN001
    assert main(ARGV) == 0
    cap = capsys.readouterr()
    assert "warning: one cycle" in cap.err and "R+ = R- = 0" in cap.err
    assert "2 targets over 0.2 rad, 1 cycle\n" in cap.out
    assert main([*ARGV, "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["repeatability_up"] == 0.0 and any(w.startswith("one cycle") for w in d["health"]["warnings"])


def test_two_cycles_do_not_warn(capsys) -> None:  # noqa: ANN001
    argv = [*ARGV[:6], "2", *ARGV[7:]]
    assert main(argv) == 0
    cap = capsys.readouterr()
    assert "one cycle" not in cap.err and "2 cycles" in cap.out
