"""What every command shares: argument types read from the schema, JSON and CSV writers, progress, warnings."""

from __future__ import annotations

import argparse
import contextlib
import csv
import errno
import json
import math
import re
import sys
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import InputError
from ..files import json_ready, write_whole
from ..units import POINTS, Spec

__all__ = ["spec_arg", "positive_float", "positive_quantity", "finite_float", "nonnegative_float", "dump_json",
           "write_csv_stream", "say_written", "save_figure", "progress_bar", "warn", "POINTS", "OMEGA", "TORQUE",
           "TARGETS", "CYCLES", "STAGE", "JOBS", "WHOLE", "write_whole", "iter_json", "write_json", "earlier_plots",
           "remove_earlier_plots", "dropped_notes", "quiet_unawaited_coroutines", "sigterm_as_ctrl_c"]

#: command-line quantities not in a model file (POINTS is the schema's: the Python API checks the same range)
OMEGA = Spec(unit="rad/s", doc="initial shaft speed", low=-1e5, high=1e5)
TORQUE = Spec(unit="N m", doc="torque", low=-1e6, high=1e6)
TARGETS = Spec(unit="1", doc="target positions", low=2, high=50, integer=True)
CYCLES = Spec(unit="1", doc="cycles", low=1, high=50, integer=True)
STAGE = Spec(unit="1", doc="stage", low=1, high=6, integer=True)
#: a local cluster's worker processes (bench, perf, sweep alike: the memory check refuses what would not fit)
JOBS = Spec(unit="1", doc="worker processes", low=1, high=1024, integer=True)
WHOLE = Spec(unit="1", doc="whole number", low=-2**31, high=2**31, integer=True)


def spec_arg(spec: Spec) -> Callable[[str], Any]:
    """An argparse type that parses a number and checks it against ``spec`` (the schema's range).

    Parameters
    ----------
    spec : Spec
        The quantity's unit and range.

    Returns
    -------
    callable
        ``parse(text)``: the number (an int for an integer spec, a whole number kept exact), or
        ``argparse.ArgumentTypeError`` with the spec's rule.
    """
    def parse(text: str) -> Any:
        if spec.integer and re.fullmatch(r"\s*[+-]?\d+\s*", text):
            # a whole number as typed: float() rounds beyond 2**53 (--seed 9000000000000000001 ran as ...000, and
            # 2**63 - 1, the largest seed, was refused)
            n = int(text)
            try:
                spec.check("value", n)  # (an int compared exactly)
            except InputError as exc:
                raise argparse.ArgumentTypeError(f"{text} {exc.rule}") from None
            return n
        try:
            v = float(text)
        except ValueError:
            raise not_a_number(text, spec.unit) from None
        try:
            spec.check("value", v)
        except InputError as exc:
            raise argparse.ArgumentTypeError(f"{text} {exc.rule}") from None
        return int(v) if spec.integer else v

    parse.__name__ = spec.doc.replace(" ", "_")
    parse.spec = spec  # type: ignore[attr-defined]  # (the help states its range: cli._state_ranges)
    return parse


#: a number followed by a unit or a word (``10s``, ``50 um``, ``0.3sec``)
_NUMBER_AND_UNIT = re.compile(r"\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*([^\d\s.+-][^=,;]*?)\s*")


def not_a_number(text: str, unit: str | None = None) -> argparse.ArgumentTypeError:
    """The error for ``text`` that is no number; a number typed with a unit (``--duration 10s``) is told to drop
    it, with the number to give where the unit typed is the one expected (``10s`` -> ``10``; ``10ms`` for seconds
    is not ``10``, so only the unit is named)."""
    m = _NUMBER_AND_UNIT.fullmatch(text)
    if m is None:
        return argparse.ArgumentTypeError(f"{text!r} is not a number")
    number, typed = m.groups()
    if unit is None or unit == "1":
        return argparse.ArgumentTypeError(f"{text!r} is not a number: give the number alone, without {typed!r}")
    same = typed.replace(" ", "") == unit.replace(" ", "") or (unit == "s" and typed in ("sec", "secs", "second",
                                                                                       "seconds"))
    example = f" ({number})" if same else ""
    if unit == "rad" and typed.lower() in ("deg", "degree", "degrees", "°"):  # SI units: radians on the command line
        example = f" ({number} deg = {math.radians(float(number)):.6g} rad)"
    return argparse.ArgumentTypeError(f"{text!r} is not a number: give the value in {unit} (SI) as a plain number, "
                                      f"without the unit{example}")


