"""Parallel runs on Dask.distributed: a local cluster sized to the machine, or a running scheduler.

gearctl has one way to run work in parallel. :class:`Engine` opens a Dask client (a ``LocalCluster`` of
single-threaded worker processes, or ``tcp://HOST:PORT`` of a cluster started with ``dask scheduler`` and
``dask worker``) and closes what it opened; :func:`map_tasks` runs one function over many arguments on it
and returns the results in order. ``gearctl bench`` and ``gearctl sweep`` both go through it.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import hashlib
import logging
import os
import signal
import threading
import time
import uuid
import warnings
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, cast

from .errors import InputError
from .limits import available_memory

__all__ = ["Engine", "check_one_cluster", "map_tasks", "check_local_workers", "WORKER_BYTES",
           "completed", "default_workers", "local_cluster", "probe_scheduler", "code_id",
           "checked", "killed_worker_text", "numerics_versions", "NUMERICS", "CONNECT_TIMEOUT", "WORKER_TIMEOUT",
           "DROP_TIMEOUT", "ANSWER_TIMEOUT", "TasksInterrupted"]

#: Seconds to reach a scheduler, and for its first worker to join.
CONNECT_TIMEOUT, WORKER_TIMEOUT = 10.0, 60.0


def default_workers() -> int:
    """Worker processes of the local cluster: the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover (not Linux)
        return os.cpu_count() or 1


def code_id() -> str:
    """This gearctl's version and a hash of its code (the package's Python and C sources), e.g.
    ``0.1.0+3f2a9c1e0b7d``: workers that run the same version string on other code (an edited checkout, a worker
    started before an edit) give other numbers, so they are refused as another version is."""
    global _CODE_ID
    if _CODE_ID is None:
        from . import __version__

        root = Path(__file__).resolve().parent
        h = hashlib.sha256()
        for f in sorted(root.rglob("*")):
            if f.is_file() and f.suffix in (".py", ".c", ".h") and "__pycache__" not in f.parts:
                h.update(f.relative_to(root).as_posix().encode())
                h.update(f.read_bytes())
        _CODE_ID = f"{__version__}+{h.hexdigest()[:12]}"
    return _CODE_ID


_CODE_ID: str | None = None

#: The packages besides gearctl whose versions decide a run's figures (with Python's): a worker on another numpy or
#: SciPy can give other last digits, so a sweep's results would no longer be the serial run's.
NUMERICS = ("numpy", "scipy", "control", "casadi")


def numerics_versions() -> dict[str, str]:
    """The versions of Python and of :data:`NUMERICS` that this process runs, e.g. ``{"python": "3.11.7",
    "numpy": "2.4.6", ...}``: an imported module's ``__version__``, else its installed distribution's (importing
    CasADi to ask took a second, in the client and in each worker, of a sweep that does not use it), else
    ``"not installed"``; and ``"gearctl kernel"``, ``"compiled C"`` or ``"pure Python"`` (no C compiler, or
    ``GEARCTL_NO_COMPILE`` set: its mirror of the kernel differs from the compiled one in the last digits, about
    1e-10 of a run's RMS error).

    Workers must run the same ones as the client (:class:`Engine`, :func:`checked`): :func:`code_id` covers
    gearctl's own code only, and a worker with another numpy ran its share of a sweep without a word."""
    import importlib.metadata
    import platform
    import sys

    from .kernel import compiled_available

    out = {"python": platform.python_version(),
           "gearctl kernel": "compiled C" if compiled_available() else "pure Python"}
    for name in NUMERICS:
        mod = sys.modules.get(name)
        if mod is not None and getattr(mod, "__version__", None):
            out[name] = str(mod.__version__)
            continue
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def _numerics_differ(theirs: dict[str, str], mine: dict[str, str]) -> str:
    """``"numpy 2.3.9 (this process: 2.4.6), ..."``: the packages whose versions differ, or ``""``."""
    keys = sorted(set(theirs) | set(mine), key=lambda k: (k != "python", k.startswith("gearctl"), k))
    return ", ".join(f"{k} {theirs.get(k, 'not reported')} (this process: {mine.get(k, 'not reported')})"
                     for k in keys if theirs.get(k) != mine.get(k))


def checked(expected: str, fn: Callable[..., Any], *args: Any, numerics: dict[str, str] | None = None) -> Any:
    """``fn(*args)`` on a worker that runs the gearctl ``expected`` (the client's :func:`code_id`) and, where
    ``numerics`` (the client's :func:`numerics_versions`) is given, the same Python, numpy, SciPy, python-control
    and CasADi; else an :class:`~gearctl.InputError` naming the worker and both. :class:`Engine` checks the
    workers there when it opens, but a worker that joined later (started from another checkout mid-sweep) ran the
    tasks it was given on its own code, its figures mixed with the others' without a word (a review: 1260 of 3000
    runs); every task goes through here.

    Parameters
    ----------
    expected : str
        The client's :func:`code_id`.
    fn : callable
        The task.
    *args
        Its arguments.
    numerics : dict of str to str, optional
        The client's :func:`numerics_versions` (default: not compared).

    Returns
    -------
    object
        ``fn(*args)``.

    Raises
    ------
    InputError
        Where the worker's gearctl or numerical libraries differ from the client's.
    """
    mine = code_id()
    differ = "" if numerics is None else _numerics_differ(numerics_versions(), numerics)
    if mine != expected or differ:
        try:
            from distributed import get_worker

            who = f"the worker {get_worker().address}"
        except (ImportError, ValueError):
            who = "a worker"
        if mine != expected:
            raise InputError(f"{who}, which joined the cluster after its workers were checked, runs gearctl {mine}, "
                             f"this is {expected} (version+code hash): install the same gearctl on every worker, and "
                             f"restart workers started before an edit", field="scheduler")
        raise InputError(f"{who}, which joined the cluster after its workers were checked, runs {differ}: "
                         f"{_NUMERICS_FIX}", field="scheduler")
    return fn(*args)


_NUMERICS_FIX = ("a run's figures depend on them (other versions give other last digits than the other workers and "
                 "a serial run); run every worker with this process's Python, numpy, SciPy, python-control and "
                 "CasADi, and its gearctl kernel (compiled C where a C compiler is found and GEARCTL_NO_COMPILE is "
                 "not set, else pure Python)")


