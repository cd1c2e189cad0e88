"""Dynamic and servo data of a gear model: mesh dynamics, servo extension, sensors.

These are the ``[dynamics]``, ``[servo]`` and ``[sensors]`` tables of a model file (and, for a train,
the dynamics keys of each ``[[stage]]``). Defaults leave the report's bare gear pair unchanged (no motor,
no load, no friction, no torque limit, ideal sensors). Units and ranges come from :mod:`gearctl.units`.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from typing import Any

from .errors import InputError
from .units import (
    ADDED_INERTIA,
    COULOMB_FRICTION,
    COULOMB_VELOCITY,
    DAMPING_RATIO,
    ENCODER_CPR,
    ENCODER_NOISE,
    LOAD_TORQUE,
    MESH_DAMPING,
    MESH_STIFFNESS,
    TORQUE_LIMIT,
    VISCOUS_FRICTION,
    validate_fields,
)

__all__ = ["ContactLaw", "FrictionLaw", "MeshDynamics", "Servo", "Sensors"]


class ContactLaw(enum.StrEnum):
    """Contact force law in contact (report eqs 3 and 10 or the no-pull variant).

    ``LINEAR``: ``F = k delta + c delta'`` as in the report; the force may turn negative (pull) just
    before separation when the flanks part faster than ``k delta / c``.
    ``NO_PULL``: the same force clamped at zero, ``F = max(0, k delta + c delta')``, as Modelica's
    ``ElastoBacklash`` does: teeth can push, never pull.
    """

    LINEAR = "linear"
    NO_PULL = "no_pull"


class FrictionLaw(enum.StrEnum):
    """How Coulomb friction acts at standstill.

    ``STICK_SLIP`` (default): ``T_c sign(omega)`` while the shaft slips; at zero speed the shaft sticks
    and friction holds any torque up to ``T_c`` (Karnopp's model with equal static and kinetic
    friction). Sticking and breaking away are located events, and a stuck shaft has one degree of
    freedom less, so the improved plant stays piecewise affine and is solved exactly: a standstill
    costs nothing.
    ``SMOOTH``: ``T_c tanh(omega / omega_s)``, a regularised law without events, integrated by the
    nonlinear solver (the first wave's law; near standstill it is a very stiff damper ``T_c / omega_s``).
    """

    STICK_SLIP = "stick_slip"
    SMOOTH = "smooth"


def _enum_field(obj: object, name: str, cls: type[enum.Enum]) -> None:
    """Turn a string field into its enum member, or raise naming the allowed values."""
    value = getattr(obj, name)
    try:
        object.__setattr__(obj, name, cls(value))
    except ValueError:
        allowed = ", ".join(repr(c.value) for c in cls)
        rule = f"is not allowed: expected one of {allowed}"
        raise InputError(f"{name} = {value!r} {rule}", field=name, rule=rule) from None


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class MeshDynamics:
    """Mesh stiffness and damping of a stage (the ``[dynamics]`` table, or a stage's own keys).

    Parameters
    ----------
    damping_ratio : float
        Damping ratio of the mesh mode [1].
    mesh_stiffness : float or None
        Mesh stiffness ``k`` replacing the computed mean [N/m] (default ``None``: computed).
    damping_coefficient : float or None
        Mesh damping ``c`` replacing eq 38 [N s/m] (default ``None``: from ``damping_ratio``).
    contact_law : ContactLaw or str
        Contact force law, ``"linear"`` (default, the report's) or ``"no_pull"`` (:class:`ContactLaw`).

    Raises
    ------
    InputError
        Naming the field: a value out of its range, or a ``contact_law`` that is not one of the two.

    Notes
    -----
    The default contact law is the report's ``"linear"`` law: it is the plant the report simulates,
    and it keeps the plant exactly linear inside each contact mode, which is what the contact-mode
    models (:mod:`gearctl.modes`) describe. ``"no_pull"`` is the physically stricter choice for
    heavily damped meshes; with the report's damping ratio of 0.05 the two differ only in the last
    microseconds of each contact.
    """

    damping_ratio: float = DAMPING_RATIO.field()
    mesh_stiffness: float | None = MESH_STIFFNESS.field(
        default=None, optional=True, doc="mesh stiffness k replacing the computed mean")
    damping_coefficient: float | None = MESH_DAMPING.field(
        default=None, optional=True, doc="mesh damping c replacing eq 38")
    contact_law: ContactLaw = ContactLaw.LINEAR

    def __post_init__(self) -> None:
        validate_fields(self)
        _enum_field(self, "contact_law", ContactLaw)


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class Servo:
    """The gear train as part of a servo: motor, load, friction, torque limit (the ``[servo]`` table).

    Signs follow the report: every shaft angle is positive in the direction the train moves forward
    (shaft 1 clockwise, shaft 2 counter-clockwise for a pair), so a load torque that resists a forward
    motion is negative. ``1`` is the motor shaft, ``2`` the load shaft; a train's intermediate shafts
    take the ``intermediate_*`` lists (one value per intermediate shaft, motor side first).

    Parameters
    ----------
    motor_inertia : float
        Motor rotor inertia on the motor shaft [kg m^2].
    load_inertia : float
        Load inertia on the load shaft [kg m^2].
    viscous_friction1, viscous_friction2 : float
        Viscous friction on the motor and the load shaft [N m s/rad].
    coulomb_friction1, coulomb_friction2 : float
        Coulomb friction on the motor and the load shaft [N m].
    coulomb_velocity : float
        Velocity scale ``omega_s`` of the smooth Coulomb law [rad/s] (default 1e-3).
    friction_law : FrictionLaw or str
        ``"stick_slip"`` (default) or ``"smooth"`` Coulomb friction (:class:`FrictionLaw`).
    torque_limit : float
        Motor torque limit [N m] (default ``inf``: none).
    load_torque : float
        Constant load torque on the load shaft [N m] (negative resists a forward motion).
    intermediate_inertia : tuple of float
        Inertia added to each intermediate shaft of a train [kg m^2] (a list is taken as a tuple).
    intermediate_viscous_friction : tuple of float
        Viscous friction on each intermediate shaft of a train [N m s/rad].
    intermediate_coulomb_friction : tuple of float
        Coulomb friction on each intermediate shaft of a train [N m].

    Raises
    ------
    InputError
        Naming the field: a value out of its range, or a ``friction_law`` that is not one of the two.

    Notes
    -----
    Coulomb friction follows :class:`FrictionLaw`: stick-slip by default. The smooth law
    ``T_c tanh(omega / omega_s)`` with ``omega_s = coulomb_velocity`` is kept as ``friction_law =
    "smooth"``.
    """

    motor_inertia: float = ADDED_INERTIA.field(default=0.0, doc="motor rotor inertia on the motor shaft")
    load_inertia: float = ADDED_INERTIA.field(default=0.0, doc="load inertia on the load shaft")
    viscous_friction1: float = VISCOUS_FRICTION.field(default=0.0, doc="viscous friction on the motor shaft")
    viscous_friction2: float = VISCOUS_FRICTION.field(default=0.0, doc="viscous friction on the load shaft")
    coulomb_friction1: float = COULOMB_FRICTION.field(default=0.0, doc="Coulomb friction on the motor shaft")
    coulomb_friction2: float = COULOMB_FRICTION.field(default=0.0, doc="Coulomb friction on the load shaft")
    coulomb_velocity: float = COULOMB_VELOCITY.field(default=1e-3)
    friction_law: FrictionLaw = FrictionLaw.STICK_SLIP
    torque_limit: float = TORQUE_LIMIT.field(default=float("inf"))
    load_torque: float = LOAD_TORQUE.field(default=0.0, doc="constant load torque on the load shaft")
    intermediate_inertia: tuple[float, ...] = ADDED_INERTIA.field(
        default=(), sequence=True, doc="inertia added to each intermediate shaft of a train")
    intermediate_viscous_friction: tuple[float, ...] = VISCOUS_FRICTION.field(
        default=(), sequence=True, doc="viscous friction on each intermediate shaft of a train")
    intermediate_coulomb_friction: tuple[float, ...] = COULOMB_FRICTION.field(
        default=(), sequence=True, doc="Coulomb friction on each intermediate shaft of a train")

    @property
    def has_coulomb(self) -> bool:
        """Whether any Coulomb friction is present."""
        return self.coulomb_friction1 > 0 or self.coulomb_friction2 > 0 or any(
            v > 0 for v in self.intermediate_coulomb_friction)

    def __post_init__(self) -> None:
        for name in ("intermediate_inertia", "intermediate_viscous_friction", "intermediate_coulomb_friction"):
            value = getattr(self, name)
            if isinstance(value, list):
                object.__setattr__(self, name, tuple(value))
        validate_fields(self)
        _enum_field(self, "friction_law", FrictionLaw)


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class Sensors:
    """Position encoders on the motor and load shafts (the ``[sensors]`` table).

    A resolution of ``None`` is an ideal (unquantised) sensor. Noise is white, Gaussian, with the given
    standard deviation, drawn from the simulation's seeded generator. ``load_encoder = False`` says the servo
    has no load encoder at all (a motor-encoder-only drive): a controller that reads one is refused
    (:meth:`check_controller`), and a log records ``theta1`` alone.

    Parameters
    ----------
    motor_encoder_cpr, load_encoder_cpr : int or None
        Resolution of the motor and the load encoder [counts/rev] (default ``None``: ideal).
    motor_noise, load_noise : float
        Standard deviation of the motor and the load encoder's noise [rad] (default 0).
    load_encoder : bool
        Whether the servo has a load encoder (default ``True``).

    Raises
    ------
    InputError
        Naming the field: a value out of its range, a ``load_encoder`` that is not a bool, or a
        ``load_encoder_cpr`` or ``load_noise`` given with ``load_encoder = False``.
    """

    motor_encoder_cpr: int | None = ENCODER_CPR.field(default=None, optional=True, doc="motor encoder resolution")
    load_encoder_cpr: int | None = ENCODER_CPR.field(default=None, optional=True, doc="load encoder resolution")
    motor_noise: float = ENCODER_NOISE.field(default=0.0, doc="motor encoder noise (std)")
    load_noise: float = ENCODER_NOISE.field(default=0.0, doc="load encoder noise (std)")
    load_encoder: bool = True

    def __post_init__(self) -> None:
        validate_fields(self)
        if not isinstance(self.load_encoder, bool):
            rule = "is not true or false: expected true (the servo has a load encoder) or false (it has none)"
            raise InputError(f"load_encoder = {self.load_encoder!r} {rule}", field="load_encoder", rule=rule)
        if not self.load_encoder:
            for name in ("load_encoder_cpr", "load_noise"):
                if getattr(self, name):
                    rule = f"describes a load encoder the table says is missing (load_encoder = false): remove {name}"
                    raise InputError(f"{name} = {getattr(self, name)!r} {rule}", field=name, rule=rule)

    def check_controller(self, controller: Any, where: str = "") -> None:
        """Refuse a controller that reads the load encoder when the servo has none.

        Parameters
        ----------
        controller : object
            The controller; it reads the load encoder when its ``uses_load_encoder`` attribute is true.
        where : str
            The controller's file, named in the message (default ``""``: none).

        Raises
        ------
        InputError
            Naming ``load_encoder`` and the controllers that run on the motor encoder alone.
        """
        if not self.load_encoder and getattr(controller, "uses_load_encoder", False):
            name = getattr(controller, "name", "controller")
            at = f" ({where})" if where else ""
            rule = (f"(the servo has no load encoder), but controller {name!r}{at} reads one: run a controller on "
                    f"the motor encoder alone (pid, deadzone_inverse, reversal_offset, or an MPC file with "
                    f"feedback = \"motor\")")
            raise InputError(f"[sensors] load_encoder = false {rule}", field="load_encoder", rule=rule)

    def reading_std(self, shaft: str) -> float:
        """Standard deviation of one reading of the ``"motor"`` or ``"load"`` encoder [rad].

        Its quantisation (a count of ``2 pi / cpr``, uniform: ``/ sqrt(12)``) and its noise, independent.

        Parameters
        ----------
        shaft : str
            ``"motor"`` for the motor encoder; any other value reads the load encoder's figures.
        """
        cpr = self.motor_encoder_cpr if shaft == "motor" else self.load_encoder_cpr
        q = 2.0 * math.pi / cpr if cpr else 0.0
        noise = self.motor_noise if shaft == "motor" else self.load_noise
        return math.sqrt(q * q / 12.0 + noise * noise)
