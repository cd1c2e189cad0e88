"""Controller files (``controllers/*.toml``) to controller objects.

A controller file has a ``kind`` (``pid``, ``deadzone_inverse``, ``mpc``), the sample time, the feedback
sensors, the design or gains, and a ``[source]`` table. Unknown keys are rejected with a suggestion; a
value out of range names the file, the key and the allowed range.
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..plant import Plant
from .base import Controller, LoopInfo, loop_info
from .deadzone import DeadzoneInverse
from .pid import PID, PIDGains, design_pid

__all__ = ["build_controller", "CONTROLLER_KEYS"]

# kind -> (top-level keys, sections with their keys)
_PID_TOP = {"kind", "name", "sample_time", "feedback", "feedforward"}
_PID_SECTIONS = {
    "design": {"bandwidth_hz", "phase_margin_deg", "integral_ratio"},
    "gains": {"kp", "ki", "kd", "derivative_filter_hz"},
}
CONTROLLER_KEYS: dict[str, tuple[set[str], dict[str, set[str]]]] = {
    "pid": (_PID_TOP, _PID_SECTIONS),
    "deadzone_inverse": (_PID_TOP | {"rule", "width", "backlash"}, _PID_SECTIONS),
    "mpc": (
        {"kind", "name", "sample_time", "feedback", "horizon", "solver", "backlash", "soft_landing",
         "landing_velocity", "max_solve_time", "smoothing"},
        {"weights": {"tracking", "torque", "torque_rate", "relative_velocity", "terminal"},
         "observer": {"process_noise", "measurement_noise"}},
    ),
}
_SOURCE_KEYS = {"citation", "table", "notes", "url", "doi"}


def _check_keys(path: Path, spec: dict[str, Any]) -> str:
    kind = spec.get("kind")
    if kind not in CONTROLLER_KEYS:
        close = difflib.get_close_matches(str(kind), list(CONTROLLER_KEYS), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise InputError(f"{path}: kind = {kind!r} is not a controller kind: expected one of "
                         f"{', '.join(CONTROLLER_KEYS)}{hint}", field="kind")
    top, sections = CONTROLLER_KEYS[kind]
    for key, value in spec.items():
        if isinstance(value, dict):
            allowed = sections.get(key, _SOURCE_KEYS if key == "source" else None)
            if allowed is None:
                close = difflib.get_close_matches(key, [*sections, "source"], n=1)
                hint = f"; did you mean [{close[0]}]?" if close else ""
                raise InputError(f"{path}: unknown section [{key}] for kind {kind!r}: expected one of "
                                 f"{', '.join(f'[{s}]' for s in [*sections, 'source'])}{hint}", field=key)
            for sub in value:
                if sub not in allowed:
                    close = difflib.get_close_matches(sub, list(allowed), n=1)
                    hint = f"; did you mean {close[0]!r}?" if close else ""
                    raise InputError(f"{path}: unknown key [{key}] {sub}: expected one of "
                                     f"{', '.join(sorted(allowed))}{hint}", field=sub)
        elif key not in top:
            close = difflib.get_close_matches(key, list(top), n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise InputError(f"{path}: unknown key {key} for kind {kind!r}: expected one of "
                             f"{', '.join(sorted(top))}{hint}", field=key)
    if "source" not in spec:
        raise InputError(f"{path}: missing section [source] (citation or notes)", field="source")
    return kind


def number(path: Path, spec: dict[str, Any], key: str, default: float | None, lo: float, hi: float,
           *, section: str | None = None, unit: str = "", lo_open: bool = False) -> float:
    """Read a number from a controller spec, checking its range; ``default`` None means required."""
    table = spec.get(section, {}) if section else spec
    label = f"[{section}] {key}" if section else key
    if key not in table:
        if default is None:
            raise InputError(f"{path}: missing key {label}: expected a number in [{lo:g}, {hi:g}] {unit}", field=key)
        return default
    v = table[key]
    ok = isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
    if ok:
        ok = (v > lo if lo_open else v >= lo) and v <= hi
    if not ok:
        left = "(" if lo_open else "["
        raise InputError(f"{path}: {label} = {v!r} is out of range: expected a number in {left}{lo:g}, {hi:g}] "
                         f"{unit}".rstrip(), field=key)
    return float(v)


def _choice(path: Path, spec: dict[str, Any], key: str, default: Any, allowed: tuple[Any, ...]) -> Any:
    v = spec.get(key, default)
    if v not in allowed:
        raise InputError(f"{path}: {key} = {v!r} is not allowed: expected one of "
                         f"{', '.join(repr(a) for a in allowed)}", field=key)
    return v


def _pid(path: Path, spec: dict[str, Any], info: LoopInfo, Ts: float, name: str) -> PID:
    feedback = _choice(path, spec, "feedback", "motor", ("motor", "load"))
    feedforward = _choice(path, spec, "feedforward", True, (True, False))
    if "gains" in spec and "design" in spec:
        raise InputError(f"{path}: give either [gains] or [design], not both", field="gains")
    if "gains" in spec:
        gains = PIDGains(
            kp=number(path, spec, "kp", None, 0.0, 1e9, section="gains", unit="[N m/rad]"),
            ki=number(path, spec, "ki", 0.0, 0.0, 1e12, section="gains", unit="[N m/(rad s)]"),
            kd=number(path, spec, "kd", 0.0, 0.0, 1e9, section="gains", unit="[N m s/rad]"),
            derivative_filter_hz=number(path, spec, "derivative_filter_hz", 1e3, 0.0, 1e6, section="gains",
                                        unit="[Hz]", lo_open=True),
        )
    else:
        gains, _ = design_pid(
            info,
            bandwidth_hz=number(path, spec, "bandwidth_hz", 20.0, 0.0, 0.5 / Ts, section="design", unit="[Hz]",
                                lo_open=True),
            phase_margin_deg=number(path, spec, "phase_margin_deg", 50.0, 1.0, 79.0, section="design",
                                    unit="[deg]"),
            integral_ratio=number(path, spec, "integral_ratio", 0.1, 0.0, 1.0, section="design"),
            Ts=Ts,
        )
    return PID(info, gains, Ts=Ts, feedback=feedback, feedforward=feedforward, name=name)


def build_controller(spec: dict[str, Any], plant: Plant, *, path: Path | str = "<controller>",
                     backlash: float | None = None) -> Controller:
    """Build a controller from a parsed controller file.

    Parameters
    ----------
    spec : dict
        The TOML document.
    plant : Plant
        The nominal plant the controller is designed on (the model's; its backlash is the default
        estimate).
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
    kind = _check_keys(path, spec)
    Ts = number(path, spec, "sample_time", 1e-3, 1e-6, 1.0, unit="[s]", lo_open=True)
    name = str(spec.get("name", path.stem))
    info = loop_info(plant)
    if kind == "pid":
        return _pid(path, spec, info, Ts, name)
    if kind == "deadzone_inverse":
        pid = _pid(path, spec, info, Ts, name + "/pid")
        b = backlash if backlash is not None else number(path, spec, "backlash", plant.backlash, 0.0, 0.01,
                                                          unit="[m]")
        rule = _choice(path, spec, "rule", "torque", ("torque", "velocity"))
        width = number(path, spec, "width", 5e-4 if rule == "torque" else 1e-2, 0.0, 1e3, lo_open=True,
                       unit="[N m] (torque rule) or [rad/s] (velocity rule)")
        return DeadzoneInverse(pid, backlash=b, rule=rule, width=width, name=name)
    from .mpc import build_mpc  # CasADi is imported only when an MPC is asked for

    return build_mpc(path, spec, info, Ts=Ts, name=name, backlash=backlash)
