"""The gear-pair plants: improved (report section 2), Yang–Sun (section 4) and time-varying stiffness.

:func:`build_plant` turns a :class:`~gearctl.catalog.GearModel` into a :class:`Plant`: the numbers the
simulator and the linear models need (inertias on each shaft, base radii, backlash, stiffness, damping,
friction) and the right-hand side of the equations of motion.

State ``x = [theta1, theta2, omega1, omega2]`` [rad, rad, rad/s, rad/s]; input
``u = [xi1, xi2]`` [N m]. Signs as in the report: shaft 1 clockwise positive, shaft 2
counter-clockwise positive, so that ``s = r_b1 theta1 - r_b2 theta2`` is the relative displacement
along the line of action; ``s > b`` is front contact, ``|s| <= b`` separation, ``s < -b`` back contact.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .errors import InputError
from .geometry import pair_geometry
from .params import ContactLaw
from .stiffness import (
    damping_coefficient,
    equivalent_mass,
    mesh_stiffness,
    mesh_stiffness_at,
    yang_sun_stiffness,
)

if TYPE_CHECKING:
    from .catalog import GearModel

__all__ = ["Mode", "PlantKind", "Plant", "build_plant", "plant_nlsys", "STATES", "INPUTS"]

STATES = ("theta1", "theta2", "omega1", "omega2")
INPUTS = ("xi1", "xi2")


class Mode(enum.IntEnum):
    """Contact mode of the gear pair (report section 2, cases 1–3)."""

    BACK = -1
    SEPARATION = 0
    FRONT = 1

    @property
    def label(self) -> str:
        """Lower-case name used in CSV and JSON (``front``, ``separation``, ``back``)."""
        return self.name.lower()


class PlantKind(enum.StrEnum):
    """Which mesh law the plant uses."""

    IMPROVED = "improved"
    YANG_SUN = "yang-sun"
    TVMS = "tvms"


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class Plant:
    """A gear pair ready to simulate: parameters in SI along shafts 1 and 2 and the line of action.

    Attributes
    ----------
    kind : PlantKind
        ``improved`` (mean stiffness, linear law), ``yang-sun`` (Hertz stiffness, ``F = (d x' + k) x``)
        or ``tvms`` (``k = K(vartheta_1)`` following the rotation).
    J1, J2 : float
        Inertias on shafts 1 and 2 (gear plus motor or load) [kg m^2].
    rb1, rb2 : float
        Base radii [m].
    backlash : float
        Half-gap ``b`` along the line of action [m] (contact when ``|s| > b``).
    k, c : float
        Mesh stiffness [N/m] and damping [N s/m] (for ``yang-sun``, ``k`` is eq 39 and ``c`` unused).
    contact_law : ContactLaw
        ``linear`` or ``no_pull``.
    d1, d2 : float
        Viscous friction on each shaft [N m s/rad].
    tc1, tc2, coulomb_velocity : float
        Coulomb friction [N m] and its smoothing velocity [rad/s].
    torque_limit : float
        Motor torque limit [N m] (``inf``: none).
    load_torque : float
        Constant torque on shaft 2 [N m].
    mesh_period : float
        Rotation of gear 1 over one mesh cycle, ``2 pi / N1`` [rad].
    mesh_phase : float
        Mesh-cycle angle ``vartheta_1`` at ``theta1 = 0`` [rad]: the neutral position puts the contact
        at the pitch point P, so ``mesh_phase = (AP - AC) / r_b1``.
    kv_table : ndarray or None
        For ``tvms``: ``K`` sampled uniformly over one mesh cycle [N/m] (periodic, linear interpolation).
    """

    kind: PlantKind
    J1: float
    J2: float
    rb1: float
    rb2: float
    backlash: float
    k: float
    c: float
    contact_law: ContactLaw
    d1: float = 0.0
    d2: float = 0.0
    tc1: float = 0.0
    tc2: float = 0.0
    coulomb_velocity: float = 1e-3
    torque_limit: float = math.inf
    load_torque: float = 0.0
    mesh_period: float = 2 * math.pi
    mesh_phase: float = 0.0
    kv_table: NDArray[np.float64] | None = None

    @property
    def m_eq(self) -> float:
        """Equivalent mass of the mesh mode along the line of action [kg]."""
        return equivalent_mass(self.J1, self.J2, self.rb1, self.rb2)

    @property
    def natural_frequency(self) -> float:
        """Undamped natural frequency of the mesh mode in contact, ``sqrt(k / m_eq)`` [rad/s]."""
        return math.sqrt(self.k / self.m_eq)

    @property
    def gear_ratio(self) -> float:
        """Kinematic ratio ``r_b2 / r_b1 = N2 / N1``."""
        return self.rb2 / self.rb1

    @property
    def is_piecewise_linear(self) -> bool:
        """Whether the dynamics are affine inside each contact mode (exact solver applies)."""
        return self.kind is PlantKind.IMPROVED and self.tc1 == 0.0 and self.tc2 == 0.0

    def with_backlash(self, backlash: float) -> Plant:
        """Copy with another backlash [m]."""
        return dataclasses.replace(self, backlash=backlash)

    def stiffness_at(self, theta1: Any) -> Any:
        """Mesh stiffness at gear-1 angle ``theta1`` [N/m]: ``k`` except for ``tvms``."""
        if self.kv_table is None:
            return self.k + 0.0 * np.asarray(theta1)
        n = self.kv_table.size
        pos = np.mod(np.asarray(theta1, dtype=float) + self.mesh_phase, self.mesh_period) / self.mesh_period * n
        i = np.floor(pos).astype(int) % n
        frac = pos - np.floor(pos)
        return self.kv_table[i] * (1 - frac) + self.kv_table[(i + 1) % n] * frac

    def relative_displacement(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """``s = r_b1 theta1 - r_b2 theta2`` [m] for states ``x`` of shape (4, ...)."""
        return self.rb1 * x[0] - self.rb2 * x[1]

    def mode_of(self, s: Any) -> Any:
        """Contact mode(s) for relative displacement(s) ``s`` (as :class:`Mode` values)."""
        s = np.asarray(s)
        return np.where(s > self.backlash, 1, np.where(s < -self.backlash, -1, 0))

    def energy(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Kinetic plus mesh-spring energy [J] (the improved plant's ``k``; state shape (4, ...))."""
        s = self.relative_displacement(x)
        pen = np.maximum(np.abs(s) - self.backlash, 0.0)
        return 0.5 * self.J1 * x[2] ** 2 + 0.5 * self.J2 * x[3] ** 2 + 0.5 * self.k * pen**2


def build_plant(
    model: GearModel,
    kind: PlantKind | str = PlantKind.IMPROVED,
    *,
    backlash: float | None = None,
    table_points: int = 512,
) -> Plant:
    """Build the plant of a gear model.

    Parameters
    ----------
    model : GearModel
        Catalog entry (gear pair, dynamics, servo).
    kind : PlantKind or str
        ``"improved"``, ``"yang-sun"`` or ``"tvms"``.
    backlash : float, optional
        Replaces the model's backlash [m] (0: backlash-free plant).
    table_points : int
        Samples of ``K`` over one mesh cycle for ``tvms``.

    Returns
    -------
    Plant

    Notes
    -----
    The improved plant uses ``[dynamics] mesh_stiffness`` if given, else the mean of eq 21 over the
    mesh cycle; ``c`` is ``[dynamics] damping_coefficient`` if given, else
    ``2 zeta sqrt(k m_eq)`` (eq 38, consistent form) with ``m_eq`` of the *total* inertias on each
    shaft: the damping ratio is the modal damping of the mesh mode, and with rigid shafts (the report's
    assumption) a motor rotor or a load on a shaft moves with its gear and belongs to that mode. For the
    bare pair this is the report's ``m_eq``; for ``shing1993_servo`` it keeps the mesh mode at
    ``zeta = 0.05`` (with the gear inertias alone it would drop to 0.017 and every impact would be
    nearly elastic).
    The time-varying plant uses ``K(vartheta_1)`` scaled so that its mean equals the improved plant's
    ``k`` (so an override of ``k`` carries over), with the same ``c``.
    """
    try:
        kind = PlantKind(kind)
    except ValueError:
        raise InputError(
            f"plant = {kind!r} is not a plant: expected one of {', '.join(p.value for p in PlantKind)}",
            field="plant",
        ) from None
    pair, dyn, servo = model.pair, model.dynamics, model.servo
    geo = pair_geometry(pair)
    rb1, rb2 = geo.base_radius
    I1, I2 = geo.inertia
    ms = None
    if dyn.mesh_stiffness is not None:
        k = dyn.mesh_stiffness
    else:
        ms = mesh_stiffness(pair, points=table_points)
        k = ms.mean
    c = dyn.damping_coefficient
    J1, J2 = I1 + servo.motor_inertia, I2 + servo.load_inertia
    if c is None:
        c = damping_coefficient(k, dyn.damping_ratio, equivalent_mass(J1, J2, rb1, rb2))
    kv = None
    if kind is PlantKind.YANG_SUN:
        k = yang_sun_stiffness(pair)
    elif kind is PlantKind.TVMS:
        th = np.linspace(0.0, geo.mesh_period_angle, table_points, endpoint=False)
        Kth = mesh_stiffness_at(pair, th, geo)
        mean = ms.mean if ms is not None else mesh_stiffness(pair).mean
        kv = Kth * (k / mean)
    if backlash is not None:
        if not (0.0 <= backlash <= 0.01):
            raise InputError(
                f"backlash = {backlash!r} is out of range: expected a number with 0 <= value <= 0.01 [m]",
                field="backlash",
            )
    return Plant(
        kind=kind,
        J1=J1,
        J2=J2,
        rb1=rb1,
        rb2=rb2,
        backlash=pair.backlash if backlash is None else float(backlash),
        k=k,
        c=c,
        contact_law=dyn.contact_law,
        d1=servo.viscous_friction1,
        d2=servo.viscous_friction2,
        tc1=servo.coulomb_friction1,
        tc2=servo.coulomb_friction2,
        coulomb_velocity=servo.coulomb_velocity,
        torque_limit=servo.torque_limit,
        load_torque=servo.load_torque,
        mesh_period=geo.mesh_period_angle,
        mesh_phase=(geo.AP - geo.AC) / rb1,
        kv_table=kv,
    )


def plant_nlsys(plant: Plant, *, name: str | None = None) -> Any:
    """The plant as a python-control ``nlsys`` with named states, inputs and outputs.

    Parameters
    ----------
    plant : Plant
        The plant.
    name : str, optional
        System name (default ``"gear_<kind>"``).

    Returns
    -------
    control.NonlinearIOSystem
        States ``theta1, theta2, omega1, omega2`` (and ``v_impact`` for Yang–Sun); inputs ``xi1, xi2``
        [N m]; outputs ``theta1, theta2, omega1, omega2, s, force``. The update function has
        python-control's ``(t, x, u, params)`` signature; ``params`` may override ``backlash``, ``k`` and
        ``c``. The servo's ``load_torque`` is added to ``xi2``.

    Notes
    -----
    This is for interconnection with the user's own blocks; it has no event location, so
    ``input_output_response`` steps across the contact switches at whatever accuracy its tolerances
    give. gearctl's own :func:`~gearctl.simulate.simulate` is the exact, fast path.

    Yang–Sun's damping factor is fixed at each contact onset from the impact speed; a continuous-time
    system cannot hold a sample, so the Yang–Sun ``nlsys`` carries a fifth state ``v_impact`` that
    follows ``|s'|`` with a 1 µs time constant while the flanks are apart and is frozen in contact.
    """
    import control as ct

    from .stiffness import yang_sun_damping_factor

    p = plant
    ys = p.kind is PlantKind.YANG_SUN
    states = [*STATES, "v_impact"] if ys else list(STATES)

    def force(x: NDArray[np.float64], params: dict[str, Any]) -> tuple[float, int]:
        b = params.get("backlash", p.backlash)
        k = params.get("k", p.k)
        c = params.get("c", p.c)
        s = p.rb1 * x[0] - p.rb2 * x[1]
        v = p.rb1 * x[2] - p.rb2 * x[3]
        side = 1 if s > b else (-1 if s < -b else 0)
        if side == 0:
            return 0.0, 0
        delta, ddelta = side * s - b, side * v
        if ys:
            F = (yang_sun_damping_factor(k, x[4]) * ddelta + k) * delta
        else:
            kk = float(p.stiffness_at(x[0])) if p.kv_table is not None else k
            F = kk * delta + c * ddelta
        if p.contact_law is ContactLaw.NO_PULL and F < 0.0:
            F = 0.0
        return side * F, side

    def updfcn(t: float, x: NDArray[np.float64], u: NDArray[np.float64], params: dict[str, Any]) -> Any:
        F, side = force(x, params)
        f1 = p.d1 * x[2] + (p.tc1 * math.tanh(x[2] / p.coulomb_velocity) if p.tc1 else 0.0)
        f2 = p.d2 * x[3] + (p.tc2 * math.tanh(x[3] / p.coulomb_velocity) if p.tc2 else 0.0)
        dx = [x[2], x[3], (u[0] - p.rb1 * F - f1) / p.J1, (u[1] + p.load_torque + p.rb2 * F - f2) / p.J2]
        if ys:
            v = abs(p.rb1 * x[2] - p.rb2 * x[3])
            dx.append(0.0 if side else (v - x[4]) / 1e-6)
        return np.array(dx)

    def outfcn(t: float, x: NDArray[np.float64], u: NDArray[np.float64], params: dict[str, Any]) -> Any:
        F, _ = force(x, params)
        return np.array([x[0], x[1], x[2], x[3], p.rb1 * x[0] - p.rb2 * x[1], F])

    return ct.nlsys(
        updfcn, outfcn, states=states, inputs=list(INPUTS),
        outputs=[*STATES, "s", "force"], name=name or f"gear_{p.kind.value.replace('-', '_')}",
    )
