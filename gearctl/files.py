"""Catalog files: where they are, how they are read, and how their keys become validated dataclasses.

Used by :mod:`gearctl.catalog` (model files) and :mod:`gearctl.design.registry` (controller files), so
both kinds of file are read by one set of rules: a key's unit and range come from the dataclass field it
feeds (:mod:`gearctl.units`), unknown keys get a "did you mean", and every error is one line naming the
file, the table and the key.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
import os
import shutil
import tempfile
import tomllib
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from .errors import InputError, short_repr
from .units import describe_range

__all__ = ["catalog_dirs", "catalog_names", "resolve", "read_toml", "toml_value", "toml_dumps", "build_dataclass",
           "check_source",
           "Binding", "MAX_FILE_BYTES", "spec_values", "table_values", "Layout", "json_ready"]

_PKG = Path(__file__).resolve().parent

#: Largest model or controller file read [bytes] (catalog files are a few kB).
MAX_FILE_BYTES = 1_000_000


def catalog_dirs(kind: str) -> list[Path]:
    """Folders searched for catalog entries of ``kind`` (``"models"`` or ``"controllers"``), in order.

    Parameters
    ----------
    kind : str
        ``"models"`` or ``"controllers"``.

    Returns
    -------
    list of Path
        The installed package's folder, then the source checkout's, those that exist.
    """
    return [d for d in (_PKG / kind, _PKG.parent / kind) if d.is_dir()]


def catalog_names(kind: str) -> list[str]:
    """Names of the catalog entries of ``kind``, sorted.

    Parameters
    ----------
    kind : str
        ``"models"`` or ``"controllers"``.

    Returns
    -------
    list of str
        The stems of the ``*.toml`` files of :func:`catalog_dirs`, each once.
    """
    names: dict[str, None] = {}
    for d in catalog_dirs(kind):
        for p in sorted(d.glob("*.toml")):
            names.setdefault(p.stem, None)
    return sorted(names)


def resolve(name_or_path: str | Path, kind: str) -> Path:
    """Find the TOML file of a catalog entry or path.

    Parameters
    ----------
    name_or_path : str or os.PathLike
        A catalog name (a bare name, even where a folder of that name exists here) or a path to a file (one with
        a ``.toml`` suffix, a folder part, or that exists).
    kind : str
        ``"models"`` or ``"controllers"`` (messages name it in the singular).

    Returns
    -------
    Path

    Raises
    ------
    InputError
        If it is neither an existing file nor a catalog name; the message lists close names.
    """
    # any path-like of text is a path (pathlib's own rule; a py.path or an os.DirEntry was read before this check)
    if not (isinstance(name_or_path, str | os.PathLike) and isinstance(os.fspath(name_or_path), str)):
        raise InputError(f"{kind[:-1]} = {short_repr(name_or_path)} is not a name or a path (a "
                         f"{type(name_or_path).__name__}): expected a catalog name or a path to a .toml file (str or "
                         "pathlib.Path)", field=kind[:-1])
    p = Path(name_or_path)
    # a bare name that is a folder here (``gearctl export ... --out pid``) still names the catalog entry
    bare_dir = p.suffix == "" and len(p.parts) == 1 and p.is_dir()
    if bare_dir:
        for d in catalog_dirs(kind):
            if (d / f"{p.name}.toml").is_file():
                return d / f"{p.name}.toml"
    if p.suffix == ".toml" or p.exists() or len(p.parts) > 1:
        if p.is_file():
            return p
        what = ("is a folder, not a file" if p.is_dir() else
                "is not a regular file (a device, pipe or socket): expected a TOML file" if p.exists() else
                "does not exist")
        # `gearctl info shing1993_servo.toml` in a folder without that file: the catalog entry was meant
        if what == "does not exist" and len(p.parts) == 1 and p.suffix == ".toml":
            if p.stem in catalog_names(kind):
                what += f"; did you mean the catalog name {p.stem} (without .toml)?"
            elif p.stem in catalog_names(_OTHER[kind]):
                what += f" (and {p.stem} is a catalog {_OTHER[kind][:-1]}, not a {kind[:-1]})"
        raise InputError(f"{kind[:-1]} file {str(p)!r} {what}", field=kind[:-1])
    for d in catalog_dirs(kind):
        cand = d / f"{p.name}.toml"
        if cand.is_file():
            return cand
    names = catalog_names(kind)
    # a controller's name where a model goes (`gearctl info pid`), or the reverse: say which it is
    other = f"{str(name_or_path)!r} is a {_OTHER[kind][:-1]}, not a {kind[:-1]}; " if (
        p.name in catalog_names(_OTHER[kind])) else ""
    close = difflib.get_close_matches(str(name_or_path), names, n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    raise InputError(
        f"unknown {kind[:-1]} {str(name_or_path)!r}: {other}expected a catalog name ({', '.join(names)}) or a path "
        f"to a .toml file{hint}",
        field=kind[:-1],
    )


#: the catalog kind a name of the other was mistaken for
_OTHER = {"models": "controllers", "controllers": "models"}


def toml_value(v: Any) -> str:
    """``v`` (bool, int, float including inf and nan, str, list or tuple of those) as a TOML value.

    Parameters
    ----------
    v : bool, int, float, str, list or tuple
        The value.

    Returns
    -------
    str

    Raises
    ------
    TypeError
        For a value of another type.

    Examples
    --------
    >>> toml_value([1, 0.5, float("inf"), "a", True])
    '[1, 0.5, inf, "a", true]'
    """
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):  # a JSON string is a TOML basic string: the same escapes
        return json.dumps(v)
    if isinstance(v, list | tuple):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} as TOML")


def toml_dumps(doc: Mapping[str, Mapping[str, Any] | Sequence[Mapping[str, Any]]],
               header: Iterable[str] = ()) -> str:
    """A document of tables of values (:func:`toml_value`) as TOML text, with ``header`` as comment lines; a list
    of tables (a train's stages) is written as an array of tables (``[[stage]]``).

    Parameters
    ----------
    doc : mapping
        ``table -> {key: value}``, or ``table -> [{key: value}, ...]`` for an array of tables.
    header : iterable of str
        Comment lines written first.

    Returns
    -------
    str

    Raises
    ------
    TypeError
        For a value :func:`toml_value` cannot write.
    """
    out = [f"# {h}" for h in header]
    for table, keys in doc.items():
        for one in ([keys] if isinstance(keys, Mapping) else keys):
            out.append(f"\n[{table}]" if isinstance(keys, Mapping) else f"\n[[{table}]]")
            out.extend(f"{k} = {toml_value(v)}" for k, v in one.items())
    return "\n".join(out) + "\n"


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file; a binary, non-UTF-8, oversized or invalid file is one :class:`InputError`.

    Parameters
    ----------
    path : Path
        The file.

    Returns
    -------
    dict

    Raises
    ------
    InputError
        For a file that cannot be read, larger than ``MAX_FILE_BYTES``, binary, not UTF-8, or not valid TOML.
    """
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise InputError(f"{path}: {size} bytes is too large for a model or controller file (at most "
                             f"{MAX_FILE_BYTES} bytes): expected a TOML file")
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot be read: {exc.strerror}") from None
    if b"\0" in raw:
        raise InputError(f"{path}: is a binary file, not TOML text")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: is not UTF-8 text (byte {exc.start}): expected a TOML file") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:  # tomllib parses nested arrays and inline tables recursively
        raise InputError(f"{path}: not valid TOML here: arrays or inline tables nested too deeply (a model or "
                         f"controller file nests a few levels)") from None


@dataclasses.dataclass(frozen=True, slots=True)
class Binding:
    """Where a dataclass field's value came from: ``[table] key = raw`` in ``path``.

    Parameters
    ----------
    table : str
        The table (``""`` for the top level; ``"override"`` for a ``--set``, ``"override <stage>"`` for one that
        every stage of a train takes).
    key : str
        The key as written.
    raw : object
        The value as written (before any conversion, e.g. of degrees).
    """

    table: str
    key: str
    raw: Any

    def label(self) -> str:
        """``[table] key`` (``--set key`` for an override, ``--set key [stage i]`` for a train's stage, ``key`` for a
        top-level key)."""
        if self.table == "override":
            return f"--set {self.key}"
        if self.table.startswith("override "):  # an override every stage of a train takes: name the stage refused
            return f"--set {self.key} (every stage; here [{self.table[9:]}])"
        return f"[{self.table}] {self.key}" if self.table else self.key


def _field_meta(cls: type, name: str) -> Mapping[str, Any]:
    for f in dataclasses.fields(cls):
        if f.name == name:
            return f.metadata
    raise KeyError(name)


def _whole(cls: type, name: str, value: Any) -> Any:
    """``value`` as an ``int`` where field ``name`` takes a whole number and TOML gave a whole float (``teeth =
    80.0``, ``motor_encoder_cpr = 1e6``): kept a float, it printed as ``80.0 x 20 teeth`` and ``1000000.0
    counts/rev`` and went into the JSON so. Any other value is left for the field's own check."""
    try:
        integer = _field_meta(cls, name).get("integer")
    except KeyError:
        return value
    if integer and isinstance(value, float) and math.isfinite(value) and value == int(value):
        return int(value)
    return value


def required_fields(cls: type) -> set[str]:
    """Fields of ``cls`` without a default."""
    return {f.name for f in dataclasses.fields(cls)
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING}


def unknown_key(path: Path, table: str, key: str, known: Iterable[str], *, context: str = "") -> InputError:
    """``file: unknown key [table] key: expected one of ...; did you mean ...?``

    ``context`` follows the key (e.g. ``" for kind 'mpc'"``).
    """
    known = list(known)
    close = difflib.get_close_matches(key, known, n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    where = f"[{table}] {key}" if table else key
    return InputError(f"{path}: unknown key {where}{context}: expected one of {', '.join(known)}{hint}", field=key)


def build_dataclass(path: Path, cls: type, values: Mapping[str, tuple[Binding | None, Any]]) -> Any:
    """Build ``cls(**values)``, restating a validation error with the file, table and key the user typed.

    Parameters
    ----------
    path : Path
        The file (messages).
    cls : type
        A dataclass whose fields validate themselves (:func:`gearctl.units.validate_fields`).
    values : mapping
        ``field -> (binding, value)``; keys ending in ``_deg`` have been converted to radians by the caller.

    Raises
    ------
    InputError
        ``file: [table] key = raw <rule>``; a missing required field names the table and key to add.
    """
    for fname in sorted(required_fields(cls) - set(values)):
        meta = _field_meta(cls, fname)
        unit = "" if meta.get("unit") in (None, "1") else f" [{meta['unit']}]"
        raise InputError(f"{path}: missing key {fname}: {meta.get('doc', '')}, {describe_range(meta)}{unit}",
                         field=fname)
    try:
        return cls(**{f: _whole(cls, f, v) for f, (_, v) in values.items()})
    except InputError as exc:
        b = values.get(exc.field or "", (None, None))[0]
        if b is not None and exc.field is not None and exc.rule:  # b is found by exc.field
            rule = exc.rule
            meta = _field_meta(cls, exc.field)
            if b.key.endswith("_deg") and meta.get("unit") == "rad":
                # a field kept in radians (the caller converted the degrees): say its range in the degrees typed;
                # a field kept in degrees (a controller's phase_margin_deg) already says it so
                rule = (f"is out of range: expected a number with {math.degrees(meta['low']):g} <= value <= "
                        f"{math.degrees(meta['high']):g} [deg]")
            raise InputError(f"{path}: {b.label()} = {b.raw!r} {rule}", field=b.key, rule=rule) from None
        msg = str(exc)
        if b is not None and exc.field and msg.startswith(f"{exc.field} = "):  # a check across keys: name the table
            msg = b.label() + msg[len(exc.field):]
        raise InputError(f"{path}: {msg}", field=exc.field, rule=exc.rule) from None
    except TypeError as exc:  # a value of a type the dataclass cannot take at all
        raise InputError(f"{path}: {exc}") from None


_SOURCE_KEYS = {"citation": False, "table": False, "notes": False, "url": False, "doi": False}


def check_source(path: Path, content: Any, *, required: tuple[str, ...] = ("citation",)) -> dict[str, str]:
    """Check a ``[source]`` table: known keys, strings, the ``required`` ones present (one of them for
    controller files, which may give ``notes`` alone).

    Parameters
    ----------
    path : Path
        The file (messages).
    content : object
        The ``[source]`` table as parsed.
    required : tuple of str
        Keys of which at least one must be given and not blank (default ``("citation",)``; empty: none).

    Returns
    -------
    dict of str to str

    Raises
    ------
    InputError
        For a ``[source]`` that is not a table, an unknown key, a value that is not a string, or no required key
        given (or only blank ones).
    """
    if not isinstance(content, dict):
        raise InputError(f"{path}: [source] must be a table with a citation", field="source")
    for key, value in content.items():
        if key not in _SOURCE_KEYS:
            raise unknown_key(path, "source", key, _SOURCE_KEYS)
        if not isinstance(value, str):
            raise InputError(f"{path}: [source] {key} = {value!r} must be a string", field=key)
    if required and not any(k in content for k in required):
        raise InputError(f"{path}: missing key [source] {required[0]}: where the data come from", field=required[0])
    if required and not any(content.get(k, "").strip() for k in required):  # `citation = ""` passed as given
        raise InputError(f"{path}: [source] {required[0]} is empty: say where the data come from", field=required[0])
    return dict(content)


def degrees_to_radians(path: Path, table: str, key: str, value: Any) -> Any:
    """A ``*_deg`` key's value in radians (checked to be a number first)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        where = f"[{table}] {key}" if table else key
        raise InputError(f"{path}: {where} = {value!r} is not a number [deg]", field=key)
    return math.radians(value)


def table_values(path: Path, table: str, content: Any, keymap: Mapping[str, str],
                 convert: Callable[[str, Any], Any] | None = None) -> dict[str, tuple[Binding, Any]]:
    """``field -> (binding, value)`` for the keys of one table, rejecting unknown keys.

    ``keymap`` maps the file's keys to dataclass fields; keys ending in ``_deg`` are converted to radians.

    Parameters
    ----------
    path : Path
        The file (messages).
    table : str
        The table's name.
    content : object
        The table as parsed.
    keymap : mapping of str to str
        File key -> dataclass field.
    convert : callable, optional
        ``convert(key, value)`` applied to each value after the degrees' conversion.

    Returns
    -------
    dict
        ``field -> (binding, value)``.

    Raises
    ------
    InputError
        For content that is not a table, an unknown key (with a "did you mean"), or a ``_deg`` value that is not a
        number.
    """
    if not isinstance(content, dict):
        raise InputError(f"{path}: [{table}] must be a table of keys, not {content!r}", field=table)
    out: dict[str, tuple[Binding, Any]] = {}
    for key, value in content.items():
        if key not in keymap:
            raise unknown_key(path, table, key, keymap)
        v = degrees_to_radians(path, table, key, value) if key.endswith("_deg") else value
        if convert is not None:
            v = convert(key, v)
        out[keymap[key]] = (Binding(table, key, value), v)
    return out


#: A file layout: table ("" for the top level) -> key -> (dataclass, field).
Layout = Mapping[str, Mapping[str, tuple[type, str]]]


def spec_values(path: Path, spec: Mapping[str, Any], layout: Layout, *, kind: str,
                skip: tuple[str, ...] = ("kind", "name", "source")) -> dict[type, dict[str, tuple[Binding, Any]]]:
    """Sort the keys of a parsed controller file into ``dataclass -> {field: (binding, value)}``.

    Parameters
    ----------
    path : Path
        The file (messages).
    spec : mapping
        The parsed file.
    layout : Layout
        ``table -> key -> (dataclass, field)`` (``""``: the top-level keys).
    kind : str
        The file's kind (messages).
    skip : tuple of str
        Top-level keys that are not settings (default ``kind``, ``name``, ``source``).

    Returns
    -------
    dict
        ``dataclass -> {field: (binding, value)}``.

    Raises
    ------
    InputError
        For an unknown table (``unknown section [x] for kind 'k'``) or key (with a "did you mean").
    """
    out: dict[type, dict[str, tuple[Binding, Any]]] = {}
    for key, value in spec.items():
        if key in skip:
            continue
        if isinstance(value, dict):
            if key not in layout or key == "":
                tables = [t for t in layout if t] + ["source"]
                close = difflib.get_close_matches(key, tables, n=1)
                hint = f"; did you mean [{close[0]}]?" if close else ""
                raise InputError(f"{path}: unknown section [{key}] for kind {kind!r}: expected one of "
                                 f"{', '.join(f'[{t}]' for t in tables)}{hint}", field=key)
            for sub, v in value.items():
                if sub not in layout[key]:
                    raise unknown_key(path, key, sub, sorted(layout[key]))
                cls, fname = layout[key][sub]
                out.setdefault(cls, {})[fname] = (Binding(key, sub, v), v)
            continue
        top = layout.get("", {})
        if key not in top:
            raise unknown_key(path, "", key, sorted([*top, *skip]), context=f" for kind {kind!r}")
        cls, fname = top[key]
        out.setdefault(cls, {})[fname] = (Binding("", key, value), value)
    return out


def _descriptor_link(path: Path) -> bool:
    """Whether ``path`` is, or links through, an open descriptor's name (``/dev/stdout``, ``/dev/stderr``,
    ``/dev/fd/N``, ``/proc/PID/fd/N``): what it leads to is the file the descriptor holds open, written into.
    A regular file elsewhere under /dev (a tmpfs such as /dev/shm) is not one."""
    for _ in range(40):  # (the kernel's own bound on a chain of links)
        parts = path.absolute().parts
        if parts[:3] in (("/", "dev", "stdout"), ("/", "dev", "stderr"), ("/", "dev", "fd")) or (
                len(parts) >= 5 and parts[1] == "proc" and parts[3] == "fd"):
            return True
        if not path.is_symlink():
            return False
        path = path.absolute().parent / os.readlink(path)
    return False


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    if hasattr(obj, "as_dict"):
        return obj.as_dict()
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def json_ready(o: Any) -> Any:
    """``o`` as the values ``json`` writes as they are: numpy arrays and scalars as lists and Python numbers, paths
    as strings, objects with ``as_dict`` as their dict, tuples as lists, inf and nan as None (JSON has no inf/nan:
    null); dict keys are left to ``json``. What every ``--json`` of the command line writes, and what a sweep's
    settings read back from one are compared as.

    Parameters
    ----------
    o : object
        Dicts, lists, tuples, numbers, strings, numpy arrays and scalars, paths, objects with ``as_dict``.

    Returns
    -------
    object
        A new object of dicts, lists, strings, ints, floats, bools and None.

    Raises
    ------
    TypeError
        Anything else.
    """
    if isinstance(o, str | int) or o is None:  # bool is an int
        return o
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, dict):
        return {k: json_ready(v) for k, v in o.items()}
    if isinstance(o, list | tuple):
        return [json_ready(v) for v in o]
    return json_ready(_json_default(o))


def write_whole(path: str | Path, write: str | Callable[[TextIO], Any], *,
                check: Callable[[Path], Any] | None = None) -> Path:
    """Write a file whole or not at all; return the path written.

    ``write`` (the text, or a function given the open file, opened with ``newline=""``) goes to a temporary file beside
    ``path`` (same suffix), ``check`` (if given) is called on it, and it then replaces ``path``, keeping an existing
    file's mode. A full disk, a Ctrl-C or a ``check`` that raises removes the temporary file and leaves ``path`` as it
    was (a review: 1 MB of a sweep's JSON, not valid JSON, after "cannot write ...: No space left on device"). A link
    is written through, onto its target; a device or a FIFO (``/dev/stdout``, ``/dev/null``) is written into, never
    replaced (as root, renaming over ``/dev/full`` replaced the device node). ``OSError`` propagates, for the caller
    to word.

    Parameters
    ----------
    path : str or Path
        The file to write.
    write : str or callable
        The text, or a function given the open text file.
    check : callable, optional
        Called with the temporary file's path before it replaces ``path``; what it raises propagates, and
        ``path`` is left as it was.

    Returns
    -------
    Path
        The path written (a link's target where ``path`` is a link).
    """
    path = Path(path)
    # a device, FIFO or pipe, through any links (``/dev/stdout`` into a pipe resolves to ``/proc/PID/fd/pipe:[N]``, no
    # path a file could be made beside: the temporary file failed there after the whole run)
    # (and a descriptor's link, even where it leads to a file: ``> out.json`` opened by the shell, or ``>> log``,
    # whose end a replaced file would not keep; a file in /dev/shm is a file, replaced)
    special = path.exists() and (not path.is_file() or _descriptor_link(path))
    if path.is_symlink() and not special:
        path = Path(os.path.realpath(path))

    def fill(fh: TextIO) -> None:
        if isinstance(write, str):
            fh.write(write)
        else:
            write(fh)

    # the temporary file beside the path; a device's (written into, never replaced) in the system's temporary folder,
    # under a name of its own (a fixed name there, shared by every user, could be a link planted to another file)
    if special:
        fd, name = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}")
        tmp = Path(name)
    else:
        fd, tmp = None, path.parent / f".{path.stem}.{os.getpid()}.tmp{path.suffix}"
    try:
        with (open(fd, "w", newline="") if fd is not None else open(tmp, "w", newline="")) as fh:
            fill(fh)
        if check is not None:
            check(tmp)
        if special:  # appended: opening /dev/stdout for "w" truncates a file the shell opened with >>
            # the checked text is copied, not written again: a writer that streams (a generator) runs once
            with open(tmp, newline="") as src, open(path, "a", newline="") as fh:
                shutil.copyfileobj(src, fh)
        else:
            if path.exists():
                shutil.copymode(path, tmp)
            os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path
