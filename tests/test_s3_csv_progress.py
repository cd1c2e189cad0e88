"""A long CSV write shows progress: `stiffness --points 1000000 --csv` wrote 253 MB for 15-20 s without a word."""

from __future__ import annotations

import csv

import numpy as np
from support import RecordingBar

from gearctl.cli import common


def test_csv_write_advances_a_bar(tmp_path, monkeypatch):
    RecordingBar.made = {}
    monkeypatch.setattr(common, "progress_bar", RecordingBar)
    t = np.linspace(0.0, 1.0, 95)
    path = tmp_path / "out.csv"
    common.write_csv_stream(str(path), ["t", "y"], lambda i0, i1: [t[i0:i1], 2 * t[i0:i1]], t.size, chunk=10)
    (calls,) = RecordingBar.made.values()
    assert len(calls) == 10 and calls == sorted(calls) and calls[-1] == 1.0
    with path.open() as fh:
        rows = list(csv.reader(fh))
    assert len(rows) == 96 and rows[0] == ["t", "y"]  # the file is whole
