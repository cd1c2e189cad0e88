"""loop_margins on a sampled loop refuses frequencies at or above its Nyquist frequency (they alias)."""

from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest

import gearctl
from gearctl import InputError


def _sampled_loop(Ts: float = 1e-3) -> ct.StateSpace:
    servo = gearctl.build_plant(gearctl.load_model("shing1993_servo"))
    pid = gearctl.load_controller("pid", servo)
    G = ct.c2d(ct.ss(gearctl.linearize_modes(servo).contact[0, 0]) / servo.gear_ratio, Ts, "zoh")
    return ct.ss(pid.gains.sampled_tf(Ts)) * G


@pytest.mark.parametrize("top", [math.pi / 1e-3, 1e4, 1e300])
def test_sampled_loop_refuses_omega_past_nyquist(top: float) -> None:
    loop = _sampled_loop()
    with pytest.raises(InputError, match=r"^omega = .* below its Nyquist frequency pi / dt = 3141\.59 rad/s") as err:
        gearctl.loop_margins(loop, omega=np.array([1.0, 10.0, top]))
    assert err.value.field == "omega"


def test_sampled_loop_below_nyquist_reads_as_the_default_grid() -> None:
    loop = _sampled_loop()
    got = gearctl.loop_margins(loop, omega=np.logspace(-2, math.log10(0.999 * math.pi / 1e-3), 20000))
    ref = gearctl.loop_margins(loop)
    for key in ("phase_margin", "gain_margin_db", "gain_crossover_hz"):
        assert got[key] == pytest.approx(ref[key], rel=1e-9)
    # a continuous loop has no Nyquist frequency: any positive grid is read
    cont = ct.tf([4.0], [1.0, 2.0, 1.0, 0.0])
    assert math.isfinite(gearctl.loop_margins(cont, omega=np.logspace(-2, 5, 2000))["phase_margin"])
