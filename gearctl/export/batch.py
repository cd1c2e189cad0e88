"""The compiled batch loop: a whole closed-loop run in C, for the sweeps (issue 15, "Throughput").

:func:`run_compiled` runs a :class:`~gearctl.runs.Run` as :func:`gearctl.runs.execute` does, with the loop of
:func:`gearctl.closedloop.simulate_closed_loop` in C (``csrc/gcx_batch.c``): the encoders, the controller's C
(the exported controllers' own code, ``csrc/gcx_pid.c``, with its parameters filled at run time from the
Python object), the torque limit and the kernel's ``gc_step`` (the very function of the kernel's compiled
library, called through its address), returning to Python only when the kernel asks (a pattern to build,
events to drain). The sensor noise is drawn beforehand with the same generator calls as the Python loop, so
the run is the Python run, bit for bit: same states, torques, events and metrics.

Controllers: ``pid``, ``reversal_offset``, ``deadzone_inverse`` (the linear ones of issue 15). Others (the
MPC, the adaptive inverse), a reference that is not gearctl's, or no C compiler: :func:`run_compiled` runs
:func:`~gearctl.runs.execute` instead, so a caller never needs to ask.
"""

from __future__ import annotations

import ctypes
import math
import time
import typing
from typing import Any, ClassVar

import numpy as np

from ..build import compile_disabled, shared_library
from ..closedloop import ClosedLoopResult, loop_result, loop_samples
from ..controller import Controller
from ..errors import GearctlError, InputError
from ..kernel import Kernel, c_structs
from ..references import Reference, move_times
from ..runs import Run, RunResult, design_controller, execute, execute_controller
from ..simulate import DIVERGENCE_LIMIT
from .kinds import KIND_IDS, kind_spec, kind_structs, source_text

__all__ = ["run_compiled", "compiled_kinds", "simulate_compiled", "batch_available"]

#: The controller kinds the batch loop runs in C.
BATCH_KINDS = ("pid", "reversal_offset", "deadzone_inverse")
_REF_KINDS = {"sine": 0, "step": 1, "ramp": 2, "move": 3}
_KSTEP = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p)


class _RefP(ctypes.Structure):
    _fields_ = [("kind", ctypes.c_int), ("trapezoid", ctypes.c_int)] + [
        (f, ctypes.c_double) for f in ("amplitude", "frequency", "start", "rate", "accel", "disturbance_time",
                                       "disturbance", "ta", "tc", "v")]


_I64 = ("n", "i", "phase", "pending", "last", "status", "diverged", "use_load", "nx", "w", "ns", "kind")


class _Loop(ctypes.Structure):
    _fields_: ClassVar[list[tuple[str, type[ctypes._SimpleCData[Any]]]]] = [
        *[(f, ctypes.c_int64) for f in _I64],
        *[(f, ctypes.c_double) for f in ("Ts", "lim", "load_torque", "div_limit", "q_m", "q_l", "noise_m", "noise_l")],
        ("z", ctypes.c_void_p), ("k_per", ctypes.c_int64), ("zi_l", ctypes.c_int64), ("ref", ctypes.c_void_p),
        ("rows", ctypes.c_void_p),
        *[(f, ctypes.c_void_p) for f in ("xs", "modes", "u", "cmd", "ym", "yl")]]


_LIB: Any = False


def _library() -> Any:
    """The runtime library (controller family + loop), built once per source; None without a compiler."""
    global _LIB
    if _LIB is not False:
        return _LIB
    _LIB = None
    if compile_disabled():
        return None
    src = "".join([
        "#include <math.h>\n#include <stdint.h>\n#include <string.h>\n",
        c_structs(),
        source_text("gcx_state.h"),
        kind_structs(["pid", "rev", "inv"]),
        source_text("gcx_common.c"),
        source_text("gcx_pid.c"),
        source_text("gcx_batch.c"),
    ])
    lib = shared_library("gearctl_batch", {"gcx_batch.c": src.encode()}, flags=("-std=c99", "-O2"))
    if lib is None:
        return None
    lib.gcx_runtime_state_size.restype = ctypes.c_long
    lib.gcx_runtime_init.restype = None
    lib.gcx_runtime_init.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p]
    lib.gcx_batch_run.restype = ctypes.c_int
    lib.gcx_batch_run.argtypes = [ctypes.c_void_p] * 6
    _LIB = lib
    return lib


