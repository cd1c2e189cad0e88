"""``--set`` and ``--vary`` given a pair file's own key names (an h2 review): ``profile_shift`` was "unknown model key",
``pressure_angle_deg`` suggested the radian key without saying so; a pair's range errors said "for this stage"."""

from __future__ import annotations

from pathlib import Path

import pytest

from gearctl.cli import main

SHIFT14 = str(Path(__file__).parent / "data" / "h2_shift14_49.toml")


@pytest.mark.parametrize(("key", "says"), [
    ("profile_shift=0.3", "profile_shift is the model file's name ([gear1] and [gear2] profile_shift); --set names it "
                          "x1 (gear 1's) or x2 (gear 2's)"),
    ("teeth=20", "--set names it teeth1 (gear 1's) or teeth2 (gear 2's)"),
    ("inertia=1e-3", "--set names it inertia1 (gear 1's) or inertia2 (gear 2's) [kg m^2]"),
    ("pressure_angle_deg=25", "--set names it pressure_angle, in rad (20 deg = 0.349)"),
])
def test_set_names_the_key_it_takes(capsys: pytest.CaptureFixture[str], key: str, says: str) -> None:
    assert main(["track", SHIFT14, "pid", "--set", key]) == 2
    err = capsys.readouterr().err
    assert says in err and "unknown model key" not in err and err.count("gearctl track: error:") == 1


def test_vary_names_the_key_it_takes(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sweep", SHIFT14, "pid", "--vary", "profile_shift=0:0.2", "--runs", "2", "--workers", "1"]) == 2
    assert "--vary names it x1 (gear 1's) or x2 (gear 2's)" in capsys.readouterr().err


def test_the_names_it_takes_work(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["track", SHIFT14, "pid", "--set", "x1=0.4", "--duration", "0.2", "--json"]) == 0
    capsys.readouterr()


def test_a_pairs_range_error_names_no_stage(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "loose.toml"
    f.write_text(Path(SHIFT14).read_text().replace("backlash = 3e-5", "backlash = 7e-4"))
    assert main(["info", str(f)]) == 2
    err = capsys.readouterr().err
    assert "[pair] backlash = 0.0007 is out of range: expected at most 0.5 x module = 0.000625 [m]\n" in err
    assert "stage" not in err


@pytest.mark.parametrize(("key", "says"), [
    ("stage2.pressure_angle_deg=25", "stage2.pressure_angle_deg: pressure_angle_deg is the model file's name ([pair] "
                                     "or [[stage]] pressure_angle_deg, in degrees); an override names it "
                                     "stage2.pressure_angle, in rad"),
    ("stage1.profile_shift=0.1", "an override names it stage1.x1 (gear 1's) or stage1.x2 (gear 2's)"),
    ("stage3.teeth=20", "an override names it stage3.teeth1 (gear 1's) or stage3.teeth2 (gear 2's)"),
])
def test_a_stage_key_with_the_files_name_is_told_the_overrides(capsys: pytest.CaptureFixture[str], key: str,
                                                                says: str) -> None:
    # the {pre} of the hints was always "": stage2.pressure_angle_deg was "not a stage's key", stage1.profile_shift
    # got no hint at all and stage3.teeth was offered stage3.teeth2 alone
    assert main(["track", "servo_3stage_quanser_srv02", "pid", "--set", key]) == 2
    err = capsys.readouterr().err
    assert says in err and "not a stage's key" not in err, err


@pytest.mark.parametrize(("argv", "ratio"), [
    (["track", "shing1993_servo", "pid", "--set", "teeth1=30", "--duration", "0.2"], "2.66667, the controller was "
                                                                                     "designed for 4 "),
    (["track", "servo_2stage_phm09", "pid", "--set", "stage2.teeth2=90", "--duration", "0.2"], "5.625, the controller "
                                                                                              "was designed for 5 "),
    (["track", "shing1993_servo", "pid", "--set", "backlash=2x", "--duration", "0.2"], None),
])
def test_set_that_changes_the_ratio_is_noted(capsys: pytest.CaptureFixture[str], argv: list[str],
                                             ratio: str | None) -> None:
    # --set teeth1=30 on the 4:1 pair ran a design for 4:1 on a 2.67:1 plant (0.55 rad RMS) with no word of why (an
    # h1 review); a --set that keeps the ratio gets no note
    main(argv)
    err = capsys.readouterr().err
    if ratio is None:
        assert "gear ratio" not in err
    else:
        assert f"gearctl track: note: --set: the true plant's gear ratio is {ratio}" in err


def test_set_a_factor_of_a_zero_nominal_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    # coulomb_friction2 is 0 on the catalog servo: `--set coulomb_friction2=2x` ran the nominal plant without a word
    # (`--vary` with the same factor is refused); 0x is 0 whatever the nominal, and a factor of a non-zero key runs
    assert main(["track", "shing1993_servo", "pid", "--set", "coulomb_friction2=2x", "--duration", "0.2"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the nominal coulomb_friction2 is 0, so every factor of it is 0" in err, err
    assert main(["track", "shing1993_servo", "pid", "--set", "coulomb_friction2=0x", "--duration", "0.2"]) == 0
    assert main(["track", "shing1993_servo", "pid", "--set", "backlash=2x", "--duration", "0.2"]) == 0
