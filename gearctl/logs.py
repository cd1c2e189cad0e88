"""Servo logs: the encoder log format that :func:`gearctl.identify.identify` reads and ``gearctl excite`` writes.

A servo log is what a drive or a data logger exports (:func:`read_log`, :func:`write_log`): CSV, optional
``#`` comment lines, a header row, then one row per sample at a fixed period with the columns

- ``t`` [s], at a fixed period: evenly spaced, or stamped with a clock that jitters by less than
  :data:`JITTER_TOLERANCE` of the period around a fixed grid (read as that grid, with a warning);
- ``torque`` [N m], the motor torque command, held from its sample to the next (zero-order hold);
- ``theta1`` [rad], the motor encoder's reading (quantised, noisy, any zero);
- ``theta2`` [rad], the load encoder's reading, optional;

any other column is kept and ignored. A bad log is one :class:`~gearctl.errors.InputError` naming the file
and the line or the column; a log above :data:`MAX_LOG_BYTES` or :data:`MAX_LOG_SAMPLES` is refused with
its size, so the memory a run takes is bounded (about 30 float arrays of the log's length).
"""

from __future__ import annotations

import collections
import csv
import dataclasses
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .errors import InputError
from .units import SAMPLE_TIME

__all__ = ["EncoderLog", "read_log", "write_log", "sample_period", "MAX_LOG_BYTES", "MAX_LOG_SAMPLES",
           "MIN_LOG_SAMPLES", "MAX_EXTRA_COLUMNS", "PERIOD_TOLERANCE", "JITTER_TOLERANCE", "REQUIRED_COLUMNS",
           "OPTIONAL_COLUMNS"]

#: Largest log file read [bytes] (a 1 kHz log of 17 min with five columns is about 60 MB).
MAX_LOG_BYTES = 100_000_000
#: Most samples a log may hold (1000 s at 1 kHz; the estimate then holds about 250 MB of arrays).
MAX_LOG_SAMPLES = 1_000_000
#: Fewest samples a log must hold (0.5 s at 1 kHz).
MIN_LOG_SAMPLES = 500
#: Other columns read, the first ones in the header (named once each); of these :attr:`EncoderLog.extra` keeps those
#: that hold numbers throughout (a text column among them takes a place: a later numeric one is not read). Any
#: further column is skipped unread, so a logger's hundreds of channels cost neither memory nor time (a 81 MB log of
#: 200 000 empty columns held a 640 MB array and ran for more than 10 minutes).
MAX_EXTRA_COLUMNS = 16
#: Samples are evenly spaced when each interval is within this fraction of the period.
PERIOD_TOLERANCE = 0.01
#: Time stamps that jitter are read as the fixed period's grid while each lies within this fraction of the period
#: of it (a logger that stamps a drive's samples with its own clock); a missing or doubled sample is refused.
JITTER_TOLERANCE = 0.25
#: The columns of a log: required, then optional.
REQUIRED_COLUMNS = ("t", "torque", "theta1")
OPTIONAL_COLUMNS = ("theta2",)


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class EncoderLog:
    """A servo log: torque command and encoder readings at a fixed period.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Sample times [s], evenly spaced.
    torque : ndarray, shape (n,)
        Motor torque command [N m], held from each sample to the next (zero-order hold).
    theta1 : ndarray, shape (n,)
        Motor encoder reading [rad] (quantised, noisy; any zero).
    theta2 : ndarray or None, shape (n,)
        Load encoder reading [rad], or None without a load encoder.
    extra : mapping
        Other columns, by name (ignored by the identification): those of the first :data:`MAX_EXTRA_COLUMNS` other
        columns of the header that hold numbers throughout.
    sample_time : float
        The period [s].
    comments : tuple of str
        The ``#`` lines before the header, without the ``#``.
    path : Path or None
        The file read.
    jitter : tuple of float
        RMS and largest distance of the time stamps from the fixed period's grid [s] (zeros when the samples are
        evenly spaced within :data:`PERIOD_TOLERANCE`).
    """

    t: NDArray[np.float64]
    torque: NDArray[np.float64]
    theta1: NDArray[np.float64]
    theta2: NDArray[np.float64] | None = None
    extra: Mapping[str, NDArray[np.float64]] = dataclasses.field(default_factory=dict)
    sample_time: float
    comments: tuple[str, ...] = ()
    path: Path | None = None
    jitter: tuple[float, float] = (0.0, 0.0)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.size)

    @property
    def name(self) -> str:
        """The file's name (or ``<log>``)."""
        return str(self.path) if self.path is not None else "<log>"

    @property
    def columns(self) -> list[str]:
        """The column names as :func:`write_log` writes them: ``t, torque, theta1[, theta2]`` and the extra ones."""
        return ["t", "torque", "theta1"] + (["theta2"] if self.theta2 is not None else []) + list(self.extra)


