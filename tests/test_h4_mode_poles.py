"""Poles of the mode models with the rigid bodies' exact: a slow friction pole is not rounded to 0.

``tests/data/heavy_motor_no_limit.toml``: d_eq / J_eq = 5.8e-5 rad/s, below 1e-7 of the mesh pole, so the
eigenvalues of the angle model (their rigid-body pair rounded by sqrt(eps |A|)) and clean_poles gave 0 and 0:
linearize printed a double integrator and the transfer functions were 6 % off at 1e-3 rad/s.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import gearctl
from gearctl.cli import main
from gearctl.modes import mode_poles

DATA = Path(__file__).parent / "data"


def _rigid(plant) -> tuple[float, float]:
    ratio = np.cumprod([1.0] + [st.ratio for st in plant.stages])
    J = sum(sh.J / r**2 for sh, r in zip(plant.shafts, ratio, strict=True))
    d = sum(sh.d / r**2 for sh, r in zip(plant.shafts, ratio, strict=True))
    return J, d


def test_slow_friction_pole_is_kept(capsys: pytest.CaptureFixture[str]) -> None:
    plant = gearctl.build_plant(gearctl.load_model(DATA / "heavy_motor_no_limit.toml"))
    J, d = _rigid(plant)
    poles = mode_poles(plant, [True])
    assert np.sum(poles == 0) == 1  # the free rotation, exactly
    slow = poles[np.argsort(np.abs(poles))[1]]
    # the coupled pole sits at -d_eq / J_eq to the mesh's share (a 60-digit eigensolve gives -5.8155456472e-5)
    np.testing.assert_allclose(slow, -d / J, rtol=1e-8)
    assert main(["linearize", str(DATA / "heavy_motor_no_limit.toml")]) == 0
    assert "-5.8155e-05+0j, 0+0j" in capsys.readouterr().out
    # the transfer function has it: motor angle per torque at 1e-5 rad/s is 1 / (s (J s + d)), not 1 / (J s^2)
    modes = gearctl.linearize_modes(plant)
    s = 1j * np.array([1e-5, 1e-4, 1e-3])
    np.testing.assert_allclose(modes.motor_angle(s), 1.0 / (s * (J * s + d)), rtol=1e-4)


@pytest.mark.parametrize("model", ["shing1993", "servo_2stage_phm09", str(DATA / "h1_train_b0_mid.toml"),
                                   str(DATA / "h4_train4_review.toml")], ids=lambda m: Path(m).stem)
def test_mode_poles_are_the_models_eigenvalues(model: str) -> None:
    """Away from zero the poles are the state-space model's eigenvalues; at zero, one per rigid body, two
    without friction: counted from the plant, not guessed from the size."""
    plant = gearctl.build_plant(gearctl.load_model(model))
    n = plant.n_stages
    combos = [[True] * n, [b == 0.0 for b in plant.backlashes]]
    combos += [[j != i for j in range(n)] for i in range(n) if plant.backlashes[i] > 0 and n > 1]
    for loaded in combos:
        got = mode_poles(plant, loaded)
        eig = gearctl.modes.mode_model(plant, loaded).poles()
        big = np.abs(eig) > 1e-3 * np.abs(eig).max()
        for p in eig[big]:
            assert np.min(np.abs(got - p)) <= 1e-9 * abs(p)
        bodies = 1 + sum(not f for f in loaded)
        free_bodies, j = 0, 0
        for i in range(n + 1):  # a body ends at a separated stage or the load
            if i == n or not loaded[i]:
                free_bodies += all(plant.shafts[s].d == 0.0 for s in range(j, i + 1))
                j = i + 1
        assert np.sum(got == 0) == bodies + free_bodies
        assert got.size == 2 * (n + 1)


def test_pair_frictionless_double_zero() -> None:
    plant = gearctl.build_plant(gearctl.load_model("shing1993"))  # no [servo]: no viscous friction
    poles = mode_poles(plant, [True])
    assert np.sum(poles == 0) == 2
    wn = math.sqrt(plant.k / plant.m_eq)
    np.testing.assert_allclose(np.abs(poles[0]), wn, rtol=1e-12)
