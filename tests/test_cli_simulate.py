"""``gearctl simulate`` through ``main(argv)``: JSON summary, CSV, plot, the report's cases, bad input.

The JSON and CSV are checked against the API (:func:`gearctl.simulate.report_case`) and against closed
forms of the report's free-vibration case (TR 93-28 section 5.1.1): all energy kinetic at t = 0,
``0.5 I1 50^2``; the CSV's ``s`` is ``r_b1 theta1 - r_b2 theta2`` of its own angles; no force in the gap.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from gearctl import GearModel, build_plant
from gearctl.cli import main
from gearctl.simulate import report_case

CSV_HEADER = ["t", "theta1", "theta2", "omega1", "omega2", "s", "mode", "force"]


def run_json(argv: list[str], capsys: pytest.CaptureFixture[str]) -> dict:
    """``main(argv + ['--json'])``: exit 0, nothing on stderr, one JSON object on stdout."""
    code = main([*argv, "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert err == ""
    return json.loads(out)


def read_csv(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def test_simulate_json_keys(capsys: pytest.CaptureFixture[str]) -> None:
    summary = run_json(["simulate", "shing1993", "--duration", "0.005"], capsys)
    assert set(summary["impacts"]) == {"front", "back"}
    assert all(isinstance(v, int) for v in summary["impacts"].values())
    assert isinstance(summary["max_penetration"], float)
    assert set(summary["final"]) == {"theta1", "theta2", "omega1", "omega2"}
    assert set(summary["energy"]) == {"initial", "final"}
    assert all(isinstance(v, float) for v in (*summary["final"].values(), *summary["energy"].values()))
    assert summary["plant"] == "improved" and summary["case"] == "free"
    assert summary["duration"] == pytest.approx(0.005, rel=1e-12)


def test_simulate_json_matches_api(shing: GearModel, capsys: pytest.CaptureFixture[str]) -> None:
    summary = run_json(["simulate", "shing1993", "--duration", "0.005"], capsys)
    plant = build_plant(shing)
    res = report_case(plant, "free", 0.005)
    assert summary["impacts"] == res.impact_counts()
    assert summary["impacts"]["front"] >= 5 and summary["impacts"]["back"] >= 5
    # JSON carries floats at repr precision: the same run, rtol 1e-15
    assert_allclose(summary["max_penetration"], res.max_penetration, rtol=1e-15)
    assert_allclose(list(summary["final"].values()), res.x[:, -1], rtol=1e-15)
    assert_allclose(summary["impact_times"], [e.t for e in res.impacts], rtol=1e-15)
    # section 5.1.1 start: all energy kinetic, 0.5 I1 50^2 (rtol 1e-14); damped, it only decreases
    assert_allclose(summary["energy"]["initial"], 0.5 * plant.J1 * 50.0**2, rtol=1e-14)
    assert summary["energy"]["final"] < summary["energy"]["initial"]
    # first impact: s' = 50 rb1 in the gap, so the fastest impact is the first, at 50 rb1 (rtol 1e-12)
    assert_allclose(summary["max_impact_velocity"], 50.0 * plant.rb1, rtol=1e-12)


def test_simulate_csv(tmp_path: Path, shing: GearModel, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "out" / "free.csv"
    summary = run_json(["simulate", "shing1993", "--duration", "0.005", "--dt", "1e-5", "--csv", str(path)],
                       capsys)
    header, rows = read_csv(path)
    assert header == CSV_HEADER
    assert len(rows) == 501
    modes = [r[6] for r in rows]
    assert set(modes) <= {"front", "separation", "back"}
    assert set(modes) == {"front", "separation", "back"}  # 5 ms of free vibration visits all three
    data = np.array([[float(v) for i, v in enumerate(r) if i != 6] for r in rows]).T
    t, th1, th2, w1, w2, s, force = data
    plant = build_plant(shing)
    b = plant.backlash
    # 10 significant digits in the file: t on the 1e-5 grid to 1e-9 relative
    assert_allclose(t, 1e-5 * np.arange(501), rtol=1e-9, atol=1e-20)
    # s = rb1 theta1 - rb2 theta2 from the rounded angles: a difference of two ~3 mm arcs, each rounded
    # to 10 digits, so 1e-9 of the arc (not of s)
    arc = float(np.max(np.abs(plant.rb1 * th1)))
    assert_allclose(s, plant.rb1 * th1 - plant.rb2 * th2, rtol=0, atol=1e-9 * arc)
    # mode column is the mode of s; zero force exactly in the gap; front force pushes (closing)
    gap = np.abs(s) <= b
    assert all((m == "separation") == g for m, g in zip(modes, gap, strict=True))
    assert np.all(force[gap] == 0.0)
    front = np.array([m == "front" for m in modes])
    closing = front & (plant.rb1 * w1 - plant.rb2 * w2 > 0)
    assert closing.any() and np.all(force[closing] > 0)
    # the JSON's max penetration is located between the outputs, so it bounds the CSV's:
    # >= max(|s| - b) over the rows, allowing the 10-digit rounding of s (1e-9 b)
    assert summary["max_penetration"] >= np.max(np.abs(s) - b) - 1e-9 * b
    assert summary["max_penetration"] > 0


def test_simulate_plot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "sub" / "free.png"
    code = main(["simulate", "shing1993", "--duration", "0.002", "--dt", "1e-5", "--plot", str(path)])
    out, err = capsys.readouterr()
    assert code == 0 and err == ""
    assert str(path) in out
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_simulate_load_case_yang_sun(tmp_path: Path, shing: GearModel,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "load.csv"
    summary = run_json(["simulate", "shing1993", "--case", "load", "--plant", "yang-sun", "--duration", "0.05",
                        "--dt", "1e-5", "--csv", str(path)], capsys)
    assert summary["plant"] == "yang-sun" and summary["case"] == "load"
    assert summary["solver"].startswith("dopri5")
    # section 5.1.2: impacts on both sides first, then one-sided (front) contact to the end
    assert summary["impacts"]["back"] >= 1 and summary["impacts"]["front"] > summary["impacts"]["back"]
    assert summary["final_mode"] == "front"
    # the load case drives gear 1 forward: energy grows (xi1 = 1 N m does work)
    assert summary["energy"]["final"] > summary["energy"]["initial"]
    _, rows = read_csv(path)
    assert len(rows) == 5001
    assert [r[6] for r in rows[-100:]] == ["front"] * 100
    res = report_case(build_plant(shing, "yang-sun"), "load", 0.05, dt=1e-5)
    assert summary["impacts"] == res.impact_counts()


def test_simulate_human_output(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["simulate", "shing1993", "--duration", "0.002", "--omega1", "20", "--torque1", "0.1"])
    out, err = capsys.readouterr()
    assert code == 0 and err == ""
    assert "impacts" in out and "max penetration" in out and "energy" in out


# --- bad input -----------------------------------------------------------------------------------------------


def assert_clean_failure(err: str) -> None:
    assert "Traceback" not in err
    assert "Error:" not in err  # no exception class names leak (InputError:, ValueError:, ...)


def test_unknown_model_exits_2_with_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["simulate", "nosuchmodel"])
    out, err = capsys.readouterr()
    assert code == 2
    assert out == ""
    assert_clean_failure(err)
    lines = err.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("gearctl simulate: error:") and "nosuchmodel" in lines[0]


@pytest.mark.parametrize(
    ("argv", "names"),
    [
        (["simulate", "shing1993", "--duration", "-1"], "--duration"),
        (["simulate", "shing1993", "--duration", "0"], "--duration"),
        (["simulate", "shing1993", "--dt", "nan"], "--dt"),
        (["simulate", "shing1993", "--plant", "nosuchplant"], "--plant"),
        (["simulate", "shing1993", "--case", "nosuchcase"], "--case"),
        (["simulate", "shing1993", "--omega1", "inf"], "--omega1"),
    ],
)
def test_bad_arguments_exit_2(argv: list[str], names: str, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2
    assert out == ""
    assert_clean_failure(err)
    # argparse's usage errors print the usage block (as the other commands do, see
    # test_cli_basic.py) and then exactly one error line naming the argument
    error_lines = [ln for ln in err.splitlines() if "error:" in ln]
    assert len(error_lines) == 1
    assert names in error_lines[0]
    assert err.strip().splitlines()[-1] == error_lines[0]


def test_unwritable_csv_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    code = main(["simulate", "shing1993", "--duration", "0.001", "--csv", str(blocker / "x.csv")])
    _, err = capsys.readouterr()
    assert code == 2
    assert_clean_failure(err)
    assert len(err.strip().splitlines()) == 1 and "cannot write" in err


def test_model_file_path(write_model, capsys: pytest.CaptureFixture[str]) -> None:
    # a model given as a TOML path (conftest's write_model): twice the backlash, one line of the template
    path = write_model({"backlash = 5e-5 ": "backlash = 1e-4 "})
    summary = run_json(["simulate", str(path), "--duration", "0.002"], capsys)
    assert summary["backlash"] == 1e-4
    # first impact at b / (50 rb1) (section 5.1.1 start): the JSON's first impact time, rtol 1e-12
    rb1 = 0.02 * math.cos(math.radians(20.0))
    assert_allclose(summary["impact_times"][0], 1e-4 / (50.0 * rb1), rtol=1e-12)


@pytest.mark.parametrize("argv", [["simulate", "shing1993_servo", "--duration", "0.002"],
                                  ["track", "shing1993_servo", "pid", "--duration", "0.05"]])
def test_csv_dash_is_standard_output(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    # `--csv -` wrote a file named '-' (a reviewer); it is standard output now, the command's own lines on stderr
    assert main([*argv, "--csv", "-"]) == 0
    cap = capsys.readouterr()
    rows = list(csv.reader(cap.out.splitlines()))
    assert rows[0][0] == "t" and len(rows) > 10 and all(len(r) == len(rows[0]) for r in rows)
    assert "wrote standard output (CSV)" in cap.err and not Path("-").exists()
    assert main([*argv, "--csv", "-", "--json"]) == 2
    assert "both would write standard output" in capsys.readouterr().err


def test_the_model_load_torque_is_reported_with_the_case_torques(capsys: pytest.CaptureFixture[str]) -> None:
    """A gravity-loaded model's ``load_torque`` acts in every case (simulate adds it), but the output spoke only of
    the case ("free case": no torque; "load case": -1 N m) and its JSON had no torque (review hA: a -40 N m arm).
    The JSON now gives the torques applied, and the text says where the load's came from."""
    data = str(Path(__file__).resolve().parent / "data" / "robot_joint_2stage_gravity.toml")  # load_torque -1.5
    out = run_json(["simulate", data, "--case", "load", "--duration", "0.005"], capsys)
    assert out["torque"] == {"motor": 1.0, "load": -1.0 - 1.5}
    # the run applied that total: the same model without its load torque, given -2.5 N m by the case, ends alike
    from dataclasses import replace

    from gearctl import load_model

    m = load_model(data)
    bare = build_plant(replace(m, servo=replace(m.servo, load_torque=0.0)))
    ref = report_case(bare, "load", 0.005, torque2=-2.5)
    assert_allclose(out["final"]["theta"], ref.x[: ref.x.shape[0] // 2, -1], rtol=1e-9, atol=1e-12)
    assert main(["simulate", data, "--duration", "0.005"]) == 0
    text = capsys.readouterr().out
    assert "load -1.5 N m (the free case's 0 plus the model's load_torque -1.5)" in text
    assert main(["simulate", "shing1993_servo", "--duration", "0.005"]) == 0
    assert "torques" not in capsys.readouterr().out  # no load torque: the case's torques are the whole story