def finite_float(text: str) -> float:
    """A finite number.

    Parameters
    ----------
    text : str
        The argument as typed.

    Returns
    -------
    float

    Raises
    ------
    argparse.ArgumentTypeError
        For text that is not such a number (argparse then exits with code 2 and the option's name).
    """
    try:
        v = float(text)
    except ValueError:
        raise not_a_number(text) from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"{text} is out of range: expected a finite number")
    return v


def positive_float(text: str) -> float:
    """A finite number > 0.

    Parameters
    ----------
    text : str
        The argument as typed.

    Returns
    -------
    float

    Raises
    ------
    argparse.ArgumentTypeError
        For text that is not such a number (argparse then exits with code 2 and the option's name).
    """
    v = finite_float(text)
    if v <= 0:
        raise argparse.ArgumentTypeError(f"{text} is out of range: expected a number > 0")
    return v


def positive_quantity(unit: str) -> Callable[[str], float]:
    """A parser of a finite number > 0 whose range error states ``unit`` (``--dwell -1``: "-1 is out of range: expected
    a number > 0 [s]").

    Parameters
    ----------
    unit : str
        The unit the messages state.

    Returns
    -------
    callable
        ``parse(text)``: the number, or ``argparse.ArgumentTypeError``.
    """

    def parse(text: str) -> float:
        try:
            float(text)
        except ValueError:
            raise not_a_number(text, unit) from None
        try:
            return positive_float(text)
        except argparse.ArgumentTypeError as err:
            raise argparse.ArgumentTypeError(f"{err} [{unit}]") from None

    parse.__name__ = f"positive_quantity_{unit}"
    return parse


def nonnegative_float(text: str) -> float:
    """A finite number >= 0.

    Parameters
    ----------
    text : str
        The argument as typed.

    Returns
    -------
    float

    Raises
    ------
    argparse.ArgumentTypeError
        For text that is not such a number (argparse then exits with code 2 and the option's name).
    """
    v = finite_float(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"{text} is out of range: expected a number >= 0")
    return v


def dump_json(obj: Any) -> str:
    """``obj`` as indented JSON (numpy values, dataclasses with ``as_dict``, inf/nan as null).

    Parameters
    ----------
    obj : object
        Dicts, lists, tuples, numbers, strings, numpy arrays and scalars, paths, objects with ``as_dict``.

    Returns
    -------
    str
    """
    return "".join(iter_json(obj))


def iter_json(obj: Any) -> Iterator[str]:
    """:func:`dump_json`'s text in pieces, for :func:`write_json`. The object is made JSON-ready in one copy
    (:func:`gearctl.files.json_ready`); ``dump_json`` was ``json.dumps`` of ``json.loads`` of ``json.dumps`` (three
    copies and the text): writing a sweep's ``--json`` took 6.1 kB a run over the results' 1.5 kB, past the 4 kB a run
    (``gearctl.sweep.ROW_BYTES``) its memory check allows for.

    Parameters
    ----------
    obj : object
        As :func:`dump_json` takes it.

    Yields
    ------
    str
        Pieces of the text.
    """
    return json.JSONEncoder(indent=2).iterencode(json_ready(obj))


def write_json(fh: Any, obj: Any) -> None:
    """Write :func:`dump_json`'s text to the open file ``fh`` piece by piece (no whole text in memory).

    Parameters
    ----------
    fh : file
        An open text file.
    obj : object
        As :func:`dump_json` takes it.
    """
    for chunk in iter_json(obj):
        fh.write(chunk)


