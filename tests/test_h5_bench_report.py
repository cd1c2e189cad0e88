"""What `gearctl bench` reports on a machine builder's own servos (h5's review, models tests/data/h5_*.toml).

The report a user keeps, ``--out DIR/report.md``, and the lines on standard error must tell the same story: which
figures cannot be compared, which compensator does worse than the PID, what the designs changed.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from gearctl.cli import main

DATA = Path(__file__).resolve().parent / "data"
INSTRUMENT = str(DATA / "h5_instrument_coarse_14bit.toml")  # 0.05 N m motor x 5: holds 0.25 N m at the load
JOINT = str(DATA / "h5_robot_joint_15x60_shifted.toml")


def _stderr_lines(err: str, kind: str) -> list[str]:
    head = f"gearctl bench: {kind}: "
    return [line[len(head):] for line in err.splitlines() if line.startswith(head)]


def test_report_md_carries_the_warnings_of_standard_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the instrument's step: a 0.5 N m load step, twice what the motor holds at the load, ran the load 156 rad away
    # under every controller; stderr said so, report.md showed the 1.562e+08 urad figures alone
    out = tmp_path / "rep"
    argv = ["bench", INSTRUMENT, "--controllers", "pid", "--plants", "improved", "--references", "step",
            "--duration", "1.5", "--no-precision", "--jobs", "1", "--quiet", "--out", str(out)]
    assert main(argv) == 0
    warnings = _stderr_lines(capsys.readouterr().err, "warning")
    assert any("the reference's load step, 0.5 N m" in w for w in warnings)
    report = (out / "report.md").read_text()
    assert "## Warnings" in report
    for w in warnings:
        assert f"- {w}" in report


def test_a_design_note_shared_by_several_controllers_comes_once(capsys: pytest.CaptureFixture[str]) -> None:
    # the joint's PID-family loop: 'bandwidth_hz = 20 lowered to 7.88 Hz ...' came once per controller of the family
    argv = ["bench", JOINT, "--controllers", "pid", "deadzone_inverse", "--plants", "improved", "--references", "sine",
            "--duration", "1", "--no-precision", "--jobs", "1", "--quiet"]
    assert main(argv) == 0
    notes = _stderr_lines(capsys.readouterr().err, "note")
    lowered = [n for n in notes if "bandwidth_hz = 20 lowered" in n]
    assert len(lowered) == 1
    assert lowered[0].startswith(f"{JOINT}, pid, deadzone_inverse: ") or \
        lowered[0].startswith(f"{JOINT}, deadzone_inverse, pid: ")


def test_the_tables_mark_the_rows_of_a_load_step_no_controller_can_hold() -> None:
    # the instrument's step rows read '1.562e+08 / 4.018e+08' urad and '1 / 1' over the PID and the backlash-free
    # plant for every controller: a tie, to a reader, where the load ran 156 rad away under each; the joint (3 N m x 4)
    # holds the 0.5 N m step and is not marked
    from gearctl.bench import BenchSpec, bench_table, run_bench

    res = run_bench(BenchSpec(models=(INSTRUMENT, JOINT), controllers=("pid",), plants=("improved",),
                              references=("step",), duration=1.5, precision=False), jobs=1)
    held = {r["model"]: r["unholdable_load_step"] for r in res["runs"]}
    assert held[JOINT] is None and "2 times the torque the motor can put on the load" in held[INSTRUMENT]
    for markdown in (False, True):
        text = bench_table(res, markdown=markdown)
        rows = [line for line in text.splitlines() if " step " in line or "| step |" in line]
        assert len(rows) == 4  # the error table's and the ratio table's row of each model
        for line in rows:
            assert (" *" in line) is (INSTRUMENT in line), line
        star = "\\* " if markdown else "* "
        assert f"\n{star}the reference's load step, 0.5 N m, is 2 times" in text
        assert text.count("no controller can hold it, the load runs away") == 2  # under each table that marks
