"""``gearctl linearize --step``: the step runs over eight periods of the lowest resonance, not the mesh mode's.

On a train the lowest resonance is far below the mesh mode (398 Hz against 18 kHz on the four-stage review
train): eight mesh periods (0.44 ms) showed s1 still rising, not one period of the mode a controller meets.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import gearctl
import gearctl.plots
from gearctl.cli import main

DATA = Path(__file__).parent / "data"


MODELS = ["shing1993_servo", "servo_3stage_quanser_srv02", str(DATA / "h4_train4_review.toml")]


@pytest.mark.parametrize("model", MODELS, ids=lambda m: Path(m).stem)
def test_step_window_covers_the_lowest_resonance(model: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    seen = {}
    real = gearctl.plots.plot_step

    def spy(systems, **kw):  # noqa: ANN001, ANN003, ANN202
        seen.update(kw)
        return real(systems, **kw)

    monkeypatch.setattr(gearctl.plots, "plot_step", spy)
    assert main(["linearize", model, "--step", str(tmp_path / "step.png")]) == 0
    capsys.readouterr()
    modes = gearctl.linearize_modes(gearctl.build_plant(gearctl.load_model(model)))
    T = np.asarray(seen["T"])
    f_lo, f_hi = min(modes.resonances_hz), modes.mesh.natural_frequency_hz
    assert T[-1] == pytest.approx(8 / f_lo, rel=1e-12)
    assert T[-1] / (T.size - 1) <= 1 / (20 * f_hi) or T.size == 20000  # the mesh mode resolved, or the cap
    assert (tmp_path / "step.png").stat().st_size > 0
