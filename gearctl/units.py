"""Physical fields: unit and allowed range declared once, checked everywhere.

A dataclass field made with :func:`quantity` carries its unit, its allowed range and a one-line
description in its metadata. :func:`validate_fields` checks an instance against them, and the TOML
loader, error messages and plot labels read the same metadata, so a range is stated in one place.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any

from .errors import InputError

__all__ = ["quantity", "validate_fields", "describe_range", "field_unit"]


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
    default: Any = dataclasses.MISSING,
) -> Any:
    """Declare a physical dataclass field with its unit and allowed range.

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
    default : optional
        Default value; without it the field is required.
    """
    meta = {
        "unit": unit,
        "doc": doc,
        "low": low,
        "high": high,
        "low_open": low_open,
        "high_open": high_open,
        "integer": integer,
        "optional": optional,
    }
    return dataclasses.field(default=default, metadata=meta)


def describe_range(meta: dict[str, Any]) -> str:
    """Say the allowed range of a field in words, e.g. ``"0 < value < 0.5"``."""
    lo, hi = meta.get("low"), meta.get("high")
    kind = "a whole number" if meta.get("integer") else "a number"
    if lo is None and hi is None:
        return f"{kind}"
    parts = []
    if lo is not None:
        parts.append(f"{lo:g} {'<' if meta['low_open'] else '<='} ")
    parts.append("value")
    if hi is not None:
        parts.append(f" {'<' if meta['high_open'] else '<='} {hi:g}")
    return f"{kind} with {''.join(parts)}"


def field_unit(cls: type, name: str) -> str:
    """Return the unit declared for field ``name`` of dataclass ``cls``."""
    for f in dataclasses.fields(cls):
        if f.name == name:
            return str(f.metadata.get("unit", ""))
    raise KeyError(name)


def validate_fields(obj: Any) -> None:
    """Check every :func:`quantity` field of a dataclass instance against its declared range.

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
        unit = "" if meta["unit"] == "1" else f" [{meta['unit']}]"
        allowed = describe_range(meta)
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            rule = f"is not a number: expected {allowed}{unit}"
            raise InputError(f"{f.name} = {value!r} {rule}", field=f.name, rule=rule)
        if meta["integer"] and (not math.isfinite(float(value)) or float(value) != int(value)):
            rule = f"is not whole: expected {allowed}{unit}"
            raise InputError(f"{f.name} = {value!r} {rule}", field=f.name, rule=rule)
        v = float(value)
        lo, hi = meta["low"], meta["high"]
        bad = not math.isfinite(v) and not (math.isinf(v) and hi is None and v > 0)
        if lo is not None:
            bad = bad or (v <= lo if meta["low_open"] else v < lo)
        if hi is not None:
            bad = bad or (v >= hi if meta["high_open"] else v > hi)
        if bad:
            rule = f"is out of range: expected {allowed}{unit}"
            raise InputError(f"{f.name} = {value!r} {rule}", field=f.name, rule=rule)
