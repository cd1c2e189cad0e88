"""read_log on logs from loggers gearctl has not seen (h2's review): a logger's many extra channels, rows in reverse
time order, CRLF line ends, and the figures of a log that holds more columns than it needs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gearctl import InputError
from gearctl.cli import main
from gearctl.logs import MAX_EXTRA_COLUMNS, read_log

LOG = Path(__file__).resolve().parent / "data" / "logs" / "other_sim_chirp_5khz.csv"


def _rows(path: Path) -> tuple[str, list[str]]:
    rows = [ln for ln in path.read_text().splitlines() if ln.strip() and not ln.startswith("#")]
    return rows[0], rows[1:]


def test_extra_columns_beyond_the_kept_ones_are_not_read(tmp_path: Path) -> None:
    """A logger's 20 000 channels besides the four: the first MAX_EXTRA_COLUMNS numeric ones are kept, the rest skipped
    unread (before: every one kept, and an n x ncol array of the whole header's width allocated, 8 bytes per comma of
    the file; each column's name was counted across the header, quadratic in its width: 8 s for this log, an 81 MB
    log of 200 000 empty columns ran for more than 10 minutes in 640 MB)."""
    n, named, empty = 600, 40, 20000
    path = tmp_path / "wide.csv"
    with path.open("w") as fh:
        fh.write("t,torque,theta1," + ",".join(f"x{i}" for i in range(named)) + "," * empty + "\n")
        for i in range(n):
            fh.write(f"{i * 1e-3},{0.1 * np.sin(i / 50)},{1e-3 * np.cos(i / 50)}," +
                     ",".join(f"{i + j}" for j in range(named)) + "," * empty + "\n")
    log = read_log(path)
    assert list(log.extra) == [f"x{i}" for i in range(MAX_EXTRA_COLUMNS)]
    np.testing.assert_array_equal(log.extra["x3"], np.arange(n) + 3.0)
    np.testing.assert_allclose(log.theta1, 1e-3 * np.cos(np.arange(n) / 50), rtol=1e-12)


def test_a_log_in_reverse_time_order_is_named_so(tmp_path: Path) -> None:
    """Rows written newest first: the refusal said 'a clock printed with too few digits repeats values'."""
    header, body = _rows(LOG)
    path = tmp_path / "reversed.csv"
    path.write_text("\n".join([header, *reversed(body)]) + "\n")
    with pytest.raises(InputError, match="rows run backwards in time.*sort the log by t") as exc:
        read_log(path)
    assert exc.value.field == "t"
    assert "too few digits" not in str(exc.value)


def test_crlf_line_ends_read_as_lf(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    header, body = _rows(LOG)
    path = tmp_path / "crlf.csv"
    path.write_bytes(("\r\n".join([header, *body]) + "\r\n").encode())
    a, b = read_log(LOG), read_log(path)
    np.testing.assert_array_equal(a.theta1, b.theta1)
    np.testing.assert_array_equal(a.torque, b.torque)
    assert main(["identify", str(path), "--model", "shing1993_servo", "--json"]) == 0


def test_a_decimal_comma_is_named(tmp_path: Path) -> None:
    """A spreadsheet's semicolon file with decimal commas: refused (README), but the message asked whether the first
    row was a units row."""
    header, body = _rows(LOG)
    path = tmp_path / "comma.csv"
    path.write_text("\n".join([header.replace(",", ";"), *(r.replace(",", ";").replace(".", ",") for r in body)]))
    with pytest.raises(InputError, match="line 2: column theta1 = '0,75.*' is not a number: a decimal comma\\? "
                                         "numbers take a decimal point") as exc:
        read_log(path)
    assert "units row" not in str(exc.value)
