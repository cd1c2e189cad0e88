"""Every worker of a running cluster must run this process's numerics (Python, numpy, SciPy, python-control,
CasADi), not only its gearctl (gearctl.parallel.numerics_versions).

An outsider's check: a `dask worker` whose numpy differed from the client's (a worker without the client's
environment) passed the cluster's check, which compares gearctl's own code alone, and ran its share of the sweep
without a word; the README promises the same results on one worker or many, which other last digits of a numpy
routine break. Here a worker's preload stands for another numpy (it rewrites ``numpy.__version__``).
"""

from __future__ import annotations

import contextlib
import io
import logging
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from gearctl import InputError
from gearctl.cli import main
from gearctl.kernel import compiled_available
from gearctl.parallel import Engine, checked, code_id, numerics_versions

#: The scheduler's HTTP server on a free port: on Dask's 8787, held by another cluster, it warns (an error here).
_NO_HTTP = {"dashboard": False, "dashboard_address": "127.0.0.1:0"}
#: The numpy version the cluster's worker reports.
OTHER = f"{np.__version__}.post999"


def _double(x: int) -> int:
    return 2 * x


def test_numerics_versions_are_this_processs() -> None:
    import platform

    import scipy

    v = numerics_versions()
    assert v["python"] == platform.python_version()
    assert v["numpy"] == np.__version__ and v["scipy"] == scipy.__version__
    assert set(v) == {"python", "numpy", "scipy", "control", "casadi", "gearctl kernel"}
    assert v["gearctl kernel"] == ("compiled C" if compiled_available() else "pure Python")


def test_checked_runs_the_task_on_the_same_numerics() -> None:
    assert checked(code_id(), _double, 21, numerics=numerics_versions()) == 42


def test_checked_refuses_a_worker_on_another_numpy() -> None:
    client_side = {**numerics_versions(), "numpy": "0.0.1"}
    with pytest.raises(InputError, match=rf"a worker, which joined .* runs numpy {np.__version__} \(this process: "
                                         r"0\.0\.1\): a run's figures depend on them") as e:
        checked(code_id(), _double, 21, numerics=client_side)
    assert e.value.field == "scheduler"


@pytest.fixture(scope="module")
def other_numpy_cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[object, str]]:
    """A cluster of one worker process whose numpy says it is another: the client and the worker's address."""
    from distributed import Client, LocalCluster

    preload = Path(tmp_path_factory.mktemp("preload")) / "other_numpy.py"
    # a later build of the same numpy: in SciPy's supported range (it warns on import about one outside it)
    preload.write_text(f"import numpy\nnumpy.__version__ = {OTHER!r}  # a worker on another numpy\n")
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None,
                      scheduler_kwargs=_NO_HTTP,
                      silence_logs=logging.ERROR, preload=[str(preload)]) as cluster, \
            Client(cluster, set_as_default=False) as client:
        worker = next(iter(client.scheduler_info()["workers"]))
        yield client, worker


def test_a_worker_on_another_numpy_is_refused_naming_it(other_numpy_cluster: tuple[object, str]) -> None:
    client, worker = other_numpy_cluster
    with pytest.raises(InputError, match=rf"the worker {worker} of \S+ runs numpy {re.escape(OTHER)} \(this "
                                         rf"process: {re.escape(np.__version__)}\): .* run every worker with this "
                                         r"process's Python, numpy") as e:
        Engine(client=client)
    assert e.value.field == "scheduler"
    assert client.status == "running"  # a client given is left open


def test_the_sweep_command_refuses_it_in_one_line(other_numpy_cluster: tuple[object, str]) -> None:
    client, worker = other_numpy_cluster
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = main(["sweep", "--runs", "2", "--duration", "0.2", "--quiet",
                   "--scheduler", client.scheduler.address])
    lines = err.getvalue().strip().splitlines()
    assert rc == 2
    assert "Traceback" not in err.getvalue()
    assert lines[-1].startswith(f"gearctl sweep: error: the worker {worker} ")
    assert f"numpy {OTHER} (this process: {np.__version__})" in lines[-1]


@pytest.mark.skipif(not compiled_available(), reason="needs gearctl's compiled kernel here (a C compiler)")
def test_a_worker_without_the_compiled_kernel_is_refused_naming_it() -> None:
    # a `dask worker` started with GEARCTL_NO_COMPILE (or on a host without a C compiler) ran the pure-Python
    # kernel: on a real cluster its runs differed from the serial sweep's (pid, 40 runs: RMS 9.453636591083633e-4
    # against 9.453636591894023e-4), and nothing said so
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None,
                      scheduler_kwargs=_NO_HTTP,
                      silence_logs=logging.ERROR, env={"GEARCTL_NO_COMPILE": "1"}) as cluster, \
            Client(cluster, set_as_default=False) as client:
        worker = next(iter(client.scheduler_info()["workers"]))
        with pytest.raises(InputError, match=rf"the worker {worker} of \S+ runs gearctl kernel pure Python \(this "
                                             r"process: compiled C\): .*GEARCTL_NO_COMPILE") as e:
            Engine(client=client)
        assert e.value.field == "scheduler"
