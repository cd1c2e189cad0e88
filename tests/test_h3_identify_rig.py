"""What a test engineer feeding rig logs to ``gearctl identify`` met (helper h3, second round).

Oracles: the user's model file and what ``--write-model`` writes from it (keys the user gave come back as given);
the refusal of a log whose units are off by 1000x names the column and the likely cause.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from gearctl import load_model
from gearctl.cli import main

DATA = Path(__file__).resolve().parent / "data" / "logs"
CHIRP = DATA / "other_sim_chirp_5khz.csv"  # another simulator's log of shing1993_servo_friction, b = 50 um
MODELS = Path(__file__).resolve().parents[1] / "models"


def _user_model(tmp_path: Path) -> Path:
    """shing1993_servo_friction as a user keeps it: with a url and a doi in its [source]."""
    text = (MODELS / "shing1993_servo_friction.toml").read_text()
    text = text.replace("[source]\n", '[source]\nurl = "https://rig.example/servo-a"\ndoi = "10.1000/rig.42"\n', 1)
    path = tmp_path / "rig.toml"
    path.write_text(text)
    return path


def test_write_model_keeps_the_sources_url_and_doi(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the written [source] kept citation, table and notes, and dropped the user's url and doi
    model = _user_model(tmp_path)
    out = tmp_path / "out.toml"
    assert main(["identify", str(CHIRP), "--model", str(model), "--write-model", str(out)]) == 0
    src = tomllib.loads(out.read_text())["source"]
    assert src["url"] == "https://rig.example/servo-a"
    assert src["doi"] == "10.1000/rig.42"
    assert str(CHIRP) in src["citation"]
    assert load_model(out).source["doi"] == "10.1000/rig.42"  # a model gearctl reads
    capsys.readouterr()
