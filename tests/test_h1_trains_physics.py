"""Found by an outside user's own gear pairs and trains (h1): each test fails on the code before its fix."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from gearctl import build_plant, linearize_modes, load_model
from gearctl.cli import main
from gearctl.modes import mesh_mode
from gearctl.oracle import reference_solution
from gearctl.simulate import report_case

DATA = Path(__file__).resolve().parent / "data"
PAIR = DATA / "h1_pair_17x43_frictionless.toml"  # no [servo]: no viscous friction, a double zero pole
TRAIN = DATA / "h1_train_b0_mid.toml"


def _variant(tmp_path: Path, src: Path, drop: str = "", edit: tuple[str, str] = ("", "")) -> Path:
    """A copy of ``src`` without the lines starting with ``drop``, ``edit[0]`` replaced by ``edit[1]``."""
    lines = [ln for ln in src.read_text().splitlines() if not (drop and ln.startswith(drop))]
    text = "\n".join(lines) + "\n"
    if edit[0]:
        assert edit[0] in text
        text = text.replace(edit[0], edit[1])
    p = tmp_path / src.name
    p.write_text(text)
    return p


def test_a_frictionless_pair_has_one_resonance_and_two_zero_poles(capsys: pytest.CaptureFixture[str]) -> None:
    # the double zero of a free rigid body came out of the eigenvalue solver as +5e-12 +/- 1.4e-4j rad/s (2.3e-9
    # of the mesh pole, above the 1e-10 taken for rounding): linearize printed poles with a positive real part and
    # resonances_hz listed a 2.2e-5 Hz resonance beside the mesh mode
    plant = build_plant(load_model(PAIR))
    modes = linearize_modes(plant)
    assert len(modes.resonances_hz) == 1
    assert_allclose(modes.resonances_hz[0], plant.natural_frequency / (2 * math.pi), rtol=1e-9)
    assert main(["linearize", str(PAIR), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    poles = np.array([complex(*p) for p in doc["poles"]])
    assert np.all(poles.real <= 0.0)
    assert np.sum(poles == 0) == 2
    assert doc["resonances_hz"] == list(modes.resonances_hz)


def test_a_frictionless_train_lists_one_resonance_per_stage(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    # a three-stage train without viscous friction printed 'resonances in contact 2.7422e-05, 503.58, 6599.2,
    # 9161.4 Hz' in info and linearize, and its stage-1-separated model a real pole at +1.5e-4 rad/s
    p = _variant(tmp_path, TRAIN, drop="viscous_friction")
    plant = build_plant(load_model(p))
    assert all(sh.d == 0.0 for sh in plant.shafts)
    modes = linearize_modes(plant)
    assert len(modes.resonances_hz) == plant.n_stages
    damped = linearize_modes(build_plant(load_model(TRAIN)))  # with the file's friction: the same three modes
    assert_allclose(modes.resonances_hz, damped.resonances_hz, rtol=1e-3)
    assert main(["info", str(p), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["plant"]["resonances_hz"] == list(modes.resonances_hz)
    assert main(["linearize", str(p), "--mode", "stage1", "--json"]) == 0
    poles = np.array([complex(*q) for q in json.loads(capsys.readouterr().out)["poles"]])
    assert np.all(poles.real <= 0.0) and np.sum(poles == 0) == 4  # two free bodies while stage 1 is open


def test_an_overdamped_frictionless_pair_reports_its_mesh_mode(tmp_path: Path) -> None:
    # with damping_ratio 1.5 on a pair without viscous friction the spurious rigid-body pair was the only
    # 'oscillating' pole: the mesh mode came out at 5.2e-5 Hz with a damping ratio of -1.4e-8, the anti-resonance nan
    p = _variant(tmp_path, PAIR, edit=("damping_ratio = 0.05", "damping_ratio = 1.5"))
    plant = build_plant(load_model(p))
    mm = mesh_mode(plant)
    assert_allclose(mm.natural_frequency, plant.natural_frequency, rtol=1e-9)
    assert_allclose(mm.damping_ratio, 1.5, rtol=1e-9)
    assert mm.overdamped
    # holding the motor, the load rings on the mesh spring at sqrt(k rb2^2 / J2)
    st = plant.stages[0]
    assert_allclose(mm.antiresonance, math.sqrt(st.k * st.rb2**2 / plant.shafts[1].J), rtol=1e-9)


def test_a_load_step_equal_to_what_the_motor_gives_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # a speed-up train of overall ratio 1 with a 0.5 N m motor: the step's 0.5 N m equals ratio x torque_limit, the
    # load ran off 8.2 rad under every controller (saturated at the balance, nothing left to stop it) and track
    # warned only of a saturated actuator (the check asked for a step strictly above what the motor gives)
    p = DATA / "h1_speedup_ratio1.toml"
    assert build_plant(load_model(p)).gear_ratio * 0.5 == 0.5
    assert main(["track", str(p), "pid", "--reference", "step", "--duration", "1.3", "--json"]) == 0
    out = capsys.readouterr()
    assert "equals the torque the motor can put on the load (ratio x torque_limit = 0.5 N m)" in out.err
    assert abs(json.loads(out.out)["final_error"]) > 0.5  # it does run off
    # 10 % more torque than the step: no warning
    q = _variant(tmp_path, p, edit=("torque_limit = 0.5", "torque_limit = 0.55"))
    assert main(["track", str(q), "pid", "--reference", "step", "--duration", "1.3"]) == 0
    assert "no controller can hold it" not in capsys.readouterr().err


@pytest.mark.parametrize(("case", "torque"), [("free", (0.0, 0.0)), ("load", (1.0, -1.0))])
def test_the_oracle_follows_a_no_pull_train_with_a_stage_without_backlash(case: str,
                                                                          torque: tuple[float, float]) -> None:
    # gearctl.oracle.reference_solution watched s = 0 of a stage without backlash as a flank event: under no_pull
    # that stage grazed s = 0 and the oracle raised 'event cascade' (100 000 flips at t = 0.325 ms) on this
    # four-stage train; the flank of such a stage is now the sign of s in the right-hand side. An independent
    # solve_ivp of the same equations (h1's, events at 1e-16 m) gave the kernel's impacts to 1e-13 s.
    plant = build_plant(load_model(DATA / "h1_train4_nopull_b0.toml"))
    assert plant.contact_law.value == "no_pull" and plant.backlashes[2] == 0.0
    res = report_case(plant, case, 0.02, dt=1e-5)
    x_ref, impacts_ref = reference_solution(plant, res.x[:, 0], res.t, torque=torque, rtol=1e-12)
    impacts = [e for e in res.impacts if e.kind == "impact"]
    assert len(impacts) == len(res.impacts) >= 40
    assert [(e.stage + 1) * (1 if e.side == "front" else -1) for e in impacts] == [s for _, s in impacts_ref]
    # impact times: measured 8e-13 s; gaps: measured 1.1e-7 of b (2e-12 m on the stage without backlash)
    assert_allclose([e.t for e in impacts], [t for t, _ in impacts_ref], rtol=0, atol=1e-9)
    scale = np.array([max(b, 1e-6) for b in plant.backlashes])[:, None]
    assert np.max(np.abs(res.s - plant.gaps(x_ref)) / scale) <= 1e-5
