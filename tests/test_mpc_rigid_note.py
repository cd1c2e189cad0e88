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


def test_rigid_for_upstream_gaps_names_them_not_the_noise() -> None:
    """On a train whose stages before the last hold over half the lost motion, the contact tolerance (which takes
    those gaps in) exceeds half the gap and the plan is rigid. The reason said "the measured gap's noise (1.3e-05 m
    std ...)", a std the design never had: the 2^20-count encoders' gap noise is 200x smaller (review hA, a speed
    increaser 72 -> 24 teeth before a 30 -> 30 stage). It names the upstream share now."""
    from gearctl.design.mpc import upstream_gap_share

    m = load_model("servo_2stage_phm09")
    plant = build_plant(m, backlash=(4e-5, 1e-5))  # the first stage: 2/3 of the lost motion
    mpc = load_controller("mpc", plant, sensors=m.sensors)
    assert mpc.describe()["gap_model"] == "rigid"
    assert mpc._gap_reading_std() < 0.01 * mpc.settings.backlash  # the encoders resolve the gap
    assert "noise" not in mpc.rigid_reason
    assert f"{upstream_gap_share(plant):.0%} of the lost motion" in mpc.rigid_reason
    # the catalog train (a third upstream) keeps its gap plan
    assert load_controller("mpc", build_plant(m), sensors=m.sensors).rigid_reason == ""
