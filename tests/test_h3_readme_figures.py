"""The README's figures against the commands next to them (issue 12: "every figure in the README's results table is
reproduced by the command next to it"), as a new user reads them.

Two kinds of check:

- *Transcripts*: every ``$ gearctl ...`` block of README.md whose command runs here without files the README does
  not give (the catalog's models and controllers; the log that ``excite`` writes for ``identify``) is run through
  ``main(argv)`` in a scratch folder, in the README's order, and every line the README shows under it must be a line
  of what the command prints, character for character (aligned columns included). Lines that time the machine
  (``wall time``, ``solve time``) and elisions (a ``...`` line; a line ending in `` ...`` is a prefix) are left
  out.
- *Prose*: figures quoted in running text beside a command, formatted from that command's own output.

A README edited without rerunning the command fails here; so does a change of the code that moves a quoted figure.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from gearctl.cli import main

README = Path(__file__).resolve().parents[1] / "README.md"
DATA = Path(__file__).resolve().parent / "data"

# lines that measure the machine, not the code
_TIMED = ("  wall time", "  solve time")
# transcripts whose inputs the README describes but does not ship (a user's broken file, a copied controller), and
# the sweep (Dask workers: tests/test_sweep.py runs its example)
_NEEDS_FILES = ("bad.toml", "badtrain.toml", "my_servo.toml", "pid200.toml", " sweep ")


def readme_transcripts(text: str) -> list[tuple[str, list[str]]]:
    """``(command, shown lines)`` of every ``$ gearctl`` line in the README's fenced blocks, in order."""
    out: list[tuple[str, list[str]]] = []
    in_block = False
    current: tuple[str, list[str]] | None = None
    for line in text.splitlines():
        if line.startswith("```"):
            in_block = not in_block
            current = None
            continue
        if not in_block:
            continue
        if line.startswith("$ "):
            current = (line[2:].strip(), [])
            out.append(current)
        elif current is not None:
            current[1].append(line)
    return [(cmd, lines) for cmd, lines in out if cmd.startswith("gearctl ")]


def _runnable(cmd: str) -> bool:
    return not any(s in f" {cmd} " for s in _NEEDS_FILES)


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, list[str]]:
    rc = main(argv)
    out, err = capsys.readouterr()
    return rc, err.splitlines() + out.splitlines()


def test_readme_has_transcripts() -> None:
    # the parser finds the README's transcripts (a parser that found none would make the next test vacuous)
    cmds = [c for c, _ in readme_transcripts(README.read_text()) if _runnable(c)]
    for expected in ("gearctl info shing1993", "gearctl simulate shing1993", "gearctl track shing1993_servo pid",
                     "gearctl precision shing1993_servo_friction mpc", "gearctl describe shing1993_servo pid_load",
                     "gearctl export shing1993_servo deadzone_inverse --out ctrl/"):
        assert expected in cmds


