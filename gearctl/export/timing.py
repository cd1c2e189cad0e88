"""Speed of the exported controllers, for ``gearctl perf``'s ``export`` section.

- The whole MPC step in C: ``make bench`` in an exported folder (the recorded 3 s sine and move, replayed
  until a second has passed), median and 99th percentile per step.
- The same step called from Python through the SIL path (:class:`~gearctl.export.sil.ExportedController` in
  gearctl's closed loop, 3 s sine), beside the Python MPC's whole step in the same loop.
- The compiled batch loop (:func:`~gearctl.export.batch.run_compiled`) against :func:`gearctl.runs.execute`:
  CPU time per 1 s run of the benchmark servo, per linear controller.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["export_timing", "bench_folder", "step_times", "batch_timing"]


def bench_folder(folder: str | Path, *, timeout: float = 300.0) -> dict[str, Any] | None:
    """``make bench`` in an exported folder: its JSON line (``step_median``, ``step_p99``, ``step_max`` [s],
    ``steps``), or None where ``make`` or a C compiler is missing or the build fails.

    Parameters
    ----------
    folder : str or Path
        An exported folder (with its ``Makefile``).
    timeout : float
        Longest wait for ``make`` [s] (default 300); past it the result is None.

    Returns
    -------
    dict or None
        The last JSON line ``make bench`` printed.
    """
    if shutil.which("make") is None:
        return None
    try:
        proc = subprocess.run(["make", "-s", "-C", str(folder), "bench"], capture_output=True, text=True,
                              timeout=timeout)
    except (OSError, subprocess.SubprocessError):
        return None
    if proc.returncode != 0:
        return None
    for line in reversed(proc.stdout.splitlines()):
        if line.startswith("{"):
            return json.loads(line)
    return None


def step_times(controller: Any, plant: Any, sensors: Any, duration: float = 3.0) -> np.ndarray:
    """Wall time of each ``controller.step`` in gearctl's closed loop on the sine [s].

    Parameters
    ----------
    controller : Controller
        The controller to time; its ``step`` is wrapped for the run (an instance attribute, deleted after).
    plant : Plant
        The simulated plant.
    sensors : Sensors or None
        The encoders.
    duration : float
        Simulated time of the catalog sine (:func:`gearctl.reference`) [s] (default 3).

    Returns
    -------
    ndarray
        One wall time per step [s].
    """
    from ..closedloop import simulate_closed_loop
    from ..references import reference

    inner = controller.step
    times: list[float] = []
    perf = time.perf_counter

    def timed(*args: Any) -> float:
        t0 = perf()
        u = inner(*args)
        times.append(perf() - t0)
        return u

    controller.step = timed
    try:
        simulate_closed_loop(plant, controller, reference("sine"), duration, sensors=sensors)
    finally:
        del controller.step
    return np.asarray(times)


def _cpu_per_run(fn: Callable[[Any], Any], run: Any, repeats: int) -> float:
    fn(run)  # designs, compiles, warms the caches
    ts = []
    for _ in range(repeats):
        c0 = time.process_time()
        fn(run)
        ts.append(time.process_time() - c0)
    return float(np.median(ts))


def batch_timing(controllers: tuple[str, ...] = ("pid", "reversal_offset", "deadzone_inverse"), *,
                 model: str = "shing1993_servo", duration: float = 1.0, repeats: int = 15) -> dict[str, Any]:
    """CPU time of one run in the compiled batch loop and through :func:`gearctl.runs.execute` (median of ``repeats``).

    Parameters
    ----------
    controllers : tuple of str
        Catalog controller names (default the PID, the reversal offset and the dead-zone inverse).
    model : str
        Catalog model name (default ``shing1993_servo``).
    duration : float
        Simulated time of each run on the catalog sine [s] (default 1).
    repeats : int
        Timed runs per path, after one untimed (default 15).

    Returns
    -------
    dict
        controller -> {``per_run_s``, ``execute_per_run_s`` [s], ``speedup``, ``equal`` (the two results'
        metrics, wall time left out, agree exactly), ``duration`` [s], ``model``}.
    """
    from ..runs import execute, make_run
    from .batch import run_compiled

    out = {}
    for c in controllers:
        run = make_run(model, c, reference_kind="sine", duration=duration)
        a, b = execute(run), run_compiled(run)
        ma, mb = (dict(r.metrics.as_dict()) if r.metrics is not None else {} for r in (a, b))
        for m in (ma, mb):
            m.pop("wall_time", None)
        t_c = _cpu_per_run(run_compiled, run, repeats)
        t_e = _cpu_per_run(execute, run, repeats)
        out[c] = {"per_run_s": t_c, "execute_per_run_s": t_e, "speedup": t_e / t_c, "equal": ma == mb,
                  "duration": duration, "model": model}
    return out


def export_timing(*, model: str = "shing1993_servo", controller: str = "mpc", duration: float = 3.0,
                  batch: bool = True) -> dict[str, Any]:
    """Step times of an exported catalog controller in C and through the SIL path, beside the Python controller's.

    Parameters
    ----------
    model, controller : str
        Catalog names (default: the benchmark servo's MPC).
    duration : float
        Simulated time of the sine the SIL and Python steps are timed on [s].
    batch : bool
        Also time the compiled batch loop (:func:`batch_timing`).

    Returns
    -------
    dict
        ``step_median``, ``step_p99``, ``step_max`` [s]: the C step (``make bench``; None without ``make`` or a
        compiler); ``sil`` {``step_median``, ``step_p99``, ``step_max``, ``within_8kHz``}: the C step called from
        Python; ``python`` {``step_median``, ``step_p99``, ``step_max``}: the Python controller's step in the same
        loop; ``table_bytes``, ``state_bytes``; ``batch`` (:func:`batch_timing`) or None.
    """
    from ..catalog import load_controller, load_model
    from ..plant import build_plant
    from .emit import export_controller
    from .sil import load_exported

    m = load_model(model)
    plant = build_plant(m)
    ctrl = load_controller(controller, plant, sensors=m.sensors)
    with tempfile.TemporaryDirectory(prefix="gearctl-export-") as tmp:
        info = export_controller(ctrl, tmp, plant=plant, sensors=m.sensors, model=m.name)
        c = bench_folder(tmp)
        sil = load_exported(tmp)
        t_sil = step_times(sil, plant, m.sensors, duration)
    t_py = step_times(ctrl, plant, m.sensors, duration)

    def stats(t: np.ndarray) -> dict[str, float]:
        return {"step_median": float(np.median(t)), "step_p99": float(np.percentile(t, 99)),
                "step_max": float(np.max(t))}

    return {
        "model": model, "controller": controller, "Ts": ctrl.Ts,
        "step_median": c["step_median"] if c else None, "step_p99": c["step_p99"] if c else None,
        "step_max": c["step_max"] if c else None, "c_steps": c["steps"] if c else 0,
        "sil": {**stats(t_sil), "within_8kHz": float(np.mean(t_sil <= 125e-6)), "steps": int(t_sil.size)},
        "python": {**stats(t_py), "steps": int(t_py.size)},
        "table_bytes": info.table_bytes, "state_bytes": sil.state_bytes,
        "batch": batch_timing() if batch else None,
    }
