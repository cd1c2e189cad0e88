"""``examples/08_train_crossing_trace.py`` on trains with a stage without backlash, and on a model with none (h7's
review: ``--model tests/data/h1_train_b0_mid.toml`` printed ``-inf`` for stage 2's ``s/b`` and wrote ``inf`` and
``nan`` into the CSV with two numpy RuntimeWarnings; a model with no backlash divided by a lost motion of 0)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from support import example_main

DATA = Path(__file__).parent / "data"


def test_a_stage_without_backlash_is_left_out_of_the_trace(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no division by a backlash of 0
        example_main("08_train_crossing_trace")(["--model", str(DATA / "h1_train_b0_mid.toml"), "--duration", "1",
                                                 "--reversal", "1", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert "no backlash on stage 2" in out and "inf" not in out and "nan" not in out
    data = np.genfromtxt(tmp_path / "trace.csv", delimiter=",", names=True)
    assert "s2_over_b" not in data.dtype.names and {"s1_over_b", "s3_over_b"} <= set(data.dtype.names)
    assert all(np.isfinite(data[c]).all() for c in data.dtype.names if c not in ("flank", "crossing"))


def test_a_model_without_backlash_is_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = (DATA / "no_load_encoder.toml").read_text()
    assert "backlash = 5e-5" in src
    model = tmp_path / "tight.toml"
    model.write_text(src.replace("backlash = 5e-5", "backlash = 0.0"))
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exc:
        example_main("08_train_crossing_trace")(["--model", str(model), "--out", str(out)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--model" in err and "backlash" in err and "Traceback" not in err
    assert not out.exists()
