"""Ctrl-C mid-bench keeps the cells finished, as the sweep keeps its runs (tests/test_t2_interrupt.py).

``gearctl bench`` on Ctrl-C (or SIGTERM) lost every run that had finished: one line, exit 130, nothing written. Now
the cells that finished are written (``--json``, ``--out``) with ``interrupted`` and ``not_run`` (the cells that did
not run), the tables of what finished are printed, then one line naming where they are, exit 130; from Python a
:class:`gearctl.bench.BenchInterrupted`, a ``KeyboardInterrupt`` carrying them. A small bench: one model, the PID,
short runs.
"""

from __future__ import annotations

import contextlib
import io
import json
import signal
import sys
from pathlib import Path
from typing import Any

import pytest
from support import signal_when_marked

import gearctl
import gearctl.bench
from gearctl.bench import BenchInterrupted, BenchSpec, run_bench
from gearctl.cli import main

_SPEC = BenchSpec(models=("shing1993_servo",), controllers=("pid",), plants=("improved",),
                  references=("sine", "step"), duration=0.2, precision=False)


def _key(r: dict[str, Any]) -> tuple[str, ...]:
    return tuple(r[k] for k in ("model", "controller", "plant", "design", "reference"))


@pytest.fixture(scope="module")
def whole() -> dict[str, Any]:
    return run_bench(_SPEC, jobs=1)


# --- from Python ------------------------------------------------------------------------------------------

def test_ctrl_c_in_a_bench_raises_a_keyboard_interrupt_carrying_the_cells_finished(whole: dict[str, Any]) -> None:
    def progress(done: int, total: int) -> None:  # noqa: ARG001 (Ctrl-C once 2 of the 4 runs are in)
        if done >= 2:
            raise KeyboardInterrupt

    with pytest.raises(BenchInterrupted) as info:
        run_bench(_SPEC, jobs=1, progress=progress)
    exc = info.value
    assert isinstance(exc, KeyboardInterrupt) and not isinstance(exc, Exception)  # no `except Exception` eats it
    r = exc.result
    assert str(exc) == "interrupted: 2 of 4 runs finished, 2 did not"
    assert r["interrupted"] is True and r["tasks"] == 4 and len(r["runs"]) == 2
    # the tasks run in order: the sine on the improved and backlash-free plants, then the step's, not run
    assert r["not_run"] == [{"model": "shing1993_servo", "controller": "pid", "plant": p, "design": "improved",
                             "reference": "step"} for p in ("improved", "backlash-free")]
    cells = {_key(x): x for x in whole["runs"]}
    for x in r["runs"]:  # the figures of a whole bench (its wall time aside)
        assert {**x, "wall_time": 0} == {**cells[_key(x)], "wall_time": 0}
    assert set(map(_key, r["runs"])) | {_key(c) for c in r["not_run"]} == set(cells)
    assert "interrupted: 2 of 4 runs did not run" in gearctl.bench.bench_table(r)


def test_ctrl_c_before_any_run_finished_is_a_plain_keyboard_interrupt() -> None:
    import gearctl.parallel

    with pytest.raises(KeyboardInterrupt) as plain:
        gearctl.parallel.map_tasks(_stop, [1, 2], workers=1)
    assert type(plain.value) is KeyboardInterrupt


def _stop(x: Any) -> Any:  # noqa: ARG001
    raise KeyboardInterrupt


# --- the command line, without a cluster ----------------------------------------------------------------

_CLI = ["bench", "shing1993_servo", "--controllers", "pid", "--plants", "improved", "--references", "sine,step",
        "--duration", "0.2", "--no-precision", "--jobs", "1", "--quiet"]


def _partial(whole: dict[str, Any]) -> dict[str, Any]:
    gone = [r for r in whole["runs"] if r["reference"] == "step"]
    out = {**whole, "runs": [r for r in whole["runs"] if r["reference"] != "step"], "interrupted": True,
           "not_run": [dict(zip(("model", "controller", "plant", "design", "reference"), _key(r), strict=True))
                       for r in gone]}
    out["ratios"] = gearctl.bench._ratios(out["runs"])
    return out


