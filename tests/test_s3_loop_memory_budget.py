"""The closed loop's memory budget per sample covers what the process really holds (its peak RSS), on a train too.

The budget (640 B + 24 B per state: 832 B for a three-stage train) had been set from tracemalloc's peak, which counts
the bytes asked for, not what malloc holds for them: the peak RSS of the three-stage train's MPC grew by 1173 B a
sample under `precision` (977 B under `track`), the two-stage train's by 975-1002 B against its 784 B budget, so a
request accepted just under the cap would have taken 1.4x the cap.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from gearctl.catalog import load_model
from gearctl.closedloop import loop_bytes
from gearctl.plant import build_plant

# the peak RSS is the process's own VmHWM: getrusage's ru_maxrss starts from the parent's RSS at the fork and carries
# across the exec, so under a full suite (a pytest process of several hundred MB) the child's growth never showed
_CHILD = """
import json, sys
import gearctl
from gearctl.precision import precision_test
def hwm():
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmHWM:"))
model, ctrl, k = sys.argv[1], sys.argv[2], int(sys.argv[3])
m = gearctl.load_model(model)
p = gearctl.build_plant(m)
c = gearctl.load_controller(ctrl, p, sensors=m.sensors)
precision_test(p, c, targets=2, cycles=1, dwell=0.05, sensors=m.sensors)  # every code path warm
r0 = hwm()
res = precision_test(p, c, targets=k, cycles=k, dwell=0.1, sensors=m.sensors)
r1 = hwm()
print(json.dumps({"samples": int(res.run.t.size), "grew": (r1 - r0) * 1024}))
"""


def _grown(model: str, ctrl: str, k: int) -> dict[str, float]:
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    out = subprocess.run([sys.executable, "-c", _CHILD, model, ctrl, str(k)], capture_output=True, text=True,
                         env=env, timeout=300, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="VmHWM in /proc/self/status is Linux's")
def test_the_budget_per_sample_covers_the_peak_rss_of_a_train_under_the_mpc() -> None:
    model = "servo_3stage_quanser_srv02"
    small, large = _grown(model, "mpc", 3), _grown(model, "mpc", 6)
    per_sample = (large["grew"] - small["grew"]) / (large["samples"] - small["samples"])
    budget = loop_bytes(build_plant(load_model(model)), 1.0, 1.0) / 2  # two samples: t = 0 and t = 1
    assert 500 < per_sample <= budget, (per_sample, budget)
