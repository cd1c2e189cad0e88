"""Speed benchmarks: gearctl's simulator against python-control's ``input_output_response``.

Each figure is a ratio measured in the same run on the same plant and scenario, with each solver's
error against an independent tight reference (:func:`gearctl.oracle.reference_solution`):

- ``free``: the report's free vibration (``omega1(0) = 50 rad/s``) on ``shing1993``, outputs every 10 µs;
- ``pd``: a 1 kHz sampled PD position loop on a 1 Hz sine, on ``shing1993_servo`` (zero-order hold).

Error is the largest ``|s - s_ref|`` over the outputs, as a fraction of the backlash ``b``.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .catalog import load_model
from .kernel import Kernel
from .oracle import reference_solution
from .plant import Plant, build_plant, plant_nlsys
from .simulate import simulate

__all__ = ["sim_speed", "pd_gains", "mpc_timing", "bench_wall_time", "loop_speed", "standstill_cost", "train_speed"]


#: A sampled control law ``f(i, x) -> (xi_motor, xi_load)``; ``x`` is the state, a list (the kernel's loop) or an
#: array (the reference solutions).
SampledLaw = Callable[[int, Sequence[float] | NDArray[np.float64]], tuple[float, float]]


def pd_gains(plant: Plant, bandwidth_hz: float = 20.0) -> tuple[float, float]:
    """Motor-side PD gains ``(Kp, Kd)`` [N m/rad, N m s/rad] for a rigid-body loop of the given bandwidth.

    ``Kp = J wc^2``, ``Kd = 1.4 J wc`` with ``J = J1 + J2 / N^2`` and ``wc = 2 pi bandwidth_hz``.

    Parameters
    ----------
    plant : Plant
        The plant (its ``J1``, ``J2`` and gear ratio).
    bandwidth_hz : float
        The loop's bandwidth [Hz] (default 20).

    Returns
    -------
    tuple of float
        ``(Kp, Kd)``.
    """
    N = plant.gear_ratio
    J = plant.J1 + plant.J2 / N**2
    wc = 2 * math.pi * bandwidth_hz
    return J * wc**2, 2 * 0.7 * J * wc


def _pd_controller(plant: Plant, Ts: float) -> SampledLaw:
    Kp, Kd = pd_gains(plant)
    N = plant.gear_ratio
    lim = plant.torque_limit

    def ctrl(i: int, x: Sequence[float] | NDArray[np.float64]) -> tuple[float, float]:
        r = 0.1 * math.sin(2 * math.pi * 1.0 * i * Ts) * N  # motor-side reference of a 0.1 rad, 1 Hz load sine
        u = Kp * (r - x[0]) - Kd * x[2]
        return (min(max(u, -lim), lim), 0.0)

    return ctrl


def _run_gearctl(plant: Plant, x0: np.ndarray, n: int, dt: float,
                 ctrl: SampledLaw | None) -> np.ndarray:
    if ctrl is None:  # open loop: the user's path, one kernel call for the whole run
        return simulate(plant, x0, n * dt, dt=dt).x
    kn = Kernel(plant, x0, dt=dt)
    advance, xk, tl = kn.advance, kn._x, plant.load_torque
    xs = [list(x0)]
    for i in range(n):  # the loop of closedloop.simulate_closed_loop, with the PD law inlined
        u1, u2 = ctrl(i, xs[-1])
        status = advance(u1, u2 + tl, dt)
        if status:
            raise RuntimeError(kn.run_message(status))
        xs.append(xk.tolist())
    return np.array(xs).T


def _run_python_control(plant: Plant, x0: np.ndarray, n: int, dt: float,
                        ctrl: SampledLaw | None,
                        solve_ivp_kwargs: dict[str, Any]) -> np.ndarray:
    import control as ct

    sys = plant_nlsys(plant)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # python-control warns about solver accuracy; that is measured
        if ctrl is None:
            T = np.arange(n + 1) * dt
            r = ct.input_output_response(sys, T, 0.0, X0=x0, solve_ivp_kwargs=solve_ivp_kwargs)
            return np.asarray(r.states)
        out = np.empty((4, n + 1))
        out[:, 0] = x0
        x = x0
        for i in range(n):
            u = ctrl(i, x)
            r = ct.input_output_response(sys, [0.0, dt], np.array([[u[0], u[0]], [u[1], u[1]]]), X0=x,
                                         solve_ivp_kwargs=solve_ivp_kwargs)
            x = np.asarray(r.states)[:, -1]
            out[:, i + 1] = x
        return out


def sim_speed(scenario: str = "free", *, duration: float | None = None,
              python_control_duration: float | None = None) -> dict[str, Any]:
    """Simulated seconds per wall second of gearctl and python-control, with their errors.

    Parameters
    ----------
    scenario : str
        ``"free"`` or ``"pd"`` (see module docstring).
    duration : float, optional
        Simulated time for gearctl [s] (default 0.02 for free, 5 for pd; errors over the first 0.5 s).
    python_control_duration : float, optional
        Simulated time for python-control (it is slow; default 0.02 for free, 0.05 for pd) [s].

    Returns
    -------
    dict
        ``gearctl_sim_per_wall``, ``python_control_sim_per_wall`` (default tolerances),
        ``python_control_tight_sim_per_wall`` (rtol 1e-10), ``ratio`` (gearctl over python-control at
        default tolerances), ``ratio_equal_accuracy`` (over python-control at rtol 1e-10),
        ``gearctl_error``, ``python_control_error``, ``python_control_tight_error`` (max ``|s - s_ref| / b``).
        Each speed is the median of repeated runs (at least three, at least 0.5 s), after one untimed run of
        each solver (the kernel's compilation, python-control's import and first call).
    """
    if scenario == "free":
        plant = build_plant(load_model("shing1993"))
        dt, T = 1e-5, duration or 0.02
        Tpc = python_control_duration or T
        x0 = np.array([0.0, 0.0, 50.0, 0.0])
        ctrl = None
    elif scenario == "pd":
        plant = build_plant(load_model("shing1993_servo"))
        dt, T = 1e-3, duration or 5.0
        Tpc = python_control_duration or 0.05
        x0 = np.zeros(4)
        ctrl = _pd_controller(plant, dt)
    else:
        raise ValueError(scenario)
    n, npc = round(T / dt), round(Tpc / dt)
    # reference (independent: solve_ivp + events, tight) over the first half second at most: errors are
    # compared there, speed over the whole run
    n_ref = min(max(npc, 1), n, round(0.5 / dt)) if ctrl is not None else n
    ref, _ = reference_solution(plant, x0, np.arange(max(n_ref, npc) + 1, dtype=np.float64) * dt,
                                torque=ctrl if ctrl is not None else (0.0, 0.0), rtol=1e-12)
    s_ref = plant.rb1 * ref[0] - plant.rb2 * ref[1]

    def err(x: np.ndarray) -> float:
        s = (plant.rb1 * x[0] - plant.rb2 * x[1])[: s_ref.size]
        return float(np.max(np.abs(s - s_ref[: s.size])) / plant.backlash)

    def median_wall(fn: Callable[[], np.ndarray]) -> tuple[float, np.ndarray]:
        walls: list[float] = []
        start = time.perf_counter()
        while len(walls) < 3 or time.perf_counter() - start < 0.5:  # the median of repeats: this machine is noisy
            t0 = time.perf_counter()
            x = fn()
            walls.append(time.perf_counter() - t0)
        return float(np.median(walls)), x

    tight = {"rtol": 1e-10, "atol": 1e-13}
    # Each side's one-time costs outside the timing, and the same statistic for both: the kernel is compiled or
    # loaded here, python-control imported and its solvers' first call made (timed, they had added 0.5-1 s to
    # python-control's first 0.2 s run and put the free vibration's ratio at 753x for 180-200x warm).
    Kernel(plant, x0, dt=dt)
    _run_python_control(plant, x0, min(npc, 10), dt, ctrl, {})
    _run_python_control(plant, x0, min(npc, 10), dt, ctrl, tight)
    wall_g, xg = median_wall(lambda: _run_gearctl(plant, x0, n, dt, ctrl))
    wall_pc, xpc = median_wall(lambda: _run_python_control(plant, x0, npc, dt, ctrl, {}))
    wall_pt, xpt = median_wall(lambda: _run_python_control(plant, x0, npc, dt, ctrl, tight))
    g_rate, pc_rate, pt_rate = T / wall_g, Tpc / wall_pc, Tpc / wall_pt
    return {
        "scenario": scenario,
        "model": "shing1993" if scenario == "free" else "shing1993_servo",
        "duration": T,
        "python_control_duration": Tpc,
        "output_interval": dt,
        "gearctl_sim_per_wall": g_rate,
        "python_control_sim_per_wall": pc_rate,
        "python_control_tight_sim_per_wall": pt_rate,
        "ratio": g_rate / pc_rate,
        "ratio_equal_accuracy": g_rate / pt_rate,
        "gearctl_error": err(xg),
        "python_control_error": err(xpc),
        "python_control_tight_error": err(xpt),
    }


def mpc_timing(*, duration: float = 3.0, controller: str = "mpc") -> dict[str, Any]:
    """Solve time per step of the catalog MPC on the default benchmark's sine (shing1993_servo, improved).

    Parameters
    ----------
    duration : float
        Simulated time [s] (default 3).
    controller : str
        Catalog MPC controller name (default ``"mpc"``).

    Returns
    -------
    dict
        ``median``, ``p99``, ``max`` [s] of the solver alone, ``overhead_median`` [s] (the rest of the
        controller step: observer, data copies, Python), ``step_p99`` [s] (whole controller step),
        ``budgets`` {``1kHz``, ``4kHz``, ``8kHz``: fraction of steps whose solve fits}, ``Ts`` [s],
        ``fallbacks``, ``rms_error`` [rad].
    """
    from .catalog import load_controller
    from .closedloop import simulate_closed_loop
    from .metrics import tracking_metrics
    from .references import reference

    model = load_model("shing1993_servo")
    plant = build_plant(model)
    ctrl = load_controller(controller, plant, sensors=model.sensors)
    step_times: list[float] = []
    inner = ctrl.step

    def timed_step(*args: Any) -> float:
        t0 = time.perf_counter()
        u = inner(*args)
        step_times.append(time.perf_counter() - t0)
        return u

    ctrl.step = timed_step
    res = simulate_closed_loop(plant, ctrl, reference("sine"), duration, sensors=model.sensors)
    st = np.asarray(res.solve_times)
    steps = np.asarray(step_times)
    m = tracking_metrics(res)
    return {
        "median": float(np.median(st)), "p99": float(np.percentile(st, 99)), "max": float(np.max(st)),
        "overhead_median": float(np.median(steps[: st.size] - st)) if st.size == steps.size else None,
        "step_p99": float(np.percentile(steps, 99)),
        "budgets": {name: float(np.mean(st <= b)) for name, b in (("1kHz", 1e-3), ("4kHz", 250e-6), ("8kHz", 125e-6))},
        "Ts": ctrl.Ts, "fallbacks": len(res.fallbacks), "rms_error": m["rms_error"], "steps": int(st.size),
    }


def loop_speed(model: str, controller: str = "pid", *, reference_kind: str = "sine", duration: float = 5.0,
               backlash: float | None = None, repeats: int = 5, hold: bool = False) -> dict[str, Any]:
    """Simulated seconds per wall second of a catalog closed loop (the fastest of ``repeats`` runs).

    The fastest, as :mod:`timeit` advises: every run does the same work, and a slower one measures what else the
    machine was doing (on this 2-core machine a median of three still moved by 1.5x between invocations).

    ``hold`` replaces the reference by a standstill (zero reference, no disturbance).

    Parameters
    ----------
    model : str
        Catalog model name or path.
    controller : str
        Catalog controller name or path (default ``"pid"``).
    reference_kind : str
        Reference kind (default ``"sine"``).
    duration : float
        Simulated time of each run [s] (default 5).
    backlash : float, optional
        Backlash of the true plant [m] (default: the model's).
    repeats : int
        Runs per loop, the fastest kept (default 5).
    hold : bool
        Run at standstill instead (default False).

    Returns
    -------
    dict
        ``sim_per_wall``, ``per_sample_s`` [s of wall time per controller sample] (the closed loop in Python
        around the compiled kernel, :func:`gearctl.runs.execute`); ``compiled_sim_per_wall``: the same run in the
        compiled batch loop (:func:`gearctl.export.batch.run_compiled`, the sweeps' loop; the Python loop for
        controllers it does not cover); ``model``, ``controller``, ``stages``, ``reference``, ``duration``,
        ``impacts``.
    """
    import dataclasses

    from .references import Reference
    from .runs import execute, make_run

    run = make_run(model, controller, reference_kind=reference_kind, duration=duration, backlash=backlash)
    if hold:
        run = dataclasses.replace(run, reference=Reference(kind="step", amplitude=0.0))
    from .export.batch import run_compiled

    def best_wall(fn: Any) -> tuple[float, Any]:
        walls, res = [], None
        for _ in range(repeats):
            t0 = time.perf_counter()
            res = fn(run)
            walls.append(time.perf_counter() - t0)
        return min(walls), res

    wall, last = best_wall(execute)
    wall_c, _ = best_wall(run_compiled)  # the same run, the loop in C where the controller allows it
    Ts = last.controller.get("Ts", 1e-3) if last is not None else 1e-3
    return {"model": model, "controller": controller, "stages": run.plant.n_stages,
            "reference": "hold" if hold else reference_kind, "duration": duration, "sim_per_wall": duration / wall,
            "per_sample_s": wall * Ts / duration, "compiled_sim_per_wall": duration / wall_c,
            "impacts": last.metrics.impacts if last is not None and last.metrics is not None else None}


def standstill_cost(model: str = "shing1993_servo_friction", controller: str = "pid", *,
                    duration: float = 5.0) -> dict[str, Any]:
    """Coulomb friction at standstill against motion: the same loop held at rest and on the sine.

    With stick-slip friction (events where a shaft stops or breaks away, a stuck shaft one degree of freedom
    less) a standstill costs no more than motion. Measured on the backlash-free plant, the stiff case (the
    load's friction acts through the mesh at once) that the smooth law made take minutes, and as the ISO
    230-2 test's wall time (mostly dwells at rest) with and without backlash.

    Parameters
    ----------
    model : str
        Catalog model name (default ``shing1993_servo_friction``).
    controller : str
        Catalog controller name (default ``"pid"``).
    duration : float
        Simulated time of each loop [s] (default 5).

    Returns
    -------
    dict
        ``standstill``, ``motion`` (:func:`loop_speed`), ``ratio`` (standstill's simulated s per wall s over
        motion's: >= 1 means a standstill is not dearer; the Python loop around the kernel), ``compiled_ratio``
        (the same in the compiled batch loop, where the kernel's own cost shows), ``precision``
        {``backlash_free``, ``backlash``: wall time [s] of ``gearctl precision MODEL CONTROLLER --cycles 1``}.
    """
    from .catalog import load_controller
    from .precision import precision_test

    still = loop_speed(model, controller, duration=duration, backlash=0.0, hold=True)
    moving = loop_speed(model, controller, reference_kind="sine", duration=duration, backlash=0.0)
    m = load_model(model)
    walls = {}
    for label, b in (("backlash_free", 0.0), ("backlash", None)):
        plant = build_plant(m, backlash=b)
        ctrl = load_controller(controller, plant, sensors=m.sensors)
        t0 = time.perf_counter()
        precision_test(plant, ctrl, cycles=1, sensors=m.sensors)
        walls[label] = time.perf_counter() - t0
    return {"standstill": still, "motion": moving, "ratio": still["sim_per_wall"] / moving["sim_per_wall"],
            "compiled_ratio": still["compiled_sim_per_wall"] / moving["compiled_sim_per_wall"], "precision": walls}


def train_speed(*, duration: float = 5.0) -> dict[str, Any]:
    """The 1 kHz catalog PID loop on the pair and on every catalog train: simulated s per wall s.

    Parameters
    ----------
    duration : float
        Simulated time of each loop [s] (default 5).

    Returns
    -------
    dict
        model name -> :func:`loop_speed` figures (``stages``, ``sim_per_wall``, ``per_sample_s``).
    """
    from .catalog import model_names

    out = {"shing1993_servo": loop_speed("shing1993_servo", "pid", duration=duration)}
    for name in model_names():
        if load_model(name).n_stages > 1:
            out[name] = loop_speed(name, "pid", duration=duration)
    return out


def bench_wall_time(*, jobs: int | None = None) -> dict[str, Any]:
    """Wall time of the default ``gearctl bench`` (all controllers, plants and references).

    Parameters
    ----------
    jobs : int, optional
        Worker processes, as :func:`gearctl.bench.run_bench` takes them.

    Returns
    -------
    dict
        ``wall_time`` [s], ``runs``, ``simulated_time`` [s] (all runs' together), ``jobs`` (the processes used).
    """
    from .bench import BenchSpec, run_bench

    spec = BenchSpec()
    t0 = time.perf_counter()
    result = run_bench(spec, jobs=jobs)
    wall = time.perf_counter() - t0
    sim = sum(r.get("duration", 0.0) for r in result["runs"])
    from .parallel import local_processes

    return {"wall_time": wall, "runs": len(result["runs"]), "simulated_time": sim,
            "jobs": local_processes(result["tasks"], jobs)}