#: The standard output a ``--csv -`` writes to, set by :func:`gearctl.cli.main` (which sends the rest to stderr).
CSV_STDOUT: Any = None


#: ``columns(i0, i1)``: the columns of rows ``i0..i1``, each a list of cells (written as they are) or numbers.
Columns = Callable[[int, int], Iterable[Sequence[Any] | NDArray[Any]]]


def _write_rows(fh: Any, header: Sequence[str], columns: Columns, n: int,
                chunk: int, progress: Callable[[float], Any] | None = None) -> None:
    w = csv.writer(fh, lineterminator="\n")  # Unix lines: `cut` and `awk` see no \r
    w.writerow(header)
    for i0 in range(0, n, chunk):
        cols = columns(i0, min(i0 + chunk, n))
        text = [c if isinstance(c, list) else np.char.mod("%.10g", np.asarray(c, dtype=float)).tolist()
                for c in cols]
        w.writerows(zip(*text, strict=True))
        if progress is not None:
            progress(min(i0 + chunk, n) / n)


def write_csv_stream(path: str, header: Sequence[str], columns: Columns,
                     n: int, *, chunk: int = 20_000) -> None:
    """Write a CSV in chunks of rows: ``columns(i0, i1)`` gives the columns of rows ``i0..i1``.

    Floats are written with 10 significant digits; memory stays bounded by one chunk. On a terminal a bar shows
    the rows written once the writing has taken 2 s (about 1 us a value: ``stiffness --points 1000000`` wrote
    253 MB for 15-20 s without a word).

    Parameters
    ----------
    path : str
        The file (its folder is created), or ``"-"`` for the standard output.
    header : sequence of str
        The column names.
    columns : callable
        ``columns(i0, i1)``: the columns of rows ``i0..i1``, each a list of cells (written as they are) or numbers.
    n : int
        The number of rows.
    chunk : int
        Rows per chunk (default 20 000).

    Raises
    ------
    InputError
        If the file cannot be opened or written (``cannot write PATH: reason``).
    BrokenPipeError
        If ``path`` is a pipe whose reader went away (``--csv /dev/stdout | head``): not an input error, so
        it propagates to :func:`gearctl.cli.main`, which ends quietly as for any closed output pipe.
    """
    try:
        with progress_bar(f"writing {'standard output' if path == '-' else path}", expected_s=None) as bar:
            step = bar if bar.bar else None
            if path == "-":  # standard output (main sends the command's other output to stderr meanwhile)
                out = CSV_STDOUT or sys.stdout
                _write_rows(out, header, columns, n, chunk, step)
                out.flush()
                return
            p = Path(path)
            p.parent.mkdir(parents=True, exist_ok=True)
            with open(p, "w", newline="") as fh:
                _write_rows(fh, header, columns, n, chunk, step)
    except BrokenPipeError:
        raise
    except OSError as exc:
        if exc.errno == errno.EPIPE:  # a closed pipe reported as a plain OSError: the same quiet end
            raise BrokenPipeError(exc.errno, exc.strerror) from None
        raise InputError(f"cannot write {'standard output' if path == '-' else path}: {exc.strerror}") from None


#: Arguments that name files a command reads, and those that name what it writes.
INPUT_ARGS = ("model", "controller", "log")
OUTPUT_ARGS = ("csv", "plot", "out", "write_model", "reference_only", "json", "bode", "step")
#: The outputs ``-`` sends to standard output (``--json`` where it takes a file: ``bench``, ``sweep``).
STDOUT_ARGS = ("csv", "json")
#: The files a command writes into its ``--out DIR`` (another output named like one of them there is overwritten).
OUT_DIR_FILES = {"sweep": ("runs.csv", "summary.md", "*.png"), "bench": ("report.md", "*.png")}


