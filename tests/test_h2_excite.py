"""``gearctl excite`` refuses, before the run, a log longer than ``identify`` reads (h2's review)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gearctl import InputError
from gearctl.cli import main
from gearctl.excite import record_excitation
from gearctl.logs import MAX_LOG_SAMPLES

MODEL = "shing1993_servo_friction"


def test_a_log_longer_than_identify_reads_is_refused_before_the_run(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    # 1 ms period: MAX_LOG_SAMPLES samples is 999.999 s; 1000.5 s simulated for minutes and wrote a log of 1,000,501
    # samples that identify refused
    duration = MAX_LOG_SAMPLES * 1e-3 + 0.5
    with pytest.raises(InputError, match="duration = 1000.5 s is too long for a log: 1,000,501 samples") as exc:
        record_excitation(MODEL, duration=duration)
    assert exc.value.field == "duration"
    out = tmp_path / "log.csv"
    assert main(["excite", MODEL, "--duration", str(duration), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "expected at most 999.999 s" in err and "Traceback" not in err
    assert not out.exists()
