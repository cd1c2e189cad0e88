"""Parallel runs on Dask.distributed: a local cluster sized to the machine, or a running scheduler.

gearctl has one way to run work in parallel. :class:`Engine` opens a Dask client (a ``LocalCluster`` of
single-threaded worker processes, or ``tcp://HOST:PORT`` of a cluster started with ``dask scheduler`` and
``dask worker``) and closes what it opened; :func:`map_tasks` runs one function over many arguments on it
and returns the results in order. ``gearctl bench`` and ``gearctl sweep`` both go through it.
"""

from __future__ import annotations

import logging
import os
import uuid
from collections.abc import Callable, Sequence
from typing import Any

from .errors import InputError

__all__ = ["Engine", "map_tasks", "default_workers", "local_cluster", "CONNECT_TIMEOUT", "WORKER_TIMEOUT"]

#: Seconds to reach a scheduler, and for its first worker to join.
CONNECT_TIMEOUT, WORKER_TIMEOUT = 10.0, 60.0


def default_workers() -> int:
    """Worker processes of the local cluster: the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover (not Linux)
        return os.cpu_count() or 1


def _worker_version() -> str:
    from . import __version__

    return __version__


def local_cluster(workers: int) -> Any:
    """A ``distributed.LocalCluster`` of ``workers`` single-threaded processes, for gearctl's runs.

    No dashboard, and the workers' statistical profiler off (it samples every thread's stack every 10 ms, a
    cost of its own in runs of a few milliseconds). Dask's nanny starts each worker with one BLAS thread. The
    scheduler's HTTP server (its health routes, which run even without a dashboard) listens on a free local port:
    on the default 8787, which another cluster or notebook often holds, it warns (an error under pytest's
    warnings-as-errors).
    """
    import dask
    import distributed

    with dask.config.set({"distributed.worker.profile.enabled": False}):
        return distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                        dashboard_address=None, silence_logs=logging.ERROR,
                                        scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"})


class Engine:
    """A Dask client on a local cluster or a running scheduler; closes what it opened.

    Parameters
    ----------
    workers : int, optional
        Processes of the local cluster (default :func:`default_workers`); ignored with a scheduler.
    scheduler : str, optional
        ``tcp://HOST:PORT`` of a running scheduler (default the ``DASK_SCHEDULER_ADDRESS`` environment
        variable, else a local cluster). Its workers must run the same gearctl version.
    client : distributed.Client, optional
        An open client to use as is (not closed here).
    """

    def __init__(self, *, workers: int | None = None, scheduler: str | None = None, client: Any = None) -> None:
        import distributed

        self.cluster = None
        self.own = client is None
        address = scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS") or None
        if client is not None:
            self.client = client
            self.where = str(getattr(client.scheduler, "address", "client"))
        elif address:
            try:
                self.client = distributed.Client(address, timeout=CONNECT_TIMEOUT, set_as_default=False)
            except (OSError, TimeoutError) as exc:
                raise InputError(f"cannot reach the Dask scheduler at {address}: {exc}", field="scheduler") from None
            try:
                self.client.wait_for_workers(1, timeout=WORKER_TIMEOUT)
            except TimeoutError:
                self.client.close()
                raise InputError(f"no worker joined the Dask scheduler at {address} within {WORKER_TIMEOUT:g} s: "
                                 f"start one with `dask worker {address} --nthreads 1`", field="scheduler") from None
            self.where = address
        else:
            from .kernel import compiled_available

            compiled_available()  # compile the kernel once, before the workers start
            n = workers or default_workers()
            self.cluster = local_cluster(n)
            self.client = distributed.Client(self.cluster, set_as_default=False)
            self.where = f"local cluster ({n} process{'es' if n > 1 else ''})"
        if self.cluster is None:
            from . import __version__

            try:
                versions = set(self.client.run(_worker_version).values())
            except Exception as exc:  # the workers' environment, not gearctl: say it in one line
                self.close()
                raise InputError(f"the workers of {self.where} cannot run gearctl: {type(exc).__name__}: {exc}",
                                 field="scheduler") from None
            if versions - {__version__}:
                self.close()
                raise InputError(f"the workers of {self.where} run gearctl {', '.join(sorted(versions))}, this is "
                                 f"{__version__}: install the same version on every worker", field="scheduler")

    @property
    def workers(self) -> int:
        """Workers the scheduler knows now."""
        return max(1, len(self.client.scheduler_info(n_workers=-1)["workers"]))

    def close(self) -> None:
        if self.own:
            self.client.close()
            if self.cluster is not None:
                self.cluster.close()

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def map_tasks(fn: Callable[[Any], Any], items: Sequence[Any], *, workers: int | None = None,
              scheduler: str | None = None, progress: Callable[[int, int], Any] | None = None,
              name: str = "gearctl") -> list[Any]:
    """``[fn(x) for x in items]``, in parallel on Dask; in this process when one worker would do.

    Parameters
    ----------
    fn : callable
        A module-level function (the workers import it).
    items : sequence
        Its arguments, one task each (batch them beforehand where a task is short).
    workers, scheduler
        As :class:`Engine`. ``workers=1`` without a scheduler runs here, one after the other.
    progress : callable, optional
        ``progress(done, total)`` as tasks finish.
    name : str
        Prefix of the Dask task keys (shown on the dashboard).

    Returns
    -------
    list
        The results, in the order of ``items``. An exception in a task is raised here.
    """
    n = len(items)
    scheduler = scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS") or None
    if n == 0:
        return []
    if scheduler is None and ((workers or default_workers()) == 1 or n == 1):
        out = []
        for i, x in enumerate(items):
            out.append(fn(x))
            if progress:
                progress(i + 1, n)
        return out
    from distributed import as_completed

    results: list[Any] = [None] * n
    with Engine(workers=min(workers or default_workers(), n), scheduler=scheduler) as eng:
        tag = uuid.uuid4().hex[:12]
        futures = {eng.client.submit(fn, x, key=f"{name}-{tag}-{k}", pure=False): k for k, x in enumerate(items)}
        try:
            for done, fut in enumerate(as_completed(list(futures), loop=eng.client.loop), start=1):
                results[futures[fut]] = fut.result()
                fut.release()
                if progress:
                    progress(done, n)
        finally:
            for fut in futures:
                fut.cancel()
    return results