#: Dask's address schemes a scheduler may be given with.
_SCHEMES = ("tcp", "tls", "ucx", "inproc", "ws", "wss")


def probe_scheduler(address: str, timeout: float | None = None) -> None:
    """Check that ``address`` is a Dask scheduler that answers, within ``timeout`` seconds in all, before a client
    is opened on it: a malformed address, a closed port, a host that does not answer, or a server that speaks
    another protocol (a dashboard's HTTP port hung ``distributed.Client`` past its own timeout; a server that sent a
    banner made it allocate exabytes) is an :class:`~gearctl.InputError` naming ``scheduler``. ``timeout``: default
    :data:`CONNECT_TIMEOUT`.

    Parameters
    ----------
    address : str
        The scheduler's address, ``tcp://HOST:PORT``.
    timeout : float, optional
        Longest wait in all [s] (default :data:`CONNECT_TIMEOUT`).

    Raises
    ------
    InputError
        Naming ``scheduler``, where it is not a Dask scheduler that answers in time.
    """
    import asyncio

    from distributed.comm import connect
    from distributed.comm.addressing import parse_address, parse_host_port

    timeout = CONNECT_TIMEOUT if timeout is None else timeout

    def refuse(why: str) -> InputError:
        return InputError(f"cannot reach the Dask scheduler at {address}: {why}; expected the address of a running "
                          f"Dask scheduler, tcp://HOST:PORT", field="scheduler")

    try:
        scheme, loc = (parse_address(address, strict=True) if not address.startswith("inproc://")
                       else ("inproc", address[len("inproc://"):]))  # (its own parse fails on a foreign form)
        if scheme not in _SCHEMES:
            web = (" (an http:// address is a web page's, such as the Dask dashboard's; the scheduler itself "
                   "listens on tcp://HOST:PORT, port 8786 unless it was started with another)"
                   if scheme.lower() in ("http", "https") else "")
            raise ValueError(f"unknown scheme {scheme!r}{web}")
        if scheme == "inproc":  # a scheduler inside one process: reachable from that process alone
            from distributed.comm.inproc import global_manager

            try:
                listening = global_manager.get_listener_for(loc) is not None
            except (ValueError, TypeError):  # not even an inproc address of this machine's form
                listening = False
            if not listening:
                raise ValueError("no scheduler listens at this inproc:// address in this process (an inproc:// "
                                 "scheduler is reachable only from the Python process that runs it: pass its "
                                 "Client, sweep(..., client=...), or give the cluster a tcp:// address)")
        if scheme == "ucx":
            import importlib.util

            if importlib.util.find_spec("ucp") is None and importlib.util.find_spec("distributed_ucxx") is None:
                raise ValueError("ucx:// needs UCX for Dask (ucx-py or distributed-ucxx), which is not installed here")
        if scheme in ("tcp", "tls", "ws", "wss"):
            try:
                port = parse_host_port(loc)[1]
            except ValueError as exc:  # Python's own words ("invalid literal for int() with base 10: '8786/'")
                if "invalid literal" not in str(exc):
                    raise
                raise ValueError(f"the port {loc.rpartition(':')[2]!r} is not a whole number 1..65535 (with no "
                                 f"path or '/' after it)") from None
            if not 0 < port < 65536:
                raise ValueError(f"invalid port {port}: expected 1..65535")
    except (ValueError, TypeError) as exc:
        raise refuse(str(exc)) from None

    if scheme == "tcp":  # a closed port or an unknown host fails at once here (Dask's connect retries to its timeout)
        import socket

        host, port = parse_host_port(loc)
        try:
            socket.create_connection((host, port), timeout=timeout).close()
        except OSError as exc:
            raise refuse(f"cannot connect: {exc}") from None

    from distributed.security import Security

    # the client's TLS settings from Dask's configuration, as distributed.Client takes them: without them a tls://
    # scheduler set up by the book was refused ("does not answer as a Dask scheduler (TypeError: TLS expects a
    # `ssl_context` ...)") while Dask's own client reached it
    args = Security().get_connection_args("client")
    if scheme == "tls" and args.get("ssl_context") is None:
        raise refuse("a tls:// address needs this machine's TLS certificates in Dask's configuration "
                     "(distributed.comm.tls.ca-file, distributed.comm.tls.client.cert and .key); none are set")

    async def identity() -> Any:
        comm = await connect(address, timeout=timeout, **args)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    try:
        reply = asyncio.run(asyncio.wait_for(identity(), timeout))
    except TimeoutError:
        raise refuse(f"no Dask answer within {timeout:g} s") from None
    except MemoryError:  # Dask read a frame length off another protocol's first bytes (an HTTP server's reply)
        raise refuse("the server there does not answer as a Dask scheduler (its reply is in another protocol: an "
                     "HTTP server's, say)") from None
    except Exception as exc:  # another protocol's bytes, a connection dropped
        raise refuse(f"the server there does not answer as a Dask scheduler ({type(exc).__name__}: "
                     f"{str(exc)[:120]})") from None
    if not (isinstance(reply, dict) and reply.get("type") == "Scheduler"):
        raise refuse(f"the server there is not a Dask scheduler (it says it is {str(reply)[:80]})")


#: Memory of one local worker process [bytes]: 170 MB measured on the two-core machine (Python, numpy, SciPy, Dask
#: and gearctl loaded, a sweep running), budgeted at 200 MB.
WORKER_BYTES = 200_000_000


