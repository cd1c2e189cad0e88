"""C structs described once in Python: their C declaration, a :mod:`ctypes` mirror, and their values as
a ``static const`` initializer (the exported source) or as a filled :mod:`ctypes` object (the runtime
library of the batch loop).

A field type is ``"double"``, ``"int"``, ``"double[N]"``, a pointer (``"const double *"``, ``"const int16_t *"``,
...), or the name of another :class:`CStruct` (nested by value).
"""

from __future__ import annotations

import ctypes
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["CStruct", "CArray", "c_double", "c_array"]

_SCALARS: dict[str, Any] = {"double": ctypes.c_double, "int": ctypes.c_int}
_POINTEE = {"double": np.float64, "int16_t": np.int16, "int8_t": np.int8, "int32_t": np.int32,
            "uint16_t": np.uint16, "uint8_t": np.uint8}
_ARRAY = re.compile(r"^(double|int)\[(\d+)\]$")
_POINTER = re.compile(r"^const (\w+) \*$")


def c_double(v: float) -> str:
    """A C99 literal that parses to exactly ``v`` (shortest round-trip repr; INFINITY / NAN from math.h).

    Parameters
    ----------
    v : float
        The value (anything :class:`float` takes).

    Returns
    -------
    str

    Examples
    --------
    >>> c_double(1), c_double(0.1), c_double(float("-inf"))
    ('1.0', '0.1', '-INFINITY')
    """
    v = float(v)
    if math.isnan(v):
        return "NAN"
    if math.isinf(v):
        return "INFINITY" if v > 0 else "-INFINITY"
    text = repr(v)
    return text if ("." in text or "e" in text) else text + ".0"


@dataclass(frozen=True)
class CArray:
    """A constant table a pointer field points at: its C name, element type and data.

    Parameters
    ----------
    symbol : str
        The C name of the table.
    ctype : str
        Element type: ``double``, ``int16_t``, ``int8_t``, ``int32_t``, ``uint16_t`` or ``uint8_t``.
    data : ndarray
        The values, stored flattened, contiguous, converted to ``ctype``.

    Raises
    ------
    KeyError
        For another ``ctype``.
    """

    symbol: str
    ctype: str  # element type: double, int16_t, int8_t, int32_t, uint16_t
    data: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "data", np.ascontiguousarray(self.data, dtype=_POINTEE[self.ctype]).ravel())

    @property
    def nbytes(self) -> int:
        """Size of the table [bytes]."""
        return int(self.data.nbytes)


def c_array(arr: CArray, per_line: int = 6) -> str:
    """``static const <type> <symbol>[n] = {...};`` (doubles exact: shortest round-trip literals).

    Parameters
    ----------
    arr : CArray
        The table (an empty one is written as one 0).
    per_line : int
        Values per line (default 6).

    Returns
    -------
    str
    """
    fmt = c_double if arr.ctype == "double" else (lambda v: str(int(v)))
    vals = [fmt(v) for v in arr.data.tolist()] or ["0"]
    lines = [", ".join(vals[i:i + per_line]) for i in range(0, len(vals), per_line)]
    body = ",\n    ".join(lines)
    return f"static const {arr.ctype} {arr.symbol}[{max(arr.data.size, 1)}] = {{\n    {body}\n}};\n"


