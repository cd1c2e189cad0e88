"""`gearctl precision`: every ISO 230-2 figure the text prints is the --json one (E, the systematic deviation, was in
the JSON only), and the JSON's figures follow the standard's definitions from its own per-target deviations."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from gearctl.cli import main

MODEL = str(Path(__file__).resolve().parent / "data" / "controller_files" / "rack_axis_20x200.toml")
ARGV = ["precision", MODEL, "pid", "--targets", "3", "--cycles", "2", "--travel", "0.2", "--dwell", "0.2"]


def test_text_figures_are_the_json_ones_and_follow_iso_230_2(capsys) -> None:  # noqa: ANN001
    assert main(ARGV) == 0
    text = capsys.readouterr().out
    assert main([*ARGV, "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    labels = {"reversal value B": "reversal_value", "repeatability R": "repeatability", "accuracy A": "accuracy",
              "mean bidirectional M": "mean_bidirectional_deviation", "systematic E": "systematic_deviation"}
    for label, key in labels.items():
        m = re.search(rf"^  {label}\s+([-0-9.e+]+) urad", text, re.M)
        assert m, f"{label} not printed"
        assert float(m.group(1)) == float(f"{d[key] * 1e6:.4g}")
    up = np.array([p["deviations_up"] for p in d["per_target"]])
    down = np.array([p["deviations_down"] for p in d["per_target"]])
    mu, md = up.mean(1), down.mean(1)
    su, sd = up.std(1, ddof=1), down.std(1, ddof=1)
    B = mu - md
    assert np.isclose(d["reversal_value"], np.abs(B).max(), rtol=1e-12)
    assert np.isclose(d["repeatability"], np.maximum(2 * su + 2 * sd + np.abs(B), 4 * np.maximum(su, sd)).max(),
                      rtol=1e-12)
    assert np.isclose(d["mean_bidirectional_deviation"], np.ptp((mu + md) / 2), rtol=1e-12)
    assert np.isclose(d["systematic_deviation"], max(mu.max(), md.max()) - min(mu.min(), md.min()), rtol=1e-12)
    assert np.isclose(d["accuracy"], max((mu + 2 * su).max(), (md + 2 * sd).max())
                      - min((mu - 2 * su).min(), (md - 2 * sd).min()), rtol=1e-12)