def check_local_workers(workers: int, task_bytes: int = 0) -> None:
    """Refuse a local cluster whose worker processes would not fit in half the available memory.

    ``gearctl sweep --workers 1000`` (in its range, 1..1024) started a thousand processes on a two-core machine
    with 23 GB, until the kernel's out-of-memory killer ended processes of the whole machine. Each worker also
    holds the run it is running: ``task_bytes``, the largest task's memory (``bench --jobs 8 --duration 5000``
    passed with each run's 4.2 GB under the one-run cap, 34 GB at once).

    Parameters
    ----------
    workers : int
        Worker processes asked for.
    task_bytes : int
        Memory the largest task holds while it runs [bytes] (0: the workers alone).

    Raises
    ------
    InputError
        With the figure and the most workers that fit (``error.field``: ``workers``).
    """
    avail = available_memory()
    each = WORKER_BYTES + max(0, int(task_bytes))
    if avail is None or workers * each <= avail / 2:
        return
    most = int(avail / 2 // each)
    what = (f"{WORKER_BYTES / 1e9:g} GB each" if task_bytes <= 0 else
            f"{WORKER_BYTES / 1e9:g} GB each and {task_bytes / 1e9:.3g} GB for the run each holds at once")
    ask = (f"at most {most} (--workers / --jobs)" if most >= 1 else "fewer workers (--workers / --jobs)")
    if task_bytes > 0:
        ask += " or shorter runs (--duration)"
    raise InputError(f"workers = {workers}: {workers} local worker processes would take about "
                     f"{workers * each / 1e9:.3g} GB ({what}), more than half the {avail / 1e9:.3g} GB available; "
                     f"ask for {ask}", field="workers")


def local_cluster(workers: int) -> Any:
    """A ``distributed.LocalCluster`` of ``workers`` single-threaded processes, for gearctl's runs.

    No dashboard, and the workers' statistical profiler off (it samples every thread's stack every 10 ms, a
    cost of its own in runs of a few milliseconds). Dask's nanny starts each worker with one BLAS thread. The
    scheduler's HTTP server (its health routes, which run even without a dashboard) listens on a free local port:
    on the default 8787, which another cluster or notebook often holds, it warns (an error under pytest's
    warnings-as-errors). The workers ignore SIGINT (:mod:`gearctl._worker_setup`): Ctrl-C reaches the whole process
    group, and each worker printed a traceback while the command ended with its one line. A Ctrl-C while the
    cluster starts is held until it is up (:func:`_sigint_held`), then closes it and raises ``KeyboardInterrupt``.

    Parameters
    ----------
    workers : int
        Worker processes, one thread each.

    Returns
    -------
    distributed.LocalCluster
    """
    import dask
    import distributed

    with _sigint_held() as interrupted, dask.config.set({"distributed.worker.profile.enabled": False}), \
            warnings.catch_warnings():
        # Dask warns when its scratch folder takes over a second to create: a loaded machine, not a fault (a line of
        # noise for the user, an error under pytest's warnings-as-errors)
        warnings.filterwarnings("ignore", message="Creating scratch directories is taking a surprisingly long time")
        cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                           dashboard_address=None, silence_logs=logging.CRITICAL,
                                           scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"},
                                           preload=["gearctl._worker_setup"])
    if interrupted():  # Ctrl-C while the workers started: close them, then end as a Ctrl-C does
        cluster.close()
        raise KeyboardInterrupt
    return cluster


@contextlib.contextmanager
def _sigint_held(*, tracker: bool = True) -> Iterator[Callable[[], bool]]:
    """Hold a Ctrl-C while the local cluster's processes start; yields a function that tells, after the block,
    whether one came.

    The worker processes ignore SIGINT only once their preload has run (:mod:`gearctl._worker_setup`). A Ctrl-C
    in the second or two before, which the terminal sends to the whole process group, printed a traceback from
    each starting worker (``spawn_main``), or reached this process inside Dask's start-up, which turned it into
    another exception (exit 1 with a traceback). Here, while the cluster starts:

    - SIGINT is blocked in this thread, so the threads Dask starts (its IO loop, which starts the workers) inherit
      the mask, and so do the processes they start: a worker keeps a Ctrl-C pending until its preload ignores it;
    - a Ctrl-C that reaches this process is only noted (a handler that raises nothing), to act on once the cluster
      is up.

    Multiprocessing's resource tracker is launched first: launched by the IO loop, it unblocks SIGINT in that
    thread. Only from the main thread (where Python handles signals), where the platform has signal masks and where
    SIGINT is not ignored; elsewhere a no-op. ``tracker=False`` (while a cluster closes: no process starts) leaves
    the resource tracker alone.
    """
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield lambda: False
        return
    if signal.getsignal(signal.SIGINT) in (signal.SIG_IGN, None):
        # SIGINT ignored (a background job of a script, nohup-like launchers): a Ctrl-C must stay without effect, not
        # end the command once the cluster is up; None, a handler set outside Python, could not be restored
        yield lambda: False
        return
    if tracker:
        from multiprocessing import resource_tracker

        resource_tracker.ensure_running()
    came = False

    def note(signum: int, frame: Any) -> None:  # noqa: ARG001 (a signal handler's signature)
        nonlocal came
        came = True

    old_handler = signal.signal(signal.SIGINT, note)
    old_mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield lambda: came
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old_mask)  # one pending here is noted now
        signal.signal(signal.SIGINT, old_handler)


def env_scheduler() -> str | None:
    """The ``DASK_SCHEDULER_ADDRESS`` environment variable's address, or None where it is not set; set but empty
    (``export DASK_SCHEDULER_ADDRESS=$ADDR`` with the variable unset) is refused, as an empty ``--scheduler`` is: it
    ran on a local cluster without a word."""
    value = os.environ.get("DASK_SCHEDULER_ADDRESS")
    if value is None:
        return None
    if not value.strip():
        raise InputError(f"DASK_SCHEDULER_ADDRESS = {value!r}: the environment variable is set but empty; expected "
                         f"tcp://HOST:PORT of a running Dask scheduler, or unset it for a local cluster",
                         field="scheduler")
    return value


