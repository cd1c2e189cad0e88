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
from typing import Any

import numpy as np

from .errors import InputError
from .geometry import GearPair, Geometry, pair_geometry
from .params import FrictionLaw, MeshDynamics, Sensors, Servo
from .stiffness import equivalent_mass, mesh_stiffness
from .units import BACKLASH, BASE_RADIUS, DAMPING_RATIO, INERTIA, MESH_DAMPING

__all__ = ["StageModel", "GearModel", "check_model", "disk_inertia", "MAX_INERTIA_RATIO", "MAX_FRICTION_RATE",
           "STIFFNESS_FACTOR", "MAX_BACKLASH_PER_MODULE", "MIN_FACE_WIDTH_PER_MODULE", "GEAR_INERTIA_FACTOR"]

#: A motor, load or added inertia may be at most this many times the inertia of the gears on its shaft.
MAX_INERTIA_RATIO = 1e6
#: Viscous friction over inertia (the inverse of a shaft's mechanical time constant) at most [1/s].
MAX_FRICTION_RATE = 1e5
#: A given mesh stiffness must lie within this factor of the one computed from the gear data.
STIFFNESS_FACTOR = 1e3
#: Backlash along the line of action at most this fraction of the module.
MAX_BACKLASH_PER_MODULE = 0.5
#: Face width at least this fraction of the module (a gear thinner than a tenth of its module is a blade).
MIN_FACE_WIDTH_PER_MODULE = 0.1
#: A given gear inertia within this factor of the solid disk of its pitch radius and face width, either way
#: (a thin-rimmed wheel is a few times lighter, a pinion with its hub and shaft a few times heavier).
GEAR_INERTIA_FACTOR = 1e3

# where the pair format puts each stage key (a train writes ``[stage i] key``)
_PAIR_LABELS = {"teeth1": "[gear1] teeth", "teeth2": "[gear2] teeth", "inertia1": "[gear1] inertia",
                "inertia2": "[gear2] inertia", "module": "[pair] module", "face_width": "[pair] face_width",
                "backlash": "[pair] backlash", "density": "[material] density",
                "damping_ratio": "[dynamics] damping_ratio", "mesh_stiffness": "[dynamics] mesh_stiffness",
                "damping_coefficient": "[dynamics] damping_coefficient"}


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class StageModel:
    """One stage of a train: a gear pair and its mesh dynamics.

    Parameters
    ----------
    pair : GearPair
        The stage's gears (``[pair]``, ``[gear1]``, ``[gear2]`` of the model file).
    dynamics : MeshDynamics
        The stage's mesh dynamics (``[dynamics]``).
    """

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
        """A one-stage model from a gear pair and its dynamics.

        Parameters
        ----------
        name : str
            Catalog name of the model.
        pair : GearPair
            The gear pair of the one stage.
        dynamics : MeshDynamics
            Its mesh stiffness and damping.
        **kw
            The other fields of :class:`GearModel`: ``servo``, ``sensors``, ``source``, ``path``.
        """
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
        """Copy with another backlash [m]: one value for every stage or one per stage (0: backlash-free).

        Parameters
        ----------
        backlash : float or sequence of float
            Backlash ``b`` along the line of action [m]: one value for every stage, or one per stage.

        Raises
        ------
        InputError
            Naming ``backlash``: a count other than 1 or one per stage, or a value out of its range.
        """
        vals = per_stage_backlash(backlash, len(self.stages))
        stages = tuple(dataclasses.replace(s, pair=dataclasses.replace(s.pair, backlash=b))
                       for s, b in zip(self.stages, vals, strict=True))
        return dataclasses.replace(self, stages=stages)


