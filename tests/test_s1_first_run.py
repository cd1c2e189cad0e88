"""A first-time user's session, from the README alone: the commands and examples as typed, and the mistakes a
newcomer makes (found by running them in a fresh virtual environment).

- ``python examples/02_simulator_benchmark.py --help`` ran the whole benchmark (about a minute of runs) and printed
  its figures instead of a usage line; any other argument was ignored the same way.
- A controller where a model goes: ``gearctl track pid`` said which is which, but ``gearctl info pid`` (and
  ``stiffness``, ``simulate``, ``linearize``, ``bench``, ``identify --model``) said only "unknown model 'pid':
  expected a catalog name (...)", and ``gearctl info controllers/pid.toml`` "key kind = 'pid' outside any
  section"; ``gearctl info shing1993_servo.toml`` (the catalog name with the file's suffix, in a folder without
  it) said "does not exist" without pointing at the catalog entry. In Python, a model file given to
  ``load_controller`` was "missing key kind".
- A unit typed with a value (``--duration 10s``, ``--backlash 50um``) was "'10s' is not a number", and a misspelt
  choice (``gearctl trak``, ``--reference sin``, ``--plant yangsun``) listed the choices without the one meant;
  ``--travel 5deg`` was not told the radians, ``sweep --vary backlash=0.5x-2x`` not that a range is ``LOW:HIGH``.
- ``examples/06_tolerance_study.py`` made its own ``LocalCluster`` with Dask's default logging: on a loaded
  machine a worker's "Failed to communicate with scheduler during heartbeat" and a 30-line traceback came after
  the results; ``--scheduler tcp://HOST:8786`` (its docstring's example) waited Dask's 30 s connect timeout and
  ended in an ``OSError`` traceback. It now opens gearctl's :class:`~gearctl.parallel.Engine`, as ``gearctl
  sweep`` does: quiet workers, and a scheduler that does not answer is one usage line at once.
- ``examples/03_bode_step_margins.py --model MODEL`` (the README's "another pair or a train") with a misspelt
  name, or a controller's, ended in an ``InputError`` traceback (exit 1).
- ``examples/05_benchmark_report.py`` (36 s) and ``06_tolerance_study.py`` (30 s) showed nothing on a terminal
  until they ended; they now show a progress bar there (none in a pipe), as ``gearctl bench`` and ``sweep`` do.
- ``--help`` of examples 03, 04, 07 and 08 listed ``--out OUT`` with no words: not where the figures go by default.
"""

from __future__ import annotations

import io
import logging
import re
import sys
import time
from pathlib import Path

import pytest
from support import example_main

import gearctl
from gearctl.cli import main as cli_main

REPO = Path(__file__).resolve().parents[1]


def _no_runs(*args: object, **kwargs: object) -> None:
    raise AssertionError("the benchmark ran")


