"""A first-time user's session, from the README alone: the commands and examples as typed, and the mistakes a
newcomer makes (found by running them in a fresh virtual environment).

- ``python examples/02_simulator_benchmark.py --help`` ran the whole benchmark (about a minute of runs) and printed
  its figures instead of a usage line; any other argument was ignored the same way.
"""

from __future__ import annotations

import pytest
from support import example_main


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
