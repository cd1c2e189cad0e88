"""Dead-zone inverse: cross the backlash gap on purpose, on the flank that must carry the load.

Seen from the motor, the backlash is a dead zone of width ``2 b`` along the line of action, i.e.
``2 b / r_b2`` of load angle. The inverse offsets the motor's position target by ``sigma b / r_b2`` (load
units) so that the intended flank is closed and the load follows as if there were no gap. ``sigma`` is a
smooth sign (``tanh``) of either

- the torque the mesh must transmit to the load, ``J2 r'' + d2 r' + T_c2 sign(r') - load_torque``
  (the default: on an
  inertia-dominated load the decelerating half of every cycle is carried by the back flank although
  the motion is still forward), or
- the reference velocity ``r'`` (the textbook rule, which is wrong over half of each cycle for an inertial
  load).

The transition width keeps noise from chattering between the flanks; while the reference is at rest the
last flank is held (a load stopped by friction rests on the flank that drove it).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

from ..controller import ReferenceLike
from ..errors import InputError
from ..files import Layout, build_dataclass, spec_values
from ..units import BACKLASH, check_choice, quantity, validate_fields
from .base import Controller, LoopInfo
from .pid import LOOP_KEYS, PID, PID_TABLES, LoopSettings, pid_from_values, restate

__all__ = ["DeadzoneInverse", "InverseSettings", "KIND", "LAYOUT", "build"]

#: The controller-file kind this module builds (:mod:`gearctl.design.registry`).
KIND = "deadzone_inverse"


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class InverseSettings:
    """The inverse's own keys of a ``deadzone_inverse`` file."""

    rule: str = "torque"
    width: float | None = quantity(unit="N m or rad/s", doc="transition width of the smooth sign (torque rule: "
                                   "N m; velocity rule: rad/s)", low=0.0, low_open=True, high=1e3, optional=True,
                                   default=None)
    backlash: float | None = BACKLASH.field(default=None, optional=True, doc="backlash estimate (default: the "
                                            "model's)")

    def __post_init__(self) -> None:
        check_choice("rule", self.rule, ("torque", "velocity"))
        validate_fields(self)


class DeadzoneInverse(Controller):
    """A PID wrapped in a backlash (dead-zone) inverse.

    Parameters
    ----------
    pid : PID
        The position PID it wraps (its feedback setting decides the structure, see Notes).
    backlash : float
        Backlash estimate ``b`` along the line of action [m] (from the model or the controller file,
        so that a wrong estimate can be tested).
    rule : str
        ``"torque"`` (default) or ``"velocity"``: what decides the flank.
    width : float
        Transition width of the smooth sign: [N m] for the torque rule, [rad/s] for the velocity rule.

    Notes
    -----
    With motor-side feedback the PID regulates ``theta1 / N`` to ``r + sigma b / r_b2``. With load-side
    feedback the proportional and derivative action stay on the motor encoder (collocated, so the loop
    is stable in the gap too, where the load is not connected), aimed at ``r + sigma b / r_b2``, and the
    integral acts on the load error ``r - theta2``, which removes what the offset misses (a wrong
    backlash estimate, mesh deflection).
    """

    def __init__(self, pid: PID, *, backlash: float, rule: str = "torque", width: float | None = None,
                 name: str = "deadzone_inverse") -> None:
        super().__init__()
        check_choice("rule", rule, ("torque", "velocity"))
        BACKLASH.check("backlash", backlash)
        self.pid, self.backlash, self.rule, self.name = pid, backlash, rule, name
        self.width = width if width is not None else (5e-4 if rule == "torque" else 1e-2)
        if not (self.width > 0 and math.isfinite(self.width)):
            raise InputError(f"width = {self.width!r} is out of range: expected a number > 0", field="width")
        self.Ts = pid.Ts
        self.uses_load_encoder = pid.feedback == "load"
        p = pid.info.plant
        self._offset = backlash / p.rb2  # half the lost motion, load angle [rad]
        self._J2, self._d2, self._tl = p.J2, p.d2, p.load_torque
        self._tc2 = p.tc2
        self.reset()

    def set_backlash(self, backlash: float) -> None:
        """Change the backlash estimate ``b`` [m] (e.g. an adaptive law's), keeping every other state."""
        BACKLASH.check("backlash", backlash)
        self.backlash = backlash
        self._offset = backlash / self.pid.info.plant.rb2

    def reset(self) -> None:
        """Reset the wrapped PID and the held flank."""
        self.pid.reset()
        self._sigma = 0.0
        self.solve_times, self.fallbacks = [], []

    def flank(self, t: float, ref: ReferenceLike) -> float:
        """Smooth sign in [-1, 1] of the flank that must carry the load (+1 front, -1 back).

        While the reference is at rest (``r' = r'' = 0``) the last value is held: a load that friction
        stopped on the driving flank stays there, so the offset must too.
        """
        r, rd, rdd = ref.at(t)
        if rd == 0.0 and rdd == 0.0:
            return self._sigma
        if self.rule == "torque":  # the model's known load and friction, not the (unknown) disturbance
            drive = self._J2 * rdd + self._d2 * rd - self._tl
            if self._tc2 > 0.0 and rd != 0.0:  # full Coulomb friction while the load moves
                drive += math.copysign(self._tc2, rd)
        else:
            drive = rd
        self._sigma = math.tanh(drive / self.width)
        return self._sigma

    def step(self, t: float, y_motor: float, y_load: float | None, ref: ReferenceLike) -> float:
        r, rd, rdd = ref.at(t)
        target = r + self.flank(t, ref) * self._offset
        ym = y_motor / self.pid.N
        if self.pid.feedback == "motor":
            return self.pid.torque(t, target, rd, rdd, target - ym, ym, target - ym)
        return self.pid.torque(t, target, rd, rdd, target - ym, ym, r - float(y_load))  # type: ignore[arg-type]

    def describe(self) -> dict[str, Any]:
        """Settings of the inverse and of the PID."""
        return {**self.pid.describe(), "name": self.name, "kind": "deadzone_inverse", "rule": self.rule,
                "width": self.width, "backlash_estimate": self.backlash}


#: The keys of a ``deadzone_inverse`` controller file and the settings fields they feed.
LAYOUT: Layout = {"": {**LOOP_KEYS, **{f.name: (InverseSettings, f.name) for f in dataclasses.fields(InverseSettings)}},
                  **PID_TABLES}


def build(path: Path, spec: dict[str, Any], info: LoopInfo, *, name: str,
          backlash: float | None = None) -> DeadzoneInverse:
    """The inverse of a ``kind = "deadzone_inverse"`` file; ``backlash`` overrides the file's estimate."""
    values = spec_values(path, spec, LAYOUT, kind=KIND)
    loop = build_dataclass(path, LoopSettings, values.get(LoopSettings, {}))
    settings = build_dataclass(path, InverseSettings, values.get(InverseSettings, {}))
    b = backlash if backlash is not None else (settings.backlash if settings.backlash is not None
                                               else info.plant.backlash)
    pid = pid_from_values(path, values, info, loop, name + "/pid")
    try:
        return DeadzoneInverse(pid, backlash=b, rule=settings.rule, width=settings.width, name=name)
    except InputError as exc:
        raise restate(path, exc, values) from None
