"""Sweeps and the bench as a controls engineer runs them on a cluster: output to a pipe that closes early, a user's
own ``distributed.Client``.

The runs are short (0.2 s simulated); the sweep's CLI runs its batches in this process (``engine="serial"``), which
gives the Dask path's rows (tests/test_sweep.py), so no cluster starts where the point is the output.
"""

from __future__ import annotations

import contextlib
import functools
import io
import json
import os
import signal
import time
from pathlib import Path

import pytest
from support import subprocess_cluster

import gearctl
import gearctl.sweep
from gearctl.cli import main


class _ClosedPipe(io.StringIO):
    """Standard output whose reader went away (``| head`` after its lines): every write fails as a pipe's does."""

    def write(self, s: str) -> int:
        raise BrokenPipeError(32, "Broken pipe")


def _cli_into_closed_pipe(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stdout(_ClosedPipe()), contextlib.redirect_stderr(err), \
            contextlib.suppress(ValueError):  # (main points a real stdout at /dev/null; a StringIO has no fileno)
        rc = main(argv)
    return rc, err.getvalue()


def test_sweep_json_to_a_closed_pipe_still_writes_out_and_the_summary(tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    # `gearctl sweep ... --json - --out DIR | head`: the JSON was written first, the closed pipe ended the command
    # quietly (exit 0), and the --out folder and the summary, written after it, were never made: a cluster sweep's
    # results lost without a word. The JSON goes last now.
    monkeypatch.setattr(gearctl.sweep, "sweep", functools.partial(gearctl.sweep.sweep, engine="serial"))
    out = tmp_path / "sweep"
    rc, err = _cli_into_closed_pipe(["sweep", "shing1993_servo", "pid", "--vary", "backlash=0.5x:2x", "--runs", "3",
                                     "--duration", "0.2", "--quiet", "--json", "-", "--out", str(out)])
    assert rc == 0
    assert (out / "runs.csv").read_text().count("\n") == 4  # header and three runs
    assert (out / "summary.md").is_file() and (out / "error_vs_backlash.png").is_file()
    assert "RMS error [urad]" in err and f"wrote {out}/runs.csv" in err


def test_sweep_json_to_standard_output_is_whole_after_the_summary(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(gearctl.sweep, "sweep", functools.partial(gearctl.sweep.sweep, engine="serial"))
    out = tmp_path / "sweep"
    assert main(["sweep", "shing1993_servo", "pid", "--vary", "backlash=0.5x:2x", "--runs", "3", "--duration", "0.2",
                 "--quiet", "--json", "-", "--out", str(out)]) == 0
    cap = capsys.readouterr()
    d = json.loads(cap.out)  # standard output holds the JSON alone
    assert [r["index"] for r in d["runs"]] == [0, 1, 2]
    assert "RMS error [urad]" in cap.err and (out / "runs.csv").is_file()


def test_bench_json_to_a_closed_pipe_still_writes_the_report(tmp_path: Path) -> None:
    # the same for `gearctl bench --json - --out DIR | head`: report.md and the plots were lost
    out = tmp_path / "bench"
    rc, err = _cli_into_closed_pipe(["bench", "shing1993_servo", "--controllers", "pid", "--plants", "improved",
                                     "--references", "sine", "--duration", "0.2", "--no-precision", "--jobs", "1",
                                     "--quiet", "--json", "-", "--out", str(out)])
    assert rc == 0
    assert (out / "report.md").read_text().startswith("# gearctl bench")
    assert (out / "rms_by_controller.png").is_file()
    assert f"wrote {out}/report.md" in err


def test_a_sweep_rerun_into_its_out_folder_leaves_no_plot_of_the_earlier_one(tmp_path: Path,
                                                                            monkeypatch: pytest.MonkeyPatch,
                                                                            capsys: pytest.CaptureFixture[str]) -> None:
    # a two-key grid, then a one-key sweep into the same --out: error_vs_backlash.png, error_vs_estimate_error.png
    # and map.png of the first stayed beside the second's runs.csv and summary.md, as if the second's
    monkeypatch.setattr(gearctl.sweep, "sweep", functools.partial(gearctl.sweep.sweep, engine="serial"))
    out = tmp_path / "sweep"
    mine = out / "notes.png"  # the user's own file: not a plot the earlier sweep wrote, stays
    base = ["sweep", "shing1993_servo", "deadzone_inverse", "--duration", "0.2", "--quiet", "--out", str(out)]
    grid = ["--grid", "--runs", "2", "--vary", "backlash=0.5x:2x", "--vary", "estimate_error=-0.1,0.1"]
    assert main([*base, *grid]) == 0
    first = {p.name for p in out.iterdir()}
    assert {"map.png", "error_vs_backlash.png", "error_vs_estimate_error.png", "histogram.png"} <= first
    mine.write_bytes(b"mine")
    capsys.readouterr()
    assert main([*base, "--runs", "3", "--vary", "load_inertia=0.5x:2x"]) == 0
    err = capsys.readouterr().err
    assert {p.name for p in out.iterdir()} == {"runs.csv", "summary.md", "histogram.png", "error_vs_load_inertia.png",
                                               "notes.png"}
    assert "removed error_vs_backlash.png, error_vs_estimate_error.png, map.png" in err
    # and the same sweep again removes nothing, says nothing
    assert main([*base, "--runs", "3", "--vary", "load_inertia=0.5x:2x"]) == 0
    assert "removed" not in capsys.readouterr().err and mine.read_bytes() == b"mine"


def test_a_folder_whose_summary_is_not_a_sweeps_keeps_its_plots(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(gearctl.sweep, "sweep", functools.partial(gearctl.sweep.sweep, engine="serial"))
    out = tmp_path / "sweep"
    out.mkdir()
    (out / "summary.md").write_text("# my notes\n\n![a map](map.png)\n")
    (out / "map.png").write_bytes(b"mine")
    assert main(["sweep", "shing1993_servo", "pid", "--duration", "0.2", "--runs", "2", "--quiet",
                 "--vary", "backlash=0.5x:2x", "--out", str(out)]) == 0
    assert (out / "map.png").read_bytes() == b"mine"


def test_a_bench_rerun_into_its_out_folder_leaves_no_plot_of_the_earlier_one(tmp_path: Path,
                                                                            capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "bench"
    base = ["bench", "shing1993_servo", "--controllers", "pid", "--plants", "improved", "--duration", "0.2",
            "--no-precision", "--jobs", "1", "--quiet", "--out", str(out)]
    assert main([*base, "--references", "sine,move"]) == 0
    assert (out / "errors_move.png").is_file()
    capsys.readouterr()
    assert main([*base, "--references", "sine"]) == 0
    assert "removed errors_move.png" in capsys.readouterr().err
    assert {p.name for p in out.iterdir()} == {"report.md", "rms_by_controller.png", "errors_sine.png"}


def test_a_client_and_a_scheduler_together_are_refused_before_the_design() -> None:
    # sweep(client=c, scheduler="tcp://...") ran on the client's cluster and dropped the address without a word
    # (a closed port given with a working client ran as if it answered)
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
            Client(cluster, set_as_default=False) as client:
        with pytest.raises(gearctl.InputError, match=r"scheduler = 'tcp://127.0.0.1:1' and a client: give one") as e:
            gearctl.sweep.sweep("shing1993_servo", "pid", runs=2, duration=0.2, client=client,
                                scheduler="tcp://127.0.0.1:1")
        assert e.value.field == "scheduler" and client.status == "running"
        r = gearctl.sweep.sweep("shing1993_servo", "pid", runs=2, duration=0.2, client=client)  # alone: it runs
        assert r.engine["where"] == cluster.scheduler_address and client.status == "running"


def test_bench_jobs_with_a_scheduler_warns_as_sweep_workers_does(monkeypatch: pytest.MonkeyPatch,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    # `bench --scheduler ADDR --jobs 4` ran on the cluster's workers and dropped --jobs without a word (sweep's
    # --workers warns); the bench itself is not the point here: the run is replaced by its first step's refusal
    import gearctl.bench

    def no_runs(*args: object, **kwargs: object) -> None:
        raise gearctl.InputError("stop here", field="scheduler")

    monkeypatch.setattr(gearctl.bench, "run_bench", no_runs)
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    argv = ["bench", "--controllers", "pid", "--plants", "improved", "--references", "sine", "--duration", "0.2",
            "--no-precision", "--quiet"]
    assert main([*argv, "--scheduler", "tcp://127.0.0.1:1", "--jobs", "4"]) == 2
    assert "--jobs sizes the local cluster" in capsys.readouterr().err
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://127.0.0.1:1")
    assert main([*argv, "--jobs", "4"]) == 2
    assert "--jobs sizes the local cluster" in capsys.readouterr().err
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS")
    assert main([*argv, "--jobs", "4"]) == 2  # a local cluster: --jobs is what sizes it, no warning
    assert "--jobs sizes" not in capsys.readouterr().err


def test_a_task_that_kills_its_workers_is_one_line_in_map_tasks() -> None:
    # bench on a cluster whose workers died in each run (dask worker --memory-limit 120MB: the nanny killed the
    # worker as gearctl loaded) ended in Dask's KilledWorker traceback, exit 1; sweep records such a batch as failed
    # rows. Here each task ends its worker process (os._exit), which Dask restarts, up to its allowed failures.
    import os

    import dask

    from gearctl.parallel import map_tasks

    with dask.config.set({"distributed.scheduler.allowed-failures": 1}), \
            pytest.raises(gearctl.InputError, match=r"the task gearctl-\S+ could not run: each of the 2 workers that "
                                                    r"ran it died while it ran .*memory limit") as e:
        map_tasks(os._exit, [3, 3], workers=2)  # (two tasks: one would run in this process)
    assert e.value.field == "scheduler"


def test_a_worker_that_cannot_import_gearctl_is_named_with_the_fix(tmp_path: Path) -> None:
    # the refusal named the worker and its ImportError but not what to do about it
    from distributed import Client, LocalCluster

    from gearctl.parallel import Engine

    # a worker process where `import gearctl` fails (a worker's PYTHONPATH does not reach a spawned process: the
    # preload takes gearctl away as a broken install would)
    preload = tmp_path / "no_gearctl.py"
    preload.write_text("import sys\n"
                       "for name in [m for m in sys.modules if m == 'gearctl' or m.startswith('gearctl.')]:\n"
                       "    del sys.modules[name]\n"
                       "sys.modules['gearctl'] = None  # import gearctl: ImportError, a broken install\n")
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None,
                      preload=[str(preload)]) as cluster, \
            Client(cluster, set_as_default=False) as client:
        worker = next(iter(client.scheduler_info()["workers"]))
        with pytest.raises(gearctl.InputError, match=rf"the worker {worker} of \S+ cannot run gearctl \(.*gearctl.*\): "
                                                     r"install this gearctl on every worker") as e:
            Engine(client=client)
        assert e.value.field == "scheduler" and client.status == "running"


def test_an_address_from_the_environment_is_named_as_such(monkeypatch: pytest.MonkeyPatch,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    # DASK_SCHEDULER_ADDRESS=garbage (set by a profile or a notebook): "cannot reach the Dask scheduler at garbage"
    # said nothing of where the address came from
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://127.0.0.1:1")
    argv = ["sweep", "shing1993_servo", "pid", "--runs", "2", "--duration", "0.2", "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "tcp://127.0.0.1:1" in err and "DASK_SCHEDULER_ADDRESS" in err
    assert main([*argv, "--scheduler", "tcp://127.0.0.1:1"]) == 2  # typed on the command line: no such note
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "tcp://127.0.0.1:1" in err and "DASK_SCHEDULER_ADDRESS" not in err


def test_bench_tables_to_a_closed_pipe_still_write_the_json_file_and_the_report(tmp_path: Path) -> None:
    # `gearctl bench --json FILE --out DIR | head -1`: the tables were printed before the files were written, and the
    # closed pipe ended the command quietly at the first flush: the report and at times the JSON file were lost
    out, js = tmp_path / "bench", tmp_path / "bench.json"
    rc, err = _cli_into_closed_pipe(["bench", "shing1993_servo", "--controllers", "pid", "--plants", "improved",
                                     "--references", "sine", "--duration", "0.2", "--no-precision", "--jobs", "1",
                                     "--quiet", "--json", str(js), "--out", str(out)])
    assert rc == 0 and "Traceback" not in err
    assert [r["controller"] for r in json.loads(js.read_text())["runs"]].count("pid") >= 1
    assert (out / "report.md").read_text().startswith("# gearctl bench")


@pytest.mark.slow
def test_a_scheduler_that_stops_answering_mid_sweep_ends_with_one_line(tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    # a scheduler stopped mid-sweep (SIGSTOP here; a paused VM, a link cut without the connection closing) hung the
    # sweep for good: the check for workers waited for its answer without end. Now each check waits ANSWER_TIMEOUT
    # and the sweep ends after WORKER_TIMEOUT without an answer (60 s; 2 s here)
    import gearctl.parallel

    monkeypatch.setattr(gearctl.parallel, "WORKER_TIMEOUT", 2.0)
    monkeypatch.setattr(gearctl.parallel, "POLL", 0.2)
    monkeypatch.setattr(gearctl.parallel, "ANSWER_TIMEOUT", 0.5)
    with subprocess_cluster(tmp_path) as (address, procs):
        def progress(done: int, total: int) -> None:
            if done == 1:
                os.killpg(procs[0].pid, signal.SIGSTOP)

        t0 = time.monotonic()
        with pytest.raises(gearctl.InputError, match=r"the scheduler has not answered for 2 s with \d+ task\(s\) "
                                                     r"unfinished") as e:
            gearctl.sweep.sweep("shing1993_servo", "pid", vary=["backlash=0.5x:2x"], runs=12, duration=0.3,
                                scheduler=address, batch=1, progress=progress)
        assert e.value.field == "scheduler" and time.monotonic() - t0 < 60.0


@pytest.mark.slow
def test_a_worker_stopped_before_the_sweep_is_named_within_the_timeout(tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    # a worker stopped (SIGSTOP) or hung before the sweep: the check of the workers' gearctl waited for its answer
    # for good (still waiting after 150 s). Now WORKER_TIMEOUT (60 s; 2 s here), and one line
    import gearctl.parallel

    monkeypatch.setattr(gearctl.parallel, "WORKER_TIMEOUT", 2.0)
    with subprocess_cluster(tmp_path) as (address, procs):
        os.killpg(procs[1].pid, signal.SIGSTOP)
        t0 = time.monotonic()
        with pytest.raises(gearctl.InputError, match=rf"the workers of {address} did not all answer within 2 s "
                                                     r"\(stopped or hung") as e:
            gearctl.sweep.sweep("shing1993_servo", "pid", runs=2, duration=0.2, scheduler=address)
        assert e.value.field == "scheduler" and time.monotonic() - t0 < 60.0
