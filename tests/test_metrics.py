"""The loop-health test of gearctl/metrics.py: a reference change is not a growing error, a divergence is.

Oracle: the step reference's own change. Right after a step of ``h`` the error of any loop is ``h`` (the load
cannot jump), so a step in the last quarter of a run puts ``h`` into the last quarter's error whatever the
loop; a loop that diverges puts ever more. Both cases are the catalog PID on ``shing1993_servo`` with the
benchmark step (0.05 rad at 0.1 s); the divergent one is the same run with an exponentially growing
oscillation added to the load angle, so that everything else (events, torque, reference) is a real run's.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gearctl import build_plant, load_model
from gearctl.catalog import load_controller
from gearctl.closedloop import ClosedLoopResult, simulate_closed_loop
from gearctl.metrics import HEALTH_LIMITS, loop_health, tracking_metrics
from gearctl.references import reference

STEP = reference("step")  # 0.05 rad at 0.1 s


@pytest.fixture(scope="module")
def runs() -> dict[float, ClosedLoopResult]:
    """The catalog PID on the benchmark servo, step reference, for durations that put the step late."""
    model = load_model("shing1993_servo")
    plant = build_plant(model)
    out = {}
    for duration in (0.1, 0.15, 0.4):
        out[duration] = simulate_closed_loop(plant, load_controller("pid", plant), STEP, duration,
                                             sensors=model.sensors)
    return out


@pytest.mark.parametrize("duration", [0.1, 0.15])
def test_a_late_step_is_not_a_growing_error(runs: dict[float, ClosedLoopResult], duration: float) -> None:
    res = runs[duration]
    h = loop_health(res, settle=0.0)
    e = np.abs(res.error)
    q = len(e) // 4
    # the situation the test is about: the second quarter has no error, the last quarter the step's own
    # (0.1 s: the step on the last sample, e = h exactly; 0.15 s: the step in the third quarter, the loop
    # still settling in the last, we see 0.03 rad), far above growth x the second quarter's and 1 mrad;
    # before the reference's change was taken into account both warned "growing error"
    assert np.max(e[q:2 * q]) == 0.0
    assert np.max(e[-q:]) > 1e-3
    assert np.max(e[-q:]) <= STEP.amplitude * (1 + 1e-12)
    assert not h.growing and h.warnings == ()
    assert not tracking_metrics(res, settle=0.0).health.growing


def test_a_settled_step_run_is_healthy(runs: dict[float, ClosedLoopResult]) -> None:
    # the step in the second quarter: its error there is the yardstick, nothing is explained away
    h = loop_health(runs[0.4], settle=0.0)
    assert not h.growing and h.ok


@pytest.mark.parametrize("duration", [0.1, 0.15, 0.4])
def test_a_divergence_after_a_step_is_still_a_growing_error(runs: dict[float, ClosedLoopResult],
                                                            duration: float) -> None:
    res = runs[duration]
    T = float(res.t[-1])
    # an oscillation growing 1000x over the run's last half to 20 step heights (1 rad) at the end: far beyond
    # the step's own change h and beyond growth x the second quarter's error (at most h + 1 mrad, 0.4 s run)
    grow = 20 * STEP.amplitude * np.exp(math.log(1e3) * (res.t - T) / (0.5 * T)) * np.cos(2 * np.pi * res.t / 0.01)
    x = res.x.copy()
    x[x.shape[0] // 2 - 1] -= grow
    bad = dataclasses.replace(res, x=x)
    h = loop_health(bad, settle=0.0)
    assert h.growing
    assert any(w.startswith("growing error") for w in h.warnings)
    # the yardstick the reference's change gives is that change, h, when the step comes after the second
    # quarter, and nothing when it comes inside it (0.4 s: its error is then the second quarter's yardstick)
    e = np.abs(bad.error)
    q = len(e) // 4
    explained = max(np.ptp(bad.reference[2 * q:]) - np.ptp(bad.reference[q:2 * q]), 0.0)
    assert explained == pytest.approx(STEP.amplitude if duration < 0.4 else 0.0, abs=1e-15)
    assert np.max(e[-q:]) > HEALTH_LIMITS["growth"] * max(np.max(e[q:2 * q]), explained)


def test_a_loop_that_cannot_move_is_not_growing(runs: dict[float, ClosedLoopResult]) -> None:
    # the load held still (a 1 uN m motor): the error is the reference itself, h from the step on, which is
    # the reference's change and nothing more, even with the load creeping back by 1 nrad
    res = runs[0.1]
    x = res.x.copy()
    x[x.shape[0] // 2 - 1] = -1e-9
    h = loop_health(dataclasses.replace(res, x=x), settle=0.0)
    assert np.max(np.abs(res.reference - x[x.shape[0] // 2 - 1])) > STEP.amplitude
    assert not h.growing