def check_plot_format(path: str | None) -> None:
    """Refuse a ``--plot FILE`` whose suffix is no format matplotlib writes, before the run (it failed after it);
    no suffix is PNG under that very name (:func:`gearctl.plots.save`)."""
    if not isinstance(path, str) or not Path(path).suffix:
        return
    from matplotlib.backend_bases import FigureCanvasBase

    formats = FigureCanvasBase.get_supported_filetypes()
    suffix = Path(path).suffix[1:].lower()
    if suffix not in formats:
        raise InputError(f"--plot {path}: .{suffix} is not a figure format: expected one of "
                         f"{', '.join(sorted(formats))}, or no suffix (PNG)", field="plot")


def refuse_writing_over_inputs(args: argparse.Namespace) -> None:
    """Refuse an output path that is one of the command's input files (``--write-model LOG``): it would be lost;
    and two outputs naming one file (``--reference-only F --out F``, ``sweep --json D/runs.csv --out D``): the
    second would overwrite the first.

    The same file under another name (a link, ``./``) counts (:func:`os.path.samefile`).
    """
    import os

    for key in OUTPUT_ARGS:  # "" was no output at all, without a word; "-" a file named "-" (--plot, --out ...)
        out = getattr(args, key, None)
        flag = f"--{key.replace('_', '-')}"
        if isinstance(out, str) and not out.strip():
            std = " (or - for standard output)" if key in STDOUT_ARGS else ""
            raise InputError(f"{flag} {out!r}: an empty name: expected a file or folder name{std}", field=key)
        if out == "-" and key not in STDOUT_ARGS:
            raise InputError(f"{flag} -: this output cannot go to standard output (- is standard output for --csv, "
                             f"and for --json FILE of bench and sweep): give a file name", field=key)
    check_plot_format(getattr(args, "plot", None))
    inputs = [v for k in INPUT_ARGS if isinstance(v := getattr(args, k, None), str) and Path(v).is_file()]
    for key in OUTPUT_ARGS:
        out = getattr(args, key, None)
        if not isinstance(out, str) or not Path(out).exists():
            continue
        for inp in inputs:
            try:
                same = os.path.samefile(out, inp)
            except OSError:
                continue
            if same:
                raise InputError(f"--{key.replace('_', '-')} {out} is the input file {inp}: writing there would "
                                 f"lose it; write to another file", field=key)
    # two outputs of one run to one file (excite --reference-only F --out F): the second overwrote the first
    outs = [(k, v) for k in OUTPUT_ARGS if isinstance(v := getattr(args, k, None), str) and v != "-"]
    for i, (k1, o1) in enumerate(outs):
        for k2, o2 in outs[i + 1:]:
            if os.path.realpath(o1) == os.path.realpath(o2):
                raise InputError(f"--{k1.replace('_', '-')} {o1} and --{k2.replace('_', '-')} {o2} name the same "
                                 f"file: one would overwrite the other; write to two files", field=k2)
    # a file output inside the --out folder under a name the command writes there (sweep --json D/runs.csv --out D)
    folder = getattr(args, "out", None)
    if isinstance(folder, str) and getattr(args, "command", None) in OUT_DIR_FILES:
        import fnmatch

        for k, o in outs:
            if k == "out" or os.path.realpath(os.path.dirname(os.path.abspath(o))) != os.path.realpath(folder):
                continue
            if any(fnmatch.fnmatch(os.path.basename(o), pat) for pat in OUT_DIR_FILES[args.command]):
                raise InputError(f"--{k.replace('_', '-')} {o} is a file --out {folder} writes "
                                 f"({', '.join(OUT_DIR_FILES[args.command])}): one would overwrite the other; write "
                                 f"to another name", field=k)


def _file_kind(path: str) -> str | None:
    """``"controller"`` or ``"model"`` for a readable TOML file that is plainly one (a top-level ``kind``; a
    ``[gear1]`` or ``[[stage]]`` table), else None (the loaders then say what is wrong with it)."""
    p = Path(path)
    if p.suffix.lower() != ".toml" or not p.is_file():
        return None
    try:
        import tomllib

        if p.stat().st_size > 1_000_000:
            return None
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):  # (arrays nested too deeply: the loader names it)
        return None
    if isinstance(data.get("kind"), str):
        return "controller"
    if isinstance(data.get("gear1"), dict) or isinstance(data.get("stage"), list):
        return "model"
    return None


