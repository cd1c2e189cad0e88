"""A servo without a load encoder (``[sensors] load_encoder = false``): the file, the loop, the bench, the log."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from gearctl import Sensors, build_plant, load_controller, load_model, reference, simulate_closed_loop
from gearctl.bench import BenchSpec
from gearctl.cli import main
from gearctl.errors import InputError
from gearctl.excite import record_excitation

DATA = Path(__file__).parent / "data"
NO_LOAD = DATA / "no_load_encoder.toml"


def test_the_file_says_the_load_encoder_is_missing() -> None:
    m = load_model(NO_LOAD)
    assert m.sensors.load_encoder is False
    assert m.sensors.motor_encoder_cpr == 2**20
    assert load_model("shing1993_servo_friction").sensors.load_encoder is True


@pytest.mark.parametrize(("values", "field"), [
    ({"load_encoder": False, "load_encoder_cpr": 4096}, "load_encoder_cpr"),
    ({"load_encoder": False, "load_noise": 1e-6}, "load_noise"),
    ({"load_encoder": "no"}, "load_encoder"),
    ({"load_encoder": 0}, "load_encoder"),
])
def test_a_contradictory_or_mistyped_table_is_refused(values: dict, field: str) -> None:
    with pytest.raises(InputError) as exc:
        Sensors(**values)
    assert exc.value.field == field
    assert field in str(exc.value)


def test_a_file_with_a_missing_encoder_and_its_resolution_names_the_key(tmp_path: Path,
                                                                         capsys: pytest.CaptureFixture[str]) -> None:
    text = NO_LOAD.read_text().replace("\nload_encoder = false", "\nload_encoder_cpr = 4096\nload_encoder = false")
    f = tmp_path / "contradiction.toml"
    f.write_text(text)
    assert main(["info", str(f)]) == 2
    err = capsys.readouterr().err
    assert "[sensors] load_encoder_cpr = 4096" in err and "load_encoder = false" in err, err


@pytest.mark.parametrize("name", ["mpc", "pid_load", "adaptive_inverse"])
def test_a_controller_that_reads_the_load_encoder_is_refused(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["track", str(NO_LOAD), name, "--duration", "0.1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("gearctl track: error: [sensors] load_encoder = false"), err
    assert f"controller {name!r}" in err[0] and "motor encoder alone" in err[0]
    # the Python API: at design time with the model's sensors, and at run time without them
    m = load_model(NO_LOAD)
    plant = build_plant(m)
    with pytest.raises(InputError, match="load_encoder = false"):
        load_controller(name, plant, sensors=m.sensors)
    ctrl = load_controller(name, plant)
    with pytest.raises(InputError, match="load_encoder = false"):
        simulate_closed_loop(plant, ctrl, reference("sine"), 0.01, sensors=m.sensors)


@pytest.mark.parametrize("name", ["pid", "deadzone_inverse", "reversal_offset"])
def test_motor_encoder_controllers_run_as_with_a_load_encoder(name: str) -> None:
    # they never read the load encoder: the run is bit for bit the one on the servo that has one
    m = load_model(NO_LOAD)
    with_load = dataclasses.replace(m.sensors, load_encoder=True, load_encoder_cpr=2**20)
    plant = build_plant(m)
    runs = []
    for sensors in (m.sensors, with_load):
        ctrl = load_controller(name, plant, sensors=sensors)
        runs.append(simulate_closed_loop(plant, ctrl, reference("sine"), 0.5, sensors=sensors))
    assert np.array_equal(runs[0].x, runs[1].x)
    assert np.all(np.isnan(runs[0].y_load))


def test_the_bench_leaves_out_what_needs_the_missing_encoder() -> None:
    spec = BenchSpec(models=(str(NO_LOAD),), plants=("improved",), references=("sine",))
    skipped = spec.skipped()
    assert {s["controller"] for s in skipped} == {"mpc", "pid_load", "adaptive_inverse"}
    assert all("load_encoder = false" in s["reason"] for s in skipped)
    ran = {r.tags["controller"] for r in spec.runs()} | {r["controller"] for r in spec.precision_runs()}
    assert ran == {"pid", "deadzone_inverse", "reversal_offset"}
    # a controller the user names is run, and fails with the reason
    assert BenchSpec(models=(str(NO_LOAD),), controllers=("mpc",)).skipped() == []
    # a servo with a load encoder runs every catalog controller
    assert BenchSpec(models=("shing1993_servo",)).skipped() == []


def test_the_log_has_no_load_column(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ex = record_excitation(NO_LOAD, duration=1.0)
    assert ex.log.theta2 is None
    out = tmp_path / "log.csv"
    assert main(["excite", str(NO_LOAD), "--duration", "1", "--out", str(out)]) == 0
    assert "samples: t, torque, theta1, reference" in capsys.readouterr().out
    header = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")][0]
    assert header == "t,torque,theta1,reference"
    assert main(["info", str(NO_LOAD)]) == 0
    assert "load none" in capsys.readouterr().out


def test_describe_refuses_a_load_feedback_pid(capsys: pytest.CaptureFixture[str]) -> None:
    # a review: describe ran pid_load on a servo without a load encoder, where every other command refused it
    assert main(["describe", str(NO_LOAD), "pid_load", "--duration", "0.2"]) == 2
    assert "load_encoder = false" in capsys.readouterr().err


def test_excite_noise_goes_to_the_motor_encoder_alone(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # --noise is "on both encoders": on a servo without a load encoder it was refused naming a --set the user never
    # typed; it is the motor encoder's noise there
    out = tmp_path / "log.csv"
    assert main(["excite", str(NO_LOAD), "--duration", "1", "--noise", "1e-6", "--out", str(out)]) == 0, \
        capsys.readouterr().err
    assert "theta2" not in out.read_text().split("\n#")[-1]


def test_identify_says_when_the_log_has_a_load_encoder_the_model_lacks(tmp_path: Path) -> None:
    from gearctl.identify import identified_model, identify

    log = record_excitation("shing1993_servo_friction", duration=4.0).log  # both encoders
    res = identify(log, NO_LOAD)
    assert res.encoders == "motor+load"
    assert any("no load encoder" in w and "--encoders motor" in w for w in res.warnings)
    sensors = identified_model(res, load_model(NO_LOAD))["sensors"]
    assert sensors["load_encoder"] is False and "load_noise" not in sensors and "load_encoder_cpr" not in sensors


def test_a_bench_of_several_models_names_them() -> None:
    from gearctl.bench import bench_table, run_bench

    spec = BenchSpec(models=("shing1993_servo", str(NO_LOAD)), controllers=("pid", "mpc"), plants=("improved",),
                     references=("sine",), duration=0.3, precision=False)
    table = bench_table(run_bench(spec, jobs=1))
    lines = table.splitlines()
    assert lines[2].split()[:3] == ["model", "controller", "reference"]
    assert any(ln.startswith(str(NO_LOAD)) and " pid " in ln for ln in lines)
    # the run the missing encoder refuses names its model, as the bench was given it
    assert f"FAILED: mpc on {NO_LOAD}, improved (sine): [sensors] load_encoder = false" in table
