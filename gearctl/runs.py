"""Runs described by values: what to simulate, as data that can be pickled to a worker and reproduced.

A :class:`Run` is (true plant, controller design, reference, duration, seed, sensors): numbers, not catalog
names. :func:`make_run` builds one from the catalog (or from numbers); :func:`execute` runs it and returns
a :class:`RunResult`. The benchmark (:mod:`gearctl.bench`) and the sweeps take lists of runs; a worker
builds each distinct controller design once (:func:`design_controller` caches it per process).
"""

from __future__ import annotations

import dataclasses
import hashlib
import pickle
import threading
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, Literal, overload

import numpy as np

from .catalog import load_model, read_toml, resolve
from .closedloop import DEFAULT_TS, ClosedLoopResult, simulate_closed_loop
from .controller import Controller
from .design.registry import build_controller
from .errors import GearctlError, InputError, short_repr
from .metrics import TrackingMetrics, tracking_metrics
from .model import GearModel
from .overrides import Scale, check_keys_act, perturb_model, split_stage_key
from .params import Sensors
from .plant import Plant, build_plant
from .references import DEFAULT_DURATION, Reference, reference
from .units import DURATION, SEED

__all__ = ["Design", "Run", "RunResult", "make_run", "execute", "execute_controller", "design_controller",
           "controller_spec"]


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class Design:
    """A controller design: the controller file's content, the plant it is designed on, the estimate.

    Attributes
    ----------
    spec : mapping
        The parsed controller file.
    nominal : Plant
        The plant the controller is designed on (the model's improved plant, as in reality).
    backlash : float or None
        Backlash estimate overriding the file's and the model's [m].
    label : str
        The file's name (messages, reports).
    sensors : Sensors or None
        The model's encoders as the design knows them (the MPC's default observer noise follows them).
    """

    spec: Mapping[str, Any]
    nominal: Plant
    backlash: float | None = None
    label: str = "controller"
    sensors: Sensors | None = None

    def key(self) -> str:
        """A digest of the design (equal designs build equal controllers)."""
        return hashlib.sha256(pickle.dumps((dict(self.spec), self.nominal, self.backlash, self.label,
                                            self.sensors))).hexdigest()


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class Run:
    """One closed-loop run, as values.

    Attributes
    ----------
    plant : Plant
        The true plant.
    design : Design
        How the controller is built.
    reference : Reference
        Load-angle reference and disturbance.
    duration : float
        Simulated time [s].
    seed : int
        Sensor-noise seed.
    sensors : Sensors
        Encoders.
    realtime : bool
        Optimisation overruns fall back, as on the target.
    tags : mapping
        What the run stands for in a report (model, controller, plant kind, reference, varied values).
    """

    plant: Plant
    design: Design
    reference: Reference
    duration: float
    seed: int = 0
    sensors: Sensors = dataclasses.field(default_factory=Sensors)
    realtime: bool = False
    tags: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        DURATION.check("duration", self.duration)
        SEED.check("seed", self.seed)

    def __getitem__(self, key: str) -> Any:
        """A tag (``run["plant"]``) or one of the scalar fields (``duration``, ``seed``, ``realtime``)."""
        if key in self.tags:
            return self.tags[key]
        if key in ("duration", "seed", "realtime"):
            return getattr(self, key)
        raise KeyError(key)


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class RunResult:
    """What a run gave: its figures or its failure, and a short error trace for plots.

    Attributes
    ----------
    run : Run
    ok : bool
    message : str
        ``"ok"`` or the error.
    metrics : TrackingMetrics or None
        Figures (of the partial run for a failure, where there is one).
    controller : dict
        The controller's settings (:meth:`Controller.describe`).
    trace_t, trace_error : ndarray
        The load-angle error, decimated to at most ~600 points.
    """

    run: Run
    ok: bool
    message: str
    metrics: TrackingMetrics | None
    controller: dict[str, Any]
    trace_t: np.ndarray
    trace_error: np.ndarray


#: Designed controllers per thread: a controller holds the state of the run it is in, so two threads of one
#: process (a Dask worker started with ``--nthreads 2`` or more) must not share one.
_LOCAL = threading.local()


