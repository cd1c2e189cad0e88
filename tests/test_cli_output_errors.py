"""An output that cannot be written (a full disk under standard output) is one line and exit 2, not a traceback."""

from __future__ import annotations

import errno
import io
import os
import subprocess
import sys

import pytest

from gearctl.cli import main

GEARCTL = [sys.executable, "-c", "import sys; from gearctl.cli import main; sys.exit(main(sys.argv[1:]))"]


class _FullStdout:
    """A standard output on a full disk: every write fails with ENOSPC, as ``> /dev/full`` does."""

    def write(self, text: str) -> int:
        raise OSError(errno.ENOSPC, "No space left on device")

    def flush(self) -> None:
        pass

    def fileno(self) -> int:  # as an in-memory stream's (pytest's capture, io.StringIO)
        raise io.UnsupportedOperation("fileno")


@pytest.mark.parametrize("argv", [["info", "shing1993", "--json"], ["info", "shing1993"], ["models"]])
def test_full_stdout_is_one_line_exit_2(argv: list[str], monkeypatch: pytest.MonkeyPatch,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(sys, "stdout", _FullStdout())
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2
    assert err == f"gearctl {argv[0]}: error: cannot write standard output: No space left on device\n"


def test_other_os_errors_still_surface(monkeypatch: pytest.MonkeyPatch) -> None:
    # only a failing output is turned into a message; any other OSError is a bug and keeps its traceback
    class _Odd(_FullStdout):
        def write(self, text: str) -> int:
            raise OSError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(sys, "stdout", _Odd())
    with pytest.raises(PermissionError):
        main(["models"])


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full (Linux)")
def test_dev_full_from_the_shell() -> None:
    with open("/dev/full", "w") as full:
        p = subprocess.run([*GEARCTL, "info", "shing1993", "--json"], stdout=full, stderr=subprocess.PIPE,
                           timeout=120, check=False)
    assert p.returncode == 2
    assert p.stderr == b"gearctl info: error: cannot write standard output: No space left on device\n"


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full (Linux)")
def test_csv_to_a_full_stdout_names_standard_output() -> None:
    # `--csv -` on a full disk said "cannot write -"
    with open("/dev/full", "w") as full:
        p = subprocess.run([*GEARCTL, "stiffness", "shing1993", "--points", "11", "--csv", "-"], stdout=full,
                           stderr=subprocess.PIPE, timeout=120, check=False)
    assert p.returncode == 2
    assert p.stderr.decode().splitlines()[-1] == ("gearctl stiffness: error: cannot write standard output: "
                                                  "No space left on device")


@pytest.mark.parametrize(("argv", "needle"), [
    (["linearize", "shing1993_servo", "--bode", "-"], "--bode -: this output cannot go to standard output"),
    (["stiffness", "shing1993", "--plot", "-"], "--plot -: this output cannot go to standard output"),
    (["excite", "shing1993_servo_friction", "--out", "-"], "--out -: this output cannot go to standard output"),
    (["export", "shing1993_servo", "pid", "--out", ""], "--out '': an empty name"),
    (["track", "shing1993_servo", "pid", "--csv", ""], "--csv '': an empty name: expected a file or folder name (or -"),
    (["linearize", "shing1993_servo", "--step", " "], "--step ' ': an empty name"),
])
def test_empty_and_dash_outputs_are_refused(argv: list[str], needle: str, tmp_path, monkeypatch: pytest.MonkeyPatch,
                                            capsys: pytest.CaptureFixture[str]) -> None:  # noqa: ANN001
    """"" wrote nothing without a word (export --out "" wrote into the current folder); "-", standard output for
    --csv, wrote a file named "-" for --plot, --bode, excite --out and identify --write-model."""
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err, err
    assert list(tmp_path.iterdir()) == []