def test_readme_transcripts_are_what_the_commands_print(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    mismatches = []
    for cmd, shown in readme_transcripts(README.read_text()):
        if not _runnable(cmd):
            continue
        _, printed = _run(cmd.split()[1:], capsys)
        for line in shown:
            if not line.strip() or line.strip() == "..." or line.startswith(_TIMED):
                continue
            if line.endswith(" ...") and any(p.startswith(line[:-3]) for p in printed):
                continue  # the README cuts a long line short
            if line not in printed:
                near = [p for p in printed if p.split()[:1] == line.split()[:1]]
                mismatches.append(f"$ {cmd}\n  README:  {line!r}\n  printed: {near[0] if near else printed!r}")
    assert not mismatches, "\n".join(mismatches)


# ---- figures in running text --------------------------------------------------------------------------------------

def _figure(lines: list[str], label: str, unit: str = "") -> float:
    """The first number after ``label`` on the printed line that starts with it (after the indent)."""
    for line in lines:
        if line.strip().startswith(label):
            m = re.search(r"[-+]?\d[\d.]*(?:e[-+]?\d+)?", line.strip()[len(label):])
            assert m is not None, line
            return float(m.group())
    raise AssertionError(f"no line {label!r} in {lines}")


def _readme_flat() -> str:
    return " ".join(README.read_text().split())  # prose wraps anywhere: compare with single spaces


def test_reversal_offset_cuts_the_friction_servos_reversal_value(capsys: pytest.CaptureFixture[str]) -> None:
    # "on shing1993_servo_friction it cuts the PID's reversal value from 1502 to 88 µrad" (the ISO table's 88 too)
    _, pid = _run(["precision", "shing1993_servo_friction", "pid"], capsys)
    _, rev = _run(["precision", "shing1993_servo_friction", "reversal_offset"], capsys)
    b_pid, b_rev = _figure(pid, "reversal value B"), _figure(rev, "reversal value B")
    assert f"it cuts the PID's reversal value from {b_pid:.0f} to {b_rev:.0f} µrad" in _readme_flat()


@pytest.mark.slow
def test_cnc_table_inverse_against_pid(capsys: pytest.CaptureFixture[str]) -> None:
    # "gearctl precision tests/data/cnc_table_tight.toml --cycles 3 A 178 µrad against the PID's 85, now 87"
    model = str(DATA / "cnc_table_tight.toml")
    _, inv = _run(["precision", model, "--cycles", "3"], capsys)
    _, pid = _run(["precision", model, "pid", "--cycles", "3"], capsys)
    a_inv, a_pid = _figure(inv, "accuracy A"), _figure(pid, "accuracy A")
    assert f"A 178 µrad against the PID's {a_pid:.0f}, now {a_inv:.0f}" in _readme_flat()


def test_light_motor_move_ratio(capsys: pytest.CaptureFixture[str]) -> None:
    # the light-motor table: "deadzone_inverse, move | 2.8e-5 rad | 6.6e-6 rad (86× below the PID)"
    model = str(DATA / "light_motor_servo.toml")
    _, pid = _run(["track", model, "pid", "--reference", "move"], capsys)
    _, inv = _run(["track", model, "deadzone_inverse", "--reference", "move"], capsys)
    e_pid, e_inv = _figure(pid, "load-angle error       RMS"), _figure(inv, "load-angle error       RMS")
    assert f"| {e_inv:.2g} rad ({e_pid / e_inv:.0f}× below the PID) |".replace("e-06", "e-6") in README.read_text()


@pytest.mark.slow
def test_two_stage_train_positioning(capsys: pytest.CaptureFixture[str]) -> None:
    # "On servo_2stage_phm09 ... ISO A 6.7 mrad for the inverse and 5.5 for the MPC against the PID's 3.3
    # (gearctl bench servo_2stage_phm09, 5 cycles)": bench's ISO rows are precision's defaults (5 targets, 5 cycles)
    a = {}
    for ctrl in ("deadzone_inverse", "mpc", "pid"):
        _, lines = _run(["precision", "servo_2stage_phm09", ctrl], capsys)
        a[ctrl] = _figure(lines, "accuracy A") * 1e-3  # urad -> mrad
    phrase = (f"ISO A {a['deadzone_inverse']:.1f} mrad for the inverse and {a['mpc']:.1f} for the MPC against the "
              f"PID's {a['pid']:.1f}")
    assert phrase in _readme_flat()


@pytest.mark.slow
def test_perf_simulator_errors() -> None:
    # the `gearctl perf` block's accuracy figures (not its speeds, which are the machine's): each simulator's error
    # against the tight solve_ivp reference, as a fraction of b, printed with two digits (perf's `:.1e`)
    from gearctl.perf import sim_speed

    block = README.read_text().split("free vibration (shing1993):", 1)[1].split("```", 1)[0]
    shown = re.findall(r"error (\S+) b", block)
    printed = []
    for scenario in ("free", "pd"):
        r = sim_speed(scenario)
        printed += [f"{r[k]:.1e}" for k in ("gearctl_error", "python_control_error", "python_control_tight_error")]
    assert shown == printed


@pytest.mark.skipif(__import__("platform").machine() not in ("x86_64", "AMD64"), reason="the README's sizes are x86-64")
def test_exported_state_sizes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # "RAM is sizeof(gearctl_ctrl_t) per instance (x86-64: the PIDs 112 B, the reversal offset 168 B, the dead-zone
    # inverse 464 B, ...)": compiled here from each export's header
    import shutil
    import subprocess

    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler")
    m = re.search(r"x86-64: the PIDs (\d+) B, the reversal offset (\d+) B, the dead-zone inverse (\d+) B",
                  _readme_flat())
    assert m is not None
    src = tmp_path / "size.c"
    src.write_text('#include <stdio.h>\n#include "gearctl_ctrl.h"\n'
                   'int main(void) { printf("%zu", sizeof(gearctl_ctrl_t)); return 0; }\n')
    for ctrl, shown in zip(("pid", "reversal_offset", "deadzone_inverse"), m.groups(), strict=True):
        out = tmp_path / ctrl
        assert main(["export", "shing1993_servo", ctrl, "--out", str(out), "--no-vectors"]) == 0
        capsys.readouterr()
        exe = tmp_path / f"size_{ctrl}"
        subprocess.run([cc, "-std=c99", f"-I{out}", str(src), "-o", str(exe)], check=True)
        assert subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout == shown, ctrl