def per_stage_backlash(value: Any, n: int) -> tuple[float, ...]:
    """One backlash [m] for every stage, or one per stage (a sequence or a 1-D array), each checked.

    Raises
    ------
    InputError
        Naming ``backlash``: a count other than 1 or ``n``, or a value out of :data:`~gearctl.units.BACKLASH`.
    """
    try:
        ndim = 0 if isinstance(value, str | bytes) else np.ndim(value)
    except ValueError:  # a ragged nesting
        ndim = -1
    if ndim == 0:
        vals = (value,) * n
    elif ndim == 1 and isinstance(value, Sequence | np.ndarray):
        vals = tuple(value)
    else:
        raise InputError(f"backlash = {value!r} is not a backlash: expected one number, or a list or 1-D array "
                         f"of one per stage ({n}) [m]", field="backlash")
    if len(vals) != n:
        raise InputError(f"backlash = {list(vals)!r} has {len(vals)} values: expected 1 or one per stage ({n})",
                         field="backlash")
    return tuple(BACKLASH.check("backlash", v.item() if isinstance(v, np.generic | np.ndarray) else v) for v in vals)


def _label(multi: bool, i: int, key: str) -> str:
    """How the file names a stage's key: ``[stage i] key`` in a train, the pair format's table otherwise."""
    return f"[stage {i + 1}] {key}" if multi else _PAIR_LABELS.get(key, key)


def _check_stage_geometry(sm: StageModel, geo: Geometry, multi: bool, i: int) -> None:
    """The gear data against each other: size, face width, backlash and given inertias against the module."""
    p = sm.pair
    m = p.module
    for j, (teeth, rb) in enumerate(((p.teeth1, geo.base_radius[0]), (p.teeth2, geo.base_radius[1])), start=1):
        if rb > BASE_RADIUS.upper:
            raise InputError(
                f"{_label(multi, i, f'teeth{j}')} = {teeth} with {_label(multi, i, 'module')} = {m!r} gives gear {j} a "
                f"base radius of {rb:.4g} m (pitch radius {geo.pitch_radius[j - 1]:.4g} m): expected teeth x module "
                f"x cos(pressure angle) / 2 <= {BASE_RADIUS.high:g} [m]; use fewer teeth or a smaller module",
                field=f"teeth{j}" if multi else "teeth")
    if p.face_width < MIN_FACE_WIDTH_PER_MODULE * m:
        raise InputError(f"{_label(multi, i, 'face_width')} = {p.face_width!r} is out of range: expected at least "
                         f"{MIN_FACE_WIDTH_PER_MODULE:g} x module = {MIN_FACE_WIDTH_PER_MODULE * m:.4g} [m]"
                         f"{' for this stage' if multi else ''}", field="face_width")
    if p.backlash > MAX_BACKLASH_PER_MODULE * m:
        raise InputError(f"{_label(multi, i, 'backlash')} = {p.backlash!r} is out of range: expected at most "
                         f"{MAX_BACKLASH_PER_MODULE:g} x module = {MAX_BACKLASH_PER_MODULE * m:g} [m]"
                         f"{' for this stage' if multi else ''}",
                         field="backlash")
    for j, given in enumerate((p.inertia1, p.inertia2), start=1):
        if given is None:
            continue
        disk = disk_inertia(p, geo.pitch_radius[j - 1])
        lo, hi = disk / GEAR_INERTIA_FACTOR, disk * GEAR_INERTIA_FACTOR
        if not lo <= given <= hi:
            raise InputError(f"{_label(multi, i, f'inertia{j}')} = {given!r} is out of range: expected {lo:.4g} <= "
                             f"value <= {hi:.4g} [kg m^2] (within {GEAR_INERTIA_FACTOR:g}x the {disk:.4g} kg m^2 of a "
                             f"solid disk of gear {j}'s pitch radius and face width)",
                             field=f"inertia{j}" if multi else "inertia")


