"""describe on a loop that does not hold its plant: no backlash rattle, but the load swinging by radians at the
torque limit is not "no limit cycle, predicted or simulated" (a reviewer's 100 kg m^2 table under the catalog's
pid_load, fixed gains for a 5e-3 kg m^2 load)."""

from __future__ import annotations

from pathlib import Path

from gearctl.describe import describe

DATA = Path(__file__).parent / "data"


def test_unsettled_loop_is_not_called_quiet() -> None:
    d = describe(DATA / "rotary_table_m5_pid_load.toml", "pid_load", duration=10.0)
    lost = 2 * d["backlash"] / 0.281908  # r_b2 of the 120-tooth, 5 mm module gear [m]
    assert not d["simulation"]["limit_cycle"] and d["simulation"]["load_amplitude"] > 100 * lost
    assert d["verdict"].startswith("Verdict: no backlash limit cycle, but the loop does not settle: the load swings ")
    assert "no limit cycle, predicted or simulated" not in d["verdict"]
    assert d["method_notes"].endswith(d["verdict"])


def test_catalog_verdicts_unchanged() -> None:
    assert describe("shing1993_servo", "pid_load")["verdict"].startswith("Verdict: a limit cycle, predicted at ")
    assert describe("shing1993_servo", "pid")["verdict"].startswith("Verdict: a stable cycle is predicted at ")
