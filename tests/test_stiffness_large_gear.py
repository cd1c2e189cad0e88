"""The report's tooth model on large gears: its beam starts at the base circle (eqs 24-25), so a 190-tooth ring's mesh
stiffness came out at a third of ISO 6336-1's with no word from ``info`` or ``stiffness`` (an h2 review's slewing
drive, ``tests/data/h2_slewing_17x190.toml``: 6.67 N/(mm um), ISO 20.9)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

import gearctl
from gearctl.cli import main
from gearctl.stiffness import iso6336_mesh_stiffness, mesh_stiffness, stiffness_note

DATA = Path(__file__).parent / "data"
SLEWING = str(DATA / "h2_slewing_17x190.toml")


def _per_width(pair, k: float) -> float:
    return k / pair.face_width * 1e-9  # N/(mm um)


def test_model_softens_with_the_wheel_where_iso_does_not() -> None:
    pair = gearctl.load_model("shing1993").pair
    ours, iso = [], []
    for z2 in (80, 190, 300):
        p = dataclasses.replace(pair, teeth2=z2)
        ours.append(_per_width(p, mesh_stiffness(p).mean))
        iso.append(_per_width(p, iso6336_mesh_stiffness(p)))
    assert ours[0] == pytest.approx(13.85, abs=0.01) and ours[2] < 0.4 * ours[0]  # the report's model: 13.9 -> 4.9
    assert iso[0] == pytest.approx(20.4, abs=0.1) and iso[0] < iso[1] < iso[2]  # ISO: stiffer towards a rack
    assert stiffness_note(pair, mesh_stiffness(pair).mean) is None  # the report's own pair (0.68 of ISO's)
    big = dataclasses.replace(pair, teeth2=300)
    note = stiffness_note(big, mesh_stiffness(big).mean)
    assert note is not None and "300 teeth" in note and "mesh_stiffness" in note


def test_info_and_stiffness_warn_on_a_large_ring(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", SLEWING, "--json"]) == 0
    out, err = capsys.readouterr()
    s = json.loads(out)
    assert s["mesh_stiffness_per_width"] == pytest.approx(6.67, abs=0.01)
    assert _per_width(gearctl.load_model(SLEWING).pair, s["mesh_stiffness_iso6336"]) == pytest.approx(20.9, abs=0.1)
    assert s["stiffness_note"] and err.startswith("gearctl info: warning: the mesh stiffness 4.002e+08 N/m")
    assert "0.32 of ISO 6336-1's" in err and "190 teeth" in err and err.count("\n") == 1
    assert main(["stiffness", SLEWING]) == 0
    assert "gearctl stiffness: warning:" in capsys.readouterr().err


def test_no_warning_where_the_file_gives_the_stiffness(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = Path(SLEWING).read_text().replace("damping_ratio = 0.05", "damping_ratio = 0.05\nmesh_stiffness = 1.25e9")
    f = tmp_path / "given.toml"
    f.write_text(text)
    assert main(["info", str(f), "--json"]) == 0
    out, err = capsys.readouterr()
    assert err == "" and json.loads(out)["stiffness_note"] is None
    assert main(["stiffness", str(f)]) == 0  # the curve printed is still the report's: say which k the plant uses
    assert "(the plant uses the file's 1.25e+09 N/m)" in capsys.readouterr().err


def test_catalog_pairs_and_small_gears_stay_quiet(capsys: pytest.CaptureFixture[str]) -> None:
    for name in ("shing1993", "shing1993_servo", "pinion17_shifted_shing1993", "servo_2stage_phm09",
                 "nasa_glenn_28x28", "detc1992_21x29_25deg"):
        assert main(["info", name]) == 0
        assert capsys.readouterr().err == "", name
    assert main(["info", "servo_3stage_quanser_srv02"]) == 0  # its 120-tooth load gear: 0.48 of ISO's
    assert capsys.readouterr().err.startswith("gearctl info: warning: stage 3: the mesh stiffness")