def refuse_swapped_model_controller(args: argparse.Namespace) -> None:
    """A controller given where the model goes, or a model where the controller goes (``gearctl track pid``; the
    model's file as the controller): one line saying which is which and the order, where the loaders said "unknown
    model 'pid': expected a catalog name (detc1992_21x29_25deg, ...)", "unknown section [kind]", "missing key kind".
    """
    from ..catalog import controller_names, model_names

    cmd = getattr(args, "command", "")
    model, ctrl = getattr(args, "model", None), getattr(args, "controller", None)
    if not hasattr(args, "controller") or not isinstance(model, str):
        return
    models, ctrls = set(model_names()), set(controller_names())
    if cmd == "excite":  # its controller is an option (the position loop of the recorded motion)
        label = "--controller"
        order = "--controller names the position loop (e.g. gearctl excite MODEL --controller pid)"
    else:
        label = "CONTROLLER"
        order = f"the model comes first: gearctl {cmd} MODEL CONTROLLER (e.g. gearctl {cmd} shing1993_servo pid)"
    if not Path(model).exists() and model in ctrls and model not in models:
        raise InputError(f"MODEL {model!r} is a controller, not a model; {order}", field="model")
    if _file_kind(model) == "controller":
        raise InputError(f"MODEL {model}: a controller file (kind = {_kind_of(model)!r}), not a model; {order}",
                         field="model")
    if isinstance(ctrl, str):
        if not Path(ctrl).exists() and ctrl in models and ctrl not in ctrls:
            raise InputError(f"{label} {ctrl!r} is a model, not a controller; {order}", field="controller")
        if _file_kind(ctrl) == "model":
            raise InputError(f"{label} {ctrl}: a model file, not a controller; {order}", field="controller")


def _kind_of(path: str) -> str:
    import tomllib

    return str(tomllib.loads(Path(path).read_text(encoding="utf-8"))["kind"])


def check_outputs_writable(args: argparse.Namespace) -> None:
    """Refuse, before the command's work, every output file or folder it could not write at the end (one line naming
    the option, exit 2): ``identify --write-model`` into a missing folder, ``track --plot`` under a file, ... were
    found only after the run, its results printed, then exit 2 (``bench`` and ``sweep`` checked theirs before).

    ``--out`` is a folder but for ``excite`` (its log); ``--write-model``'s folder must exist (it is not created,
    :func:`gearctl.identify.write_identified_model`); ``-`` (standard output) is not a file.
    """
    import os

    for key in OUTPUT_ARGS:
        out = getattr(args, key, None)
        if not isinstance(out, str) or out == "-":
            continue
        if key == "write_model":
            parent = Path(os.path.realpath(out)).parent
            if not parent.is_dir():
                what = "is not a folder" if parent.exists() else "does not exist (create it first)"
                raise InputError(f"--write-model {out}: cannot write there: {parent} {what}", field=key)
        check_writable(out, directory=key == "out" and getattr(args, "command", None) != "excite", key=key)


