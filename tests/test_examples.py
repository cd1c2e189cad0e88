"""Smoke tests: each example runs end to end on a short horizon and writes its figures."""

from __future__ import annotations

from pathlib import Path

import pytest
from support import example_main

_main = example_main


def test_report_figures(tmp_path: Path) -> None:
    _main("01_report_figures")(["--out", str(tmp_path), "--duration", "0.002"])
    assert {p.name for p in tmp_path.glob("*.png")} == {
        "fig08-11_stiffness.png", "fig12-16_free.png", "fig17-21_load.png"}


def test_bode_step_margins(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _main("03_bode_step_margins")(["--out", str(tmp_path)])
    assert len(list(tmp_path.glob("*.png"))) == 3
    out = capsys.readouterr().out
    assert "PID on the contact" in out and "PID on the separation" in out


@pytest.mark.slow
def test_simulator_benchmark(capsys: pytest.CaptureFixture[str]) -> None:
    _main("02_simulator_benchmark")([])
    out = capsys.readouterr().out
    assert out.count("python-control (rtol 1e-10)") == 2