@pytest.mark.parametrize("where", ["files", "stdout", "nothing"])
def test_an_interrupted_bench_writes_what_finished_and_exits_130(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, whole: dict[str, Any], where: str) -> None:
    partial = _partial(whole)

    def interrupted(*a: Any, **kw: Any) -> Any:  # noqa: ARG001
        raise BenchInterrupted("interrupted: 2 of 4 runs finished, 2 did not", result=partial)

    monkeypatch.setattr(gearctl.bench, "run_bench", interrupted)
    args = {"files": ["--json", str(tmp_path / "b.json"), "--out", str(tmp_path / "o")], "stdout": ["--json", "-"],
            "nothing": []}[where]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        rc = main([*_CLI, *args])
    assert rc == 130 and "Traceback" not in err.getvalue()
    lines = err.getvalue().splitlines()
    last = lines[-1]
    assert last.startswith("gearctl bench: interrupted: 2 of 4 runs finished, 2 did not; the finished runs are in ")
    tables = err.getvalue() if where == "stdout" else out.getvalue()
    assert "interrupted: 2 of 4 runs did not run" in tables and "2 of 4 runs in " in tables
    if where == "files":
        assert last.endswith(f"--json {tmp_path / 'b.json'} and --out {tmp_path / 'o'}") and len(lines) == 1
        data = json.loads((tmp_path / "b.json").read_text())
        report = (tmp_path / "o" / "report.md").read_text()
        assert "interrupted: 2 of 4 runs did not run" in report and (tmp_path / "o" / "errors_step.png").is_file()
    elif where == "stdout":
        assert last.endswith("the JSON on standard output")
        data = json.loads(out.getvalue())
    else:
        assert last.endswith("the tables above (no --json or --out given)") and len(lines) == 1
        return
    assert data["interrupted"] is True and data["not_run"] == partial["not_run"]
    assert [r["reference"] for r in data["runs"]] == ["sine", "sine"]


def test_a_second_ctrl_c_while_the_bench_writes_ends_the_command(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, whole: dict[str, Any]) -> None:
    import gearctl.cli.loop_cmds as cmds

    def interrupted(*a: Any, **kw: Any) -> Any:  # noqa: ARG001
        raise BenchInterrupted("interrupted: 2 of 4 runs finished, 2 did not", result=_partial(whole))

    def second(*a: Any, **kw: Any) -> Any:  # noqa: ARG001
        raise KeyboardInterrupt

    monkeypatch.setattr(gearctl.bench, "run_bench", interrupted)
    monkeypatch.setattr(cmds, "write_whole", second)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = main([*_CLI, "--json", str(tmp_path / "b.json")])
    assert rc == 130 and err.getvalue() == "gearctl bench: interrupted\n"
    assert not (tmp_path / "b.json").exists()


# --- a real Ctrl-C ---------------------------------------------------------------------------------------

_CHILD = """
import sys
from pathlib import Path
import gearctl.bench
from gearctl.cli import main

original, mark = gearctl.bench.run_bench, Path(sys.argv[1])


def run_bench(*a, **kw):
    inner = kw.get("progress")

    def progress(done, total):
        inner(done, total)
        if done >= 2 and not mark.exists():
            mark.write_text(str(done))
    return original(*a, **{**kw, "progress": progress})


gearctl.bench.run_bench = run_bench
sys.exit(main(sys.argv[2:]))
"""


def _signal_after_two_runs(tmp_path: Path, jobs: str, sig: int, second: float | None = None) -> tuple[int, str, str]:
    """The bench (9 runs of 40 s: about 3 s in one process) in a session of its own; ``sig`` to its whole group once
    2 runs are in (again, as SIGINT, ``second`` s later)."""
    mark = tmp_path / "two.txt"
    rc, out, err, _, _ = signal_when_marked(
        [sys.executable, "-c", _CHILD, str(mark), "bench", "shing1993_servo", "--controllers", "pid", "--plants",
         "improved,tvms", "--references", "sine,move,step", "--duration", "40", "--no-precision", "--jobs", jobs,
         "--quiet", "--json", str(tmp_path / "b.json"), "--out", str(tmp_path / "o")], mark, tmp_path, sig, second)
    return rc, out, err


def _check_handed_over(tmp_path: Path, rc: int, out: str, err: str) -> dict[str, Any]:
    assert rc == 130, err
    assert "Traceback" not in err, err
    lines = err.splitlines()
    assert len(lines) == 1, err
    data = json.loads((tmp_path / "b.json").read_text())
    done, left = len(data["runs"]), len(data["not_run"])
    assert data["interrupted"] is True and done >= 2 and left and done + left == data["tasks"] == 9
    assert lines[0] == (f"gearctl bench: interrupted: {done} of 9 runs finished, {left} did not; the finished runs "
                        f"are in --json {tmp_path / 'b.json'} and --out {tmp_path / 'o'}")
    assert f"{done} of 9 runs in " in out and (tmp_path / "o" / "report.md").is_file()
    return data


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_or_sigterm_in_a_bench_keeps_the_cells_finished(tmp_path: Path, sig: int) -> None:
    rc, out, err = _signal_after_two_runs(tmp_path, "1", sig)
    _check_handed_over(tmp_path, rc, out, err)


@pytest.mark.slow
def test_ctrl_c_in_a_bench_on_a_local_cluster_keeps_the_cells_finished(tmp_path: Path) -> None:
    # a second Ctrl-C 0.3 s after the first falls in the cluster's close: held until it is closed, as the sweep's
    # (the single Ctrl-C is the same path up to the close; the one-process cases above end on one signal)
    rc, out, err = _signal_after_two_runs(tmp_path, "2", signal.SIGINT, 0.3)
    data = _check_handed_over(tmp_path, rc, out, err)
    assert data["jobs"] == 2