def _fail(path: Path, where: str, what: str, field: str | None = None) -> InputError:
    return InputError(f"{path}: {where}: {what}" if where else f"{path}: {what}", field=field)


def _is_number(field: str) -> bool:
    """Whether a CSV field reads as a number (as :func:`read_log` reads one)."""
    try:
        float(field)
    except ValueError:
        return False
    return "_" not in field


def read_log(path: str | Path, *, load_encoder: bool = True) -> EncoderLog:
    """Read a servo log (CSV, see :class:`EncoderLog`), checking every line.

    The file may start with a UTF-8 byte-order mark and ``#`` comment lines; then a header row naming the
    columns; then one row per sample. A ``#`` line or a blank line among the samples is skipped (a logger's
    note); error messages give the file's own line numbers. The period is fitted over the whole log
    (:func:`sample_period`). Columns ``t`` [s], ``torque`` [N m], ``theta1`` [rad] are required, ``theta2`` [rad] is
    optional; any other column is ignored (kept in :attr:`EncoderLog.extra` if it holds numbers throughout and is one
    of the first :data:`MAX_EXTRA_COLUMNS` others; the rest are not read).
    Fields may be quoted; a header with semicolons or tabs and no comma sets that delimiter.

    Parameters
    ----------
    path : str or Path
        The file.
    load_encoder : bool
        Read ``theta2``; False (``identify --encoders motor``) ignores the column, whatever it holds.

    Returns
    -------
    EncoderLog

    Raises
    ------
    InputError
        One line naming the file and the line or column: unreadable, binary or non-UTF-8, larger than
        :data:`MAX_LOG_BYTES` or :data:`MAX_LOG_SAMPLES`, no header, a missing or repeated column, a row
        with the wrong number of fields, a value that is not a finite number, time that does not increase,
        time stamps that stray from a fixed period's grid by more than :data:`JITTER_TOLERANCE` of the period
        (named at a missing or doubled sample, an interval off the period by more than twice that, where there
        is one), fewer than :data:`MIN_LOG_SAMPLES` samples.
    """
    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise InputError(f"{path}: cannot be read: {exc.strerror}", field="log") from None
    if path.is_dir():
        raise InputError(f"{path}: is a folder, not a log file", field="log")
    if size > MAX_LOG_BYTES:
        raise InputError(f"{path}: {size:,} bytes is too large for a log (at most {MAX_LOG_BYTES:,} bytes, about "
                         f"{MAX_LOG_SAMPLES:,} samples): cut the log to the part with the reversals", field="log")
    try:
        with path.open("rb") as fh:  # bounded: a pipe or a device has no size to check beforehand
            raw = fh.read(MAX_LOG_BYTES + 1)
    except OSError as exc:
        raise InputError(f"{path}: cannot be read: {exc.strerror}", field="log") from None
    if len(raw) > MAX_LOG_BYTES:
        raise InputError(f"{path}: more than {MAX_LOG_BYTES:,} bytes is too large for a log (about "
                         f"{MAX_LOG_SAMPLES:,} samples): cut the log to the part with the reversals", field="log")
    if b"\0" in raw:
        line = raw[: raw.index(b"\0")].count(b"\n") + 1
        raise _fail(path, f"line {line}", "is binary (a NUL byte), not CSV text", "log")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise _fail(path, f"line {line}", f"is not UTF-8 text (byte {exc.start}): expected a CSV log", "log") from None
    del raw
    if text.startswith("\ufeff"):  # a byte-order mark (a spreadsheet's "CSV UTF-8")
        text = text[1:]
    lines = text.splitlines()
    del text
    comments: list[str] = []
    i = 0
    while i < len(lines) and (lines[i].lstrip().startswith("#") or not lines[i].strip()):
        if lines[i].lstrip().startswith("#"):
            comments.append(lines[i].lstrip()[1:].strip())
        i += 1
    if i == len(lines):
        raise _fail(path, "", "has no header row: expected a line naming the columns t, torque, theta1[, theta2]",
                    "log")
    header_line = i + 1
    head = lines[i]
    # a comma-separated log; a header without a comma but with semicolons or tabs sets that delimiter
    delim = "," if "," in head else (";" if ";" in head else ("\t" if "\t" in head else ","))
    try:
        names = [c.strip() for c in next(csv.reader([head], delimiter=delim))]
    except csv.Error as exc:
        raise _fail(path, f"line {header_line}", f"is not a CSV header ({exc})", "log") from None
    optional = OPTIONAL_COLUMNS if load_encoder else ()
    wanted = [c for c in REQUIRED_COLUMNS + optional if c in names]
    count = collections.Counter(names)  # names.count per column was quadratic in the header's width
    for name in wanted:
        if count[name] > 1:
            raise _fail(path, f"line {header_line}", f"column {name!r} appears twice in the header", name)
    for name in REQUIRED_COLUMNS:
        if name not in names:
            got = ", ".join(repr(x) for x in names[:8])
            raise _fail(path, f"line {header_line}", f"missing column {name!r} (the header has {got}): expected t [s], "
                        f"torque [N m], theta1 [rad] and optionally theta2 [rad]", name)
    # '#' comment lines are skipped anywhere (a logger's note in the middle of the data); line numbers stay the file's
    numbered = [(j, r) for j, r in enumerate(lines[i + 1:], start=header_line + 1)
                if r.strip() and not r.lstrip().startswith("#")]
    rows = [r for _, r in numbered]
    line_of = [j for j, _ in numbered]
    n = len(rows)
    if n > MAX_LOG_SAMPLES:
        raise _fail(path, "", f"{n:,} samples is more than a log may hold ({MAX_LOG_SAMPLES:,}): cut the log to the "
                    f"part with the reversals", "log")
    ncol = len(names)
    # the columns gearctl reads must hold finite numbers on every line; any other column is ignored, and kept in
    # ``extra`` only if it is numeric throughout (a drive's status text, an empty trailing column are dropped)
    need = {names.index(c) for c in wanted}
    others = [c for c in range(ncol) if c not in need and names[c] and count[names[c]] == 1][:MAX_EXTRA_COLUMNS]
    # one array column per column read (not per header column: n x ncol floats were 8 bytes per comma of the file)
    slot = {c: j for j, c in enumerate(sorted(need) + others)}
    data = np.full((n, len(slot)), np.nan)
    numeric = dict.fromkeys(others, True)
    k = 0
    reader = csv.reader(rows, delimiter=delim)
    for line_no in line_of:
        try:
            fields = next(reader)
        except csv.Error as exc:  # a field beyond the csv module's limit (131072 characters)
            raise _fail(path, f"line {line_no}", f"is not a CSV row ({exc})", "log") from None
        if len(fields) != ncol:
            raise _fail(path, f"line {line_no}", f"{len(fields)} fields, expected {ncol} (one per header column)",
                        "log")
        for c in need:
            f = fields[c]
            try:
                if "_" in f:  # Python's float() reads '0_1' as 1
                    raise ValueError(f)
                v = float(f)
            except ValueError:
                # a units row under the header ('s', 'N m', 'rad'): no field gearctl reads is a number
                hint = (": a units row? the header holds the names alone, in SI units (delete the row or start it "
                        "with #)" if k == 0 and not any(_is_number(fields[j]) for j in need) else "")
                if f.count(",") == 1 and _is_number(f.strip().replace(",", ".")):
                    # a spreadsheet's decimal comma in a semicolon file: it was named a units row
                    hint = ": a decimal comma? numbers take a decimal point (0.001, not 0,001)"
                raise _fail(path, f"line {line_no}", f"column {names[c]} = {f.strip()!r} is not a number{hint}",
                            names[c]) from None
            if not math.isfinite(v):
                raise _fail(path, f"line {line_no}", f"column {names[c]} = {f.strip()} is not a finite number",
                            names[c])
            data[k, slot[c]] = v
        for c in others:
            if numeric[c]:
                try:
                    data[k, slot[c]] = float(fields[c])
                except ValueError:
                    numeric[c] = False
        k += 1
    del lines, rows
    data = data[:k]
    n = k
    if n < 2:
        raise _fail(path, "", f"{n} sample(s) is too short: expected at least {MIN_LOG_SAMPLES} (with at least two "
                    f"reversals of the motion)", "log")
    col = {names[c]: data[:, slot[c]].copy() for c in sorted(need)}
    col.update({names[c]: data[:, slot[c]].copy() for c in others
                if numeric[c] and np.isfinite(data[:, slot[c]]).all()})
    t = col["t"]
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        j = int(bad[0])
        step = float(np.median(dt)) if dt.size else 0.0
        why = ("the rows run backwards in time, most intervals are negative: sort the log by t" if step < 0.0 else
               "a clock printed with too few digits repeats values" if t[j + 1] == t[j] or step == 0.0 else
               f"the clock jitters, or two rows are swapped: a jittering clock's stamps are read while each lies "
               f"within {JITTER_TOLERANCE:.0%} of the period, about {step:.3g} s here, of a fixed grid")
        raise _fail(path, f"line {line_of[j + 1]}", f"t = {float(t[j + 1]):.10g} does not increase (previous "
                    f"sample t = {float(t[j]):.10g}): expected time in increasing order ({why})", "t")
    Ts = float(np.median(dt))  # robust to a gap; refined by the fit over the whole log once the spacing is checked
    try:
        SAMPLE_TIME.check("sample period", Ts)
    except InputError as exc:
        raise _fail(path, "column t", f"sample period {Ts:g} s {exc.rule}", "t") from None
    step = Ts
    Ts = sample_period(t)
    jitter = (0.0, 0.0)
    # stamps off the fixed grid: checked whatever the intervals (a clock whose rate changes by 0.5 % keeps every
    # interval within PERIOD_TOLERANCE and was accepted 10 periods off the grid). The grid is the rule: stamps each
    # within JITTER_TOLERANCE of it make intervals up to twice that off the period (such a log was refused on an
    # interval 40 % long, though its stamps were all within 20 % of the grid and the docs read it)
    dev = _grid_deviation(t, Ts)
    j = int(np.argmax(np.abs(dev)))
    if abs(dev[j]) > JITTER_TOLERANCE * Ts:
        off = _missing_sample(dt, step)
        if off is not None:  # a sample missing or doubled: named where it is, not where the grid ends up furthest
            raise _fail(path, f"line {line_of[off + 1]}", f"t = {float(t[off + 1]):.10g} is {dt[off]:.6g} s after "
                        f"the previous sample; the log's period is {step:.6g} s: expected samples at a fixed period "
                        f"(a sample missing or doubled: each interval within {2 * JITTER_TOLERANCE:.0%} of it, the "
                        f"stamps within {JITTER_TOLERANCE:.0%} of a fixed grid); resample the log or cut it at the "
                        f"gap", "t")
        raise _fail(path, f"line {line_of[j]}", f"t = {float(t[j]):.10g} is {abs(dev[j]):.3g} s off the grid of "
                    f"the log's period {Ts:.6g} s: expected samples at a fixed period (time stamps within "
                    f"{JITTER_TOLERANCE:.0%} of it); resample the log", "t")
    if np.any(np.abs(dt - Ts) > PERIOD_TOLERANCE * Ts):  # a jittering clock: how far from the fixed grid
        jitter = (float(np.sqrt(np.mean(dev * dev))), float(abs(dev[j])))
    if n < MIN_LOG_SAMPLES:
        raise _fail(path, "", f"{n} samples ({n * Ts:.3g} s) is too short: expected at least {MIN_LOG_SAMPLES} (with "
                    f"at least two reversals of the motion)", "log")
    extra = {c: v for c, v in col.items() if c not in REQUIRED_COLUMNS + OPTIONAL_COLUMNS}
    return EncoderLog(t=t, torque=col["torque"], theta1=col["theta1"], theta2=col.get("theta2"), extra=extra,
                      sample_time=Ts, comments=tuple(comments), path=path, jitter=jitter)