def batch_available() -> bool:
    """Whether the batch loop can run here (a C compiler, the compiled kernel)."""
    from ..kernel import compiled_available

    return _library() is not None and compiled_available()


def compiled_kinds() -> tuple[str, ...]:
    """The controller kinds :func:`run_compiled` runs in C (none where the batch loop cannot be built)."""
    return BATCH_KINDS if batch_available() else ()


def _ref_struct(ref: Any) -> _RefP | None:
    """The C reference of a gearctl :class:`~gearctl.references.Reference` (None for any other object)."""
    if type(ref) is not Reference:
        return None
    r = _RefP()
    r.kind = _REF_KINDS[ref.kind]
    r.trapezoid = int(ref.profile == "trapezoid")
    for f in ("amplitude", "frequency", "start", "rate", "accel", "disturbance_time", "disturbance"):
        setattr(r, f, float(getattr(ref, f)))
    r.ta, r.tc, r.v = move_times(abs(ref.amplitude), ref.rate, ref.accel, ref.profile)
    return r


def simulate_compiled(plant: Any, controller: Controller, ref: Any, duration: float, *, sensors: Any = None,
                      seed: int = 0) -> ClosedLoopResult:
    """:func:`gearctl.closedloop.simulate_closed_loop` with the loop in C (same arguments, same result).

    Parameters
    ----------
    plant : Plant
        The true plant.
    controller : Controller
        One of :data:`BATCH_KINDS`; reset before the run.
    ref : Reference
        Load-angle reference and load-torque disturbance.
    duration : float
        Simulated time, (0, 1e5] [s], at least one sample.
    sensors : Sensors, optional
        Encoders (default: ideal).
    seed : int
        Seed of the sensor-noise generator (the Python loop's draws, in its order).

    Returns
    -------
    ClosedLoopResult

    Raises
    ------
    InputError
        For a controller the batch loop cannot run (see :data:`BATCH_KINDS`), or no compiled code; a duration or
        seed out of range or an output too large (:func:`~gearctl.closedloop.loop_samples`); a controller that
        reads the load encoder where ``sensors`` have none.
    SimulationError
        As :func:`~gearctl.closedloop.simulate_closed_loop`: diverged, or the kernel failed.
    """
    from ..params import Sensors

    lib = _library() if batch_available() else None
    spec = kind_spec(controller)
    if spec.kind not in BATCH_KINDS or lib is None:
        raise InputError(f"the compiled batch loop runs {', '.join(BATCH_KINDS)} (with a C compiler); not "
                         f"{spec.kind}", field="controller")
    Ts = controller.Ts
    n = loop_samples(plant, controller, duration, seed)
    sensors = sensors or Sensors()
    sensors.check_controller(controller)
    use_load = controller.uses_load_encoder
    kn = Kernel(plant, np.zeros(plant.nx), dt=Ts, compiled=True)
    if kn._fn is None:
        raise InputError("the compiled kernel is not available", field="controller")
    controller.reset()
    # the sensor noise: the Python loop's draws, in its order (motor, then load, per sample; a last reading)
    rng = np.random.default_rng(seed)
    nm, nl = sensors.motor_noise, sensors.load_noise
    k_per = int(nm > 0.0) + int(use_load and nl > 0.0)
    z = rng.standard_normal(k_per * (n + 1)) if k_per else np.zeros(1)
    t = np.arange(n + 1) * Ts
    keep: list[Any] = []
    params = spec.struct.fill(spec.values, keep)
    state = np.zeros(int(lib.gcx_runtime_state_size()) // 8 + 1)
    lib.gcx_runtime_init(KIND_IDS[spec.prefix], ctypes.addressof(params), state.ctypes.data)
    rs = _ref_struct(ref)
    rows = np.zeros(1)
    if rs is None:  # another kind of reference: its rows (scalar calls, as the controller makes) and disturbance
        tl_list = t.tolist()[:n]
        rows = np.concatenate([np.array([ref.at(ti) for ti in tl_list], dtype=float).ravel(),
                               np.array([ref.load_disturbance(ti) for ti in tl_list], dtype=float)])
    w, nx, ns = plant.nx // 2, plant.nx, plant.n_stages
    xs = np.zeros((n + 1, nx))
    xs[0] = kn._x
    modes = np.zeros((n + 1, ns), dtype=np.int32)
    modes[0] = kn._mode
    u, cmd, ym, yl = (np.zeros(n) for _ in range(4))
    L = _Loop()
    L.n, L.nx, L.w, L.ns, L.kind = n, nx, w, ns, KIND_IDS[spec.prefix]
    L.use_load = int(use_load)
    L.Ts, L.lim, L.load_torque, L.div_limit = Ts, plant.torque_limit, plant.load_torque, DIVERGENCE_LIMIT
    cm, cl = sensors.motor_encoder_cpr, sensors.load_encoder_cpr
    L.q_m = 2 * math.pi / cm if cm else 0.0
    L.q_l = 2 * math.pi / cl if cl else 0.0
    L.noise_m, L.noise_l = nm, nl
    L.z, L.k_per, L.zi_l = z.ctypes.data, k_per, (k_per - 1 if (use_load and nl > 0.0) else -1)
    L.ref = ctypes.addressof(rs) if rs is not None else None
    L.rows = rows.ctypes.data
    L.xs, L.modes = xs.ctypes.data, modes.ctypes.data
    L.u, L.cmd, L.ym, L.yl = u.ctypes.data, cmd.ctypes.data, ym.ctypes.data, yl.ctypes.data
    klib = typing.cast(ctypes.CDLL, kn._lib)  # compiled=True: the kernel's library is loaded
    kstep = ctypes.cast(klib.gc_step, ctypes.c_void_p).value
    args = (kstep, ctypes.addressof(kn._prm), ctypes.addressof(kn._st), ctypes.addressof(L),
            ctypes.addressof(params), state.ctypes.data)
    wall0 = time.perf_counter()
    while lib.gcx_batch_run(*args):
        L.pending = kn.finish_call(int(L.pending))
    wall = time.perf_counter() - wall0
    last = int(L.last)
    message = "ok"
    if L.status:
        status = int(L.status)
        message = kn.run_message(status)
    elif L.diverged:
        message = f"diverged: |omega| > {DIVERGENCE_LIMIT:.0e} rad/s at t = {t[last]:.4g} s"
    for i in np.flatnonzero(~np.isfinite(cmd[:last])):
        controller.fallbacks.append({"t": float(t[i]), "reason": f"non-finite command {float(cmd[i])!r}, zero torque"})
    # the last readings (the Python loop's last draws)
    zf = z[k_per * last:]
    x_end = xs[last]
    y_m = x_end[0] + nm * zf[0] if nm > 0.0 else x_end[0]
    if L.q_m:
        y_m = L.q_m * math.floor(y_m / L.q_m + 0.5)
    y_l = math.nan
    if use_load:
        y_l = x_end[w - 1] + nl * zf[k_per - 1] if nl > 0.0 else x_end[w - 1]
        if L.q_l:
            y_l = L.q_l * math.floor(y_l / L.q_l + 0.5)
    sl = slice(0, last + 1)
    mode = np.sign(modes[: last + 1].T.astype(int))
    mode = mode[0] if mode.shape[0] == 1 else mode
    r = ref.at(t)[0]
    return loop_result(plant, controller, ref, kn, message, wall, t=t[sl], x=xs[: last + 1].T.copy(),
                       reference=np.asarray(r)[sl], torque=np.append(u[:last], u[last - 1]),
                       command=np.append(cmd[:last], cmd[last - 1]), y_motor=np.append(ym[:last], y_m),
                       y_load=np.append(yl[:last], y_l), mode=mode)


def run_compiled(run: Run) -> RunResult:
    """:func:`gearctl.runs.execute` with the closed loop in C where the controller allows it (same result).

    Parameters
    ----------
    run : Run

    Returns
    -------
    RunResult
        Equal to ``execute(run)`` (the metrics to the last bit; ``wall_time`` is this run's). Runs whose
        controller is not one of :data:`BATCH_KINDS`, or where no C compiler exists, are run by
        :func:`~gearctl.runs.execute`.
    """
    try:
        ctrl = design_controller(run.design)
    except GearctlError:
        return execute(run)
    if type(run.reference) is not Reference or not _runs_in_c(ctrl):
        return execute(run)
    return execute_controller(run, ctrl, simulate=simulate_compiled)


def _runs_in_c(ctrl: Controller) -> bool:
    if not batch_available():
        return False
    try:
        return kind_spec(ctrl).kind in BATCH_KINDS
    except InputError:
        return False