def check_writable(path: str, *, directory: bool = False, key: str = "out", files: Iterable[str] = ()) -> None:
    """Refuse, before a long run, an output path it could not write at its end: one line naming ``--KEY``.

    ``directory``: the path is a folder the run writes into (``files``: the names it writes there, none of which may
    be a folder: a sweep ran to its end, wrote runs.csv and stopped at a folder named histogram.png); else a file.
    Nothing is left behind: the path (through any link) must not be of the other kind, the nearest folder that
    exists on the way to it must be one that can be written, the folders missing below it are made and removed
    again, and an existing file must be writable. (Permissions as ``os.access`` sees them: a read-only file system or
    root's rights can still fail at the end, with the same one line.)
    """
    import os

    flag = f"--{key.replace('_', '-')}"
    if not directory and os.path.exists(path) and not os.path.isdir(path) and not os.path.isfile(path):
        return  # a device, a FIFO, a pipe (/dev/stdout in `| ...` resolves to /proc/PID/fd/pipe:[N], no path at all)
    p = Path(os.path.realpath(path))
    if directory and p.exists() and not p.is_dir():
        raise InputError(f"{flag} {path}: is a file, expected a folder to write into", field=key)
    if directory and p.is_dir():
        for name in files:
            if (p / name).is_dir():
                raise InputError(f"{flag} {path}: {Path(path) / name} is a folder, where the run writes a file: "
                                 f"remove it or write to another folder", field=key)
    if not directory and p.is_dir():
        raise InputError(f"{flag} {path}: is a folder, expected a file name", field=key)
    if p.exists() and not p.is_dir():
        if not os.access(p, os.W_OK):
            raise InputError(f"{flag} {path}: cannot write there (the file is read-only)", field=key)
        return
    folder = p if directory else p.parent
    here, missing = folder, []
    while not here.exists() and here != here.parent:
        missing.append(here)
        here = here.parent
    if not here.is_dir():
        raise InputError(f"{flag} {path}: cannot write there ({here} is a file, not a folder)", field=key)
    if not os.access(here, os.W_OK | os.X_OK):
        raise InputError(f"{flag} {path}: cannot write there ({here} is not writable)", field=key)
    try:  # the folders the run would make: made and removed again (a special file system refuses them here)
        for d in reversed(missing):
            d.mkdir()
    except OSError as exc:
        raise InputError(f"{flag} {path}: cannot write there ({exc.strerror or exc})", field=key) from None
    finally:
        for d in missing:
            if d.is_dir():
                d.rmdir()


def format_rate(simulated: float, wall: float) -> str:
    """Simulated seconds per wall second [s/s] as ``track`` prints it: whole numbers from 10 up, two significant
    digits below (a run slower than real time, 0.36, printed as 0)."""
    rate = simulated / max(wall, 1e-9)
    return f"{rate:.0f}" if rate >= 10 else f"{rate:.2g}"


def say_written(*pairs: tuple[str | None, str]) -> None:
    """Print ``wrote FILE (what)`` for each file the user asked for.

    Parameters
    ----------
    *pairs : tuple of (str or None, str)
        ``(path, what)``; a None or empty path is skipped, ``"-"`` is the standard output.
    """
    for path, what in pairs:
        if path:
            print(f"  wrote {'standard output' if path == '-' else path} ({what})")


def save_figure(fig: Any, path: str) -> None:
    """Write a figure, turning an unwritable path into one line.

    Parameters
    ----------
    fig : Figure
        The figure.
    path : str
        The file (:func:`gearctl.plots.save`).

    Raises
    ------
    InputError
        ``cannot write plot PATH: reason``.
    """
    from ..plots import save

    try:
        save(fig, path)
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot write plot {path}: {exc}") from None


class progress_bar:  # noqa: N801 (a context manager used like a function)
    """A tqdm bar on stderr for runs expected to take more than ``threshold`` seconds (and only on a terminal);
    with ``expected_s=None`` (a duration not known beforehand), shown once the run has taken ``threshold`` seconds.

    Call the object with the fraction done (0..1).

    Parameters
    ----------
    desc : str
        The bar's label.
    expected_s : float or None
        Expected wall time [s], or None where it is not known.
    threshold : float
        Wall time [s] below which no bar is shown (default 2).
    total : int
        Steps of the bar (default 1000).
    """

    def __init__(self, desc: str, *, expected_s: float | None, threshold: float = 2.0, total: int = 1000) -> None:
        self.bar = None
        self.total = total
        self.done = 0
        if (expected_s is None or expected_s > threshold) and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=desc, file=sys.stderr, leave=False, unit="‰",
                            delay=threshold if expected_s is None else 0.0)

    def __call__(self, fraction: float) -> None:
        if self.bar is not None:
            k = int(fraction * self.total)
            if k > self.done:
                self.bar.update(k - self.done)
                self.done = k

    def __enter__(self) -> progress_bar:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.close()


