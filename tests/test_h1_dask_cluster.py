"""Sweeps on a running Dask cluster whose scheduler or workers stop answering (``kill -STOP``: a paused VM, a hung
process, a link cut without the connection closing), as an outsider's real cluster does.

Every question gearctl asks the cluster must end within a stated time, with one line naming the address. Each test
runs the call under test in a thread and gives it a bounded time, so a hang fails the test instead of hanging it.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from support import subprocess_cluster
from support import within as _within

import gearctl
import gearctl.parallel
import gearctl.sweep
from gearctl.cli import main


@pytest.mark.slow
@pytest.mark.parametrize("after", ["probe_scheduler", "run_on_scheduler", "run"])
def test_a_scheduler_stopped_during_the_start_up_is_one_line_within_the_timeout(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, after: str) -> None:
    # a scheduler that stops answering once reached: Dask's handshake after the probe (Client() still waiting after
    # 150 s), client.scheduler_info() after the workers' check (still waiting after 150 s) waited for it for good, and
    # after the scheduler's check the workers were blamed ("the workers ... did not all answer ... stopped or hung")
    import distributed

    monkeypatch.setattr(gearctl.parallel, "CONNECT_TIMEOUT", 2.0)
    monkeypatch.setattr(gearctl.parallel, "ANSWER_TIMEOUT", 1.0)
    monkeypatch.setattr(gearctl.parallel, "WORKER_TIMEOUT", 3.0)
    with subprocess_cluster(tmp_path) as (address, procs):
        def stop_after(owner: Any, name: str) -> None:
            original = getattr(owner, name)

            def call(*args: Any, **kwargs: Any) -> Any:
                out = original(*args, **kwargs)
                os.killpg(procs[0].pid, signal.SIGSTOP)
                return out

            monkeypatch.setattr(owner, name, call)

        stop_after(gearctl.parallel if after == "probe_scheduler" else distributed.Client, after)
        err = io.StringIO()
        t0 = time.monotonic()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            rc = _within(40, lambda: main(["sweep", "shing1993_servo", "pid", "--runs", "2", "--duration", "0.2",
                                           "--scheduler", address, "--quiet"]))
        took = time.monotonic() - t0
    assert rc == 2, err.getvalue()
    assert err.getvalue().count("\n") == 1 and "Traceback" not in err.getvalue()
    assert f"the Dask scheduler at {address} did not answer within" in err.getvalue()
    assert took < 20  # the timeouts here add up to 3 s at start-up, 3 s + 2 s after the scheduler's check


def test_a_scheduler_without_workers_is_one_line_after_the_worker_timeout(tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(gearctl.parallel, "WORKER_TIMEOUT", 1.0)
    with subprocess_cluster(tmp_path, workers=0) as (address, _):
        t0 = time.monotonic()
        out = _within(30, lambda: gearctl.sweep.sweep("shing1993_servo", "pid", runs=2, duration=0.2,
                                                      scheduler=address))
        took = time.monotonic() - t0
    assert isinstance(out, gearctl.InputError) and out.field == "scheduler"
    assert str(out) == (f"no worker joined the Dask scheduler at {address} within 1 s: start one with `dask worker "
                        f"{address} --nthreads 1`")
    assert 1.0 <= took < 15


@pytest.mark.slow
def test_a_worker_stopped_mid_sweep_is_dropped_after_the_worker_timeout(tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    # two workers, one stopped (SIGSTOP) after the first results: it stays on the scheduler's list with the task it
    # was given until Dask's worker-ttl (5 min), and the sweep was still waiting after 6.5 min. A worker the
    # scheduler has not heard from for WORKER_TIMEOUT (60 s; 3 s here) that holds tasks of the sweep then ended it,
    # every finished run lost; now the scheduler drops it and the other worker runs its tasks (test_t1_silent_worker)
    from distributed import Client

    monkeypatch.setattr(gearctl.parallel, "WORKER_TIMEOUT", 3.0)
    with subprocess_cluster(tmp_path, workers=2) as (address, procs):
        with Client(address, timeout=30, set_as_default=False) as c:
            by_name = {d["name"]: w for w, d in c.scheduler_info(n_workers=-1)["workers"].items()}
        stopped = by_name["w1"]

        def progress(done: int, total: int) -> None:  # noqa: ARG001
            if done == 2:
                os.killpg(procs[2].pid, signal.SIGSTOP)

        t0 = time.monotonic()
        out = _within(60, lambda: gearctl.sweep.sweep("shing1993_servo", "pid", vary=["backlash=0.5x:2x"], runs=40,
                                                      duration=0.3, scheduler=address, batch=1, progress=progress))
        took = time.monotonic() - t0
    assert isinstance(out, gearctl.sweep.SweepResult), out
    assert [d["worker"] for d in out.engine["dropped"]] == [stopped]
    assert [r["index"] for r in out.runs] == list(range(40)) and out.summary["ok"] == 40
    assert 3.0 < took < 40


def test_a_sweep_gives_each_worker_thread_four_tasks() -> None:
    # `dask worker ADDRESS` starts a thread per core: the batches were sized by the workers, four tasks each, and a
    # worker of 4 threads got 64 runs in 4 tasks of 16, one thread each, the other three idle
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=4, processes=False, dashboard_address=None) as cluster, \
            Client(cluster, set_as_default=False) as client:
        r = gearctl.sweep.sweep("shing1993_servo", "pid", vary=["backlash=0.5x:2x"], runs=64, duration=0.2,
                                client=client)
    assert -(-64 // r.engine["batch"]) >= 4 * 4  # tasks
    assert r.engine["workers"] == 1 and r.engine["threads"] == 4
    assert [row["index"] for row in r.runs] == list(range(64))


def test_a_tls_scheduler_is_reached_with_dasks_tls_configuration(tmp_path: Path) -> None:
    # a tls:// scheduler, its certificates in Dask's configuration as Dask documents: distributed.Client reached it,
    # but gearctl's check of the address connected without them and refused it ("does not answer as a Dask
    # scheduler (TypeError: TLS expects a `ssl_context` ...)"); without any certificates that was the message too
    import dask
    from distributed import LocalCluster
    from distributed.security import Security

    pytest.importorskip("cryptography")  # Security.temporary() makes its certificates with it
    sec = Security.temporary()
    files = {}
    for key, pem in [("ca-file", sec.tls_ca_file), ("client.cert", sec.tls_client_cert),
                     ("client.key", sec.tls_client_key)]:
        files[f"distributed.comm.tls.{key}"] = str(tmp_path / f"{key}.pem")
        Path(files[f"distributed.comm.tls.{key}"]).write_text(pem)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, security=sec, protocol="tls://",
                      dashboard_address=None) as cluster:
        address = cluster.scheduler_address
        assert address.startswith("tls://")
        with pytest.raises(gearctl.InputError, match=r"tls:// address needs this machine's TLS certificates in "
                                                     r"Dask's configuration \(distributed.comm.tls.ca-file"):
            gearctl.sweep.sweep("shing1993_servo", "pid", runs=2, duration=0.2, scheduler=address)
        with dask.config.set(files):
            r = gearctl.sweep.sweep("shing1993_servo", "pid", runs=2, duration=0.2, scheduler=address)
    assert r.engine["where"] == address and r.summary["ok"] == 2


@pytest.mark.slow
def test_a_lone_worker_stopped_before_the_sweep_is_named(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # the workers' check named a silent worker only by its heartbeat 10 s behind the others': a cluster whose one
    # worker was stopped got "did not all answer within 60 s (stopped or hung)", no address
    from distributed import Client

    monkeypatch.setattr(gearctl.parallel, "WORKER_TIMEOUT", 3.0)
    with subprocess_cluster(tmp_path) as (address, procs):
        with Client(address, timeout=30, set_as_default=False) as c:
            (worker,) = c.scheduler_info(n_workers=-1)["workers"]
        os.killpg(procs[1].pid, signal.SIGSTOP)
        out = _within(40, lambda: gearctl.sweep.sweep("shing1993_servo", "pid", runs=2, duration=0.2,
                                                      scheduler=address))
    assert isinstance(out, gearctl.InputError), out
    assert str(out).startswith(f"the workers of {address} did not all answer within 3 s (stopped or hung: {worker})")


def test_a_client_that_opens_after_a_ctrl_c_is_closed(monkeypatch: pytest.MonkeyPatch) -> None:
    # a Ctrl-C while the client waited for the scheduler's handshake left it to open later, never closed (in a
    # notebook or a script that catches KeyboardInterrupt, a client and its threads for good)
    import distributed

    release, made = threading.Event(), []

    class SlowClient:
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            release.wait(30)
            self.closed = False
            made.append(self)

        def close(self, timeout: float | None = None) -> None:  # noqa: ARG002
            self.closed = True

    def interrupted(self: threading.Thread, timeout: float | None = None) -> None:  # noqa: ARG001
        raise KeyboardInterrupt

    monkeypatch.setattr(distributed, "Client", SlowClient)
    with monkeypatch.context() as m:
        m.setattr(threading.Thread, "join", interrupted)
        with pytest.raises(KeyboardInterrupt):
            gearctl.parallel._open_client("tcp://127.0.0.1:8786")
    release.set()
    deadline = time.monotonic() + 10
    while not (made and made[0].closed) and time.monotonic() < deadline:
        time.sleep(0.01)
    assert made and made[0].closed


@pytest.mark.parametrize("command", [["sweep", "shing1993_servo", "pid", "--runs", "2"],
                                     ["bench", "shing1993_servo", "--controllers", "pid", "--plants", "improved",
                                      "--references", "sine", "--no-precision"]])
def test_an_empty_scheduler_address_is_refused(command: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    # `--scheduler "$ADDR"` with the variable unset ran on a local cluster without a word
    assert main([*command, "--duration", "0.2", "--quiet", "--scheduler", ""]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "scheduler = '': an empty address; expected tcp://HOST:PORT" in err
    with pytest.raises(gearctl.InputError, match="scheduler = ' ': an empty address") as e:
        gearctl.parallel.map_tasks(abs, [1, 2], scheduler=" ")
    assert e.value.field == "scheduler"


def test_a_local_cluster_has_no_more_processes_than_tasks() -> None:
    # `--batch 1000` with 2 runs: one task, and a local cluster of 2 processes (one started for nothing)
    r = gearctl.sweep.sweep("shing1993_servo", "pid", runs=4, duration=0.2, workers=2, batch=4)
    assert r.engine["batch"] == 4 and r.engine["workers"] == 1 and r.engine["where"] == "local cluster (1 process)"


def test_a_worker_without_a_heartbeat_record_is_never_taken_for_silent() -> None:
    # a Dask whose worker info has no `last_seen` would have made every worker "silent" after WORKER_TIMEOUT
    # without a result (a sweep of long MPC batches ended, its workers named as stopped)
    from gearctl.parallel import WORKER_TIMEOUT, _held_by_silent, _silent_workers

    heard: dict = {}
    workers = {"tcp://10.0.0.1:1": {"nthreads": 1}}
    assert _held_by_silent(None, workers, heard, {"k"}, 0.0) == {}
    assert _held_by_silent(None, workers, heard, {"k"}, 10 * WORKER_TIMEOUT) == {}  # (None: no question asked)
    assert _silent_workers(workers, workers) == []
    # and with the record, one unchanged through the check is named
    seen = {"tcp://10.0.0.1:1": {"last_seen": 5.0}, "tcp://10.0.0.2:1": {"last_seen": 5.0}}
    later = {"tcp://10.0.0.1:1": {"last_seen": 5.0}, "tcp://10.0.0.2:1": {"last_seen": 9.0}}
    assert _silent_workers(seen, later) == ["tcp://10.0.0.1:1"]


def test_inproc_and_ucx_addresses_are_refused_with_their_reason(capsys: pytest.CaptureFixture[str]) -> None:
    """``--scheduler inproc://x`` read "not enough values to unpack (expected 3, got 1)", and ``ucx://`` without UCX
    "Can't instantiate abstract class UCXConnector" (h1's review): each now says why (one line, exit 2)."""
    import importlib.util

    cases = [("inproc://x", "no scheduler listens at this inproc:// address in this process")]
    if importlib.util.find_spec("ucp") is None and importlib.util.find_spec("distributed_ucxx") is None:
        cases.append(("ucx://127.0.0.1:8786", "ucx:// needs UCX for Dask"))
    for address, why in cases:
        rc = main(["sweep", "shing1993_servo", "pid", "--vary", "backlash=0.5x:2x", "--runs", "2", "--scheduler",
                   address])
        err = capsys.readouterr().err
        assert rc == 2 and why in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err


def test_an_inproc_scheduler_of_this_process_is_reached() -> None:
    """The same check lets through an inproc:// scheduler that runs in this process (a threads-only LocalCluster
    from Python): its sweep equals the serial one."""
    from distributed import LocalCluster

    kw = {"vary": ["backlash=0.5x:2x"], "runs": 2, "duration": 0.2}
    serial = gearctl.sweep.sweep("shing1993_servo", "pid", engine="serial", **kw)
    with LocalCluster(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=None) as lc:
        assert lc.scheduler_address.startswith("inproc://")
        remote = gearctl.sweep.sweep("shing1993_servo", "pid", scheduler=lc.scheduler_address, **kw)
    assert remote.runs == serial.runs


@pytest.mark.parametrize("command", ["sweep", "bench"])
def test_an_empty_scheduler_environment_variable_is_refused(command: str, monkeypatch: pytest.MonkeyPatch,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    """``export DASK_SCHEDULER_ADDRESS=$ADDR`` with the variable unset: set but empty, it was taken as unset and the
    work ran on a local cluster without a word (h6's review; an empty --scheduler was refused already)."""
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "")
    argv = (["sweep", "shing1993_servo", "pid", "--vary", "backlash=0.5x:2x", "--runs", "2"] if command == "sweep" else
            ["bench", "shing1993_servo", "--controllers", "pid", "--references", "sine", "--plants", "improved",
             "--duration", "0.2", "--no-precision"])
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "DASK_SCHEDULER_ADDRESS = '': the environment variable is set but empty" in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
