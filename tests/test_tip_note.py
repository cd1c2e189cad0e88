"""``info`` notes a tooth tip thinner than ISO's usual 0.2 modules (r1's review: a 13-tooth pinion with x1 = 0.9 had
0.059 m and went through without a word; the model itself is defined down to a pointed tip, which is refused)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from gearctl import load_model
from gearctl.cli import main
from gearctl.summary import TIP_THICKNESS_MIN, model_summary

MODEL = """[source]
citation = "test: a 13-tooth pinion with a large profile shift"
[gear1]
teeth = 13
profile_shift = {x1}
[gear2]
teeth = 47
profile_shift = -0.25
[pair]
module = 0.0015
pressure_angle_deg = 20.0
face_width = 0.012
backlash = 3e-5
[material]
young_modulus = 2.06e11
poisson_ratio = 0.3
density = 7850.0
[dynamics]
damping_ratio = 0.05
"""


def _tip(alpha: float, x: float, z: int, ra: float) -> float:
    """Tooth thickness at the tip radius ``ra`` [modules] in modules, from the involute closed form (DIN 3960)."""
    inv = lambda a: math.tan(a) - a  # noqa: E731
    r, rb = z / 2, z / 2 * math.cos(alpha)
    s = math.pi / 2 + 2 * x * math.tan(alpha)
    aa = math.acos(rb / ra)
    return 2 * ra * (s / (2 * r) + inv(alpha) - inv(aa))


@pytest.mark.parametrize(("x1", "noted"), [(0.9, True), (0.6, False)])
def test_thin_tip_is_noted(tmp_path: Path, capsys: pytest.CaptureFixture[str], x1: float, noted: bool) -> None:
    path = tmp_path / "pinion.toml"
    path.write_text(MODEL.format(x1=x1))
    summary = model_summary(load_model(path))
    # at the tip radius gearctl computes (with the tip shortening of a shifted pair): 0.059 at x1 = 0.9, 0.37 at 0.6
    s_a = _tip(math.radians(20.0), x1, 13, summary["addendum_radius"][0] / 0.0015)
    assert (s_a < TIP_THICKNESS_MIN) is noted
    note = summary["tip_note"]
    assert (note is not None) is noted
    assert main(["info", str(path)]) == 0
    err = capsys.readouterr().err
    assert ("gearctl info: note: gear 1's tooth tip is" in err) is noted
    if noted:
        assert f"{s_a:.3g} modules" in note, note


def test_catalog_tips_are_not_noted() -> None:
    from gearctl.catalog import model_names

    for name in model_names():
        s = model_summary(load_model(name))
        assert all(st["tip_note"] is None for st in (s["stages"] if s["stages_count"] > 1 else [s])), name
