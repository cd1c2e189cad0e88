"""What a new user reads on the terminal: the label/value tables of ``info`` and ``simulate`` keep one value column.

``info`` printed its ``backlash`` row one column to the right of every other row (pair and each stage of a train), and
``simulate`` on a train its ``stage N impacts`` rows one column to the left.
"""

from __future__ import annotations

import re

import pytest

from gearctl.cli import main


def _value_columns(lines: list[str]) -> dict[int, set[int]]:
    """Per indent, the columns where the value starts on the ``label<two or more spaces>value`` rows."""
    cols: dict[int, set[int]] = {}
    for line in lines:
        m = re.match(r"^( +)(\S(?:\S| (?! ))*)( {2,})\S", line)  # indent, a label with single spaces, a gap
        if m is None:
            continue
        indent = len(m.group(1))
        cols.setdefault(indent, set()).add(len(m.group(1)) + len(m.group(2)) + len(m.group(3)))
    return cols


@pytest.mark.parametrize("argv", [
    ["info", "shing1993"],
    ["info", "pinion17_shifted_shing1993"],
    ["info", "servo_3stage_quanser_srv02"],
    ["simulate", "shing1993", "--duration", "0.002"],
    ["simulate", "servo_2stage_phm09", "--duration", "0.002"],
])
def test_one_value_column(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 0
    out = capsys.readouterr().out.splitlines()
    cols = _value_columns(out)
    assert cols, out  # the parser found the table
    for indent, where in cols.items():
        assert len(where) == 1, (indent, sorted(where), out)
    # and the rows that were off are among those checked
    labels = " ".join(out)
    assert "backlash " in labels or "stage 1 impacts" in labels or "impacts " in labels


# ---- --backlash and --set backlash: two values for one key ---------------------------------------------------------

@pytest.mark.parametrize("argv", [
    ["track", "shing1993_servo", "deadzone_inverse", "--backlash", "1e-5", "--set", "backlash=2e-5"],
    ["track", "shing1993_servo", "pid", "--set", "backlash=2x", "--backlash", "1e-5"],
    ["track", "servo_2stage_phm09", "pid", "--backlash", "1e-5", "--set", "stage2.backlash=3e-5"],
    ["precision", "shing1993_servo", "pid", "--backlash", "1e-5", "--set", "backlash=2e-5", "--cycles", "1"],
])
def test_backlash_and_set_backlash_refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    # --backlash B sets the plant's backlash after --set's, so --set backlash=... was dropped without a word: the run
    # was the plant with B (track ... --backlash 1e-5 --set backlash=2e-5 printed b = 10 um and the figures of
    # --backlash 1e-5 alone)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "--backlash" in err and "--set" in err and "--estimate" in err  # names both, and the way to say it


def test_set_backlash_alone_still_changes_the_plant(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["track", "shing1993_servo", "pid", "--set", "backlash=2e-5", "--duration", "0.5", "--json"]) == 0
    import json

    assert json.loads(capsys.readouterr().out)["backlash"] == 2e-5
    assert main(["track", "shing1993_servo", "pid", "--backlash", "2e-5", "--set", "load_inertia=1.1x",
                 "--duration", "0.5", "--json"]) == 0  # --set of another key beside --backlash is fine
    assert json.loads(capsys.readouterr().out)["backlash"] == 2e-5