def disk_inertia(pair: GearPair, radius: float) -> float:
    """Inertia of a solid disk of ``radius`` [m], the pair's face width and density [kg m^2]: ``rho pi f r^4 / 2``.

    Parameters
    ----------
    pair : GearPair
        Gives the face width ``f`` [m] and the density ``rho`` [kg/m^3].
    radius : float
        The disk's radius ``r`` [m].

    Returns
    -------
    float
        The inertia [kg m^2].
    """
    return pair.density * math.pi * pair.face_width * radius**4 / 2


def _gear_culprit(model: GearModel, geos: list[Geometry], j: int) -> str:
    """The keys that make the gears of shaft ``j`` heavy: a given inertia, or the data of the solid disk."""
    n, multi = len(model.stages), len(model.stages) > 1
    on = ([(j - 1, 2)] if j > 0 else []) + ([(j, 1)] if j < n else [])  # (stage, gear) pairs on the shaft
    i, g = max(on, key=lambda sg: geos[sg[0]].inertia[sg[1] - 1])
    p = model.stages[i].pair
    given = p.inertia1 if g == 1 else p.inertia2
    if given is not None:
        return f"{_label(multi, i, f'inertia{g}')} = {given!r}"
    teeth = p.teeth1 if g == 1 else p.teeth2
    return (f"{_label(multi, i, f'teeth{g}')} = {teeth} with {_label(multi, i, 'module')} = {p.module!r}, "
            f"{_label(multi, i, 'face_width')} = {p.face_width!r} and {_label(multi, i, 'density')} = "
            f"{p.density!r} (gear {g} a solid disk of {geos[i].inertia[g - 1]:.4g} kg m^2)")


