"""Ctrl-C mid-sweep keeps the runs finished.

A Ctrl-C (SIGINT) during a sweep ended it with ``gearctl sweep: interrupted``, exit 130, and every finished run was
thrown away (3000 runs on a local cluster of 2, interrupted after 675 had finished: no JSON written). Now the finished
runs are handed over as a cluster failure's are (``--json``/``--out`` with ``missing``, the summary, one line naming
where they are), still with exit 130; from Python a :class:`gearctl.sweep.SweepInterrupted`, a ``KeyboardInterrupt``
carrying them.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from support import as_json, signal_when_marked, subprocess_cluster

import gearctl
import gearctl.parallel
import gearctl.sweep
from gearctl.cli import main

_ARGS = {"vary": ["backlash=0.5x:2x"], "runs": 12, "duration": 0.2, "batch": 2}


@pytest.fixture(scope="module")
def whole() -> gearctl.sweep.SweepResult:
    return gearctl.sweep.sweep("shing1993_servo", "pid", engine="serial", **_ARGS)


# --- from Python ------------------------------------------------------------------------------------------

def test_ctrl_c_in_a_serial_sweep_raises_a_keyboard_interrupt_carrying_the_runs_finished(
        whole: gearctl.sweep.SweepResult) -> None:
    def progress(done: int, total: int) -> None:  # noqa: ARG001 (Ctrl-C once 3 batches of 2 are in)
        if done >= 6:
            raise KeyboardInterrupt

    with pytest.raises(gearctl.sweep.SweepInterrupted) as info:
        gearctl.sweep.sweep("shing1993_servo", "pid", engine="serial", progress=progress, **_ARGS)
    exc = info.value
    assert isinstance(exc, KeyboardInterrupt) and not isinstance(exc, Exception)  # no `except Exception` eats it
    r = exc.result
    assert [x["index"] for x in r.runs] == [0, 1, 2, 3, 4, 5] and r.missing == (6, 7, 8, 9, 10, 11)
    assert as_json(r.runs) == as_json(whole.runs[:6])
    assert r.summary == gearctl.sweep.summarize(r.runs, r.keys)
    assert r.engine["interrupted"] is True and r.as_dict()["missing"] == [6, 7, 8, 9, 10, 11]
    assert str(exc) == "interrupted: 6 of 12 runs finished, 6 did not"


def test_ctrl_c_before_any_run_finished_is_a_plain_keyboard_interrupt(monkeypatch: pytest.MonkeyPatch) -> None:
    def interrupted(*a: Any, **kw: Any) -> Any:  # noqa: ARG001
        raise KeyboardInterrupt

    monkeypatch.setattr(gearctl.sweep, "sweep_task", interrupted)
    with pytest.raises(KeyboardInterrupt) as info:
        gearctl.sweep.sweep("shing1993_servo", "pid", engine="serial", **_ARGS)
    assert type(info.value) is KeyboardInterrupt


# --- the command line, without a cluster ----------------------------------------------------------------

def _partial(whole: gearctl.sweep.SweepResult, gone: tuple[int, ...]) -> gearctl.sweep.SweepResult:
    runs = [r for r in whole.runs if r["index"] not in gone]
    return gearctl.sweep.SweepResult(settings=whole.settings, vary=whole.vary, runs=runs,
                                     summary=gearctl.sweep.summarize(runs, whole.keys),
                                     engine={**whole.engine, "interrupted": True}, missing=gone)


_CLI = ["sweep", "shing1993_servo", "pid", "--vary", "backlash=0.5x:2x", "--runs", "12", "--duration", "0.2",
        "--quiet"]


@pytest.mark.parametrize("where", ["files", "stdout", "nothing"])
def test_an_interrupted_sweep_writes_what_finished_and_exits_130(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, whole: gearctl.sweep.SweepResult, where: str) -> None:
    gone = (3, 7, 11)
    partial = _partial(whole, gone)

    def interrupted(*a: Any, **kw: Any) -> Any:  # noqa: ARG001
        raise gearctl.sweep.SweepInterrupted("interrupted: 9 of 12 runs finished, 3 did not", result=partial)

    monkeypatch.setattr(gearctl.sweep, "sweep", interrupted)
    args = {"files": ["--json", str(tmp_path / "s.json"), "--out", str(tmp_path / "o")], "stdout": ["--json", "-"],
            "nothing": []}[where]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        rc = main([*_CLI, *args])
    assert rc == 130 and "Traceback" not in err.getvalue()
    lines = err.getvalue().splitlines()
    last = lines[-1]
    assert last.startswith("gearctl sweep: interrupted: 9 of 12 runs finished, 3 did not; the finished runs are in ")
    text = err.getvalue() if where == "stdout" else out.getvalue()
    assert "  missing                3 of 12 runs did not finish (interrupted): the figures are the 9 others'" in text
    if where == "files":
        assert last.endswith(f"--json {tmp_path / 's.json'} and --out {tmp_path / 'o'}") and len(lines) == 1
        data = json.loads((tmp_path / "s.json").read_text())
        rows = (tmp_path / "o" / "runs.csv").read_text().splitlines()
        assert [int(line.split(",")[0]) for line in rows[1:]] == [i for i in range(12) if i not in gone]
        assert "(interrupted)" in (tmp_path / "o" / "summary.md").read_text()
    elif where == "stdout":
        assert last.endswith("the JSON on standard output")
        data = json.loads(out.getvalue())
    else:
        assert last.endswith("the summary above (no --json or --out given)") and len(lines) == 1
        return
    assert data["missing"] == list(gone) and data["engine"]["interrupted"] is True
    assert data["runs"] == as_json(partial.runs)


def test_an_interrupted_sweep_names_the_worker_it_dropped_before(
        monkeypatch: pytest.MonkeyPatch, whole: gearctl.sweep.SweepResult) -> None:
    # a worker dropped mid-sweep, then Ctrl-C: the note was said only for a whole sweep (the JSON alone had it)
    partial = _partial(whole, (4,))
    partial.engine["dropped"] = [{"worker": "tcp://10.0.0.9:1", "tasks": 1, "restarted": False}]

    def interrupted(*a: Any, **kw: Any) -> Any:  # noqa: ARG001
        raise gearctl.sweep.SweepInterrupted("interrupted: 11 of 12 runs finished, 1 did not", result=partial)

    monkeypatch.setattr(gearctl.sweep, "sweep", interrupted)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = main(_CLI)
    lines = err.getvalue().splitlines()
    assert rc == 130 and len(lines) == 2, err.getvalue()
    assert lines[0].startswith("gearctl sweep: note: the worker tcp://10.0.0.9:1 was not heard from for ")
    assert lines[1].startswith("gearctl sweep: interrupted: 11 of 12 runs finished, 1 did not; ")


def test_a_second_ctrl_c_while_writing_ends_the_command(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, whole: gearctl.sweep.SweepResult) -> None:
    import gearctl.cli.sweep_cmds as cmds

    def interrupted(*a: Any, **kw: Any) -> Any:  # noqa: ARG001
        raise gearctl.sweep.SweepInterrupted("interrupted: 11 of 12 runs finished, 1 did not",
                                             result=_partial(whole, (5,)))

    def second(*a: Any, **kw: Any) -> Any:  # noqa: ARG001
        raise KeyboardInterrupt

    monkeypatch.setattr(gearctl.sweep, "sweep", interrupted)
    monkeypatch.setattr(cmds, "write_whole", second)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = main([*_CLI, "--json", str(tmp_path / "s.json")])
    assert rc == 130 and err.getvalue() == "gearctl sweep: interrupted\n"
    assert not (tmp_path / "s.json").exists()


class _Closing:
    """A client or a cluster whose close is interrupted by a Ctrl-C (the client's), recording the closes."""

    def __init__(self, log: list[str], name: str, ctrl_c: bool) -> None:
        self.log, self.name, self.ctrl_c = log, name, ctrl_c

    def close(self, **kw: Any) -> None:  # noqa: ARG002
        if self.ctrl_c:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)  # (where the handler would raise)
        self.log.append(self.name)