def check_one_cluster(client: Any, scheduler: str | None) -> None:
    """Refuse a ``client`` given with a ``scheduler`` address: the client's cluster ran the work and the address
    was dropped without a word (a sweep given a closed port and a working client ran, as if the port answered).
    An empty ``scheduler`` is refused too: ``--scheduler "$ADDR"`` with the variable unset ran on a local cluster
    without a word, as if the option had not been given.

    Parameters
    ----------
    client : distributed.Client or None
        An open client, if given.
    scheduler : str or None
        A scheduler address, if given.

    Raises
    ------
    InputError
        For an empty ``scheduler``, or both a ``client`` and a ``scheduler`` (field ``scheduler``).
    """
    if scheduler is not None and not str(scheduler).strip():
        raise InputError(f"scheduler = {scheduler!r}: an empty address; expected tcp://HOST:PORT of a running Dask "
                         f"scheduler, or no scheduler for a local cluster", field="scheduler")
    if client is not None and scheduler:
        where = getattr(getattr(client, "scheduler", None), "address", None) or "another"
        raise InputError(f"scheduler = {scheduler!r} and a client: give one of them (the client's own scheduler is "
                         f"{where})", field="scheduler")


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
        An open client to use as is (not closed here); not with ``scheduler`` (an
        :class:`~gearctl.InputError`: one of them was ignored). Without it, a scheduler, or ``DASK_SCHEDULER_ADDRESS``,
        dask's default client (one a script opened) is used if there is one, else a local cluster. A scheduler's
        address is checked first (:func:`probe_scheduler`), and its workers must run this gearctl
        (:func:`code_id`) on this process's Python, numpy, SciPy, python-control and CasADi, its kernel
        compiled alike (:func:`numerics_versions`).
    task_bytes : int
        Memory one task holds while it runs [bytes]: a local cluster of ``workers`` processes must fit them all
        at once (:func:`check_local_workers`).
    """

    def __init__(self, *, workers: int | None = None, scheduler: str | None = None, client: Any = None,
                 task_bytes: int = 0) -> None:
        import distributed

        check_one_cluster(client, scheduler)
        self.cluster = None
        #: The workers dropped at the check for not answering (:meth:`_ask_workers`): ``{"worker", "tasks": 0,
        #: "restarted"}`` each, as :func:`completed`'s ``on_drop`` tells them.
        self.dropped: list[dict[str, Any]] = []
        self.own = client is None
        address = scheduler or (env_scheduler() if client is None else None)
        if client is None and not address:  # a client the script opened as the default (dask's convention)
            try:
                client = distributed.default_client()
            except ValueError:
                client = None
            self.own = client is None
        if client is not None:
            if getattr(client, "status", "running") in ("closing", "closed"):
                raise InputError(f"the Dask client given is {client.status}: open a new distributed.Client",
                                 field="client")
            self.client = client
            self.where = str(getattr(client.scheduler, "address", "the client's scheduler"))
        elif address:
            try:
                probe_scheduler(address)
                self.client = _open_client(address)
                try:
                    _wait_for_a_worker(self.client, address)
                except InputError:
                    _close_client(self.client)
                    raise
            except InputError as exc:
                if scheduler:
                    raise
                # an address the user did not type here: "cannot reach the Dask scheduler at garbage" left them
                # looking for where it came from (a shell profile, a notebook's environment)
                raise InputError(f"{exc} (the address is the DASK_SCHEDULER_ADDRESS environment variable's; unset "
                                 f"it to run on a local cluster)", field="scheduler") from None
            self.where = address
        else:
            from .kernel import compiled_available

            n = workers or default_workers()
            check_local_workers(n, task_bytes)
            compiled_available()  # compile the kernel once, before the workers start
            self.cluster = local_cluster(n)
            self.client = distributed.Client(self.cluster, set_as_default=False)
            self.where = f"local cluster ({n} process{'es' if n > 1 else ''})"
        if self.cluster is None:
            # the scheduler unpickles the tasks (Dask's graph, gearctl's functions by name): one that could not import
            # gearctl, or whose gearctl lacked a function, ended the sweep in Dask's traceback and exit 1 after the
            # workers had passed their check
            try:  # within CONNECT_TIMEOUT: a scheduler stopped or hung since it was reached held it for good
                theirs = self.client.run_on_scheduler(code_id, callback_timeout=CONNECT_TIMEOUT)
            except TimeoutError:
                self.close()
                raise _no_answer(self.where, CONNECT_TIMEOUT) from None
            except Exception as exc:
                self.close()
                raise InputError(f"the scheduler at {self.where} cannot run gearctl ({type(exc).__name__}: "
                                 f"{' '.join(str(exc).split())[:200]}): install this gearctl where the scheduler runs "
                                 f"too", field="scheduler") from None
            if theirs != code_id():
                self.close()
                raise InputError(f"the scheduler at {self.where} runs gearctl {theirs}, this is {code_id()} "
                                 f"(version+code hash): Dask's scheduler reads the tasks, install the same gearctl "
                                 f"where it runs (and restart one started before an edit)", field="scheduler")
            before = _scheduler_workers(self.client, CONNECT_TIMEOUT)  # their heartbeats, to name the silent
            if before is None:
                self.close()
                raise _no_answer(self.where, CONNECT_TIMEOUT)
            ids = self._ask_workers(code_id, before)
            broken = {w: v for w, v in ids.items() if isinstance(v, BaseException)}
            if broken:
                self.close()
                w, err = sorted(broken.items())[0]
                raise InputError(f"the worker{'s' if len(broken) > 1 else ''} {', '.join(sorted(broken))} of "
                                 f"{self.where} cannot run gearctl ({w}: {type(err).__name__}: "
                                 f"{' '.join(str(err).split())[:200]}): install this gearctl on every worker (the "
                                 f"same version and sources), or start them with it on their PYTHONPATH",
                                 field="scheduler")
            other = {w: v for w, v in ids.items() if v != code_id()}
            if other:
                self.close()
                theirs = ", ".join(sorted(set(other.values())))
                raise InputError(f"the worker{'s' if len(other) > 1 else ''} {', '.join(sorted(other))} of "
                                 f"{self.where} run{'' if len(other) > 1 else 's'} gearctl {theirs}, this is "
                                 f"{code_id()} (version+code hash): install the same gearctl on every worker, and "
                                 f"restart workers started before an edit", field="scheduler")
            # gearctl's code alone: a worker on another numpy (or SciPy, ...) passed, and its runs differed from a
            # serial run's in their last digits without a word
            stacks = self._ask_workers(numerics_versions, before)
            mine = numerics_versions()
            odd = {w: (f"runs {_numerics_differ(v, mine)}" if isinstance(v, dict) else
                       f"could not report its package versions ({type(v).__name__}: {v})")
                   for w, v in stacks.items() if not isinstance(v, dict) or _numerics_differ(v, mine)}
            if odd:
                self.close()
                w, why = sorted(odd.items())[0]
                others = sorted(odd)[1:]
                more = f" (and the worker{'s' if len(others) > 1 else ''} {', '.join(others)})" if others else ""
                raise InputError(f"the worker {w} of {self.where} {why}{more}: {_NUMERICS_FIX}", field="scheduler")

    def _ask_workers(self, fn: Callable[[], Any], before: Any) -> dict[str, Any]:
        """Each worker's answer to ``fn()``, or its exception (the refusals name the workers at fault), within
        :data:`WORKER_TIMEOUT`: a worker stopped or hung (``kill -STOP``) held the answer back, and the sweep with it,
        for good. A scheduler that stops answering meanwhile is named as such (``before``: its workers' heartbeats
        before the question, to name the silent ones). Workers named silent while others are heard from are dropped
        from the scheduler (:func:`_drop_worker`, as mid-run in :func:`completed`; :attr:`dropped`) and the others
        asked again: on a shared cluster a hung worker that is not the user's to restart refused every sweep until
        Dask's ``worker-ttl`` (5 min) removed it."""
        gone = {d["worker"] for d in self.dropped}
        ask = None
        if gone:  # the others only: a dropped worker may stay on the scheduler's list for a moment
            ask = [w for w in (_scheduler_workers(self.client, CONNECT_TIMEOUT) or before) if w not in gone]
        try:
            return cast("dict[str, Any]", self.client.run(fn, workers=ask, on_error="return",
                                                          callback_timeout=WORKER_TIMEOUT))
        except TimeoutError:
            after = _scheduler_workers(self.client, CONNECT_TIMEOUT)
            if after is None:  # the scheduler, not its workers
                self.close()
                raise _no_answer(self.where, CONNECT_TIMEOUT) from None
            quiet = [w for w in _silent_workers(before, after) if w not in gone]
            why = ""
            if quiet and set(after) - set(quiet) - gone:
                why = _drop_workers(self.client, dict.fromkeys(quiet, 0), {}, self.dropped.append)
                if not why:
                    return self._ask_workers(fn, after)
            self.close()
            raise InputError(f"the workers of {self.where} did not all answer within {WORKER_TIMEOUT:g} s "
                             f"(stopped or hung{': ' + ', '.join(quiet) if quiet else ''}"
                             f"{'; ' + why if why else ''}): restart them, or stop them and run on the others",
                             field="scheduler") from None
        except Exception as exc:  # the cluster itself, not a worker: say it in one line
            self.close()
            raise InputError(f"the workers of {self.where} cannot run gearctl: {type(exc).__name__}: {exc}",
                             field="scheduler") from None

    @property
    def workers(self) -> int:
        """Workers the scheduler knows now; an :class:`~gearctl.InputError` if it does not answer within
        :data:`CONNECT_TIMEOUT` (``client.scheduler_info()`` waited for good)."""
        workers = _scheduler_workers(self.client, CONNECT_TIMEOUT)
        if workers is None:
            raise _no_answer(self.where, CONNECT_TIMEOUT)
        return max(1, len(workers))

    @property
    def threads(self) -> int:
        """Threads of the scheduler's workers now, in all (``dask worker`` starts one per core unless told
        ``--nthreads``); an :class:`~gearctl.InputError` as :attr:`workers`."""
        workers = _scheduler_workers(self.client, CONNECT_TIMEOUT)
        if workers is None:
            raise _no_answer(self.where, CONNECT_TIMEOUT)
        return max(1, sum(int(d.get("nthreads") or 1) for d in workers.values()))

    def close(self, cancel: Sequence[Any] = ()) -> None:
        """Cancel ``cancel``, then close the client and the local cluster this engine opened (a client given is left
        open). A Ctrl-C meanwhile is held until they are done (a few seconds at most), then raised as
        ``KeyboardInterrupt``: a second Ctrl-C in the close that follows a first stopped it half-way, and the local
        cluster's scheduler, in this process, printed Dask's tracebacks (``CommClosedError``) and a list of lost keys.

        Parameters
        ----------
        cancel : sequence of distributed.Future
            The tasks left to cancel, one by one (``client.cancel`` of them all at once, followed at once by the
            client's close, lost the message: the scheduler then logged a traceback for each task that finished).
        """
        with _sigint_held(tracker=False) as interrupted:
            try:
                for fut in cancel:
                    fut.cancel()
            finally:
                if self.own:
                    _close_client(self.client)
                    if self.cluster is not None:
                        self.cluster.close()
        if interrupted():
            raise KeyboardInterrupt

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