def check_model(model: GearModel) -> None:
    """Check the ranges that relate keys to each other and to the gear data.

    Each check names the key the user wrote (``[gear1] teeth``, ``[pair] face_width``, ``[servo]
    motor_inertia``; ``[stage i] key`` in a train), never a quantity derived from it, so that nothing the
    plant (:class:`~gearctl.plant.Plant`) refuses later passes here:

    - gear size: base radius ``teeth x module x cos(alpha) / 2`` at most :data:`~gearctl.units.BASE_RADIUS`'s
      10 m; face width at least :data:`MIN_FACE_WIDTH_PER_MODULE` x module; backlash at most
      :data:`MAX_BACKLASH_PER_MODULE` x module; a given gear inertia within :data:`GEAR_INERTIA_FACTOR` of
      the solid disk of its pitch radius and face width; a given mesh stiffness within
      :data:`STIFFNESS_FACTOR` of the computed one;
    - shafts: an added (motor, load, intermediate) inertia at most :data:`MAX_INERTIA_RATIO` x the gears on
      its shaft, and the shaft's total at most :data:`~gearctl.units.INERTIA`'s 1e6 kg m^2; viscous friction
      at most :data:`MAX_FRICTION_RATE` x the shaft's inertia, and with ``friction_law = "smooth"`` the
      smooth law's slope at standstill ``T_c / coulomb_velocity`` too (it is a viscous friction there);
    - mesh damping: ``c = 2 zeta sqrt(k m_eq)`` from ``damping_ratio`` within
      :data:`~gearctl.units.MESH_DAMPING`'s range.

    Parameters
    ----------
    model : GearModel
        The model as read (every field already in its own range).

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
    stiffness: dict[int, float] = {}  # computed mean mesh stiffness per stage, when needed
    for i, sm in enumerate(model.stages):
        _check_stage_geometry(sm, geos[i], multi, i)
        dyn = sm.dynamics
        if dyn.mesh_stiffness is not None:
            k0 = stiffness[i] = mesh_stiffness(sm.pair, points=16).mean
            lo, hi = k0 / STIFFNESS_FACTOR, k0 * STIFFNESS_FACTOR
            if not lo <= dyn.mesh_stiffness <= hi:
                raise InputError(f"{_label(multi, i, 'mesh_stiffness')} = {dyn.mesh_stiffness!r} is out of range: "
                                 f"expected {lo:.4g} <= value <= {hi:.4g} [N/m] (within {STIFFNESS_FACTOR:g}x the "
                                 f"{k0:.4g} N/m computed from the gear data)", field="mesh_stiffness")
    # gears on each shaft, and what the servo adds
    gear = [geos[0].inertia[0]] + [geos[j - 1].inertia[1] + geos[j].inertia[0] for j in range(1, n)] + [
        geos[-1].inertia[1]]
    added = [("motor_inertia", 0, servo.motor_inertia), ("load_inertia", n, servo.load_inertia)] + [
        ("intermediate_inertia", j + 1, v) for j, v in enumerate(servo.intermediate_inertia)]
    total = list(gear)
    for key, j, v in added:
        cap = min(MAX_INERTIA_RATIO * gear[j], INERTIA.upper - gear[j])
        if v > cap and gear[j] < INERTIA.upper:
            why = (f"{MAX_INERTIA_RATIO:g}x the {gear[j]:.4g} kg m^2 of the gears on that shaft" if cap < INERTIA.upper
                   - gear[j] else f"the shaft's inertia, with the {gear[j]:.4g} kg m^2 of its gears, at most "
                   f"{INERTIA.high:g} kg m^2")
            raise InputError(f"[servo] {key} = {v!r} is out of range: expected 0 <= value <= {cap:.4g} [kg m^2] "
                             f"({why})", field=key)
        total[j] += v
    for j, J in enumerate(total):
        if not J <= INERTIA.upper:
            raise InputError(f"{_gear_culprit(model, geos, j)} gives shaft {j + 1} an inertia of {J:.4g} kg m^2: "
                             f"expected at most {INERTIA.high:g} kg m^2 on a shaft; use a smaller gear",
                             field="inertia")
    fr = [("viscous_friction1", 0, servo.viscous_friction1), ("viscous_friction2", n, servo.viscous_friction2)] + [
        ("intermediate_viscous_friction", j + 1, v) for j, v in enumerate(servo.intermediate_viscous_friction)]
    viscous = [0.0] * (n + 1)
    for key, j, v in fr:
        cap = MAX_FRICTION_RATE * total[j]
        if v > cap:
            raise InputError(f"[servo] {key} = {v!r} is out of range: expected 0 <= value <= {cap:.4g} [N m s/rad] "
                             f"(a time constant J/d of at least {1e6 / MAX_FRICTION_RATE:g} us on a shaft of "
                             f"{total[j]:.4g} kg m^2)", field=key)
        viscous[j] = v
    if servo.friction_law is FrictionLaw.SMOOTH:
        _check_smooth_friction(servo, total, viscous)
    for i, sm in enumerate(model.stages):
        _check_mesh_damping(sm, geos[i], total[i], total[i + 1], stiffness.get(i), multi, i)


def _check_smooth_friction(servo: Servo, total: list[float], viscous: list[float]) -> None:
    """The smooth Coulomb law's slope at standstill, ``T_c / omega_s``, is a viscous friction: bound it alike."""
    n = len(total) - 1
    ws = servo.coulomb_velocity
    cf = [("coulomb_friction1", 0, servo.coulomb_friction1), ("coulomb_friction2", n, servo.coulomb_friction2)] + [
        ("intermediate_coulomb_friction", j + 1, v) for j, v in enumerate(servo.intermediate_coulomb_friction)]
    for key, j, tc in cf:
        slope = tc / ws  # may be inf for a tiny coulomb_velocity: refused below
        if viscous[j] + slope > MAX_FRICTION_RATE * total[j]:
            cap = max(MAX_FRICTION_RATE * total[j] - viscous[j], 0.0) * ws
            raise InputError(
                f"[servo] {key} = {tc!r} is out of range with friction_law = \"smooth\" and coulomb_velocity = "
                f"{ws!r}: expected 0 <= value <= {cap:.4g} [N m] (near standstill the smooth law T_c tanh(omega / "
                f"coulomb_velocity) is a viscous friction of {slope:.4g} N m s/rad; with the shaft's viscous "
                f"friction it must leave a time constant J/d of at least {1e6 / MAX_FRICTION_RATE:g} us on a shaft "
                f"of {total[j]:.4g} kg m^2); use friction_law = \"stick_slip\" or a larger coulomb_velocity",
                field=key)


