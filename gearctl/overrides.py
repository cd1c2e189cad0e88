"""A gear model with some of its values changed: ``gearctl track --set KEY=VALUE``, a sweep's runs.

A value is either absolute (on a train, every stage's) or a :class:`Scale`, a factor of the nominal value (on a
train, of each stage's own value: ``--set backlash=1.5x``). A stage key prefixed ``stageN.`` changes stage N's
alone (``--set stage2.backlash=3e-5``, ``--vary stage1.mesh_stiffness=0.8x:1.2x``; N from 1, the motor's stage).
Below the runs and the sweeps, which both use it.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from .errors import InputError
from .geometry import GearPair, pair_geometry
from .model import GearModel, check_model
from .params import FrictionLaw, MeshDynamics, Sensors, Servo
from .plant import build_plant
from .units import check_number

__all__ = ["Scale", "perturb_model", "stage_values", "split_stage_key", "check_keys_act", "MODEL_CLASSES",
           "OWNER_FIELDS", "UNREAD_BY_PLANT", "FILE_NAMES", "file_name_error"]

#: The dataclasses whose fields a model key names, in the order an override looks for it.
MODEL_CLASSES: tuple[type, ...] = (GearPair, MeshDynamics, Servo, Sensors)
#: Each class's field names.
OWNER_FIELDS = {cls: {f.name for f in dataclasses.fields(cls)} for cls in MODEL_CLASSES}


#: A model file's names of the keys that overrides spell as a stage's fields: (where the file has it, what to write;
#: ``{pre}`` is the key's ``stageN.`` prefix, if any).
FILE_NAMES = {
    "teeth": ("[gear1] and [gear2] teeth", "{pre}teeth1 (gear 1's) or {pre}teeth2 (gear 2's)"),
    "profile_shift": ("[gear1] and [gear2] profile_shift", "{pre}x1 (gear 1's) or {pre}x2 (gear 2's)"),
    "inertia": ("[gear1] and [gear2] inertia", "{pre}inertia1 (gear 1's) or {pre}inertia2 (gear 2's) [kg m^2]"),
    "pressure_angle_deg": ("[pair] or [[stage]] pressure_angle_deg, in degrees",
                           "{pre}pressure_angle, in rad (20 deg = 0.349)"),
}


def file_name_error(key: str, field: str, by: str, pre: str = "") -> InputError:
    """The error for ``key``, whose field ``field`` is spelt with a model file's name (:data:`FILE_NAMES`): where the
    file has it and how ``by`` (``--set``, ``--vary``, an override) names it, with the stage prefix ``pre``.

    Parameters
    ----------
    key : str
        The key as given (``stage2.pressure_angle_deg``).
    field : str
        Its field, a key of :data:`FILE_NAMES`.
    by : str
        What named it (``"--set"``, ``"--vary"``, ``"an override"``).
    pre : str
        The stage prefix to write in the suggested spelling (default ``""``).

    Returns
    -------
    InputError
        The error (not raised), field ``key``.
    """
    where, spelling = FILE_NAMES[field]
    lead = key if field == key else f"{key}: {field}"
    return InputError(f"{lead} is the model file's name ({where}); {by} names it " + spelling.format(pre=pre),
                      field=key)


#: A key of one stage: ``stage2.backlash``.
STAGE_KEY = re.compile(r"^stage(\d+)\.(\w+)$")


def split_stage_key(key: str) -> tuple[int | None, str]:
    """``(stage index from 0, field)`` of a ``stageN.field`` key, ``(None, key)`` for any other; a ``stageN.`` prefix
    on a field that is not a stage's (a gear pair's or its mesh dynamics') is refused naming the key.

    Parameters
    ----------
    key : str
        A model key, with or without a ``stageN.`` prefix (N from 1).

    Returns
    -------
    tuple
        ``(stage index from 0, field)``, or ``(None, key)``.

    Raises
    ------
    InputError
        For a stage number with leading zeros or below 1, a file's spelling of the field (``_deg``), or a field
        that is not a gear pair's or mesh dynamics' (with a "did you mean").
    """
    m = STAGE_KEY.match(key)
    if m is None:
        return None, key
    n, field = int(m.group(1)), m.group(2)
    if m.group(1) != str(n):
        raise InputError(f"{key}: write the stage number without leading zeros (stage{n}.{field})", field=key)
    if field in FILE_NAMES:  # stage2.pressure_angle_deg: the file's name, not an override's (as without the prefix)
        raise file_name_error(key, field, "an override", pre=f"stage{n}.")
    if not (field in OWNER_FIELDS[GearPair] or field in OWNER_FIELDS[MeshDynamics]):
        import difflib

        units = {f.name: f.metadata.get("unit") for cls in (GearPair, MeshDynamics) for f in dataclasses.fields(cls)}
        close = difflib.get_close_matches(field, sorted(k for k, u in units.items() if u), n=1)  # numbers only
        hint = (f"; {field} is not a stage's: give it without the prefix" if field in OWNER_FIELDS[Servo] |
                OWNER_FIELDS[Sensors] else f"; did you mean 'stage{n}.{close[0]}' [{units[close[0]]}]?" if close
                else "")
        raise InputError(f"{key}: {field} is not a stage's key (a stageN. prefix takes a gear pair's or its mesh "
                         f"dynamics' key: backlash, mesh_stiffness, damping_ratio, face_width, ...){hint}", field=key)
    if n < 1:
        raise InputError(f"{key}: stages are numbered from 1 (the motor's)", field=key)
    return n - 1, field


#: Model keys a true plant does not read, by plant kind: the Yang-Sun plant's stiffness is Hertz's (eq 39) and its
#: damping comes from each impact's restitution (eqs 36-37), whatever the mesh dynamics say.
UNREAD_BY_PLANT: dict[str, tuple[str, ...]] = {"yang-sun": ("mesh_stiffness", "damping_ratio", "damping_coefficient")}


def check_keys_act(keys: Iterable[str], plant: str, model: GearModel | None = None, *, option: str = "--set") -> None:
    """Refuse a changed key (``stageN.`` or not) that the true plant does not read: the ``plant`` kind's
    (:data:`UNREAD_BY_PLANT`), or ``coulomb_velocity`` where ``model``'s friction law is stick-slip (it is the smooth
    law's). Its runs would all be the nominal plant's, and a sweep reported no sensitivity to it without a word.
    A material key that feeds only the mesh stiffness is refused too where ``model`` sets its mesh stiffness.

    Parameters
    ----------
    keys : iterable of str
        The changed keys (``stageN.`` or not).
    plant : str
        The true plant's kind (``improved``, ``yang-sun``, ``tvms``).
    model : GearModel, optional
        The model (without it, the checks that need it are skipped).
    option : str
        The option that changed them, for the message (default ``"--set"``).

    Raises
    ------
    InputError
        Naming the option, the key, the plant and where the key acts.
    """
    unread = UNREAD_BY_PLANT.get(str(plant), ())
    for key in keys:
        m = STAGE_KEY.match(key)
        field = m.group(2) if m else key
        if field in unread:
            raise InputError(f"{option} {key}: the {plant} plant does not read {field} (its stiffness is Hertz's, eq "
                             f"39, and its damping comes from the restitution, eqs 36-37), so it would change "
                             f"nothing; change it on the improved or tvms plant", field=key)
        if field in MATERIAL_STIFFNESS_KEYS and model is not None and _plant_unchanged(model, key, field, plant):
            table = "[[stage]]" if model.n_stages > 1 else "[dynamics]"
            raise InputError(f"{option} {key}: {model.name} sets its mesh stiffness (mesh_stiffness in {table}), "
                             f"so {field}, which feeds only the stiffness, would change nothing on the {plant} plant; "
                             f"change mesh_stiffness instead", field=key)
        if field == "coulomb_velocity" and model is not None and model.servo.friction_law is FrictionLaw.STICK_SLIP:
            raise InputError(f"{option} {key}: {model.name}'s friction_law is stick_slip, which does not read "
                             f"coulomb_velocity (the smooth law's omega_s), so it would change nothing; set "
                             f"friction_law = \"smooth\" in the model's [servo] to vary it", field=key)


#: Material keys that feed only the mesh stiffness (and the Yang-Sun plant's Hertz stiffness): a model that sets
#: ``mesh_stiffness`` leaves them nothing to change on the improved and tvms plants.
MATERIAL_STIFFNESS_KEYS: tuple[str, ...] = ("young_modulus", "poisson_ratio")


def _plant_unchanged(model: GearModel, key: str, field: str, plant: str) -> bool:
    """Whether changing ``key`` (``field`` of every stage, or of one) by 10 % leaves the ``plant`` kind built from
    ``model`` equal, field for field."""
    index, _ = split_stage_key(key)
    if index is not None and index >= model.n_stages:
        return False  # no such stage: perturb_model says so
    meta = next(f.metadata for f in dataclasses.fields(GearPair) if f.name == field)
    bumped = {}
    for i in range(model.n_stages) if index is None else (index,):
        # each changed stage's own value by 10 %, up or down, whichever stays inside the key's range: one factor
        # for all left a train with one stage near each end of the range (or a stage key's stage near one end
        # while another stage sat near the other) unchecked, a no-op taken without a word
        v = getattr(model.stages[i].pair, field)
        bumped[f"stage{i + 1}.{field}"] = next((x for x in (v * 1.1, v * 0.9) if _inside(meta, x)), v * 1.1)
    try:
        return _same(build_plant(perturb_model(model, bumped), plant), build_plant(model, plant))
    except InputError:  # out of range: let the runs say so
        return False


def _inside(meta: Mapping[str, Any], x: float) -> bool:
    """Whether ``x`` is inside the range of a field's ``quantity`` metadata (:func:`~gearctl.units.check_number`)."""
    try:
        check_number("value", x, dict(meta))
    except InputError:
        return False
    return True


