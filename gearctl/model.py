"""A gear model: the stages of a gear train (a pair is one stage), the servo and the sensors.

This is what a model file describes and :func:`gearctl.catalog.load_model` returns. Every check that
relates one key to the others (an inertia against the gears on its shaft, a friction against the
shaft's inertia, a measured stiffness against the computed one) is here, in :func:`check_model`, so a
value valid in one place is valid everywhere.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

from .errors import InputError
from .geometry import GearPair, pair_geometry
from .params import MeshDynamics, Sensors, Servo
from .stiffness import mesh_stiffness
from .units import BACKLASH

__all__ = ["StageModel", "GearModel", "check_model", "MAX_INERTIA_RATIO", "MAX_FRICTION_RATE",
           "STIFFNESS_FACTOR", "MAX_BACKLASH_PER_MODULE"]

#: A motor, load or added inertia may be at most this many times the inertia of the gears on its shaft.
MAX_INERTIA_RATIO = 1e6
#: Viscous friction over inertia (the inverse of a shaft's mechanical time constant) at most [1/s].
MAX_FRICTION_RATE = 1e5
#: A given mesh stiffness must lie within this factor of the one computed from the gear data.
STIFFNESS_FACTOR = 1e3
#: Backlash along the line of action at most this fraction of the module.
MAX_BACKLASH_PER_MODULE = 0.5


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class StageModel:
    """One stage of a train: a gear pair and its mesh dynamics."""

    pair: GearPair
    dynamics: MeshDynamics


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class GearModel:
    """A gear-train definition from the catalog: the stages, the servo and the sensors.

    Attributes
    ----------
    name : str
        Catalog name (the file's stem).
    stages : tuple of StageModel
        The stages, motor side first (one for a pair).
    servo : Servo
        Motor, load, friction, torque limit.
    sensors : Sensors
        Encoders.
    source : mapping
        The file's ``[source]`` table.
    path : Path or None
        The file.

    Variants are made with :meth:`with_backlash` or :func:`dataclasses.replace`.
    """

    name: str
    stages: tuple[StageModel, ...]
    servo: Servo = dataclasses.field(default_factory=Servo)
    sensors: Sensors = dataclasses.field(default_factory=Sensors)
    source: Mapping[str, str] = dataclasses.field(default_factory=dict)
    path: Path | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "stages", tuple(self.stages))

    @classmethod
    def from_pair(cls, name: str, pair: GearPair, dynamics: MeshDynamics, **kw: object) -> GearModel:
        """A one-stage model from a gear pair and its dynamics."""
        return cls(name=name, stages=(StageModel(pair=pair, dynamics=dynamics),), **kw)  # type: ignore[arg-type]

    @property
    def n_stages(self) -> int:
        """Number of stages."""
        return len(self.stages)

    @property
    def pair(self) -> GearPair:
        """The gear pair of a one-stage model; for a train, its first stage's (the motor's pinion and its gear).

        Code that handles trains reads :attr:`stages`.
        """
        return self.stages[0].pair

    @property
    def dynamics(self) -> MeshDynamics:
        """The mesh dynamics of a one-stage model; for a train, its first stage's."""
        return self.stages[0].dynamics

    def with_backlash(self, backlash: float | Sequence[float]) -> GearModel:
        """Copy with another backlash [m]: one value for every stage or one per stage (0: backlash-free)."""
        n = len(self.stages)
        vals = tuple(backlash) if isinstance(backlash, Sequence) else (backlash,) * n
        if len(vals) != n:
            raise InputError(f"backlash = {list(vals)!r} has {len(vals)} values: expected 1 or {n} (one per stage)",
                             field="backlash")
        stages = tuple(dataclasses.replace(s, pair=dataclasses.replace(s.pair, backlash=BACKLASH.check("backlash", b)))
                       for s, b in zip(self.stages, vals, strict=True))
        return dataclasses.replace(self, stages=stages)


def check_model(model: GearModel) -> None:
    """Check the ranges that relate keys to each other and to the gear data.

    Raises
    ------
    InputError
        Naming the key (``[stage i] key`` for a train's stage, ``[servo] key`` for the servo), its
        value and the allowed range computed from the gear data; ``error.field`` is the key.
    """
    n = len(model.stages)
    servo = model.servo
    multi = n > 1
    for name in ("intermediate_inertia", "intermediate_viscous_friction", "intermediate_coulomb_friction"):
        vals = getattr(servo, name)
        if vals and len(vals) != n - 1:
            raise InputError(f"[servo] {name} = {list(vals)!r} has {len(vals)} values: expected one per "
                             f"intermediate shaft ({n - 1})", field=name)
    geos = [pair_geometry(s.pair) for s in model.stages]
    for i, sm in enumerate(model.stages):
        where = f"[stage {i + 1}] " if multi else "[pair] "
        b, m = sm.pair.backlash, sm.pair.module
        if b > MAX_BACKLASH_PER_MODULE * m:
            raise InputError(f"{where}backlash = {b!r} is out of range: expected at most {MAX_BACKLASH_PER_MODULE:g} "
                             f"x module = {MAX_BACKLASH_PER_MODULE * m:g} [m] for this stage", field="backlash")
        dyn = sm.dynamics
        dwhere = f"[stage {i + 1}] " if multi else "[dynamics] "
        if dyn.mesh_stiffness is not None:
            k0 = mesh_stiffness(sm.pair, points=16).mean
            lo, hi = k0 / STIFFNESS_FACTOR, k0 * STIFFNESS_FACTOR
            if not lo <= dyn.mesh_stiffness <= hi:
                raise InputError(f"{dwhere}mesh_stiffness = {dyn.mesh_stiffness!r} is out of range: expected "
                                 f"{lo:.4g} <= value <= {hi:.4g} [N/m] (within {STIFFNESS_FACTOR:g}x the "
                                 f"{k0:.4g} N/m computed from the gear data)", field="mesh_stiffness")
    # gears on each shaft, and what the servo adds
    gear = [geos[0].inertia[0]] + [geos[j - 1].inertia[1] + geos[j].inertia[0] for j in range(1, n)] + [
        geos[-1].inertia[1]]
    added = [("motor_inertia", 0, servo.motor_inertia), ("load_inertia", n, servo.load_inertia)] + [
        ("intermediate_inertia", j + 1, v) for j, v in enumerate(servo.intermediate_inertia)]
    total = list(gear)
    for key, j, v in added:
        cap = MAX_INERTIA_RATIO * gear[j]
        if v > cap:
            raise InputError(f"[servo] {key} = {v!r} is out of range: expected 0 <= value <= {cap:.4g} [kg m^2] "
                             f"({MAX_INERTIA_RATIO:g}x the {gear[j]:.4g} kg m^2 of the gears on that shaft)", field=key)
        total[j] += v
    fr = [("viscous_friction1", 0, servo.viscous_friction1), ("viscous_friction2", n, servo.viscous_friction2)] + [
        ("intermediate_viscous_friction", j + 1, v) for j, v in enumerate(servo.intermediate_viscous_friction)]
    for key, j, v in fr:
        cap = MAX_FRICTION_RATE * total[j]
        if v > cap:
            raise InputError(f"[servo] {key} = {v!r} is out of range: expected 0 <= value <= {cap:.4g} [N m s/rad] "
                             f"(a time constant J/d of at least {1e6 / MAX_FRICTION_RATE:g} us on a shaft of "
                             f"{total[j]:.4g} kg m^2)", field=key)
    if not math.isfinite(sum(total)):
        raise InputError("the shaft inertias are not finite", field="inertia")