#: Seconds between checks, while no task finishes, that the cluster still has workers.
POLL = 1.0
#: Seconds each of those checks waits for the scheduler's answer.
ANSWER_TIMEOUT = 5.0


def _scheduler_workers(client: Any, timeout: float | None = None) -> dict | None:
    """The scheduler's workers (address: its info), or None without an answer within ``timeout`` seconds (default
    :data:`ANSWER_TIMEOUT`).

    ``client.scheduler_info()`` waits for the answer without end: a scheduler stopped mid-sweep (SIGSTOP, a paused
    VM, a link cut without the connection closing) hung the sweep for good."""
    try:
        info = client.sync(client.scheduler.identity, n_workers=-1,
                           callback_timeout=ANSWER_TIMEOUT if timeout is None else timeout)
    except (TimeoutError, OSError):
        return None
    return dict(info.get("workers") or {})


def _silent_workers(before: dict, after: dict) -> list[str]:
    """The workers of ``after`` (the scheduler's, as :func:`_scheduler_workers` gives them) whose last heartbeat is
    the one they had in ``before``, or 10 s behind the latest of the others (by the scheduler's clock): those that
    did not answer, likely. Compared with the others alone, a lone worker stopped before the sweep went unnamed."""
    seen = {w: float(d.get("last_seen") or 0.0) for w, d in after.items()}
    latest = max(seen.values(), default=0.0)
    return sorted(w for w, t in seen.items() if after[w].get("last_seen") is not None and (
        latest - t > 10.0 or (w in before and before[w].get("last_seen") == after[w].get("last_seen"))))


def _no_answer(address: str, timeout: float) -> InputError:
    """The refusal of a scheduler that was reached but gives no answer within ``timeout`` seconds."""
    return InputError(f"the Dask scheduler at {address} did not answer within {timeout:g} s (stopped, hung, or cut "
                      f"off from this machine): run again when it answers", field="scheduler")


