"""Long closed loops show progress: `track` and `precision` advance their bar through the run.

`track` opened a bar for a long run and never moved it (``0/1000`` for the whole of a 300 s run on a terminal);
`precision`, up to a 100 000 s program, had no bar for its run at all.
"""

from __future__ import annotations

import pytest
from support import RecordingBar

from gearctl.cli import loop_cmds, main


@pytest.fixture
def bars(monkeypatch):
    RecordingBar.made = {}
    monkeypatch.setattr(loop_cmds, "progress_bar", RecordingBar)
    return RecordingBar.made


def test_track_advances_its_bar(bars, capsys):
    assert main(["track", "shing1993_servo", "pid", "--duration", "0.5"]) == 0
    calls = bars["gearctl track"]
    assert len(calls) >= 10
    assert calls == sorted(calls) and calls[-1] > 0.9


def test_precision_advances_its_bar(bars, capsys):
    assert main(["precision", "shing1993_servo", "pid", "--targets", "2", "--cycles", "1", "--dwell", "0.05"]) == 0
    calls = bars["gearctl precision"]
    assert len(calls) >= 10
    assert calls == sorted(calls) and calls[-1] > 0.9
