"""Controller files (``controllers/*.toml``) to controller objects.

A controller file has a ``kind``, the sample time, the feedback sensors, the design or gains, and a
``[source]`` table. Each kind's keys are a *layout*: which table and key feed which field of which settings
dataclass; the fields declare their units and ranges (:mod:`gearctl.units`), so a controller file is read
by the same rules as a model file (:mod:`gearctl.files`). Unknown keys are rejected with a suggestion; a
value out of range names the file, the key and the allowed range.
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..files import Layout, build_dataclass, check_source, spec_values
from ..plant import Plant
from ..units import BACKLASH, SAMPLE_TIME, check_choice, validate_fields
from .base import Controller, LoopInfo, loop_info
from .deadzone import DeadzoneInverse, InverseSettings
from .mpc import MPC_LAYOUT, build_mpc
from .pid import PID, PIDDesign, PIDGains, design_pid

__all__ = ["build_controller", "LoopSettings", "LAYOUTS", "CONTROLLER_KEYS"]


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class LoopSettings:
    """What every PID-based controller file states at its top level."""

    sample_time: float = SAMPLE_TIME.field(default=1e-3)
    feedback: str = "motor"
    feedforward: bool = True

    def __post_init__(self) -> None:
        validate_fields(self)
        check_choice("feedback", self.feedback, ("motor", "load"))
        check_choice("feedforward", self.feedforward, (True, False))


_LOOP = {"sample_time": (LoopSettings, "sample_time"), "feedback": (LoopSettings, "feedback"),
         "feedforward": (LoopSettings, "feedforward")}
_PID_TABLES = {"design": {f.name: (PIDDesign, f.name) for f in dataclasses.fields(PIDDesign)},
               "gains": {f.name: (PIDGains, f.name) for f in dataclasses.fields(PIDGains)}}
_INVERSE = {f.name: (InverseSettings, f.name) for f in dataclasses.fields(InverseSettings)}

#: kind -> layout of its file
LAYOUTS: dict[str, Layout] = {
    "pid": {"": _LOOP, **_PID_TABLES},
    "deadzone_inverse": {"": {**_LOOP, **_INVERSE}, **_PID_TABLES},
    "mpc": MPC_LAYOUT,
}
#: kind -> (top-level keys, {table: keys}) for documentation and the README
CONTROLLER_KEYS: dict[str, tuple[set[str], dict[str, set[str]]]] = {
    k: ({"kind", "name", *lay.get("", {})}, {t: set(v) for t, v in lay.items() if t}) for k, lay in LAYOUTS.items()
}

Values = dict[str, tuple[Any, Any]]


def _restate(path: Path, exc: InputError, values: Mapping[type, Values]) -> InputError:
    """An error raised by a design step, restated with the file and the key it came from."""
    for vals in values.values():
        if exc.field in vals:
            b = vals[exc.field][0]
            return InputError(f"{path}: {b.label()}: {exc}", field=exc.field, rule=exc.rule)
    return InputError(f"{path}: {exc}", field=exc.field, rule=exc.rule)


def _pid(path: Path, values: dict[type, Values], info: LoopInfo, loop: LoopSettings, name: str) -> PID:
    Ts = loop.sample_time
    if PIDGains in values and PIDDesign in values:
        raise InputError(f"{path}: give either [gains] or [design], not both", field="gains")
    if PIDGains in values:
        gains = build_dataclass(path, PIDGains, values[PIDGains])
    else:
        design = build_dataclass(path, PIDDesign, values.get(PIDDesign, {}))
        try:
            gains, _ = design_pid(info, bandwidth_hz=design.bandwidth_hz, phase_margin_deg=design.phase_margin_deg,
                                  integral_ratio=design.integral_ratio, Ts=Ts)
        except InputError as exc:
            raise _restate(path, exc, values) from None
    return PID(info, gains, Ts=Ts, feedback=loop.feedback, feedforward=loop.feedforward, name=name)


def _build_pid(path: Path, spec: Mapping[str, Any], info: LoopInfo, *, name: str,
               backlash: float | None) -> Controller:
    values = spec_values(path, spec, LAYOUTS["pid"], kind="pid")
    loop = build_dataclass(path, LoopSettings, values.get(LoopSettings, {}))
    return _pid(path, values, info, loop, name)


def _build_inverse(path: Path, spec: Mapping[str, Any], info: LoopInfo, *, name: str,
                   backlash: float | None) -> Controller:
    values = spec_values(path, spec, LAYOUTS["deadzone_inverse"], kind="deadzone_inverse")
    loop = build_dataclass(path, LoopSettings, values.get(LoopSettings, {}))
    settings = build_dataclass(path, InverseSettings, values.get(InverseSettings, {}))
    b = backlash if backlash is not None else (settings.backlash if settings.backlash is not None
                                               else info.plant.backlash)
    pid = _pid(path, values, info, loop, name + "/pid")
    try:
        return DeadzoneInverse(pid, backlash=b, rule=settings.rule, width=settings.width, name=name)
    except InputError as exc:
        raise _restate(path, exc, values) from None


Builder = Callable[..., Controller]
_BUILDERS: dict[str, Builder] = {"pid": _build_pid, "deadzone_inverse": _build_inverse, "mpc": build_mpc}


def build_controller(spec: dict[str, Any], plant: Plant, *, path: Path | str = "<controller>",
                     backlash: float | None = None) -> Controller:
    """Build a controller from a parsed controller file.

    Parameters
    ----------
    spec : dict
        The TOML document.
    plant : Plant
        The nominal plant the controller is designed on (the model's; its backlash is the default
        estimate; a train is designed on its equivalent pair).
    path : Path or str
        File name, for messages.
    backlash : float, optional
        Backlash estimate overriding the file's and the model's [m].

    Returns
    -------
    Controller

    Raises
    ------
    InputError
        For an unknown kind or key, or a value out of range.
    """
    path = Path(path)
    kind = spec.get("kind")
    if kind not in LAYOUTS:
        close = difflib.get_close_matches(str(kind), list(LAYOUTS), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise InputError(f"{path}: kind = {kind!r} is not a controller kind: expected one of "
                         f"{', '.join(LAYOUTS)}{hint}", field="kind")
    if "source" not in spec:
        raise InputError(f"{path}: missing section [source] (citation or notes)", field="source")
    check_source(path, spec["source"], required=("citation", "notes"))
    if backlash is not None:
        try:
            BACKLASH.check("backlash", backlash)
        except InputError as exc:
            raise InputError(f"{path}: {exc}", field="backlash", rule=exc.rule) from None
    name = str(spec.get("name", path.stem))
    info = loop_info(plant)
    if kind == "mpc":
        ts = spec.get("sample_time", 1e-3)
        try:
            Ts = SAMPLE_TIME.check("sample_time", ts)
        except InputError as exc:
            raise InputError(f"{path}: sample_time = {ts!r} {exc.rule}", field="sample_time", rule=exc.rule) from None
        return build_mpc(path, spec, info, Ts=Ts, name=name, backlash=backlash)
    return _BUILDERS[kind](path, spec, info, name=name, backlash=backlash)

