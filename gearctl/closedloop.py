"""The sampled-data closed loop: a controller at its own period, the plant integrated exactly between samples.

Per sample: the encoders read the true angles (with noise, then quantised to their counts), the
controller returns a motor torque, the torque limit clips it, and the kernel advances the plant over the
sample with that torque held (zero-order hold), locating every contact event inside the sample.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .controller import Controller, ReferenceLike
from .errors import InputError, SimulationError, short_repr
from .kernel import Kernel
from .limits import check_output_size
from .params import Sensors
from .plant import Plant, check_plant
from .simulate import DIVERGENCE_LIMIT, Event, located_events
from .units import DURATION, SEED, check_progress

__all__ = ["ClosedLoopResult", "simulate_closed_loop", "check_controller", "loop_samples", "loop_result", "Encoder"]


@dataclasses.dataclass(frozen=True, slots=True)
class Encoder:
    """A position encoder: Gaussian noise (std [rad]), then quantisation to ``cpr`` counts per revolution.

    Parameters
    ----------
    cpr : int or None
        Counts per revolution [counts/rev]; None or 0: no quantisation.
    noise : float
        Standard deviation of the Gaussian noise added before quantisation [rad] (default 0: none).
    """

    cpr: int | None
    noise: float = 0.0

    def read(self, angle: float, rng: np.random.Generator) -> float:
        """Measured angle [rad].

        Parameters
        ----------
        angle : float
            True angle [rad].
        rng : numpy.random.Generator
            Source of the noise (not drawn from when ``noise`` is 0).

        Returns
        -------
        float
            ``angle`` plus noise, rounded to the nearest count.
        """
        if self.noise > 0.0:
            angle += self.noise * rng.standard_normal()
        if self.cpr:
            q = 2 * math.pi / self.cpr
            angle = q * math.floor(angle / q + 0.5)
        return angle


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class ClosedLoopResult:
    """A closed-loop run, arrays indexed ``(signal, sample)``.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Sample times [s].
    x : ndarray, shape (nx, n)
        True plant states at the samples (shaft angles, then speeds).
    reference : ndarray, shape (n,)
        Load-angle reference [rad].
    torque : ndarray, shape (n,)
        Motor torque applied over each sample (after the limit) [N m].
    command : ndarray, shape (n,)
        Torque the controller asked for [N m].
    y_motor, y_load : ndarray, shape (n,)
        Encoder readings [rad] (``y_load`` NaN without a load encoder).
    mode : ndarray of int, shape (n,) or (stages, n)
        Contact mode at the samples (-1 back, 0 separation, 1 front), one row per stage of a train.
    event_log : ndarray
        Impacts and separations located inside the samples (:data:`gearctl.kernel.EVENT_DTYPE`);
        :attr:`events` as objects.
    counts : dict
        Exact event counts per stage (:data:`gearctl.kernel.COUNT_NAMES`), also beyond the recorded ones.
    solve_times : ndarray
        Controller optimisation solve times [s] (empty for controllers that solve none).
    fallbacks : list of dict
        Samples where the controller fell back to a safe command.
    plant : Plant
    controller : dict
        The controller's settings.
    success : bool
    message : str
    wall_time : float
        Wall time of the run [s].
    settle : float
        The reference's settle time [s] (start of the error statistics).
    overruns : int
        Optimisation solves that took longer than the controller's budget (see ``Controller.realtime``).
    """

    t: NDArray[np.float64]
    x: NDArray[np.float64]
    reference: NDArray[np.float64]
    torque: NDArray[np.float64]
    command: NDArray[np.float64]
    y_motor: NDArray[np.float64]
    y_load: NDArray[np.float64]
    mode: NDArray[np.int_]
    event_log: np.ndarray
    counts: dict[str, Any]
    solve_times: NDArray[np.float64]
    fallbacks: list[dict[str, Any]]
    plant: Plant
    controller: dict[str, Any]
    success: bool
    message: str
    wall_time: float
    settle: float = 0.0
    overruns: int = 0

    @property
    def load_angle(self) -> NDArray[np.float64]:
        """True load-shaft angle [rad]."""
        return self.x[self.x.shape[0] // 2 - 1]

    @property
    def error(self) -> NDArray[np.float64]:
        """Load-angle tracking error ``r - theta_load`` [rad]."""
        return self.reference - self.load_angle

    @property
    def s(self) -> NDArray[np.float64]:
        """Relative displacement along the line of action [m] (one row per stage of a train)."""
        return self.plant.relative_displacement(self.x)

    @property
    def events(self) -> list[Event]:
        """The recorded mesh events as objects."""
        return located_events(self.event_log)

    @property
    def impacts(self) -> list[Event]:
        """Impacts, including plastic ones."""
        return [e for e in self.events if e.kind in ("impact", "plastic")]

    @property
    def impact_count(self) -> int:
        """Impacts of all stages (exact, also beyond the recorded events)."""
        c = self.counts
        return int(np.sum(c["impacts_front"] + c["impacts_back"] + c["plastic_front"] + c["plastic_back"]))


def loop_samples(plant: Plant, controller: Controller, duration: float, seed: int) -> int:
    """The number of controller samples of a closed-loop run, after checking its inputs (duration, seed,
    and the size of the output the run would write).

    Parameters
    ----------
    plant : Plant
        The simulated plant (its state count sizes the memory a sample takes).
    controller : Controller
        The controller; its ``Ts`` [s] sets the sample count.
    duration : float
        Simulated time, (0, 1e5] [s].
    seed : int
        Random seed of the encoder noise, 0..2**63 - 1.

    Returns
    -------
    int
        ``round(duration / controller.Ts)``, at least 1.

    Raises
    ------
    InputError
        For a duration or seed out of range, a run shorter than one sample, or an output too large.
    """
    DURATION.check("duration", duration)
    SEED.check("seed", seed)
    n = check_loop_duration(duration, controller.Ts)
    # what a sample costs while the loop runs, not only the arrays it returns: the per-sample lists of the loop and
    # of the controller (torques, statuses, solve and step times): the peak RSS grew by 581 B (a pair's PID), 736 B
    # (its MPC) and 1173 B (the three-stage train's MPC) per sample. The arrays alone, nx + 8 doubles, let a reviewer's
    # 97 000 s ISO program through that would have needed about 57 GB (3.3 GB measured for 5568 s)
    check_loop_memory(plant, duration, controller.Ts)
    return n


#: The catalog controllers' sample time [s] (``LoopSettings.sample_time``): what a run is sized at before its
#: controller is designed (``bench``, ``sweep``); each run checks again at its own.
DEFAULT_TS = 1e-3


def check_loop_duration(duration: float, Ts: float, *, field: str = "duration", who: str = "") -> int:
    """The samples of a closed loop of ``duration`` [s] sampled every ``Ts`` [s], ``round(duration / Ts)``; a run of
    none is refused, naming ``field`` and the least duration (``bench`` and ``sweep`` check their runs with it before
    any starts: each run failed alone, and the command ended with exit 0).

    Parameters
    ----------
    duration : float
        Simulated time [s].
    Ts : float
        The controller's sample time [s].
    field : str
        The name the message gives the duration (default ``"duration"``; ``"--duration"`` from the command line).
    who : str
        Whose sample it is, for the message (``" of pid"``, the controller; default ``""``).

    Returns
    -------
    int
        The number of samples, at least 1.

    Raises
    ------
    InputError
        If ``duration`` holds no sample (shorter than half of ``Ts``, which rounds to none).
    """
    n = int(round(duration / Ts))
    if n < 1:
        raise InputError(f"{field} = {duration!r} is shorter than one sample{who} ({Ts:g} s): expected "
                         f"{field} >= {Ts / 2:g} s (a run is rounded to whole samples, at least one)", field="duration")
    return n


def check_loop_memory(plant: Plant, duration: float, Ts: float = DEFAULT_TS, *, field: str = "duration",
                      fix: str = "a shorter --duration") -> None:
    """Refuse a closed loop of ``duration`` [s] sampled every ``Ts`` [s] that would not fit in memory (see
    :func:`loop_samples`), naming ``field`` and what to change."""
    per = LOOP_SAMPLE_BYTES + LOOP_STATE_BYTES * plant.nx
    check_output_size(int(round(duration / Ts)) + 1, -(-per // 8), field=field, fix=fix, what="the closed loop")


def loop_bytes(plant: Plant, duration: float, Ts: float = DEFAULT_TS) -> int:
    """Memory a closed loop of ``duration`` [s] sampled every ``Ts`` [s] takes while it runs [bytes]: what
    :func:`check_loop_memory` weighs (a local cluster's workers each hold one such run at once)."""
    per = LOOP_SAMPLE_BYTES + LOOP_STATE_BYTES * plant.nx
    return 8 * (int(round(duration / Ts)) + 1) * -(-per // 8)


#: Memory a closed-loop sample takes while the run lasts [bytes]: a fixed part and a part per state (see
#: loop_samples): 840 B for a pair, 1080 B for a two-stage and 1320 B for a three-stage train, against the peak RSS's
#: growth per sample of 581-736 B, 725-1002 B and 863-1173 B measured (track and precision, PID, inverse and MPC).
#: (640 B + 24 B per state had been set from tracemalloc's peak, which counts the bytes asked for, not what malloc
#: holds for them: the three-stage train's MPC took 1.4x its 832 B.)
LOOP_SAMPLE_BYTES, LOOP_STATE_BYTES = 360, 120


def check_controller(controller: Any) -> None:
    """Refuse what is not a controller (``Ts``, ``reset`` and ``step``) with an InputError naming ``controller``.

    Parameters
    ----------
    controller : object
        What a caller passed as the controller.

    Raises
    ------
    InputError
        If ``controller`` lacks any of ``Ts``, ``reset``, ``step``.
    """
    if not all(hasattr(controller, a) for a in ("Ts", "reset", "step")):
        raise InputError(f"controller = {short_repr(controller)} is not a controller: expected a "
                         "gearctl.load_controller(...) or gearctl.load_exported(...)", field="controller")


def _reference_samples(ref: Any, t: NDArray[np.floating]) -> NDArray[np.float64]:
    """The reference's angle at the loop's samples ``t``, after checking that its angle, speed and acceleration are
    finite there: a NaN in a user's reference ran the PID on NaN commands (zero torque, each logged as a fallback)
    and stopped the MPC's QP with "QP data rejected", neither naming the reference."""
    try:
        given = [np.asarray(v, dtype=float) for v in ref.at(t)]
    except (ValueError, TypeError) as exc:
        raise InputError(f"reference: at(t) gave no numbers ({exc}); expected (r, r', r'') [rad, rad/s, rad/s^2]",
                         field="reference") from None
    try:
        if len(given) != 3:
            raise ValueError
        parts = [np.broadcast_to(v, t.shape) for v in given]
    except ValueError:  # (the MPC's preview words it alike)
        shapes = ", ".join(str(v.shape) for v in given)
        raise InputError(f"reference: at(t) of {t.size} times gave (r, r', r'') of shapes {shapes}; expected arrays "
                         f"of t's shape ({t.size},) or scalars", field="reference") from None
    ok = np.isfinite(parts[0]) & np.isfinite(parts[1]) & np.isfinite(parts[2])
    if not ok.all():
        k = int(np.argmin(ok))
        r_k, rd_k, rdd_k = (float(v[k]) for v in parts)
        raise InputError(f"reference: not finite at t = {t[k]:.6g} s: (r, r', r'') = ({r_k:.6g}, {rd_k:.6g}, "
                         f"{rdd_k:.6g}) [rad, rad/s, rad/s^2] (and at {int(np.count_nonzero(~ok)) - 1} more samples)",
                         field="reference")
    return np.array(parts[0])


def simulate_closed_loop(
    plant: Plant,
    controller: Controller,
    ref: ReferenceLike,
    duration: float,
    *,
    sensors: Sensors | None = None,
    seed: int = 0,
    x0: NDArray[np.float64] | None = None,
    compiled: bool | None = None,
    progress: Callable[[float], Any] | None = None,
) -> ClosedLoopResult:
    """Run a controller against the nonlinear plant.

    Parameters
    ----------
    plant : Plant
        The true plant (its backlash may differ from the controller's estimate).
    controller : Controller
        Reset before the run.
    ref : Reference
        Load-angle reference and load-torque disturbance.
    duration : float
        Simulated time, (0, 1e5] [s], at least one sample.
    sensors : Sensors, optional
        Encoders (default: ideal). A controller that uses the load encoder gets an ideal one if none is
        given.
    seed : int
        Seed of the sensor-noise generator (results are deterministic for a seed).
    x0 : ndarray, optional
        Initial state (default: at rest with the flanks centred, ``s = 0``).
    compiled : bool, optional
        Force the compiled or the Python kernel.
    progress : callable, optional
        Called with the fraction done about a hundred times.

    Returns
    -------
    ClosedLoopResult

    Raises
    ------
    InputError
        If ``plant`` is not a Plant, ``ref`` not a reference, ``controller`` not a controller, ``sensors`` not a
        :class:`~gearctl.params.Sensors`, ``duration`` or ``seed`` out of range or shorter than one sample, the
        run's output would not fit in memory (:func:`loop_samples`), ``x0`` not a state of the plant,
        ``progress`` not callable, or the controller reads the load encoder and ``sensors`` say the servo has
        none.
    SimulationError
        If the loop diverges or the plant state becomes NaN; ``error.result`` holds the run so far.
    """
    plant = check_plant(plant)
    if not all(hasattr(ref, a) for a in ("at", "load_disturbance")):
        raise InputError(f"ref = {ref!r} is not a reference: expected a gearctl.reference(...) "
                         "(sine, step, ramp or move)", field="ref")
    check_controller(controller)
    if sensors is not None and not isinstance(sensors, Sensors):
        raise InputError(f"sensors = {sensors!r} is not a Sensors: expected the model's (model.sensors) or None "
                         "(ideal encoders)", field="sensors")
    Ts = controller.Ts
    n = loop_samples(plant, controller, duration, seed)
    sensors = sensors or Sensors()
    sensors.check_controller(controller)
    enc_m = Encoder(sensors.motor_encoder_cpr, sensors.motor_noise)
    enc_l = Encoder(sensors.load_encoder_cpr, sensors.load_noise)
    rng = np.random.default_rng(seed)
    check_progress(progress)
    kn = Kernel(plant, np.zeros(plant.nx) if x0 is None else x0, dt=Ts, compiled=compiled)  # checks x0 by name
    x0 = np.array(kn.x0, dtype=float)
    w = plant.nx // 2
    controller.reset()
    t = np.arange(n + 1) * Ts
    tl_list = t.tolist()
    r = _reference_samples(ref, t)
    lim = plant.torque_limit
    tl = plant.load_torque
    use_load = controller.uses_load_encoder
    tick = max(1, n // 100)
    status, last, message = 0, n, "ok"
    xk = kn._x
    advance, step, read_m, read_l = kn.advance, controller.step, enc_m.read, enc_l.read
    disturbance = ref.load_disturbance
    # per-sample records as Python lists (cheaper than numpy element writes); arrays at the end
    xs_l: list[list[float]] = [list(x0)]
    modes = kn._mode
    mode_l = [modes.tolist()]
    u_l: list[float] = []
    cmd_l: list[float] = []
    ym_l: list[float] = []
    yl_l: list[float] = []
    nan = math.nan
    wall0 = time.perf_counter()
    for i in range(n):
        x = xs_l[-1]
        ti = tl_list[i]
        y1 = read_m(x[0], rng)
        y2 = read_l(x[w - 1], rng) if use_load else nan
        c = step(ti, y1, y2 if use_load else None, ref)
        if math.isfinite(c):
            ui = c if -lim <= c <= lim else math.copysign(lim, c)
        else:  # keep what the controller asked for in `command`; apply zero torque
            ui = 0.0
            controller.fallbacks.append({"t": ti, "reason": f"non-finite command {c!r}, zero torque"})
        ym_l.append(y1)
        yl_l.append(y2)
        cmd_l.append(c)
        u_l.append(ui)
        status = advance(ui, tl + disturbance(ti), Ts)
        xn = xk.tolist()
        xs_l.append(xn)
        mode_l.append(modes.tolist())
        if status != 0:
            last, message = i + 1, kn.run_message(status)
            break
        if max(map(abs, xn[w:])) >= DIVERGENCE_LIMIT or xn[w] != xn[w]:  # (a NaN fails the second test)
            last, message = i + 1, f"diverged: |omega| > {DIVERGENCE_LIMIT:.0e} rad/s at t = {t[i + 1]:.4g} s"
            break
        if progress is not None and i % tick == 0:
            progress(i / n)
    xs = np.array(xs_l).T
    mode = np.sign(np.array(mode_l).T)  # the solver's +-2 (no_pull, overlapping without load) are contact too
    mode = mode[0] if mode.shape[0] == 1 else mode
    u = np.array([*u_l, u_l[-1]])
    cmd = np.array([*cmd_l, cmd_l[-1]])
    ym = np.array([*ym_l, enc_m.read(xs[0, -1], rng)])
    yl = np.array([*yl_l, enc_l.read(xs[w - 1, -1], rng) if use_load else nan])
    wall = time.perf_counter() - wall0
    sl = slice(0, last + 1)
    return loop_result(plant, controller, ref, kn, message, wall, t=t[sl], x=xs[:, sl], reference=r[sl],
                       torque=u[sl], command=cmd[sl], y_motor=ym[sl], y_load=yl[sl], mode=mode[..., sl])


def loop_result(plant: Plant, controller: Controller, ref: ReferenceLike, kn: Kernel, message: str, wall: float,
                **samples: Any) -> ClosedLoopResult:
    """The :class:`ClosedLoopResult` of a finished loop (the Python one here, or the compiled batch loop): the
    per-sample arrays given, the kernel's events, the controller's solve times and fallbacks.

    Parameters
    ----------
    plant : Plant
        The simulated plant.
    controller : Controller
        The controller that ran (its ``solve_times``, ``fallbacks``, ``describe()`` and ``overruns`` are read).
    ref : ReferenceLike
        The reference (its ``settle`` [s] where it has one, else 0).
    kn : Kernel
        The plant kernel that integrated the run (its ``event_log`` and ``counts``).
    message : str
        ``"ok"``, or why the run stopped.
    wall : float
        Wall-clock time of the run [s].
    **samples
        The per-sample arrays, by :class:`ClosedLoopResult` field: ``t``, ``x``, ``reference``, ``torque``,
        ``command``, ``y_motor``, ``y_load``, ``mode``.

    Returns
    -------
    ClosedLoopResult

    Raises
    ------
    SimulationError
        Unless ``message`` is ``"ok"``; ``error.result`` holds the run so far.
    """
    res = ClosedLoopResult(
        **samples, event_log=kn.event_log, counts=kn.counts,
        solve_times=np.asarray(controller.solve_times, dtype=float),
        fallbacks=list(controller.fallbacks), plant=plant, controller=controller.describe(),
        success=message == "ok", message=message, wall_time=wall,
        settle=getattr(ref, "settle", 0.0),  # a reference of one's own (at, load_disturbance) need not have one
        overruns=getattr(controller, "overruns", 0),
    )
    if not res.success:
        raise SimulationError(f"closed loop failed: {message}", result=res)
    return res
