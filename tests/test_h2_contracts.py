"""Contracts the second-wave issues name, checked where an audit found the code short of them (one light test per
fix): each is what a command or the Python API promises to an outside caller."""

from __future__ import annotations

import pytest

from gearctl.cli import main


def _refusal(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err


@pytest.mark.parametrize("argv", [
    ["bench", "--controllers", "pid", "--plants", "improved", "--references", "sine", "--no-precision", "--jobs", "1",
     "--quiet", "--duration", "0.0004"],
    ["sweep", "shing1993_servo", "pid", "--runs", "2", "--workers", "1", "--quiet", "--duration", "0.0004"],
])
def test_bench_and_sweep_refuse_a_run_shorter_than_one_sample(capsys: pytest.CaptureFixture[str],
                                                               argv: list[str]) -> None:
    # track refused it; bench and sweep ran every run into the same error and ended with exit 0 ("diverged 100%")
    err = _refusal(capsys, argv)
    assert "--duration = 0.0004 is shorter than one sample of pid (0.001 s)" in err
    assert "expected --duration >= 0.0005 s" in err


def test_bench_names_the_environment_variable_of_a_scheduler_it_cannot_reach(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    # the sweep said where an address it was not given came from; the bench named it as if the user had typed it
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://127.0.0.1:1")
    err = _refusal(capsys, ["bench", "--controllers", "pid", "--plants", "improved", "--references", "sine",
                            "--no-precision", "--quiet", "--duration", "0.1"])
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:1" in err
    assert "the DASK_SCHEDULER_ADDRESS environment variable's" in err


def test_stiffness_names_the_stage_flag_and_the_trains_range(capsys: pytest.CaptureFixture[str]) -> None:
    err = _refusal(capsys, ["stiffness", "servo_2stage_phm09", "--stage", "3"])
    assert "--stage 3 is out of range" in err and "expected 1 <= value <= 2" in err


def test_simulate_json_damping_on_the_yang_sun_plant_and_a_pairs_lost_motion(
        capsys: pytest.CaptureFixture[str]) -> None:
    # the Yang-Sun plant damps by restitution; its JSON reported the improved plant's unused c (269 N s/m)
    import json

    assert main(["simulate", "shing1993", "--plant", "yang-sun", "--duration", "0.001", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["damping_coefficient"] is None and d["mesh_stiffness"] > 1e9  # eq 39's Hertz stiffness
    assert main(["simulate", "shing1993", "--duration", "0.001", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["damping_coefficient"] > 0
    # a pair's JSON has the lost motion a train's has (2 b / r_b2 at the load)
    assert d["lost_motion"] == pytest.approx(2 * 5e-5 / 0.0751754, rel=1e-5)


def test_models_json_gives_numbers_for_the_numeric_columns(capsys: pytest.CaptureFixture[str]) -> None:
    # module_mm and pressure_angle_deg were the table's text ("1/1", "20/20" on a train)
    import json

    assert main(["models", "--json"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    q = rows["servo_3stage_quanser_srv02"]
    assert q["module_mm"] == pytest.approx(0.3) and q["pressure_angle_deg"] == pytest.approx(20.0)
    assert q["modules_mm"] == pytest.approx([0.3, 0.3, 0.52917]) and len(q["pressure_angles_deg"]) == 3
    assert rows["shing1993"]["module_mm"] == pytest.approx(2.0) and rows["shing1993"]["teeth"] == "20x80"


@pytest.mark.parametrize("argv", [
    ["track", "servo_2stage_phm09", "pid", "--set", "intermediate_inertia=2x"],
    ["sweep", "servo_2stage_phm09", "pid", "--vary", "intermediate_inertia=1x:2x", "--runs", "2", "--quiet"],
])
def test_a_list_key_is_named_as_a_list_not_as_not_a_number(capsys: pytest.CaptureFixture[str],
                                                           argv: list[str]) -> None:
    # "intermediate_inertia is not a number --set can change" of a list of numbers
    err = _refusal(capsys, argv)
    assert "intermediate_inertia is a list (one value per intermediate shaft)" in err and "not a number" not in err