def _check_mesh_damping(sm: StageModel, geo: Geometry, J1: float, J2: float, k: float | None, multi: bool,
                        i: int) -> None:
    """The mesh damping ``c = 2 zeta sqrt(k m_eq)`` the plant will compute, within MESH_DAMPING's range; a given
    ``damping_coefficient``, a damping ratio ``c / (2 sqrt(k m_eq))`` within DAMPING_RATIO's.

    Why the second: a given coefficient was bounded by MESH_DAMPING alone, and on a light mesh 1e8 N s/m is a damping
    ratio of 1e3 to 1e4 (fuzzed pairs: 1822 and 10800). Such a mesh's fast root, ``c / m_eq`` (7.4e10 rad/s), sets
    every solver's step: 3.7e8 steps for 3 ms, 10 s of the exact solver and 15 s of the ODE path, and a 0.1 s loop
    ran 13 s. A gear mesh's damping ratio is a few hundredths to about 0.2 (damping_ratio allows up to 2)."""
    dyn = sm.dynamics
    if dyn.damping_coefficient is not None:
        if dyn.damping_coefficient > 0.0:
            m_eq = equivalent_mass(J1, J2, *geo.base_radius)
            if k is None:
                k = dyn.mesh_stiffness or mesh_stiffness(sm.pair, points=16).mean
            zeta = dyn.damping_coefficient / (2.0 * math.sqrt(k * m_eq))
            if zeta > DAMPING_RATIO.upper:
                cmax = DAMPING_RATIO.upper * 2.0 * math.sqrt(k * m_eq)
                raise InputError(f"{_label(multi, i, 'damping_coefficient')} = {dyn.damping_coefficient!r} is out of "
                                 f"range: expected 0 <= value <= {cmax:.4g} [N s/m] for this "
                                 f"{'stage' if multi else 'pair'} (a damping ratio c / (2 sqrt(k m_eq)) of at most "
                                 f"{DAMPING_RATIO.high:g}, as damping_ratio's, with k = {k:.4g} N/m and m_eq = "
                                 f"{m_eq:.4g} kg of the shaft inertias; this value is {zeta:.4g})",
                                 field="damping_coefficient")
        return
    if dyn.damping_ratio == 0.0:
        return
    m_eq = equivalent_mass(J1, J2, *geo.base_radius)
    # cheap bound first: a mean mesh stiffness is well below E f (0.07 E f for the report's pair)
    k_bound = dyn.mesh_stiffness or sm.pair.young_modulus * sm.pair.face_width
    if 2.0 * dyn.damping_ratio * math.sqrt(k_bound * m_eq) <= MESH_DAMPING.upper:
        return
    if k is None:
        k = dyn.mesh_stiffness or mesh_stiffness(sm.pair, points=16).mean
    c = 2.0 * dyn.damping_ratio * math.sqrt(k * m_eq)
    if c > MESH_DAMPING.upper:
        zmax = MESH_DAMPING.upper / (2.0 * math.sqrt(k * m_eq))
        raise InputError(f"{_label(multi, i, 'damping_ratio')} = {dyn.damping_ratio!r} is out of range: expected "
                         f"0 <= value <= {zmax:.4g} for this {'stage' if multi else 'pair'} (its mesh damping "
                         f"c = 2 zeta sqrt(k m_eq) = "
                         f"{c:.4g} N s/m with k = {k:.4g} N/m and m_eq = {m_eq:.4g} kg of the shaft inertias; at most "
                         f"{MESH_DAMPING.high:g} N s/m); or give {_label(multi, i, 'damping_coefficient')}",
                         field="damping_ratio")
