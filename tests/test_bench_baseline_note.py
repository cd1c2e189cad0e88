"""`gearctl bench --controllers` without the catalog pid has no baseline: no ratios over the PID and no 'worse than the
pid' warnings, which it used to drop without a word (review hH: a rack axis's inverse, ISO A 2x the PID's, came out
unflagged). It says so."""

from __future__ import annotations

from pathlib import Path

import pytest

from gearctl.cli import main

MODEL = str(Path(__file__).resolve().parent / "data" / "controller_files" / "rack_axis_20x200.toml")


@pytest.mark.parametrize(("controllers", "noted"), [(["deadzone_inverse"], True),
                                                    (["pid", "deadzone_inverse"], False)])
def test_bench_without_pid_notes_the_missing_baseline(capsys, controllers: list[str], noted: bool) -> None:  # noqa: ANN001
    argv = ["bench", MODEL, "--controllers", *controllers, "--plants", "improved", "--references", "move",
            "--duration", "0.2", "--no-precision", "--jobs", "1", "--quiet"]
    assert main(argv) == 0
    assert ("note: --controllers without pid: no PID baseline" in capsys.readouterr().err) is noted
