"""Found by an outside user's own models (h1): each test fails on the code before its fix."""

from __future__ import annotations

import json
from pathlib import Path

from gearctl import load_model
from gearctl.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _servo_with(tmp_path: Path, *edits: tuple[str, str]) -> Path:
    text = (ROOT / "models" / "shing1993_servo.toml").read_text()
    for old, new in edits:
        assert old in text
        text = text.replace(old, new, 1)
    p = tmp_path / "m.toml"
    p.write_text(text)
    return p


def test_a_whole_number_written_as_a_float_is_kept_a_whole_number(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    # TOML's `teeth = 20.0` and `motor_encoder_cpr = 1e6` pass the whole-number check, but stayed floats: `info`
    # printed "20.0 x 80 teeth" and "1000000.0 counts/rev", and the JSON gave 20.0 and 1000000.0
    p = _servo_with(tmp_path, ("teeth = 20\n", "teeth = 20.0\n"),
                    ("motor_encoder_cpr = 1048576", "motor_encoder_cpr = 1e6"))
    m = load_model(p)
    assert type(m.pair.teeth1) is int and m.pair.teeth1 == 20
    assert type(m.sensors.motor_encoder_cpr) is int and m.sensors.motor_encoder_cpr == 1_000_000
    assert main(["info", str(p)]) == 0
    out = capsys.readouterr().out
    assert "20 x 80 teeth" in out and "motor 1000000 counts/rev" in out
    assert main(["info", str(p), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["teeth"][0] == 20 and isinstance(doc["teeth"][0], int)
    assert isinstance(doc["sensors"]["motor_encoder_cpr"], int)


def test_a_fractional_whole_number_key_is_still_refused(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    p = _servo_with(tmp_path, ("teeth = 20\n", "teeth = 20.5\n"))
    assert main(["info", str(p)]) == 2
    assert "[gear1] teeth = 20.5 is not a whole number" in capsys.readouterr().err


def test_set_a_factor_of_a_whole_number_key_says_why_it_is_refused(capsys) -> None:  # noqa: ANN001
    # `--set motor_encoder_cpr=2x` said "'2x' is not a number": the factor form is for real-valued keys only
    assert main(["track", "shing1993_servo", "pid", "--set", "motor_encoder_cpr=2x"]) == 2
    err = capsys.readouterr().err
    assert "motor_encoder_cpr = '2x': a whole-number key takes a whole number, not a factor" in err
    assert "4 <= value <= 1099511627776 [counts/rev]" in err and "is not a number" not in err  # 2**40, exact


def test_the_unholdable_load_step_counts_the_models_load_torque(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    # the step's 0.5 N m alone is below what the motor gives the load (4 x 0.19 = 0.76 N m), but the model's own
    # -0.3 N m load torque acts the same way: 0.8 N m in all, and the load ran off (1.55 rad) with no word of why
    p = _servo_with(tmp_path, ("torque_limit = 1.0", "torque_limit = 0.19"),
                    ("load_torque = 0.0", "load_torque = -0.3"))
    assert main(["track", str(p), "pid", "--reference", "step"]) == 0
    err = capsys.readouterr().err
    assert "on top of the model's load_torque (-0.3 N m), 0.8 N m in all" in err and "no controller can hold it" in err
    # a load torque against the step leaves less to hold: no warning
    p = _servo_with(tmp_path, ("torque_limit = 1.0", "torque_limit = 0.1"), ("load_torque = 0.0", "load_torque = 0.3"))
    assert main(["track", str(p), "pid", "--reference", "step", "--duration", "1.2"]) == 0
    assert "no controller can hold it" not in capsys.readouterr().err


def test_an_empty_citation_is_refused(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    # [source] citation is required; `citation = ""` (or blanks) gave a model with no source at all
    text = (ROOT / "models" / "shing1993.toml").read_text()
    start = text.index("citation = ")
    end = text.index("\n", start)
    p = tmp_path / "m.toml"
    p.write_text(text[:start] + 'citation = "  "' + text[end:])
    assert main(["info", str(p)]) == 2
    assert "[source] citation is empty" in capsys.readouterr().err
