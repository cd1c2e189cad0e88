"""The progress bar of a long ODE run whose cost is set by a stiff mesh, not by its output rows.

A fuzzed pair (``tests/data/fuzz/stiff_overdamped_light_mesh.toml``: a 1e-4 kg mesh mass, ``c = 7.4e6`` N s/m, a root
at 7.4e10 rad/s) took 15 s for 3 ms of the tvms plant without a bar: the CLI's estimate counted the output rows
(7 ms). It now adds the steps the fastest mesh root asks of the explicit solver (:func:`gearctl.simulate.stiff_steps`).
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from gearctl import build_plant, load_model
from gearctl.cli import main, model_cmds
from gearctl.simulate import DOPRI5_STABILITY, stiff_steps

STIFF = Path(__file__).parent / "data" / "fuzz" / "stiff_overdamped_light_mesh.toml"


def test_stiff_steps_follow_the_fastest_mesh_root() -> None:
    m = load_model(STIFF)
    tvms = build_plant(m, "tvms")
    s, mass = tvms.stages[0], tvms.stage_m_eq(0)
    assert s.c / mass > math.sqrt(s.k / mass)  # overdamped: the fast real root c / m_eq sets the step
    assert stiff_steps(tvms, 3e-3) == pytest.approx(3e-3 * (s.c / mass) / DOPRI5_STABILITY, rel=1e-12)
    assert stiff_steps(build_plant(m, "improved"), 3e-3) == 0.0  # the exact path takes no steps of its own
    servo = build_plant(load_model("shing1993_servo"), "yang-sun")  # lightly damped: sqrt(k / m_eq)
    assert stiff_steps(servo, 1.0) == pytest.approx(servo.natural_frequency / DOPRI5_STABILITY, rel=1e-9)


def test_the_stiff_runs_bar_is_expected(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[float | None] = []
    real = model_cmds.progress_bar

    def spy(desc: str, *, expected_s: float | None, **kw: object) -> object:
        seen.append(expected_s)
        return real(desc, expected_s=expected_s, **kw)

    monkeypatch.setattr(model_cmds, "progress_bar", spy)
    assert main(["simulate", str(STIFF), "--plant", "tvms", "--duration", "2e-5"]) == 0
    # 2e-5 s asks ~4.5e5 steps (~0.1 s); 3 ms asks 6.7e7, some 15 s: the bar is shown from that estimate
    tvms = build_plant(load_model(STIFF), "tvms")
    assert seen == [pytest.approx(21 * 2e-6 + 2e-5 * 0.2 + stiff_steps(tvms, 2e-5) * 2.5e-7)]
    assert stiff_steps(tvms, 3e-3) * 2.5e-7 > 10.0
