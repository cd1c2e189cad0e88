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


SWEEP = ["sweep", "shing1993_servo", "pid", "--vary", "backlash=0.5x:2x", "--runs", "2", "--duration", "0.05"]
BENCH = ["bench", "shing1993_servo", "--no-precision"]


@pytest.mark.parametrize(("argv", "name"), [
    *[(SWEEP, n) for n in ("runs.csv", "summary.md", "histogram.png", ".")],
    *[(BENCH, n) for n in ("report.md", "histogram.png", ".")],
])
def test_a_json_file_among_the_out_folders_files_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                            argv: list[str], name: str) -> None:
    # sweep --json D/runs.csv --out D wrote the JSON, then runs.csv over it (exit 0); --json D --out D likewise
    d = tmp_path / "d"
    assert main([*argv, "--json", str(d / name), "--out", str(d)]) == 2
    err = capsys.readouterr().err
    assert "--json" in err and len(err.strip().splitlines()) == 1, err
    assert not d.exists()


def test_a_json_file_of_its_own_name_in_the_out_folder_is_written(tmp_path: Path) -> None:
    d = tmp_path / "d"
    assert main(["sweep", "shing1993_servo", "pid", "--vary", "backlash=0.5x:2x", "--runs", "2", "--duration", "0.05",
                 "--workers", "1", "--quiet", "--json", str(d / "sweep.json"), "--out", str(d)]) == 0
    assert (d / "sweep.json").read_text().lstrip().startswith("{") and (d / "runs.csv").exists()


def test_write_model_into_a_fifo_writes_through_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # --write-model renamed its checked temporary file over the path: as root, `--write-model /dev/full` replaced the
    # device node with a regular file. A device or a FIFO is written into, never replaced (a FIFO here: no root)
    import os
    import stat
    import threading

    log = Path(__file__).resolve().parent / "data" / "logs" / "other_sim_chirp_5khz.csv"
    fifo = tmp_path / "model.fifo"
    os.mkfifo(fifo)
    got: list[str] = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_text()), daemon=True)
    reader.start()
    assert main(["identify", str(log), "--model", "shing1993_servo", "--write-model", str(fifo)]) == 0, \
        capsys.readouterr().err
    reader.join(timeout=30)
    assert stat.S_ISFIFO(fifo.stat().st_mode)
    assert got and "backlash" in got[0] and "written by gearctl identify" in got[0]
