"""``identify`` on logs of h3's independent simulator (``tests/data/logs/h3_sim``: a Hertz-like mesh with damping only
in contact, Stribeck friction with stiction, symplectic Euler at 4 us, its own PD loop, the logger's own clock).

The logs are ``make_logs.py``'s cases of the same names (``python tests/data/logs/h3_sim/make_logs.py OUTDIR CASE``).
"""

from __future__ import annotations

from pathlib import Path

from gearctl.identify import identify

DATA = Path(__file__).parent / "data" / "logs" / "h3_sim"


def test_the_coulomb_split_carries_the_motor_inertia_it_was_fitted_with() -> None:
    # a PD loop crossing the gap at a steady acceleration: in free flight J1 theta1'' and tc1 sgn(theta1') trade
    # against each other, J1 is not identified (0.2 of the truth), and the split fitted with it put 1.16 mN m of
    # Coulomb friction on the motor with a 10 % interval where the truth is 0
    res = identify(DATA / "pd_tri_800hz_tc1_0.csv", "shing1993_servo_friction", encoders="motor+load")
    assert abs(res.backlash - 50e-6) < 1e-6
    assert "J1" in res.not_identified
    lo, hi = res.friction_ci["coulomb1"]
    assert lo <= 0.0 <= hi or "coulomb1" in res.not_identified
    lo, hi = res.friction_ci["coulomb2"]
    assert lo <= 0.25 <= hi or "coulomb2" in res.not_identified
