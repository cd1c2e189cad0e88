"""An MPC file asking for a backlash-aware plan that the design turns into the rigid train's (a gap the encoders or
the drive cannot resolve) says so in its design notes, which track, precision and bench print (review hH: on a
pointing drive with a 4096-count load encoder the MPC came out as the PID with not a word, rigid_reason in the JSON
only)."""

from __future__ import annotations

from pathlib import Path

from gearctl import build_plant, load_controller, load_model
from gearctl.cli import main

POINTING = str(Path(__file__).resolve().parent / "data" / "pointing_17x153_coarse_load.toml")


def test_rigid_plan_is_a_design_note() -> None:
    m = load_model(POINTING)
    mpc = load_controller("mpc", build_plant(m), sensors=m.sensors)
    assert mpc.describe()["gap_model"] == "rigid"
    notes = [n for n in mpc.design_notes if n.startswith("gap model off:")]
    assert len(notes) == 1 and mpc.rigid_reason in notes[0]


def test_gap_plan_and_backlash_zero_have_no_such_note() -> None:
    m = load_model("shing1993_servo")
    plant = build_plant(m)
    assert not [n for n in load_controller("mpc", plant, sensors=m.sensors).design_notes if "gap model off" in n]
    zero = load_controller("mpc", plant, backlash=0.0, sensors=m.sensors)  # asked for: nothing to say
    assert zero.describe()["gap_model"] == "rigid"
    assert not [n for n in zero.design_notes if "gap model off" in n]


def test_track_prints_the_note(capsys) -> None:  # noqa: ANN001
    assert main(["track", POINTING, "mpc", "--duration", "0.02"]) == 0
    assert "gearctl track: note: mpc: gap model off:" in capsys.readouterr().err
