"""A train's PID, designed on the equivalent pair, checked on the whole train in contact: a design note where its
gain margin there is thin (h4's review: 3.1 dB at 398 Hz on a four-stage train, against 24 dB on the pair; the
margins of the sampled controller that runs, which a closed-loop pole check confirms)."""

from __future__ import annotations

import math
from pathlib import Path

import control as ct
import numpy as np
import pytest

from gearctl.catalog import load_controller, load_model
from gearctl.design.pid import TRAIN_GAIN_MARGIN_DB, train_margin_notes
from gearctl.modes import linearize_modes, loop_margins
from gearctl.plant import build_plant

DATA = Path(__file__).resolve().parent / "data"


def _whole_train_loop(plant, pid, contact=None):  # noqa: ANN001, ANN202
    # built here, not by train_margin_notes: the motor angle over the motor torque of the whole train in contact,
    # sampled, in load units, times the PID's sampled law
    G = linearize_modes(plant).contact if contact is None else contact
    return ct.ss(pid.gains.sampled_tf(pid.Ts)) * ct.c2d(ct.ss(G[0, 0]) / pid.info.N, pid.Ts, "zoh")


def _largest_pole(loop, gain: float) -> float:  # noqa: ANN001
    return float(np.max(np.abs(np.linalg.eigvals(ct.feedback(gain * loop, 1).A))))


@pytest.mark.parametrize(("model", "noted"), [(DATA / "h4_train4_review.toml", True),
                                              ("servo_3stage_quanser_srv02", False),
                                              ("servo_2stage_phm09", False), ("shing1993_servo", False)])
def test_a_thin_margin_on_the_whole_train_is_noted(model, noted: bool) -> None:  # noqa: ANN001
    m = load_model(model)
    plant = build_plant(m)
    for kind in ("pid", "deadzone_inverse"):
        c = load_controller(kind, plant, sensors=m.sensors)
        pid = c if kind == "pid" else c.pid
        notes = [n for n in c.design_notes if "whole train" in n]
        assert bool(notes) is noted
        if plant.n_stages > 1:
            loop = _whole_train_loop(plant, pid)
            m_ = loop_margins(loop)
            assert (m_["gain_margin_db"] < TRAIN_GAIN_MARGIN_DB) is noted
            if noted:  # the figure is the whole train's: at the stated frequency the loop's phase is -180 deg
                assert f"keeps {m_['gain_margin_db']:.3g} dB" in notes[0]
                f = m_["phase_crossover_hz"]
                z = complex(loop(complex(math.cos(2 * math.pi * f * pid.Ts), math.sin(2 * math.pi * f * pid.Ts))))
                assert abs(abs(math.degrees(math.atan2(z.imag, z.real))) - 180.0) < 5.0  # a sharp resonance
                assert -20.0 * math.log10(abs(z)) == pytest.approx(m_["gain_margin_db"], abs=0.05)
                # independent of the frequency response: the closed loop turns unstable at that gain
                k = 10.0 ** (m_["gain_margin_db"] / 20.0)
                assert _largest_pole(loop, 0.97 * k) < 1.0 < _largest_pole(loop, 1.03 * k)
                design = loop_margins(_whole_train_loop(plant, pid, pid.info.modes.contact))["gain_margin_db"]
                assert design > 3.0 * m_["gain_margin_db"]


def test_a_pair_gets_no_train_note() -> None:
    m = load_model("shing1993_servo")
    c = load_controller("pid", build_plant(m), sensors=m.sensors)
    assert train_margin_notes(c.info, c.gains, c.Ts, "motor") == ()
