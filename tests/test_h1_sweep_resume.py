"""Resuming a sweep that did not finish: ``gearctl sweep --resume PREVIOUS.json`` and ``gearctl.sweep.resume``.

A sweep the cluster could not finish (``SweepIncomplete``, exit 2) or a Ctrl-C stopped (``SweepInterrupted``, exit
130) writes the runs that finished and ``missing``; nothing reran only the missing runs. A resumed sweep takes every
setting from the previous sweep's JSON, reruns the indices in ``missing`` and writes the whole sweep: the same figures
as a whole sweep of the same settings (checked here against one, ``missing`` forced by editing the JSON).
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from support import as_json

import gearctl
import gearctl.sweep
from gearctl.cli import main

_ARGS = {"vary": ["backlash=0.5x:2x"], "runs": 6, "duration": 0.2}
_GONE = [1, 4]


@pytest.fixture(scope="module")
def whole() -> gearctl.sweep.SweepResult:
    return gearctl.sweep.sweep("shing1993_servo", "pid", engine="serial", **_ARGS)


def _previous(whole: gearctl.sweep.SweepResult, gone: list[int] = _GONE) -> dict[str, Any]:
    """The whole sweep's JSON edited as if the runs ``gone`` had not finished (an interrupted sweep's)."""
    data = as_json(whole.as_dict())
    data["runs"] = [r for r in data["runs"] if r["index"] not in gone]
    data["missing"] = list(gone)
    data["engine"]["interrupted"] = True
    return data


def _write(path: Path, data: dict[str, Any]) -> Path:
    path.write_text(json.dumps(data))
    return path


def _same_sweep(resumed: Any, whole: Any) -> None:
    a, b = as_json(resumed), as_json(whole)
    assert [r["index"] for r in a["runs"]] == list(range(len(b["runs"])))
    assert a["runs"] == b["runs"]  # the figures of every run, to the last bit, and their commands
    assert a["summary"] == b["summary"] and a["settings"] == b["settings"]
    assert "missing" not in a


# --- from Python ------------------------------------------------------------------------------------------

def test_a_resumed_sweep_is_the_whole_sweep(tmp_path: Path, whole: gearctl.sweep.SweepResult) -> None:
    prev = _write(tmp_path / "prev.json", _previous(whole))
    done: list[tuple[int, int]] = []
    r = gearctl.sweep.resume(prev, engine="serial", progress=lambda d, n: done.append((d, n)))
    _same_sweep(r.as_dict(), whole.as_dict())
    assert r.missing == () and done[-1] == (2, 2)  # only the missing runs ran
    res = r.engine["resumed"]
    assert res["from"] == str(prev) and res["reused"] == 4 and res["rerun"] == 2
    assert res["previous"]["interrupted"] is True and "interrupted" not in r.engine
    # the keys varied as factors of each stage's value (none here) and the vary specs are the sweep's own
    assert r.keys == whole.keys and r.vary == whole.vary


def test_the_draws_are_seeded_per_run_so_a_rerun_is_the_run_it_would_have_been(
        whole: gearctl.sweep.SweepResult) -> None:
    # the draws and noise seeds of run i depend on (seed, i, key) alone: the same runs alone as among all
    plan = gearctl.sweep.plan_sweep("shing1993_servo", "pid", **_ARGS)
    assert [(j[1], j[2]) for j in plan.jobs] == [(r["params"], r["seed"]) for r in whole.runs]
    alone = gearctl.sweep.sweep_task(plan.context, [plan.jobs[i] for i in _GONE])
    assert as_json(alone) == as_json([whole.runs[i] for i in _GONE])


def test_resume_takes_the_result_of_an_interrupted_sweep_and_resumes_again(
        whole: gearctl.sweep.SweepResult) -> None:
    def progress(done: int, total: int) -> None:  # noqa: ARG001 (Ctrl-C once one batch of 1 is in)
        if done >= 1:
            raise KeyboardInterrupt

    prev = _previous(whole, [0, 2, 5])
    with pytest.raises(gearctl.sweep.SweepInterrupted) as info:
        gearctl.sweep.resume(prev, engine="serial", batch=1, progress=progress)
    part = info.value.result
    assert part.missing == (2, 5) and [r["index"] for r in part.runs] == [0, 1, 3, 4]
    assert str(info.value) == "interrupted: 4 of 6 runs finished, 2 did not"
    assert part.engine["interrupted"] is True and part.engine["resumed"]["from"] is None
    r = gearctl.sweep.resume(part, engine="serial")  # the SweepResult itself
    _same_sweep(r.as_dict(), whole.as_dict())
    assert r.engine["resumed"]["previous"]["resumed"]["rerun"] == 3  # the chain of parts is recorded


def _refusal(prev: Any) -> str:
    with pytest.raises(gearctl.InputError) as info:
        gearctl.sweep.resume(prev, engine="serial")
    assert info.value.field == "resume" and "\n" not in str(info.value)
    return str(info.value)


def test_what_cannot_be_resumed_is_refused_in_one_line(tmp_path: Path, whole: gearctl.sweep.SweepResult) -> None:
    (tmp_path / "text.json").write_text("runs: 6\n")
    assert "not a gearctl sweep's JSON (not JSON:" in _refusal(tmp_path / "text.json")
    assert "cannot read it: No such file or directory" in _refusal(tmp_path / "none.json")
    assert "not a gearctl sweep's JSON (expected settings, engine, summary and runs" in _refusal(
        _write(tmp_path / "bench.json", {"spec": {}, "runs": [], "precision": []}))
    finished = as_json(whole.as_dict())
    assert "the sweep finished (no missing runs: all 6 ran): nothing to resume" in _refusal(finished)
    other = _previous(whole)
    other["settings"]["gearctl"] = "0.0.9+0123456789ab"
    assert f"written by gearctl 0.0.9+0123456789ab, this is {gearctl.parallel.code_id()}" in _refusal(other)
    old = _previous(whole)
    del old["settings"]["gearctl"]
    assert "did not record its version and files" in _refusal(old)
    numpy = _previous(whole)
    numpy["settings"]["numerics"]["numpy"] = "1.0.0"
    assert "run on numpy 1.0.0 (this process: " in _refusal(numpy)
    holes = _previous(whole)
    holes["missing"] = [1]  # run 4 neither finished nor missing
    assert "its runs (4) and missing (1) do not make up its 6 runs, each once" in _refusal(holes)
    seed = _previous(whole)
    seed["settings"]["seed"] = 1  # (the settings agree with themselves; the runs' draws do not)
    assert "run 0's draws" in _refusal(seed) and "differ from those planned again" in _refusal(seed)
    design = _previous(whole)
    design["settings"]["design"]["Ts"] = 2e-3
    assert "its settings differ from those planned again from them (design)" in _refusal(design)


def test_a_model_file_changed_since_the_sweep_is_refused(tmp_path: Path) -> None:
    model = tmp_path / "servo.toml"
    shutil.copy(Path(gearctl.__file__).parents[1] / "models" / "shing1993_servo.toml", model)
    part = gearctl.sweep.sweep(str(model), "pid", engine="serial", vary=["backlash=0.5x:2x"], runs=2, duration=0.1)
    prev = as_json(part.as_dict())
    assert set(prev["settings"]["files"]) == {"model", "controller"}
    prev["runs"], prev["missing"] = prev["runs"][:1], [1]
    gearctl.sweep.resume(prev, engine="serial")  # unchanged: resumed
    model.write_text(model.read_text() + "\n# edited\n")
    assert f"the model file {model} changed since the sweep (its SHA-256 differs)" in _refusal(prev)


# --- the command line -------------------------------------------------------------------------------------

def _cli(args: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        rc = main(args)
    return rc, out.getvalue(), err.getvalue()


def test_sweep_resume_on_a_local_cluster_writes_the_whole_sweep(tmp_path: Path,
                                                                whole: gearctl.sweep.SweepResult) -> None:
    prev = _write(tmp_path / "prev.json", _previous(whole))
    rc, out, err = _cli(["sweep", "--resume", str(prev), "--workers", "2", "--quiet", "--json",
                         str(tmp_path / "r.json"), "--out", str(tmp_path / "o")])
    assert rc == 0, err
    data = json.loads((tmp_path / "r.json").read_text())
    _same_sweep(data, whole.as_dict())
    assert data["engine"]["where"] == "local cluster (2 processes)"  # the reruns: 2 runs, 2 processes
    assert data["engine"]["resumed"]["from"] == str(prev) and data["engine"]["resumed"]["reused"] == 4
    assert f"  resumed                from {prev}: 4 runs reused, 2 rerun" in out
    rows = (tmp_path / "o" / "runs.csv").read_text().splitlines()
    assert [int(line.split(",")[0]) for line in rows[1:]] == list(range(6))


@pytest.mark.parametrize(("extra", "named"), [(["--runs", "5"], "--runs"), (["--seed", "0"], "--seed"),
                                              (["shing1993_servo"], "MODEL"), (["--grid"], "--grid"),
                                              (["--vary", "backlash=1x", "--plant", "tvms"], "--vary, --plant")])
def test_sweep_resume_refuses_the_options_that_set_the_runs(tmp_path: Path, whole: gearctl.sweep.SweepResult,
                                                            extra: list[str], named: str) -> None:
    prev = _write(tmp_path / "prev.json", _previous(whole))
    rc, _, err = _cli(["sweep", "--resume", str(prev), *extra, "--quiet"])
    assert rc == 2 and err.startswith(f"gearctl sweep: error: --resume {prev} and {named}: a resumed sweep takes "
                                      f"every setting from the previous sweep's JSON") and err.count("\n") == 1


def test_sweep_resume_of_a_finished_sweep_is_one_line_and_exit_2(tmp_path: Path,
                                                                 whole: gearctl.sweep.SweepResult) -> None:
    prev = _write(tmp_path / "whole.json", as_json(whole.as_dict()))
    rc, out, err = _cli(["sweep", "--resume", str(prev), "--quiet"])
    assert rc == 2 and out == ""
    assert err == (f"gearctl sweep: error: --resume {prev}: the sweep finished (no missing runs: all 6 ran): nothing "
                   f"to resume\n")


def test_a_trains_factors_read_back_from_json_are_factors_again() -> None:
    # a relative spec of a key whose stages differ draws factors of each stage's value (Scale): read back from the
    # JSON they are plain numbers, and the runs.csv column of a resumed sweep must still be `backlash_factor`
    part = gearctl.sweep.sweep("servo_3stage_quanser_srv02", "pid", vary=["backlash=0.5x:2x"], runs=3, duration=0.1,
                               engine="serial")
    prev = as_json(part.as_dict())
    prev["runs"], prev["missing"] = prev["runs"][:1], [1, 2]
    r = gearctl.sweep.resume(prev, engine="serial")
    assert all(isinstance(x["params"]["backlash"], gearctl.sweep.Scale) for x in r.runs)
    assert r.table()[0][2] == "backlash_factor"
    _same_sweep(r.as_dict(), part.as_dict())


def test_a_previous_sweep_too_large_to_read_is_refused_with_the_figure(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, whole: gearctl.sweep.SweepResult) -> None:
    prev = _write(tmp_path / "prev.json", _previous(whole))
    size = prev.stat().st_size
    monkeypatch.setattr(gearctl.sweep, "available_memory", lambda: 4 * size)  # half of it: 2 x the text, < 4 x
    with pytest.raises(gearctl.InputError, match=r"GB of JSON would take about .* GB to read, more than half the "
                                                 r"memory available") as info:
        gearctl.sweep.resume(prev, engine="serial")
    assert info.value.field == "resume"