class CStruct:
    """A C struct: name and ordered ``(field, type)`` pairs; nested structs are given in ``registry``.

    Parameters
    ----------
    name : str
        The C type name.
    fields : sequence of (str, str)
        ``(field, type)`` in order; a type is ``double``, ``int``, ``double[n]``, ``int[n]``, a pointer
        ``const <type> *`` or the name of a struct in ``registry``.
    registry : mapping of str to CStruct, optional
        The nested structs by name.
    """

    def __init__(self, name: str, fields: Sequence[tuple[str, str]], registry: Mapping[str, CStruct] | None = None):
        self.name = name
        self.fields = tuple(fields)
        self.registry = dict(registry or {})
        self._ctype: type[ctypes.Structure] | None = None

    def _nested(self, ty: str) -> CStruct | None:
        return self.registry.get(ty)

    def c_decl(self) -> str:
        """``typedef struct { ... } name;``."""
        lines = []
        for f, ty in self.fields:
            m = _ARRAY.match(ty)
            if m:
                lines.append(f"    {m.group(1)} {f}[{m.group(2)}];")
            elif ty.endswith("*"):
                lines.append(f"    {ty}{f};")
            else:
                lines.append(f"    {ty} {f};")
        return "typedef struct {\n" + "\n".join(lines) + f"\n}} {self.name};\n"

    def ctype(self) -> type[ctypes.Structure]:
        """The :mod:`ctypes` mirror (built once)."""
        if self._ctype is None:
            cf = []
            for f, ty in self.fields:
                m = _ARRAY.match(ty)
                if m:
                    cf.append((f, _SCALARS[m.group(1)] * int(m.group(2))))
                elif ty.endswith("*"):
                    cf.append((f, ctypes.c_void_p))
                elif ty in _SCALARS:
                    cf.append((f, _SCALARS[ty]))
                else:
                    cf.append((f, self.registry[ty].ctype()))
            self._ctype = type(self.name, (ctypes.Structure,), {"_fields_": cf})
        return self._ctype

    def _check(self, values: Mapping[str, Any]) -> None:
        names = {f for f, _ in self.fields}
        missing, extra = names - set(values), set(values) - names
        if missing or extra:
            raise ValueError(f"{self.name}: missing {sorted(missing)}, unknown {sorted(extra)}")

    def c_init(self, values: Mapping[str, Any], indent: str = "    ") -> str:
        """A C initializer ``{ .field = value, ... }`` (pointers: the :class:`CArray`'s symbol).

        Parameters
        ----------
        values : mapping
            ``field -> value``: a number, a sequence for an array field, a :class:`CArray` (or anything else: a
            null pointer) for a pointer field, a mapping for a nested struct; exactly the struct's fields.
        indent : str
            Indentation of the fields (nested structs four spaces more; default four spaces).

        Returns
        -------
        str

        Raises
        ------
        ValueError
            For a missing or unknown field (or, for :meth:`c_init`, an array field of the wrong length).
        """
        self._check(values)
        parts = []
        for f, ty in self.fields:
            v = values[f]
            m = _ARRAY.match(ty)
            if m:
                fmt = c_double if m.group(1) == "double" else (lambda x: str(int(x)))
                seq = list(v)
                if len(seq) != int(m.group(2)):
                    raise ValueError(f"{self.name}.{f}: {len(seq)} values for {ty}")
                text = "{" + ", ".join(fmt(x) for x in seq) + "}"
            elif ty.endswith("*"):
                text = v.symbol if isinstance(v, CArray) else "0"
            elif ty == "double":
                text = c_double(v)
            elif ty == "int":
                text = str(int(v))
            else:
                text = self.registry[ty].c_init(v, indent + "    ")
            parts.append(f"{indent}.{f} = {text}")
        close = indent[:-4] if len(indent) >= 4 else ""
        return "{\n" + ",\n".join(parts) + f"\n{close}}}"

    def fill(self, values: Mapping[str, Any], keep: list[Any]) -> ctypes.Structure:
        """A filled :mod:`ctypes` object; the arrays pointed at are appended to ``keep`` (keep it alive).

        Parameters
        ----------
        values : mapping
            ``field -> value``: a number, a sequence for an array field, a :class:`CArray` (or anything else: a
            null pointer) for a pointer field, a mapping for a nested struct; exactly the struct's fields.
        keep : list
            Appended to: the arrays the pointers point at, which must outlive the object.

        Returns
        -------
        ctypes.Structure

        Raises
        ------
        ValueError
            For a missing or unknown field (or, for :meth:`c_init`, an array field of the wrong length).
        """
        self._check(values)
        obj = self.ctype()()
        for f, ty in self.fields:
            v = values[f]
            m = _ARRAY.match(ty)
            if m:
                arr = getattr(obj, f)
                for i, x in enumerate(v):
                    arr[i] = x
            elif ty.endswith("*"):
                if isinstance(v, CArray):
                    keep.append(v.data)
                    setattr(obj, f, v.data.ctypes.data)
                else:
                    setattr(obj, f, None)
            elif ty in _SCALARS:
                setattr(obj, f, float(v) if ty == "double" else int(v))
            else:
                setattr(obj, f, self.registry[ty].fill(v, keep))
        return obj

    def arrays(self, values: Mapping[str, Any]) -> list[CArray]:
        """The tables the pointer fields (nested ones included) point at.

        Parameters
        ----------
        values : mapping
            ``field -> value``: a number, a sequence for an array field, a :class:`CArray` (or anything else: a
            null pointer) for a pointer field, a mapping for a nested struct; exactly the struct's fields.

        Returns
        -------
        list of CArray
        """
        out: list[CArray] = []
        for f, ty in self.fields:
            v = values[f]
            if ty.endswith("*") and isinstance(v, CArray):
                out.append(v)
            elif ty in self.registry:
                out.extend(self.registry[ty].arrays(v))
        return out
