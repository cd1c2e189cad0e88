"""One stage's value on a train: ``--set stage2.backlash=3e-5``, ``--vary stage1.mesh_stiffness=0.8x:1.2x`` (an outside
user could change a key on every stage only: ``stage2.backlash`` was refused as an unknown key)."""

from __future__ import annotations

import re

import pytest

from gearctl import InputError, build_plant, load_model
from gearctl.cli import main
from gearctl.overrides import Scale, perturb_model
from gearctl.sweep import parse_set, sweep

TWO = "servo_2stage_phm09"


def test_a_stage_key_changes_that_stage_alone() -> None:
    m = load_model(TWO)
    b1, b2 = (s.pair.backlash for s in m.stages)
    one = perturb_model(m, {"stage2.backlash": 1e-6})
    assert [s.pair.backlash for s in one.stages] == [b1, 1e-6]
    half = perturb_model(m, {"stage1.backlash": Scale(0.5)})
    assert [s.pair.backlash for s in half.stages] == [0.5 * b1, b2]
    # every stage's first, then the one stage's
    both = perturb_model(m, {"stage2.backlash": 1e-6, "backlash": 3e-5})
    assert [s.pair.backlash for s in both.stages] == [3e-5, 1e-6]
    k = build_plant(m).stages[0].k
    stiff = perturb_model(m, {"stage1.mesh_stiffness": Scale(2.0)})
    assert build_plant(stiff).stages[0].k == pytest.approx(2.0 * k, rel=1e-12)
    assert build_plant(stiff).stages[1].k == build_plant(m).stages[1].k


@pytest.mark.parametrize(("text", "fragment"), [
    ("stage0.backlash=1e-6", "stages are numbered from 1"),
    ("stage1.load_inertia=1", "load_inertia is not a stage's key"),
    ("stage2.backlash=-1", r"stage2.backlash = -1.0 is out of range"),
])
def test_a_bad_stage_key_is_named(text: str, fragment: str) -> None:
    with pytest.raises(InputError, match=fragment):
        parse_set(text)


def test_a_stage_beyond_the_train_is_refused_with_the_count(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["track", TWO, "pid", "--duration", "0.1", "--set", "stage3.backlash=1e-6"]) == 2
    assert "stage3.backlash: servo_2stage_phm09 has 2 stages: expected stage1 .. stage2" in capsys.readouterr().err
    assert main(["track", "shing1993_servo", "pid", "--duration", "0.1", "--set", "stage2.backlash=1e-6"]) == 2
    assert "has 1 stage: expected stage1 .. stage1" in capsys.readouterr().err


def test_track_and_a_sweep_on_one_stage(capsys: pytest.CaptureFixture[str]) -> None:
    import json

    assert main(["track", TWO, "pid", "--duration", "0.2", "--set", "stage2.backlash=1e-6", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["backlash"] == [load_model(TWO).stages[0].pair.backlash, 1e-6]
    sw = sweep(TWO, "pid", vary=["stage2.backlash=0.5x:2x"], runs=3, duration=0.2, engine="serial")
    b2 = load_model(TWO).stages[1].pair.backlash
    vals = [r["params"]["stage2.backlash"] for r in sw.runs]
    assert all(0.5 * b2 <= v <= 2.0 * b2 for v in vals) and len(set(vals)) == 3
    # each run's command rebuilds its plant
    assert all(f"--set stage2.backlash={v!r}" in r["command"] for v, r in zip(vals, sw.runs, strict=True))


def test_an_estimate_error_on_a_pair_is_checked_against_its_stage_key() -> None:
    # on a pair the estimate is checked before any run against the run's backlash: with stage1.backlash varied it took
    # the model's backlash, so an estimate out of range was a failed run instead of the error before any run that
    # --vary backlash gives
    for key in ("backlash", "stage1.backlash"):
        with pytest.raises(InputError, match="run 0 draws estimate = 0.011, which is out of range"):
            sweep("shing1993_servo", "deadzone_inverse", vary=[f"{key}=1e-3", "estimate_error=10"], runs=1, grid=True,
                  duration=0.1, engine="serial")


def test_a_stage_number_with_leading_zeros_is_refused() -> None:
    # stage02.backlash was read as stage2's: a reproducer command should name one spelling
    with pytest.raises(InputError, match=r"without leading zeros \(stage2.backlash\)"):
        parse_set("stage02.backlash=1e-6")


def test_a_check_across_one_stage_keys_names_that_stage(capsys: pytest.CaptureFixture[str]) -> None:
    """An undercut or interference from ``--set stageN.KEY`` said ``teeth1 = 12 is below the undercut limit`` with no
    stage, on a train where every stage has a teeth1 (review hA); range errors already said ``[stage 3]``."""
    m = load_model(TWO)  # pinions of 32 and 48 teeth
    with pytest.raises(InputError, match=r"^\[stage 2\] teeth1 = 12 is below the undercut limit"):
        perturb_model(m, {"stage2.teeth1": 12})
    with pytest.raises(InputError, match=r"^\[stage 1\] x1 = 1.5 .*interference"):
        perturb_model(m, {"stage1.x1": 1.5})
    assert main(["track", TWO, "pid", "--set", "stage2.teeth1=12", "--duration", "0.01"]) == 2
    err = capsys.readouterr().err
    assert "error: [stage 2] teeth1 = 12" in err and "Traceback" not in err


def test_an_estimate_below_the_floor_is_refused_before_any_run_and_a_trains_failed_run_says_it() -> None:
    # the estimate's range lacked the 1 nm floor: estimate=1e-12 passed the plan and failed its run; on a train
    # (whose estimate from estimate_error is known in the run only) the failed run's command lacked --estimate and
    # reproduced a healthy run with the nominal estimate instead of the refusal
    with pytest.raises(InputError, match=r"estimate = 1e-12 is out of range.*at least 1e-09"):
        sweep("shing1993_servo", "deadzone_inverse", vary=["estimate=1e-12,5e-5"], grid=True, duration=0.1,
              engine="serial")
    res = sweep(TWO, "deadzone_inverse", vary=["estimate_error=-0.9999999"], grid=True, duration=0.1,
                engine="serial")
    (row,) = res.runs
    assert row["status"] == "failed" and "at least 1e-09" in row["message"]
    assert row["estimate"] < 1e-9 and f"--estimate {row['estimate']!r}" in row["command"]


@pytest.mark.parametrize(("text", "hint"), [
    ("stage2.backlsh=1e-5", "did you mean 'stage2.backlash' [m]?"),
    # the file's key, in degrees: named as the other file names are (tests/test_set_file_names.py)
    ("stage2.pressure_angle_deg=20", "an override names it stage2.pressure_angle, in rad (20 deg = 0.349)"),
    ("stage1.face_widht=1e-3", "did you mean 'stage1.face_width' [m]?"),
    ("stage1.load_inertia=1", "load_inertia is not a stage's: give it without the prefix"),
])
def test_a_misspelt_stage_key_gets_a_suggestion(text: str, hint: str) -> None:
    # a key without the prefix got "did you mean"; with it, none (stage2.pressure_angle_deg, the file's spelling)
    with pytest.raises(InputError, match=re.escape(hint)):
        parse_set(text)
