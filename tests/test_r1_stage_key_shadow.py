"""An every-stage key beside ``stageN.`` keys that cover every stage (r1's review).

``stageN.KEY`` applies after ``KEY`` (README, *track*), so where the stage keys name every stage (a pair's
``stage1.backlash``) the every-stage value was dropped without a word: ``track shing1993_servo pid --set
stage1.backlash=3e-5 --set backlash=1e-5`` ran with 3e-5. It is refused, as a backlash ``--set`` beside
``--backlash`` is; a stage key on some stages only still leaves the others the every-stage value.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from gearctl import InputError, load_model
from gearctl.cli import main
from gearctl.overrides import Scale, perturb_model

TRAIN = str(Path(__file__).parent / "data" / "r1_pom_train_m04.toml")


def test_pair_stage1_key_beside_the_plain_key_is_refused() -> None:
    model = load_model("shing1993_servo")
    with pytest.raises(InputError, match=r"backlash and stage1\.backlash: .* backlash would change nothing"):
        perturb_model(model, {"stage1.backlash": 3e-5, "backlash": 1e-5})
    with pytest.raises(InputError, match=r"face_width and stage1\.face_width"):
        perturb_model(model, {"face_width": Scale(1.2), "stage1.face_width": 0.011})


def test_train_every_stage_covered_is_refused_partly_covered_is_kept() -> None:
    model = load_model(TRAIN)
    with pytest.raises(InputError, match=r"stage1\.backlash, stage2\.backlash"):
        perturb_model(model, {"backlash": 3e-5, "stage1.backlash": 1e-5, "stage2.backlash": 2e-5})
    out = perturb_model(model, {"backlash": 3e-5, "stage1.backlash": 1e-5})
    assert [sm.pair.backlash for sm in out.stages] == [1e-5, 3e-5]


def test_cli_track_refuses(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["track", "shing1993_servo", "pid", "--duration", "0.05", "--set", "stage1.backlash=3e-5",
                 "--set", "backlash=1e-5"])
    _, err = capsys.readouterr()
    assert code == 2
    assert err.startswith("gearctl track: error: backlash and stage1.backlash") and len(err.splitlines()) == 1


@pytest.mark.parametrize("cmd", [["track", "--duration", "0.05"], ["precision", "--cycles", "1", "--targets", "2"]])
@pytest.mark.parametrize("key", ["backlash", "stage1.backlash"])
def test_cli_set_key_twice_is_refused(cmd: list[str], key: str, capsys: pytest.CaptureFixture[str]) -> None:
    # before: the last value won and the first was dropped without a word (sweep's --vary refused it already)
    code = main([cmd[0], "shing1993_servo", "pid", *cmd[1:], "--set", f"{key}=3e-5", "--set", f"{key}=1e-5"])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err == f"gearctl {cmd[0]}: error: --set {key} is given twice: give each key once\n"
