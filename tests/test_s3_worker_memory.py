"""A local cluster is sized with the runs its workers hold at once, not at 0.2 GB a worker alone.

Each run was checked against the one-run cap and the workers at 0.2 GB each, so ``gearctl bench --jobs 8
--duration 5000`` (4.2 GB a run, under the cap) passed both checks and would hold 34 GB at once.
"""

from __future__ import annotations

import pytest

from gearctl import parallel
from gearctl.catalog import load_model
from gearctl.cli import main
from gearctl.closedloop import LOOP_SAMPLE_BYTES, LOOP_STATE_BYTES, check_loop_memory, loop_bytes
from gearctl.errors import InputError
from gearctl.plant import build_plant

GB = 1e9


@pytest.fixture
def small_machine(monkeypatch):
    """8 GB available to the cluster's workers; a cluster must not start (the runs would be long)."""
    monkeypatch.setattr(parallel, "available_memory", lambda: int(8 * GB))

    def no_cluster(n):
        raise AssertionError(f"a local cluster of {n} workers was started")

    monkeypatch.setattr(parallel, "local_cluster", no_cluster)


def test_loop_bytes_is_what_the_one_run_check_weighs():
    plant = build_plant(load_model("shing1993_servo"))
    b = loop_bytes(plant, 2000.0, 1e-3)
    assert b == 2_000_001 * (LOOP_SAMPLE_BYTES + 4 * LOOP_STATE_BYTES)  # a pair: 4 states
    assert loop_bytes(plant, 4000.0, 1e-3) == pytest.approx(2 * b, rel=1e-6)
    check_loop_memory(plant, 2000.0, 1e-3)  # one such run alone fits


def test_check_local_workers_counts_each_workers_run(small_machine):
    parallel.check_local_workers(3)  # 0.6 GB of processes alone fit
    run = int(1.5 * GB)
    parallel.check_local_workers(2, run)  # 2 x 1.7 GB < 4 GB
    with pytest.raises(InputError, match=r"workers = 3: .*5\.1 GB .*1\.5 GB for the run each holds.*at most 2") as e:
        parallel.check_local_workers(3, run)
    assert e.value.field == "workers"


def test_bench_refuses_jobs_whose_runs_do_not_fit(small_machine, capsys):
    # a 2000 s run is 1.7 GB, under the one-run cap; three workers holding one each are 5.6 GB, over half of 8 GB
    assert main(["bench", "--controllers", "pid", "--plants", "improved", "--references", "sine,move,step",
                 "--no-precision", "--duration", "2000", "--jobs", "3"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "workers = 3" in err and "for the run each holds" in err and "--duration" in err


def test_sweep_refuses_workers_whose_runs_do_not_fit(small_machine, capsys):
    assert main(["sweep", "shing1993_servo", "pid", "--vary", "backlash=0.5x:2x", "--runs", "6",
                 "--duration", "2000", "--workers", "3", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "workers = 3" in err and "for the run each holds" in err
