"""``ContactModes.mode`` takes the names ``gearctl linearize --mode`` takes, stageK included."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import gearctl
from gearctl import InputError

DATA = Path(__file__).parent / "data"


def test_stage_names_give_the_stage_separated_models() -> None:
    modes = gearctl.linearize_modes(gearctl.build_plant(gearctl.load_model(DATA / "h4_train4_review.toml")))
    for k in range(1, 5):
        sys_ = modes.mode(f"stage{k}")
        assert sys_ is modes.stage_separated[k - 1]
        # stage k separated: the motor torque does not reach the load, and force k is identically zero
        assert np.allclose(sys_[1, 0](1j * np.logspace(0, 5, 7)), 0.0)
        assert not np.any(sys_.C[list(sys_.output_labels).index(f"force{k}")])
    for name in ("contact", "separation", "rigid"):
        assert modes.mode(name) is getattr(modes, name)


@pytest.mark.parametrize("name,match", [("stage5", r"needs 1 <= K <= 4"), ("stage0", r"needs 1 <= K <= 4"),
                                        ("stagex", r"needs 1 <= K <= 4"),
                                        ("front", r"expected contact, separation or rigid, or stage1 to stage4")])
def test_bad_names_on_a_train(name: str, match: str) -> None:
    modes = gearctl.linearize_modes(gearctl.build_plant(gearctl.load_model(DATA / "h4_train4_review.toml")))
    with pytest.raises(InputError, match=match) as err:
        modes.mode(name)
    assert err.value.field == "mode"


def test_stage_names_on_a_pair_and_on_a_stage_without_backlash() -> None:
    pair = gearctl.linearize_modes(gearctl.build_plant(gearctl.load_model("shing1993_servo")))
    with pytest.raises(InputError, match=r"needs a train; this plant is a pair"):
        pair.mode("stage1")
    b0 = gearctl.linearize_modes(gearctl.build_plant(gearctl.load_model(DATA / "h1_train_b0_mid.toml")))
    with pytest.raises(InputError, match=r"stage 2 has no backlash"):
        b0.mode("stage2")
    assert b0.mode("stage3") is b0.stage_separated[2]
