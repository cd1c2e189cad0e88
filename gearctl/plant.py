"""The gear plants: n stages on n + 1 shafts, improved (report section 2), Yang–Sun (section 4) and
time-varying stiffness. A pair is the one-stage case.

:func:`build_plant` turns a :class:`~gearctl.catalog.GearModel` into a :class:`Plant`: the shafts (inertia,
friction), the stages (base radii, backlash, stiffness, damping) and the servo's limits. This module is
also the one definition of the dynamics every solver and design model uses:

- :func:`mode_matrices` and :func:`input_matrix`: ``x' = A x + B u + e`` per contact pattern;
- :func:`force_coefficients` and :func:`mesh_force`: the contact force law;
- :func:`affine_terms` and :func:`event_table`: the constant terms and the mode boundaries the kernel
  integrates and locates (:mod:`gearctl.kernel` receives them as data).

State ``x = [theta_0 .. theta_n, omega_0 .. omega_n]`` [rad, rad/s], shaft 0 the motor shaft, shaft n the
load shaft; input ``u = [xi_motor, xi_load]`` [N m]. Signs as in the report: every shaft angle is positive
in the direction the train moves forward, so that ``s_i = r_b1,i theta_(i-1) - r_b2,i theta_i`` is the
relative displacement of stage i along its line of action; ``s > b`` is front contact, ``|s| <= b``
separation, ``s < -b`` back contact. A pair keeps the report's names: ``theta1, theta2, omega1, omega2``
and ``xi1, xi2``.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InputError, short_repr
from .geometry import pair_geometry
from .model import MAX_BACKLASH_PER_MODULE, per_stage_backlash
from .params import ContactLaw, FrictionLaw
from .stiffness import (
    damping_coefficient,
    equivalent_mass,
    mesh_stiffness,
    mesh_stiffness_at,
    yang_sun_damping_factor,
    yang_sun_stiffness,
)
from .units import (
    BASE_RADIUS,
    COULOMB_FRICTION,
    COULOMB_VELOCITY,
    GAP,
    INERTIA,
    LOAD_TORQUE,
    MESH_DAMPING,
    MESH_STIFFNESS,
    TORQUE_LIMIT,
    VISCOUS_FRICTION,
    validate_fields,
)

if TYPE_CHECKING:
    from .catalog import GearModel

__all__ = [
    "Mode", "PlantKind", "Shaft", "Stage", "Plant", "build_plant", "plant_nlsys", "STATES", "INPUTS",
    "MAX_STAGES", "mode_matrices", "input_matrix", "force_coefficients", "affine_terms", "event_table",
    "mesh_force", "signal_names", "check_plant",
]

#: State and input names of a pair (report eqs 1-12); a train's are ``theta0..thetan``, ``omega0..omegan``.
STATES = ("theta1", "theta2", "omega1", "omega2")
INPUTS = ("xi1", "xi2")

#: Most stages a plant may have (the kernel's fixed-size buffers follow from it).
MAX_STAGES = 6


class Mode(enum.IntEnum):
    """Contact mode of a stage (report section 2, cases 1–3)."""

    BACK = -1
    SEPARATION = 0
    FRONT = 1

    @property
    def label(self) -> str:
        """Lower-case name used in CSV and JSON (``front``, ``separation``, ``back``)."""
        return self.name.lower()


class PlantKind(enum.StrEnum):
    """Which mesh law the plant uses (every stage the same)."""

    IMPROVED = "improved"
    YANG_SUN = "yang-sun"
    TVMS = "tvms"


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class Shaft:
    """A shaft with everything on it: its gears, and the motor or the load.

    Attributes
    ----------
    J : float
        Total inertia [kg m^2].
    d : float
        Viscous friction [N m s/rad].
    tc : float
        Coulomb friction [N m].
    """

    J: float = INERTIA.field(doc="inertia of the shaft (its gears plus motor or load)")
    d: float = VISCOUS_FRICTION.field(default=0.0)
    tc: float = COULOMB_FRICTION.field(default=0.0)

    def __post_init__(self) -> None:
        validate_fields(self)


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class Stage:
    """One mesh: the pinion on shaft ``i`` drives the gear on shaft ``i + 1``.

    Attributes
    ----------
    rb1, rb2 : float
        Base radii of the pinion and the gear [m].
    backlash : float
        Half-gap ``b`` along the line of action [m] (contact when ``|s| > b``).
    k, c : float
        Mesh stiffness [N/m] and damping [N s/m] (for ``yang-sun``, ``k`` is eq 39 and ``c`` unused).
    mesh_period : float
        Rotation of the pinion over one mesh cycle, ``2 pi / N1`` [rad].
    mesh_phase : float
        Mesh-cycle angle (from C) of the front flank's contact at zero pinion angle [rad]. Zero is the
        report's neutral position (section 2: a pinion tooth centred on the line of centres): its front
        flank then meets the line of action ``t_b1 / 2 + r_b1 alpha_w`` from A (a quarter base pitch past
        P without shift), so ``mesh_phase = (t_b1 / 2 + r_b1 alpha_w - AC) / r_b1``. The back flank is
        the mirror image: its cycle angle is ``mesh_phase - theta`` where the front's is
        ``mesh_phase + theta`` (:meth:`Plant.stiffness_at`).
    kv_table : ndarray or None
        For ``tvms``: ``K`` sampled uniformly over one mesh cycle [N/m] (periodic, linear interpolation).
    """

    rb1: float = BASE_RADIUS.field(doc="base radius of the pinion")
    rb2: float = BASE_RADIUS.field(doc="base radius of the gear")
    backlash: float = GAP.field()
    k: float = MESH_STIFFNESS.field()
    c: float = MESH_DAMPING.field()
    mesh_period: float = 2 * math.pi
    mesh_phase: float = 0.0
    kv_table: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        validate_fields(self)

    @property
    def ratio(self) -> float:
        """Kinematic ratio of the stage ``r_b2 / r_b1 = N2 / N1``."""
        return self.rb2 / self.rb1


# pair name -> (shaft or stage, index, attribute): the report's names of a one-stage plant
_PAIR_SHAFT = {"J1": (0, "J"), "J2": (1, "J"), "d1": (0, "d"), "d2": (1, "d"), "tc1": (0, "tc"), "tc2": (1, "tc")}
_PAIR_STAGE = ("rb1", "rb2", "backlash", "k", "c", "mesh_period", "mesh_phase", "kv_table")


def _pair_attr(name: str) -> property:
    if name in _PAIR_SHAFT:
        j, attr = _PAIR_SHAFT[name]

        def get(self: Plant) -> Any:
            self._one_stage(name)
            return getattr(self.shafts[j], attr)
    else:
        def get(self: Plant) -> Any:
            self._one_stage(name)
            return getattr(self.stages[0], name)
    get.__doc__ = f"``{name}`` of a pair (one-stage plant): the report's name."
    return property(get)


@dataclasses.dataclass(frozen=True, slots=True, init=False, eq=False)
class Plant:
    """A gear train ready to simulate: shafts, stages and the servo's limits, SI units.

    Parameters
    ----------
    kind : PlantKind
        ``improved`` (mean stiffness, linear law), ``yang-sun`` (Hertz stiffness, ``F = (d x' + k) x``)
        or ``tvms`` (``k = K(vartheta)`` following the rotation of each pinion).
    shafts : sequence of Shaft
        ``n + 1`` shafts, motor first.
    stages : sequence of Stage
        ``n`` stages; stage ``i`` couples shafts ``i`` and ``i + 1``.
    contact_law : ContactLaw
        ``linear`` or ``no_pull`` (every stage).
    friction_law : FrictionLaw
        ``stick_slip`` (default) or ``smooth`` Coulomb friction.
    coulomb_velocity : float
        Velocity scale of the smooth Coulomb law [rad/s].
    torque_limit : float
        Motor torque limit [N m] (``inf``: none).
    load_torque : float
        Constant torque on the load shaft [N m].
    **pair
        For a pair, the report's names may be given instead of (or on top of) ``shafts`` and ``stages``:
        ``J1, J2, d1, d2, tc1, tc2, rb1, rb2, backlash, k, c, mesh_period, mesh_phase, kv_table``. So
        ``dataclasses.replace(plant, k=2e8)`` works on a pair as it always did.

    Raises
    ------
    InputError
        For a value out of its range (named), a count of stages and shafts other than ``n`` and ``n + 1`` (or more
        stages than allowed), a ``kind``, ``contact_law`` or ``friction_law`` not among its choices, or pair names
        given for a train.
    TypeError
        For a keyword that is neither a parameter above nor one of the pair names.
    """

    kind: PlantKind
    shafts: tuple[Shaft, ...]
    stages: tuple[Stage, ...]
    contact_law: ContactLaw
    friction_law: FrictionLaw
    coulomb_velocity: float
    torque_limit: float
    load_torque: float

    def __init__(self, *, kind: PlantKind | str = PlantKind.IMPROVED, shafts: Sequence[Shaft] | None = None,
                 stages: Sequence[Stage] | None = None, contact_law: ContactLaw | str = ContactLaw.LINEAR,
                 friction_law: FrictionLaw | str = FrictionLaw.STICK_SLIP, coulomb_velocity: float = 1e-3,
                 torque_limit: float = math.inf, load_torque: float = 0.0, **pair: Any) -> None:
        unknown = set(pair) - set(_PAIR_SHAFT) - set(_PAIR_STAGE)
        if unknown:
            raise TypeError(f"Plant() got unexpected keyword arguments {sorted(unknown)}")
        shafts = list(shafts) if shafts is not None else []
        stages = list(stages) if stages is not None else []
        if pair:
            if len(stages) > 1 or len(shafts) > 2:
                raise InputError(f"{', '.join(sorted(pair))}: the report's pair names apply to a one-stage plant; "
                                 f"this one has {len(stages)} stages (give shafts= and stages=)", field=min(pair))
            sh = [dataclasses.asdict(s) for s in shafts] or [{}, {}]
            for name, (j, attr) in _PAIR_SHAFT.items():
                if name in pair:
                    sh[j][attr] = pair[name]
            st = {f.name: getattr(stages[0], f.name) for f in dataclasses.fields(Stage)} if stages else {}
            st.update({name: pair[name] for name in _PAIR_STAGE if name in pair})
            shafts = [Shaft(**kw) for kw in sh]
            stages = [Stage(**st)]
        if not stages or len(shafts) != len(stages) + 1:
            raise InputError(f"a plant needs n >= 1 stages and n + 1 shafts, got {len(stages)} stages and "
                             f"{len(shafts)} shafts", field="stages")
        if len(stages) > MAX_STAGES:
            raise InputError(f"stages = {len(stages)} is out of range: expected at most {MAX_STAGES} stages",
                             field="stages")
        try:
            kind = PlantKind(kind)
        except ValueError:
            raise InputError(f"kind = {kind!r} is not a plant kind: expected one of "
                             f"{', '.join(p.value for p in PlantKind)}", field="kind") from None
        for name, value, cls in (("contact_law", contact_law, ContactLaw), ("friction_law", friction_law,
                                                                            FrictionLaw)):
            try:
                cls(value)
            except ValueError:
                raise InputError(f"{name} = {value!r} is not allowed: expected one of "
                                 f"{', '.join(repr(c.value) for c in cls)}", field=name) from None
        object.__setattr__(self, "kind", kind)
        object.__setattr__(self, "shafts", tuple(shafts))
        object.__setattr__(self, "stages", tuple(stages))
        object.__setattr__(self, "contact_law", ContactLaw(contact_law))
        object.__setattr__(self, "friction_law", FrictionLaw(friction_law))
        object.__setattr__(self, "coulomb_velocity", COULOMB_VELOCITY.check("coulomb_velocity", coulomb_velocity))
        object.__setattr__(self, "torque_limit", TORQUE_LIMIT.check("torque_limit", torque_limit))
        object.__setattr__(self, "load_torque", LOAD_TORQUE.check("load_torque", load_torque))

    def __repr__(self) -> str:
        return (f"Plant(kind={self.kind.value!r}, {self.n_stages} stage(s), J={[s.J for s in self.shafts]}, "
                f"b={list(self.backlashes)}, k={[s.k for s in self.stages]})")

    # -- sizes and the pair's names
    @property
    def n_stages(self) -> int:
        """Number of stages (meshes) n."""
        return len(self.stages)

    @property
    def nx(self) -> int:
        """Number of states, ``2 (n + 1)``."""
        return 2 * len(self.shafts)

    def _one_stage(self, name: str) -> None:
        if len(self.stages) != 1:
            raise AttributeError(f"{name!r} is a pair's attribute; this plant has {len(self.stages)} stages: use "
                                 f"plant.stages[i] or plant.shafts[j]")

    J1 = _pair_attr("J1")
    J2 = _pair_attr("J2")
    d1 = _pair_attr("d1")
    d2 = _pair_attr("d2")
    tc1 = _pair_attr("tc1")
    tc2 = _pair_attr("tc2")
    rb1 = _pair_attr("rb1")
    rb2 = _pair_attr("rb2")
    backlash = _pair_attr("backlash")
    k = _pair_attr("k")
    c = _pair_attr("c")
    mesh_period = _pair_attr("mesh_period")
    mesh_phase = _pair_attr("mesh_phase")
    kv_table = _pair_attr("kv_table")

    # -- derived figures
    @property
    def backlashes(self) -> tuple[float, ...]:
        """Backlash of every stage [m]."""
        return tuple(s.backlash for s in self.stages)

    @property
    def gear_ratio(self) -> float:
        """Overall kinematic ratio, motor angle over load angle, ``prod r_b2 / r_b1``."""
        return math.prod(s.ratio for s in self.stages)

    def ratio_after(self, i: int) -> float:
        """Ratio of the stages after stage ``i`` (1 for the last): a gear-shaft angle over the load's.

        Parameters
        ----------
        i : int
            Stage index, 0 for the motor's stage (from 0 to ``n - 1``).

        Raises
        ------
        InputError
            If ``i`` is not a stage index (a negative one read the stages from the end).
        """
        i = self._stage_index(i, "i")
        return math.prod(s.ratio for s in self.stages[i + 1:])

    def _stage_index(self, i: Any, field: str) -> int:
        """``i`` as a stage index 0..n-1, else :class:`InputError` naming ``field`` (a negative index would read
        the stages from the end and pair the last stage with the motor shaft)."""
        if not (isinstance(i, int | np.integer) and not isinstance(i, bool) and 0 <= i < self.n_stages):
            raise InputError(f"{field} = {i!r} is out of range: expected a stage index from 0 to "
                             f"{self.n_stages - 1}", field=field)
        return int(i)

    def _states(self, x: Any, field: str = "x") -> NDArray[np.float64]:
        """``x`` as an array of states, shape ``(nx, ...)``, else :class:`InputError` naming ``field``."""
        try:
            a = np.asarray(x, dtype=float)
        except (TypeError, ValueError):
            a = None
        if a is None or a.ndim == 0 or a.shape[0] != self.nx:
            shape = "not numbers" if a is None else f"shape {a.shape}"
            raise InputError(f"{field} has {shape}: expected states of shape ({self.nx}, ...), the "
                             f"{len(self.shafts)} shaft angles [rad], then their velocities [rad/s]", field=field)
        return a

    @property
    def stage_lost_motions(self) -> tuple[float, ...]:
        """Each stage's lost motion at the load shaft, ``2 b_i / (r_b2,i prod_(j > i) N_j)`` [rad]."""
        return tuple(2 * s.backlash / (s.rb2 * self.ratio_after(i)) for i, s in enumerate(self.stages))

    @property
    def lost_motion(self) -> float:
        """Lost motion at the load shaft, the sum of :attr:`stage_lost_motions` [rad]."""
        return sum(self.stage_lost_motions)

    def stage_m_eq(self, i: int) -> float:
        """Equivalent mass of stage ``i``'s mesh mode between its two shafts [kg].

        Parameters
        ----------
        i : int
            Stage index, 0 for the motor's stage; the stage couples shafts ``i`` and ``i + 1``.

        Raises
        ------
        InputError
            If ``i`` is not a stage index.
        """
        i = self._stage_index(i, "i")
        s = self.stages[i]
        return equivalent_mass(self.shafts[i].J, self.shafts[i + 1].J, s.rb1, s.rb2)

    @property
    def m_eq(self) -> float:
        """Equivalent mass of the mesh mode along the line of action [kg] (a pair)."""
        self._one_stage("m_eq")
        return self.stage_m_eq(0)

    @property
    def natural_frequency(self) -> float:
        """Fastest stage mesh mode, ``max_i sqrt(k_i / m_eq,i)`` [rad/s] (a pair: its mesh mode)."""
        return max(math.sqrt(s.k / self.stage_m_eq(i)) for i, s in enumerate(self.stages))

    @property
    def equivalent_stiffness(self) -> float:
        """Torsional stiffness of the train in contact, seen at the load shaft [N m/rad] (stages in series)."""
        return 1.0 / sum(1.0 / (s.k * s.rb2**2 * self.ratio_after(i) ** 2) for i, s in enumerate(self.stages))

    @property
    def has_coulomb(self) -> bool:
        """Whether any shaft has Coulomb friction."""
        return any(s.tc > 0 for s in self.shafts)

    @property
    def is_piecewise_linear(self) -> bool:
        """Whether the dynamics are affine inside each pattern (the exact solver applies)."""
        return self.kind is PlantKind.IMPROVED and not (self.has_coulomb and self.friction_law is FrictionLaw.SMOOTH)

    def with_backlash(self, backlash: float | Sequence[float]) -> Plant:
        """Copy with another backlash [m]: one value for every stage, or one per stage.

        Parameters
        ----------
        backlash : float or sequence of float
            Half-gap ``b`` along each stage's line of action [m]: one value for every stage, or one per stage.

        Raises
        ------
        InputError
            Naming ``backlash``: a count other than 1 or one per stage, or a value out of its range.
        """
        bs = per_stage_backlash(backlash, self.n_stages)
        return dataclasses.replace(self, stages=tuple(dataclasses.replace(s, backlash=b)
                                                      for s, b in zip(self.stages, bs, strict=True)))

    def stiffness_at(self, theta: Any, stage: int = 0, flank: Any = 1) -> Any:
        """Mesh stiffness of ``stage`` at pinion angle ``theta`` [N/m]: ``k`` except for ``tvms``.

        Symmetric teeth make the back flank the mirror image of the front: it sees at ``theta`` what the front
        sees at ``-theta``.

        Parameters
        ----------
        theta : float or array_like
            Angle of the stage's pinion shaft [rad] (the state ``x[stage]``).
        stage : int
            Stage index, 0 for the motor's stage.
        flank : int or array_like
            The contact's side, broadcast with ``theta``: negative for the back flank, anything else (1, or 0 in
            the gap) for the front.

        Raises
        ------
        InputError
            If ``stage`` is not a stage index.
        """
        s = self.stages[self._stage_index(stage, "stage")]
        if s.kv_table is None:
            return s.k + 0.0 * np.asarray(theta)
        n = s.kv_table.size
        side = np.where(np.asarray(flank) < 0, -1.0, 1.0)
        pos = np.mod(s.mesh_phase + side * np.asarray(theta, dtype=float), s.mesh_period) / s.mesh_period * n
        i = np.floor(pos).astype(int) % n
        frac = pos - np.floor(pos)
        return s.kv_table[i] * (1 - frac) + s.kv_table[(i + 1) % n] * frac

    def gaps(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """``s_i`` of every stage [m], shape ``(n, ...)`` for states ``x`` of shape ``(nx, ...)``.

        Parameters
        ----------
        x : array_like
            States, shape ``(nx, ...)``: the ``n + 1`` shaft angles [rad], then their velocities [rad/s].

        Raises
        ------
        InputError
            If ``x`` is not numbers of shape ``(nx, ...)``.
        """
        x = self._states(x)
        return np.stack([s.rb1 * x[i] - s.rb2 * x[i + 1] for i, s in enumerate(self.stages)])

    def gap_rates(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """``s_i'`` of every stage [m/s], shape ``(n, ...)``.

        Parameters
        ----------
        x : array_like
            States, shape ``(nx, ...)``: the ``n + 1`` shaft angles [rad], then their velocities [rad/s].

        Raises
        ------
        InputError
            If ``x`` is not numbers of shape ``(nx, ...)``.
        """
        x = self._states(x)
        w = len(self.shafts)
        return np.stack([s.rb1 * x[w + i] - s.rb2 * x[w + i + 1] for i, s in enumerate(self.stages)])

    def relative_displacement(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """``s = r_b1 theta1 - r_b2 theta2`` [m]; for a train, every stage's (shape ``(n, ...)``).

        Parameters
        ----------
        x : array_like
            States, shape ``(nx, ...)``: the ``n + 1`` shaft angles [rad], then their velocities [rad/s].

        Raises
        ------
        InputError
            If ``x`` is not numbers of shape ``(nx, ...)``.
        """
        g = self.gaps(x)
        return g[0] if self.n_stages == 1 else g

    def mode_of(self, s: Any) -> Any:
        """Contact mode(s) for relative displacement(s) ``s`` (as :class:`Mode` values; one row per stage).

        Parameters
        ----------
        s : float or array_like
            Relative displacement(s) along the line of action [m]: for a train, one row per stage
            (:meth:`relative_displacement`).

        Raises
        ------
        InputError
            For a train, if ``s`` has not one row per stage.
        """
        s = np.asarray(s)
        if self.n_stages > 1 and (s.ndim == 0 or s.shape[0] != self.n_stages):
            raise InputError(f"s has shape {s.shape}: expected one row per stage ({self.n_stages}, ...), as "
                             "relative_displacement(x) gives it", field="s")
        b = np.array(self.backlashes).reshape((-1,) + (1,) * (s.ndim - 1)) if self.n_stages > 1 else self.backlash
        return np.where(s > b, 1, np.where(s < -b, -1, 0))

    def energy(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Kinetic plus mesh-spring energy [J], ``sum J_j omega_j^2 / 2 + sum k_i delta_i^2 / 2``.

        ``k_i`` is the stage's stiffness where its pinion stands (:meth:`stiffness_at`: the mean ``k`` but on the
        ``tvms`` plant; Yang–Sun's ``k`` of eq 39). Conserved without damping and friction on the improved plant.
        The ``tvms`` plant's force ``K(theta) delta`` has no potential (the mesh's elastic torque on the pinion,
        ``-K'(theta) delta^2 / 2``, is left out, as in the parametric mesh models of the literature): its energy
        changes by the work of the stiffness variation, ``integral of delta^2 dK / 2`` (:meth:`stiffness_work`).

        Parameters
        ----------
        x : array_like
            States, shape ``(nx, ...)``: the ``n + 1`` shaft angles [rad], then their velocities [rad/s].

        Raises
        ------
        InputError
            If ``x`` is not numbers of shape ``(nx, ...)``.
        """
        x = self._states(x)
        w = len(self.shafts)
        E = sum(0.5 * sh.J * x[w + j] ** 2 for j, sh in enumerate(self.shafts))
        for i, st in enumerate(self.stages):
            s = st.rb1 * x[i] - st.rb2 * x[i + 1]
            pen = np.maximum(np.abs(s) - st.backlash, 0.0)
            E = E + 0.5 * self.stiffness_at(x[i], i, np.sign(s)) * pen * pen
        return E

    def stiffness_work(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The energy the ``tvms`` plant's stiffness variation puts in along a trajectory, from its first state [J].

        ``W(t) = sum_i integral of delta_i^2 dK_i / 2`` (trapezoids between the states ``x[:, j]``, so as exact as
        they are dense): without damping and friction ``energy(x) - energy(x[:, 0]) = W``. Zeros on a plant whose
        stiffness does not vary.

        Parameters
        ----------
        x : array_like
            A trajectory, shape ``(nx, m)``: states in time order, one per column (angles [rad], then
            velocities [rad/s]).

        Raises
        ------
        InputError
            If ``x`` is not numbers of shape ``(nx, m)``.
        """
        x = self._states(x)
        if x.ndim != 2:
            raise InputError(f"x has shape {x.shape}: expected a trajectory of shape ({self.nx}, m), one state "
                             "per column", field="x")
        W = np.zeros(x.shape[1])
        for i, st in enumerate(self.stages):
            if st.kv_table is None:
                continue
            s = st.rb1 * x[i] - st.rb2 * x[i + 1]
            pen2 = np.maximum(np.abs(s) - st.backlash, 0.0) ** 2
            K = self.stiffness_at(x[i], i, np.sign(s))
            W[1:] += np.cumsum(0.25 * (pen2[1:] + pen2[:-1]) * np.diff(K))
        return W

    def equivalent_pair(self) -> Plant:
        """The one-gap pair a controller designs on: the plant itself for a pair.

        For a train: the load shaft as gear 2, everything upstream reflected to the motor shaft as gear 1
        (inertia ``J_0 + sum_j J_j / N_(0->j)^2``, friction likewise), one gap of the train's whole lost
        motion at the output and the stages' series stiffness, on the last stage's line of action
        (``r_b2`` of the last stage, ``r_b1 = r_b2 / N``).

        Notes
        -----
        Lumping the gaps is exact for the kinematics of the lost motion (the motor turns
        ``N sum(...)`` through all of it before the load moves) and for the rigid train; it misses the
        order in which the stages' gaps close and the intermediate shafts' own motion in the gaps, which
        the controllers' models neglect anyway (intermediate gears are light).
        """
        if self.n_stages == 1:
            return self
        N = self.gear_ratio
        last = self.stages[-1]
        rb2 = last.rb2
        rb1 = rb2 / N
        ratio_to = [math.prod(s.ratio for s in self.stages[:j]) for j in range(len(self.shafts))]
        up = range(len(self.shafts) - 1)
        J1 = sum(self.shafts[j].J / ratio_to[j] ** 2 for j in up)
        d1 = sum(self.shafts[j].d / ratio_to[j] ** 2 for j in up)
        tc1 = sum(self.shafts[j].tc / ratio_to[j] for j in up)
        b = 0.5 * self.lost_motion * rb2
        k = self.equivalent_stiffness / rb2**2
        zeta = np.mean([s.c / (2 * math.sqrt(s.k * self.stage_m_eq(i))) for i, s in enumerate(self.stages)])
        load = self.shafts[-1]
        m_eq = equivalent_mass(J1, load.J, rb1, rb2)
        return Plant(kind=PlantKind.IMPROVED, shafts=(Shaft(J=J1, d=d1, tc=tc1), load),
                     stages=(Stage(rb1=rb1, rb2=rb2, backlash=b, k=k, c=2 * float(zeta) * math.sqrt(k * m_eq)),),
                     contact_law=self.contact_law, friction_law=self.friction_law,
                     coulomb_velocity=self.coulomb_velocity, torque_limit=self.torque_limit,
                     load_torque=self.load_torque)


def check_plant(plant: Any, *, field: str = "plant") -> Plant:
    """``plant`` itself if it is a :class:`Plant`; else an :class:`~gearctl.errors.InputError` naming ``field``.

    A gear model (from :func:`~gearctl.catalog.load_model`) or its name is the usual slip: the message says to
    build the plant first.

    Parameters
    ----------
    plant : object
        What a caller passed as the plant.
    field : str
        The name the message gives it (default ``"plant"``).

    Returns
    -------
    Plant
        ``plant`` itself.

    Raises
    ------
    InputError
        If ``plant`` is not a :class:`Plant`.
    """
    if isinstance(plant, Plant):
        return plant
    if hasattr(plant, "servo") and hasattr(plant, "stages"):
        hint = ": build it first, gearctl.build_plant(model)"
    elif isinstance(plant, str | os.PathLike):
        hint = f": build it first, gearctl.build_plant(gearctl.load_model({str(plant)!r}))"
    else:
        hint = ": expected a gearctl.build_plant(model)"
    raise InputError(f"{field} = {short_repr(plant)} is not a Plant{hint}", field=field)


def signal_names(plant: Plant) -> tuple[list[str], list[str]]:
    """State and input names: the report's for a pair, ``theta0..thetan``, ``xi0, xin`` for a train.

    Parameters
    ----------
    plant : Plant
        A pair or a train.

    Returns
    -------
    states : list of str
        :data:`STATES` for a pair; ``theta0..theta<n>`` then ``omega0..omega<n>`` for a train.
    inputs : list of str
        :data:`INPUTS` for a pair; ``xi0`` and ``xi<n>`` for a train.
    """
    if plant.n_stages == 1:
        return list(STATES), list(INPUTS)
    w = len(plant.shafts)
    return [f"theta{j}" for j in range(w)] + [f"omega{j}" for j in range(w)], ["xi0", f"xi{w - 1}"]


# --- the dynamics, once -----------------------------------------------------------------------------------


def force_coefficients(plant: Plant, i: int, sigma: int) -> tuple[NDArray[np.float64], float]:
    """The improved law's force of stage ``i`` on flank ``sigma`` as ``F = fc . x + f0`` [N].

    ``F = k (s - sigma b) + c s'`` (eqs 3 and 10, signed as the front flank's force), linear in the state.

    Parameters
    ----------
    plant : Plant
        A pair or a train.
    i : int
        Stage index, 0 at the motor.
    sigma : int
        Flank: +1 front, -1 back (0: the force of ``k s + c s'`` alone).

    Returns
    -------
    fc : ndarray, shape (nx,)
        Coefficients on the state [N/rad, N s/rad].
    f0 : float
        Constant part ``-sigma k b`` [N].
    """
    st = plant.stages[i]
    w = len(plant.shafts)
    fc = np.zeros(2 * w)
    fc[i], fc[i + 1] = st.k * st.rb1, -st.k * st.rb2
    fc[w + i], fc[w + i + 1] = st.c * st.rb1, -st.c * st.rb2
    return fc, -sigma * st.k * st.backlash


def mode_matrices(plant: Plant, loaded: Sequence[bool], stuck: Sequence[bool] | None = None) -> NDArray[np.float64]:
    """``A`` of ``x' = A x + B u + e`` with the stages ``loaded`` in contact and the shafts ``stuck``.

    Front and back contact share ``A`` (they differ only in ``e``, see :func:`affine_terms`); a stuck
    shaft (stick-slip friction holding it) has ``omega' = 0``. Eqs 1-2, 6-9 of the report per stage,
    with the viscous friction of each shaft.

    Parameters
    ----------
    plant : Plant
        A pair or a train.
    loaded : sequence of bool
        Per stage: in contact (front or back).
    stuck : sequence of bool, optional
        Per shaft: held by static friction (default: none).

    Returns
    -------
    ndarray, shape (nx, nx)
        ``A``: the rows ``theta' = omega``, then each shaft's ``omega'`` (entries [1/s^2] on the angles, [1/s] on
        the speeds).
    """
    w = len(plant.shafts)
    A = np.zeros((2 * w, 2 * w))
    A[:w, w:] = np.eye(w)
    for j, sh in enumerate(plant.shafts):
        A[w + j, w + j] = -sh.d / sh.J
    for i, st in enumerate(plant.stages):
        if not loaded[i]:
            continue
        k, c, r1, r2 = st.k, st.c, st.rb1, st.rb2
        J1, J2 = plant.shafts[i].J, plant.shafts[i + 1].J
        cols = [i, i + 1, w + i, w + i + 1]
        A[w + i, cols] += np.array([-k * r1**2, k * r1 * r2, -c * r1**2, c * r1 * r2]) / J1
        A[w + i + 1, cols] += np.array([k * r1 * r2, -k * r2**2, c * r1 * r2, -c * r2**2]) / J2
    for j, flag in enumerate(stuck or ()):
        if flag:
            A[w + j] = 0.0
    return A


def input_matrix(plant: Plant) -> NDArray[np.float64]:
    """``B``: motor torque on shaft 0, load torque on the last shaft.

    Parameters
    ----------
    plant : Plant
        A pair or a train.

    Returns
    -------
    ndarray, shape (nx, 2)
        ``1 / J`` of the first and the last shaft in their ``omega'`` rows [1/(kg m^2)].
    """
    w = len(plant.shafts)
    B = np.zeros((2 * w, 2))
    B[w, 0] = 1 / plant.shafts[0].J
    B[2 * w - 1, 1] = 1 / plant.shafts[-1].J
    return B


def affine_terms(plant: Plant) -> NDArray[np.float64]:
    """The constant part of each loaded stage's force on its two shafts' accelerations.

    Returns an array ``(n, 2, 2)``: ``[i, sigma > 0]`` holds the terms added to ``omega_i'`` and
    ``omega_(i+1)'`` by stage ``i`` in contact on flank ``sigma`` (``F``'s ``-sigma k b``, eqs 3 and 10),
    [rad/s^2].

    Parameters
    ----------
    plant : Plant
        A pair or a train.
    """
    out = np.zeros((plant.n_stages, 2, 2))
    for i, st in enumerate(plant.stages):
        J1, J2 = plant.shafts[i].J, plant.shafts[i + 1].J
        for sigma in (-1, 1):
            # written as the kernel always has: rb1 k sigma b / J1, and minus rb2 k sigma b / J2
            out[i, int(sigma > 0)] = (st.rb1 * st.k * sigma * st.backlash / J1,
                                      -(st.rb2 * st.k * sigma * st.backlash / J2))
    return out


#: event-function types in :func:`event_table`
EVENT_GEOMETRIC, EVENT_FORCE = 0, 1


def event_table(plant: Plant) -> dict[str, NDArray[Any]]:
    """The boundaries of every stage's modes as linear functions ``g = cg . x + g0 > 0`` inside the mode.

    Parameters
    ----------
    plant : Plant
        A pair or a train.

    Returns
    -------
    dict
        Arrays over ``slot = 5 i + (mode + 2)`` (modes -2 .. 2, see :mod:`gearctl.kernel`) with up to two
        functions each, ``row = 2 slot + e``: ``count`` (per slot), ``cg`` (rows x nx), ``g0``,
        ``target`` (the mode entered), ``type`` (0: ``|s| = b``, 1: the no_pull law's zero force) and
        ``ssign`` (``g = ssign s + g0`` for type 0).
    """
    n, w = plant.n_stages, len(plant.shafts)
    nx = 2 * w
    count = np.zeros(5 * n, dtype=np.int64)
    cg = np.zeros((10 * n, nx))
    g0 = np.zeros(10 * n)
    target = np.zeros(10 * n, dtype=np.intc)
    typ = np.zeros(10 * n, dtype=np.intc)
    ssign = np.zeros(10 * n)
    no_pull = plant.contact_law is ContactLaw.NO_PULL
    for i, st in enumerate(plant.stages):
        sv = np.zeros(nx)
        vv = np.zeros(nx)
        sv[i], sv[i + 1] = st.rb1, -st.rb2
        vv[w + i], vv[w + i + 1] = st.rb1, -st.rb2
        kk, cc, b = st.k, st.c, st.backlash
        for mode in (-2, -1, 0, 1, 2):
            slot = 5 * i + mode + 2
            rows: list[tuple[NDArray[np.float64], float, int, int, float]] = []
            if mode == 0:  # separation: b - s > 0 (front next), s + b > 0 (back next)
                rows = [(-sv, b, 1, EVENT_GEOMETRIC, -1.0), (sv.copy(), b, -1, EVENT_GEOMETRIC, 1.0)]
            elif mode > 0:  # front: s - b > 0; loaded F > 0 / unloaded -F > 0
                rows = [(sv.copy(), -b, 0, EVENT_GEOMETRIC, 1.0)]
                if no_pull:
                    sg = 1.0 if mode == 1 else -1.0
                    rows.append((sg * (kk * sv + cc * vv), -sg * kk * b, 2 if mode == 1 else 1, EVENT_FORCE, 0.0))
            else:  # back: -s - b > 0; loaded F_B = k(-s-b) - c v > 0
                rows = [(-sv, -b, 0, EVENT_GEOMETRIC, -1.0)]
                if no_pull:
                    sg = 1.0 if mode == -1 else -1.0
                    rows.append((-sg * (kk * sv + cc * vv), -sg * kk * b, -2 if mode == -1 else -1, EVENT_FORCE,
                                 0.0))
            count[slot] = len(rows)
            for e, (c_, g, t, ty, ss) in enumerate(rows):
                cg[2 * slot + e], g0[2 * slot + e] = c_, g
                target[2 * slot + e], typ[2 * slot + e], ssign[2 * slot + e] = t, ty, ss
    return {"count": count, "cg": cg, "g0": g0, "target": target, "type": typ, "ssign": ssign}


def mesh_force(plant: Plant, x: NDArray[np.float64], modes: NDArray[np.int_],
               d_ys: ArrayLike = 0.0) -> NDArray[np.float64]:
    """Contact force of every stage along its line of action [N], signed as the front flank's.

    Parameters
    ----------
    plant : Plant
    x : ndarray, shape (nx, ...)
        States.
    modes : ndarray, shape (n, ...)
        Modes per stage (the sign is what counts: 0 in the gap).
    d_ys : float or ndarray, shape (n, ...)
        Yang–Sun damping factor of each stage's current contact [N s/m^2].

    Returns
    -------
    ndarray, shape (n, ...)
        Zero in separation; the report's law (eqs 3, 10), its no-pull clamp, or Yang–Sun's
        ``(d x' + k) x``. The C kernel's ``force()`` is the same law (a test checks that they agree).
    """
    x = np.asarray(x, dtype=float)
    modes = np.asarray(modes)
    d_ys = np.broadcast_to(np.asarray(d_ys, dtype=float), (plant.n_stages, *x.shape[1:]))
    s, v = plant.gaps(x), plant.gap_rates(x)
    out = np.empty_like(s)
    for i, st in enumerate(plant.stages):
        sigma = np.sign(modes[i]).astype(float)
        delta = sigma * s[i] - st.backlash
        ddelta = sigma * v[i]
        if plant.kind is PlantKind.YANG_SUN:
            F = (d_ys[i] * ddelta + st.k) * delta
        else:
            F = plant.stiffness_at(x[i], i, sigma) * delta + st.c * ddelta
        if plant.contact_law is ContactLaw.NO_PULL:
            F = np.maximum(F, 0.0)
        out[i] = np.where(sigma != 0, sigma * F, 0.0)
    return out


# --- building a plant from a model --------------------------------------------------------------------------


def build_plant(
    model: GearModel,
    kind: PlantKind | str = PlantKind.IMPROVED,
    *,
    backlash: float | Sequence[float] | None = None,
    table_points: int = 4096,
) -> Plant:
    """Build the plant of a gear model (a pair or a train).

    Parameters
    ----------
    model : GearModel
        Catalog entry (stages, servo).
    kind : PlantKind or str
        ``"improved"``, ``"yang-sun"`` or ``"tvms"``.
    backlash : float or sequence of float, optional
        Replaces the model's backlash [m]: one value for every stage or one per stage (0: backlash-free).
    table_points : int
        Samples of ``K`` over one mesh cycle for ``tvms``, read by linear interpolation: each jump of ``K``
        (a tooth pair entering or leaving) is smeared over one sample. With 512 a contact of the report's load
        case ended 5 % off in speed (one impact more in 20 ms); from 1024 the run agrees with an exact-``K``
        integration within 2e-6 b (4096 by default: no slower).

    Returns
    -------
    Plant

    Raises
    ------
    InputError
        For an unknown ``kind``, a ``model`` that is not a gear model, or a ``backlash`` of the wrong count,
        out of range (0, or 1e-9 up to 0.01 m) or above the file's bound on the stage
        (``MAX_BACKLASH_PER_MODULE`` x module).

    Notes
    -----
    Each stage uses ``mesh_stiffness`` from its dynamics if given, else the mean of eq 21 over the mesh
    cycle; ``c`` is the given ``damping_coefficient``, else ``2 zeta sqrt(k m_eq)`` (eq 38, consistent
    form) with ``m_eq`` of the *total* inertias of the stage's two shafts: the damping ratio is the modal
    damping of the mesh mode, and with rigid shafts (the report's assumption) a motor rotor or a load on a
    shaft moves with its gear and belongs to that mode. For the bare pair this is the report's ``m_eq``;
    for ``shing1993_servo`` it keeps the mesh mode at ``zeta = 0.05`` (with the gear inertias alone it
    would drop to 0.017 and every impact would be nearly elastic).
    A shaft's inertia is the sum of its gears' (a train's intermediate shaft carries one stage's gear
    and the next stage's pinion), the motor's or the load's and any ``intermediate_inertia``.
    The time-varying plant uses ``K(vartheta)`` scaled so that its mean equals the stage's ``k`` (so an
    override of ``k`` carries over), with the same ``c``.
    """
    try:
        kind = PlantKind(kind)
    except ValueError:
        raise InputError(
            f"kind = {kind!r} is not a plant kind: expected one of {', '.join(p.value for p in PlantKind)}",
            field="kind",
        ) from None
    if not (hasattr(model, "servo") and hasattr(model, "stages")):
        hint = f": load it first, gearctl.load_model({str(model)!r})" if isinstance(model, str | os.PathLike) else ""
        raise InputError(f"model = {model!r} is not a gear model{hint}", field="model")
    servo = model.servo
    n = len(model.stages)
    geos = [pair_geometry(sm.pair) for sm in model.stages]
    inter = servo.intermediate_inertia or (0.0,) * (n - 1)
    J = [geos[0].inertia[0] + servo.motor_inertia]
    for j in range(1, n):
        J.append(geos[j - 1].inertia[1] + geos[j].inertia[0] + inter[j - 1])
    J.append(geos[-1].inertia[1] + servo.load_inertia)
    d = [servo.viscous_friction1, *(servo.intermediate_viscous_friction or (0.0,) * (n - 1)), servo.viscous_friction2]
    tc = [servo.coulomb_friction1, *(servo.intermediate_coulomb_friction or (0.0,) * (n - 1)),
          servo.coulomb_friction2]
    if backlash is not None:
        bs = per_stage_backlash(backlash, n)
        for i, (b, sm) in enumerate(zip(bs, model.stages, strict=True)):  # the file's bound on a stage's backlash
            top = MAX_BACKLASH_PER_MODULE * sm.pair.module
            if b > top:
                where = f" on stage {i + 1}" if n > 1 else ""
                raise InputError(f"backlash = {b!r} is out of range{where}: expected at most "
                                 f"{MAX_BACKLASH_PER_MODULE:g} x module = {top:g} [m]", field="backlash")
    else:
        bs = tuple(sm.pair.backlash for sm in model.stages)
    stages = []
    for i, (sm, geo) in enumerate(zip(model.stages, geos, strict=True)):
        pair, dyn = sm.pair, sm.dynamics
        rb1, rb2 = geo.base_radius
        ms = None
        if dyn.mesh_stiffness is not None:
            k = dyn.mesh_stiffness
        else:
            ms = mesh_stiffness(pair, points=table_points)
            k = ms.mean
        c = dyn.damping_coefficient
        if c is None:
            c = damping_coefficient(k, dyn.damping_ratio, equivalent_mass(J[i], J[i + 1], rb1, rb2))
        kv = None
        if kind is PlantKind.YANG_SUN:
            k = yang_sun_stiffness(pair)
        elif kind is PlantKind.TVMS:
            th = np.linspace(0.0, geo.mesh_period_angle, table_points, endpoint=False)
            Kth = mesh_stiffness_at(pair, th, geo)
            mean = ms.mean if ms is not None else mesh_stiffness(pair).mean
            kv = Kth * (k / mean)
        # the neutral position's front contact, from A: half the base thickness plus r_b1 alpha_w (Stage.mesh_phase)
        neutral = geo.tooth_thickness_base[0] / 2 + rb1 * geo.operating_pressure_angle
        stages.append(Stage(rb1=rb1, rb2=rb2, backlash=float(bs[i]), k=k, c=c, mesh_period=geo.mesh_period_angle,
                            mesh_phase=math.fmod((neutral - geo.AC) / rb1, geo.mesh_period_angle), kv_table=kv))
    return Plant(
        kind=kind,
        shafts=tuple(Shaft(J=J[j], d=d[j], tc=tc[j]) for j in range(n + 1)),
        stages=tuple(stages),
        contact_law=model.stages[0].dynamics.contact_law,
        friction_law=servo.friction_law,
        coulomb_velocity=servo.coulomb_velocity,
        torque_limit=servo.torque_limit,
        load_torque=servo.load_torque,
    )


def plant_nlsys(plant: Plant, *, name: str | None = None) -> Any:
    """The plant as a python-control ``nlsys`` with named states, inputs and outputs.

    Parameters
    ----------
    plant : Plant
        The plant (a pair or a train).
    name : str, optional
        System name (default ``"gear_<kind>"``).

    Returns
    -------
    control.NonlinearIOSystem
        States as :func:`signal_names` (plus ``v_impact`` per stage for Yang–Sun: ``v_impact`` for a pair,
        ``v_impact1..n`` for a train); inputs motor and load torque [N m]; outputs the states, then ``s``
        and ``force`` (``s1..sn``, ``force1..forcen`` for a train). The update function has
        python-control's ``(t, x, u, params)`` signature; ``params`` may override ``backlash``, ``k`` and
        ``c`` of a pair, whose values the system declares (``sys.params``, python-control's defaults). The
        servo's ``load_torque`` is added to the load torque input.

    Raises
    ------
    InputError
        If ``plant`` is not a :class:`Plant` (a gear model: build it first with :func:`build_plant`), or ``name``
        is not a string (or None). When it is evaluated: a ``params`` value out of its range (named), or
        ``backlash``, ``k`` or ``c`` given for a train (named ``params``).

    Notes
    -----
    This is for interconnection with the user's own blocks; it has no event location, so
    ``input_output_response`` steps across the contact switches at whatever accuracy its tolerances
    give. gearctl's own :func:`~gearctl.simulate.simulate` is the exact, fast path. Coulomb friction is
    the smooth law here (a continuous-time system cannot stick).

    Yang–Sun's damping factor is fixed at each contact onset from the impact speed; a continuous-time
    system cannot hold a sample, so the Yang–Sun ``nlsys`` carries a state ``v_impact`` per stage that
    follows ``|s'|`` with a 1 µs time constant while the flanks are apart and is frozen in contact.
    """
    import control as ct

    p = check_plant(plant)
    if name is not None and not isinstance(name, str):
        raise InputError(f"name = {short_repr(name)} is not a system name: expected a string (or None)", field="name")
    n, w = p.n_stages, len(p.shafts)
    ys = p.kind is PlantKind.YANG_SUN
    # a pair's parameters with their values: python-control's declared defaults (sys.params)
    declared = {"backlash": p.stages[0].backlash, "k": p.stages[0].k, "c": p.stages[0].c} if n == 1 else {}
    states, inputs = signal_names(p)
    suffix = [""] if n == 1 else [str(i + 1) for i in range(n)]
    if ys:
        states = states + [f"v_impact{sfx}" for sfx in suffix]

    def with_params(params: dict[str, Any]) -> Plant:
        if n > 1 and any(k in params for k in ("backlash", "k", "c")):
            raise InputError(f"params = {short_repr(params)}: backlash, k and c may be overridden on a pair only; "
                             "this plant is a train (change its stages instead)", field="params")
        over = {k: params[k] for k in ("backlash", "k", "c") if k in params and params[k] is not declared[k]}
        return dataclasses.replace(p, **over) if over else p

    def forces(q: Plant, x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.int_]]:
        s = q.gaps(x[:2 * w])
        modes = np.array([1 if s[i] > st.backlash else (-1 if s[i] < -st.backlash else 0)
                          for i, st in enumerate(q.stages)])
        d_ys = [yang_sun_damping_factor(st.k, x[2 * w + i]) for i, st in enumerate(q.stages)] if ys else 0.0
        return mesh_force(q, x[:2 * w], modes, d_ys), modes

    def updfcn(t: float, x: NDArray[np.float64], u: NDArray[np.float64], params: dict[str, Any]) -> Any:
        q = with_params(params)
        F, modes = forces(q, x)
        dx = np.zeros_like(x)
        dx[:w] = x[w:2 * w]
        T = np.zeros(w)
        T[0] += u[0]
        T[-1] += u[1] + q.load_torque
        for i, st in enumerate(q.stages):
            T[i] -= st.rb1 * F[i]
            T[i + 1] += st.rb2 * F[i]
        for j, sh in enumerate(q.shafts):
            fr = sh.d * x[w + j] + (sh.tc * math.tanh(x[w + j] / q.coulomb_velocity) if sh.tc else 0.0)
            dx[w + j] = (T[j] - fr) / sh.J
        if ys:
            v = np.abs(q.gap_rates(x[:2 * w]))
            for i in range(n):
                dx[2 * w + i] = 0.0 if modes[i] else (v[i] - x[2 * w + i]) / 1e-6
        return dx

    def outfcn(t: float, x: NDArray[np.float64], u: NDArray[np.float64], params: dict[str, Any]) -> Any:
        q = with_params(params)
        F, _ = forces(q, x)
        return np.concatenate([x[:2 * w], q.gaps(x[:2 * w]), F])

    outputs = signal_names(p)[0] + [f"s{sfx}" for sfx in suffix] + [f"force{sfx}" for sfx in suffix]
    return ct.nlsys(updfcn, outfcn, states=states, inputs=inputs, outputs=outputs, params=declared,
                    name=name or f"gear_{p.kind.value.replace('-', '_')}")
