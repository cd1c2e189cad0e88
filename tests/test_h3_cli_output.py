"""What a new user reads on the terminal: the label/value tables of ``info`` and ``simulate`` keep one value column.

``info`` printed its ``backlash`` row one column to the right of every other row (pair and each stage of a train), and
``simulate`` on a train its ``stage N impacts`` rows one column to the left.
"""

from __future__ import annotations

import re
from pathlib import Path

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


# ---- outputs that cannot be written are refused before the work --------------------------------------------------

def _blocked(tmp_path: Path, name: str) -> str:
    """A path under a plain file: no folder can be made there, on any system and for any user (root included)."""
    (tmp_path / "a_file").write_text("x")
    return str(tmp_path / "a_file" / name)


def test_write_model_into_missing_folder_refused_before_identifying(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "log.csv"
    assert main(["excite", "shing1993_servo_friction", "--out", str(log)]) == 0
    capsys.readouterr()
    # identified first (results printed, 1.5 s here, minutes on a long log), then "does not exist (create it first)"
    rc = main(["identify", str(log), "--model", "shing1993_servo_friction",
               "--write-model", str(tmp_path / "no_such_folder" / "mine.toml")])
    out, err = capsys.readouterr()
    assert rc == 2 and out == ""
    assert err.count("\n") == 1 and "--write-model" in err and "does not exist" in err
    assert not (tmp_path / "no_such_folder").exists()
    # into a folder that exists it writes, as before
    assert main(["identify", str(log), "--model", "shing1993_servo_friction",
                 "--write-model", str(tmp_path / "mine.toml")]) == 0
    assert (tmp_path / "mine.toml").is_file()


#: per command, the function that does its work: the test makes it fail, so a refusal must come before it
_WORK = {"track": "gearctl.runs.execute", "precision": "gearctl.precision.precision_test",
         "simulate": "gearctl.simulate.report_case", "linearize": "gearctl.modes.linearize_modes",
         "export": "gearctl.export.export_controller", "excite": "gearctl.excite.record_excitation"}


@pytest.mark.parametrize("argv", [
    ["track", "shing1993_servo", "pid", "--plot", "{blocked}"],
    ["track", "shing1993_servo", "pid", "--csv", "{blocked}"],
    ["precision", "shing1993_servo", "pid", "--cycles", "1", "--plot", "{blocked}"],
    ["simulate", "shing1993", "--csv", "{blocked}"],
    ["linearize", "shing1993_servo", "--bode", "{blocked}"],
    ["export", "shing1993_servo", "pid", "--out", "{blocked}"],
    ["excite", "shing1993_servo_friction", "--out", "{blocked}"],
])
def test_unwritable_output_refused_before_the_run(argv: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    # each ran its whole work (a precision test, an export's recorded vectors, a long track) and only then found it
    # could not write (a traceback-free line, exit 2, but the run was lost)
    def started(*a: object, **k: object) -> None:
        raise AssertionError("the work started before the output was checked")

    monkeypatch.setattr(_WORK[argv[0]], started)
    blocked = _blocked(tmp_path, "x.png" if "--plot" in argv or "--bode" in argv else "x.csv")
    rc = main([a.replace("{blocked}", blocked) for a in argv])
    out, err = capsys.readouterr()
    assert rc == 2 and out == ""
    assert err.count("\n") == 1 and "Traceback" not in err and "cannot write" in err


def test_excite_out_is_a_file_and_export_out_a_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # excite --out names the log (an existing one is replaced), export --out a folder (made, with the ones above it)
    log = tmp_path / "log.csv"
    log.write_text("old")
    assert main(["excite", "shing1993_servo_friction", "--duration", "1", "--out", str(log)]) == 0
    assert log.read_text().count("\n") > 1000
    assert main(["export", "shing1993_servo", "pid", "--no-vectors", "--out", str(tmp_path / "a" / "b")]) == 0
    assert (tmp_path / "a" / "b" / "gearctl_ctrl.h").is_file()


# ---- bench --controllers takes every word after it ---------------------------------------------------------------

def test_bench_model_after_controllers_is_named(capsys: pytest.CaptureFixture[str]) -> None:
    # `gearctl bench --controllers pid shing1993_servo_friction` read the model as a controller: "unknown controller
    # 'shing1993_servo_friction': expected a catalog name (adaptive_inverse, ...)", with no word of why
    assert main(["bench", "--controllers", "pid", "shing1993_servo_friction", "--no-precision"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is a model" in err and "before --controllers" in err


def test_bench_help_says_controllers_are_names_or_files(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "--controllers CONTROLLER [CONTROLLER ...]" in text and "catalog names or TOML files" in text


# ---- a model and a controller given the other way round ----------------------------------------------------------

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(("argv", "said"), [
    (["track", "pid"], "'pid' is a controller, not a model"),
    (["precision", "mpc"], "'mpc' is a controller, not a model"),
    (["track", "shing1993_servo", "shing1993_servo_friction"],
     "'shing1993_servo_friction' is a model, not a controller"),
    (["export", "deadzone_inverse", "shing1993_servo", "--out", "x"], "is a controller, not a model"),
    (["track", str(REPO / "controllers" / "pid.toml")], "a controller file (kind = 'pid'), not a model"),
    (["sweep", "shing1993_servo", str(REPO / "models" / "shing1993_servo.toml")], "a model file, not a controller"),
    (["excite", "shing1993_servo", "--controller", "shing1993_servo", "--out", "x.csv"],
     "--controller 'shing1993_servo' is a model, not a controller"),
])
def test_model_and_controller_swapped_are_named(argv: list[str], said: str, tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    # `gearctl track pid` said "unknown model 'pid': expected a catalog name (detc1992_21x29_25deg, ...)", the
    # controller file as the model "unknown section [kind]", a model file as the controller "missing key kind"
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and said in err and "Traceback" not in err
    assert "first" in err or "--controller names the position loop" in err  # and says the order


def test_csv_to_dev_stdout_in_a_pipe_as_a_user(tmp_path: Path) -> None:
    # `--csv /dev/stdout | ...`: /dev/stdout resolves to /proc/PID/fd/pipe:[N], which is no path, in a folder a user
    # (not root) cannot write: the check before the work must let a device or a pipe through, as the writer does.
    # A user's rights are emulated: os.access refuses writing under /proc, as it does for anyone but root.
    import subprocess
    import sys

    code = ("import os, sys\n"
            "real = os.access\n"
            "os.access = lambda p, m, *a, **k: False if str(p).startswith('/proc/') and m & os.W_OK else real(p, m)\n"
            "from gearctl.cli import main\n"
            "sys.exit(main(sys.argv[1:]))\n")
    r = subprocess.run([sys.executable, "-c", code, "track", "shing1993_servo", "pid", "--duration", "0.05",
                        "--csv", "/dev/stdout"], capture_output=True, text=True, cwd=tmp_path,
                       env={**__import__("os").environ, "PYTHONPATH": str(REPO)})
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("t,reference,theta1")