def _open_client(address: str) -> Any:
    """``distributed.Client(address)``, or an :class:`~gearctl.InputError` within :data:`CONNECT_TIMEOUT` (and
    :data:`ANSWER_TIMEOUT` to spare).

    Dask's timeout covers the TCP connect only: its handshake then waits for the scheduler's reply without end, so
    a scheduler stopped (``kill -STOP``) or hung after :func:`probe_scheduler` had its answer hung the command for
    good (still waiting after 150 s). The client opens in a thread of its own; one that gives up on it leaves the
    thread to end, or to close the client it gets, whenever the scheduler answers."""
    import distributed

    lock = threading.Lock()
    box: dict[str, Any] = {}  # "client", "error" (what opening raised), "gave up" (the waiting thread's)

    def open_() -> None:
        try:
            client = distributed.Client(address, timeout=CONNECT_TIMEOUT, set_as_default=False)
        except BaseException as exc:  # noqa: BLE001 (handed to the waiting thread, which raises it)
            box["error"] = exc
            return
        with lock:
            if "gave up" not in box:
                box["client"] = client
                return
        _close_client(client)

    t = threading.Thread(target=open_, name="gearctl-client-open", daemon=True)
    t.start()
    try:
        t.join(CONNECT_TIMEOUT + ANSWER_TIMEOUT)
    except BaseException:  # a Ctrl-C while it waits: the client, now or when it opens, is closed
        with lock:
            box["gave up"] = True
            client = box.pop("client", None)
        if client is not None:
            _close_client(client)
        raise
    with lock:
        if "client" in box:
            return box["client"]
        box["gave up"] = True
    exc = box.get("error")
    if exc is None:  # still waiting for the scheduler's handshake
        raise _no_answer(address, CONNECT_TIMEOUT + ANSWER_TIMEOUT)
    if isinstance(exc, (OSError, TimeoutError)):
        raise InputError(f"cannot reach the Dask scheduler at {address}: {exc}", field="scheduler") from None
    raise exc


def _wait_for_a_worker(client: Any, address: str) -> None:
    """Wait until the scheduler has a worker: an :class:`~gearctl.InputError` if none joined within
    :data:`WORKER_TIMEOUT`, or if the scheduler gives no answer within :data:`CONNECT_TIMEOUT`
    (``client.wait_for_workers`` asks it first without a timeout: a scheduler stopped then waited for good)."""
    deadline = time.monotonic() + WORKER_TIMEOUT
    while True:
        workers = _scheduler_workers(client, CONNECT_TIMEOUT)
        if workers is None:
            raise _no_answer(address, CONNECT_TIMEOUT)
        if workers:
            return
        if time.monotonic() > deadline:
            raise InputError(f"no worker joined the Dask scheduler at {address} within {WORKER_TIMEOUT:g} s: start "
                             f"one with `dask worker {address} --nthreads 1`", field="scheduler")
        time.sleep(0.1)


def _close_client(client: Any) -> None:
    """Close ``client`` within :data:`ANSWER_TIMEOUT`: Dask's own close waits up to twice its connect timeout for a
    scheduler that does not answer, then raises ``TimeoutError`` (a traceback where a one-line error was due)."""
    with contextlib.suppress(TimeoutError, OSError):
        client.close(timeout=ANSWER_TIMEOUT)


def completed(client: Any, futures: Sequence[Any], *, where: str = "the cluster",
              on_drop: Callable[[dict[str, Any]], Any] | None = None,
              ) -> Iterator[tuple[Any, Any, BaseException | None]]:
    """``(future, result, None)`` or ``(future, None, exception)`` for each future as it finishes
    (``distributed.as_completed`` on ``client``'s loop), its result fetched here. A cluster left without workers for
    :data:`WORKER_TIMEOUT` seconds is an :class:`~gearctl.InputError`: with every worker killed a sweep waited
    forever, for the tasks left and for a finished task's result that only the dead worker held. While nothing
    arrives, the cluster's workers are counted every :data:`POLL` seconds; a scheduler that gives no answer for
    :data:`WORKER_TIMEOUT` seconds (each question waits :data:`ANSWER_TIMEOUT`) is an ``InputError`` too, and so
    is a worker the scheduler has not heard from for :data:`WORKER_TIMEOUT` seconds that holds some of the tasks
    (:func:`_held_by_silent`) when no other worker is left, or when the scheduler does not drop it.

    A silent worker holding tasks is dropped from the scheduler (:func:`_drop_worker`: as its own ``worker-ttl``
    does after 5 min, restarted by its nanny or removed) while another worker is heard from: its tasks, and
    the finished results only it held, are recomputed on the workers left, and the sweep goes on (a worker stopped
    with ``kill -STOP`` ended an hour's sweep after 60 s, every finished run lost). A worker stopped and resumed
    within :data:`WORKER_TIMEOUT` is never dropped.

    Parameters
    ----------
    client : distributed.Client
        The client the futures belong to.
    futures : sequence of distributed.Future
        The tasks.
    where : str
        How messages name the cluster (default ``"the cluster"``).
    on_drop : callable, optional
        ``on_drop(record)`` after a silent worker is dropped, ``record`` ``{"worker": address, "tasks": n,
        "restarted": bool}``: how many of ``futures`` it held, and whether its nanny started a fresh one in its place
        (:func:`_drop_worker`; else it was removed) (default: nothing told).

    Yields
    ------
    tuple
        ``(future, result, None)`` or ``(future, None, exception)``.

    Raises
    ------
    InputError
        For a cluster without workers, a scheduler that does not answer, or a silent worker holding tasks that
        cannot be dropped (no other worker left, or the scheduler refused), each for :data:`WORKER_TIMEOUT` seconds.
    """
    from distributed import as_completed
    from distributed.comm.core import CommClosedError

    ac = as_completed(list(futures), loop=client.loop)
    keys = {f.key for f in futures}
    checked = time.monotonic()
    alone_since: float | None = None
    silent_since: float | None = None
    heard: dict[str, tuple[Any, float]] = {}  # worker: (its last heartbeat by the scheduler's clock, when it changed)

    def watch(left: int) -> None:
        nonlocal checked, alone_since, silent_since
        now = time.monotonic()
        if now - checked < POLL:
            return
        workers = _scheduler_workers(client)
        checked = now = time.monotonic()
        if workers is None:
            if silent_since is None:
                silent_since = now
            elif now - silent_since > WORKER_TIMEOUT:
                raise InputError(f"{where}: the scheduler has not answered for {WORKER_TIMEOUT:g} s with {left} "
                                 f"task(s) unfinished (stopped, hung, or cut off from this machine); run again when "
                                 f"it answers", field="scheduler")
            return
        silent_since = None
        held = _held_by_silent(client, workers, heard, keys, now)
        if held:
            quiet = {w for w, (_, since) in heard.items() if w in workers and now - since > WORKER_TIMEOUT}
            live = sorted(set(workers) - quiet - set(held))
            why = ("no other worker is left to take them" if not live else
                   _drop_workers(client, held, heard, on_drop))
            if why:
                many = len(held) > 1
                raise InputError(f"{where}: the worker{'s' if many else ''} {', '.join(sorted(held))} "
                                 f"{'have' if many else 'has'} not been heard from for {WORKER_TIMEOUT:g} s "
                                 f"(stopped, hung, or cut off from the scheduler) and hold{'' if many else 's'} "
                                 f"{sum(held.values())} of the {left} unfinished task(s), and {why}: Dask takes "
                                 f"them back only after its worker-ttl (5 min by default), if at all; restart or "
                                 f"stop {'them' if many else 'it'} and run again", field="scheduler")
            return
        if workers:
            alone_since = None
        elif alone_since is None:
            alone_since = now
        elif now - alone_since > WORKER_TIMEOUT:
            raise InputError(f"{where} has had no worker for {WORKER_TIMEOUT:g} s with {left} task(s) unfinished: "
                             f"the workers died or left; start some with `dask worker ADDRESS --nthreads 1` and run "
                             f"again", field="scheduler")

    while not ac.is_empty():
        if not ac.has_ready():
            time.sleep(_NAP)
            watch(ac.count())
            continue
        batch = ac.next_batch(block=False)
        for k, fut in enumerate(batch):
            while True:
                try:
                    got = fut.result(timeout=POLL)
                except TimeoutError:  # finished, but its result is on a worker that is gone: recomputed, or none left
                    watch(ac.count() + len(batch) - k)
                    continue
                except (concurrent.futures.CancelledError, CommClosedError) as exc:
                    # not a task's error: the scheduler cancelled it or went away (killed mid-run: "scheduler-
                    # connection-lost", or the connection reset while a result was fetched), which ended a sweep in
                    # a traceback, exit 1
                    raise InputError(f"{where}: the run's tasks were cancelled with {ac.count() + len(batch) - k} "
                                     f"unfinished ({type(exc).__name__}: {' '.join(str(exc).split())}): the "
                                     f"scheduler went away or cancelled them; run again when it is back",
                                     field="scheduler") from None
                except Exception as exc:  # the task's own error, for the caller to raise or record
                    yield fut, None, exc
                else:
                    yield fut, got, None
                break
            alone_since = None