def test_simulator_benchmark_help_runs_nothing(monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr("gearctl.perf.sim_speed", _no_runs)  # (the example binds it when loaded, below)
    main = example_main("02_simulator_benchmark")
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.startswith("usage: ")


def test_simulator_benchmark_refuses_an_unknown_argument(monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr("gearctl.perf.sim_speed", _no_runs)
    main = example_main("02_simulator_benchmark")
    with pytest.raises(SystemExit) as exc:
        main(["--out", "out/perf"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "unrecognized arguments: --out" in err and "Traceback" not in err


@pytest.mark.parametrize("argv", [
    ["info", "pid"],
    ["stiffness", "deadzone_inverse"],
    ["simulate", "mpc", "--duration", "0.001"],
    ["linearize", "pid_load"],
    ["bench", "pid", "--quiet"],
])
def test_a_controller_name_where_a_model_goes_is_named(argv: list[str], tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    name = argv[1]
    assert cli_main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"'{name}' is a controller, not a model" in err, err


def test_a_controller_file_where_a_model_goes_is_named(capsys: pytest.CaptureFixture[str]) -> None:
    path = REPO / "controllers" / "pid.toml"
    assert cli_main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "a controller file (kind = 'pid'), not a model" in err, err


def test_a_model_file_given_as_a_controller_is_named() -> None:
    plant = gearctl.build_plant(gearctl.load_model("shing1993_servo"))
    with pytest.raises(gearctl.InputError, match="a model file .*not a controller"):
        gearctl.load_controller(REPO / "models" / "shing1993_servo.toml", plant)
    with pytest.raises(gearctl.InputError, match="'shing1993_servo' is a model, not a controller"):
        gearctl.load_controller("shing1993_servo", plant)


def test_a_catalog_name_typed_as_a_file_points_at_the_entry(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    assert cli_main(["info", "shing1993_servo.toml"]) == 2
    err = capsys.readouterr().err
    assert "'shing1993_servo.toml' does not exist" in err and "did you mean the catalog name shing1993_servo" in err
    assert cli_main(["info", "nonesuch.toml"]) == 2  # no hint where there is no such entry
    assert "did you mean" not in capsys.readouterr().err


@pytest.mark.parametrize(("argv", "said"), [
    (["track", "shing1993_servo", "pid", "--duration", "10s"],
     "'10s' is not a number: give the value in s (SI) as a plain number, without the unit (10)"),
    (["simulate", "shing1993", "--duration", "0.01sec"], "in s (SI) as a plain number, without the unit (0.01)"),
    # another unit than the one expected: no number offered (10 ms is not 10 s)
    (["track", "shing1993_servo", "pid", "--duration", "10ms"], "in s (SI) as a plain number, without the unit (usage"),
    (["track", "shing1993_servo", "pid", "--backlash", "50um"], "in m (SI) as a plain number, without the unit (usage"),
    (["precision", "shing1993_servo_friction", "pid", "--dwell", "0.3s"], "without the unit (0.3)"),
    (["simulate", "shing1993", "--dt", "1e-6s"], "without the unit (1e-6)"),
    # a negative value with a unit was taken for an option: "argument --duration: expected one argument"
    (["track", "shing1993_servo", "pid", "--duration", "-3s"], "'-3s' is not a number: give the value in s"),
    (["simulate", "shing1993", "--omega1", "-50rad/s"], "without the unit (-50)"),
    (["precision", "shing1993_servo_friction", "pid", "--travel", "5deg"],
     "in rad (SI) as a plain number, without the unit (5 deg = 0.0872665 rad)"),
    (["sweep", "shing1993_servo", "pid", "--vary", "backlash=0.5x-2x"], "; a range is LOW:HIGH (0.5x:2x)"),
    (["sweep", "shing1993_servo", "pid", "--vary", "backlash=2e-5-1e-4"], "; a range is LOW:HIGH (2e-5:1e-4)"),
    (["precision", "shing1993_servo_friction", "pid", "--targets", "5x"], "give the number alone, without 'x'"),
    (["trak"], "invalid choice: 'trak' (choose from "),
    (["track", "shing1993_servo", "pid", "--reference", "sin"], "; did you mean 'sine'?"),
    (["track", "shing1993_servo", "pid", "--plant", "yangsun"], "; did you mean 'yang-sun'?"),
    (["linearize", "shing1993_servo", "--mode", "sep"], "; did you mean 'separation'?"),
])
def test_first_timer_typos_are_told_the_fix(argv: list[str], said: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert said in err, err
    if argv == ["trak"]:
        assert "did you mean 'track'?" in err


def test_a_word_that_is_no_number_is_not_told_of_units(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(["track", "shing1993_servo", "pid", "--duration", "ten"]) == 2
    err = capsys.readouterr().err
    assert "'ten' is not a number (usage" in err
    assert cli_main(["track", "shing1993_servo", "pid", "--plant", "xyz"]) == 2  # nothing close: no suggestion
    assert "did you mean" not in capsys.readouterr().err


def test_tolerance_study_unreachable_scheduler_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    t0 = time.perf_counter()
    with pytest.raises(SystemExit) as exc:
        example_main("06_tolerance_study")(["--scheduler", "tcp://127.0.0.1:1", "--points", "2", "--out", str(out)])
    assert exc.value.code == 2 and time.perf_counter() - t0 < 20  # (Dask's own connect waited 30 s)
    err = capsys.readouterr().err
    assert "error: cannot reach the Dask scheduler at tcp://127.0.0.1:1" in err and "Traceback" not in err
    assert not out.exists()


class _Started(Exception):
    pass


def test_tolerance_study_local_cluster_keeps_worker_logs_quiet(tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    seen: dict[str, object] = {}

    def cluster(*args: object, **kwargs: object) -> None:
        seen.update(kwargs)
        raise _Started

    monkeypatch.setattr("distributed.LocalCluster", cluster)
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    with pytest.raises(_Started):
        example_main("06_tolerance_study")(["--workers", "1", "--points", "2", "--out", str(tmp_path / "out")])
    # Dask's default (WARN) let a closing worker's heartbeat error and its traceback through
    assert isinstance(seen.get("silence_logs"), int) and seen["silence_logs"] >= logging.CRITICAL


@pytest.mark.parametrize("name", ["shing1993_srvo", "pid"])
def test_bode_example_bad_model_is_a_usage_error(name: str, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exc:
        example_main("03_bode_step_margins")(["--model", name, "--out", str(out)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"error: --model {name}: unknown model '{name}'" in err and "Traceback" not in err
    assert not out.exists()


_EXAMPLES = sorted(p.stem for p in (REPO / "examples").glob("[0-9][0-9]_*.py"))


@pytest.mark.parametrize("name", _EXAMPLES)
def test_example_help_describes_every_option(name: str, monkeypatch: pytest.MonkeyPatch,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr("gearctl.perf.sim_speed", _no_runs)  # (02 binds it when loaded)
    main = example_main(name)
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    options = text.split("options:", 1)[1]
    # each option's entry: its flags, then words (on the same line or the next, indented further)
    entries = re.findall(r"^  (-[^\n]*?)(?:  +(\S[^\n]*))?\n((?:   +\S[^\n]*\n)*)", options, flags=re.MULTILINE)
    assert entries, text
    for flags, same_line, following in entries:
        assert same_line or following.strip(), f"{name}: {flags.strip()} has no description:\n{text}"
    if "--out" in options:
        default = re.search(r"--out OUT\s+(.*?)(?=\n  -|\Z)", options, flags=re.DOTALL)
        assert default and "(default" in default.group(1), f"{name}: --out does not say its default:\n{text}"


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize("terminal", [True, False])
def test_benchmark_report_example_shows_progress_on_a_terminal_only(terminal: bool, tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    err = _Terminal() if terminal else io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    monkeypatch.setattr("tqdm.std.tqdm.monitor_interval", 0)  # (no monitor thread left running)
    example_main("05_benchmark_report")(["--out", str(tmp_path), "--duration", "0.05"])
    text = err.getvalue()
    if terminal:
        assert re.search(r"bench: +\d+%\|", text), text[-500:]
    else:
        assert text == ""
    # the report itself (one run of the example serves both checks: it is the suite's slowest example)
    report = (tmp_path / "report.md").read_text()
    assert "| controller |" in report and "backlash-free" in report
    assert (tmp_path / "rms_by_controller.png").stat().st_size > 0


class _Engine:
    client = None

    def __init__(self, **kwargs: object) -> None:
        pass

    def __enter__(self) -> _Engine:
        return self

    def __exit__(self, *exc: object) -> None:
        pass


def test_tolerance_study_example_shows_progress_on_a_terminal(tmp_path: Path,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    err = _Terminal()
    monkeypatch.setattr(sys, "stderr", err)
    monkeypatch.setattr("tqdm.std.tqdm.monitor_interval", 0)
    main = example_main("06_tolerance_study")
    calls: list[str] = []

    def sweep(model: str, name: str, *, progress: object = None, **kwargs: object) -> None:
        calls.append(name)
        assert callable(progress), "the sweep is given no progress callback"
        time.sleep(0.15)  # (tqdm draws an update 0.1 s after the last drawing at the earliest)
        progress(1, 2)
        raise _Started  # (enough: the bar has been drawn)

    monkeypatch.setitem(main.__globals__, "sweep", sweep)
    monkeypatch.setitem(main.__globals__, "Engine", _Engine)
    with pytest.raises(_Started):
        main(["--points", "2", "--out", str(tmp_path / "out")])
    assert calls == ["pid"] and re.search(r"pid: +50%\|", err.getvalue()), err.getvalue()[-300:]
