"""Mesh mode and resonances of a train whose upper modes are overdamped (``damping_ratio`` up to 2 is allowed).

Before, a train's mesh mode was its highest *oscillating* pole pair and its resonances the oscillating pairs only:
with damping_ratio 0.9 the four-stage review train's two upper modes have real poles, so ``linearize`` and
``info`` reported the 7.4 kHz second mode as the mesh mode (the highest undamped one is at 18.1 kHz) and two
resonances for four stages.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla

import gearctl
from gearctl.cli import main as cli_main

DATA = Path(__file__).parent / "data"


def _with_damping(tmp_path: Path, name: str, zeta: float) -> Path:
    text = (DATA / name).read_text()
    lines = [f"damping_ratio = {zeta}" if ln.strip().startswith("damping_ratio") else ln for ln in text.splitlines()]
    out = tmp_path / f"{Path(name).stem}_zeta{zeta}.toml"
    out.write_text("\n".join(lines) + "\n")
    return out


def _undamped_hz(plant) -> np.ndarray:
    """Natural frequencies of K phi = w^2 M phi [Hz], K from each mesh k (r_b1 theta_i - r_b2 theta_(i+1))^2."""
    w = len(plant.shafts)
    K = np.zeros((w, w))
    for i, st in enumerate(plant.stages):
        g = np.zeros(w)
        g[i], g[i + 1] = st.rb1, -st.rb2
        K += st.k * np.outer(g, g)
    lam = sla.eigh(K, np.diag([sh.J for sh in plant.shafts]), eigvals_only=True)
    return np.sqrt(lam[1:]) / (2 * math.pi)


@pytest.mark.parametrize("zeta", [0.9, 1.5])
def test_train_with_overdamped_modes(tmp_path: Path, zeta: float) -> None:
    plant = gearctl.build_plant(gearctl.load_model(_with_damping(tmp_path, "h4_train4_review.toml", zeta)))
    modes = gearctl.linearize_modes(plant)
    poles = modes.contact.poles()
    assert np.sum(np.abs(poles.imag) < 1e-9 * np.abs(poles).max()) >= 4  # some mode is overdamped here
    f = _undamped_hz(plant)
    # the resonances are the modes that ring (complex poles): the lower ones here, the undamped ones to 20 %
    # (heavy, non-proportional damping moves the coupled modes)
    res = np.array(modes.resonances_hz)
    assert 1 <= res.size < plant.n_stages
    np.testing.assert_allclose(res, f[:res.size], rtol=0.2)
    # the mesh mode is the highest mode, overdamped or not: not the highest resonance that rings
    np.testing.assert_allclose(modes.mesh.natural_frequency_hz, f[-1], rtol=0.1)
    assert modes.mesh.overdamped and modes.mesh.natural_frequency_hz > 2 * res.max()


def test_overdamped_pair(tmp_path: Path) -> None:
    """A pair with damping_ratio 1.5: its mesh mode at the undamped sqrt(k / m_eq), and no resonance (no ringing)."""
    plant = gearctl.build_plant(gearctl.load_model(_with_damping(tmp_path, "plastic_pom.toml", 1.5)))
    modes = gearctl.linearize_modes(plant)
    wn = math.sqrt(plant.k / plant.m_eq)
    assert modes.resonances_hz == ()
    np.testing.assert_allclose(modes.mesh.natural_frequency, wn, rtol=1e-3)
    assert modes.mesh.damping_ratio > 1.0


def test_catalog_train_modes_match_the_undamped_ones() -> None:
    """At the catalog's mesh damping (0.05) the coupled modes are the undamped eigenfrequencies to 5e-4."""
    for name in ("servo_2stage_phm09", "servo_3stage_quanser_srv02", DATA / "h4_train4_review.toml"):
        plant = gearctl.build_plant(gearctl.load_model(name))
        modes = gearctl.linearize_modes(plant)
        np.testing.assert_allclose(modes.resonances_hz, _undamped_hz(plant), rtol=5e-4)


@pytest.mark.parametrize("c", [1e6, 1e8])
def test_strongly_overdamped_mesh_mode(c: float) -> None:
    """A mesh damped far past critical: its slow root -k/c lies below the rounding that sets a rigid body's near-zero
    poles to 0 (-2.6 rad/s beside -3.4e7 at 1e8 on a fuzzed pair); taken for a rigid body, it left no mesh mode and
    `gearctl linearize` (and every loop design) ended in a traceback. A model file now refuses such a coefficient
    (below); a plant built in Python may still have it, and its mesh mode is the undamped sqrt(k / m_eq) with
    damping ratio c / (2 sqrt(k m_eq))."""
    servo = gearctl.build_plant(gearctl.load_model("shing1993_servo"))
    plant = dataclasses.replace(servo, stages=(dataclasses.replace(servo.stages[0], c=c),))
    mesh = gearctl.linearize_modes(plant).mesh
    np.testing.assert_allclose(mesh.natural_frequency, math.sqrt(plant.k / plant.m_eq), rtol=1e-6)
    np.testing.assert_allclose(mesh.damping_ratio, c / (2.0 * math.sqrt(plant.k * plant.m_eq)), rtol=1e-6)


def test_a_damping_coefficient_past_the_damping_ratio_range_is_refused(tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """A given damping_coefficient was bounded by 1e8 N s/m alone: on fuzzed light pairs that is a damping ratio of
    1822 and 10800, whose fast root c / m_eq set every solver's step (10 s for 3 ms of the exact solver, a 0.1 s loop
    13 s). It is now held to the damping ratio damping_ratio allows, 2: the largest coefficient that gives, refused
    beyond, and just inside accepted."""
    servo = gearctl.build_plant(gearctl.load_model("shing1993_servo"))
    cmax = 2.0 * 2.0 * math.sqrt(servo.k * servo.m_eq)
    text = (DATA.parent.parent / "models" / "shing1993_servo.toml").read_text()
    for c, ok in ((0.999 * cmax, True), (1.001 * cmax, False), (1e8, False)):
        path = tmp_path / f"c{c:.6g}.toml"
        path.write_text(text.replace("[dynamics]\n", f"[dynamics]\ndamping_coefficient = {c!r}\n", 1))
        if ok:
            assert gearctl.build_plant(gearctl.load_model(path)).c == c
            assert cli_main(["linearize", str(path)]) == 0
            capsys.readouterr()
            continue
        with pytest.raises(gearctl.InputError, match=r"damping_coefficient = .* expected 0 <= value <= ") as err:
            gearctl.load_model(path)
        assert err.value.field == "damping_coefficient"
        assert f"{cmax:.4g}" in str(err.value)
        assert cli_main(["info", str(path)]) == 2
        line = capsys.readouterr().err.strip().splitlines()
        assert len(line) == 1 and "[dynamics] damping_coefficient" in line[0]
