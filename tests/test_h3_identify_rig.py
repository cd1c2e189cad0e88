"""What a test engineer feeding rig logs to ``gearctl identify`` met (helper h3, second round).

Oracles: the user's model file and what ``--write-model`` writes from it (keys the user gave come back as given);
the refusal of a log whose units are off by 1000x names the column and the likely cause.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from gearctl import identify as ident
from gearctl import load_model
from gearctl.cli import main

DATA = Path(__file__).resolve().parent / "data" / "logs"
CHIRP = DATA / "other_sim_chirp_5khz.csv"  # another simulator's log of shing1993_servo_friction, b = 50 um
MODELS = Path(__file__).resolve().parents[1] / "models"


def _user_model(tmp_path: Path) -> Path:
    """shing1993_servo_friction as a user keeps it: with a url and a doi in its [source]."""
    text = (MODELS / "shing1993_servo_friction.toml").read_text()
    text = text.replace("[source]\n", '[source]\nurl = "https://rig.example/servo-a"\ndoi = "10.1000/rig.42"\n', 1)
    path = tmp_path / "rig.toml"
    path.write_text(text)
    return path


def test_write_model_keeps_the_sources_url_and_doi(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the written [source] kept citation, table and notes, and dropped the user's url and doi
    model = _user_model(tmp_path)
    out = tmp_path / "out.toml"
    assert main(["identify", str(CHIRP), "--model", str(model), "--write-model", str(out)]) == 0
    src = tomllib.loads(out.read_text())["source"]
    assert src["url"] == "https://rig.example/servo-a"
    assert src["doi"] == "10.1000/rig.42"
    assert str(CHIRP) in src["citation"]
    assert load_model(out).source["doi"] == "10.1000/rig.42"  # a model gearctl reads
    capsys.readouterr()


def _scaled_log(tmp_path: Path, name: str, factors: tuple[float, float, float, float]) -> Path:
    """The chirp log with its columns t, torque, theta1, theta2 multiplied by ``factors`` (a unit slip)."""
    a = np.loadtxt(CHIRP, delimiter=",", comments="#", skiprows=4) * np.array(factors)
    path = tmp_path / name
    np.savetxt(path, a, delimiter=",", header="t,torque,theta1,theta2", comments="", fmt="%.10g")
    return path


def _refusal(path: Path, capsys: pytest.CaptureFixture[str]) -> str:
    assert main(["identify", str(path), "--model", "shing1993_servo_friction"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1
    return err


def test_a_clock_scaled_down_is_refused_on_t_not_as_a_motor_that_does_not_move(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # a 5 kHz log whose t was divided by 200 (period 1 us, the shortest the reader takes): the motor's reading still
    # changes by 1.1 rad and reverses, but the window of steady motion (capped at an eighth of the log) never holds
    # one sign. It was refused as "column theta1: the motor does not move (its reading changes by 1.12 rad)"
    err = _refusal(_scaled_log(tmp_path, "t_scaled.csv", (1 / 200, 1, 1, 1)), capsys)
    assert "column t:" in err and "does not move" not in err
    assert re.search(r"lasts 0\.0025 s", err) and "t in ks" in err
    # a motor that truly stands still is still said so
    a = np.loadtxt(CHIRP, delimiter=",", comments="#", skiprows=4)
    a[:, 2] = a[0, 2]
    path = tmp_path / "still.csv"
    np.savetxt(path, a, delimiter=",", header="t,torque,theta1,theta2", comments="", fmt="%.10g")
    assert "column theta1: the motor does not move (its reading changes by 0 rad)" in _refusal(path, capsys)


@pytest.mark.parametrize(("factors", "column", "hint"), [
    ((1, 1, 1e3, 1e3), "theta1", "(theta1 in mrad, or torque in kN m?)"),  # both encoders in mrad: no hint before
    ((1, 1e-3, 1, 1), "theta1", "(theta1 in mrad, or torque in kN m?)"),  # the same balance: torque in kN m
    ((1, 1, 1e3, 1), "theta2", "(theta1 in mrad?)"),  # was "(a dead load encoder?)", a load encoder that moves
    ((1, 1, 1, 1e3), "theta2", "(theta2 in mrad?)"),  # no hint before
])
def test_a_column_in_milliradians_or_kilonewton_metres_is_named(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], factors: tuple[float, float, float, float], column: str,
        hint: str) -> None:
    err = _refusal(_scaled_log(tmp_path, "scaled.csv", factors), capsys)
    assert f"column {column}:" in err and hint in err
    assert "dead load encoder" not in err


def test_inertia_hints_name_the_clock_the_way_it_is_off() -> None:
    # a lumped inertia 1e-6 of the model's is a clock 1000x too fast (t divided by 1000 once too often): the hint
    # said "t in us", whose numbers are 1e6x too large and give an inertia 1e12x too large
    hint = ident._unit_hint(1e-6, ident.INERTIA_HINTS)
    assert "1000x" in hint and "us" not in hint
    assert ident._unit_hint(1e6, ident.INERTIA_HINTS) == " (t in ms?)"



@pytest.mark.xfail(strict=True, reason="open: an encoder's position-dependent error biases b with both encoders")
def test_an_encoders_interpolation_error_leaves_b_inside_its_interval() -> None:
    # h3's own rig simulator (tests/data/logs/h3b_sim): true b = 3 um, 2^22-count encoders with a 1 % interpolation
    # error (0.58 and 1.15 um along the line of action). A rest whose motor still creeps reads flat only near an
    # extreme of the error, and the plateaus kept are the outer ones: b 4.12 um, 95 % interval 3.42-4.82 um (2-6 um
    # read 1.1-1.2 um high). A term for the wander of s along a flank while the shafts move in contact covered it,
    # but also widened a rattling closed loop's interval tenfold (its motor bounces off the flank while moving).
    # h4 measured that wander (90th minus 50th percentile of the deflection-corrected s over each steady contact
    # motion, median over the plateaus): 1.06 um here (0.26 b), but 2.6 um on gearctl's own excite log of the h1 pair
    # (b right, 59.85 um), 3.0 um on the rattling PD log and 4.9 and 5.2 um on two other_sim logs whose b is right:
    # as an interval term it widens correct logs 4-8x, as a flag at a share of b it would be tuned to this log
    res = ident.identify(DATA / "h3b_sim" / "interpolation_error_b3um.csv", "shing1993_servo_friction")
    lo, hi = res.backlash_ci
    assert lo <= 3e-6 <= hi or "backlash" in res.not_identified


def test_a_units_row_under_the_header_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # a data logger's export with a units row: refused as "line 2: column t = 's' is not a number", now with the cause
    lines = CHIRP.read_text().splitlines()
    head = lines.index("t,torque,theta1,theta2")
    path = tmp_path / "units.csv"
    path.write_text("\n".join(lines[:head + 1] + ["s,N m,rad,rad"] + lines[head + 1:]) + "\n")
    err = _refusal(path, capsys)
    assert f"line {head + 2}: column t = 's' is not a number: a units row?" in err
    # a single bad field in the first row is not taken for one
    path.write_text("\n".join(lines[:head + 1] + ["0,abc,0.75,2.38"] + lines[head + 2:]) + "\n")
    err = _refusal(path, capsys)
    assert "column torque = 'abc' is not a number" in err and "units row" not in err


@pytest.mark.xfail(strict=True, reason="open: LuGre load friction on a speed-increasing pair, J1 +7.3 % and J2 -13.8 % "
                   "with intervals that miss by 0.4 % and 0.15 % of the truth, unflagged (the Coulomb friction holds "
                   "its truth since h4's Student t interval of the split)")
def test_a_speed_increasing_pair_with_lugre_friction_is_honest() -> None:
    # h3's rig simulator (tests/data/logs/h3b_sim): the motor on the 80-tooth gear (ratio 0.25), LuGre friction on
    # the load. b is right (49.5 um [45.5, 53.5] for 50); J1 +7.3 % [7.05e-3, 8.01e-3], J2 -13.8 % [1.59e-4, 2.19e-4]
    # come out with intervals that miss and no flag (before h4 also the motor's Coulomb friction, 7.4 mN m [2.7, 12.2]
    # for 0, and the load's 9 % low; the split's Student t interval now holds both). h4: the two halves of the log
    # agree (J1 7.29e-3 and 7.59e-3 from the first and the second half: the bias is the same in both, a split-half
    # check does not see it); the contact rows alone give J1 + J2/N^2 right (1.05e-2) and the free flights split it:
    # without the load's free flights J1 is 6.63e-3, but that shift is within what the block's information explains
    # (z = -1.3), and the free-flight blocks alone are too weak for a closure test (J1 + J2/N^2 from them is 24 %
    # under the contact's here, z = -1.8, and 76 % under it, z = -8.3, on gearctl's own excite log of the h1 pair,
    # whose values are right). The re-simulation passes both gates (0.18 b RMS, 0.37 b in the gap; the chirp log,
    # right, reads 0.16 b and 0.31 b)
    folder = DATA / "h3b_sim"
    res = ident.identify(folder / "speed_up_lugre.csv", folder / "speed_up_rig.toml")
    truth = {"J1": 0.0070185, "J2": 0.0002196, "coulomb1": 0.0, "coulomb2": 0.02}
    assert res.backlash_ci[0] <= 5e-5 <= res.backlash_ci[1]
    cis = {**res.inertia_ci, **res.friction_ci}
    missed = [k for k, v in truth.items() if k not in res.not_identified and not cis[k][0] <= v <= cis[k][1]]
    assert missed == []
