"""The command line through ``main(argv)``: ``models``, ``info`` (human and JSON), ``stiffness``.

``info shing1993 --json`` is checked against the report's published numbers (TR 93-28 section 3.2,
Table 1, section 5, eq 39) with the same tolerances as the API tests in test_geometry.py and
test_stiffness.py.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest
from numpy.testing import assert_allclose

from gearctl import load_model, mesh_stiffness, model_names, pair_geometry
from gearctl.cli import main

DEG = math.pi / 180.0


@pytest.fixture
def shing_json(capsys: pytest.CaptureFixture[str]) -> dict:
    """``gearctl info shing1993 --json`` through ``main``, parsed."""
    assert main(["info", "shing1993", "--json"]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    return json.loads(out)


def test_info_json_keys(shing_json: dict) -> None:
    for key in ("contact_ratio", "base_pitch", "damping_coefficient", "yang_sun_stiffness", "backlash"):
        assert isinstance(shing_json[key], float), key
    assert len(shing_json["base_radius"]) == 2
    assert len(shing_json["inertia"]) == 2
    assert set(shing_json["mesh_stiffness"]) >= {"mean", "c1", "c2", "min", "max"}


def test_info_json_report_geometry(shing_json: dict) -> None:
    # TR 93-28 section 3.2: contact ratio 1.69129; atol 5e-6 = half a unit in the last printed digit
    assert_allclose(shing_json["contact_ratio"], 1.69129, rtol=0, atol=5e-6)
    I1, I2 = shing_json["inertia"]
    # section 3.2: I1 = 1.9604e-05 kg m^2, rtol 1e-3 (0.1 %)
    assert_allclose(I1, 1.9604e-5, rtol=1e-3)
    # section 3.2 prints I2 = 0.0050 kg m^2: rounds to it, and is rho pi f r2^4 / 2 (rtol 1e-12)
    assert f"{I2:.4f}" == "0.0050"
    assert_allclose(I2, 7800.0 * math.pi * 0.01 * 0.08**4 / 2, rtol=1e-12)
    # section 3.2 data: base radii r_p cos 20 deg, base pitch pi m cos 20 deg, backlash 0.00005 m;
    # rtol 1e-12 (closed forms; JSON writes floats with repr precision)
    rb = [0.02 * math.cos(20 * DEG), 0.08 * math.cos(20 * DEG)]
    assert_allclose(shing_json["base_radius"], rb, rtol=1e-12)
    assert_allclose(shing_json["base_pitch"], math.pi * 0.002 * math.cos(20 * DEG), rtol=1e-12)
    assert shing_json["backlash"] == 5e-5


def test_info_json_report_stiffness(shing_json: dict) -> None:
    ms = shing_json["mesh_stiffness"]
    # Table 1 mean 1.3868e8 N/m: gearctl -0.10 %, rtol 2e-3 (0.2 %)
    assert_allclose(ms["mean"], 1.3868e8, rtol=2e-3)
    # Table 1 C2 1.684e7 N/m: gearctl -0.07 %, rtol 2e-3 (0.2 %)
    assert_allclose(ms["c2"], 1.684e7, rtol=2e-3)
    # Table 1 C1 2.956e7 N/m does not follow from the report's own equations (3.475e7, +17.6 %; the
    # value is checked by an independent Fourier integral in test_stiffness.py): not within 10 %
    assert abs(ms["c1"] / 2.956e7 - 1) > 0.10
    # the CLI reports the API's numbers; rtol 1e-12 (JSON round trip of float repr is exact)
    api = mesh_stiffness(load_model("shing1993").pair)
    assert_allclose([ms["mean"], ms["c1"], ms["c2"], ms["min"], ms["max"]],
                    [api.mean, api.c1, api.c2, api.min, api.max], rtol=1e-12)
    assert ms["min"] <= ms["mean"] <= ms["max"]


def test_info_json_report_damping_and_yang_sun(shing_json: dict) -> None:
    rb1, rb2 = shing_json["base_radius"]
    I1, I2 = shing_json["inertia"]
    m_eq = I1 * I2 / (I2 * rb1**2 + I1 * rb2**2)
    # eq 38 (consistent form) with Table 1's k: 269.15 N s/m; gearctl uses its computed k (-0.10 %),
    # c ~ sqrt(k): rtol 1e-3
    assert_allclose(shing_json["damping_coefficient"], 2 * 0.05 * math.sqrt(1.3868e8 * m_eq), rtol=1e-3)
    # the report's 237.6651 N s/m (section 5) comes from base-radius disks (see test_stiffness.py), so
    # the pitch-radius-disk value differs by more than 10 %
    assert abs(shing_json["damping_coefficient"] / 237.6651 - 1) > 0.10
    # eq 39: pi E f / (4 (1 - nu^2)); rtol 1e-12
    k_ys = math.pi * 2.068e11 * 0.01 / (4 * (1 - 0.3**2))
    assert_allclose(shing_json["yang_sun_stiffness"], k_ys, rtol=1e-12)


def test_info_human(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", "shing1993"]) == 0
    out, err = capsys.readouterr()
    assert "contact ratio" in out
    assert "1.69129" in out  # printed to 6 significant digits, as in the report
    assert err == ""


def test_models_lists_catalog(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["models"]) == 0
    out = capsys.readouterr().out
    for name in model_names():
        assert name in out
    assert main(["models", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == model_names()
    for r in rows:
        # printed to 3 decimals: atol 5e-4
        eps = pair_geometry(load_model(r["name"]).pair).contact_ratio
        assert_allclose(float(r["contact_ratio"]), eps, rtol=0, atol=5e-4)


def test_stiffness_writes_csv_and_plot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    csv_path, png_path = tmp_path / "k.csv", tmp_path / "sub" / "k.png"
    argv = ["stiffness", "shing1993", "--points", "101", "--csv", str(csv_path), "--plot", str(png_path)]
    code = main(argv)
    assert code == 0
    out = capsys.readouterr().out
    assert str(csv_path) in out and str(png_path) in out
    with open(csv_path, newline="") as fh:
        rows = list(csv.reader(fh))
    header, data = rows[0], rows[1:]
    assert header[:2] == ["theta1", "K"]
    assert len(data) == 101
    assert all(len(r) == len(header) for r in data)
    theta = [float(r[0]) for r in data]
    K = [float(r[1]) for r in data]
    geo = pair_geometry(load_model("shing1993").pair)
    # theta1 spans the path of contact C -> D; the CSV prints 10 significant digits: rtol 1e-9
    assert_allclose([theta[0], theta[-1]], [0.0, (geo.AD - geo.AC) / geo.base_radius[0]], rtol=1e-9, atol=0)
    assert all(k > 0 for k in K)
    assert png_path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plot_without_suffix_is_written_under_its_name(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # matplotlib appends ".png" to a name without a suffix: `--plot k` wrote k.png and said "wrote k" (and
    # `--plot /dev/full` wrote /dev/full.png, exit 0, instead of failing on the full device)
    path = tmp_path / "k"
    assert main(["stiffness", "shing1993", "--points", "11", "--plot", str(path)]) == 0
    assert f"wrote {path} " in capsys.readouterr().out
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (tmp_path / "k.png").exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["stiffness", "shing1993", "--points", "0"],
        ["stiffness", "shing1993", "--points", "x"],
        ["nosuchcommand"],
        ["info"],
    ],
)
def test_usage_errors_exit_2(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "usage" in err and "Traceback" not in err


@pytest.mark.parametrize(("argv", "fragment"), [
    (["track", "shing1993_servo", "pid", "--backlash", "-1e-5"], "--backlash: -1e-5 is out of range"),
    (["simulate", "shing1993_servo", "--dt", "-1e-6"], "--dt: -1e-6 is out of range: expected a number > 0 [s]"),
])
def test_a_negative_number_in_exponent_form_is_a_value(argv: list[str], fragment: str,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    # argparse's own pattern of a negative number knows -1 and -.5, not -1e-5: it read the value as an option and
    # said "expected one argument" instead of the range
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert fragment in err and "expected one argument" not in err


def test_every_schema_option_states_its_range_in_the_help() -> None:
    # the README: "gearctl COMMAND --help gives every option with its unit and range"; a new user found the ranges of
    # --duration, --travel, --seed ... only in the errors
    import argparse

    from gearctl.cli import _parser

    ap, _ = _parser()
    sub = next(a for a in ap._actions if isinstance(a, argparse._SubParsersAction))
    checked = 0
    for name, p in sub.choices.items():
        for action in p._actions:
            spec = getattr(action.type, "spec", None)
            if spec is not None and action.help:
                checked += 1
                assert "<=" in action.help or ".." in action.help, (name, action.option_strings, action.help)
    assert checked >= 20


def test_the_command_line_starts_without_importing_the_computation() -> None:
    # the console script imports gearctl.cli before main() runs: it imported numpy, SciPy and every design module
    # (0.3 s), and a Ctrl-C then was Python's traceback, exit -2. Now the package and the CLI import nothing heavy
    import subprocess
    import sys

    code = ("import sys, gearctl, gearctl.cli\n"
            "print(','.join(sorted(m for m in sys.modules if m.split('.')[0] in ('numpy', 'scipy', 'control')\n"
            "                     or m.startswith('gearctl.') and m not in ('gearctl.cli', 'gearctl.errors'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True).stdout
    assert out.strip() == ""


def test_dir_of_the_package_lists_its_lazy_names() -> None:
    # the names imported on first use were missing from dir(gearctl) (tab completion, help()) until used
    import subprocess
    import sys

    code = ("import sys, gearctl; d = dir(gearctl)\n"
            "print(all(n in d for n in gearctl.__all__), 'numpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True).stdout
    assert out.split() == ["True", "False"]


def test_ctrl_c_while_the_commands_load_is_one_line(monkeypatch: pytest.MonkeyPatch,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    import gearctl.cli

    def interrupted() -> tuple:
        raise KeyboardInterrupt

    monkeypatch.setattr(gearctl.cli, "groups", interrupted)
    assert main(["info", "shing1993_servo"]) == 130
    assert capsys.readouterr().err == "gearctl: interrupted\n"


def test_a_plot_suffix_that_is_no_format_is_refused_before_the_run(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    # `--plot out.v2` failed with one line only after the simulation it plots
    import time

    t0 = time.perf_counter()
    assert main(["track", "shing1993_servo", "pid", "--duration", "30", "--plot", str(tmp_path / "k.v2")]) == 2
    assert time.perf_counter() - t0 < 5.0  # 30 s of a 1 kHz loop is not run
    err = capsys.readouterr().err
    assert ".v2 is not a figure format" in err and "or no suffix (PNG)" in err
    assert not any(tmp_path.iterdir())


def test_a_run_slower_than_real_time_is_not_printed_as_zero_speed() -> None:
    """``track`` printed ``wall time 0.139 s (0 simulated s per wall s)`` for a 0.05 s run of a four-stage train
    (review hA): the rate was rounded to a whole number. Below 10 it keeps two significant digits."""
    from gearctl.cli.common import format_rate

    assert format_rate(0.05, 0.139) == "0.36"
    assert format_rate(3.0, 0.939) == "3.2"
    assert format_rate(3.0, 0.0125) == "240"  # the README's figure for the pair keeps its form
    assert float(format_rate(1e-3, 10.0)) == pytest.approx(1e-4)


def test_stiffness_figures_do_not_depend_on_the_sampled_points(capsys) -> None:  # noqa: ANN001
    # 'stiffness --points 2' said "(2 points): mean ..." as if two samples made the figures; they come from a
    # quadrature over the cycle's smooth segments, the points sample the curves of --csv and --plot
    lines = []
    for n in ("2", "3000"):
        assert main(["stiffness", "shing1993", "--points", n]) == 0
        out = capsys.readouterr().out.splitlines()[0]
        assert out.endswith(f"(the curves sampled at {n} points)")
        lines.append(out.rsplit(" (", 1)[0])
    assert lines[0] == lines[1] and "mean 1.3854e+08 N/m" in lines[0]