def design_controller(design: Design, progress: Callable[[float], Any] | None = None) -> Controller:
    """The controller of ``design``, built once per process and thread (then reset before each run); ``progress`` is
    called with the fraction of the design done where it is built here (see :func:`build_controller`).

    Parameters
    ----------
    design : Design
        The controller file, the plant, the estimate.
    progress : callable, optional
        Called with the fraction of the design done (only where the controller is built, not when cached).

    Returns
    -------
    Controller
        The cached controller (the same object on every call with an equal design; the caller resets it).

    Raises
    ------
    InputError
        For a controller file the design refuses (:func:`~gearctl.design.registry.build_controller`).
    """
    designs: dict[str, Controller] | None = getattr(_LOCAL, "designs", None)
    if designs is None:
        designs = _LOCAL.designs = {}
    key = design.key()
    ctrl = designs.get(key)
    if ctrl is None:
        if len(designs) > 64:  # a sweep over estimates builds many: keep the cache bounded
            designs.clear()
        ctrl = build_controller(dict(design.spec), design.nominal, path=design.label, backlash=design.backlash,
                                sensors=design.sensors, progress=progress)
        designs[key] = ctrl
    return ctrl


def controller_spec(name_or_path: str | Path) -> tuple[dict[str, Any], str]:
    """A controller file's content and its path label.

    Parameters
    ----------
    name_or_path : str or Path
        A catalog controller name or a path to a controller file.

    Returns
    -------
    spec : dict
        The parsed file.
    label : str
        The file's path.

    Raises
    ------
    InputError
        For an unknown name, a missing file, or a file that is not readable TOML.
    """
    path = resolve(name_or_path, "controllers")
    return read_toml(path), str(path)


def true_model(name: str | Path, model: GearModel, overrides: Mapping[str, Any], plant: str = "improved") -> GearModel:
    """The model ``name`` (already loaded as ``model``) with ``overrides`` (``--set``): read from the file again, or,
    where a value is a factor of the nominal one (:class:`~gearctl.overrides.Scale`, ``--set backlash=1.5x``), each
    stage's own value scaled, and a key of one stage (``--set stage2.backlash=3e-5``) that stage's alone. A key the
    true ``plant`` does not read is refused (:func:`~gearctl.overrides.check_keys_act`)."""
    check_keys_act(overrides, plant, model)
    if any(isinstance(v, Scale) or split_stage_key(k)[0] is not None for k, v in overrides.items()):
        return perturb_model(model, overrides)  # a factor, or one stage's value: from the loaded model
    return load_model(name, **overrides)


def unholdable_load_step(plant: Plant, ref: Reference) -> str | None:
    """A warning when the reference's load-torque step reaches what the motor can put on the load, else None.

    The most torque the motor puts on the load shaft is ``gear_ratio x torque_limit`` [N m]; a step as large
    (nothing left to stop the load once it moves) or larger drives the load away under any controller (the
    benchmark's 0.5 N m step on a servo of a few mN m). The step adds to the model's own ``load_torque``, so
    the two are held together: a 0.5 N m step on a load already under 0.3 N m of gravity the same way needs
    0.8 N m (a review's servo holding 0.76 ran off unexplained).
    """
    hold = plant.gear_ratio * plant.torque_limit
    step = float(getattr(ref, "disturbance", 0.0))
    static = float(getattr(plant, "load_torque", 0.0))
    total = abs(step + static)
    # a step equal to what the motor gives (to rounding of the ratio) leaves nothing to stop the load once the
    # step has set it moving: a speed-up train of ratio 1 and a 0.5 N m motor ran off 8 rad under every controller
    if not (step != 0.0 and total >= hold * (1.0 - 1e-9) and np.isfinite(total)):
        return None
    head = f"the reference's load step, {abs(step):g} N m,"
    if static != 0.0:
        head = (f"the reference's load step, {abs(step):g} N m, on top of the model's load_torque "
                f"({static:g} N m), {total:g} N m in all,")
    if total <= hold:
        return (f"{head} equals the torque the motor can put on the load (ratio x torque_limit = {hold:.3g} N m): "
                "once the step sets the load moving, no torque is left to stop it, so no controller can hold it")
    return (f"{head} is {total / hold:.3g} times the torque the motor can put on "
            f"the load (ratio x torque_limit = {hold:.3g} N m): no controller can hold it")


