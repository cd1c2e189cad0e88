"""The controller interface and what a controller may know about the plant at design time."""

from __future__ import annotations

import abc
import dataclasses
from typing import Any

from ..modes import ContactModes, linearize_modes
from ..plant import Plant
from ..references import Reference

__all__ = ["Controller", "LoopInfo", "loop_info"]


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class LoopInfo:
    """Design-time knowledge of the plant: the model, not the true state.

    Attributes
    ----------
    plant : Plant
        The nominal plant the controller is designed on (its backlash is the controller's estimate
        unless the controller file overrides it).
    modes : ContactModes
        Its linear models.
    N : float
        Gear ratio ``r_b2 / r_b1``.
    J_eq, d_eq : float
        Inertia [kg m^2] and viscous friction [N m s/rad] of the rigid train, on the motor shaft.
    torque_limit : float
        Motor torque limit [N m].
    """

    plant: Plant
    modes: ContactModes
    N: float
    J_eq: float
    d_eq: float
    torque_limit: float


def loop_info(plant: Plant) -> LoopInfo:
    """Design-time knowledge of a plant."""
    N = plant.gear_ratio
    return LoopInfo(
        plant=plant, modes=linearize_modes(plant), N=N, J_eq=plant.J1 + plant.J2 / N**2,
        d_eq=plant.d1 + plant.d2 / N**2, torque_limit=plant.torque_limit,
    )


class Controller(abc.ABC):
    """A sampled position controller: one motor-torque command per sample.

    Attributes
    ----------
    name : str
        Label for reports.
    Ts : float
        Sample period [s].
    uses_load_encoder : bool
        Whether it needs the load encoder.
    solve_times : list of float
        Wall time of each optimisation solve [s] (empty for controllers that solve none).
    fallbacks : list of dict
        Samples where a solve failed or overran and a safe command was used: ``{"t", "reason"}``.
    realtime : bool
        For controllers that solve an optimisation: whether a solve that overruns its time budget falls
        back to the safe command, as on the target (True), or is only counted in :attr:`overruns`
        (False, the default: the simulated trajectory then does not depend on how busy this machine is,
        and results are deterministic for a seed).
    overruns : int
        Solves that took longer than the budget.
    """

    name: str = "controller"
    Ts: float = 1e-3
    uses_load_encoder: bool = False
    realtime: bool = False

    def __init__(self) -> None:
        self.solve_times: list[float] = []
        self.fallbacks: list[dict[str, Any]] = []
        self.overruns = 0

    @abc.abstractmethod
    def reset(self) -> None:
        """Forget all internal state (integrators, observers, warm starts)."""

    @abc.abstractmethod
    def step(self, t: float, y_motor: float, y_load: float | None, ref: Reference) -> float:
        """Motor torque command for sample time ``t`` [N m].

        Parameters
        ----------
        t : float
            Sample time [s].
        y_motor : float
            Motor encoder reading, motor angle ``theta1`` [rad].
        y_load : float or None
            Load encoder reading ``theta2`` [rad], or None without a load encoder.
        ref : Reference
            The load-angle reference (the controller may read it ahead: preview).
        """

    def describe(self) -> dict[str, Any]:
        """Settings for reports (gains, horizon, ...)."""
        return {"name": self.name, "Ts": self.Ts}
