"""``gearctl bench`` tells of a silent worker it dropped, as the sweep does.

The bench runs on the same ``parallel.completed`` as the sweep, which drops a worker the scheduler has not heard from
for ``WORKER_TIMEOUT`` seconds holding tasks (and ``Engine`` one silent at the workers' check), its tasks rerun on
the others; the sweep says so in a note and in its JSON's ``engine.dropped``, the bench said nothing. A fake cluster
stands in for Dask here (tests/test_t1_silent_worker.py drops real workers).
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path
from typing import Any

import pytest

import gearctl.parallel
from gearctl.cli import main


class _Future:
    def __init__(self, value: Any) -> None:
        self.value, self.key = value, "k"

    def release(self) -> None:
        pass

    def cancel(self) -> None:
        pass


class _Client:
    def submit(self, fn: Any, *args: Any, key: str, pure: bool, numerics: Any) -> _Future:  # noqa: ARG002
        return _Future(fn(*args, numerics=numerics))  # run here: checked(code_id, _task, task)


class _Engine:
    """A cluster whose worker tcp://10.0.0.7:1 was dropped at the workers' check, without a Dask cluster."""

    def __init__(self, **kw: Any) -> None:  # noqa: ARG002
        self.client, self.where = _Client(), "tcp://10.0.0.1:8786"
        self.dropped = [{"worker": "tcp://10.0.0.7:1", "tasks": 0, "restarted": False}]

    def close(self, cancel: Any = ()) -> None:
        pass

    def __enter__(self) -> _Engine:
        return self

    def __exit__(self, *exc: object) -> None:
        pass


def _completed(client: Any, futures: list, *, where: str, on_drop: Any = None) -> Any:  # noqa: ARG001
    # the second worker goes silent holding 2 tasks and is dropped (its nanny restarts it) before the results come
    if on_drop is not None:
        on_drop({"worker": "tcp://10.0.0.9:1", "tasks": 2, "restarted": True})
    for f in futures:
        yield f, f.value, None


def test_bench_tells_of_the_silent_workers_it_dropped(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(gearctl.parallel, "Engine", _Engine)
    monkeypatch.setattr(gearctl.parallel, "completed", _completed)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        rc = main(["bench", "shing1993_servo", "--controllers", "pid", "--plants", "improved", "--references", "step",
                   "--duration", "0.2", "--no-precision", "--quiet", "--scheduler", "tcp://10.0.0.1:8786",
                   "--json", str(tmp_path / "b.json"), "--out", str(tmp_path / "o")])
    assert rc == 0, err.getvalue()
    t = gearctl.parallel.WORKER_TIMEOUT
    notes = [line for line in err.getvalue().splitlines() if "dropped" in line]
    assert notes == [
        f"gearctl bench: note: the worker tcp://10.0.0.7:1 was not heard from for {t:g} s at the check of the "
        f"workers, before any run: dropped from the scheduler (removed), its tasks rerun on the other workers",
        f"gearctl bench: note: the worker tcp://10.0.0.9:1 was not heard from for {t:g} s holding 2 task(s): "
        f"dropped from the scheduler (its nanny started a fresh one), its tasks rerun on the other workers"]
    data = json.loads((tmp_path / "b.json").read_text())
    assert data["dropped"] == [{"worker": "tcp://10.0.0.7:1", "tasks": 0, "restarted": False},
                               {"worker": "tcp://10.0.0.9:1", "tasks": 2, "restarted": True}]
    assert "tcp://10.0.0.9:1 was not heard from" in (tmp_path / "o" / "report.md").read_text()


def test_the_sweep_and_the_bench_word_a_dropped_worker_alike() -> None:
    from gearctl.cli.common import dropped_notes

    t = gearctl.parallel.WORKER_TIMEOUT
    assert dropped_notes([{"worker": "tcp://h:1", "tasks": 3, "restarted": False}]) == [
        f"the worker tcp://h:1 was not heard from for {t:g} s holding 3 task(s): dropped from the scheduler "
        f"(removed), its tasks rerun on the other workers"]
