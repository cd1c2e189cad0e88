"""Helpers several test modules share (not itself a test module): a real Dask cluster of ``dask scheduler`` and
``dask worker`` processes, as an outsider starts them, and an example script's ``main``."""

from __future__ import annotations

import contextlib
import importlib.util
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import gearctl


@contextlib.contextmanager
def subprocess_cluster(tmp_path: Path, workers: int = 1) -> Iterator[tuple[str, list[subprocess.Popen]]]:
    """A ``dask scheduler`` and ``workers`` ``dask worker`` processes (no nanny), each in its own process group:
    the address and [scheduler, worker, ...]. Their gearctl is this one (PYTHONPATH as this process's)."""
    sched_file = tmp_path / "scheduler.json"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(Path(gearctl.__file__).parents[1]),
                                                                      os.environ.get("PYTHONPATH")]))}
    common = {"cwd": tmp_path, "env": env, "stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL,
              "start_new_session": True}
    procs = [subprocess.Popen([sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0",
                               "--no-dashboard", "--scheduler-file", str(sched_file)], **common)]
    try:
        deadline = time.monotonic() + 60
        address = None
        while address is None and time.monotonic() < deadline:
            with contextlib.suppress(OSError, ValueError, KeyError):
                address = json.loads(sched_file.read_text())["address"]
            time.sleep(0.1)
        assert address, "the dask scheduler did not start"
        for k in range(workers):
            procs.append(subprocess.Popen([sys.executable, "-m", "dask", "worker", address, "--nthreads", "1",
                                           "--no-nanny", "--no-dashboard", "--host", "127.0.0.1", "--name", f"w{k}",
                                           "--local-directory", str(tmp_path / f"w{k}")], **common))
        from distributed import Client

        if workers:
            with Client(address, timeout=30, set_as_default=False) as c:
                c.wait_for_workers(workers, timeout=90)
        yield address, procs
    finally:
        for p in procs:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGKILL)
            p.wait(timeout=30)


EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def example_main(name: str) -> Callable[..., object]:
    """``main`` of ``examples/<name>.py``, loaded from its file (the examples are scripts, not a package)."""
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    spec.loader.exec_module(mod)  # type: ignore[union-attr]
    return mod.main


class ReadingFilter:
    """A controller whose readings a test alters before they reach it (a harness's missed samples, a glitch): the
    wrapped controller's attributes the closed loop reads, its ``reset``, and ``step`` passing
    :meth:`readings`' values on. Subclasses override :meth:`readings` ((sample number, y_motor, y_load) to the
    readings given)."""

    def __init__(self, inner) -> None:  # noqa: ANN001
        self.inner, self.n = inner, 0
        self.Ts, self.preview, self.name = inner.Ts, inner.preview, inner.name
        self.uses_load_encoder = inner.uses_load_encoder
        self.solve_times, self.fallbacks = [], []

    def reset(self) -> None:
        self.inner.reset()
        self.n = 0

    def readings(self, k: int, y_motor: float, y_load: float | None) -> tuple[float, float | None]:
        return y_motor, y_load

    def step(self, t, y_motor, y_load, ref):  # noqa: ANN001, ANN201
        k, self.n = self.n, self.n + 1
        return self.inner.step(t, *self.readings(k, y_motor, y_load), ref)


class RecordingBar:
    """Stands in for :func:`gearctl.cli.common.progress_bar`: always shown, records the fractions each bar is given
    (``RecordingBar.made[desc]``; reset it in each test)."""

    made: dict[str, list[float]] = {}

    def __init__(self, desc: str, *, expected_s: float, threshold: float = 2.0, total: int = 1000) -> None:
        self.bar = True
        self.calls = RecordingBar.made.setdefault(desc, [])

    def __call__(self, fraction: float) -> None:
        self.calls.append(fraction)

    def __enter__(self) -> RecordingBar:
        return self

    def __exit__(self, *exc: object) -> None:
        return None


def within(seconds: float, fn: Callable[[], Any]) -> Any:
    """``fn()`` in a thread: its result or its exception; a failed test if it has not ended within ``seconds``."""
    box: dict[str, Any] = {}

    def run() -> None:
        try:
            box["out"] = fn()
        except BaseException as exc:  # noqa: BLE001 (handed to the test)
            box["out"] = exc

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(seconds)
    assert not t.is_alive(), f"still waiting after {seconds:g} s"
    return box["out"]


def as_json(obj: Any) -> Any:
    """``obj`` as the CLI's ``--json`` writes it, read back (floats exact: repr round-trips)."""
    from gearctl.cli.common import dump_json

    return json.loads(dump_json(obj))


def checkout_env() -> dict[str, str]:
    """The environment with this checkout first on ``PYTHONPATH``: a child process imports the gearctl under test,
    not an installed copy."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(Path(gearctl.__file__).parents[1]),
                                                                       os.environ.get("PYTHONPATH")]))}


def signal_when_marked(argv: list[str], mark: Path, cwd: Path, sig: int = signal.SIGINT,
                       second: float | None = None) -> tuple[int, str, str, float, int]:
    """Run ``argv`` in a session of its own (this checkout's gearctl); once the file ``mark`` exists, ``sig`` to its
    whole group (as a terminal's Ctrl-C; again, as SIGINT, ``second`` s later). Its exit code, stdout, stderr, the
    seconds it took to end after the signal, and its session id."""
    p = subprocess.Popen(argv, cwd=cwd, env=checkout_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while not mark.exists() and p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert mark.exists(), p.communicate(timeout=30)
        t0 = time.monotonic()
        os.killpg(p.pid, sig)
        if second is not None:
            time.sleep(second)
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGINT)
        out, err = p.communicate(timeout=60)
        took = time.monotonic() - t0
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(p.pid, signal.SIGKILL)
        p.wait(timeout=30)
    return p.returncode, out, err, took, p.pid
