"""Every parameter of gearctl's public API is documented, and every documented parameter exists.

The public API is what ``gearctl.__all__`` reaches: its functions, its classes (the constructor's parameters or
the dataclass fields, documented in the class docstring under Parameters or Attributes) and their public methods,
and the public names of the submodules it lists (``gearctl.simulate``, ``gearctl.identify``, ``gearctl.sweep``).
The docstrings are numpydoc; the small parser below reads their ``Parameters``, ``Other Parameters`` and
``Attributes`` sections (a header underlined with dashes, entries ``name : type`` or ``name1, name2 : type`` at
the section's indentation). Idea from python-control's ``docstrings_test.py``, which fails on an undocumented
argument; the code is gearctl's own.
"""

from __future__ import annotations

import dataclasses
import enum
import inspect
import re
import types
from collections.abc import Callable, Iterator

import gearctl

#: Sections whose entries name parameters (Attributes only counts for a class).
PARAMETER_SECTIONS = ("Parameters", "Other Parameters")
ATTRIBUTE_SECTIONS = ("Attributes",)
_HEADER = re.compile(r"^-{3,}\s*$")
_ENTRY = re.compile(r"^(?P<names>\*{0,2}[A-Za-z_]\w*(?:\s*,\s*\*{0,2}[A-Za-z_]\w*)*)\s*(?::.*)?$")


def docstring_entries(doc: str | None) -> dict[str, list[tuple[str, str]]]:
    """The entries of each section of a numpydoc docstring, by section title: ``(name, description)`` pairs.

    A section starts at a title line underlined with dashes and ends at the next such title. Its entries are the
    lines at the title's indentation, ``name : type`` or ``name1, name2 : type`` (each name gets the entry's
    description, the lines indented further below it); ``*args`` and ``**kwargs`` keep their stars.
    """
    lines = inspect.cleandoc(doc or "").splitlines()
    sections: dict[str, list[tuple[str, str]]] = {}
    current: list[tuple[str, str]] | None = None
    names: list[str] = []
    text: list[str] = []

    def close() -> None:
        if current is not None and names:
            current.extend((n, " ".join(text)) for n in names)
        names.clear()
        text.clear()

    indent = 0
    i = 0
    while i < len(lines):
        line = lines[i]
        if i + 1 < len(lines) and line.strip() and _HEADER.match(lines[i + 1].strip()) \
                and len(lines[i + 1].strip()) >= len(line.strip()) - 1:
            close()
            current = sections.setdefault(line.strip(), [])
            indent = len(line) - len(line.lstrip())
            i += 2
            continue
        if current is not None and line.strip() and len(line) - len(line.lstrip()) <= indent:
            close()
            match = _ENTRY.match(line.strip())
            if match:
                names.extend(n.strip() for n in match.group("names").split(","))
        elif names and line.strip():
            text.append(line.strip())
        i += 1
    close()
    return sections


def docstring_sections(doc: str | None) -> dict[str, list[str]]:
    """The entry names of each section of a numpydoc docstring, by section title."""
    return {title: [name for name, _ in entries] for title, entries in docstring_entries(doc).items()}


def documented(doc: str | None, titles: tuple[str, ...]) -> list[str]:
    """The names documented in the given sections, stars kept."""
    sections = docstring_sections(doc)
    return [name for title in titles for name in sections.get(title, [])]


def _strip(name: str) -> str:
    return name.lstrip("*")


def signature_names(func: Callable[..., object]) -> list[str]:
    """The parameters to document: all but a method's ``self``/``cls``; ``*args``/``**kwargs`` with their stars.

    (A function's own parameter named ``cls``, e.g. :func:`gearctl.units.field_unit`'s dataclass, is one.)
    """
    try:
        sig = inspect.signature(func)
    except (TypeError, ValueError):  # a builtin without a signature
        return []
    method = "." in getattr(func, "__qualname__", "").replace("<locals>.", "")
    out = []
    for i, p in enumerate(sig.parameters.values()):
        if p.name in ("self", "cls") and method and i == 0:
            continue
        star = {inspect.Parameter.VAR_POSITIONAL: "*", inspect.Parameter.VAR_KEYWORD: "**"}.get(p.kind, "")
        out.append(star + p.name)
    return out


