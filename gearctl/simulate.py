"""Open-loop simulation of a gear plant (a pair or a train): the report's free-vibration and constant-load
cases and any torque history, with every contact event located (see :mod:`gearctl.kernel`).

The result holds arrays indexed ``(signal, time)`` like python-control's responses and ``solve_ivp``,
with the events (impacts, separations) and the solver's status. Per-stage signals (``s``, ``mode``,
``force``) have one row per stage; for a pair they are squeezed to one dimension, as python-control
squeezes the signals of a SISO system.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InputError, SimulationError
from .kernel import EVENT_DTYPE, EventKind, Kernel
from .limits import check_output_size
from .plant import Mode, Plant, check_plant, mesh_force, signal_names
from .units import DURATION, OUTPUT_INTERVAL, RTOL, check_progress

__all__ = ["Event", "SimulationResult", "simulate", "report_case", "contact_force", "CASES", "DIVERGENCE_LIMIT",
           "default_output_interval", "output_steps", "located_events"]

#: |omega| above which a simulation is declared divergent [rad/s].
DIVERGENCE_LIMIT = 1e6

#: The report's simulation cases (section 5.1): initial velocities and torques.
CASES: dict[str, dict[str, float]] = {
    "free": {"omega1": 50.0, "omega2": 0.0, "torque1": 0.0, "torque2": 0.0},
    # a load that resists the motion of gear 2 is negative in the report's sign convention (xi2
    # counter-clockwise positive); the report prints "xi2 = 1 Nm", see README.
    "load": {"omega1": 50.0, "omega2": 0.0, "torque1": 1.0, "torque2": -1.0},
}

#: Output rows the default output interval aims at (:func:`default_output_interval`).
DEFAULT_ROWS = 20_000


def output_steps(duration: float, dt: float, *, field: str = "dt") -> int:
    """The output intervals of a run of ``duration`` at ``dt`` [s]: at least one, so that an interval longer than
    the run still gives its end (one of 1e308 s gave the initial state alone, and a summary that failed on it).

    Parameters
    ----------
    duration : float
        Simulated time [s].
    dt : float
        Output interval [s].
    field : str
        Name of the interval in the error message (default ``"dt"``).

    Raises
    ------
    InputError
        Naming ``field`` when the count is not even a finite number (``dt = 5e-324``); a finite count is sized by
        :func:`gearctl.limits.check_output_size`.
    """
    steps = duration / dt
    if not math.isfinite(steps):
        raise InputError(f"{field} = {dt!r}: the output would hold {steps} samples; ask for fewer samples: a larger "
                         f"output interval", field=field)
    return max(1, int(math.ceil(steps - 1e-9)))


def default_output_interval(duration: float) -> float:
    """The output interval a run of ``duration`` gets by default [s].

    1 µs up to 20 ms (the report's figures), then the next 1, 2 or 5 x 10^k that keeps about
    :data:`DEFAULT_ROWS` rows: the output follows the question, not the other way round. Events between
    outputs are located exactly either way.

    Parameters
    ----------
    duration : float
        Simulated time [s].
    """
    d = duration / DEFAULT_ROWS
    if d <= 1e-6:
        return 1e-6
    k = math.floor(math.log10(d))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * 10.0**k >= d * (1 - 1e-12):
            return m * 10.0**k
    return 10.0 ** (k + 1)


@dataclasses.dataclass(frozen=True, slots=True)
class Event:
    """A located contact event.

    Attributes
    ----------
    t : float
        Time [s].
    kind : str
        ``impact``, ``separation``, ``lift``, ``reload`` or ``plastic`` (an impact below the Zeno
        velocity, made perfectly plastic); ``stick`` or ``slip`` for a shaft with stick-slip friction.
    side : str
        ``front`` or ``back``; for friction events, the way a ``slip`` starts (``forward`` or ``backward``) and
        ``-`` for a ``stick``.
    velocity : float
        Relative velocity along the line of action ``s'`` at the event [m/s]; for ``stick``, the torque friction
        holds [N m], for a ``slip`` the torque that carried the shaft on through zero speed [N m] (0 for a
        break-away from standstill).
    stage : int
        The stage (0 for a pair), or the shaft of a friction event.
    """

    t: float
    kind: str
    side: str
    velocity: float
    stage: int = 0


def located_events(log: np.ndarray, *, mesh_only: bool = True) -> list[Event]:
    """The events of a kernel's :attr:`~gearctl.kernel.Kernel.event_log` as :class:`Event` objects.

    Parameters
    ----------
    log : ndarray
        Event log, a structured array of :data:`~gearctl.kernel.EVENT_DTYPE` (fields ``t``, ``v``, ``kind``,
        ``side``, ``where``).
    mesh_only : bool
        Keep the contact events alone (default); ``False`` adds the friction events, ``stick`` and ``slip``.
    """
    if mesh_only:
        log = log[log["kind"] <= EventKind.PLASTIC]
    sides = {1: "front", -1: "back", 0: "-"}
    return [Event(t, EventKind.NAMES[k], sides.get(sd, "-") if k <= EventKind.PLASTIC else
                  {1: "forward", -1: "backward", 0: "-"}[sd], v, w)
            for t, v, k, sd, w in zip(log["t"].tolist(), log["v"].tolist(), log["kind"].tolist(),
                                      log["side"].tolist(), log["where"].tolist(), strict=True)]


def _squeeze(a: NDArray[Any]) -> NDArray[Any]:
    return a[0] if a.shape[0] == 1 else a


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class SimulationResult:
    """Trajectory of a gear plant.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Output times [s].
    x : ndarray, shape (nx, n)
        States: shaft angles [rad], then shaft speeds [rad/s] (a pair: ``theta1, theta2, omega1, omega2``).
    u : ndarray, shape (2, n)
        Applied motor and load torques [N m] (held from each output time to the next).
    s : ndarray, shape (n,) or (stages, n)
        Relative displacement along each stage's line of action [m].
    mode : ndarray of int, shape (n,) or (stages, n)
        Contact mode (:class:`~gearctl.plant.Mode`: -1 back, 0 separation, 1 front).
    force : ndarray, shape (n,) or (stages, n)
        Contact force along the line of action, signed as the front flank's [N].
    event_log : ndarray
        The recorded events (:data:`gearctl.kernel.EVENT_DTYPE`); :attr:`events` as objects.
    counts : dict
        Exact event counts per stage (:data:`gearctl.kernel.COUNT_NAMES`, ``max_impact_velocity``), also
        beyond the events recorded in detail.
    events_dropped : int
        Events located but not recorded in detail (a run with more than the kernel's ``max_records``).
    max_penetration : float
        Largest ``|s| - b`` of any stage over the run [m], between output points too: the peak inside each
        contact sub-step is estimated with a cubic Hermite model of ``s`` (relative error about 1e-4 at
        100 µs outputs, 1e-8 at 1 µs).
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
    event_log: np.ndarray
    counts: dict[str, NDArray[Any]]
    max_penetration: float
    success: bool
    message: str
    plant: Plant
    solver: str
    steps: int
    events_dropped: int = 0

    @property
    def events(self) -> list[Event]:
        """Every recorded impact, separation (and, for ``no_pull``, lift/reload) in time order."""
        return located_events(self.event_log)

    @property
    def states(self) -> dict[str, NDArray[np.float64]]:
        """The state rows by name."""
        return dict(zip(signal_names(self.plant)[0], self.x, strict=True))

    @property
    def impacts(self) -> list[Event]:
        """Impacts (including plastic ones) in time order."""
        return [e for e in self.events if e.kind in ("impact", "plastic")]

    def impact_counts(self) -> dict[str, int]:
        """Number of impacts on each flank, all stages: ``{"front": n, "back": n}`` (exact)."""
        c = self.counts
        return {"front": int(np.sum(c["impacts_front"] + c["plastic_front"])),
                "back": int(np.sum(c["impacts_back"] + c["plastic_back"]))}

    def stage_impacts(self) -> list[dict[str, int]]:
        """Impacts per stage: ``[{"front": n, "back": n}, ...]`` (exact)."""
        c = self.counts
        return [{"front": int(c["impacts_front"][i] + c["plastic_front"][i]),
                 "back": int(c["impacts_back"][i] + c["plastic_back"][i])} for i in range(self.plant.n_stages)]

    def energy(self) -> NDArray[np.float64]:
        """Kinetic plus mesh-spring energy at the output times [J] (springs of the plant's ``k``)."""
        return self.plant.energy(self.x)

    def mode_labels(self) -> list[str]:
        """Modes of a pair as ``front``, ``separation``, ``back`` (the first stage's for a train)."""
        m = self.mode if self.mode.ndim == 1 else self.mode[0]
        labels = {int(v): Mode(int(v)).label for v in (-1, 0, 1)}
        return [labels[v] for v in m.tolist()]


def contact_force(plant: Plant, x: NDArray[np.float64], mode: NDArray[np.int_],
                  d_ys: NDArray[np.float64] | float = 0.0) -> NDArray[np.float64]:
    """Contact force along the line of action [N], signed as the front flank's (:func:`~gearctl.plant.mesh_force`).

    For a pair, ``mode`` and ``d_ys`` may be one-dimensional and the result is; for a train they have one
    row per stage.

    Parameters
    ----------
    plant : Plant
        The plant.
    x : ndarray, shape (nx, ...)
        States: shaft angles [rad], then shaft speeds [rad/s].
    mode : ndarray of int
        Contact mode per stage (its sign counts: 0 in the gap), e.g. :attr:`SimulationResult.mode`.
    d_ys : float or ndarray
        Yang–Sun damping factor of each stage's current contact [N s/m^2] (0 for the other plants).
    """
    mode = np.asarray(mode)
    if plant.n_stages == 1 and (mode.ndim == 0 or mode.shape[0] != 1 or mode.ndim == np.asarray(x).ndim - 1):
        F = mesh_force(plant, x, mode[None], np.asarray(d_ys)[None] if np.ndim(d_ys) else d_ys)
        return F[0]
    return mesh_force(plant, x, mode, d_ys)


def _torque_pair(value: Any, t: float) -> tuple[float, float]:
    """The torque function's value as two finite floats, or an :class:`InputError` naming ``torque``."""
    try:
        pair = [float(v) for v in value]
    except (TypeError, ValueError):
        pair = []
    if len(pair) != 2 or not all(math.isfinite(v) for v in pair):
        raise InputError(f"torque(t, x) = {value!r} at t = {t:.6g} s is not a torque: expected (xi_motor, xi_load), "
                         "two finite numbers [N m]", field="torque")
    return pair[0], pair[1]


def simulate(
    plant: Plant,
    x0: ArrayLike,
    duration: float,
    *,
    torque: tuple[float, float] | Callable[[float, NDArray[np.float64]], tuple[float, float]] = (0.0, 0.0),
    dt: float | None = None,
    rtol: float = 1e-9,
    compiled: bool | None = None,
    progress: Callable[[float], Any] | None = None,
) -> SimulationResult:
    """Simulate the plant from ``x0`` for ``duration`` seconds.

    Parameters
    ----------
    plant : Plant
        From :func:`~gearctl.plant.build_plant`.
    x0 : sequence of float
        Initial state: shaft angles, then speeds (a pair: ``[theta1, theta2, omega1, omega2]``).
    duration : float
        Simulated time [s].
    torque : (float, float) or callable
        Constant ``(xi_motor, xi_load)`` [N m], or ``f(t, x) -> (xi_motor, xi_load)`` evaluated at each
        output time and held until the next (zero-order hold). The servo's ``load_torque`` is added to
        the load torque.
    dt : float, optional
        Output interval [s]; default :func:`default_output_interval` of the duration. Events between
        outputs are still located exactly.
    rtol : float
        Relative tolerance of the nonlinear solver (Yang–Sun, tvms, smooth Coulomb friction).
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
        For a non-positive duration or output interval, an output too large to hold, a bad initial
        state, a torque (or a value of the torque function) that is not two finite numbers, an ``rtol``
        outside 1e-14..1e-2 or a ``progress`` that is not callable.
    SimulationError
        If the state becomes NaN or diverges, or events cascade without end; ``error.result`` holds
        the trajectory up to the failure.
    """
    plant = check_plant(plant)
    DURATION.check("duration", duration)
    dt = default_output_interval(duration) if dt is None else dt
    dt = OUTPUT_INTERVAL.check("dt", dt)  # a string or a bool is named as such, not 'out of range'
    RTOL.check("rtol", rtol)
    check_progress(progress)
    if not callable(torque):
        try:
            pair = [float(v) for v in torque]
        except (TypeError, ValueError):
            pair = []
        if len(pair) != 2 or not all(math.isfinite(v) for v in pair):
            raise InputError(f"torque = {torque!r} is not a torque: expected (xi_motor, xi_load), two finite "
                             "numbers [N m], or a function f(t, x) -> (xi_motor, xi_load)", field="torque")
    n = output_steps(duration, dt)
    nx, ns = plant.nx, plant.n_stages
    check_output_size(n + 1, 3 * nx + 3 * ns + 4, field="dt", fix="a larger output interval --dt")
    kn = Kernel(plant, x0, dt=min(dt, duration), rtol=rtol, compiled=compiled)
    t = np.empty(n + 1)
    x = np.empty((nx, n + 1))
    u = np.empty((2, n + 1))
    mode = np.empty((ns, n + 1), dtype=int)
    dys = np.zeros((ns, n + 1))
    t[0], x[:, 0], mode[:, 0], dys[:, 0] = kn.t, kn.x, np.sign(kn.modes), kn.d_ys
    fixed = not callable(torque)
    status, last = 0, 0
    lt = plant.load_torque
    if fixed:
        u1, u2 = (float(v) for v in torque)  # type: ignore[union-attr]
        u[:] = np.array([[u1], [u2]])
        exact_grid = abs(dt * n - duration) <= 1e-12 * duration
        if exact_grid and progress is None:  # the whole run in a few kernel calls
            status, xs, ms, ds = kn.run(u1, u2 + lt, dt, n)
            m = xs.shape[1]
            t[1:m + 1] = t[0] + dt * np.arange(1, m + 1)
            x[:, 1:m + 1], mode[:, 1:m + 1], dys[:, 1:m + 1] = xs, np.sign(ms), ds
            n = 0
            last = m
    tick = max(1, n // 100)
    for i in range(n):
        if not fixed:
            u1, u2 = _torque_pair(torque(t[i], x[:, i]), t[i])  # type: ignore[operator]
        u[:, i] = (u1, u2)
        step = dt if i < n - 1 else duration - dt * (n - 1)
        status = kn.advance(u1, u2 + lt, step)
        t[i + 1], x[:, i + 1], mode[:, i + 1], dys[:, i + 1] = kn.t, kn.x, np.sign(kn.modes), kn.d_ys
        last = i + 1
        if status != 0 or not np.all(np.abs(x[nx // 2:, i + 1]) < DIVERGENCE_LIMIT):
            break
        if progress is not None and i % tick == 0:
            progress(i / n)
    u[:, last] = u[:, max(last - 1, 0)]
    sl = slice(0, last + 1)
    res = _result(plant, kn, t[sl], x[:, sl], u[:, sl], mode[:, sl], dys[:, sl], status)
    if not res.success:
        raise SimulationError(f"simulation failed at t = {res.t[-1]:.6g} s: {res.message}", result=res)
    return res


def _result(plant: Plant, kn: Kernel, t: NDArray, x: NDArray, u: NDArray, mode: NDArray, dys: NDArray,
            status: int) -> SimulationResult:
    w = plant.nx // 2
    diverged = status == 0 and not np.all(np.abs(x[w:, -1]) < DIVERGENCE_LIMIT)
    ok = status == 0 and not diverged
    message = "ok" if ok else (f"diverged: |omega| > {DIVERGENCE_LIMIT:.0e} rad/s" if diverged
                               else kn.run_message(status))
    return SimulationResult(
        t=t, x=x, u=u, s=_squeeze(plant.gaps(x)), mode=_squeeze(mode), force=_squeeze(mesh_force(plant, x, mode, dys)),
        event_log=kn.event_log, counts=kn.counts, max_penetration=kn.max_penetration, success=ok, message=message,
        plant=plant, solver=f"{'exact' if kn.exact else 'dopri5'} ({kn.path})", steps=kn.steps,
        events_dropped=kn.dropped_events,
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
    dt: float | None = None,
    compiled: bool | None = None,
    progress: Callable[[float], Any] | None = None,
) -> SimulationResult:
    """One of the report's simulations (section 5.1), optionally with other values.

    ``free``: ``omega1(0) = 50 rad/s``, ``omega2(0) = 0``, neutral positions, no torque (Figs 12–16).
    ``load``: the same start with ``xi1 = 1 N m`` and the resisting load ``xi2 = -1 N m`` (Figs 17–21).
    For a train, ``omega1`` is the motor shaft's speed, ``omega2`` the load shaft's, and every intermediate
    shaft starts at the speed that keeps its stages' gaps closing neither way (the motor's over the ratio
    up to it).

    Parameters
    ----------
    plant : Plant
        From :func:`~gearctl.plant.build_plant`.
    case : str
        ``"free"`` or ``"load"`` (:data:`CASES`).
    duration : float
        Simulated time [s] (default 0.02, the report's figures).
    omega1, omega2 : float, optional
        Initial speeds of the motor and the load shaft [rad/s], replacing the case's.
    torque1, torque2 : float, optional
        Constant torques ``xi_motor``, ``xi_load`` [N m], replacing the case's.
    dt : float, optional
        Output interval [s]; default :func:`default_output_interval` of the duration.
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
        If ``plant`` is not a Plant, ``case`` is not a case, a given speed or torque is not finite, or as
        :func:`simulate` raises it (duration, output interval).
    SimulationError
        As :func:`simulate`: the state becomes NaN or diverges, or events cascade without end.

    Notes
    -----
    The report prints ``xi2 = 1 Nm`` for the load, "equal but opposite". With its sign conventions
    (``xi2`` counter-clockwise positive, gear 2 turning counter-clockwise when gear 1 turns clockwise) a
    load that resists the motion is ``xi2 = -1 N m``; ``+1 N m`` would drive gear 2 forward too.
    """
    plant = check_plant(plant)
    if case not in CASES:
        raise InputError(f"case = {case!r} is not a case: expected one of {', '.join(CASES)}", field="case")
    c = dict(CASES[case])
    for key, val in (("omega1", omega1), ("omega2", omega2), ("torque1", torque1), ("torque2", torque2)):
        if val is not None:
            if isinstance(val, bool) or not isinstance(val, numbers.Real) or not math.isfinite(val):
                raise InputError(f"{key} = {val!r} must be a finite number", field=key)
            c[key] = float(val)
    w = plant.nx // 2
    x0 = np.zeros(plant.nx)
    x0[w] = c["omega1"]
    for j in range(1, w - 1):  # intermediate shafts of a train: moving with the motor
        x0[w + j] = c["omega1"] / math.prod(s.ratio for s in plant.stages[:j])
    x0[-1] = c["omega2"]
    return simulate(plant, x0, duration, torque=(c["torque1"], c["torque2"]), dt=dt, compiled=compiled,
                    progress=progress)


_ = EVENT_DTYPE  # re-exported for readers of SimulationResult.event_log
