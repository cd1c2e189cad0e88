"""What the CLI says on input an external review found unclear: every refusal names the field and the allowed range,
exit code 2, and the figures a command prints say where they come from."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gearctl.cli import main
from gearctl.errors import InputError

ROOT = Path(__file__).resolve().parents[1]


def _refusal(capsys, argv: list[str]) -> str:  # noqa: ANN001
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


@pytest.mark.parametrize("command", ["track", "precision"])
def test_backlash_override_beyond_half_a_module_is_refused(capsys, command: str) -> None:  # noqa: ANN001
    # the file and --set refuse b > 0.5 module (2 mm module: 1 mm); the --backlash override did not
    err = _refusal(capsys, [command, "shing1993_servo", "pid", "--backlash", "5e-3"])
    assert "backlash = 0.005" in err and "0.5 x module = 0.001" in err


def test_backlash_override_names_the_stage_of_a_train(capsys) -> None:  # noqa: ANN001
    err = _refusal(capsys, ["track", "servo_3stage_quanser_srv02", "pid", "--backlash", "2e-4"])
    assert "on stage 1" in err and "0.5 x module = 0.00015" in err


def test_a_precision_program_too_long_names_what_to_lower(capsys) -> None:  # noqa: ANN001
    err = _refusal(capsys, ["precision", "shing1993_servo", "pid", "--travel", "1e4"])
    assert "travel = 10000" in err and "lasts 100029 s" in err and "np.float64" not in err


def _model_with(tmp_path: Path, old: str, new: str | None) -> Path:
    text = (ROOT / "models" / "shing1993.toml").read_text()
    lines = [ln for ln in text.splitlines() if not ln.startswith(old)] if new is None else None
    out = "\n".join(lines) if lines is not None else text.replace(old, new, 1)
    assert out != text
    p = tmp_path / "m.toml"
    p.write_text(out)
    return p


def test_a_missing_key_states_its_range(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    err = _refusal(capsys, ["info", str(_model_with(tmp_path, "module", None))])
    assert "missing key [pair] module" in err and "1e-05 <= value <= 0.1 [m]" in err


def test_a_missing_degree_key_states_its_range_in_degrees(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    # the key is typed in degrees: its range is said in degrees, not in the radians it is kept in
    err = _refusal(capsys, ["info", str(_model_with(tmp_path, "pressure_angle_deg", None))])
    assert "missing key [pair] pressure_angle_deg" in err and "10 <= value <= 35 [deg]" in err


@pytest.mark.parametrize("value", ["[]", "[1e-5, 1e-5]"])
def test_a_train_refuses_a_list_per_intermediate_shaft_of_the_wrong_length(tmp_path: Path, capsys,  # noqa: ANN001
                                                                          value: str) -> None:
    # servo_2stage_phm09 has one intermediate shaft: an explicit empty list is no value for it
    text = (ROOT / "models" / "servo_2stage_phm09.toml").read_text()
    p = tmp_path / "t.toml"
    p.write_text(text.replace("[servo]\n", f"[servo]\nintermediate_inertia = {value}\n", 1))
    err = _refusal(capsys, ["info", str(p)])
    assert "[servo] intermediate_inertia" in err and "expected one per intermediate shaft (1" in err


@pytest.mark.parametrize("old, new, said", [("teeth = 20", 'teeth = "20"', "a string"),
                                            ("backlash = ", "backlash = true #", "true/false")])
def test_a_value_of_the_wrong_type_is_called_so(tmp_path: Path, capsys, old: str, new: str,  # noqa: ANN001
                                                said: str) -> None:
    text = (ROOT / "models" / "shing1993.toml").read_text()
    assert old in text
    err = _refusal(capsys, ["info", str(_model_with(tmp_path, old, new))])
    assert "is not a number" in err and said in err and "expected" in err


def test_info_says_which_stiffness_and_damping_are_given(capsys) -> None:  # noqa: ANN001
    # shing1993_report gives the report's k and c: info must not label the given c as eq 38's
    assert main(["info", "shing1993_report"]) == 0
    out = capsys.readouterr().out
    assert "(given in the file)" in out and "eq 38, consistent form" not in out
    assert main(["info", "shing1993", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["damping_coefficient_given"] is False and d["mesh_stiffness_given"] is False
    assert d["plant_stiffness"] == pytest.approx(d["mesh_stiffness"]["mean"], rel=1e-12)


WATCH = (Path(__file__).parent / "data" / "watch_m02.toml").read_text()


def test_a_diverging_simulation_says_which_inputs_to_lower(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    # a watch-size pair (shafts of 8e-11 and 2e-8 kg m^2) under the load case's 1 N m
    p = tmp_path / "watch.toml"
    p.write_text(WATCH)
    err = _refusal(capsys, ["simulate", str(p), "--case", "load"])
    assert "diverged" in err and "--torque1" in err and "kg m^2" in err


def test_penetration_far_beyond_elastic_is_warned(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    # the free case's 50 rad/s on the catalog pair: 50 um, 2.5 % of the 2 mm module, no warning; at 500 rad/s the
    # teeth would interpenetrate by 5 % of the module and more
    assert main(["simulate", "shing1993_servo", "--json"]) == 0
    assert "warning" not in capsys.readouterr().err
    assert main(["simulate", "shing1993_servo", "--omega1", "500", "--json"]) == 0
    err = capsys.readouterr().err
    assert "interpenetrate" in err and "of the module" in err


def test_python_build_plant_refuses_the_same_override() -> None:
    from gearctl.catalog import load_model
    from gearctl.plant import build_plant

    with pytest.raises(InputError, match="0.5 x module"):
        build_plant(load_model("shing1993_servo"), backlash=2e-3)


def test_a_load_step_beyond_the_motor_is_said(capsys: pytest.CaptureFixture[str]) -> None:
    """The step reference's 0.5 N m load step on a 1 mN m instrument servo (ratio 4: 4 mN m at the load) ran off
    with only 'saturated' and 'growing error' warnings; track now says the step is 125 times what the motor holds."""
    from gearctl.cli import main

    data = Path(__file__).parent / "data" / "instrument_1mNm.toml"
    main(["track", str(data), "pid", "--reference", "step", "--duration", "1.2"])
    err = capsys.readouterr().err
    assert "load step, 0.5 N m, is 125 times the torque the motor can put on the load" in err
    main(["track", "shing1993_servo", "pid", "--reference", "step", "--duration", "1.2"])
    assert "load step" not in capsys.readouterr().err


@pytest.mark.parametrize(("argv", "says"), [
    (["track", "shing1993_servo", "pid", "--duration", "-1"], "argument --duration: -1 is out of range: expected 0 <"),
    (["track", "shing1993_servo", "pid", "--plant", "foo"], "argument --plant: invalid choice: 'foo'"),
    (["precision", "shing1993_servo", "pid", "--targets", "x"], "argument --targets:"),
])
def test_a_bad_option_value_is_one_line(capsys, argv: list[str], says: str) -> None:  # noqa: ANN001
    # argparse printed its usage block above such a line; like every other input error it is one line now
    lines = _refusal(capsys, argv).splitlines()
    assert len(lines) == 1 and says in lines[0], lines
    assert lines[0].startswith(f"gearctl {argv[0]}: error: ") and lines[0].endswith(f"(usage: gearctl {argv[0]} -h)")


def test_an_unknown_option_keeps_the_usage(capsys) -> None:  # noqa: ANN001
    err = _refusal(capsys, ["track", "--bogus"])
    assert err.startswith("usage: gearctl track") and "unrecognized arguments: --bogus" in err


def test_interference_names_the_other_shift_too(capsys) -> None:  # noqa: ANN001
    # a reviewer raised stage 2's x1 to 1.2 (x2 = -0.1) and was told of x2 alone: gear 2's tip reaches below the
    # pinion's involute, which both shifts move. The other key's limit is given too
    err = _refusal(capsys, ["info", str(ROOT / "tests" / "data" / "interference_x1_raised.toml")])
    assert "[stage 2] x2 = -0.1" in err and "interference" in err
    assert "or x1 = 1.2 at most 1.07" in err


def test_describe_names_the_intermediate_shafts_coulomb_friction(capsys, tmp_path: Path) -> None:  # noqa: ANN001
    # on a train the design pair's motor side lumps the intermediate shafts' Coulomb friction: a reviewer was told to
    # set coulomb_friction1/2 to 0, both already 0
    text = (ROOT / "models" / "servo_3stage_quanser_srv02.toml").read_text()
    text = text.replace("load_torque = 0.0", "load_torque = 0.0\nintermediate_coulomb_friction = [1e-4, 2e-4]", 1)
    path = tmp_path / "train.toml"
    path.write_text(text)
    err = _refusal(capsys, ["describe", str(path), "pid"])
    assert "set the model's intermediate_coulomb_friction to 0" in err and "coulomb_friction1" not in err


def test_a_stage_mode_on_a_pair_says_it_is_a_pair(capsys) -> None:  # noqa: ANN001
    err = _refusal(capsys, ["linearize", "shing1993_servo", "--mode", "stage1"])
    assert "is a pair" in err and "1 <= K <= 1" not in err
    err = _refusal(capsys, ["linearize", "servo_3stage_quanser_srv02", "--mode", "stage4"])
    assert "1 <= K <= 3" in err


def test_info_json_of_a_train_has_its_ratio(capsys) -> None:  # noqa: ANN001
    assert main(["info", "servo_3stage_quanser_srv02", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["ratio"] == pytest.approx(70.0, rel=1e-12) and len(d["stages"]) == 3
