"""identify on an outside user's pair (h1's review): gearctl's own excitation log of a 25 deg 12 x 50 pair with
profile shift, heavy load (J2 / d2 = 11.5 s), no Coulomb friction."""

from __future__ import annotations

from pathlib import Path

import pytest

from gearctl import build_plant, load_model
from gearctl.excite import record_excitation
from gearctl.identify import identify

MODEL = str(Path(__file__).parent / "data" / "h1_pair_12x50_pa25_shifted.toml")


@pytest.mark.xfail(strict=True, reason=(
    "open: the load's viscous friction comes out 6.9e-9 N m s/rad (gearctl excite; 2.3e-10 from record_excitation's "
    "defaults) with a 95 % interval [0, 4.1e-7] against a true "
    "1e-3, not flagged (the motor's 1.7e-5 for 1e-5 and Coulomb friction of 4.6e-5 and 5.7e-5 N m where the truth has "
    "none: the total viscous torque N^2 d1 + d2 read 4x low and traded against Coulomb friction; the re-simulation "
    "misses by 0.2 b, under the 0.25 b gate). b is right: 59.85 um [59.34, 60.35] for 60"))
def test_every_identified_quantity_of_a_heavy_viscous_load_holds_its_truth() -> None:
    model = load_model(MODEL)
    ex = record_excitation(model, duration=10.0)
    res = identify(ex.log, model)
    truth = {"viscous1": model.servo.viscous_friction1, "viscous2": model.servo.viscous_friction2,
             "coulomb1": 0.0, "coulomb2": 0.0}
    lo, hi = res.backlash_ci
    assert lo <= build_plant(model).backlash <= hi
    for key, value in truth.items():
        if key in res.not_identified:
            continue
        a, b = res.friction_ci[key]
        assert a <= value <= b, (key, res.friction[key], (a, b), value)
