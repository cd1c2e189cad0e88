"""The parameter schema: every physical quantity's unit and allowed range, declared once.

A :class:`Spec` states a quantity's unit, allowed range and one-line meaning. The named specs below
(:data:`BACKLASH`, :data:`INERTIA`, ...) are the only place those ranges are written: the model and
controller dataclasses declare their fields with :meth:`Spec.field`, :func:`validate_fields` checks an
instance against them, and the TOML loader, the CLI, error messages and plot labels read the same
metadata. A value valid in one place is valid everywhere.

Every number must be finite unless its spec allows infinity as "none" (a torque limit). A quantity whose
zero means "none" (a backlash) may also have a physical floor: 0, or at least the floor.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from typing import Any

from .errors import InputError, short_repr

__all__ = [
    "Spec", "quantity", "check_choice", "validate_fields", "describe_range", "describe_rule", "field_unit",
    "check_number", "MODULE", "FACE_WIDTH", "BACKLASH_FLOOR",
    "BACKLASH", "GAP", "INERTIA", "ADDED_INERTIA", "VISCOUS_FRICTION", "COULOMB_FRICTION", "COULOMB_VELOCITY",
    "TORQUE_LIMIT", "LOAD_TORQUE", "MESH_STIFFNESS", "MESH_DAMPING", "DAMPING_RATIO", "BASE_RADIUS",
    "SAMPLE_TIME", "ENCODER_CPR", "ENCODER_NOISE", "DURATION", "OUTPUT_INTERVAL", "SEED", "POINTS",
]


@dataclasses.dataclass(frozen=True, slots=True)
class Spec:
    """Unit, allowed range and meaning of one kind of quantity.

    Attributes
    ----------
    unit : str
        SI unit, e.g. ``"m"``, ``"kg m^2"``; ``"1"`` for dimensionless.
    doc : str
        One-line description (error messages, README tables).
    low, high : float or None
        Bounds of the allowed range (``None``: unbounded on that side).
    low_open, high_open : bool
        Whether the bound itself is excluded.
    integer : bool
        Whether the value must be a whole number.
    allow_inf : bool
        Whether ``+inf`` is allowed (it means "none", e.g. no torque limit).
    floor : float or None
        Physical floor of a quantity whose 0 means "none": a value inside ``[low, high]`` must be 0 or at
        least ``floor`` (a backlash of 1e-124 m is no backlash a machine has, and NaN in a controller).
    """

    unit: str
    doc: str
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    integer: bool = False
    allow_inf: bool = False
    floor: float | None = None

    def meta(self, *, doc: str | None = None, optional: bool = False, sequence: bool = False) -> dict[str, Any]:
        """Field metadata of this spec (what :func:`validate_fields` reads).

        Parameters
        ----------
        doc : str, optional
            The field's own description (default: the spec's).
        optional : bool
            Whether ``None`` is allowed (default False).
        sequence : bool
            Whether the field holds a sequence of such values, each checked (default False).

        Returns
        -------
        dict
            ``unit``, ``doc``, the range (``low``, ``high``, ``low_open``, ``high_open``, ``integer``,
            ``allow_inf``, ``floor``), ``optional`` and ``sequence``.
        """
        return {"unit": self.unit, "doc": doc or self.doc, "low": self.low, "high": self.high,
                "low_open": self.low_open, "high_open": self.high_open, "integer": self.integer,
                "allow_inf": self.allow_inf, "floor": self.floor, "optional": optional, "sequence": sequence}

    def field(self, *, default: Any = dataclasses.MISSING, doc: str | None = None, optional: bool = False,
              sequence: bool = False) -> Any:
        """A dataclass field of this quantity (``sequence``: a tuple of such values).

        Parameters
        ----------
        default : optional
            Default value; without it the field is required.
        doc : str, optional
            The field's own description (default: the spec's).
        optional : bool
            Whether ``None`` is allowed (default False).
        sequence : bool
            Whether the field holds a sequence of such values, each checked (default False).

        Returns
        -------
        dataclasses.Field
        """
        return dataclasses.field(default=default, metadata=self.meta(doc=doc, optional=optional, sequence=sequence))

    def check(self, name: str, value: Any) -> float:
        """Return ``value`` as a float if it is allowed, else raise :class:`InputError` naming ``name``.

        Parameters
        ----------
        name : str
            The name the message gives the value.
        value : object
            The value to check.

        Returns
        -------
        float

        Raises
        ------
        InputError
            As :func:`check_number`.
        """
        return check_number(name, value, self.meta())

    @property
    def upper(self) -> float:
        """``high``, for a spec that has one (code that computes with the bound); TypeError for an unbounded one."""
        if self.high is None:
            raise TypeError(f"the spec of {self.doc} has no upper bound")
        return self.high

    def rule(self) -> str:
        """The allowed range in words with the unit, e.g. ``"0 <= value <= 0.01 [m], either 0 or at least 1e-09"``."""
        return describe_rule(self.meta())


def quantity(
    *,
    unit: str,
    doc: str,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    integer: bool = False,
    optional: bool = False,
    allow_inf: bool = False,
    floor: float | None = None,
    default: Any = dataclasses.MISSING,
) -> Any:
    """Declare a physical dataclass field with its unit and allowed range (a one-off :class:`Spec`).

    Parameters
    ----------
    unit : str
        SI unit, e.g. ``"m"``, ``"N/m"``, ``"kg m^2"``; ``"1"`` for dimensionless.
    doc : str
        One-line description, used in error messages and the README.
    low, high : float, optional
        Bounds of the allowed range (``None``: unbounded).
    low_open, high_open : bool
        Whether the bound itself is excluded.
    integer : bool
        Whether the value must be a whole number.
    optional : bool
        Whether ``None`` is allowed (meaning "compute it").
    allow_inf : bool
        Whether ``+inf`` is allowed ("none").
    floor : float, optional
        Physical floor: a value must be 0 or at least this (see :class:`Spec`).
    default : optional
        Default value; without it the field is required.
    """
    spec = Spec(unit=unit, doc=doc, low=low, high=high, low_open=low_open, high_open=high_open, integer=integer,
                allow_inf=allow_inf, floor=floor)
    return spec.field(default=default, optional=optional)


def describe_range(meta: Mapping[str, Any]) -> str:
    """Say the allowed range of a field in words, e.g. ``"0 < value < 0.5"``, ``"a whole number with 0 <= value"``.

    Parameters
    ----------
    meta : mapping
        Field metadata (:meth:`Spec.meta`): ``unit``, ``low``, ``high``, ``low_open``, ``high_open``, ``integer``,
        and optionally ``allow_inf`` and ``floor``.

    Returns
    -------
    str

    Examples
    --------
    >>> describe_range({"low": 0.0, "high": 0.5, "low_open": True, "high_open": True})
    '0 < value < 0.5'
    """
    lo, hi = meta.get("low"), meta.get("high")
    kind = "a whole number" if meta.get("integer") else "a number"
    inf = " (or inf: none)" if meta.get("allow_inf") else ""
    if lo is None and hi is None:
        return f"a finite {kind[2:]}" if not meta.get("integer") else kind
    def num(x: float) -> str:  # a whole-number bound that %g rounds (2**63 - 1 read 9.22337e+18) is written out
        return str(int(x)) if meta.get("integer") and float(f"{x:g}") != x else f"{x:g}"

    parts = []
    if lo is not None:
        parts.append(f"{num(lo)} {'<' if meta['low_open'] else '<='} ")
    parts.append("value")
    if hi is not None:
        parts.append(f" {'<' if meta['high_open'] else '<='} {num(hi)}")
    prefix = f"{kind} with " if meta.get("integer") else ""
    return f"{prefix}{''.join(parts)}{inf}"


def describe_rule(meta: Mapping[str, Any]) -> str:
    """The allowed range in words with the unit and any floor, e.g. ``"0 <= value < 0.01 [m], either 0 or at
    least 1e-09 [m]"`` (the text after "expected" in an error message).

    Parameters
    ----------
    meta : mapping
        Field metadata (:meth:`Spec.meta`): ``unit``, ``low``, ``high``, ``low_open``, ``high_open``, ``integer``,
        and optionally ``allow_inf`` and ``floor``.

    Returns
    -------
    str
    """
    unit = "" if meta["unit"] == "1" else f" [{meta['unit']}]"
    floor = f", either 0 or at least {meta['floor']:g}{unit}" if meta.get("floor") is not None else ""
    return f"{describe_range(meta)}{unit}{floor}"


def field_unit(cls: type, name: str) -> str:
    """Return the unit declared for field ``name`` of dataclass ``cls``.

    Parameters
    ----------
    cls : type
        A dataclass.
    name : str
        One of its fields.

    Returns
    -------
    str
        The unit, or ``""`` for a field declared without one.

    Raises
    ------
    KeyError
        For a name that is not a field of ``cls``.
    """
    for f in dataclasses.fields(cls):
        if f.name == name:
            return str(f.metadata.get("unit", ""))
    raise KeyError(name)


def check_number(name: str, value: Any, meta: Mapping[str, Any]) -> float:
    """Check one value against field metadata; return it as a float.

    Parameters
    ----------
    name : str
        The name the message gives the value.
    value : object
        The value: a real number (not a bool).
    meta : mapping
        Field metadata (:meth:`Spec.meta`): ``unit``, ``low``, ``high``, ``low_open``, ``high_open``, ``integer``,
        and optionally ``allow_inf`` and ``floor``.

    Returns
    -------
    float

    Raises
    ------
    InputError
        Naming ``name``, the value, the allowed range and the unit; ``error.field`` is ``name`` and
        ``error.rule`` the text after the value.
    """
    allowed = describe_rule(meta)
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        kind = ("true/false" if isinstance(value, bool) else "a string: write the number without quotes"
                if isinstance(value, str) else f"a {type(value).__name__}")
        rule = f"is not a number ({kind}): expected {allowed}"
        raise InputError(f"{name} = {value!r} {rule}", field=name, rule=rule)
    try:
        v = float(value)
    except OverflowError:  # an int beyond any float (10**400): out of every range, not a traceback
        rule = f"is out of range: expected {allowed}"
        raise InputError(f"{name} = {short_repr(value)} {rule}", field=name, rule=rule) from None
    if meta["integer"] and (not math.isfinite(v) or v != int(v)):
        rule = f"is not a whole number: expected {allowed}"
        raise InputError(f"{name} = {value!r} {rule}", field=name, rule=rule)
    lo, hi = meta["low"], meta["high"]
    bad = not math.isfinite(v) and not (meta.get("allow_inf") and v == math.inf)
    if math.isfinite(v):
        x = value if isinstance(value, numbers.Integral) else v  # an int as it is: float() rounds beyond 2**53
        if lo is not None:
            bad = bad or (x <= lo if meta["low_open"] else x < lo)
        if hi is not None:
            bad = bad or (x >= hi if meta["high_open"] else x > hi)
        floor = meta.get("floor")
        if floor is not None:
            bad = bad or (v != 0.0 and abs(v) < floor)
    if bad:
        rule = f"is out of range: expected {allowed}"
        raise InputError(f"{name} = {value!r} {rule}", field=name, rule=rule)
    return v


def check_choice(name: str, value: Any, allowed: tuple[Any, ...], *, what: str = "") -> Any:
    """Return ``value`` if it is one of ``allowed``, else raise :class:`InputError` naming ``name``.

    ``what`` words the kind of value (``"a QP solver"``); the default message says "is not allowed".

    Parameters
    ----------
    name : str
        The name the message gives the value.
    value : object
        The value; equal to a choice and of the same type (``1`` is not ``True``).
    allowed : tuple
        The choices.
    what : str
        The kind of value, for the message (default: none).

    Returns
    -------
    object
        ``value``.

    Raises
    ------
    InputError
        Naming ``name`` and the choices.
    """
    ok = any(value == a and type(value) is type(a) for a in allowed)
    if not ok:
        head = f"is not {what}" if what else "is not allowed"
        rule = f"{head}: expected one of {', '.join(repr(a) for a in allowed)}"
        raise InputError(f"{name} = {value!r} {rule}", field=name, rule=rule)
    return value


def check_progress(progress: Any) -> None:
    """Refuse a ``progress`` that is neither None nor callable (else it failed at its first call, a TypeError).

    Raises
    ------
    InputError
        Naming ``progress``.
    """
    if progress is not None and not callable(progress):
        raise InputError(f"progress = {progress!r} is not callable: expected a function f(fraction) or None",
                         field="progress")


def validate_fields(obj: Any) -> None:
    """Check every spec'd field of a dataclass instance against its declared range.

    Parameters
    ----------
    obj : object
        A dataclass instance; its fields declared with a unit (:func:`quantity`, :meth:`Spec.field`) are checked.

    Raises
    ------
    InputError
        On the first field of wrong type or out of range; the message names the field, the value,
        the allowed range and the unit, and ``error.field`` holds the field name.
    """
    for f in dataclasses.fields(obj):
        meta = f.metadata
        if "unit" not in meta:
            continue
        value = getattr(obj, f.name)
        if value is None and meta["optional"]:
            continue
        if meta.get("sequence"):
            if isinstance(value, str) or not hasattr(value, "__iter__"):
                rule = f"is not a list: expected a list of numbers, each {describe_range(meta)}"
                raise InputError(f"{f.name} = {value!r} {rule}", field=f.name, rule=rule)
            for v in value:
                try:
                    check_number(f.name, v, meta)
                except InputError as exc:
                    rule = f"has an element {v!r} that {exc.rule}"
                    raise InputError(f"{f.name} = {list(value)!r} {rule}", field=f.name, rule=rule) from None
            continue
        check_number(f.name, value, meta)


# --- the named quantities: each range is written here and nowhere else ---------------------------------

#: Smallest backlash other than none [m]: 1 nm, a thousandth of the finest gear grades' backlash; below it a
#: gap is no physical clearance and the controllers' arithmetic on b (b / v, 1 / b) leaves float range.
BACKLASH_FLOOR = 1e-9
#: Backlash b along the line of action (half the lost motion of a stage), per stage: 0 (backlash-free) or
#: at least :data:`BACKLASH_FLOOR`.
BACKLASH = Spec(unit="m", doc="backlash b along the line of action", low=0.0, high=0.01, high_open=True,
                floor=BACKLASH_FLOOR)
#: Half-gap of a plant's stage (any finite physical value; gear data in files and controllers' estimates
#: take :data:`BACKLASH`).
GAP = Spec(unit="m", doc="half-gap along the line of action", low=0.0)
#: Inertia of a gear or a whole shaft (strictly positive).
INERTIA = Spec(unit="kg m^2", doc="inertia", low=0.0, low_open=True, high=1e6)
#: Inertia added to a shaft (motor rotor, load, coupling).
ADDED_INERTIA = Spec(unit="kg m^2", doc="inertia added to a shaft", low=0.0, high=1e6)
VISCOUS_FRICTION = Spec(unit="N m s/rad", doc="viscous friction", low=0.0, high=1e3)
COULOMB_FRICTION = Spec(unit="N m", doc="Coulomb friction", low=0.0, high=1e4)
COULOMB_VELOCITY = Spec(unit="rad/s", doc="velocity scale of the smooth Coulomb law", low=0.0, low_open=True,
                        high=10.0)
#: Motor torque limit: from 1 uN m (below the stall torque of the smallest micro motors, ~30 uN m) to 1 MN m.
TORQUE_LIMIT = Spec(unit="N m", doc="motor torque limit", low=1e-6, high=1e6, allow_inf=True)
LOAD_TORQUE = Spec(unit="N m", doc="constant load torque", low=-1e4, high=1e4)
MESH_STIFFNESS = Spec(unit="N/m", doc="mesh stiffness", low=0.0, low_open=True, high=1e13)
MESH_DAMPING = Spec(unit="N s/m", doc="mesh damping", low=0.0, high=1e8)
DAMPING_RATIO = Spec(unit="1", doc="damping ratio of the mesh mode", low=0.0, high=2.0)
#: Module of a gear pair: from 10 um (micro gears) to 0.1 m.
MODULE = Spec(unit="m", doc="module (pitch diameter / teeth)", low=1e-5, high=0.1)
#: Face width of a gear pair: from 10 um to 1 m (and relative to the module: :func:`gearctl.model.check_model`).
FACE_WIDTH = Spec(unit="m", doc="face width", low=1e-5, high=1.0)
BASE_RADIUS = Spec(unit="m", doc="base radius", low=0.0, low_open=True, high=10.0)
SAMPLE_TIME = Spec(unit="s", doc="sample period", low=1e-6, high=1.0)
ENCODER_CPR = Spec(unit="counts/rev", doc="encoder resolution", low=4, high=2**40, integer=True)
ENCODER_NOISE = Spec(unit="rad", doc="encoder noise (std)", low=0.0, high=1.0)
DURATION = Spec(unit="s", doc="simulated time", low=0.0, low_open=True, high=1e5)
#: A simulation's output interval (``dt`` of :func:`gearctl.simulate.simulate` and the kernel); its size against
#: the duration is checked by :func:`gearctl.limits.check_output_size`.
OUTPUT_INTERVAL = Spec(unit="s", doc="output interval", low=0.0, low_open=True)
RTOL = Spec(unit="1", doc="relative tolerance of the nonlinear solver", low=1e-14, high=1e-2)
SEED = Spec(unit="1", doc="random seed", low=0, high=2**63 - 1, integer=True)
#: Sample points of a computed curve over a mesh cycle or a path of contact (``points`` of
#: :func:`gearctl.stiffness.mesh_stiffness` and :func:`~gearctl.stiffness.tooth_deflections`, the CLI's ``--points``).
POINTS = Spec(unit="1", doc="sample points", low=2, high=1_000_000, integer=True)
