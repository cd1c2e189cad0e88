"""Model and controller files: TOML in, validated frozen dataclasses out.

A model is named by catalog name (``shing1993``) or by a path to a TOML file. Only this module and
:mod:`gearctl.files` locate the catalog folders: an explicit path wins; otherwise the name is looked up in
the installed copy (``gearctl/models`` inside the wheel) or, in a source checkout, the repository's
``models/`` folder.

Two model formats, one :class:`~gearctl.model.GearModel`:

- a pair: ``[gear1]``, ``[gear2]``, ``[pair]``, ``[material]``, ``[dynamics]`` (a one-stage train);
- a train: an ordered list of ``[[stage]]`` tables, each a pair with its own gear data, material,
  backlash and dynamics keys; top-level ``[material]`` and ``[dynamics]`` give defaults for every stage.

Both take ``[servo]``, ``[sensors]`` and a ``[source]`` with a citation.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from .design.registry import build_controller
from .errors import InputError
from .files import (
    Binding,
    build_dataclass,
    catalog_dirs,
    catalog_names,
    check_source,
    degrees_to_radians,
    read_toml,
    required_fields,
    resolve,
    table_values,
    unknown_key,
)
from .geometry import GearPair
from .model import GearModel, StageModel, check_model
from .params import MeshDynamics, Sensors, Servo
from .plant import MAX_STAGES
from .units import describe_rule

__all__ = [
    "GearModel",
    "StageModel",
    "load_model",
    "load_controller",
    "controller_names",
    "model_names",
    "catalog_dirs",
    "resolve",
    "read_toml",
    "PAIR_TABLES",
    "STAGE_KEYS",
]

# --- the schema: which key of which table feeds which dataclass field -----------------------------------

_GEAR_FIELDS = {f.name for f in dataclasses.fields(GearPair)}
_PAIR_KEYS = {"module": "module", "pressure_angle_deg": "pressure_angle", "face_width": "face_width",
              "backlash": "backlash", "addendum_coefficient": "addendum_coefficient",
              "dedendum_coefficient": "dedendum_coefficient"}
_MATERIAL_KEYS = {"young_modulus": "young_modulus", "poisson_ratio": "poisson_ratio", "density": "density"}
_DYNAMICS_KEYS = {k: k for k in ("damping_ratio", "mesh_stiffness", "damping_coefficient", "contact_law")}


def _gear_keys(j: int) -> dict[str, str]:
    keys = {"teeth": f"teeth{j}", "inertia": f"inertia{j}"}
    if f"x{j}" in _GEAR_FIELDS:
        keys["profile_shift"] = f"x{j}"
    return keys


#: table -> (dataclass, {key: field}, required) of the pair format
PAIR_TABLES: dict[str, tuple[type, dict[str, str], bool]] = {
    "gear1": (GearPair, _gear_keys(1), True),
    "gear2": (GearPair, _gear_keys(2), True),
    "pair": (GearPair, _PAIR_KEYS, True),
    "material": (GearPair, _MATERIAL_KEYS, True),
    "dynamics": (MeshDynamics, _DYNAMICS_KEYS, True),
}
_COMMON_TABLES: dict[str, tuple[type, dict[str, str]]] = {
    "servo": (Servo, {f.name: f.name for f in dataclasses.fields(Servo)}),
    "sensors": (Sensors, {f.name: f.name for f in dataclasses.fields(Sensors)}),
}
#: keys of a ``[[stage]]`` table -> (dataclass, field)
STAGE_KEYS: dict[str, tuple[type, str]] = {
    **{k: (GearPair, k) for k in ("teeth1", "teeth2", "inertia1", "inertia2") + (
        ("x1", "x2") if "x1" in _GEAR_FIELDS else ())},
    **{k: (GearPair, f) for k, f in _PAIR_KEYS.items()},
    **{k: (GearPair, f) for k, f in _MATERIAL_KEYS.items()},
    **{k: (MeshDynamics, f) for k, f in _DYNAMICS_KEYS.items() if k != "contact_law"},
}
_TRAIN_DEFAULTS = {"material": _MATERIAL_KEYS, "dynamics": {"damping_ratio": "damping_ratio",
                                                            "contact_law": "contact_law"}}
# where to add a missing required field, for the message
_PAIR_WHERE = {f: f"[{t}] {k}" for t, (_, km, _) in PAIR_TABLES.items() for k, f in km.items()}


def model_names() -> list[str]:
    """Names of the models in the catalog, sorted."""
    return catalog_names("models")


def controller_names() -> list[str]:
    """Names of the controllers in the catalog, sorted."""
    return catalog_names("controllers")


Values = dict[str, tuple[Binding, Any]]


def _apply_overrides(path: Path, per_class: dict[type, Values], overrides: Mapping[str, Any],
                     stage: str | None = None) -> None:
    classes = (GearPair, MeshDynamics, Servo, Sensors)
    for fname, value in overrides.items():
        owners = [cls for cls in classes if fname in {f.name for f in dataclasses.fields(cls)}]
        if not owners:
            every = sorted({f.name for cls in classes for f in dataclasses.fields(cls)})
            close = difflib.get_close_matches(fname, every, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise InputError(f"unknown override {fname!r}: expected a field of the model{hint}", field=fname)
        table = "override" if stage is None else f"override {stage}"
        per_class.setdefault(owners[0], {})[fname] = (Binding(table, fname, value), value)


def _missing(path: Path, cls: type, values: Values, where: Mapping[str, str]) -> None:
    for fname in sorted(required_fields(cls) - set(values)):
        label = where.get(fname, fname)
        meta = next(f.metadata for f in dataclasses.fields(cls) if f.name == fname)
        rule = describe_rule(dict(meta)) if "low" in meta else ""
        if label.endswith("_deg") and "low" in meta and math.isfinite(meta.get("high", math.inf)):
            # typed in degrees: the range in degrees (a closed one: the only such key, pressure_angle_deg)
            lo_op = "<" if meta.get("low_open") else "<="
            hi_op = "<" if meta.get("high_open") else "<="
            rule = f"{math.degrees(meta['low']):g} {lo_op} value {hi_op} {math.degrees(meta['high']):g} [deg]"
        what = f": {meta['doc']}, {rule}" if "doc" in meta and rule else ""
        raise InputError(f"{path}: missing key {label}{what}", field=label.split()[-1])


def _pair_model(path: Path, data: dict[str, Any], overrides: Mapping[str, Any]) -> tuple[StageModel, ...]:
    per: dict[type, Values] = {}
    for table, (cls, keymap, required) in PAIR_TABLES.items():
        if table not in data:
            if required:
                raise InputError(f"{path}: missing section [{table}] (keys: {', '.join(keymap)})", field=table)
            continue
        per.setdefault(cls, {}).update(table_values(path, table, data[table], keymap))
    for cls in (GearPair, MeshDynamics):
        per.setdefault(cls, {})
    _apply_overrides(path, per, {k: v for k, v in overrides.items() if k not in _servo_sensor_fields()})
    _missing(path, GearPair, per[GearPair], _PAIR_WHERE)
    pair = build_dataclass(path, GearPair, per[GearPair])
    dyn = build_dataclass(path, MeshDynamics, per[MeshDynamics])
    return (StageModel(pair=pair, dynamics=dyn),)


def _servo_sensor_fields() -> set[str]:
    return {f.name for cls in (Servo, Sensors) for f in dataclasses.fields(cls)}


def _train_model(path: Path, data: dict[str, Any], overrides: Mapping[str, Any]) -> tuple[StageModel, ...]:
    stages = data["stage"]
    if not isinstance(stages, list) or not stages or not all(isinstance(s, dict) for s in stages):
        raise InputError(f"{path}: [[stage]] must be a list of tables, one per stage", field="stage")
    if len(stages) > MAX_STAGES:
        raise InputError(f"{path}: {len(stages)} [[stage]] tables: expected at most {MAX_STAGES}", field="stage")
    defaults: dict[type, Values] = {GearPair: {}, MeshDynamics: {}}
    for table, keymap in _TRAIN_DEFAULTS.items():
        if table in data:
            cls = GearPair if table == "material" else MeshDynamics
            defaults[cls].update(table_values(path, table, data[table], keymap))
    out = []
    for i, content in enumerate(stages, start=1):
        label = f"stage {i}"
        per: dict[type, Values] = {GearPair: dict(defaults[GearPair]), MeshDynamics: dict(defaults[MeshDynamics])}
        for key, value in content.items():
            if key not in STAGE_KEYS:
                raise unknown_key(path, label, key, STAGE_KEYS)
            owner, fname = STAGE_KEYS[key]
            v = value
            if key.endswith("_deg"):
                v = degrees_to_radians(path, label, key, value)
            per[owner][fname] = (Binding(label, key, value), v)
        _apply_overrides(path, per, {k: v for k, v in overrides.items() if k not in _servo_sensor_fields()}, label)
        where = {f: f"[{label}] {k}" for k, (_, f) in STAGE_KEYS.items()}
        _missing(path, GearPair, per[GearPair], where)
        if "damping_ratio" not in per[MeshDynamics]:
            raise InputError(f"{path}: missing key [{label}] damping_ratio (or [dynamics] damping_ratio for every "
                             f"stage)", field="damping_ratio")
        out.append(StageModel(pair=build_dataclass(path, GearPair, per[GearPair]),
                              dynamics=build_dataclass(path, MeshDynamics, per[MeshDynamics])))
    return tuple(out)


def load_model(name_or_path: str | Path, **overrides: Any) -> GearModel:
    """Load a gear model (a pair or a train) by catalog name or TOML path.

    Parameters
    ----------
    name_or_path : str or Path
        A catalog name (see :func:`model_names`) or a path to a TOML file.
    **overrides
        Field values replacing the file's (e.g. ``backlash=0.0``; for a train, every stage's), validated
        like the file.

    Returns
    -------
    GearModel

    Raises
    ------
    InputError
        ``file: [table] key = value <rule>`` for any bad key or value, or an unknown model name.

    Examples
    --------
    >>> m = load_model("shing1993")
    >>> m.pair.teeth1, m.pair.teeth2
    (20, 80)
    """
    path = resolve(name_or_path, "models")
    data = read_toml(path)
    # `gearctl info controllers/pid.toml`: a controller file where the model goes
    if isinstance(data.get("kind"), str) and not ({"gear1", "stage"} & set(data)):
        raise InputError(f"{path}: a controller file (kind = {data['kind']!r}), not a model: a model file has the "
                         f"tables [gear1], [gear2], [pair], ... or [[stage]] (gearctl models lists the catalog's)",
                         field="model")
    train = "stage" in data
    pair_tables = set(PAIR_TABLES) - {"material", "dynamics"}
    known = ["stage", "material", "dynamics", *_COMMON_TABLES, "source"] if train else [
        *PAIR_TABLES, *_COMMON_TABLES, "source", "stage"]
    for table in data:
        if table not in known or (train and table in pair_tables):
            if train and table in pair_tables:
                raise InputError(f"{path}: [{table}] and [[stage]] in one file: a pair is either [gear1], [gear2], "
                                 f"[pair] or one [[stage]]", field=table)
            close = difflib.get_close_matches(table, known, n=1)
            hint = f"; did you mean [{close[0]}]?" if close else ""
            if not isinstance(data[table], dict | list):  # a key above every table (h3's review: "unknown section")
                raise InputError(f"{path}: key {table} = {data[table]!r} outside any section: every key belongs in "
                                 f"one of {', '.join(f'[{s}]' for s in known)} (a key typed above the first table "
                                 f"header){hint}", field=table)
            raise InputError(f"{path}: unknown section [{table}]: expected one of "
                             f"{', '.join(f'[{s}]' for s in known)}{hint}", field=table)
    if "source" not in data:
        raise InputError(f"{path}: missing section [source] (citation, table, notes)", field="source")
    source = check_source(path, data["source"])
    stages = _train_model(path, data, overrides) if train else _pair_model(path, data, overrides)
    common: dict[type, Values] = {}
    for table, (cls, keymap) in _COMMON_TABLES.items():
        if table in data:
            common[cls] = table_values(path, table, data[table], keymap)
    _apply_overrides(path, common, {k: v for k, v in overrides.items() if k in _servo_sensor_fields()})
    n_inter = len(stages) - 1
    for key in ("intermediate_inertia", "intermediate_viscous_friction", "intermediate_coulomb_friction"):
        given = data.get("servo", {}).get(key) if isinstance(data.get("servo"), dict) else None
        if isinstance(given, list) and len(given) != n_inter:  # an empty list too: one value per intermediate shaft
            count = f"{len(given)} value" + ("" if len(given) == 1 else "s")
            raise InputError(f"{path}: [servo] {key} = {given!r} has {count}: expected one per intermediate shaft "
                             f"({n_inter}; leave the key out for none added)", field=key)
    servo = build_dataclass(path, Servo, common[Servo]) if Servo in common else Servo()
    sensors = build_dataclass(path, Sensors, common[Sensors]) if Sensors in common else Sensors()
    model = GearModel(name=path.stem, stages=stages, servo=servo, sensors=sensors, source=source, path=path)
    try:
        check_model(model)
    except InputError as exc:
        raise InputError(f"{path}: {exc}", field=exc.field, rule=exc.rule) from None
    return model


def load_controller(name_or_path: str | Path, plant: Any, *, backlash: float | None = None,
                    sensors: Sensors | None = None, progress: Callable[[float], Any] | None = None) -> Any:
    """Load a controller by catalog name (``pid``, ``deadzone_inverse``, ``mpc``, ...) or TOML path.

    Parameters
    ----------
    name_or_path : str or Path
        Catalog name or path.
    plant : Plant
        The nominal plant it is designed on.
    backlash : float, optional
        Backlash estimate overriding the file's and the model's [m] (for a train: the lost motion's
        equivalent half-gap on the last stage's line of action, see :meth:`Plant.equivalent_pair`).
    sensors : Sensors, optional
        The model's encoders (``model.sensors``): the MPC's default observer noise follows them.
    progress : callable, optional
        Called with the fraction of the design done (an MPC's, which takes seconds to minutes at long horizons;
        see :func:`~gearctl.design.registry.build_controller`).

    Returns
    -------
    gearctl.design.Controller

    Raises
    ------
    InputError
        Unknown name, bad key or value.
    """
    from .plant import check_plant

    plant = check_plant(plant)
    path = resolve(name_or_path, "controllers")
    return build_controller(read_toml(path), plant, path=path, backlash=backlash, sensors=sensors,
                            progress=progress)
