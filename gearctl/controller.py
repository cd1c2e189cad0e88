"""The controller interface the sampled closed loop calls (:mod:`gearctl.closedloop`).

A controller sees only the sensor signals (motor and, optionally, load encoder) and the reference, never
the plant state; what it needs beyond that it estimates itself. The designs live in :mod:`gearctl.design`;
this module is the contract between them and the simulation layer, and imports neither.
"""

from __future__ import annotations

import abc
from typing import Any, Protocol

__all__ = ["Controller", "ReferenceLike", "READING_LIMIT", "check_reading"]

#: Readings and reference values beyond it [rad, rad/s, rad/s^2] (or not finite) are a bad input: the exported C
#: API's ``GEARCTL_INPUT_LIMIT`` (:data:`gearctl.design.mpc.INPUT_LIMIT`).
READING_LIMIT = 1e12


def check_reading(name: str, t: float, value: Any, unit: str = "rad", *, field: str | None = None) -> None:
    """Raise :class:`~gearctl.errors.InputError` naming ``name`` if ``value`` is not a finite number within
    :data:`READING_LIMIT` [``unit``] (the PID family's :meth:`Controller.step`: a NaN reading would put NaN in its
    integrator and filters, and every later torque would be NaN).

    Parameters
    ----------
    name : str
        What the value is, for the message (``y_motor``, ``y_load``, ``ref.at(t)[1]``).
    t : float
        Sample time [s], for the message.
    value : float
        The reading or reference value.
    unit : str
        Its unit, for the message.
    field : str, optional
        The name the error carries (default ``name``).

    Raises
    ------
    InputError
        If ``value`` is not a real number, not finite, or beyond :data:`READING_LIMIT`.
    """
    try:
        ok = bool(abs(value) <= READING_LIMIT) and not isinstance(value, bool | str)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        from .errors import InputError, short_repr

        raise InputError(f"{name} = {short_repr(value)} at t = {t!r} s: expected a finite number within "
                         f"{READING_LIMIT:g} [{unit}]; the controller's state is unchanged (the MPC takes such a motor "
                         "reading as a missed sample, returning 0)", field=field or name)


class ReferenceLike(Protocol):
    """What a controller reads of a reference: ``(r, r', r'')`` at a time, and the known load torque."""

    def at(self, t: Any) -> tuple[Any, Any, Any]:
        """``(r, r', r'')`` of the load angle at time(s) ``t`` [rad, rad/s, rad/s^2].

        Parameters
        ----------
        t : float or ndarray
            Time(s) [s]; the MPC passes an array of sample times and takes arrays of that shape (or scalars)
            back.
        """

    def load_disturbance(self, t: float) -> float:
        """Load-torque disturbance at time ``t`` [N m].

        Parameters
        ----------
        t : float
            Time [s].
        """


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
    preview : int
        How many reference samples each step reads (1: only ``r(t)``; an MPC of horizon N reads
        ``N + 1``). Stated so that comparisons can say which controllers see the future.
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
    design_notes : tuple of str
        What the design changed of what the controller file asked, one sentence each (a PID's bandwidth lowered
        so that the motor alone stays stable in the gap); empty for most designs. ``describe()`` carries it.
    """

    name: str = "controller"
    Ts: float = 1e-3
    uses_load_encoder: bool = False
    realtime: bool = False
    preview: int = 1
    design_notes: tuple[str, ...] = ()

    def __init__(self) -> None:
        self.solve_times: list[float] = []
        self.fallbacks: list[dict[str, Any]] = []
        self.overruns = 0

    @abc.abstractmethod
    def reset(self) -> None:
        """Forget all internal state (integrators, observers, warm starts)."""

    @abc.abstractmethod
    def step(self, t: float, y_motor: float, y_load: float | None, ref: ReferenceLike) -> float:
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
            The load-angle reference (the controller may read it ahead: :attr:`preview`).

        Raises
        ------
        InputError
            The PID family (pid, reversal offset, both inverses): for a ``y_motor``, a ``y_load`` it reads (the
            adaptive inverse: one given) or a reference value ``(r, r', r'')`` not finite or beyond
            :data:`READING_LIMIT`, before anything changes (:func:`check_reading`). The MPC takes such a motor
            reading as a missed sample (torque 0, recorded in :attr:`fallbacks`), a load reading as a missing one.
        """

    def describe(self) -> dict[str, Any]:
        """Settings for reports (gains, horizon, ...)."""
        return {"name": self.name, "Ts": self.Ts, "preview": self.preview}
