"""examples/03_bode_step_margins.py on a model of the user's: a train names its signals theta0, thetan, xi0."""

from __future__ import annotations

from pathlib import Path

import pytest
from support import example_main

DATA = Path(__file__).parent / "data"


@pytest.mark.parametrize("model", ["servo_2stage_phm09", str(DATA / "h4_train4_review.toml")],
                         ids=lambda m: Path(m).stem)
def test_bode_step_margins_on_a_train(model: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    example_main("03_bode_step_margins")(["--model", model, "--out", str(tmp_path)])
    assert {p.name for p in tmp_path.glob("*.png")} == {"bode_motor_angle.png", "bode_load_angle.png",
                                                        "step_force.png"}
    out = capsys.readouterr().out
    for mode in ("contact", "separation"):
        line = next(ln for ln in out.splitlines() if ln.startswith(f"PID on the {mode}"))
        assert "nan" not in line  # a crossover was found: the loop is the motor torque to the motor angle


def test_bode_step_margins_takes_a_pair_by_path(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    example_main("03_bode_step_margins")(["--model", str(DATA / "plastic_pom.toml"), "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert "PID on the contact" in out and len(list(tmp_path.glob("*.png"))) == 3


def test_bode_step_margins_on_an_overdamped_mesh(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """damping_ratio 1.5 (the schema allows up to 2): no oscillating mode, so no resonance to size the step by."""
    text = (DATA / "plastic_pom.toml").read_text()
    assert "damping_ratio = " in text
    lines = [("damping_ratio = 1.5" if ln.strip().startswith("damping_ratio") else ln) for ln in text.splitlines()]
    model = tmp_path / "overdamped.toml"
    model.write_text("\n".join(lines) + "\n")
    example_main("03_bode_step_margins")(["--model", str(model), "--out", str(tmp_path)])
    assert "PID on the contact" in capsys.readouterr().out and (tmp_path / "step_force.png").exists()
