"""`gearctl perf`'s ratios against python-control count no one-time cost of either side.

The kernel was compiled outside the timing but python-control's import and first solver call were timed: the free
vibration's "753x" was 180-200x against a warm python-control on the same machine.
"""

from __future__ import annotations

import time

import numpy as np

from gearctl import perf


def test_python_control_first_call_is_not_timed(monkeypatch):
    calls = []

    def fake_python_control(plant, x0, n, dt, ctrl, solve_ivp_kwargs):
        # a one-time cost on the first call (python-control's import), then a steady cost per call
        time.sleep(0.4 if not calls else 0.01)
        calls.append(n)
        return np.tile(np.asarray(x0, dtype=float)[:, None], (1, n + 1))

    monkeypatch.setattr(perf, "_run_python_control", fake_python_control)
    r = perf.sim_speed("free", duration=2e-4, python_control_duration=2e-4)
    # the steady call takes 0.01 s for 2e-4 simulated s: 0.02 sim-s per wall s; the first call's 0.4 s would give
    # 5e-4 if it were timed
    for key in ("python_control_sim_per_wall", "python_control_tight_sim_per_wall"):
        assert r[key] > 2e-4 / 0.1, (key, r[key])
    assert len(calls) >= 4  # a warm-up and repeats, for each tolerance