class _Cancellable:
    def __init__(self, log: list[str]) -> None:
        self.log = log

    def cancel(self) -> None:
        self.log.append("cancel")


def test_a_ctrl_c_while_the_cluster_closes_is_held_until_it_is_closed() -> None:
    log: list[str] = []
    eng = object.__new__(gearctl.parallel.Engine)
    eng.own, eng.client = True, _Closing(log, "client", ctrl_c=True)
    eng.cluster = _Closing(log, "cluster", ctrl_c=False)
    with pytest.raises(KeyboardInterrupt):
        eng.close(cancel=[_Cancellable(log), _Cancellable(log)])
    assert log == ["cancel", "cancel", "client", "cluster"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


# --- a real Ctrl-C ---------------------------------------------------------------------------------------

_CHILD = """
import sys
from pathlib import Path
import gearctl.sweep
from gearctl.cli import main

original, mark = gearctl.sweep.sweep, Path(sys.argv[1])


def sweep(*a, **kw):
    def progress(done, total):
        if done >= 4 and not mark.exists():
            mark.write_text(str(done))
    return original(*a, **{**kw, "progress": progress})


gearctl.sweep.sweep = sweep
sys.exit(main(sys.argv[2:]))
"""


def _ctrl_c_after_some_runs(tmp_path: Path, extra: list[str], second: float | None = None,
                            sig: int = signal.SIGINT) -> tuple[int, str, str, float, int]:
    """Run the CLI sweep in a process of its own session; once 4 runs are in, SIGINT its whole group (as a
    terminal's Ctrl-C; again ``second`` seconds later); its exit code, stdout, stderr, the seconds it took to end
    and its session id."""
    mark = tmp_path / "four.txt"
    return signal_when_marked([sys.executable, "-c", _CHILD, str(mark), "sweep", "shing1993_servo", "pid", "--vary",
                               "backlash=0.5x:2x", "--runs", "4000", "--duration", "1", "--batch", "1", "--quiet",
                               "--json", str(tmp_path / "s.json"), "--out", str(tmp_path / "o"), *extra], mark,
                              tmp_path, sig, second)


def _check_handed_over(tmp_path: Path, rc: int, out: str, err: str) -> dict[str, Any]:
    assert rc == 130, err
    assert "Traceback" not in err, err
    lines = err.splitlines()
    assert len(lines) == 1, err
    data = json.loads((tmp_path / "s.json").read_text())
    done, missing = [r["index"] for r in data["runs"]], data["missing"]
    assert len(done) >= 4 and missing and sorted(done + missing) == list(range(4000))
    assert lines[0] == (f"gearctl sweep: interrupted: {len(done)} of 4000 runs finished, {len(missing)} did not; the "
                        f"finished runs are in --json {tmp_path / 's.json'} and --out {tmp_path / 'o'}")
    assert data["engine"]["interrupted"] is True and data["summary"]["runs"] == len(done)
    assert all(r["status"] == "ok" for r in data["runs"])
    assert f"  missing                {len(missing)} of 4000 runs did not finish (interrupted)" in out
    assert len((tmp_path / "o" / "runs.csv").read_text().splitlines()) == len(done) + 1
    return data


@pytest.mark.slow
def test_ctrl_c_on_a_local_cluster_keeps_the_runs_finished(tmp_path: Path) -> None:
    # a second Ctrl-C 0.3 s after the first falls in the cluster's close: held until it is closed (it stopped the
    # close half-way, and the scheduler's tracebacks, CommClosedError, filled stderr), then the runs handed over.
    # (The single Ctrl-C is the same path up to the close: this case checks it too; the SIGTERM test below ends
    # on one signal.)
    second = 0.3
    import psutil

    rc, out, err, took, sid = _ctrl_c_after_some_runs(tmp_path, ["--workers", "2"], second)
    data = _check_handed_over(tmp_path, rc, out, err)
    assert data["engine"]["where"] == "local cluster (2 processes)"
    assert took < 20
    # the session's processes (the workers and their nannies) are gone with the command
    time.sleep(0.5)
    left = []
    for q in psutil.process_iter(["pid", "status"]):
        with contextlib.suppress(OSError):
            if q.info["status"] != psutil.STATUS_ZOMBIE and os.getsid(q.info["pid"]) == sid:
                left.append(q)
    assert not left, left



@pytest.mark.slow
def test_ctrl_c_on_a_scheduler_keeps_the_runs_finished_and_cancels_the_rest(tmp_path: Path) -> None:
    from distributed import Client

    with subprocess_cluster(tmp_path, workers=1) as (address, _procs):
        rc, out, err, took, _ = _ctrl_c_after_some_runs(tmp_path, ["--scheduler", address])
        data = _check_handed_over(tmp_path, rc, out, err)
        assert data["engine"]["where"] == address and took < 20
        with Client(address, timeout=30, set_as_default=False) as c:  # the cluster's share cancelled, still usable
            deadline = time.monotonic() + 15
            while c.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks)) and \
                    time.monotonic() < deadline:
                time.sleep(0.2)
            assert c.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks)) == 0
            assert c.submit(sum, [1, 2]).result(timeout=30) == 3


@pytest.mark.slow
def test_sigterm_hands_over_the_runs_finished_as_ctrl_c_does(tmp_path: Path) -> None:
    # `kill PID` (SIGTERM; a batch system at the end of a job's time sends it to the job's processes) ended the sweep
    # at once, nothing written: it is now taken as a Ctrl-C, the finished runs handed over, exit 130
    rc, out, err, took, _ = _ctrl_c_after_some_runs(tmp_path, ["--workers", "2"], sig=signal.SIGTERM)
    data = _check_handed_over(tmp_path, rc, out, err)
    assert data["engine"]["interrupted"] is True and took < 20