def _held_by_silent(client: Any, workers: dict, heard: dict[str, tuple[Any, float]], keys: set,
                    now: float) -> dict[str, int]:
    """The workers silent for :data:`WORKER_TIMEOUT` seconds that hold some of ``keys`` (running them, or their
    results), with how many; ``heard`` is updated with ``workers``' heartbeats as of ``now``.

    A worker is silent when the scheduler's record of its last heartbeat (``last_seen``; a worker sends one every
    0.5 to a few seconds, from its event loop, even while its tasks run) has not changed for that long by this
    machine's clock, so the two clocks need not agree. A worker stopped with ``kill -STOP`` (or hung, or cut off
    without its connection closing) stays on the scheduler's list with the tasks it was given until Dask's
    ``worker-ttl`` (5 min): a sweep on two workers, one of them stopped, was still waiting after 6.5 min."""
    for w, info in workers.items():
        seen = info.get("last_seen")
        if seen is None:  # a Dask that does not say: never taken for silent
            heard.pop(w, None)
        elif w not in heard or heard[w][0] != seen:
            heard[w] = (seen, now)
    silent = sorted(w for w, (_, since) in heard.items() if w in workers and now - since > WORKER_TIMEOUT)
    if not silent:
        return {}
    held: dict[str, int] = {}
    try:
        for ask in (client.scheduler.processing, client.scheduler.has_what):
            for w, ks in client.sync(ask, workers=silent, callback_timeout=ANSWER_TIMEOUT).items():
                n = len(keys.intersection(ks))
                if n:
                    held[w] = held.get(w, 0) + n
    except (TimeoutError, OSError):  # the scheduler's own silence is watched apart
        return {}
    return held


def _drop_workers(client: Any, held: dict[str, int], heard: dict[str, tuple[Any, float]],
                  on_drop: Callable[[dict[str, Any]], Any] | None) -> str:
    """Have the scheduler drop each worker of ``held`` (address: tasks it holds), telling ``on_drop`` its record
    (``{"worker", "tasks", "restarted"}``: restarted by its nanny, Dask's ``"OK"``); ``""``, or
    why one could not be dropped (the scheduler did not answer within :data:`DROP_TIMEOUT` and
    :data:`ANSWER_TIMEOUT`, or refused)."""
    for w, n in sorted(held.items()):
        try:
            how = client.run_on_scheduler(_drop_worker, w, DROP_TIMEOUT,
                                          callback_timeout=DROP_TIMEOUT + ANSWER_TIMEOUT)
        except (TimeoutError, OSError):
            return f"the scheduler did not drop {w} within {DROP_TIMEOUT + ANSWER_TIMEOUT:g} s"
        except Exception as exc:  # a scheduler that refuses to run functions (distributed.scheduler.pickle off)
            return (f"the scheduler did not drop {w} ({type(exc).__name__}: "
                    f"{' '.join(str(exc).split())[:120]})")
        heard.pop(w, None)
        if on_drop is not None:
            on_drop({"worker": w, "tasks": n, "restarted": str(how) == "OK"})
    return ""


#: Seconds the scheduler gives a silent worker's nanny to end it (:func:`_drop_worker`), then removes it anyway.
DROP_TIMEOUT = 10.0


async def _drop_worker(address: str, timeout: float, dask_scheduler: Any = None) -> str:
    """Run on the scheduler (``client.run_on_scheduler``): drop the worker ``address`` as Dask's own ``worker-ttl``
    check drops one that has stopped sending heartbeats (``Scheduler.check_worker_ttl``: ``restart_workers``
    without waiting for it to return). A worker with a nanny is ended by it, which starts a fresh one; one without,
    or whose nanny does not answer within ``timeout`` seconds (a stopped machine), is removed
    (``remove_worker``, told to close should it resume). Either way its tasks go back to be run elsewhere and its
    results held nowhere else are recomputed. ``retire_workers`` would first copy its results off it, which waits
    for the silent worker. What Dask says of it: ``"OK"`` (restarted by its nanny), ``"removed"`` (no nanny),
    ``"timed out"`` (its nanny did not answer: removed), or ``""`` (already gone)."""
    out = await dask_scheduler.restart_workers([address], timeout=timeout, wait_for_workers=False, on_error="return",
                                               stimulus_id=f"gearctl-silent-worker-{time.time()}")
    return str(out.get(address, ""))


