"""Controller files (``controllers/*.toml``) to controller objects.

A controller file has a ``kind``, the sample time, the feedback sensors, the design or gains, and a
``[source]`` table. Each kind is one module of :mod:`gearctl.design` with a ``KIND``, a ``LAYOUT`` (which
table and key feed which field of which settings dataclass; the fields declare their units and ranges in
:mod:`gearctl.units`, so a controller file is read by the same rules as a model file) and a ``build``
function. Adding a controller is adding a module to :data:`MODULES`. Unknown keys are rejected with a
suggestion; a value out of range names the file, the key and the allowed range.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

from ..errors import InputError
from ..files import Layout, check_source
from ..params import Sensors
from ..plant import Plant
from ..units import BACKLASH, SAMPLE_TIME
from . import adaptive, deadzone, mpc, pid, reversal
from .base import Controller, loop_info

__all__ = ["build_controller", "MODULES", "LAYOUTS", "CONTROLLER_KEYS"]

#: The controller kinds: one module each (``KIND``, ``LAYOUT``, ``build``).
MODULES: dict[str, ModuleType] = {m.KIND: m for m in (pid, deadzone, reversal, adaptive, mpc)}
#: kind -> layout of its file
LAYOUTS: dict[str, Layout] = {k: m.LAYOUT for k, m in MODULES.items()}
#: kind -> (top-level keys, {table: keys}) for documentation and the README
CONTROLLER_KEYS: dict[str, tuple[set[str], dict[str, set[str]]]] = {
    k: ({"kind", "name", *lay.get("", {})}, {t: set(v) for t, v in lay.items() if t}) for k, lay in LAYOUTS.items()
}


def build_controller(spec: dict[str, Any], plant: Plant, *, path: Path | str = "<controller>",
                     backlash: float | None = None, sensors: Sensors | None = None,
                     progress: Callable[[float], Any] | None = None) -> Controller:
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
    sensors : Sensors, optional
        The model's encoders, as the design knows them: the MPC's default ``measurement_noise`` follows them
        (see :func:`gearctl.design.mpc.build_mpc`), and the inverses' rattle guard is never finer than the motor
        encoder (:func:`gearctl.design.deadzone.jump_floor`); the other kinds do not use them.
    progress : callable, optional
        Called with the fraction of the design done: an MPC's condensed QPs, which take seconds to minutes at long
        horizons (:class:`~gearctl.design.mpc.MPC`); the other kinds are designed at once and do not call it.

    Returns
    -------
    Controller

    Raises
    ------
    InputError
        For an unknown kind or key, or a value out of range; for a controller that reads the load encoder when
        ``sensors`` say the servo has none (``load_encoder = false``).
    """
    path = Path(path)
    kind = spec.get("kind")
    if kind is None and ("gear1" in spec or "stage" in spec):  # load_controller("models/shing1993_servo.toml", ...)
        raise InputError(f"{path}: a model file ([gear1] or [[stage]] tables), not a controller: a controller file "
                         f"has kind = one of {', '.join(MODULES)}", field="kind")
    if kind is None:
        raise InputError(f"{path}: missing key kind: expected one of {', '.join(MODULES)} (kind = \"pid\", ...)",
                         field="kind")
    if not isinstance(kind, str) or kind not in MODULES:  # a list or table is no kind (and unhashable)
        close = difflib.get_close_matches(str(kind), list(MODULES), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise InputError(f"{path}: kind = {kind!r} is not a controller kind: expected one of "
                         f"{', '.join(MODULES)}{hint}", field="kind")
    if "source" not in spec:
        raise InputError(f"{path}: missing section [source] (citation or notes)", field="source")
    check_source(path, spec["source"], required=("citation", "notes"))
    if backlash is not None:
        try:
            BACKLASH.check("backlash", backlash)
        except InputError as exc:
            raise InputError(f"{path}: {exc}", field="backlash", rule=exc.rule) from None
    name = spec.get("name", path.stem)
    control = isinstance(name, str) and any((ord(ch) < 32 and ch != "\t") or ord(ch) == 127 for ch in name)
    if "name" not in spec:
        if control or not name.strip():
            # the default, the file's stem: no name = was given to name in the message, and the 200-character cap
            # is the key's (a file named with 201-255 characters ran before that cap, and still does)
            raise InputError(f"{str(path)!r}: the file's name {name!r}, the controller's default name, cannot head "
                             "its notes (a line break or other control character but a tab, or no name): set name = "
                             "\"...\" in the file, or rename it", field="name")
    elif not (isinstance(name, str) and name.strip() and len(name) <= 200 and not control):
        # the name heads the controller's notes, tables and files: a list or a line break there misreads them
        raise InputError(f"{path}: name = {name!r} is not a controller name: expected a string of 1 to 200 "
                         "characters without line breaks or other control characters but tabs", field="name")
    info = loop_info(plant)
    if kind == "mpc":  # the MPC takes its sample time as an argument (its settings have none)
        ts = spec.get("sample_time", 1e-3)
        try:
            Ts = SAMPLE_TIME.check("sample_time", ts)
        except InputError as exc:
            raise InputError(f"{path}: sample_time = {ts!r} {exc.rule}", field="sample_time", rule=exc.rule) from None
        ctrl = mpc.build_mpc(path, spec, info, Ts=Ts, name=name, backlash=backlash, sensors=sensors,
                             progress=progress)
    elif kind in ("deadzone_inverse", "adaptive_inverse"):  # the rattle guard's floor follows the motor encoder
        ctrl = MODULES[kind].build(path, spec, info, name=name, backlash=backlash, sensors=sensors)
    else:
        ctrl = MODULES[kind].build(path, spec, info, name=name, backlash=backlash)
    if sensors is not None:
        sensors.check_controller(ctrl, str(path))
    return ctrl
