"""The keys of a sweep's JSON runs are the ones the README's sweep section names.

An outsider reading the README against `gearctl sweep --json` found keys it did not name (a run's `estimate`,
and with `--precision` its ISO 230-2 figures, `precision_message` and `precision_command`). The track metrics and
health flags, named there as a group, are :data:`gearctl.sweep.METRICS` and :data:`gearctl.sweep.FLAGS`.
"""

from __future__ import annotations

import re
from pathlib import Path

from gearctl.sweep import FLAGS, METRICS, sweep

README = Path(__file__).resolve().parents[1] / "README.md"


def _json_bullet() -> str:
    text = README.read_text()
    section = text[text.index("## Robustness sweeps"):text.index("## Gear trains")]
    start = section.index("- `--json FILE`:")
    return section[start:section.index("\n- ", start + 1)]


def test_every_run_key_is_named_in_the_readme() -> None:
    named = set(re.findall(r"`([a-z_]+)`", _json_bullet())) | set(METRICS) | set(FLAGS)
    iso = sweep("shing1993_servo", "pid", vary=["backlash=1x"], runs=1, duration=0.2, engine="serial", precision=True)
    runs = [*sweep("shing1993_servo", "deadzone_inverse", vary=["estimate_error=-0.1,0.1"], runs=2, grid=True,
                   duration=0.2, engine="serial").runs, *iso.runs]
    keys = set().union(*runs)
    assert {"estimate", "precision_command", "reversal_value"} <= keys  # the cases the sweeps above exercise
    assert keys - named == set()
    # the summary has the ISO figures the terminal prints (it printed them; the JSON had none)
    for k in ("reversal_value", "repeatability", "accuracy"):
        assert iso.summary[k]["median"] == iso.summary[k]["max"] == iso.runs[0][k] > 0
        assert f"`{k}`" in _json_bullet()