def killed_worker_text(exc: BaseException) -> str:
    """What Dask's ``KilledWorker`` means, in one line: a task whose every worker died while running it (a worker
    past its memory limit, ``dask worker --memory-limit``, restarted by its nanny each time, or a crash).

    Parameters
    ----------
    exc : BaseException
        The ``KilledWorker`` (its ``allowed_failures`` and ``last_worker`` are read where present).

    Returns
    -------
    str
    """
    tries = getattr(exc, "allowed_failures", None)
    last = getattr(getattr(exc, "last_worker", None), "address", None)
    return (f"each of the {tries + 1 if isinstance(tries, int) else 'several'} workers that ran it died while it ran"
            f"{f' (the last {last})' if last else ''}: a worker's memory limit (a gearctl worker takes about "
            f"{WORKER_BYTES / 1e9:g} GB; `dask worker --memory-limit`) or a crash, see the workers' logs")


#: Seconds between looks for finished tasks (a task takes tens of ms at least: batches, see gearctl.sweep).
_NAP = 0.01


def local_processes(tasks: int, workers: int | None = None) -> int:
    """The processes :func:`map_tasks` runs ``tasks`` on without a scheduler: ``workers`` (default
    :func:`default_workers`), never more than the tasks (1: here, one after the other)."""
    return max(1, min(workers or default_workers(), tasks))


class TasksInterrupted(KeyboardInterrupt):
    """A Ctrl-C (or a SIGTERM taken as one) after some tasks had finished: what they gave is not lost.

    A ``KeyboardInterrupt`` still (``except Exception`` does not swallow it), raised once the cluster's tasks are
    cancelled and a local cluster closed. :func:`map_tasks` raises it, and the sweep's engine (``gearctl.sweep``):
    a sweep and a bench keep the runs finished alike.

    Parameters
    ----------
    results : list
        One entry per task, in the order given: its result, or None where it did not finish.
    info : dict, optional
        What the caller records of the engine (the sweep's ``engine``).

    Attributes
    ----------
    results : list
    info : dict
    missing : tuple of int
        The positions of the tasks that did not finish.
    """

    def __init__(self, results: list[Any], info: dict[str, Any] | None = None,
                 missing: Sequence[int] | None = None) -> None:
        super().__init__()
        self.results, self.info = results, {} if info is None else info
        self.missing = tuple(i for i, r in enumerate(results) if r is None) if missing is None else tuple(missing)


def map_tasks(fn: Callable[[Any], Any], items: Sequence[Any], *, workers: int | None = None,
              scheduler: str | None = None, progress: Callable[[int, int], Any] | None = None,
              name: str = "gearctl", task_bytes: int = 0,
              on_drop: Callable[[dict[str, Any]], Any] | None = None) -> list[Any]:
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
    task_bytes : int
        Memory of the largest task while it runs [bytes] (see :class:`Engine`).
    on_drop : callable, optional
        ``on_drop(record)`` for each silent worker dropped from the scheduler, at the workers' check
        (:attr:`Engine.dropped`, ``tasks`` 0) or holding tasks (as :func:`completed`'s) (default: nothing told).

    Returns
    -------
    list
        The results, in the order of ``items``. An exception in a task is raised here.

    Raises
    ------
    TasksInterrupted
        A Ctrl-C after some tasks had finished (the cluster's tasks cancelled and a local cluster closed first; a
        second Ctrl-C during that close is held until it is done): their results, None for the others. Before any
        had finished, a plain ``KeyboardInterrupt``.
    """
    check_one_cluster(None, scheduler)
    n = len(items)
    # the address the user typed stays apart from DASK_SCHEDULER_ADDRESS's, which the Engine reads itself and names
    # when it cannot be reached (a bench's error named an address the user had not typed, as the sweep's no longer did)
    address = scheduler or env_scheduler()
    if n == 0:
        return []
    results: list[Any] = [None] * n
    finished = [False] * n

    def interrupted() -> KeyboardInterrupt:
        if not any(finished):
            return KeyboardInterrupt()
        return TasksInterrupted(results, missing=[i for i, f in enumerate(finished) if not f])

    if address is None and local_processes(n, workers) == 1:
        try:
            for i, x in enumerate(items):
                results[i] = fn(x)
                finished[i] = True
                if progress:
                    progress(i + 1, n)
        except KeyboardInterrupt:
            raise interrupted() from None
        return results
    from distributed import KilledWorker

    try:
        with Engine(workers=local_processes(n, workers), scheduler=scheduler, task_bytes=task_bytes) as eng:
            if on_drop is not None:  # the workers dropped at the check, before any task (told as the sweep tells them)
                for d in eng.dropped:
                    on_drop(d)
            tag = uuid.uuid4().hex[:12]
            mine, stack = code_id(), numerics_versions()
            futures = {eng.client.submit(checked, mine, fn, x, key=f"{name}-{tag}-{k}", pure=False,
                                         numerics=stack): k for k, x in enumerate(items)}
            try:
                for done, (fut, got, exc) in enumerate(completed(eng.client, list(futures), where=eng.where,
                                                                 on_drop=on_drop), start=1):
                    if isinstance(exc, KilledWorker):  # Dask's traceback and exit 1 (a bench on workers of 120 MB)
                        raise InputError(f"{eng.where}: the task {fut.key} could not run: {killed_worker_text(exc)}",
                                         field="scheduler") from None
                    if exc is not None:
                        raise exc
                    k = futures.pop(fut)
                    results[k], finished[k] = got, True
                    fut.release()
                    if progress:
                        progress(done, n)
            finally:
                eng.close(cancel=list(futures))  # (a Ctrl-C meanwhile is held until the cluster is closed)
    except KeyboardInterrupt:  # Ctrl-C, after the cluster's tasks were cancelled and it was closed
        raise interrupted() from None
    return results
