"""``gearctl bench --plants yang-sun`` without the improved plant (r1's review).

The cross-design cell (each controller designed on the Yang-Sun plant, run on the improved one) was added whenever
``yang-sun`` was asked for, and looked up an improved plant built only when ``improved`` was: ``--plants yang-sun``
ended in a ``KeyError: 'improved'`` traceback before any run.
"""

from __future__ import annotations

import json

import pytest

from gearctl.bench import BenchSpec
from gearctl.cli import main


@pytest.mark.parametrize(("plants", "cross"), [(("yang-sun",), 0), (("improved", "yang-sun"), 1),
                                                (("yang-sun", "tvms"), 0)])
def test_runs_per_plant_set(plants: tuple[str, ...], cross: int) -> None:
    spec = BenchSpec(controllers=("pid",), plants=plants, references=("sine",), duration=0.05, precision=False)
    runs = spec.runs()
    cells = {(r.tags["plant"], r.tags["design"]) for r in runs}
    # one run per asked plant and the backlash-free limit, designed on the improved plant; the cross cell only
    # where its improved plant is asked for too
    assert {p for p, d in cells if d == "improved"} == {*plants, "backlash-free"}
    assert sum(d == "yang-sun" for _, d in cells) == cross
    assert len(runs) == len(plants) + 1 + cross


def test_cli_bench_yang_sun_alone(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["bench", "shing1993_servo", "--controllers", "pid", "--plants", "yang-sun", "--references", "sine",
                 "--no-precision", "--jobs", "1", "--quiet", "--duration", "0.05", "--json", "-"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "Traceback" not in err
    result = json.loads(out)
    assert {r["plant"] for r in result["runs"]} == {"yang-sun", "backlash-free"}
    assert result["ratios"]["cross_design"] == {}


@pytest.mark.parametrize(("argv", "field", "match"), [
    (["--plants", ""], "plants", "none given: expected one or more of improved, yang-sun, tvms"),
    (["--references", ""], "references", "none given: expected one or more of sine"),
    (["--plants", "improved,improved"], "plants", "'improved' given more than once"),
    (["--references", "sine,move,sine"], "references", "'sine' given more than once"),
    (["--controllers", "pid", "pid"], "controllers", "'pid' given more than once"),
])
def test_empty_or_repeated_lists_are_refused(argv: list[str], field: str, match: str,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    # before: an empty list ran nothing (or the backlash-free limit alone) with exit 0; a repeated entry ran every
    # run twice and named the PID its own runner-up
    code = main(["bench", "shing1993_servo", "--no-precision", "--jobs", "1", "--quiet", "--duration", "0.05", *argv])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.startswith("gearctl bench: error: ") and f"{field}: " in err and match in err
    assert "Traceback" not in err and len(err.splitlines()) == 1


def test_repeated_model_is_refused_in_the_api() -> None:
    from gearctl import InputError

    with pytest.raises(InputError, match="models: 'shing1993_servo' given more than once"):
        BenchSpec(models=("shing1993_servo", "shing1993_servo"))