def earlier_plots(index: Path, title: str, patterns: Sequence[str]) -> list[str]:
    """The plots an earlier run wrote into an ``--out`` folder, as its index (``summary.md``, ``report.md``, which
    starts with ``title``) links them; only names matching ``patterns`` (gearctl's own plot names), none when the
    index is not gearctl's.

    Parameters
    ----------
    index : Path
        The earlier run's index file (an unreadable one: none).
    title : str
        The first line a gearctl index of this command starts with.
    patterns : sequence of str
        Shell patterns of gearctl's plot names.

    Returns
    -------
    list of str
        The file names, each once.
    """
    import fnmatch

    try:
        with open(index, encoding="utf-8") as fh:
            text = fh.read(1_000_000)
    except (OSError, UnicodeDecodeError):
        return []
    if not text.startswith(title + "\n"):
        return []
    names = re.findall(r"^!\[[^\]\n]*\]\(([^()/\\\n]+)\)$", text, flags=re.MULTILINE)
    return [n for n in dict.fromkeys(names) if any(fnmatch.fnmatch(n, pat) for pat in patterns)]


def remove_earlier_plots(folder: Path, earlier: Iterable[str], written: Iterable[str]) -> list[str]:
    """Remove from ``folder`` the plots of :func:`earlier_plots` that this run did not write again; return their
    names. Re-running a sweep into its ``--out`` folder with other keys left the earlier run's plots
    (``error_vs_backlash.png``, ``map.png``) beside the new ``runs.csv`` and ``summary.md``, as if this run's.

    Only regular files (not links) are removed; one that cannot be is left, unnamed.

    Parameters
    ----------
    folder : Path
        The ``--out`` folder.
    earlier : iterable of str
        :func:`earlier_plots`.
    written : iterable of str
        The plots this run wrote.

    Returns
    -------
    list of str
        The names removed, sorted.
    """
    gone = []
    for name in sorted(set(earlier) - set(written)):
        f = folder / name
        if f.is_file() and not f.is_symlink():
            try:
                f.unlink()
            except OSError:
                continue
            gone.append(name)
    return gone


def warn(command: str, warnings: Iterable[str], *, kind: str = "warning") -> None:
    """Print each warning of an unhealthy loop (or, ``kind="note"``, each design note) on stderr, one line each.

    Parameters
    ----------
    command : str
        The command, named in each line (``gearctl COMMAND: KIND: text``).
    warnings : iterable of str
        The sentences.
    kind : str
        ``"warning"`` (default) or ``"note"``.
    """
    for w in warnings:
        print(f"gearctl {command}: {kind}: {w}", file=sys.stderr)


def quiet_unawaited_coroutines() -> None:
    """Silence Python's warning of a coroutine never awaited, for the rest of a Dask command (sweep, bench).

    A Ctrl-C that lands while the Dask client waits on a result leaves the client's request (a tornado coroutine)
    unawaited, and Python warns of it when it is collected: on a loaded machine a
    ``RuntimeWarning: coroutine 'Future._result' was never awaited`` line, with the source line, came before the
    command's own ``interrupted`` line. gearctl awaits every coroutine of its own; these are Dask's, left by the
    interrupt the user asked for.
    """
    warnings.filterwarnings("ignore", message=r"coroutine '.*' was never awaited", category=RuntimeWarning)


@contextlib.contextmanager
def sigterm_as_ctrl_c() -> Iterator[None]:
    """While a Dask command runs (sweep, bench), a SIGTERM (``kill PID``; a batch system at the end of a job's time) is
    taken as a Ctrl-C: the process sends itself SIGINT, so the runs finished are handed over and the cluster closed as
    for a Ctrl-C (held while the local cluster starts or closes). Before, it ended the sweep at once with nothing
    written. From the main thread only (where Python handles signals), and only where SIGINT is not ignored (a
    background job of a non-interactive shell ignores it: a SIGTERM turned into it would be lost, and the command
    unkillable but by SIGKILL); the previous handler is put back after."""
    import os
    import signal
    import threading

    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) in (signal.SIG_IGN, None)):
        yield
        return
    previous = signal.signal(signal.SIGTERM, lambda signum, frame: os.kill(os.getpid(), signal.SIGINT))
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)


