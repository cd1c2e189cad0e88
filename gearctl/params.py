"""Dynamic and servo data of a gear model: mesh dynamics, servo extension, sensors.

These are the ``[dynamics]``, ``[servo]`` and ``[sensors]`` tables of a model file. Defaults leave the
report's bare gear pair unchanged (no motor, no load, no friction, no torque limit, ideal sensors).
"""

from __future__ import annotations

import dataclasses
import enum
import math

from .errors import InputError
from .units import quantity, validate_fields

__all__ = ["ContactLaw", "MeshDynamics", "Servo", "Sensors"]


class ContactLaw(enum.StrEnum):
    """Contact force law in contact (report eqs 3 and 10 or the no-pull variant).

    ``LINEAR``: ``F = k delta + c delta'`` as in the report; the force may turn negative (pull) just
    before separation when the flanks part faster than ``k delta / c``.
    ``NO_PULL``: the same force clamped at zero, ``F = max(0, k delta + c delta')``, as Modelica's
    ``ElastoBacklash`` does: teeth can push, never pull.
    """

    LINEAR = "linear"
    NO_PULL = "no_pull"


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class MeshDynamics:
    """Mesh stiffness and damping of the plant (the ``[dynamics]`` table).

    Notes
    -----
    The default contact law is the report's ``"linear"`` law: it is the plant the report simulates,
    and it keeps the plant exactly linear inside each contact mode, which is what the contact-mode
    models (:mod:`gearctl.modes`) describe. ``"no_pull"`` is the physically stricter choice for
    heavily damped meshes; with the report's damping ratio of 0.05 the two differ only in the last
    microseconds of each contact.
    """

    damping_ratio: float = quantity(unit="1", doc="damping ratio of the mesh mode", low=0.0, high=2.0)
    mesh_stiffness: float | None = quantity(
        unit="N/m", doc="mesh stiffness k replacing the computed mean", low=0.0, high=1e13,
        low_open=True, optional=True, default=None,
    )
    damping_coefficient: float | None = quantity(
        unit="N s/m", doc="mesh damping c replacing eq 38", low=0.0, high=1e8, optional=True, default=None
    )
    contact_law: ContactLaw = ContactLaw.LINEAR

    def __post_init__(self) -> None:
        validate_fields(self)
        try:
            object.__setattr__(self, "contact_law", ContactLaw(self.contact_law))
        except ValueError:
            allowed = ", ".join(repr(c.value) for c in ContactLaw)
            rule = f"is not a contact law: expected one of {allowed}"
            raise InputError(f"contact_law = {self.contact_law!r} {rule}", field="contact_law", rule=rule) from None


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class Servo:
    """The gear pair as part of a servo: motor, load, friction, torque limit (the ``[servo]`` table).

    Signs follow the report: torques and angles of shaft 1 positive clockwise, of shaft 2 positive
    counter-clockwise, so a load torque that resists a positive motion of gear 2 is negative.

    Notes
    -----
    Coulomb friction ``T_c sign(omega)`` is regularised as ``T_c tanh(omega / omega_s)`` with
    ``omega_s = coulomb_velocity``: a documented smooth law instead of stick-slip events, so the
    nonlinear integrator stays event-free on the friction side.
    """

    motor_inertia: float = quantity(unit="kg m^2", doc="motor rotor inertia on shaft 1", low=0.0, default=0.0)
    load_inertia: float = quantity(unit="kg m^2", doc="load inertia on shaft 2", low=0.0, default=0.0)
    viscous_friction1: float = quantity(
        unit="N m s/rad", doc="viscous friction on shaft 1", low=0.0, high=1e3, default=0.0
    )
    viscous_friction2: float = quantity(
        unit="N m s/rad", doc="viscous friction on shaft 2", low=0.0, high=1e3, default=0.0
    )
    coulomb_friction1: float = quantity(unit="N m", doc="Coulomb friction on shaft 1", low=0.0, high=1e4, default=0.0)
    coulomb_friction2: float = quantity(unit="N m", doc="Coulomb friction on shaft 2", low=0.0, high=1e4, default=0.0)
    coulomb_velocity: float = quantity(
        unit="rad/s", doc="velocity scale of the smooth Coulomb law", low=0.0, low_open=True, high=10.0, default=1e-3
    )
    torque_limit: float = quantity(
        unit="N m", doc="motor torque limit", low=0.0, low_open=True, default=math.inf
    )
    load_torque: float = quantity(unit="N m", doc="constant load torque on shaft 2", low=-1e4, high=1e4, default=0.0)

    @property
    def has_coulomb(self) -> bool:
        """Whether any Coulomb friction is present."""
        return self.coulomb_friction1 > 0 or self.coulomb_friction2 > 0

    def __post_init__(self) -> None:
        validate_fields(self)


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class Sensors:
    """Position encoders on the motor and load shafts (the ``[sensors]`` table).

    A resolution of ``None`` is an ideal (unquantised) sensor. Noise is white, Gaussian, with the given
    standard deviation, drawn from the simulation's seeded generator.
    """

    motor_encoder_cpr: int | None = quantity(
        unit="counts/rev", doc="motor encoder resolution", low=4, high=2**40, integer=True, optional=True,
        default=None,
    )
    load_encoder_cpr: int | None = quantity(
        unit="counts/rev", doc="load encoder resolution", low=4, high=2**40, integer=True, optional=True,
        default=None,
    )
    motor_noise: float = quantity(unit="rad", doc="motor encoder noise (std)", low=0.0, high=1.0, default=0.0)
    load_noise: float = quantity(unit="rad", doc="load encoder noise (std)", low=0.0, high=1.0, default=0.0)

    def __post_init__(self) -> None:
        validate_fields(self)
