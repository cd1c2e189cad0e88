"""Model and controller files: TOML in, validated frozen dataclasses out.

A model is named by catalog name (``shing1993``) or by a path to a TOML file. Only this module locates
the catalog folders: an explicit path wins; otherwise the name is looked up in the installed copy
(``gearctl/models`` inside the wheel) or, in a source checkout, the repository's ``models/`` folder.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import tomllib
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from .errors import InputError
from .geometry import GearPair
from .params import MeshDynamics, Sensors, Servo
from .units import describe_range

__all__ = [
    "GearModel",
    "load_model",
    "load_controller",
    "controller_names",
    "model_names",
    "catalog_dirs",
    "resolve",
    "read_toml",
    "build_sections",
    "MODEL_SCHEMA",
]

_PKG = Path(__file__).resolve().parent


def catalog_dirs(kind: str) -> list[Path]:
    """Folders searched for catalog entries of ``kind`` (``"models"`` or ``"controllers"``), in order."""
    return [d for d in (_PKG / kind, _PKG.parent / kind) if d.is_dir()]


def _names(kind: str) -> list[str]:
    names: dict[str, None] = {}
    for d in catalog_dirs(kind):
        for p in sorted(d.glob("*.toml")):
            names.setdefault(p.stem, None)
    return sorted(names)


def model_names() -> list[str]:
    """Names of the models in the catalog, sorted."""
    return _names("models")


def controller_names() -> list[str]:
    """Names of the controllers in the catalog, sorted."""
    return _names("controllers")


def resolve(name_or_path: str | Path, kind: str) -> Path:
    """Find the TOML file of a catalog entry or path.

    Raises
    ------
    InputError
        If it is neither an existing file nor a catalog name; the message lists close names.
    """
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists() or len(p.parts) > 1:
        if p.is_file():
            return p
        raise InputError(f"{kind[:-1]} file {str(p)!r} does not exist", field=kind[:-1])
    for d in catalog_dirs(kind):
        cand = d / f"{p.name}.toml"
        if cand.is_file():
            return cand
    names = _names(kind)
    close = difflib.get_close_matches(str(name_or_path), names, n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    raise InputError(
        f"unknown {kind[:-1]} {str(name_or_path)!r}: expected a catalog name ({', '.join(names)}) or a path "
        f"to a .toml file{hint}",
        field=kind[:-1],
    )


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file, turning syntax errors into :class:`InputError` naming the file."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot be read: {exc.strerror}") from None


# --- schema -------------------------------------------------------------------------------------------
# section -> {toml key: dataclass field}; keys ending in _deg are converted to radians.
MODEL_SCHEMA: dict[str, tuple[type, dict[str, str], bool]] = {
    # section: (dataclass, key map, required section)
    "gear1": (GearPair, {"teeth": "teeth1", "inertia": "inertia1"}, True),
    "gear2": (GearPair, {"teeth": "teeth2", "inertia": "inertia2"}, True),
    "pair": (
        GearPair,
        {
            "module": "module",
            "pressure_angle_deg": "pressure_angle",
            "face_width": "face_width",
            "backlash": "backlash",
            "addendum_coefficient": "addendum_coefficient",
            "dedendum_coefficient": "dedendum_coefficient",
        },
        True,
    ),
    "material": (
        GearPair,
        {"young_modulus": "young_modulus", "poisson_ratio": "poisson_ratio", "density": "density"},
        True,
    ),
    "dynamics": (
        MeshDynamics,
        {k: k for k in ("damping_ratio", "mesh_stiffness", "damping_coefficient", "contact_law")},
        True,
    ),
    "servo": (Servo, {f.name: f.name for f in dataclasses.fields(Servo)}, False),
    "sensors": (Sensors, {f.name: f.name for f in dataclasses.fields(Sensors)}, False),
}

_SOURCE_KEYS = {"citation": True, "table": False, "notes": False, "url": False, "doi": False}


def _field_meta(cls: type, name: str) -> Mapping[str, Any]:
    for f in dataclasses.fields(cls):
        if f.name == name:
            return f.metadata
    raise KeyError(name)


def _required(cls: type) -> set[str]:
    return {
        f.name
        for f in dataclasses.fields(cls)
        if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    }


def build_sections(
    path: Path,
    data: Mapping[str, Any],
    schema: Mapping[str, tuple[type, dict[str, str], bool]],
    *,
    extra_sections: Mapping[str, Callable[[str, Any], None]] | None = None,
    overrides: Mapping[str, Any] | None = None,
) -> dict[type, Any]:
    """Build the dataclasses of a TOML document section by section, validating every key.

    Parameters
    ----------
    path : Path
        File name, used in messages.
    data : mapping
        The parsed TOML document.
    schema : mapping
        ``section -> (dataclass, {key: field}, required)``. Several sections may feed one dataclass.
    extra_sections : mapping, optional
        ``section -> checker(section, value)`` for sections outside the schema (e.g. ``[source]``).
    overrides : mapping, optional
        ``field -> value`` replacing what the file says (e.g. a ``--backlash`` option).

    Returns
    -------
    dict
        ``dataclass -> instance`` for every dataclass named in the schema with at least one key given
        (or required).

    Raises
    ------
    InputError
        ``file: [section] key = value <rule>`` for an unknown, missing, mistyped or out-of-range key.
    """
    extra_sections = extra_sections or {}
    known = list(schema) + list(extra_sections)
    kwargs: dict[type, dict[str, Any]] = {}
    where: dict[str, tuple[str, str, Any]] = {}  # field -> (section, key, raw value)
    for section, content in data.items():
        if section in extra_sections:
            extra_sections[section](section, content)
            continue
        if section not in schema:
            close = difflib.get_close_matches(section, known, n=1)
            hint = f"; did you mean [{close[0]}]?" if close else ""
            raise InputError(
                f"{path}: unknown section [{section}]: expected one of {', '.join(f'[{s}]' for s in known)}{hint}",
                field=section,
            )
        if not isinstance(content, dict):
            raise InputError(f"{path}: [{section}] must be a table of keys, not {content!r}", field=section)
        cls, keymap, _ = schema[section]
        for key, value in content.items():
            if key not in keymap:
                close = difflib.get_close_matches(key, list(keymap), n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise InputError(
                    f"{path}: unknown key [{section}] {key}: expected one of {', '.join(keymap)}{hint}",
                    field=key,
                )
            fname = keymap[key]
            v = value
            if key.endswith("_deg"):
                if isinstance(v, bool) or not isinstance(v, int | float):
                    raise InputError(f"{path}: [{section}] {key} = {value!r} is not a number [deg]", field=key)
                v = math.radians(v)
            kwargs.setdefault(cls, {})[fname] = v
            where[fname] = (section, key, value)
    # missing sections / keys
    for section, (cls, keymap, required) in schema.items():
        if required and section not in data:
            raise InputError(f"{path}: missing section [{section}] (keys: {', '.join(keymap)})", field=section)
        if section in data or required:
            kwargs.setdefault(cls, {})
        for key, fname in keymap.items():
            if fname in _required(cls) and fname not in kwargs.get(cls, {}) and section in data:
                meta = _field_meta(cls, fname)
                unit = "" if meta.get("unit") in (None, "1") else f" [{meta['unit']}]"
                raise InputError(
                    f"{path}: missing key [{section}] {key}: {meta.get('doc', '')}, {describe_range(meta)}{unit}",
                    field=key,
                )
    for fname, value in (overrides or {}).items():
        owners = [cls for cls, _, _ in schema.values() if fname in {f.name for f in dataclasses.fields(cls)}]
        if not owners:
            every = sorted({f.name for cls, _, _ in schema.values() for f in dataclasses.fields(cls)})
            close = difflib.get_close_matches(fname, every, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise InputError(f"unknown override {fname!r}: expected a field of the model{hint}", field=fname)
        kwargs.setdefault(owners[0], {})[fname] = value
        where[fname] = ("override", fname, value)
    out: dict[type, Any] = {}
    for cls, kw in kwargs.items():
        try:
            out[cls] = cls(**kw)
        except InputError as exc:
            raise _restate(path, exc, where, cls) from None
        except TypeError as exc:  # a value of a type the dataclass cannot take at all
            raise InputError(f"{path}: {exc}") from None
    return out


def _restate(path: Path, exc: InputError, where: Mapping[str, tuple[str, str, Any]], cls: type) -> InputError:
    """Restate a dataclass validation error with the file, section and key the user typed."""
    if exc.field in where and exc.rule:
        section, key, raw = where[exc.field]
        rule = exc.rule
        if key.endswith("_deg"):
            meta = _field_meta(cls, exc.field)
            lo, hi = math.degrees(meta["low"]), math.degrees(meta["high"])
            rule = f"is out of range: expected a number with {lo:g} <= value <= {hi:g} [deg]"
        label = f"--{key.replace('_', '-')}" if section == "override" else f"[{section}] {key}"
        return InputError(f"{path}: {label} = {raw!r} {rule}", field=key, rule=rule)
    return InputError(f"{path}: {exc}", field=exc.field, rule=exc.rule)


def _check_source(path: Path) -> Callable[[str, Any], None]:
    def check(section: str, content: Any) -> None:
        if not isinstance(content, dict):
            raise InputError(f"{path}: [source] must be a table with a citation", field="source")
        for key, value in content.items():
            if key not in _SOURCE_KEYS:
                close = difflib.get_close_matches(key, list(_SOURCE_KEYS), n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise InputError(
                    f"{path}: unknown key [source] {key}: expected one of {', '.join(_SOURCE_KEYS)}{hint}",
                    field=key,
                )
            if not isinstance(value, str):
                raise InputError(f"{path}: [source] {key} = {value!r} must be a string", field=key)
        for key, needed in _SOURCE_KEYS.items():
            if needed and key not in content:
                raise InputError(f"{path}: missing key [source] {key}: where the data come from", field=key)

    return check


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class GearModel:
    """A gear-train definition from the catalog: the pair, its dynamics, the servo and sensors.

    Variants are made with :func:`dataclasses.replace`, e.g. a backlash-free copy with
    ``dataclasses.replace(model, pair=dataclasses.replace(model.pair, backlash=0.0))``.
    """

    name: str
    pair: GearPair
    dynamics: MeshDynamics
    servo: Servo = dataclasses.field(default_factory=Servo)
    sensors: Sensors = dataclasses.field(default_factory=Sensors)
    source: Mapping[str, str] = dataclasses.field(default_factory=dict)
    path: Path | None = None

    def with_backlash(self, backlash: float) -> GearModel:
        """Copy with another backlash [m] (0 gives the backlash-free plant)."""
        return dataclasses.replace(self, pair=dataclasses.replace(self.pair, backlash=backlash))


def load_model(name_or_path: str | Path, **overrides: Any) -> GearModel:
    """Load a gear model by catalog name or TOML path.

    Parameters
    ----------
    name_or_path : str or Path
        A catalog name (see :func:`model_names`) or a path to a TOML file.
    **overrides
        Field values replacing the file's (e.g. ``backlash=0.0``), validated like the file.

    Returns
    -------
    GearModel

    Raises
    ------
    InputError
        ``file: [section] key = value <rule>`` for any bad key or value, or an unknown model name.

    Examples
    --------
    >>> m = load_model("shing1993")
    >>> m.pair.teeth1, m.pair.teeth2
    (20, 80)
    """
    path = resolve(name_or_path, "models")
    data = read_toml(path)
    built = build_sections(
        path, data, MODEL_SCHEMA, extra_sections={"source": _check_source(path)}, overrides=overrides
    )
    if "source" not in data:
        raise InputError(f"{path}: missing section [source] (citation, table, notes)", field="source")
    return GearModel(
        name=path.stem,
        pair=built[GearPair],
        dynamics=built[MeshDynamics],
        servo=built.get(Servo, Servo()),
        sensors=built.get(Sensors, Sensors()),
        source=dict(data["source"]),
        path=path,
    )


def load_controller(name_or_path: str | Path, plant: Any, *, backlash: float | None = None) -> Any:
    """Load a controller by catalog name (``pid``, ``deadzone_inverse``, ``mpc``) or TOML path.

    Parameters
    ----------
    name_or_path : str or Path
        Catalog name or path.
    plant : Plant
        The nominal plant it is designed on.
    backlash : float, optional
        Backlash estimate overriding the file's and the model's [m].

    Returns
    -------
    gearctl.design.Controller

    Raises
    ------
    InputError
        Unknown name, bad key or value.
    """
    from .design.registry import build_controller

    path = resolve(name_or_path, "controllers")
    return build_controller(read_toml(path), plant, path=path, backlash=backlash)
