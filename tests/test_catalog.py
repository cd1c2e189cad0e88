"""Catalog loading and bad input: one case per field at the API, and every kind of bad model file at
the loader and the command line (exit code 2, one line on stderr naming the file and the key).
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path

import pytest
from numpy.testing import assert_allclose

import gearctl.geometry
from gearctl import (
    GearPair,
    InputError,
    MeshDynamics,
    Sensors,
    Servo,
    load_model,
    model_names,
    pair_geometry,
)
from gearctl.catalog import catalog_dirs
from gearctl.cli import main

DEG = math.pi / 180.0


# --- the catalog ----------------------------------------------------------------------------------------


def test_model_names_are_the_files() -> None:
    files = {p.stem for d in catalog_dirs("models") for p in d.glob("*.toml")}
    assert model_names() == sorted(files)
    assert "shing1993" in model_names()


@pytest.mark.parametrize("name", model_names())
def test_every_catalog_entry_loads_with_a_citation(name: str) -> None:
    model = load_model(name)
    assert model.name == name
    assert model.path is not None and model.path.stem == name
    assert model.source["citation"].strip()
    assert pair_geometry(model.pair).contact_ratio >= 1.0


def test_report_pair_fields(shing) -> None:
    p = shing.pair
    # TR 93-28 section 3.2 data, in SI and radians; rtol 1e-15 (one conversion)
    assert (p.teeth1, p.teeth2) == (20, 80)
    assert_allclose(p.pressure_angle, 20 * DEG, rtol=1e-15)
    assert (p.module, p.face_width, p.backlash) == (0.002, 0.01, 5e-5)
    assert (p.young_modulus, p.poisson_ratio, p.density) == (2.068e11, 0.3, 7800.0)
    assert shing.dynamics.damping_ratio == 0.05


def test_nasa_contact_ratio_matches_source() -> None:
    # NASA/TM-2010-216251 Table 1 (as cited in the model file): contact ratio 1.64, printed to 2 decimals
    eps = pair_geometry(load_model("nasa_glenn_28x28").pair).contact_ratio
    assert_allclose(eps, 1.64, rtol=0, atol=0.005)


def test_liou_contact_ratio_inside_source_range() -> None:
    # Liou et al. 1992 (abstract): addendum varied to span contact ratios 1.20-2.40
    eps = pair_geometry(load_model("liou1992_28x28_hcr").pair).contact_ratio
    assert 1.20 <= eps <= 2.40


def test_overrides_and_variants(shing) -> None:
    assert load_model("shing1993", backlash=0.0).pair.backlash == 0.0
    assert shing.with_backlash(1e-4).pair.backlash == 1e-4
    assert shing.pair.backlash == 5e-5  # frozen: the original is untouched
    with pytest.raises(InputError, match="backlash"):
        load_model("shing1993", backlash=-1e-5)


def test_override_with_unknown_name_is_rejected() -> None:
    # a misspelt override must not return the file's value unchanged
    with pytest.raises(InputError, match="backlsh"):
        load_model("shing1993", backlsh=0.0)


def test_override_of_a_section_absent_from_the_file() -> None:
    # shing1993.toml has no [servo] table; the override must still reach the Servo
    assert load_model("shing1993", motor_inertia=1e-3).servo.motor_inertia == 1e-3


# --- bad input at the API: one case per field -------------------------------------------------------

GEAR_PAIR_CASES = [
    ("teeth1", 12),  # below the undercut limit 17.1 at 20 deg
    ("teeth2", 80.5),  # not a whole number
    ("module", 0.0),  # must be > 0
    ("pressure_angle", 40 * DEG),  # above 35 deg
    ("face_width", 0.0),  # must be > 0
    ("backlash", -1e-6),  # must be >= 0
    ("addendum_coefficient", 0.5),  # contact ratio 0.90 < 1 for the 20 x 80 pair
    ("dedendum_coefficient", 0.9),  # must exceed the addendum (tip clearance)
    ("young_modulus", -2.0e11),
    ("poisson_ratio", 0.5),  # open interval 0 < nu < 0.5
    ("density", 0.0),
    ("inertia1", 0.0),
    ("inertia2", -1.0),
    ("x1", 2.0),  # above the profile-shift range 1.5
    ("x2", -1.5),  # below the profile-shift range -1
]


@pytest.mark.parametrize(("field", "value"), GEAR_PAIR_CASES, ids=[c[0] for c in GEAR_PAIR_CASES])
def test_gear_pair_rejects_bad_field(shing, field: str, value: float) -> None:
    with pytest.raises(InputError, match=field) as info:
        dataclasses.replace(shing.pair, **{field: value})
    assert info.value.field == field
    assert f"{field} = {value!r}" in str(info.value)  # names the field and the value


@pytest.mark.parametrize(
    ("field", "value"),
    [("module", -0.002), ("module", "two"), ("poisson_ratio", 0.0), ("pressure_angle", 5 * DEG),
     ("face_width", math.inf), ("density", math.nan),
     # non-finite whole numbers must be an InputError, not int()'s ValueError / OverflowError
     ("teeth1", math.nan), ("teeth2", math.inf)],
)
def test_gear_pair_rejects_more_bad_values(shing, field: str, value: object) -> None:
    with pytest.raises(InputError, match=field):
        dataclasses.replace(shing.pair, **{field: value})


def test_contact_ratio_below_one_is_reported(shing) -> None:
    # addendum 0.5 m on the report's pair: no undercut (limit 8.5 teeth), no interference, but
    # eps = (sqrt(0.021^2 - rb1^2) + sqrt(0.081^2 - rb2^2) - 0.1 sin 20) / (pi 0.002 cos 20) = 0.9024
    rb1, rb2 = 0.02 * math.cos(20 * DEG), 0.08 * math.cos(20 * DEG)
    eps = (math.sqrt(0.021**2 - rb1**2) + math.sqrt(0.081**2 - rb2**2) - 0.1 * math.sin(20 * DEG)) / (
        math.pi * 0.002 * math.cos(20 * DEG)
    )
    assert eps < 1
    with pytest.raises(InputError, match="contact ratio") as info:
        dataclasses.replace(shing.pair, addendum_coefficient=0.5)
    assert f"{eps:.4g}" in str(info.value)


def test_interference_is_reported(shing, monkeypatch: pytest.MonkeyPatch) -> None:
    """The interference check, reached by switching off the undercut check.

    With the same addendum on both gears the undercut limit already rules out interference (see
    test_geometry.test_undercut_limit_is_the_rack_interference_limit), so no valid GearPair reaches
    the interference check; it is exercised here with the undercut limit patched to zero. A 6-tooth
    pinion against 80 teeth: gear 2's tip reaches past the pinion's base circle.
    """
    monkeypatch.setattr(gearctl.geometry, "undercut_limit", lambda *args, **kwargs: 0.0)
    with pytest.raises(InputError, match="interference") as info:
        dataclasses.replace(shing.pair, teeth1=6)
    assert info.value.field == "addendum_coefficient"
    assert "gear 2" in str(info.value)


MESH_DYNAMICS_CASES = [
    ("damping_ratio", -0.05),
    ("mesh_stiffness", 0.0),
    ("damping_coefficient", -1.0),
    ("contact_law", "sticky"),
]


@pytest.mark.parametrize(("field", "value"), MESH_DYNAMICS_CASES, ids=[c[0] for c in MESH_DYNAMICS_CASES])
def test_mesh_dynamics_rejects_bad_field(shing, field: str, value: object) -> None:
    with pytest.raises(InputError, match=field) as info:
        dataclasses.replace(shing.dynamics, **{field: value})
    assert info.value.field == field


SERVO_CASES = [
    ("motor_inertia", -1e-5),
    ("load_inertia", -1e-3),
    ("viscous_friction1", -0.1),
    ("viscous_friction2", -0.1),
    ("coulomb_friction1", -0.1),
    ("coulomb_friction2", -0.1),
    ("coulomb_velocity", 0.0),
    ("torque_limit", 0.0),
    ("load_torque", math.nan),
    ("friction_law", "viscous"),
    ("intermediate_inertia", (1e-4, -1e-4)),
    ("intermediate_viscous_friction", (math.inf,)),
    ("intermediate_coulomb_friction", 0.1),  # not a list
]


@pytest.mark.parametrize(("field", "value"), SERVO_CASES, ids=[c[0] for c in SERVO_CASES])
def test_servo_rejects_bad_field(field: str, value: float) -> None:
    with pytest.raises(InputError, match=field):
        Servo(**{field: value})


SENSOR_CASES = [
    ("motor_encoder_cpr", 2),
    ("load_encoder_cpr", 1000.5),
    ("motor_noise", -1e-6),
    ("load_noise", 2.0),
    ("load_encoder", "no"),
]


@pytest.mark.parametrize(("field", "value"), SENSOR_CASES, ids=[c[0] for c in SENSOR_CASES])
def test_sensors_rejects_bad_field(field: str, value: float) -> None:
    with pytest.raises(InputError, match=field):
        Sensors(**{field: value})


def test_every_field_has_a_bad_input_case() -> None:
    """Adding a field to an input dataclass without a bad-input case above fails here."""
    for cls, cases in ((GearPair, GEAR_PAIR_CASES), (MeshDynamics, MESH_DYNAMICS_CASES),
                       (Servo, SERVO_CASES), (Sensors, SENSOR_CASES)):
        assert {f.name for f in dataclasses.fields(cls)} == {c[0] for c in cases}, cls.__name__


# --- bad model files: the loader and the command line -------------------------------------------------

MODULE_LINE = "module = 0.002                # m (pitch radii 0.02 m and 0.08 m)\n"
DYN = "[dynamics]\ndamping_ratio"
SERVO = "[servo]\n"
CITATION = 'citation = "T. K. Shing'
MATERIAL = (
    "[material]\nyoung_modulus = 2.068e11      # Pa\npoisson_ratio = 0.3\n"
    "density = 7800.0              # kg/m^3\n"
)

# (id, replacements in shing1993.toml, substrings the one-line message must contain)
FILE_CASES = [
    ("missing_key", [(MODULE_LINE, "")], ["missing key", "module"]),
    ("misspelt_key", [("module = 0.002", "modul = 0.002")], ["modul", "did you mean 'module'"]),
    ("unknown_section",
     [("[dynamics]\ndamping_ratio", "[servoo]\nmotor_inertia = 1e-5\n\n[dynamics]\ndamping_ratio")],
     ["[servoo]", "did you mean [servo]"]),
    ("wrong_type", [("module = 0.002", 'module = "two"')], ["module", "'two'", "not a number"]),
    ("teeth_undercut", [("teeth = 20", "teeth = 12")], ["[gear1] teeth", "12", "undercut"]),
    ("module_zero", [("module = 0.002", "module = 0.0")], ["module", "out of range"]),
    ("module_negative", [("module = 0.002", "module = -0.002")], ["module", "-0.002"]),
    ("face_width_zero", [("face_width = 0.01", "face_width = 0.0")], ["face_width", "out of range"]),
    ("poisson_half", [("poisson_ratio = 0.3", "poisson_ratio = 0.5")], ["poisson_ratio", "0.5"]),
    ("poisson_zero", [("poisson_ratio = 0.3", "poisson_ratio = 0.0")], ["poisson_ratio", "0.0"]),
    ("backlash_negative", [("backlash = 5e-5", "backlash = -5e-5")], ["backlash", "-5e-05"]),
    ("contact_ratio_below_1", [("addendum_coefficient = 1.0", "addendum_coefficient = 0.5")],
     ["addendum_coefficient", "contact ratio", "0.9024"]),
    ("pressure_angle_high", [("pressure_angle_deg = 20.0", "pressure_angle_deg = 40.0")],
     ["pressure_angle_deg", "40", "35", "[deg]"]),
    ("pressure_angle_low", [("pressure_angle_deg = 20.0", "pressure_angle_deg = 5.0")],
     ["pressure_angle_deg", "5", "10", "[deg]"]),
    ("contact_law", [('contact_law = "linear"', 'contact_law = "sticky"')],
     ["contact_law", "sticky", "linear", "no_pull"]),
    # TOML allows nan and inf: one line, exit 2, no traceback
    ("teeth_nan", [("teeth = 20", "teeth = nan")], ["[gear1] teeth", "nan"]),
    ("teeth_inf", [("teeth = 80", "teeth = inf")], ["[gear2] teeth", "inf"]),
    ("toml_syntax", [("module = 0.002", "module = = 0.002")], ["not valid TOML", "line"]),
    ("misspelt_citation", [(CITATION, 'citaton = "T. K. Shing')],
     ["[source] citaton", "did you mean 'citation'"]),
    ("missing_citation", [("citation = ", "doi = ")], ["missing key [source] citation"]),
    ("misspelt_source", [("[source]", "[sauce]")], ["unknown section [sauce]", "did you mean [source]"]),
    # a key typed above the first table header is no section (it read "unknown section [backlash]")
    ("key_outside_sections", [("[source]", "backlash = 5e-5\n[source]")],
     ["key backlash = 5e-05 outside any section", "[pair]", "above the first table header"]),
    ("missing_section", [(MATERIAL, "")], ["missing section [material]"]),
    # physical floors and relative checks (issue 11): each names the key the file has, never a plant quantity
    ("module_floor", [("module = 0.002", "module = 1e-300")], ["[pair] module = 1e-300", "1e-05 <= value <= 0.1 [m]"]),
    ("face_width_floor", [("face_width = 0.01", "face_width = 1e-300")],
     ["[pair] face_width = 1e-300", "1e-05 <= value <= 1 [m]"]),
    ("face_width_per_module", [("face_width = 0.01", "face_width = 1e-4")],
     ["[pair] face_width = 0.0001", "at least 0.1 x module = 0.0002 [m]"]),
    ("backlash_floor", [("backlash = 5e-5", "backlash = 1e-124")],
     ["[pair] backlash = 1e-124", "either 0 or at least 1e-09 [m]"]),
    # the range of every estimate and --backlash (units.BACKLASH), so a model that loads can build every controller
    ("backlash_ceiling", [("backlash = 5e-5", "backlash = 0.01")], ["[pair] backlash = 0.01", "0 <= value < 0.01"]),
    ("gear_too_large", [("teeth = 80", "teeth = 1000"), (MODULE_LINE, "module = 0.05\n")],
     ["[gear2] teeth = 1000 with [pair] module = 0.05", "base radius of 23.49 m", "<= 10 [m]"]),
    ("gear_inertia_light", [("teeth = 20\n", "teeth = 20\ninertia = 1e-300\n")],
     ["[gear1] inertia = 1e-300", "1.96e-08 <= value <= 0.0196 [kg m^2]", "1000x the 1.96e-05 kg m^2"]),
    ("gear_inertia_heavy", [("teeth = 20\n", "teeth = 20\ninertia = 1.0\n")], ["[gear1] inertia = 1.0", "0.0196"]),
    ("gears_over_shaft_cap", [(MODULE_LINE, "module = 0.1\n"), ("face_width = 0.01", "face_width = 1.0")],
     ["[gear2] teeth = 80 with [pair] module = 0.1", "shaft 2 an inertia of 3.137e+06 kg m^2", "at most 1e+06"]),
    ("motor_inertia_over_shaft_cap", [(MODULE_LINE, "module = 0.1\n"), ("face_width = 0.01", "face_width = 1.0"),
                                      ("teeth = 80", "teeth = 20"), (DYN, SERVO + "motor_inertia = 1e6\n\n" + DYN)],
     ["[servo] motor_inertia = 1000000.0", "0 <= value <= 9.877e+05 [kg m^2]", "at most 1e+06 kg m^2"]),
    ("mesh_damping_over_cap", [(MODULE_LINE, "module = 0.1\n"), ("face_width = 0.01", "face_width = 1.0"),
                               ("teeth = 80", "teeth = 20"), ("damping_ratio = 0.05", "damping_ratio = 2.0"),
                               (DYN, SERVO + "motor_inertia = 9e5\nload_inertia = 9e5\n\n" + DYN)],
     ["[dynamics] damping_ratio = 2.0", "c = 2 zeta sqrt(k m_eq)", "at most 1e+08 N s/m",
      "[dynamics] damping_coefficient"]),
    ("smooth_friction_stiff", [(DYN, SERVO + 'coulomb_friction1 = 1e4\nfriction_law = "smooth"\n\n' + DYN)],
     ["[servo] coulomb_friction1 = 10000.0", 'friction_law = "smooth"', "0 <= value <= 0.00196 [N m]",
      "at least 10 us"]),
    ("torque_limit_floor", [(DYN, SERVO + "torque_limit = 1e-300\n\n" + DYN)],
     ["[servo] torque_limit = 1e-300", "1e-06 <= value <= 1e+06 (or inf: none) [N m]"]),
]


@pytest.mark.parametrize(("replace", "expected"), [c[1:] for c in FILE_CASES], ids=[c[0] for c in FILE_CASES])
def test_bad_file_at_loader(write_model, replace, expected: list[str]) -> None:
    path = write_model(replace)
    with pytest.raises(InputError) as info:
        load_model(path)
    message = str(info.value)
    assert str(path) in message
    for text in expected:
        assert text in message, (text, message)


@pytest.mark.parametrize(("replace", "expected"), [c[1:] for c in FILE_CASES], ids=[c[0] for c in FILE_CASES])
def test_bad_file_at_cli(
    write_model, capsys: pytest.CaptureFixture[str], replace, expected: list[str]
) -> None:
    path = write_model(replace)
    assert main(["info", str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert len(err.strip().splitlines()) == 1, err  # one line, no traceback
    assert "Traceback" not in err
    assert str(path) in err
    for text in expected:
        assert text in err, (text, err)


def test_interference_at_cli(write_model, capsys, monkeypatch: pytest.MonkeyPatch) -> None:
    # see test_interference_is_reported: only reachable with the undercut check switched off
    monkeypatch.setattr(gearctl.geometry, "undercut_limit", lambda *args, **kwargs: 0.0)
    path = write_model([("teeth = 20", "teeth = 6")])
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert str(path) in err and "[pair] addendum_coefficient" in err and "interference" in err


def test_unknown_model_name(capsys) -> None:
    assert main(["info", "shing1939"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert "shing1939" in err and "did you mean shing1993" in err
    with pytest.raises(InputError, match="shing1993"):
        load_model("shing1939")


def test_missing_file(tmp_path: Path, capsys) -> None:
    path = tmp_path / "nope.toml"
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and str(path) in err


def test_relative_checks_name_a_train_stage() -> None:
    # a train's stage keys are named [stage i] key, as the train format writes them
    with pytest.raises(InputError) as info:
        load_model("servo_2stage_phm09", face_width=5e-5)
    assert "[stage 1] face_width = 5e-05 is out of range: expected at least 0.1 x module" in str(info.value)
    assert info.value.field == "face_width"
    with pytest.raises(InputError, match=r"\[stage 1\] damping_ratio = 2\.0 is out of range"):
        load_model("servo_2stage_phm09", module=0.1, face_width=1.0, teeth1=20, teeth2=20, damping_ratio=2.0,
                   motor_inertia=9e5, load_inertia=9e5, intermediate_inertia=[9e5])


def test_relative_limits_keep_the_catalog_valid() -> None:
    # every catalog model sits well inside the new relative limits (the closest: Quanser's third stage, a gear
    # 1.57x its solid disk; the thinnest face width 2 modules)
    from gearctl.geometry import pair_geometry
    from gearctl.model import GEAR_INERTIA_FACTOR, MIN_FACE_WIDTH_PER_MODULE, disk_inertia

    for name in model_names():
        for st in load_model(name).stages:
            p, g = st.pair, pair_geometry(st.pair)
            assert p.face_width >= 20 * MIN_FACE_WIDTH_PER_MODULE * p.module, name
            for j in range(2):
                ratio = g.inertia[j] / disk_inertia(p, g.pitch_radius[j])
                assert 1 / GEAR_INERTIA_FACTOR < ratio / 100 and ratio * 100 < GEAR_INERTIA_FACTOR, name


def test_a_folder_named_like_a_catalog_entry_does_not_hide_it(tmp_path: Path,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """``gearctl export MODEL pid --out pid`` then ``gearctl track MODEL pid --exported pid`` in the same folder:
    the bare name still names the catalog's controller (and model), a path to the folder is still refused."""
    from gearctl.files import resolve

    monkeypatch.chdir(tmp_path)
    (tmp_path / "pid").mkdir()
    (tmp_path / "shing1993").mkdir()
    assert resolve("pid", "controllers").name == "pid.toml"
    assert resolve("shing1993", "models").name == "shing1993.toml"
    with pytest.raises(InputError, match="is a folder"):
        resolve(str(tmp_path / "pid"), "controllers")


@pytest.mark.parametrize("kind", ["models", "controllers"])
def test_a_device_or_pipe_is_not_said_not_to_exist(tmp_path: Path, kind: str) -> None:
    """/dev/null or a named pipe given as a file: it exists, so "does not exist" misled (the pipe is not opened:
    reading one would wait for a writer)."""
    from gearctl.files import resolve

    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    for path in (os.devnull, str(fifo)):
        with pytest.raises(InputError, match="is not a regular file"):
            resolve(path, kind)
    with pytest.raises(InputError, match="does not exist"):
        resolve(str(tmp_path / "missing.toml"), kind)
