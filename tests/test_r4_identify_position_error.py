"""An encoder error that depends on the angle (eccentricity) against the plateaus' b (r4's simulator).

The log ``tests/data/logs/r4/eccentric_load_encoder.csv`` comes from r4's own simulator (``r4sim.c`` beside it: RK4
at 0.5 us, a PD loop on the motor encoder at 1 kHz, tanh Coulomb friction on the load), the pair and servo of
``shing1993_servo_friction`` with b = 5 um and a load encoder whose reading carries a once-per-turn sine of 5 counts
(2.2 um along the line of action), under cosine moves between +-1.5 rad with dwells: the load rests on the front flank
at one end of its travel and on the back flank at the other.
"""

import math
import sys
import types
from pathlib import Path

import numpy as np
import pytest

import gearctl
from gearctl.identify import POSITION_BIN, _position_check, identify

LOG = Path(__file__).parent / "data" / "logs" / "r4" / "eccentric_load_encoder.csv"
B_TRUE = 5e-6  # [m], the simulator's backlash along the line of action


def test_eccentric_load_encoder_b_not_identified() -> None:
    # before: b 6.70 um [6.07, 7.32] for the true 5, unflagged: the front rests at one end of the travel, the back ones
    # at the other, and no angle holds contact on both flanks to compare them at
    r = identify(LOG, gearctl.load_model("shing1993_servo_friction"))
    lo, hi = r.backlash_ci
    assert lo <= B_TRUE <= hi, (r.backlash, r.backlash_ci)
    assert "flanks move with the load angle" in r.not_identified.get("backlash", ""), r.not_identified


def test_eccentric_load_encoder_cli(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    from gearctl.cli import main

    out = tmp_path / "m.toml"
    code = main(["identify", str(LOG), "--model", "shing1993_servo_friction", "--write-model", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()  # --write-model refuses a b that is not identified
    assert "flanks move with the load angle" in err and "Traceback" not in err


def _problem(x: np.ndarray) -> types.SimpleNamespace:
    return types.SimpleNamespace(nominal=types.SimpleNamespace(k=1e8), log=types.SimpleNamespace(theta2=x))


@pytest.mark.parametrize("b", [3e-6, 2e-5])
def test_position_check_cancels_an_eccentricity_at_shared_angles(b: float) -> None:
    # s on the front flank b + c + e(x), on the back flank -(b - c - e(x)) with e an eccentricity of 2.2 um and an
    # encoder zero c; the front rests over [-1.5, 0.5] rad, the back ones over [-0.5, 1.5] (shared: [-0.5, 0.5])
    rng = np.random.default_rng(0)
    e = lambda x: 2.2e-6 * np.sin(x + 0.7) + 4e-7  # noqa: E731
    xf = np.linspace(-1.5, 0.5, 4000)
    xb = np.linspace(-0.5, 1.5, 4000)
    x = np.concatenate([xf, xb])
    noise = 2e-8 * rng.standard_normal(x.size)
    s = np.concatenate([b + e(xf), -(b - e(xb))]) + noise
    force = np.zeros_like(s)
    contact = {1: [np.arange(xf.size)], -1: [xf.size + np.arange(xb.size)]}
    b_pos, n, spread = _position_check(_problem(x), contact, s, force, 4e-8, 3)  # width: twice the noise, as identify's
    assert n >= 0.9 * 1.0 / POSITION_BIN
    assert b_pos == pytest.approx(b, abs=5e-8)
    # each flank's profile spans the eccentricity over its own 2 rad: about 2.2 um * (sin range) on each, a little
    # less after the running mean over POSITION_RUN bins
    expected = sum(2.2e-6 * float(np.ptp(np.sin(xs + 0.7))) for xs in (xf, xb))
    assert 0.85 * expected <= spread <= 1.02 * expected


def test_position_check_without_shared_angles_gives_the_spread_only() -> None:
    e = lambda x: 2.2e-6 * np.sin(x + 0.7)  # noqa: E731
    xf = np.linspace(0.5, 1.5, 2000)
    xb = np.linspace(-1.5, -0.5, 2000)
    x = np.concatenate([xf, xb])
    s = np.concatenate([5e-6 + e(xf), -(5e-6 - e(xb))])
    contact = {1: [np.arange(xf.size)], -1: [xf.size + np.arange(xb.size)]}
    b_pos, n, spread = _position_check(_problem(x), contact, s, np.zeros_like(s), 4e-8, 3)
    assert math.isnan(b_pos) and n == 0
    expected = sum(2.2e-6 * float(np.ptp(np.sin(xs + 0.7))) for xs in (xf, xb))
    assert 0.85 * expected <= spread <= 1.02 * expected


def test_position_check_a_flank_that_scatters_from_bin_to_bin_does_not_move() -> None:
    # a loop that rattles scatters single bins' flanks by about a micrometre with no trend along the angle (another
    # simulator's rattling PD log, b right): the running mean over POSITION_RUN bins leaves a fraction of it
    rng = np.random.default_rng(1)
    xf = np.linspace(-0.1, 0.1, 3000)
    xb = np.linspace(-0.1, 0.1, 3000)
    jump_f = 1e-6 * rng.standard_normal(10)[np.minimum(((xf + 0.1) / POSITION_BIN).astype(int), 9)]
    jump_b = 1e-6 * rng.standard_normal(10)[np.minimum(((xb + 0.1) / POSITION_BIN).astype(int), 9)]
    x = np.concatenate([xf, xb])
    s = np.concatenate([5e-5 + jump_f, -(5e-5 + jump_b)])
    contact = {1: [np.arange(xf.size)], -1: [xf.size + np.arange(xb.size)]}
    _, _, spread = _position_check(_problem(x), contact, s, np.zeros_like(s), 4e-8, 3)
    single = float(np.ptp(jump_f)) + float(np.ptp(jump_b))
    assert spread < 0.6 * single


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-q"]))
