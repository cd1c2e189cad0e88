"""A log made in Python (an EncoderLog, not a file) has its time stamps checked as read_log checks a file's: before,
identify ignored t and ran on sample_time alone, so unsorted, repeated or reversed stamps, t in ms, or a sample_time
that disagrees with t were accepted without a word."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from gearctl import InputError
from gearctl.identify import identify, read_log

LOG = Path(__file__).resolve().parent / "data" / "logs" / "other_sim_chirp_5khz.csv"
MODEL = "shing1993_servo"


def _swap(t: np.ndarray) -> np.ndarray:
    t = t.copy()
    t[[1000, 1001]] = t[[1001, 1000]]
    return t


@pytest.mark.parametrize("change, fragment", [
    (lambda lg: {"t": _swap(lg.t)}, "column t: sample 1001 .* does not increase"),
    (lambda lg: {"t": np.zeros(lg.n)}, "column t: sample 1 .* does not increase"),
    (lambda lg: {"t": lg.t[::-1].copy()}, "column t: sample 1 .* does not increase"),
    (lambda lg: {"t": lg.t * 1000.0}, "column t: its period 0.2 s differs from sample_time"),
    (lambda lg: {"sample_time": lg.sample_time * 2.0}, "column t: its period 0.0002 s differs from sample_time"),
    (lambda lg: {"t": np.concatenate([lg.t[:1000], lg.t[1005:], lg.t[-1] + lg.sample_time * np.arange(1, 6)])},
     "column t: sample 1000 .* is 0.0012 s after the previous sample"),
    (lambda lg: {"t": lg.t + np.where(np.arange(lg.n) >= lg.n // 2, 0.01 * (lg.t - lg.t[lg.n // 2]), 0.0)},
     "column t: sample .* off the grid of sample_time"),
])
def test_time_stamps_of_a_python_log_are_checked(change, fragment) -> None:
    log = read_log(LOG)
    with pytest.raises(InputError, match=fragment) as exc:
        identify(dataclasses.replace(log, **change(log)), MODEL, encoders="motor+load")
    assert exc.value.field == "t"


def test_a_python_log_on_its_grid_is_accepted() -> None:
    log = read_log(LOG)
    t = 12.5 + np.arange(log.n) * log.sample_time  # another clock origin, evenly stamped
    res = identify(dataclasses.replace(log, t=t), MODEL, encoders="motor+load")
    assert res.backlash == pytest.approx(5e-5, rel=0.01)


def test_a_file_whose_clock_changes_rate_is_refused(tmp_path: Path) -> None:
    """Every interval within 1 % of the period (0.5 % short, then 0.5 % long) but the stamps 10 periods off the
    fixed grid: read_log checked the grid only when an interval was more than 1 % off, and read the log as if
    evenly stamped, without a word."""
    lines = LOG.read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("#") or not ln.strip()]
    rows = [ln for ln in lines if ln.strip() and not ln.startswith("#")]
    header, body = rows[0], rows[1:]
    n, Ts = len(body), 2e-4
    dt = np.where(np.arange(n) < n // 2, 0.995 * Ts, 1.005 * Ts)
    t = np.concatenate([[0.0], np.cumsum(dt[:-1])])
    out = head + [header] + [f"{t[k]:.17g}," + row.split(",", 1)[1] for k, row in enumerate(body)]
    (tmp_path / "drift.csv").write_text("\n".join(out) + "\n")
    with pytest.raises(InputError, match=r"drift.csv: line \d+: t = .* off the grid of the log's period") as exc:
        read_log(tmp_path / "drift.csv")
    assert exc.value.field == "t"


def test_a_python_log_of_lists_is_read_and_one_of_text_or_rows_is_refused() -> None:
    # an EncoderLog holding Python lists raised AttributeError ('list' has no attribute 'size'), text TypeError, and
    # identify(log, None) TypeError: lists are read as arrays; the rest is refused naming the column or the model
    log = read_log(LOG)
    listed = dataclasses.replace(log, t=log.t.tolist(), torque=log.torque.tolist(), theta1=log.theta1.tolist(),
                                 theta2=log.theta2.tolist())
    assert identify(listed, MODEL).backlash == identify(log, MODEL).backlash
    with pytest.raises(InputError, match="column torque holds .* not numbers") as exc:
        identify(dataclasses.replace(log, torque=np.array(["x"] * log.n)), MODEL)
    assert exc.value.field == "torque"
    with pytest.raises(InputError, match=r"column theta1 has shape \(\d+, 2\): expected a 1-D array") as exc:
        identify(dataclasses.replace(log, theta1=np.column_stack([log.theta1, log.theta1])), MODEL)
    assert exc.value.field == "theta1"
    with pytest.raises(InputError, match="model = None is not a model") as exc:
        identify(log, None)
    assert exc.value.field == "model"


def test_a_python_log_stamped_by_a_clock_some_ppm_off_is_accepted(tmp_path: Path) -> None:
    """A sample_time within 1 % of the stamps' period is accepted as read_log accepts the same stamps from a file: the
    grid is the stamps' own period. On the grid of sample_time, a clock 300 ppm off (all 2501 stamps evenly spaced)
    drifted 0.37 periods off by the log's end and was refused, while the file of those stamps was identified."""
    log = read_log(LOG)
    t = np.arange(log.n) * log.sample_time * (1 + 3e-4)
    res = identify(dataclasses.replace(log, t=t), MODEL, encoders="motor+load")
    lines = LOG.read_text().splitlines()
    rows = [ln for ln in lines if ln.strip() and not ln.startswith("#")]
    head = [ln for ln in lines if ln.startswith("#")]
    out = head + [rows[0]] + [f"{t[k]:.17g}," + row.split(",", 1)[1] for k, row in enumerate(rows[1:])]
    (tmp_path / "ppm.csv").write_text("\n".join(out) + "\n")
    assert res.backlash == pytest.approx(identify(tmp_path / "ppm.csv", MODEL, encoders="motor+load").backlash,
                                         rel=1e-3)