def dropped_notes(dropped: Iterable[Mapping[str, Any]]) -> list[str]:
    """One note per silent worker dropped from the Dask scheduler (a sweep's ``engine["dropped"]``, a bench's
    ``dropped``): sweep and bench say it alike.

    Parameters
    ----------
    dropped : iterable of dict
        ``{"worker": address, "tasks": n, "restarted": bool}`` each (``tasks`` 0: at the check of the workers).

    Returns
    -------
    list of str
    """
    from .. import parallel

    out = []
    for d in dropped:
        held = f"holding {d['tasks']} task(s)" if d["tasks"] else "at the check of the workers, before any run"
        out.append(f"the worker {d['worker']} was not heard from for {parallel.WORKER_TIMEOUT:g} s {held}: dropped "
                   f"from the scheduler ({'its nanny started a fresh one' if d.get('restarted') else 'removed'}), "
                   f"its tasks rerun on the other workers")
    return out


def unused_estimate(kind: str | None, estimate: float | None) -> list[str]:
    """A note for ``--estimate`` given to a plain PID, which has no backlash estimate to take it (it ran silently)."""
    if estimate is None or kind != "pid":
        return []
    return [f"--estimate {estimate:g}: a pid has no backlash estimate, so the value changes nothing (it is for "
            f"reversal_offset, deadzone_inverse, adaptive_inverse and mpc)"]


def ratio_changed(nominal: Any, true: Any) -> list[str]:
    """A note where ``--set`` (teeth) gave the true plant another gear ratio than the design's: every loop gain, the
    lost motion at the load and the feedforward then act on a ratio the controller was not designed for (a reviewer's
    ``--set teeth1=30`` on a 4:1 pair ran at 0.55 rad RMS with no word of why)."""
    n, t = nominal.gear_ratio, true.gear_ratio
    if abs(t - n) <= 1e-9 * abs(n):
        return []
    return [f"--set: the true plant's gear ratio is {t:.6g}, the controller was designed for {n:.6g} (the design "
            "stays nominal; vary the teeth of the model file itself to design for the new ratio)"]


def yang_sun_notes(model: Any, plant: str) -> list[str]:
    """Notes for a Yang-Sun ``plant`` of ``model`` whose material is not steel (:func:`gearctl.stiffness.
    restitution_note`): its restitution law is steel's (a review's POM train ran on it without a word). One note per
    distinct material, naming the stages of a train."""
    if str(plant) != "yang-sun":
        return []
    from ..stiffness import restitution_note

    by_note: dict[str, list[int]] = {}
    for i, sm in enumerate(model.stages, start=1):
        note = restitution_note(sm.pair)
        if note is not None:
            by_note.setdefault(note, []).append(i)
    if model.n_stages == 1:
        return list(by_note)
    return [f"stage{'s' if len(st) > 1 else ''} {', '.join(map(str, st))}: {note}" for note, st in by_note.items()]


def separated_past_flank(plant: Any, s: Any, mode: Any) -> float:
    """The largest ``(|s| - b) / b`` of a stage labelled separated at an output time (0 if none): a contact the
    kernel missed, the teeth passing through each other (``simulate`` and ``track --json``, the fuzzer's oracle;
    stages without backlash skipped). ``s``, ``mode``: per stage and sample (a pair's may be 1-D)."""
    s, mode = np.atleast_2d(s), np.atleast_2d(mode)
    worst = 0.0
    for i, b in enumerate(plant.backlashes):
        sep = mode[i] == 0
        if b > 0.0 and sep.any():
            worst = max(worst, float(np.max(np.abs(s[i, sep]))) / b - 1.0)
    return worst