#: Relative difference of a plant's numbers taken as rounding: the tvms plant's K(theta) is eq 21 (proportional to
#: E) scaled to the set mean, so a changed young_modulus moved its table by 6e-16, and the sweep ran every run on
#: the same plant but for the last bit ('rank correlation +0.00, elasticity -7e-08'). A key that acts, changed by
#: 10 %, moves a number by far more (poisson_ratio shapes that table by 1e-4).
ROUNDING = 1e-12


def _same(a: Any, b: Any) -> bool:
    """Field-for-field equality of plants, up to :data:`ROUNDING` (their dataclasses compare by identity; arrays by
    value)."""
    if dataclasses.is_dataclass(a) and type(a) is type(b):
        return all(_same(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    if isinstance(a, tuple | list) and isinstance(b, tuple | list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if hasattr(a, "shape") or hasattr(b, "shape"):
        if not (hasattr(a, "shape") and hasattr(b, "shape") and a.shape == b.shape):
            return False
        if getattr(a, "dtype", None) is not None and a.dtype.kind in "fc" and a.size:
            scale = max(float(np.max(np.abs(a))), float(np.max(np.abs(b))))
            return bool(np.all((a == b) | (np.abs(a - b) <= ROUNDING * scale)))  # NaN: not the same
        return bool((a == b).all())
    if isinstance(a, float) and isinstance(b, float) and a != b:
        return abs(a - b) <= ROUNDING * max(abs(a), abs(b))  # NaN, inf against a number: not the same
    return bool(a == b)


class Scale(float):
    """A model value given as a factor of the nominal one (``--set backlash=1.5x``): on a train, each stage's own
    value times it (the reading of a relative sweep spec on a train whose stages differ in the key)."""

    __slots__ = ()

    def __repr__(self) -> str:
        return f"{float(self)!r}x"


def _check_scalable(key: str, factor: float, nominals: list[float]) -> None:
    """Refuse a factor other than 0 of a key whose nominal value is 0 (on a train, every stage's): every factor of 0
    is 0, so ``--set coulomb_friction2=2x`` ran the nominal plant without a word (``--vary`` refuses it too)."""
    if factor != 0.0 and all(v == 0.0 for v in nominals):
        raise InputError(f"{key} = {factor!r}: the nominal {key} is 0, so every factor of it is 0 (the plant would "
                         f"not change); give a number", field=key)


def perturb_model(model: GearModel, overrides: Mapping[str, float]) -> GearModel:
    """The model with some fields changed (every stage's, for a stage key), checked like a model file.

    The same values as :func:`gearctl.catalog.load_model` with ``**overrides`` gives for the model's file,
    built from the loaded model (a remote worker needs no file).

    Parameters
    ----------
    model : GearModel
        The loaded model.
    overrides : mapping of str to float
        ``key -> value`` (a ``stageN.`` key: that stage's alone; a :class:`Scale`: a factor of the nominal value,
        each stage's own on a train).

    Returns
    -------
    GearModel

    Raises
    ------
    InputError
        A key that is not a model key (or a bad ``stageN.`` key, :func:`split_stage_key`), a stage beyond the
        model's, a factor of a value that has no finite nominal, a value out of its range, or a model the changed
        value makes invalid (:func:`check_model`).
    """
    per: dict[type, dict[str, Any]] = {cls: {} for cls in MODEL_CLASSES}
    scaled: dict[str, float] = {}  # stage keys given as a factor of each stage's own value
    one: dict[int, dict[str, Any]] = {}  # stageN.key: stage N's alone, after the every-stage ones
    for key, value in overrides.items():
        i, field = split_stage_key(key)
        if i is not None:
            if i >= len(model.stages):
                raise InputError(f"{key}: {model.name} has {len(model.stages)} stage"
                                 f"{'s' if len(model.stages) > 1 else ''}: expected stage1 .. "
                                 f"stage{len(model.stages)}", field=key)
            if isinstance(value, Scale):
                _check_scalable(key, value, [stage_values(field, model)[i]])
                value = float(value) * stage_values(field, model)[i]
            one.setdefault(i, {})[field] = value
            continue
        owner = next((cls for cls in MODEL_CLASSES if key in OWNER_FIELDS[cls]), None)
        if owner is None:
            raise InputError(f"{key} is not a model key", field=key)
        if isinstance(value, Scale):
            if owner in (GearPair, MeshDynamics):
                _check_scalable(key, value, stage_values(key, model))
                scaled[key] = float(value)
                continue
            nominal = getattr(model.servo if owner is Servo else model.sensors, key)
            if nominal is None or not math.isfinite(nominal):
                raise InputError(f"{key} = {value!r}: {key} has no nominal value to scale; give a number", field=key)
            _check_scalable(key, value, [nominal])
            value = float(value) * float(nominal)
        per[owner][key] = value
    # an every-stage key that a stageN. key overrides on every stage changes nothing: refused, not dropped (a pair's
    # `--set stage1.backlash=3e-5 --set backlash=1e-5` ran with 3e-5 and said nothing of the 1e-5)
    for key in (*scaled, *per[GearPair], *per[MeshDynamics]):
        if all(key in one.get(i, {}) for i in range(len(model.stages))):
            named = ", ".join(f"stage{i + 1}.{key}" for i in range(len(model.stages)))
            many = len(model.stages) > 1
            raise InputError(f"{key} and {named}: the stage key{'s set every' if many else ' sets the'} stage's "
                             f"{key} after {key}, so {key} would change nothing: give one of them", field=key)
    values = {key: stage_values(key, model) for key in scaled}

    def stage_fields(cls: type, i: int) -> dict[str, Any]:
        out = dict(per[cls])
        out.update({k: f * values[k][i] for k, f in scaled.items() if k in OWNER_FIELDS[cls]})
        out.update({k: v for k, v in one.get(i, {}).items() if k in OWNER_FIELDS[cls]})
        return out

    stages = []
    for i, sm in enumerate(model.stages):
        pf, df = stage_fields(GearPair, i), stage_fields(MeshDynamics, i)
        try:
            stages.append(dataclasses.replace(sm, pair=dataclasses.replace(sm.pair, **pf) if pf else sm.pair,
                                              dynamics=dataclasses.replace(sm.dynamics, **df) if df else sm.dynamics))
        except InputError as exc:  # a check across a stage's keys (undercut, interference): name the stage
            if len(model.stages) == 1:
                raise
            raise InputError(f"[stage {i + 1}] {exc}", field=exc.field, rule=exc.rule) from None
    out = dataclasses.replace(
        model, stages=tuple(stages),
        servo=dataclasses.replace(model.servo, **per[Servo]) if per[Servo] else model.servo,
        sensors=dataclasses.replace(model.sensors, **per[Sensors]) if per[Sensors] else model.sensors)
    check_model(out)
    return out


def stage_values(key: str, model: GearModel) -> list[float]:
    """Each stage's value of a stage key (a computed one, e.g. an unset ``mesh_stiffness``: the plant's).

    Parameters
    ----------
    key : str
        A field of :class:`~gearctl.geometry.GearPair` or :class:`~gearctl.params.MeshDynamics`, without prefix.
    model : GearModel
        The model.

    Returns
    -------
    list of float
        One value per stage, in the field's unit.
    """
    pair = key in OWNER_FIELDS[GearPair]
    vals = []
    plant = None
    for i, sm in enumerate(model.stages):
        v = getattr(sm.pair if pair else sm.dynamics, key)
        if v is None:  # computed: the plant's value
            if key in ("inertia1", "inertia2"):
                v = pair_geometry(sm.pair).inertia[0 if key == "inertia1" else 1]
            else:
                plant = plant or build_plant(model)
                v = plant.stages[i].k if key == "mesh_stiffness" else plant.stages[i].c
        vals.append(float(v))
    return vals
