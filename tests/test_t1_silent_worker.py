"""A sweep on a real Dask cluster whose worker is stopped (``kill -STOP``) or hangs mid-sweep.

A worker the scheduler has not heard from for ``WORKER_TIMEOUT`` seconds that holds some of the sweep's tasks
ended the sweep (exit 2) and every run already finished was thrown away: 107 of 200 runs lost after 66 s on a
two-worker cluster. Now the scheduler drops it (its own ``remove_worker``, as its ``worker-ttl`` would after
5 min) while another worker is left, and the sweep finishes with a serial run's figures; with no worker left
(or a scheduler that will not drop it) the runs finished are handed over with the others named.

The clusters are real ``dask scheduler`` / ``dask worker`` processes (tests/support.py), each stopped worker
killed at the end; ``WORKER_TIMEOUT`` is shortened to a few seconds.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from support import as_json, subprocess_cluster
from support import within as _within

import gearctl.parallel
import gearctl.sweep
from gearctl.cli import main

_ARGS = {"vary": ["backlash=0.5x:2x"], "runs": 24, "duration": 0.5, "batch": 1}
_CLI = ["sweep", "shing1993_servo", "pid", "--vary", "backlash=0.5x:2x", "--runs", "24", "--duration", "0.5",
        "--batch", "1", "--quiet"]




def _names(address: str) -> dict[str, str]:
    from distributed import Client

    with Client(address, timeout=30, set_as_default=False) as c:
        return {d["name"]: w for w, d in c.scheduler_info(n_workers=-1)["workers"].items()}


@pytest.fixture(scope="module")
def serial() -> gearctl.sweep.SweepResult:
    return gearctl.sweep.sweep("shing1993_servo", "pid", engine="serial", **_ARGS)


def _stop_when(procs: list, k: int, at: int) -> Callable[[int, int], None]:
    """A progress callback that stops the worker process ``procs[k]`` (its whole group) once ``at`` runs are done."""
    def progress(done: int, total: int) -> None:  # noqa: ARG001
        if done >= at and not getattr(progress, "stopped", False):
            progress.stopped = True  # type: ignore[attr-defined]
            os.killpg(procs[k].pid, signal.SIGSTOP)
    return progress


@pytest.mark.slow
def test_a_stopped_worker_is_dropped_and_the_sweep_ends_as_a_serial_run(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, serial: gearctl.sweep.SweepResult) -> None:
    # the CLI on two workers, one stopped after the first results: it was exit 2 after WORKER_TIMEOUT, every
    # finished run lost; now it is dropped, its tasks rerun on the other, and the JSON is the serial run's
    monkeypatch.setattr(gearctl.parallel, "WORKER_TIMEOUT", 3.0)
    out = tmp_path / "sweep.json"
    with subprocess_cluster(tmp_path, workers=2) as (address, procs):
        stopped = _names(address)["w0"]
        original = gearctl.sweep.sweep

        def with_stop(*a: Any, **kw: Any) -> Any:  # (the command imports sweep when it runs)
            return original(*a, **{**kw, "progress": _stop_when(procs, 1, 2)})

        monkeypatch.setattr(gearctl.sweep, "sweep", with_stop)
        err = io.StringIO()
        t0 = time.monotonic()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            rc = _within(40, lambda: main([*_CLI, "--scheduler", address, "--json", str(out)]))
        took = time.monotonic() - t0
        with contextlib.suppress(ProcessLookupError):
            os.killpg(procs[1].pid, signal.SIGCONT)
    assert rc == 0, err.getvalue()
    assert "Traceback" not in err.getvalue()
    notes = [line for line in err.getvalue().splitlines() if "dropped" in line]
    assert len(notes) == 1 and notes[0].startswith(f"gearctl sweep: note: the worker {stopped} was not heard from "
                                                   f"for 3 s holding "), err.getvalue()
    assert notes[0].endswith("task(s): dropped from the scheduler (removed), its tasks rerun on the other workers")
    got = json.loads(out.read_text())
    want = as_json(serial.as_dict())
    assert got["runs"] == want["runs"]
    assert got["summary"] == want["summary"]
    assert "missing" not in got
    assert [(d["worker"], d["restarted"]) for d in got["engine"]["dropped"]] == [(stopped, False)]
    assert 3.0 < took < 35


@pytest.mark.slow
def test_a_stopped_worker_under_a_nanny_is_restarted_by_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, serial: gearctl.sweep.SweepResult) -> None:
    # `dask worker` starts each worker under a nanny: Dask's worker-ttl has the nanny end it and start a fresh one,
    # and so does the drop (the cluster keeps its workers); here the worker process alone is stopped
    import subprocess
    import sys

    import psutil
    from distributed import Client

    monkeypatch.setattr(gearctl.parallel, "WORKER_TIMEOUT", 3.0)
    with subprocess_cluster(tmp_path, workers=1) as (address, procs):
        nanny = subprocess.Popen([sys.executable, "-m", "dask", "worker", address, "--nthreads", "1",
                                  "--no-dashboard", "--host", "127.0.0.1", "--name", "n0",
                                  "--local-directory", str(tmp_path / "n0")],
                                 cwd=tmp_path, env={**os.environ, "PYTHONPATH": os.pathsep.join(
                                     filter(None, [str(Path(gearctl.__file__).parents[1]),
                                                   os.environ.get("PYTHONPATH")]))},
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        procs.append(nanny)  # (killed with its group at the end, as the others)
        worker_pid = None
        try:
            with Client(address, timeout=30, set_as_default=False) as client:
                client.wait_for_workers(2, timeout=60)
                stopped = _names(address)["n0"]
                pid = {int(p.pid) for p in psutil.Process(nanny.pid).children()
                       if "spawn_main" in " ".join(p.cmdline())}
                assert len(pid) == 1
                worker_pid = pid.pop()

                def progress(done: int, total: int) -> None:  # noqa: ARG001
                    if done >= 2 and not getattr(progress, "stopped", False):
                        progress.stopped = True  # type: ignore[attr-defined]
                        os.kill(worker_pid, signal.SIGSTOP)

                r = _within(40, lambda: gearctl.sweep.sweep("shing1993_servo", "pid", client=client,
                                                            progress=progress, **_ARGS))
                client.wait_for_workers(2, timeout=30)  # the nanny's fresh worker joined
                names = sorted(d["name"] for d in client.scheduler_info(n_workers=-1)["workers"].values())
        finally:
            if worker_pid is not None:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(worker_pid, signal.SIGCONT)
    assert not isinstance(r, BaseException), r
    assert r.engine["dropped"] == [{"worker": stopped, "tasks": r.engine["dropped"][0]["tasks"], "restarted": True}]
    assert names == ["n0", "w0"]  # a fresh n0 in place of the stopped one, which its nanny ended
    assert not psutil.pid_exists(worker_pid) or psutil.Process(worker_pid).status() == psutil.STATUS_ZOMBIE
    assert as_json(r.runs) == as_json(serial.runs)


@pytest.mark.slow
def test_a_worker_stopped_and_resumed_within_the_timeout_is_not_dropped(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, serial: gearctl.sweep.SweepResult) -> None:
    # kill -STOP, then kill -CONT before WORKER_TIMEOUT: the sweep finishes normally, nothing dropped
    from distributed import Client

    monkeypatch.setattr(gearctl.parallel, "WORKER_TIMEOUT", 6.0)
    with subprocess_cluster(tmp_path, workers=2) as (address, procs):
        stop = _stop_when(procs, 1, 2)

        def progress(done: int, total: int) -> None:
            first = not getattr(stop, "stopped", False)
            stop(done, total)
            if first and getattr(stop, "stopped", False):
                threading.Timer(3.0, os.killpg, (procs[1].pid, signal.SIGCONT)).start()

        with Client(address, timeout=30, set_as_default=False) as client:
            r = _within(40, lambda: gearctl.sweep.sweep("shing1993_servo", "pid", client=client, progress=progress,
                                                        **_ARGS))
            left = len(client.scheduler_info(n_workers=-1)["workers"])
    assert not isinstance(r, BaseException), r
    assert getattr(stop, "stopped", False)
    assert "dropped" not in r.engine and left == 2
    assert as_json(r.runs) == as_json(serial.runs)


@pytest.mark.slow
@pytest.mark.parametrize("via", ["api", "cli"])
def test_a_lone_stopped_worker_hands_over_the_runs_finished(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, serial: gearctl.sweep.SweepResult, via: str) -> None:
    # one worker, stopped mid-sweep: nobody is left to take its tasks, so the sweep ends (exit 2), but with the
    # runs finished (they were thrown away) and the others named
    monkeypatch.setattr(gearctl.parallel, "WORKER_TIMEOUT", 3.0)
    out = tmp_path / "sweep.json"
    with subprocess_cluster(tmp_path, workers=1) as (address, procs):
        stopped = _names(address)["w0"]
        if via == "api":
            got = _within(40, lambda: gearctl.sweep.sweep("shing1993_servo", "pid", scheduler=address,
                                                          progress=_stop_when(procs, 1, 4), **_ARGS))
        else:
            original = gearctl.sweep.sweep
            monkeypatch.setattr(gearctl.sweep, "sweep", lambda *a, **kw: original(
                *a, **{**kw, "progress": _stop_when(procs, 1, 4)}))
            err = io.StringIO()
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                rc = _within(40, lambda: main([*_CLI, "--scheduler", address, "--json", str(out)]))
        with contextlib.suppress(ProcessLookupError):
            os.killpg(procs[1].pid, signal.SIGCONT)
    want = {r["index"]: r for r in as_json(serial.runs)}
    if via == "api":
        assert isinstance(got, gearctl.sweep.SweepIncomplete), got
        assert isinstance(got, gearctl.InputError) and got.field == "scheduler"
        msg, data = str(got), as_json(got.result.as_dict())
    else:
        assert rc == 2
        lines = err.getvalue().splitlines()
        assert len(lines) == 1 and "Traceback" not in err.getvalue(), err.getvalue()
        msg, data = lines[0], json.loads(out.read_text())
        assert msg.startswith("gearctl sweep: error: ") and msg.endswith(f"the finished runs are in --json {out}")
    assert f"the worker {stopped} has not been heard from for 3 s" in msg
    assert "no other worker is left to take them" in msg
    done = [r["index"] for r in data["runs"]]
    missing = data["missing"]
    assert len(done) >= 4 and missing and sorted(done + missing) == list(range(24))
    assert f"; {len(missing)} of 24 runs did not finish (runs " in msg
    assert [want[r["index"]] for r in data["runs"]] == data["runs"]  # each finished run is the serial run's
    assert data["summary"]["runs"] == len(done)
    assert data["settings"] == as_json(serial.settings)


class _Refusing:
    """A client whose scheduler will not run the drop (it times out, or refuses functions)."""

    def __init__(self, exc: BaseException) -> None:
        self.exc, self.asked = exc, []

    def run_on_scheduler(self, fn: Any, *args: Any, **kwargs: Any) -> Any:
        self.asked.append((fn, args, kwargs))
        raise self.exc


@pytest.mark.parametrize(("exc", "why"), [
    (TimeoutError(), "the scheduler did not drop tcp://10.0.0.1:1 within 15 s"),
    (RuntimeError("pickle disallowed"), "the scheduler did not drop tcp://10.0.0.1:1 (RuntimeError: pickle "
                                         "disallowed)")])
def test_a_drop_the_scheduler_does_not_do_is_said_and_not_counted(exc: BaseException, why: str) -> None:
    heard = {"tcp://10.0.0.1:1": (1.0, 0.0)}
    told: list = []
    client = _Refusing(exc)
    got = gearctl.parallel._drop_workers(client, {"tcp://10.0.0.1:1": 2}, heard, lambda w, n: told.append((w, n)))
    assert got == why
    assert told == [] and "tcp://10.0.0.1:1" in heard
    fn, args, kwargs = client.asked[0]
    assert fn is gearctl.parallel._drop_worker and args == ("tcp://10.0.0.1:1", gearctl.parallel.DROP_TIMEOUT)
    assert kwargs == {"callback_timeout": gearctl.parallel.DROP_TIMEOUT + gearctl.parallel.ANSWER_TIMEOUT}


@pytest.mark.parametrize("where", ["out", "stdout", "nothing"])
def test_an_unfinished_grid_sweep_writes_what_finished(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                        where: str) -> None:
    # the CLI's side of SweepIncomplete, without a cluster: a two-key grid with runs missing writes runs.csv,
    # summary.md and the plots but the map (a grid with holes), the JSON with `missing`, the summary, then one line
    whole = gearctl.sweep.sweep("shing1993_servo", "pid", vary=["backlash=0.5x:2x", "coulomb_friction2=0,0.01,0.02"],
                                runs=3, grid=True, duration=0.2, engine="serial")
    gone = (2, 5)
    partial = gearctl.sweep.SweepResult(
        settings=whole.settings, vary=whole.vary, runs=[r for r in whole.runs if r["index"] not in gone],
        summary=gearctl.sweep.summarize([r for r in whole.runs if r["index"] not in gone], whole.keys),
        engine=whole.engine, missing=gone)

    def unfinished(*a: Any, **kw: Any) -> Any:  # noqa: ARG001
        raise gearctl.sweep.SweepIncomplete("tcp://h:1: the worker tcp://h:2 has ...; 2 of 9 runs did not finish "
                                            "(runs 2, 5), 7 did", result=partial, field="scheduler")

    monkeypatch.setattr(gearctl.sweep, "sweep", unfinished)
    args = ["sweep", "shing1993_servo", "pid", "--grid", "--vary", "backlash=0.5x:2x", "--vary",
            "coulomb_friction2=0,0.01,0.02", "--runs", "3", "--duration", "0.2", "--quiet"]
    args += {"out": ["--out", str(tmp_path / "o"), "--json", str(tmp_path / "s.json")], "stdout": ["--json", "-"],
             "nothing": []}[where]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        rc = main(args)
    assert rc == 2 and "Traceback" not in err.getvalue()
    last = err.getvalue().splitlines()[-1]
    assert last.startswith("gearctl sweep: error: tcp://h:1: the worker tcp://h:2 has ...; 2 of 9 runs did not "
                           "finish (runs 2, 5), 7 did; the finished runs are in ")
    text = err.getvalue() if where == "stdout" else out.getvalue()
    assert "  missing                2 of 9 runs did not finish (the cluster failed): the figures are the 7 " in text
    if where == "out":
        assert last.endswith(f"--json {tmp_path / 's.json'} and --out {tmp_path / 'o'}")
        data = json.loads((tmp_path / "s.json").read_text())
        rows = (tmp_path / "o" / "runs.csv").read_text().splitlines()
        assert [int(line.split(",")[0]) for line in rows[1:]] == [i for i in range(9) if i not in gone]
        assert (tmp_path / "o" / "histogram.png").exists() and not (tmp_path / "o" / "map.png").exists()
        assert "missing" in (tmp_path / "o" / "summary.md").read_text()
    elif where == "stdout":
        assert last.endswith("the JSON on standard output")
        data = json.loads(out.getvalue())
    else:
        assert last.endswith("the summary above (no --json or --out given)")
        assert err.getvalue().count("\n") == 1
        return
    assert data["missing"] == list(gone) and [r["index"] for r in data["runs"]] == [0, 1, 3, 4, 6, 7, 8]
    assert data["summary"]["runs"] == 7 and data["settings"]["runs"] == 9


@pytest.mark.slow
def test_a_scheduler_lost_mid_sweep_hands_over_the_runs_finished(
        tmp_path: Path, serial: gearctl.sweep.SweepResult) -> None:
    # the other ways a cluster fails mid-sweep lost the runs finished too: the scheduler killed (kill -9) after 3
    with subprocess_cluster(tmp_path, workers=1) as (address, procs):
        def progress(done: int, total: int) -> None:  # noqa: ARG001
            if done >= 3 and procs[0].poll() is None:
                os.killpg(procs[0].pid, signal.SIGKILL)
                procs[0].wait(timeout=30)

        got = _within(40, lambda: gearctl.sweep.sweep("shing1993_servo", "pid", scheduler=address, progress=progress,
                                                      **_ARGS))
    assert isinstance(got, gearctl.sweep.SweepIncomplete), got
    assert "the scheduler went away or cancelled them" in str(got)
    data = as_json(got.result.as_dict())
    want = {r["index"]: r for r in as_json(serial.runs)}
    assert len(data["runs"]) >= 3 and sorted([r["index"] for r in data["runs"]] + data["missing"]) == list(range(24))
    assert all(want[r["index"]] == r for r in data["runs"])
    miss = data["missing"]
    shown = ", ".join(map(str, miss[:10])) + (", ..." if len(miss) > 10 else "")
    assert str(got).endswith(f"{len(miss)} of 24 runs did not finish (runs {shown}), {len(data['runs'])} did")


@pytest.mark.slow
def test_a_worker_stopped_before_the_sweep_is_dropped_when_others_answer(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, serial: gearctl.sweep.SweepResult) -> None:
    # a worker hung before the sweep (not the user's to restart on a shared cluster) refused every sweep with
    # "did not all answer ... restart them, or stop them" until Dask's worker-ttl removed it; with another worker
    # answering it is dropped at the check, and the sweep runs on the others
    monkeypatch.setattr(gearctl.parallel, "WORKER_TIMEOUT", 3.0)
    out = tmp_path / "sweep.json"
    with subprocess_cluster(tmp_path, workers=2) as (address, procs):
        stopped = _names(address)["w1"]
        os.killpg(procs[2].pid, signal.SIGSTOP)
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            rc = _within(40, lambda: main([*_CLI, "--scheduler", address, "--json", str(out)]))
        with contextlib.suppress(ProcessLookupError):
            os.killpg(procs[2].pid, signal.SIGCONT)
    assert rc == 0, err.getvalue()
    assert f"gearctl sweep: note: the worker {stopped} was not heard from for 3 s at the check of the workers, " \
           f"before any run: dropped from the scheduler (removed)" in err.getvalue()
    got = json.loads(out.read_text())
    assert got["engine"]["dropped"] == [{"worker": stopped, "tasks": 0, "restarted": False}]
    assert got["runs"] == as_json(serial.runs)
