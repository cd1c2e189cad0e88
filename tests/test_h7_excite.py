"""``gearctl excite``: a duration whose log identify would refuse writes no file, ``--reference-only`` included
(h7's review: ``--reference-only R --out L --duration 1000`` wrote R, 41 MB, then refused the log, exit 2; and
``--reference-only R`` alone wrote a motion of 1,000,001 samples at 1 ms, whose drive log identify refuses)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gearctl import InputError
from gearctl.cli import main
from gearctl.excite import check_reference_duration, excitation, write_reference
from gearctl.logs import MAX_LOG_SAMPLES

MODEL = "shing1993_servo_friction"
TOO_LONG = MAX_LOG_SAMPLES * 1e-3 + 0.5  # 1000.5 s at 1 ms: 1,000,501 samples


def test_reference_only_longer_than_identify_reads_is_refused(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    ref = tmp_path / "ref.csv"
    assert main(["excite", MODEL, "--duration", str(TOO_LONG), "--reference-only", str(ref)]) == 2
    err = capsys.readouterr().err
    assert "duration = 1000.5 s" in err and "expected at most 999.999 s" in err and "Traceback" not in err
    assert not ref.exists()
    with pytest.raises(InputError, match="too long for a reference") as exc:
        write_reference(tmp_path / "r2.csv", excitation("identify", duration=TOO_LONG), duration=TOO_LONG)
    assert exc.value.field == "duration" and not (tmp_path / "r2.csv").exists()


def test_a_refused_log_leaves_no_reference_behind(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # a PID at 0.5 ms: 600 s is a reference of 600,001 rows at 1 ms, which passes, and a log of 1,200,001, refused;
    # the reference was written before the log was refused
    ctrl = tmp_path / "pid_2khz.toml"
    ctrl.write_text('kind = "pid"\nsample_time = 5e-4\n\n[design]\nbandwidth_hz = 30.0\n\n'
                    '[source]\nnotes = "h7: a 2 kHz PID"\n')
    ref, log = tmp_path / "ref.csv", tmp_path / "log.csv"
    assert main(["excite", MODEL, "--duration", "600", "--controller", str(ctrl), "--reference-only", str(ref),
                 "--out", str(log)]) == 2
    err = capsys.readouterr().err
    assert "too long for a log: 1,200,001 samples" in err and "expected at most 499.9995 s" in err
    assert not ref.exists() and not log.exists()


def test_the_longest_reference_is_allowed() -> None:
    assert check_reference_duration((MAX_LOG_SAMPLES - 1) * 1e-3) == MAX_LOG_SAMPLES


def test_both_outputs_still_written(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ref, log = tmp_path / "ref.csv", tmp_path / "log.csv"
    assert main(["excite", MODEL, "--duration", "1", "--reference-only", str(ref), "--out", str(log)]) == 0
    out = capsys.readouterr().out
    assert "reference, 1001 samples" in out and "log, 1001 samples" in out
    assert len(ref.read_text().splitlines()) == 1003 and log.exists()
