"""Two outputs of one command naming one file: refused before the run, exit 2 (`excite --reference-only F --out F`
wrote the reference, then the log over it, and said it wrote both; `identify --plot F --write-model F` likewise)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gearctl.cli import main

LOG = Path(__file__).resolve().parent / "data" / "logs" / "other_sim_chirp_5khz.csv"


def test_excite_refuses_one_file_for_both_outputs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "ref.csv"
    assert main(["excite", "shing1993_servo", "--duration", "1", "--reference-only", str(out),
                 "--out", str(tmp_path / "." / "ref.csv")]) == 2
    err = capsys.readouterr().err
    assert "name the same file" in err and "--reference-only" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_identify_refuses_one_file_for_plot_and_model(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "same.png"
    assert main(["identify", str(LOG), "--model", "shing1993_servo", "--plot", str(out),
                 "--write-model", str(out)]) == 2
    assert "--plot" in capsys.readouterr().err and not out.exists()


def test_two_files_are_written(tmp_path: Path) -> None:
    assert main(["excite", "shing1993_servo", "--duration", "1", "--reference-only", str(tmp_path / "r.csv"),
                 "--out", str(tmp_path / "l.csv")]) == 0
    assert (tmp_path / "r.csv").read_text() != (tmp_path / "l.csv").read_text()
