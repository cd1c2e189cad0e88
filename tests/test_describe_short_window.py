"""`gearctl describe --duration` short enough that the measured window (the second half) holds under three periods of
a cycle that is still hitting the flanks: the verdict said the simulation "does not sustain one" (review hH: 0.05 s on
a rack axis, 200 impacts/s in the window); it now says the window is too short, and 0.3 s measures the cycle."""

from __future__ import annotations

from pathlib import Path

from gearctl.describe import describe

DATA = Path(__file__).resolve().parent / "data" / "controller_files"
MODEL, CTRL = DATA / "rack_axis_20x200_nofriction.toml", DATA / "pid_load_30hz.toml"


def test_a_window_too_short_is_said_so() -> None:
    d = describe(MODEL, CTRL, duration=0.05)
    sim = d["simulation"]
    assert sim["impacts_per_second"] > 100 and sim["amplitude"] > d["backlash"] and sim["frequency_hz"] is None
    assert sim["too_short"] and not sim["limit_cycle"]
    assert "too short to measure a cycle" in d["verdict"] and "does not sustain" not in d["verdict"]


def test_a_longer_run_measures_the_cycle() -> None:
    d = describe(MODEL, CTRL, duration=0.3)
    assert d["simulation"]["limit_cycle"] and not d["simulation"]["too_short"]
    assert d["verdict"].startswith("Verdict: a limit cycle, predicted at")
    assert 70 < d["simulation"]["frequency_hz"] < 100  # measured 83.3 Hz