def unholdable_load_torque(plant: Plant) -> str | None:
    """A warning when the model's constant ``load_torque`` reaches what the motor can put on the load, else None.

    The motor puts at most ``gear_ratio x torque_limit`` [N m] on the load shaft; a constant load torque as large
    drives the load away under any controller and on every reference (a review's gravity servo with 6 N m on a
    ratio-5, 1 N m drive ran 145 rad off on the sine, and ``track`` said only that the loop did not follow).
    """
    hold = plant.gear_ratio * plant.torque_limit
    static = float(getattr(plant, "load_torque", 0.0))
    if not (static != 0.0 and np.isfinite(hold) and abs(static) >= hold * (1.0 - 1e-9)):
        return None
    return (f"[servo] load_torque = {static:g} N m is {abs(static) / hold:.3g} times the torque the motor can put on "
            f"the load (ratio x torque_limit = {hold:.3g} N m): no controller can hold it, the load runs away; "
            f"expected |load_torque| below {hold:.3g} N m (a larger torque_limit or ratio)")


def make_run(model: str | Path, controller: str | Path, *, plant: str = "improved", reference_kind: str = "sine",
             duration: float | None = None, seed: int = 0, backlash: float | None = None,
             estimate: float | None = None, realtime: bool = False, design_plant: str = "improved",
             tags: Mapping[str, Any] | None = None, overrides: Mapping[str, Any] | None = None) -> Run:
    """A run from catalog names (the CLI's ``track``): the controller designed on the model's plant.

    Parameters
    ----------
    model, controller : str or Path
        Catalog names or paths.
    plant : str
        True plant kind (``improved``, ``yang-sun``, ``tvms``).
    reference_kind : str
        ``sine``, ``step``, ``ramp`` or ``move``.
    duration : float, optional
        Simulated time [s] (default per reference).
    seed : int
        Sensor-noise seed.
    backlash : float, optional
        Changes the model's backlash (plant and the default estimate; 0: the backlash-free plant).
    estimate : float, optional
        The controller's backlash estimate, if it should differ from the model's.
    realtime : bool
        Overruns fall back.
    design_plant : str
        Plant kind the controller is designed on.
    tags : mapping, optional
        Report labels (default: model, controller, plant, reference).
    overrides : mapping, optional
        Model keys changed on the true plant only (``gearctl track --set KEY=VALUE``): the controller is still
        designed on the unchanged model, as in reality.

    Raises
    ------
    InputError
        ``backlash`` given beside a backlash key in ``overrides`` (two values for one plant); an unknown model,
        controller, plant or reference, or a bad value (from the loaders).
    """
    keys = [k for k in (overrides or {}) if k == "backlash" or str(k).endswith(".backlash")]
    if backlash is not None and keys:
        # applied after the overrides, backlash dropped theirs without a word (h3's review, as at the command line)
        raise InputError(f"backlash = {backlash!r} and overrides[{keys[0]!r}]: both set the true plant's backlash "
                         "(backlash the model's, the design's included; overrides the true plant's alone): give one; "
                         "for a design estimate other than the true backlash use estimate= with overrides",
                         field="backlash")
    m = load_model(model)
    m_true = true_model(model, m, overrides, plant) if overrides else m
    true = build_plant(m_true, plant, backlash=backlash)
    nominal = build_plant(m, design_plant, backlash=backlash)
    spec, label = controller_spec(controller)
    ref = reference(reference_kind)
    dur = duration if duration is not None else DEFAULT_DURATION[reference_kind]
    design = Design(spec=spec, nominal=nominal, backlash=estimate, label=label, sensors=m.sensors)
    return Run(plant=true, design=design, reference=ref, duration=dur, seed=seed, sensors=m_true.sensors,
               realtime=realtime,
               tags=dict(tags) if tags is not None else {"model": m.name, "controller": Path(label).stem,
                                                         "plant": plant, "reference": reference_kind})


