"""A loop that hunts at the Nyquist frequency across the gap is no rest on a flank (r4's simulator).

``tests/data/logs/r4/hunting_pd_500hz.csv``: r4's simulator (``r4sim.c``) with the pair and servo of
``shing1993_servo_friction``, b = 10 um, under ``excite``'s identify motion of 0.5 rad; its PD loop at 1 kHz hunts at
500 Hz, s = r_b1 theta1 - r_b2 theta2 alternating +5.5 / -6.5 um from sample to sample while the load's friction holds
it. The travel of s over +-1 sample is blind to that oscillation, and those samples read as rests on the back flank.
"""

from pathlib import Path

import pytest

from gearctl.cli import main
from gearctl.errors import InputError
from gearctl.identify import identify

LOG = Path(__file__).parent / "data" / "logs" / "r4" / "hunting_pd_500hz.csv"


def test_a_loop_hunting_at_nyquist_is_not_read_as_rests() -> None:
    # before: b 7.94 um [7.40, 8.48] for the true 10, unflagged
    with pytest.raises(InputError, match="no rest on the back flank") as exc:
        identify(LOG, "shing1993_servo_friction")
    assert exc.value.field == "theta2"


def test_a_loop_hunting_at_nyquist_cli(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["identify", str(LOG), "--model", "shing1993_servo_friction"]) == 2
    err = capsys.readouterr().err
    assert "no rest on the back flank" in err and "Traceback" not in err