def compare(where: str, wanted: list[str], docs: list[str], *, extra_ok: Callable[[str], bool] = lambda n: False
            ) -> list[str]:
    """Problems: parameters not documented, documented names that are not parameters (unless ``extra_ok``)."""
    have = {_strip(n) for n in docs}
    want = {_strip(n) for n in wanted}
    problems = [f"{where}: parameter {n!r} is not documented" for n in wanted if _strip(n) not in have]
    problems += [f"{where}: documented {n!r} is not a parameter" for n in docs
                 if _strip(n) not in want and not extra_ok(_strip(n))]
    return problems


def public_objects() -> Iterator[tuple[str, object]]:
    """``(qualified name, object)`` for every function and class ``gearctl.__all__`` reaches."""
    seen: set[int] = set()
    for name in sorted(set(gearctl.__all__)):
        obj = getattr(gearctl, name)
        if isinstance(obj, types.ModuleType):
            names = getattr(obj, "__all__", None)
            if names is None:
                names = [n for n, v in vars(obj).items() if not n.startswith("_")
                         and getattr(v, "__module__", None) == obj.__name__]
            members = [(f"{obj.__name__}.{n}", getattr(obj, n)) for n in names]
        else:
            members = [(f"gearctl.{name}", obj)]
        for qual, member in members:
            if (inspect.isfunction(member) or inspect.isclass(member)) and id(member) not in seen:
                seen.add(id(member))
                yield qual, member


def _own_module(obj: object) -> bool:
    return (getattr(obj, "__module__", "") or "").startswith("gearctl")


def _attribute_exists(cls: type, name: str) -> bool:
    """A documented attribute that the class has: a field, a slot, an annotation, a class attribute, a property,
    or an instance attribute its code sets (``self.name``)."""
    for klass in cls.__mro__:
        if name in vars(klass) or name in getattr(klass, "__annotations__", {}) \
                or name in (getattr(klass, "__slots__", ()) or ()):
            return True
    try:
        source = inspect.getsource(cls)
    except (OSError, TypeError):
        return False
    return re.search(rf"\bself\.{re.escape(name)}\b", source) is not None


def unit_problems(qual: str, cls: type) -> list[str]:
    """A dataclass field declared with a unit (:func:`gearctl.units.quantity`, :meth:`gearctl.units.Spec.field`)
    and documented in the class docstring states that unit as ``[unit]`` (``[1]`` or nothing when dimensionless):
    the docstring repeats the schema for ``help()``, and this keeps the two from drifting apart."""
    if not dataclasses.is_dataclass(cls):
        return []
    units = {f.name: f.metadata["unit"] for f in dataclasses.fields(cls) if f.metadata.get("unit")}
    problems = []
    for title in PARAMETER_SECTIONS + ATTRIBUTE_SECTIONS:
        for name, text in docstring_entries(inspect.getdoc(cls)).get(title, []):
            unit = units.get(name)
            if unit is None:
                continue
            stated = re.findall(r"\[([^\]]+)\]", text)
            if f"[{unit}]" not in text and not (unit == "1" and not stated):
                problems.append(f"{qual}: field {name!r} is declared in [{unit}] but documented as "
                                f"{', '.join(f'[{s}]' for s in stated) or 'without a unit'}")
    return problems


