"""A controller file's bad value is one line naming the file, the key as typed and the allowed range in the file's
units (a machine builder's own files, derived from the catalog's)."""

from __future__ import annotations

from pathlib import Path

from gearctl.cli import main

DATA = Path(__file__).resolve().parent / "data" / "controller_files"
MODEL = str(DATA / "rack_axis_20x200.toml")


def _refusal(capsys, ctrl: str) -> str:  # noqa: ANN001
    assert main(["track", MODEL, str(DATA / ctrl), "--duration", "0.1"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return [ln for ln in err.splitlines() if "error:" in ln][0]


def test_phase_margin_range_is_said_in_degrees(capsys) -> None:  # noqa: ANN001
    # the PID keeps phase_margin_deg in degrees: its range read 57.2958 <= value <= 4526.37 [deg] (1..79 taken
    # for radians)
    err = _refusal(capsys, "pid_phase_margin_85.toml")
    assert "pid_phase_margin_85.toml: [design] phase_margin_deg = 85.0 is out of range" in err
    assert "1 <= value <= 79 [deg]" in err and "57.2958" not in err


def test_observer_bandwidth_names_the_key_once_with_unit_and_nyquist(capsys) -> None:  # noqa: ANN001
    # was "observer_hz: observer_hz = 600.0 is out of range: expected 0 <= value <= 500"
    err = _refusal(capsys, "deadzone_observer_600hz.toml")
    assert "deadzone_observer_600hz.toml: observer_hz = 600.0 is out of range" in err
    assert "observer_hz: observer_hz" not in err
    assert "0 <= value <= 500 [Hz]" in err and "Nyquist" in err


def test_a_check_across_keys_names_the_table(capsys) -> None:  # noqa: ANN001
    # was "min_backlash = 0.0001 is out of range: ..." without the [adaptation] the key sits in
    err = _refusal(capsys, "adaptive_min_above_max.toml")
    assert "adaptive_min_above_max.toml: [adaptation] min_backlash = 0.0001 is out of range" in err
    assert "at most max_backlash = 1e-05 [m]" in err


def test_a_missing_kind_is_a_missing_key(capsys) -> None:  # noqa: ANN001
    # was "kind = None is not a controller kind"
    err = _refusal(capsys, "no_kind.toml")
    assert "no_kind.toml: missing key kind: expected one of pid," in err and "None" not in err


def test_a_name_that_is_no_one_line_string_is_refused(capsys, tmp_path) -> None:  # noqa: ANN001
    # name = [1, 2] headed the notes '[1, 2]:' and a line break split them; the file's stem stays the default
    text = (Path(__file__).resolve().parents[1] / "controllers" / "pid.toml").read_text()
    for value, shown in (("[1, 2]", "[1, 2]"), ('"axis\\nsecond"', "'axis\\nsecond'"), ('""', "''")):
        f = tmp_path / "named.toml"
        f.write_text(f"name = {value}\n" + text)
        assert main(["track", MODEL, str(f), "--duration", "0.05"]) == 2
        err = capsys.readouterr().err
        assert f"named.toml: name = {shown} is not a controller name" in err, err
    f.write_text('name = "axis 2"\n' + text)
    assert main(["track", MODEL, str(f), "--duration", "0.05", "--json"]) == 0
    assert '"axis 2"' in capsys.readouterr().out


def test_a_long_file_name_is_still_the_default_name(capsys, tmp_path) -> None:  # noqa: ANN001
    # the 1-200 rule is the name key's: a file of 210 characters and no name = (it ran before the rule) was refused
    # with "name = 'ppp...' is not a controller name", a key the file does not have
    text = (Path(__file__).resolve().parents[1] / "controllers" / "pid.toml").read_text()
    f = tmp_path / ("p" * 210 + ".toml")
    f.write_text(text)
    assert main(["track", MODEL, str(f), "--duration", "0.05", "--json"]) == 0
    assert '"' + "p" * 210 + '"' in capsys.readouterr().out
    f = tmp_path / "line\nbreak.toml"  # the stem cannot head the notes: said of the file's name, on one line
    f.write_text(text)
    assert main(["track", MODEL, str(f), "--duration", "0.05"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the file's name 'line\\nbreak', the controller's default name" in err, err
