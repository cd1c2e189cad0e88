"""Open-loop simulation of a gear plant: the report's free-vibration and constant-load cases and any
torque history, with every contact event located (see :mod:`gearctl.kernel`).

The result holds arrays indexed ``(signal, time)`` like python-control's responses and ``solve_ivp``,
with the events (impacts, separations) and the solver's status.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .errors import InputError, SimulationError
from .kernel import EventKind, Kernel
from .plant import STATES, Mode, Plant, PlantKind

__all__ = ["Event", "SimulationResult", "simulate", "report_case", "contact_force", "CASES", "DIVERGENCE_LIMIT"]

#: |omega| above which a simulation is declared divergent [rad/s].
DIVERGENCE_LIMIT = 1e6

#: The report's simulation cases (section 5.1): initial velocities and torques.
CASES: dict[str, dict[str, float]] = {
    "free": {"omega1": 50.0, "omega2": 0.0, "torque1": 0.0, "torque2": 0.0},
    # a load that resists the motion of gear 2 is negative in the report's sign convention (xi2
    # counter-clockwise positive); the report prints "xi2 = 1 Nm", see README.
    "load": {"omega1": 50.0, "omega2": 0.0, "torque1": 1.0, "torque2": -1.0},
}


@dataclasses.dataclass(frozen=True, slots=True)
class Event:
    """A located contact event.

    Attributes
    ----------
    t : float
        Time [s].
    kind : str
        ``impact``, ``separation``, ``lift``, ``reload`` or ``plastic`` (an impact below the Zeno
        velocity, made perfectly plastic).
    side : str
        ``front`` or ``back``.
    velocity : float
        Relative velocity along the line of action ``s'`` at the event [m/s].
    """

    t: float
    kind: str
    side: str
    velocity: float


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class SimulationResult:
    """Trajectory of a gear plant.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Output times [s].
    x : ndarray, shape (4, n)
        States ``theta1, theta2`` [rad], ``omega1, omega2`` [rad/s].
    u : ndarray, shape (2, n)
        Applied torques ``xi1, xi2`` [N m] (held from each output time to the next).
    s : ndarray, shape (n,)
        Relative displacement along the line of action [m].
    mode : ndarray of int, shape (n,)
        Contact mode (:class:`~gearctl.plant.Mode`: -1 back, 0 separation, 1 front).
    force : ndarray, shape (n,)
        Contact force along the line of action, signed as the front flank's [N].
    events : list of Event
        Every impact, separation (and, for ``no_pull``, lift/reload) in time order.
    max_penetration : float
        Largest ``|s| - b`` over the run [m], between output points too: the peak inside each contact
        sub-step is estimated with a cubic Hermite model of ``s`` (relative error about 1e-4 at 100 µs
        outputs, 1e-8 at 1 µs).
    success : bool
        Whether the run reached its end.
    message : str
        Solver status in words.
    plant : Plant
        The simulated plant.
    solver : str
        ``exact`` or ``dopri5``, and ``compiled`` or ``python``.
    steps : int
        Internal sub-steps taken.
    """

    t: NDArray[np.float64]
    x: NDArray[np.float64]
    u: NDArray[np.float64]
    s: NDArray[np.float64]
    mode: NDArray[np.int_]
    force: NDArray[np.float64]
    events: list[Event]
    max_penetration: float
    success: bool
    message: str
    plant: Plant
    solver: str
    steps: int

    @property
    def states(self) -> dict[str, NDArray[np.float64]]:
        """The state rows by name."""
        return dict(zip(STATES, self.x, strict=True))

    @property
    def impacts(self) -> list[Event]:
        """Impacts (including plastic ones) in time order."""
        return [e for e in self.events if e.kind in ("impact", "plastic")]

    def impact_counts(self) -> dict[str, int]:
        """Number of impacts on each flank: ``{"front": n, "back": n}``."""
        out = {"front": 0, "back": 0}
        for e in self.impacts:
            out[e.side] += 1
        return out

    def energy(self) -> NDArray[np.float64]:
        """Kinetic plus mesh-spring energy at the output times [J] (spring of the plant's ``k``)."""
        return self.plant.energy(self.x)

    def mode_labels(self) -> list[str]:
        """Modes as ``front``, ``separation``, ``back``."""
        return [Mode(int(m)).label for m in self.mode]


def contact_force(plant: Plant, x: NDArray[np.float64], mode: NDArray[np.int_],
                  d_ys: NDArray[np.float64] | float = 0.0) -> NDArray[np.float64]:
    """Contact force along the line of action [N], signed as the front flank's, for states ``(4, n)``.

    Zero in separation; the report's law (eqs 3, 10), its no-pull clamp, or Yang–Sun's
    ``(d x' + k) x`` with the damping factor ``d_ys`` of the current contact.
    """
    s = plant.rb1 * x[0] - plant.rb2 * x[1]
    v = plant.rb1 * x[2] - plant.rb2 * x[3]
    sigma = np.sign(mode).astype(float)
    delta = sigma * s - plant.backlash
    ddelta = sigma * v
    if plant.kind is PlantKind.YANG_SUN:
        F = (np.asarray(d_ys) * ddelta + plant.k) * delta
    else:
        F = plant.stiffness_at(x[0]) * delta + plant.c * ddelta
    if plant.contact_law.value == "no_pull":
        F = np.maximum(F, 0.0)
    return np.where(sigma != 0, sigma * F, 0.0)


def simulate(
    plant: Plant,
    x0: Sequence[float],
    duration: float,
    *,
    torque: tuple[float, float] | Callable[[float, NDArray[np.float64]], tuple[float, float]] = (0.0, 0.0),
    dt: float = 1e-6,
    rtol: float = 1e-9,
    compiled: bool | None = None,
    progress: Callable[[float], Any] | None = None,
) -> SimulationResult:
    """Simulate the plant from ``x0`` for ``duration`` seconds.

    Parameters
    ----------
    plant : Plant
        From :func:`~gearctl.plant.build_plant`.
    x0 : sequence of 4 floats
        Initial ``[theta1, theta2, omega1, omega2]`` [rad, rad, rad/s, rad/s].
    duration : float
        Simulated time [s].
    torque : (float, float) or callable
        Constant ``(xi1, xi2)`` [N m], or ``f(t, x) -> (xi1, xi2)`` evaluated at each output time and
        held until the next (zero-order hold). The servo's ``load_torque`` is added to ``xi2``.
    dt : float
        Output interval [s]; events between outputs are still located exactly.
    rtol : float
        Relative tolerance of the nonlinear solver (Yang–Sun, tvms, Coulomb friction).
    compiled : bool, optional
        Force the compiled or the Python kernel (default: compiled where available).
    progress : callable, optional
        Called with the fraction done, about a hundred times per run.

    Returns
    -------
    SimulationResult

    Raises
    ------
    InputError
        For a non-positive duration or output interval, or a bad initial state.
    SimulationError
        If the state becomes NaN or diverges, or events cascade without end; ``error.result`` holds
        the trajectory up to the failure.
    """
    if not (duration > 0 and math.isfinite(duration)):
        raise InputError(f"duration = {duration!r} is out of range: expected a number > 0 [s]", field="duration")
    if not (dt > 0 and math.isfinite(dt)):
        raise InputError(f"dt = {dt!r} is out of range: expected a number > 0 [s]", field="dt")
    n = int(math.ceil(duration / dt - 1e-9))
    kn = Kernel(plant, np.asarray(x0, dtype=float), dt=min(dt, duration), rtol=rtol, compiled=compiled)
    t = np.empty(n + 1)
    x = np.empty((4, n + 1))
    u = np.empty((2, n + 1))
    mode = np.empty(n + 1, dtype=int)
    dys = np.zeros(n + 1)
    t[0], x[:, 0], mode[0], dys[0] = kn.t, kn.x, int(np.sign(kn.mode)), kn._st.d_ys
    fixed = not callable(torque)
    status, last = 0, 0
    if fixed:
        u1, u2 = (float(v) for v in torque)  # type: ignore[union-attr]
        u[:] = np.array([[u1], [u2]])
        exact_grid = abs(dt * n - duration) <= 1e-12 * duration
        if exact_grid and progress is None:  # the whole run in one kernel call
            status, xs, ms, ds = kn.run(u1, u2 + plant.load_torque, dt, n)
            m = xs.shape[1]
            t[1:m + 1] = t[0] + dt * np.arange(1, m + 1)
            x[:, 1:m + 1], mode[1:m + 1], dys[1:m + 1] = xs, np.sign(ms), ds
            n = 0
            last = m
    tick = max(1, n // 100)
    for i in range(n):
        if not fixed:
            u1, u2 = (float(v) for v in torque(t[i], x[:, i]))  # type: ignore[operator]
        u[:, i] = (u1, u2)
        step = dt if i < n - 1 else duration - dt * (n - 1)
        status = kn.advance(u1, u2 + plant.load_torque, step)
        t[i + 1], x[:, i + 1], mode[i + 1], dys[i + 1] = kn.t, kn.x, int(np.sign(kn.mode)), kn._st.d_ys
        last = i + 1
        if status != 0 or not np.all(np.abs(x[2:, i + 1]) < DIVERGENCE_LIMIT):
            break
        if progress is not None and i % tick == 0:
            progress(i / n)
    u[:, last] = u[:, max(last - 1, 0)]
    sl = slice(0, last + 1)
    res = _result(plant, kn, t[sl], x[:, sl], u[:, sl], mode[sl], dys[sl], status)
    if not res.success:
        raise SimulationError(f"simulation failed at t = {res.t[-1]:.6g} s: {res.message}", result=res)
    return res


def located_events(kn: Kernel) -> list[Event]:
    """The events a kernel located, as :class:`Event` objects in time order."""
    return [Event(float(te), EventKind.NAMES[int(k)], "front" if sd > 0 else "back", float(v))
            for te, k, sd, v in kn.events]


def _result(plant: Plant, kn: Kernel, t: NDArray, x: NDArray, u: NDArray, mode: NDArray, dys: NDArray,
            status: int) -> SimulationResult:
    diverged = status == 0 and not np.all(np.abs(x[2:, -1]) < DIVERGENCE_LIMIT)
    ok = status == 0 and not diverged
    message = "ok" if ok else (f"diverged: |omega| > {DIVERGENCE_LIMIT:.0e} rad/s" if diverged
                               else Kernel.status_message(status))
    events = located_events(kn)
    return SimulationResult(
        t=t, x=x, u=u, s=plant.rb1 * x[0] - plant.rb2 * x[1], mode=mode,
        force=contact_force(plant, x, mode, dys), events=events, max_penetration=kn.max_penetration,
        success=ok, message=message, plant=plant,
        solver=f"{'exact' if kn.exact else 'dopri5'} ({kn.path})", steps=kn.steps,
    )


def report_case(
    plant: Plant,
    case: str = "free",
    duration: float = 0.02,
    *,
    omega1: float | None = None,
    omega2: float | None = None,
    torque1: float | None = None,
    torque2: float | None = None,
    dt: float = 1e-6,
    compiled: bool | None = None,
) -> SimulationResult:
    """One of the report's simulations (section 5.1), optionally with other values.

    ``free``: ``omega1(0) = 50 rad/s``, ``omega2(0) = 0``, neutral positions, no torque (Figs 12–16).
    ``load``: the same start with ``xi1 = 1 N m`` and the resisting load ``xi2 = -1 N m`` (Figs 17–21).

    Notes
    -----
    The report prints ``xi2 = 1 Nm`` for the load, "equal but opposite". With its sign conventions
    (``xi2`` counter-clockwise positive, gear 2 turning counter-clockwise when gear 1 turns clockwise) a
    load that resists the motion is ``xi2 = -1 N m``; ``+1 N m`` would drive gear 2 forward too.
    """
    if case not in CASES:
        raise InputError(f"case = {case!r} is not a case: expected one of {', '.join(CASES)}", field="case")
    c = dict(CASES[case])
    for key, val in (("omega1", omega1), ("omega2", omega2), ("torque1", torque1), ("torque2", torque2)):
        if val is not None:
            if not math.isfinite(val):
                raise InputError(f"{key} = {val!r} must be a finite number", field=key)
            c[key] = float(val)
    return simulate(plant, [0.0, 0.0, c["omega1"], c["omega2"]], duration,
                    torque=(c["torque1"], c["torque2"]), dt=dt, compiled=compiled)