def _missing_sample(dt: NDArray[np.float64], Ts: float) -> int | None:
    """The first interval of ``dt`` that no jitter within :data:`JITTER_TOLERANCE` explains (a sample missing or
    doubled), or None.

    Two stamps each within ``JITTER_TOLERANCE * Ts`` of their grid points lie up to twice that apart from ``Ts``.
    """
    off = np.flatnonzero(np.abs(np.asarray(dt) - Ts) > 2.0 * JITTER_TOLERANCE * Ts)
    return int(off[0]) if off.size else None


def _grid_deviation(t: NDArray[np.float64], Ts: float) -> NDArray[np.float64]:
    """The time stamps' distance from the least-squares grid ``t0 + k Ts`` [s] (origin subtracted first)."""
    tt = np.asarray(t, dtype=float) - float(t[0])
    k = np.arange(tt.size, dtype=float)
    t0 = float(np.mean(tt - k * Ts))
    return tt - t0 - k * Ts


def sample_period(t: NDArray[np.float64]) -> float:
    """The period of evenly spaced sample times [s]: the least-squares slope of ``t - t[0]`` on the sample index.

    The clock's origin is subtracted first (a Unix-epoch clock of 1.7e9 s keeps its microseconds), and the fit uses
    every sample, so neither the origin nor the rounding of the printed times moves the period (the median of
    the differences of rounded times is off by the rounding: 72 ppm at 1.7e9 s printed to 10 digits). The
    period is given to 9 significant digits.

    Parameters
    ----------
    t : array_like
        Sample times [s], in order.

    Returns
    -------
    float
        The period [s]; NaN for fewer than two samples.
    """
    tt = np.asarray(t, dtype=float) - float(t[0])
    n = tt.size
    if n < 2:
        return math.nan
    k = np.arange(n, dtype=float) - 0.5 * (n - 1)
    # to 9 digits (1e-9, far below any clock's accuracy): the rounding of the times (2.4e-7 s at 1.7e9 s) would
    # otherwise move the period's last digits with the origin, and the fits downstream follow them
    return float(f"{float(np.dot(k, tt - tt.mean()) / np.dot(k, k)):.9g}")


