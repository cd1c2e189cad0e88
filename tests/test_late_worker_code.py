"""Every Dask task checks that its worker runs the client's gearctl (gearctl.parallel.checked).

The Engine checks the workers there when it opens; a worker started from another checkout that joined mid-sweep
ran the tasks it was given on its own code, its figures mixed with the others' without a word (a review: 1260 of
3000 runs came from it).
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

import gearctl
from gearctl import InputError
from gearctl.parallel import checked, code_id
from gearctl.sweep import sweep


def _double(x: int) -> int:
    return 2 * x


def test_checked_runs_the_task_on_the_same_code() -> None:
    assert checked(code_id(), _double, 21) == 42


def test_checked_refuses_other_code() -> None:
    with pytest.raises(InputError, match=r"a worker, which joined .* runs gearctl \S+\+[0-9a-f]{12}, this is "
                                         r"0\.1\.0\+000000000000 \(version\+code hash\)"):
        checked("0.1.0+000000000000", _double, 21)


def test_a_worker_that_joins_mid_sweep_with_other_code_is_refused(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    # the checked worker leaves once the Engine has checked it, before any task is given out, and a worker of
    # another checkout joins: every task can only run there. (This test let the first worker leave at the first
    # result, with the tasks under way: its retirement could be refused for want of a worker to take its results,
    # or the runs all end before the newcomer joined, and it failed one run in three with "DID NOT RAISE".)
    from distributed import Client, LocalCluster

    import gearctl.sweep

    alt = tmp_path / "alt"
    shutil.copytree(Path(gearctl.__file__).parent, alt / "gearctl", ignore=shutil.ignore_patterns("__pycache__"))
    with (alt / "gearctl" / "sweep.py").open("a") as f:
        f.write("# an edit\n")
    env = {**os.environ, "PYTHONPATH": str(alt)}
    procs: list[subprocess.Popen] = []
    with (LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0",
                       silence_logs=logging.ERROR) as cluster,
          Client(cluster, set_as_default=False) as client):
        first = list(client.scheduler_info()["workers"])
        engine = gearctl.sweep.Engine

        def checked_then_swapped(**kwargs: object) -> gearctl.parallel.Engine:
            eng = engine(**kwargs)  # the workers are checked here
            client.retire_workers(workers=first)
            deadline = time.monotonic() + 30
            while client.scheduler_info(n_workers=-1)["workers"] and time.monotonic() < deadline:
                time.sleep(0.05)
            assert not client.scheduler_info(n_workers=-1)["workers"], "the first worker did not leave"
            procs.append(subprocess.Popen([sys.executable, "-m", "dask", "worker", cluster.scheduler_address,
                                           "--nthreads", "1", "--no-nanny", "--no-dashboard",
                                           "--host", "127.0.0.1", "--local-directory", str(tmp_path / "w")],
                                          env=env, cwd=tmp_path, stdout=subprocess.DEVNULL,
                                          stderr=subprocess.DEVNULL, start_new_session=True))
            return eng

        monkeypatch.setattr(gearctl.sweep, "Engine", checked_then_swapped)
        try:
            with pytest.raises(InputError, match=r"the worker tcp://\S+, which joined the cluster after its workers "
                                                 r"were checked, runs gearctl \S+, this is " + code_id().replace(
                                                     "+", r"\+")):
                sweep("shing1993_servo", "pid", vary=["backlash=0.5x:2x"], runs=20, duration=0.3, client=client,
                      batch=1)
        finally:
            for p in procs:
                p.kill()
                p.wait(timeout=30)
    assert procs, "the second worker was not started"


def _scheduler(tmp_path: Path, env: dict[str, str]) -> tuple[subprocess.Popen, str]:
    sched_file = tmp_path / "scheduler.json"
    proc = subprocess.Popen([sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0",
                             "--no-dashboard", "--scheduler-file", str(sched_file)], env=env, cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and proc.poll() is None:
        if sched_file.exists():
            try:
                return proc, json.loads(sched_file.read_text())["address"]
            except json.JSONDecodeError:
                pass
        time.sleep(0.1)
    proc.kill()
    raise RuntimeError("the dask scheduler did not start")


def test_a_scheduler_that_cannot_import_gearctl_is_one_line(tmp_path: Path) -> None:
    # Dask's scheduler unpickles the tasks: one without gearctl ended a sweep in Dask's traceback ("Error during
    # deserialization of the task graph"), exit 1, after the workers had passed their check
    from gearctl.cli import main

    bare = tmp_path / "bare" / "gearctl"
    bare.mkdir(parents=True)
    (bare / "__init__.py").write_text('raise ImportError("no gearctl here")\n')
    sched, address = _scheduler(tmp_path, {**os.environ, "PYTHONPATH": str(bare.parent)})
    worker = subprocess.Popen([sys.executable, "-m", "dask", "worker", address, "--nthreads", "1", "--no-nanny",
                               "--no-dashboard", "--host", "127.0.0.1", "--local-directory", str(tmp_path / "w")],
                              cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              start_new_session=True)
    try:
        with pytest.raises(InputError, match=rf"the scheduler at {address} cannot run gearctl \(ImportError: no "
                                             r"gearctl here\): install this gearctl where the scheduler runs too"):
            sweep("shing1993_servo", "pid", runs=2, duration=0.3, scheduler=address)
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            rc = main(["sweep", "shing1993_servo", "pid", "--runs", "2", "--duration", "0.3", "--scheduler", address,
                       "--quiet", "--json", str(tmp_path / "s.json")])
        assert rc == 2 and err.getvalue().count("\n") == 1 and "cannot run gearctl" in err.getvalue()
        assert not (tmp_path / "s.json").exists()
    finally:
        for p in (worker, sched):
            p.kill()
            p.wait(timeout=30)