def class_problems(qual: str, cls: type) -> list[str]:
    """The constructor's parameters against the class docstring; the public methods against theirs."""
    problems: list[str] = []
    doc = inspect.getdoc(cls)
    params = documented(doc, PARAMETER_SECTIONS)
    attrs = documented(doc, ATTRIBUTE_SECTIONS)
    init = vars(cls).get("__init__")
    if issubclass(cls, enum.Enum) or issubclass(cls, BaseException) and init is None:
        wanted: list[str] = []
    elif dataclasses.is_dataclass(cls) and cls.__dataclass_params__.init:  # type: ignore[attr-defined]
        wanted = [f.name for f in dataclasses.fields(cls) if f.init]
    elif init is not None and _own_module(init):
        init_doc = inspect.getdoc(init)
        params = params + documented(init_doc, PARAMETER_SECTIONS)
        wanted = signature_names(init)
    else:
        wanted = []
    have = {_strip(n) for n in params + attrs}
    problems += unit_problems(qual, cls)
    problems += [f"{qual}: parameter {n!r} is not documented" for n in wanted if _strip(n) not in have]
    want = {_strip(n) for n in wanted}
    problems += [f"{qual}: documented parameter {n!r} is not a parameter" for n in params if _strip(n) not in want]
    problems += [f"{qual}: documented attribute {n!r} does not exist" for n in attrs
                 if _strip(n) not in want and not _attribute_exists(cls, _strip(n))]
    for mname, member in vars(cls).items():
        if mname.startswith("_"):
            continue
        if isinstance(member, (classmethod, staticmethod)):
            member = member.__func__
        if inspect.isfunction(member):
            func = getattr(cls, mname)
            problems += function_problems(f"{qual}.{mname}", func)
    return problems


_SAME_AS = re.compile(r"Parameters are those of :func:`~?([\w.]+)`")


def function_problems(qual: str, func: Callable[..., object]) -> list[str]:
    """A function's parameters against its docstring. A docstring that says "Parameters are those of
    :func:`other`" (a planning step beside its runner, :func:`gearctl.sweep.plan_sweep`) is checked against
    ``other``'s Parameters: each of its own parameters must be documented there under the same name."""
    doc = inspect.getdoc(func)
    wanted = signature_names(func)
    same = _SAME_AS.search(doc or "")
    if same and not documented(doc, PARAMETER_SECTIONS):
        target: object = inspect.getmodule(func)
        for part in same.group(1).split("."):
            target = getattr(target, part, None)
        if not callable(target):
            return [f"{qual}: says its parameters are those of {same.group(1)!r}, which is not found"]
        have = {_strip(n) for n in documented(inspect.getdoc(target), PARAMETER_SECTIONS)}
        return [f"{qual}: parameter {n!r} is not documented in {same.group(1)}" for n in wanted
                if _strip(n) not in have]
    return compare(qual, wanted, documented(doc, PARAMETER_SECTIONS))


def all_problems() -> list[str]:
    problems: list[str] = []
    for qual, obj in public_objects():
        if inspect.isclass(obj):
            problems += class_problems(qual, obj)
        else:
            problems += function_problems(qual, obj)
    return problems


def test_every_public_parameter_is_documented() -> None:
    problems = all_problems()
    assert not problems, "\n".join(problems)


if __name__ == "__main__":
    print("\n".join(all_problems()))


def test_the_check_sees_the_api() -> None:
    names = {qual for qual, _ in public_objects()}
    assert {"gearctl.simulate_closed_loop", "gearctl.GearPair", "gearctl.sweep.sweep",
            "gearctl.identify.identify", "gearctl.simulate.simulate"} <= names
    assert len(names) > 50, len(names)


def _sample(plant: object, duration: float, *, dt: float = 0.1, **settings: object) -> None:
    """A sample function.

    Parameters
    ----------
    plant, duration : object
        Two on one line.
    dtt : float
        Misspelt [s].

    Returns
    -------
    None
    """


def test_the_check_flags_missing_and_stale_names() -> None:
    assert docstring_sections(_sample.__doc__) == {"Parameters": ["plant", "duration", "dtt"], "Returns": ["None"]}
    assert function_problems("f", _sample) == ["f: parameter 'dt' is not documented",
                                               "f: parameter '**settings' is not documented",
                                               "f: documented 'dtt' is not a parameter"]
