"""What a controller may know about the plant at design time (the controller interface itself is
:class:`gearctl.controller.Controller`, re-exported here)."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from ..controller import Controller
from ..errors import InputError, short_repr
from ..plant import Plant, check_plant

if TYPE_CHECKING:
    from ..modes import ContactModes

__all__ = ["Controller", "LoopInfo", "loop_info", "check_loop_info"]


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class LoopInfo:
    """Design-time knowledge of the plant: the model, not the true state.

    Attributes
    ----------
    plant : Plant
        The design model: the nominal plant for a pair, its :meth:`~gearctl.plant.Plant.equivalent_pair`
        (one gap of the whole lost motion) for a train. Its backlash is the controller's estimate unless the
        controller file overrides it.
    nominal : Plant
        The nominal plant itself (a pair or a train).
    N : float
        Overall gear ratio, motor angle over load angle.
    J_eq, d_eq : float
        Inertia [kg m^2] and viscous friction [N m s/rad] of the rigid train, on the motor shaft.
    torque_limit : float
        Motor torque limit [N m].
    """

    plant: Plant
    nominal: Plant
    N: float
    J_eq: float
    d_eq: float
    torque_limit: float

    @property
    def modes(self) -> ContactModes:
        """Linear models of the design plant (python-control; built on first use)."""
        from ..modes import linearize_modes

        return linearize_modes(self.plant)


def loop_info(plant: Plant) -> LoopInfo:
    """Design-time knowledge of a plant (a pair, or a train through its equivalent pair).

    Parameters
    ----------
    plant : Plant
        The nominal plant, from :func:`~gearctl.plant.build_plant`.

    Returns
    -------
    LoopInfo

    Raises
    ------
    InputError
        If ``plant`` is not a :class:`~gearctl.plant.Plant` (a gear model: build it first).
    """
    plant = check_plant(plant)
    eq = plant.equivalent_pair()
    N = eq.gear_ratio
    return LoopInfo(
        plant=eq, nominal=plant, N=N, J_eq=eq.J1 + eq.J2 / N**2, d_eq=eq.d1 + eq.d2 / N**2,
        torque_limit=eq.torque_limit,
    )


def check_loop_info(info: object, *, field: str = "info") -> LoopInfo:
    """``info`` itself if it is a :class:`LoopInfo`; else an :class:`~gearctl.errors.InputError` naming ``field``.

    A plant or a gear model is the usual slip: the message says how to make the design knowledge from it.

    Parameters
    ----------
    info : LoopInfo
        What to check.
    field : str
        The argument's name, for the message.

    Raises
    ------
    InputError
        If ``info`` is not a :class:`LoopInfo`.
    """
    if isinstance(info, LoopInfo):
        return info
    if isinstance(info, Plant):
        hint = "make it from the plant, gearctl.design.loop_info(plant)"
    elif hasattr(info, "servo") and hasattr(info, "stages"):
        hint = "make it from the built plant, gearctl.design.loop_info(gearctl.build_plant(model))"
    else:
        hint = "expected gearctl.design.loop_info(plant)"
    raise InputError(f"{field} = {short_repr(info)} is not a LoopInfo: {hint}", field=field)
