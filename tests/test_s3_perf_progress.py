"""`gearctl perf` (several minutes) advances a bar through its sections; it printed nothing for about 4 minutes."""

from __future__ import annotations

import json

from support import RecordingBar

import gearctl.export as export
import gearctl.perf as perf
import gearctl.sweep as sweep
from gearctl.cli import loop_cmds, main


def test_perf_advances_its_bar_section_by_section(monkeypatch, capsys):
    RecordingBar.made = {}
    monkeypatch.setattr(loop_cmds, "progress_bar", RecordingBar)
    done = []

    def section(name):
        def fake(*args, **kwargs):
            done.append((name, len(RecordingBar.made.get("gearctl perf", []))))
            return {"gearctl_sim_per_wall": 1.0, "python_control_sim_per_wall": 1.0, "ratio": 1.0,
                    "gearctl_error": 0.0, "python_control_error": 0.0}
        return fake

    for name in ("sim_speed", "train_speed", "standstill_cost", "mpc_timing", "bench_wall_time"):
        monkeypatch.setattr(perf, name, section(name))
    monkeypatch.setattr(export, "export_timing", section("export_timing"))
    monkeypatch.setattr(sweep, "sweep_perf", section("sweep_perf"))
    assert main(["perf", "--json"]) == 0
    json.loads(capsys.readouterr().out)
    calls = RecordingBar.made["gearctl perf"]
    assert calls == sorted(calls) and calls[-1] == 1.0
    # the bar moved between the sections: each later section started with more of it done
    seen = [n for _, n in done]
    assert len(done) == 8 and seen == sorted(seen) and seen[-1] >= 6