def write_log(path: str | Path, log: EncoderLog, *, comments: Sequence[str] = ()) -> None:
    """Write a log in the format :func:`read_log` reads (``#`` comments, header, 10 significant digits; the
    time 15, so that a clock far from zero keeps its resolution).

    Parameters
    ----------
    path : str or Path
        The file; its folder is created if missing.
    log : EncoderLog
        The log; its own ``comments`` are written first.
    comments : sequence of str
        More comment lines, each written as ``# line`` (a multi-line string gives one comment per line).

    Raises
    ------
    InputError
        If the file cannot be written.
    """
    path = Path(path)
    names = log.columns
    cols = [log.t, log.torque, log.theta1] + ([log.theta2] if log.theta2 is not None else []) + \
        [np.asarray(v) for v in log.extra.values()]
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "w") as fh:
            for c in (*log.comments, *comments):
                for line in str(c).splitlines():
                    fh.write(f"# {line}\n")
            fh.write(",".join(names) + "\n")
            chunk = 50_000
            for i0 in range(0, log.n, chunk):
                block = np.column_stack([np.asarray(c[i0:i0 + chunk], dtype=float) for c in cols])
                # time to 15 digits: a clock of 1.7e9 s (Unix time) keeps its 10 us
                np.savetxt(fh, block, fmt=["%.15g"] + ["%.10g"] * (len(cols) - 1), delimiter=",")
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror}") from None