def _trace(res: ClosedLoopResult) -> tuple[np.ndarray, np.ndarray]:
    step = max(1, res.t.size // 600)
    return res.t[::step].copy(), res.error[::step].copy()


def run_sample_time(run: Run) -> float:
    """The sample time [s] of ``run``'s controller as its file gives it, before the design (the catalog's 1 ms when
    it gives none, or a bad one, which is the design's error): what a run is sized at (``bench``)."""
    ts = (run.design.spec or {}).get("sample_time", DEFAULT_TS)
    ok = isinstance(ts, int | float) and not isinstance(ts, bool) and ts > 0
    return float(ts) if ok else DEFAULT_TS


def check_run(run: Any) -> Run:
    """``run`` itself if it is a :class:`Run`, else an :class:`InputError` naming ``run``."""
    if not isinstance(run, Run):
        raise InputError(f"run = {short_repr(run)} is not a Run: expected gearctl.make_run(model, controller, ...)",
                         field="run")
    return run


@overload
def execute(run: Run, *, keep: Literal[False] = ..., progress: Callable[[float], Any] | None = None) -> RunResult: ...
@overload
def execute(run: Run, *, keep: Literal[True], progress: Callable[[float], Any] | None = None,
            ) -> tuple[RunResult, ClosedLoopResult | None]: ...
@overload
def execute(run: Run, *, keep: bool, progress: Callable[[float], Any] | None = None,
            ) -> RunResult | tuple[RunResult, ClosedLoopResult | None]: ...


def execute(run: Run, *, keep: bool = False, progress: Callable[[float], Any] | None = None,
            ) -> RunResult | tuple[RunResult, ClosedLoopResult | None]:
    """Run one closed loop; a failure is a result too, never an exception.

    Parameters
    ----------
    run : Run
    keep : bool
        Also return the whole :class:`ClosedLoopResult` (None for a run that failed before it started).
    progress : callable, optional
        Called with the fraction of the closed loop done (``simulate_closed_loop``'s ``progress``).

    Returns
    -------
    RunResult, or (RunResult, ClosedLoopResult or None) with ``keep``

    Raises
    ------
    InputError
        If ``run`` is not a :class:`Run` (from :func:`make_run`): not a run that failed, a call that is wrong.
    """
    check_run(run)
    try:
        ctrl = design_controller(run.design)
    except GearctlError as exc:
        out = RunResult(run=run, ok=False, message=str(exc), metrics=None, controller={}, trace_t=np.zeros(0),
                        trace_error=np.zeros(0))
        return (out, None) if keep else out
    return execute_controller(run, ctrl, keep=keep, progress=progress)


@overload
def execute_controller(run: Run, ctrl: Controller, *, simulate: Callable[..., ClosedLoopResult] | None = None,
                       keep: Literal[False] = ..., progress: Callable[[float], Any] | None = None) -> RunResult: ...
@overload
def execute_controller(run: Run, ctrl: Controller, *, simulate: Callable[..., ClosedLoopResult] | None = None,
                       keep: Literal[True], progress: Callable[[float], Any] | None = None,
                       ) -> tuple[RunResult, ClosedLoopResult | None]: ...
@overload
def execute_controller(run: Run, ctrl: Controller, *, simulate: Callable[..., ClosedLoopResult] | None = None,
                       keep: bool, progress: Callable[[float], Any] | None = None,
                       ) -> RunResult | tuple[RunResult, ClosedLoopResult | None]: ...


def execute_controller(run: Run, ctrl: Controller, *, simulate: Callable[..., ClosedLoopResult] | None = None,
                       keep: bool = False, progress: Callable[[float], Any] | None = None,
                       ) -> RunResult | tuple[RunResult, ClosedLoopResult | None]:
    """:func:`execute` with the controller given (designed, compiled or exported) and, optionally, the loop.

    Parameters
    ----------
    run : Run
        Plant, reference, duration, sensors, seed and ``realtime`` of the run (its design is not used).
    ctrl : Controller
    simulate : callable, optional
        ``simulate(plant, ctrl, reference, duration, sensors=, seed=) -> ClosedLoopResult`` (default
        :func:`gearctl.closedloop.simulate_closed_loop`; the compiled batch loop passes its own).
    keep : bool
        Also return the whole :class:`ClosedLoopResult`.
    progress : callable, optional
        Passed to ``simulate`` as ``progress=`` (when given): called with the fraction done.
    """
    ctrl.realtime = run.realtime
    extra: dict[str, Any] = {} if progress is None else {"progress": progress}
    try:
        res = (simulate or simulate_closed_loop)(run.plant, ctrl, run.reference, run.duration, sensors=run.sensors,
                                                 seed=run.seed, **extra)
        ok, message = True, "ok"
    except GearctlError as exc:
        part = getattr(exc, "result", None)
        if not isinstance(part, ClosedLoopResult) or part.t.size < 2:
            out = RunResult(run=run, ok=False, message=str(exc), metrics=None, controller=ctrl.describe(),
                            trace_t=np.zeros(0), trace_error=np.zeros(0))
            return (out, None) if keep else out
        res, ok, message = part, False, str(exc)
    t, e = _trace(res)
    out = RunResult(run=run, ok=ok, message=message, metrics=tracking_metrics(res), controller=ctrl.describe(),
                    trace_t=t, trace_error=e)
    return (out, res) if keep else out
