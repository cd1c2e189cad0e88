"""Robustness sweeps: one controller design against many perturbed plants, on Dask.distributed.

A designer signs off a controller only when it holds over the tolerances the servo will meet. A sweep
designs the controller ONCE on the nominal model (a :class:`~gearctl.runs.Design`) and runs it on each
perturbed plant, as in reality: Monte Carlo draws or a full grid over model keys (``backlash``,
``mesh_stiffness``, ``coulomb_friction2``, ``load_inertia``, ``load_noise``, ...) and the controller's
backlash ``estimate``.

Specs (the text after ``KEY=``; numbers in SI, a trailing ``x`` means "times the nominal value")

============================  =============================================  =================================
spec                          Monte Carlo draw                               grid of N points
============================  =============================================  =================================
``a:b``, ``uniform(a,b)``     uniform on [a, b]                              N points a..b, ends included
``loguniform(a,b)``           log-uniform on [a, b] (0 < a)                  N geometric points a..b
``normal(m,s)``               Gaussian, mean m, std s                        N equal-probability quantiles
``normal(m,s,lo,hi)``         the same truncated to [lo, hi]                 (midpoints ``(j + 1/2) / N``)
``lognormal(m,s[,lo,hi])``    ``m exp(s Z)``: median m, log-std s            likewise
``a,b,c`` (one value: fixed)  one of the values, equally likely              every value
============================  =============================================  =================================

Keys: every numeric field :func:`gearctl.catalog.load_model` accepts as an override (the fields of
:class:`~gearctl.geometry.GearPair`, :class:`~gearctl.params.MeshDynamics`, :class:`~gearctl.params.Servo`,
:class:`~gearctl.params.Sensors`; for a train an absolute value sets every stage, and a relative spec of a key whose
stages differ scales each stage's own value: its values are factors, :class:`Scale`), plus ``estimate`` (the
controller's backlash estimate [m]; ``x`` scales the nominal estimate) and ``estimate_error`` (the
estimate's relative error against each run's true backlash: ``estimate = (1 + e) b``).

Determinism: run ``i`` draws each key from ``SeedSequence([seed, i, crc32(key)])`` (one uniform number
put through the spec's quantile function, so a key's draws do not depend on which other keys vary) and
takes its sensor-noise seed from ``SeedSequence([seed, i])``. The draws are made here, before any run,
so the results are the same on one worker, on many, and after a lost worker's batch is run again.

Decisions
---------
- A drawn value outside its key's range is an error before any run, naming the run, the draw and the
  range; never clipped. Clipping would pile a fraction of the runs on the bound (a point mass the user
  did not ask for, which moves quantiles and sensitivities) and hide it. A distribution meant to stay
  in range says so: ``normal(0.2,0.05,0,inf)`` is truncated at 0 (drawn by inverse CDF, exact).
- The engine is Dask.distributed: a ``LocalCluster`` of one-thread processes sized to the machine, or a
  running scheduler (``scheduler=`` or ``DASK_SCHEDULER_ADDRESS``). Each task is a batch of runs
  (:func:`batch_size`: a task costs about 5 ms of CPU in the client and scheduler on the two-core machine,
  a 1 s run of a linear controller 10-15 ms); the shared context (nominal model, design, reference,
  2.5 kB pickled) goes by value with each batch: it survives the loss of every worker holding it, which a
  scattered copy does not, and scattering it once measured no cheaper (50 tasks: 0.23-0.26 s of client
  CPU either way).
- :func:`run_batch` is the one place where closed loops run (the compiled loop of issue 14 plugs in
  there); everything a worker returns is a small dict per run.
- A sweep that did not finish (:class:`SweepIncomplete`, :class:`SweepInterrupted`) is finished by :func:`resume`:
  planned again from its settings, it reruns the ``missing`` runs alone (seeded per run, they are the runs they
  would have been). Its settings record what must not have changed since: this gearctl (``gearctl``, version and
  code hash), its numerical libraries (``numerics``) and the model's and controller's files (``files``, SHA-256).
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import shlex
import time
import uuid
import zlib
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .catalog import load_model
from .closedloop import check_loop_duration, check_loop_memory, loop_bytes
from .errors import GearctlError, InputError
from .export.batch import BATCH_KINDS, run_compiled
from .files import json_ready
from .limits import available_memory
from .model import GearModel
from .overrides import (
    FILE_NAMES,
    MODEL_CLASSES,
    OWNER_FIELDS,
    Scale,
    check_keys_act,
    file_name_error,
    split_stage_key,
    stage_values,
)
from .overrides import perturb_model as _perturb
from .parallel import (
    CONNECT_TIMEOUT,
    WORKER_TIMEOUT,
    Engine,
    TasksInterrupted,
    check_one_cluster,
    checked,
    code_id,
    completed,
    default_workers,
    env_scheduler,
    killed_worker_text,
    local_cluster,
    local_processes,
    numerics_versions,
)
from .plant import PlantKind, build_plant
from .references import DEFAULT_DURATION, REFERENCES, Reference, reference
from .runs import Design, Run, RunResult, controller_spec, design_controller
from .units import BACKLASH, DURATION, SEED, Spec, check_number, describe_rule

__all__ = ["Vary", "SweepResult", "SweepIncomplete", "SweepInterrupted", "SweepContext", "SweepPlan", "sweep",
           "resume", "file_hashes", "plan_sweep", "run_batch", "parse_vary",
           "parse_set", "perturb_model", "Scale", "sweep_keys", "summarize", "grid_axes", "compare_grids", "sweep_perf",
           "ROW_BYTES", "KEY_BYTES", "PRECISION_BYTES", "noise_seed", "sweep_task", "check_memory", "batch_size",
           "run_cost", "default_workers",
           "SWEEP_RUNS", "GRID_POINTS", "METRICS", "FLAGS", "ISO_FIGURES", "CONNECT_TIMEOUT", "WORKER_TIMEOUT"]

#: Monte Carlo runs of one sweep.
SWEEP_RUNS = Spec(unit="1", doc="runs", low=1, high=10_000_000, integer=True)
#: Points per key of a grid.
GRID_POINTS = Spec(unit="1", doc="grid points per key", low=1, high=10_000, integer=True)
#: Memory one run's result takes on the client, measured on a row with three varied keys and its
#: command (``sys.getsizeof`` over the dict, its keys and values: 2.6 kB), rounded up [bytes].
ROW_BYTES = 4096
#: What each varied key beyond three, and ``precision``, add to :data:`ROW_BYTES` [bytes], with the same headroom
#: (measured on a three-stage train: 2.75 kB a row with 3 keys, 4.3 kB with 12, 5.8 kB with 12 and the ISO figures).
KEY_BYTES, PRECISION_BYTES = 400, 1536
#: Figures of each run (from :class:`~gearctl.metrics.TrackingMetrics`; timing figures are left out: they
#: differ from one machine, or one run, to the next, and the results must not).
METRICS = ("rms_error", "max_error", "final_error", "impacts", "max_impact_velocity", "torque_rms",
           "saturated_fraction", "fallbacks")
#: Health flags of each run (:class:`~gearctl.metrics.LoopHealth`).
FLAGS = ("limit_cycle", "saturated", "impact_rate_high", "growing", "not_following", "falling_back", "chattering")
#: Seconds to wait for a scheduler to answer, then for its first worker.
#: ISO 230-2 figures of each run with ``precision=True``.
ISO_FIGURES = ("reversal_value", "repeatability", "accuracy")

_ESTIMATE = Spec(unit="m", doc="backlash estimate of the controller", low=BACKLASH.low, high=BACKLASH.high,
                 high_open=BACKLASH.high_open, floor=BACKLASH.floor)  # the floor too: 1e-12 failed every run
_ESTIMATE_ERROR = Spec(unit="1", doc="relative error of the backlash estimate against the true backlash",
                       low=-1.0, high=10.0)
_DISTS: dict[str, int | tuple[int, ...]] = {"uniform": 2, "loguniform": 2, "normal": (2, 4), "lognormal": (2, 4)}
_NUM = re.compile(r"^\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|[+-]?inf)\s*(x?)\s*$")


# --- keys -----------------------------------------------------------------------------------------------

def sweep_keys() -> dict[str, dict[str, Any]]:
    """The keys a sweep can vary: ``key -> field metadata`` (unit, range, doc; ``owner``: the dataclass).

    Every numeric field of the model's dataclasses, then ``estimate`` and ``estimate_error``. Fields that
    are not numbers (``contact_law``, ``friction_law``) or lists (``intermediate_*``) are not keys.
    """
    out: dict[str, dict[str, Any]] = {}
    for cls in MODEL_CLASSES:
        for f in dataclasses.fields(cls):
            if "unit" in f.metadata and not f.metadata.get("sequence") and f.name not in out:
                out[f.name] = {**f.metadata, "owner": cls.__name__}
    out["estimate"] = {**_ESTIMATE.meta(), "owner": "controller"}
    out["estimate_error"] = {**_ESTIMATE_ERROR.meta(), "owner": "controller"}
    return out


class _Keys(dict):
    """:func:`sweep_keys`, which also knows a key of one stage (``stage2.backlash``: its field's metadata, with
    ``stage``, the index from 0)."""

    def __missing__(self, key: str) -> dict[str, Any]:
        i, field = split_stage_key(key)
        if i is None or field not in self:
            raise KeyError(key)
        return {**self[field], "stage": i}

    def __contains__(self, key: object) -> bool:
        if dict.__contains__(self, key):
            return True
        if not isinstance(key, str):
            return False
        i, field = split_stage_key(key)
        return i is not None and dict.__contains__(self, field)


_KEYS = _Keys(sweep_keys())


def _key_meta(key: str, *, what: str = "sweep key") -> dict[str, Any]:
    """The metadata of a key a sweep varies or ``--set`` changes (``what`` names it in the error: a ``--set`` key is
    a model key, the sweep's may also be the controller's estimate)."""
    if key in _KEYS:
        return _KEYS[key]
    sweep = what == "sweep key"
    every = {f.name for cls in MODEL_CLASSES for f in dataclasses.fields(cls)}
    if key in every:
        doing = "a sweep can vary" if sweep else "--set can change"
        if key.startswith("intermediate_"):  # a list of numbers, not "not a number"
            who = "--vary" if sweep else "--set"
            raise InputError(f"{key} is a list (one value per intermediate shaft): {who} takes keys of one number; "
                             "change the list in a copy of the model file", field=key)
        raise InputError(f"{key} is not a number {doing}: numeric keys only (e.g. backlash, mesh_stiffness, "
                         f"coulomb_friction2, load_inertia, load_noise{', estimate' if sweep else ''})", field=key)
    if key in FILE_NAMES:  # a pair file's name of a key the overrides spell as the train's (a review's
        # `--set profile_shift=0.3` was told of an unknown model key, `pressure_angle_deg` pointed to the rad key)
        raise file_name_error(key, key, "--vary" if sweep else "--set")
    import difflib

    # a --set key is the model's: the controller's estimate has an option of its own, so it is no suggestion there
    keys = [k for k, meta in _KEYS.items() if sweep or meta["owner"] != "controller"]
    close = difflib.get_close_matches(key, keys, n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    also = ", estimate or estimate_error" if sweep else ""
    raise InputError(f"unknown {what} {key!r}: expected a model key (backlash, mesh_stiffness, "
                     f"coulomb_friction2, load_inertia, load_noise, ...; one stage's: stage2.backlash){also}{hint}",
                     field=key)


def parse_set(text: str) -> tuple[str, float | int]:
    """Parse ``KEY=VALUE`` (one model key and one plain number), checked against the key's range.

    The reading ``gearctl track --set`` uses, so a sweep's ``command`` rebuilds the very same plant:
    whole-number keys become ``int``, every other value ``float``. ``VALUE`` with a trailing ``x`` is a factor
    of the nominal value (:class:`Scale`; on a train, of each stage's own value), checked once applied.

    Parameters
    ----------
    text : str
        ``KEY=VALUE``, e.g. ``backlash=6e-5`` or ``backlash=2x``.

    Returns
    -------
    key : str
    value : int, float or Scale

    Raises
    ------
    InputError
        Not ``KEY=VALUE``, an unknown key or a controller's key (the estimate), a value that is not a number,
        a factor below 0, or a value out of the key's range.
    """
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key:
        raise InputError(f"{text!r} is not KEY=VALUE (e.g. backlash=6e-5)", field="set")
    meta = _key_meta(key, what="model key")
    if meta["owner"] == "controller":
        raise InputError(f"{key} is not a model key: the estimate is an option of its own (--estimate)", field=key)
    text_v = value.strip()
    if text_v.endswith("x") and meta["integer"]:  # '2x' read as a number said "'2x' is not a number"
        raise InputError(f"{key} = {text_v!r}: a whole-number key takes a whole number, not a factor of the nominal "
                         f"value: expected {describe_rule(meta)}", field=key)
    if text_v.endswith("x"):
        try:
            f = float(text_v[:-1])
        except ValueError:
            raise InputError(f"{key} = {text_v!r} is not a number", field=key) from None
        if not (f >= 0.0 and math.isfinite(f)):
            raise InputError(f"{key} = {text_v!r}: a factor of the nominal value is a number >= 0", field=key)
        return key, Scale(f)
    try:
        v = float(value)
    except ValueError:
        raise InputError(f"{key} = {value.strip()!r} is not a number", field=key) from None
    check_number(key, v, meta)
    return key, (int(v) if meta["integer"] else v)


def perturb_model(model: GearModel, overrides: Mapping[str, float]) -> GearModel:
    """:func:`gearctl.overrides.perturb_model`, an unknown key named as the sweep's keys are (with a hint).

    Parameters
    ----------
    model : GearModel
        The nominal model.
    overrides : mapping
        ``{key: value}`` of model keys (``stageN.key`` for one stage of a train); a :class:`Scale` value is a
        factor of each stage's own value.

    Raises
    ------
    InputError
        An unknown key (with a suggestion), a value out of its range, or a model the changed value makes invalid.
    """
    for key in overrides:
        field = split_stage_key(key)[1]
        if not any(field in OWNER_FIELDS[cls] for cls in MODEL_CLASSES):
            _key_meta(key)  # raises the unknown-key message
    return _perturb(model, overrides)


def _nominal(key: str, model: GearModel, spec: Mapping[str, Any]) -> float | None:
    """The nominal value a relative spec (``1.5x``) scales, or None if there is none."""
    if key == "estimate":
        b = spec.get("backlash")
        return float(b) if isinstance(b, int | float) else float(build_plant(model).equivalent_pair().backlash)
    if key == "estimate_error":
        return None
    meta = _KEYS[key]
    if meta["owner"] in ("Servo", "Sensors"):
        v = getattr(model.servo if meta["owner"] == "Servo" else model.sensors, key)
        return None if v is None or not math.isfinite(v) else float(v)
    i, field = split_stage_key(key)
    if i is not None:  # one stage's own value
        if i >= model.n_stages:
            raise InputError(f"{key}: {model.name} has {model.n_stages} stage{'s' if model.n_stages > 1 else ''}: "
                             f"expected stage1 .. stage{model.n_stages}", field=key)
        return stage_values(field, model)[i]
    vals = stage_values(key, model)
    if len(set(vals)) > 1:
        raise _DifferingStages(f"{key} differs between the stages of {model.name} "
                               f"({', '.join(f'{v:g}' for v in vals)})", field=key)
    return vals[0]


class _DifferingStages(InputError):
    """A stage key whose value differs between a train's stages: a relative spec scales each stage."""


def _parse_vary_on(text: str, model: GearModel, spec: Mapping[str, Any]) -> Vary:
    """:func:`parse_vary` against a nominal model. A relative spec of a stage key whose stages differ scales each
    stage's own value: its numbers are factors (every number relative, or 0 or inf), drawn as :class:`Scale`."""
    try:
        return parse_vary(text, lambda k: _nominal(k, model, spec))
    except _DifferingStages as exc:
        key = text.partition("=")[0].strip()
        if _KEYS[key]["integer"]:
            raise InputError(f"--vary {text}: {exc}; a whole-number key is not scaled: give its values", field=key,
                             rule=exc.rule) from None
        values = text.partition("=")[2].strip()
        dist = re.fullmatch(r"([a-z]+)\s*\((.*)\)", values)
        tokens = [t.strip() for t in re.split(r"[,:]", dist.group(2) if dist else values)]
        for j, tok in enumerate(tokens):
            if dist and dist.group(1) == "lognormal" and j == 1:  # the log-std is no value of the key
                continue
            if not tok.lower().endswith("x") and tok.lower().lstrip("+-") not in ("0", "0.0", "inf"):
                raise InputError(f"--vary {text}: {exc}, so a relative spec scales each stage's own value: give "
                                 f"every number of it with an x (e.g. 0.5x:2x), or absolute values for every "
                                 f"stage alike", field=key) from None
        return dataclasses.replace(parse_vary(text, {key: 1.0}, check=False), scale=True, nominal=1.0,
                                   unit="x each stage's value")


# --- specs ----------------------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class Vary:
    """One varied key: its spec parsed to absolute values.

    Attributes
    ----------
    key : str
    text : str
        The spec as typed (``0.5x:2x``).
    kind : str
        ``range``, ``loguniform``, ``normal``, ``lognormal`` or ``list``.
    args : tuple of float
        Absolute parameters: (a, b) of a range; (m, s, lo, hi) of a normal or lognormal (``lo, hi``
        infinite when not truncated); the values of a list.
    nominal : float or None
        The nominal value relative numbers scaled.
    unit : str
    scale : bool
        The values are factors of each stage's own value (a relative spec of a stage key whose stages differ),
        drawn as :class:`Scale`.
    """

    key: str
    text: str
    kind: str
    args: tuple[float, ...]
    nominal: float | None
    unit: str
    scale: bool = False

    @property
    def bounded(self) -> bool:
        """Whether grid points include the ends (ranges) rather than quantile midpoints."""
        return self.kind in ("range", "loguniform")

    def quantile(self, u: np.ndarray) -> np.ndarray:
        """Values at probabilities ``u`` in (0, 1) (the spec's inverse CDF; for a list, the ``floor(u n)``-th).

        Parameters
        ----------
        u : array_like
            Probabilities in (0, 1).
        """
        from scipy.special import ndtr, ndtri

        u = np.asarray(u, dtype=float)
        a = self.args
        if self.kind == "range":
            return a[0] + u * (a[1] - a[0])
        if self.kind == "loguniform":
            return np.exp(math.log(a[0]) + u * (math.log(a[1]) - math.log(a[0])))
        if self.kind == "list":
            return np.asarray(a)[np.minimum((u * len(a)).astype(int), len(a) - 1)]
        m, s, lo, hi = a
        if self.kind == "normal":
            zlo, zhi = (lo - m) / s, (hi - m) / s
        else:
            zlo = math.log(lo / m) / s if lo > 0 else -math.inf
            zhi = math.log(hi / m) / s if math.isfinite(hi) else math.inf
        plo, phi = float(ndtr(zlo)), float(ndtr(zhi))
        z = ndtri(plo + u * (phi - plo))
        return m + s * z if self.kind == "normal" else m * np.exp(s * z)

    def grid(self, n: int) -> np.ndarray:
        """The grid points: every value of a list; n points, ends included, of a range; else n quantiles.

        Parameters
        ----------
        n : int
            Points of a range or a distribution (a range with ``n = 1`` gives its middle); a list ignores it.
        """
        if self.kind == "list":
            return np.asarray(self.args)
        if self.bounded:
            if n == 1:
                return self.quantile(np.array([0.5]))
            pts = self.quantile(np.linspace(0.0, 1.0, n))
            pts[0], pts[-1] = self.args[0], self.args[1]  # the ends exactly
            return pts
        return self.quantile((np.arange(n) + 0.5) / n)

    def describe(self) -> str:
        """``backlash = 0.5x:2x (2.5e-05 .. 0.0001 m)``."""
        unit = "" if self.unit == "1" else f" {self.unit}"
        if self.kind == "list":
            span = ", ".join(f"{v:.4g}" for v in self.args[:6]) + (", ..." if len(self.args) > 6 else "")
        elif self.kind in ("range", "loguniform"):
            span = f"{self.args[0]:.4g} .. {self.args[1]:.4g}"
        else:  # the unit follows each value of the key (a log-std has none)
            m, s, lo, hi = self.args
            normal = self.kind == "normal"
            span = f"{'mean' if normal else 'median'} {m:.4g}{unit}, " + \
                   f"{'std' if normal else 'log-std'} {s:.4g}{unit if normal else ''}" + \
                   (f", in [{lo:.4g}, {hi:.4g}]{unit}" if math.isfinite(lo) or math.isfinite(hi) else "")
            return f"{self.key} = {self.text} ({span})"
        return f"{self.key} = {self.text} ({span}{unit})"


def _number(token: str, where: str, nominal: float | None, key: str, *, relative: bool = True,
            allow_inf: bool = False) -> float:
    m = _NUM.match(token)
    if not m:
        # `--vary backlash=0.5x-2x`: a range written with a dash (not an exponent's sign: 2e-5-1e-4)
        ranges = [(token[:i].strip(), token[i + 1:].strip()) for i, c in enumerate(token)
                  if c == "-" and i > 0 and token[i - 1] not in "eE" and _NUM.match(token[:i]) and
                  _NUM.match(token[i + 1:])]
        hint = f"; a range is LOW:HIGH ({ranges[0][0]}:{ranges[0][1]})" if ranges else ""
        raise InputError(f"{where}: {token.strip()!r} is not a number (e.g. 2e-5, 1.5x){hint}", field=key)
    v = float(m.group(1))
    if math.isinf(v) and not allow_inf:
        raise InputError(f"{where}: {token.strip()!r}: inf is allowed only as a truncation bound", field=key)
    if m.group(2):
        if not relative:
            raise InputError(f"{where}: {token.strip()!r}: this parameter is not relative to the nominal value "
                             f"(no 'x')", field=key)
        if nominal is None:
            raise InputError(f"{where}: {token.strip()!r}: {key} has no nominal value to scale; give absolute "
                             f"values", field=key)
        if nominal == 0.0 and v != 0.0:  # every factor of 0 is 0: the sweep would vary nothing, without a word
            raise InputError(f"{where}: {token.strip()!r}: the nominal {key} is 0, so every factor of it is 0 (the "
                             f"runs would not vary it); give absolute values", field=key)
        v *= nominal
    return v


def parse_vary(text: str, nominal: Callable[[str], float | None] | Mapping[str, float | None] | None = None, *,
               check: bool = True) -> Vary:
    """Parse ``KEY=SPEC`` (see the module docstring for the specs).

    Parameters
    ----------
    text : str
        E.g. ``backlash=0.5x:2x``, ``coulomb_friction2=normal(0.2,0.05,0,inf)``, ``load_noise=0,1e-6,2e-6``.
    nominal : callable or mapping, optional
        The nominal value of a key, for relative numbers (``1.5x``); without it relative numbers are errors.
    check : bool
        Check a bounded spec's ends against the key's range (off for factors, :class:`Scale`).

    Returns
    -------
    Vary

    Raises
    ------
    InputError
        One line naming the key and what is wrong: unknown key, bad syntax, bad parameters, a bounded
        spec reaching outside the key's range.
    """
    key, sep, spec = text.partition("=")
    key, spec = key.strip(), spec.strip()
    if not sep or not key or not spec:
        raise InputError(f"--vary {text!r} is not KEY=SPEC (e.g. backlash=0.5x:2x, "
                         f"coulomb_friction2=normal(0.2,0.05))", field="vary")
    meta = _key_meta(key)
    where = f"--vary {key}={spec}"
    lazy: dict[str, float | None] = {}

    def nom() -> float | None:
        if "v" not in lazy:
            lazy["v"] = nominal(key) if callable(nominal) else (nominal or {}).get(key)
        return lazy["v"]

    def num(tok: str, *, relative: bool = True, allow_inf: bool = False) -> float:
        needs = bool((match := _NUM.match(tok)) and match.group(2))
        return _number(tok, where, nom() if needs else None, key, relative=relative, allow_inf=allow_inf)

    args: tuple[float, ...]  # (a, b), (m, s, lo, hi) or the list's values
    dist = re.fullmatch(r"([a-z]+)\s*\((.*)\)", spec)
    if dist:
        name, body = dist.group(1), dist.group(2).split(",")
        if name not in _DISTS:
            import difflib

            close = difflib.get_close_matches(name, list(_DISTS), n=1)
            hint = f"; did you mean {close[0]}(...)?" if close else ""
            raise InputError(f"{where}: unknown distribution {name!r}: expected uniform(a,b), loguniform(a,b), "
                             f"normal(mean,std[,low,high]) or lognormal(median,log_std[,low,high]){hint}", field=key)
        arity = _DISTS[name]
        counts = arity if isinstance(arity, tuple) else (arity,)
        if len(body) not in counts:
            want = " or ".join(str(c) for c in counts)
            raise InputError(f"{where}: {name} takes {want} numbers, got {len(body)}", field=key)
        if name in ("uniform", "loguniform"):
            a, b = num(body[0]), num(body[1])
            kind, args = ("range" if name == "uniform" else "loguniform"), (a, b)
        else:
            m = num(body[0])
            s = num(body[1], relative=name == "normal")
            lo = num(body[2], allow_inf=True) if len(body) == 4 else -math.inf
            hi = num(body[3], allow_inf=True) if len(body) == 4 else math.inf
            if not (s > 0 and math.isfinite(s)):
                raise InputError(f"{where}: the {'std' if name == 'normal' else 'log-std'} must be > 0, got {s:g}",
                                 field=key)
            if name == "lognormal" and not m > 0:
                raise InputError(f"{where}: the median of a lognormal must be > 0, got {m:g}", field=key)
            if not lo < hi:
                raise InputError(f"{where}: the truncation needs low < high, got [{lo:g}, {hi:g}]", field=key)
            if name == "lognormal" and hi <= 0:
                raise InputError(f"{where}: a lognormal is positive: the upper bound must be > 0", field=key)
            kind, args = name, (m, s, lo, hi)
    elif ":" in spec:
        parts = spec.split(":")
        if len(parts) != 2:
            raise InputError(f"{where}: a range is a:b (e.g. 0.5x:2x)", field=key)
        a, b = num(parts[0]), num(parts[1])
        kind, args = "range", (a, b)
    else:
        vals = tuple(num(t) for t in spec.split(","))
        kind, args = "list", vals
    if kind in ("range", "loguniform"):
        a, b = args
        if not a <= b:
            raise InputError(f"{where}: the range needs low <= high, got {a:g} > {b:g}", field=key)
        if kind == "loguniform" and not a > 0:
            raise InputError(f"{where}: a log-uniform range needs 0 < low, got {a:g}", field=key)
        for v in (a, b):  # a bounded spec inside the range is checked once, here
            if check:
                _check_value(key, v, meta, where)
    if kind == "list":
        for v in args:
            if check:
                _check_value(key, v, meta, where)
    return Vary(key=key, text=spec, kind=kind, args=tuple(float(a) for a in args), nominal=lazy.get("v"),
                unit=meta["unit"])


def _check_value(key: str, v: float, meta: Mapping[str, Any], where: str, run: int | None = None) -> None:
    try:
        check_number(key, v, dict(meta))
    except InputError as exc:
        drew = f"run {run} draws {key} = {v!r}, which" if run is not None else f"{key} = {v!r}"
        hint = "; truncate the distribution, e.g. normal(m,s,low,high)" if run is not None else ""
        if meta.get("integer") and "whole" in (exc.rule or ""):
            hint = "; a whole-number key takes a list (e.g. 20,21,22)"
        raise InputError(f"{where}: {drew} {exc.rule}{hint}", field=key, rule=exc.rule) from None


def _uniforms(seed: int, index: int, key: str) -> float:
    """Run ``index``'s uniform number in (0, 1) for ``key``: 53 random bits from SeedSequence([seed, index, crc])."""
    word = int(np.random.SeedSequence([seed, index, zlib.crc32(key.encode())]).generate_state(1, np.uint64)[0])
    return ((word >> 11) + 0.5) / 2.0**53


def noise_seed(seed: int, index: int) -> int:
    """Run ``index``'s sensor-noise seed: 53 bits of SeedSequence([seed, index]) (a CLI number keeps them exactly).

    Parameters
    ----------
    seed : int
        The sweep's seed.
    index : int
        The run's index in the sweep.
    """
    return int(np.random.SeedSequence([seed, index]).generate_state(1, np.uint64)[0]) >> 11


# --- the plan: what to run, as values -------------------------------------------------------------------

@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class SweepContext:
    """What every run of a sweep shares (sent with each batch; a few kB).

    Attributes
    ----------
    model : GearModel
        The nominal model.
    design : Design
        The controller designed on the nominal model (improved plant), estimate as in its file.
    plant : str
        True plant kind.
    reference : Reference
    duration : float
        Simulated time of each run [s].
    precision : bool
        Also run the ISO 230-2 test on each perturbed plant.
    command : tuple of str
        ``gearctl track MODEL CONTROLLER --plant .. --reference .. --duration ..`` (each run adds its own
        ``--seed``, ``--set`` and ``--estimate``).
    precision_command : tuple of str
        The same for ``gearctl precision``.
    """

    model: GearModel
    design: Design
    plant: str
    reference: Reference
    duration: float
    precision: bool
    command: tuple[str, ...]
    precision_command: tuple[str, ...]


#: A run of a sweep as a worker receives it: (index, {key: value}, sensor-noise seed).
Job = tuple[int, dict[str, float], int]


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class SweepPlan:
    """A sweep, planned and checked: the shared context and one job per run (:func:`plan_sweep`).

    Attributes
    ----------
    context : SweepContext
        What every run shares.
    jobs : list of tuple
        One :data:`Job` per run: ``(index, {key: value}, sensor-noise seed)``.
    vary : tuple of Vary
        The varied keys, in the order given.
    grid : bool
        A full grid rather than Monte Carlo draws.
    points : int
        Monte Carlo runs, or with ``grid`` the points per key.
    seed : int
        Seed of the draws and of each run's sensor noise.
    settings : dict
        The settings as :attr:`SweepResult.settings` reports them.
    """

    context: SweepContext
    jobs: list[Job]
    vary: tuple[Vary, ...]
    grid: bool
    points: int
    seed: int
    settings: dict[str, Any]


def _count(vary: Sequence[Vary], points: int, grid: bool) -> int:
    if not grid:
        return points
    return math.prod(len(v.args) if v.kind == "list" else points for v in vary)


def check_memory(n: int, *, grid: bool, keys: int = 3, precision: bool = False) -> None:
    """Refuse a sweep whose results would not fit in half of the free memory (:data:`ROW_BYTES` a run, more with over
    three varied ``keys`` or ``precision``: :data:`KEY_BYTES`, :data:`PRECISION_BYTES`; with 12 keys and the ISO
    figures a row took 5.8 kB, over the 4 kB that were assumed for every sweep).

    Parameters
    ----------
    n : int
        Runs of the sweep.
    grid : bool
        Whether it is a grid (the message's advice differs).
    keys : int
        Varied keys.
    precision : bool
        Whether each run also carries the ISO 230-2 figures.

    Raises
    ------
    InputError
        Saying how much the table needs, how much there is, and which option makes it smaller.
    """
    import psutil

    row = ROW_BYTES + KEY_BYTES * max(0, keys - 3) + (PRECISION_BYTES if precision else 0)
    need = n * row
    free = psutil.virtual_memory().available
    if need > free / 2:
        what = "fewer points per key (--runs) or fewer keys" if grid else "fewer runs (--runs)"
        raise InputError(f"runs = {n} would hold about {need / 1e9:.3g} GB of results ({row} B a run) and "
                         f"{free / 1e9:.3g} GB of memory is free (at most half of it is used): ask for {what}",
                         field="runs")


def plan_sweep(model: str | Path = "shing1993_servo", controller: str | Path = "deadzone_inverse", *,
               vary: Sequence[str] | Mapping[str, str] = (), runs: int | None = None, grid: bool = False,
               reference_kind: str = "sine", duration: float | None = None, seed: int = 0,
               plant: str = "improved", precision: bool = False) -> SweepPlan:
    """Parse, draw and check a sweep before anything runs.

    Parameters are those of :func:`sweep`.

    Returns
    -------
    SweepPlan

    Raises
    ------
    InputError
        A bad spec, a draw out of its key's range, a perturbed model that is invalid (naming the run and
        its values), a controller that cannot be designed on the nominal model, too many runs, or a run or a
        table of results that would not fit in memory.
    """
    if reference_kind not in REFERENCES:
        raise InputError(f"reference = {reference_kind!r} is not a reference: expected one of "
                         f"{', '.join(REFERENCES)}", field="reference")
    try:
        PlantKind(plant)
    except ValueError:
        raise InputError(f"plant = {plant!r} is not a plant: expected one of "
                         f"{', '.join(k.value for k in PlantKind)}", field="plant") from None
    SEED.check("seed", seed)
    dur = float(duration) if duration is not None else DEFAULT_DURATION[reference_kind]
    DURATION.check("duration", dur)
    points = runs if runs is not None else (5 if grid else 100)
    (GRID_POINTS if grid else SWEEP_RUNS).check("runs", points)
    points = int(points)
    texts = ([f"{k}={v}" for k, v in vary.items()] if isinstance(vary, Mapping)
             else [vary] if isinstance(vary, str) else list(vary))  # one "KEY=SPEC" string is one key
    nominal_model = load_model(model)
    spec, label = controller_spec(controller)
    varies = tuple(_parse_vary_on(t, nominal_model, spec) for t in texts)
    keys = [v.key for v in varies]
    dup = sorted({k for k in keys if keys.count(k) > 1})
    if dup:
        raise InputError(f"--vary {dup[0]} is given twice", field=dup[0])
    check_keys_act(keys, plant, nominal_model, option="--vary")
    if "estimate" in keys and "estimate_error" in keys:
        raise InputError("--vary estimate and estimate_error set the same thing: give one", field="estimate")
    n = _count(varies, points, grid)
    if n > SWEEP_RUNS.upper:
        raise InputError(f"the grid has {n} runs: expected at most {SWEEP_RUNS.high:.0f}; use fewer points per key "
                         f"(--runs) or fewer keys", field="runs")
    check_memory(n, grid=grid, keys=len(varies), precision=precision)
    # the design, once, on the nominal model: a controller that cannot be designed stops here
    design = Design(spec=spec, nominal=build_plant(nominal_model), label=label, sensors=nominal_model.sensors)
    ctrl = design_controller(design)
    # a run that would not fit is refused here, at the controller's own sample time: the command line checked it at
    # the catalog's 1 ms, and a 0.1 ms controller's 1000 s runs on a train all failed, exit 0
    check_loop_memory(design.nominal, dur, ctrl.Ts)
    # and a run of no sample: every run failed alone ("diverged 100%"), exit 0
    check_loop_duration(dur, ctrl.Ts, field="--duration", who=f" of {Path(label).stem}")
    if {"estimate", "estimate_error"} & set(keys) and not _uses_estimate(ctrl):
        raise InputError(f"--vary {'estimate' if 'estimate' in keys else 'estimate_error'}: "
                         f"{Path(label).stem} uses no backlash estimate (vary it for a controller that takes one: "
                         "deadzone_inverse, adaptive_inverse, reversal_offset or mpc)",
                         field="estimate")
    # the values of every run, drawn and checked here
    columns = _draw(varies, n, points, grid, seed)
    metas = {v.key: _KEYS[v.key] for v in varies}
    model_keys = [v.key for v in varies if metas[v.key]["owner"] != "controller"]
    jobs: list[Job] = []
    b_nominal = nominal_model.stages[0].pair.backlash if nominal_model.n_stages == 1 else None
    err_text = next((v.text for v in varies if v.key == "estimate_error"), "")
    for i in range(n):
        params: dict[str, float] = {}  # a Scale where the key scales each stage's value
        for v in varies:
            x = columns[v.key][i]
            if v.scale:  # a factor of each stage's value: checked on the stages, by perturb_model below
                params[v.key] = Scale(x)
                continue
            x = int(round(x)) if metas[v.key]["integer"] and float(x).is_integer() else float(x)
            _check_value(v.key, x, metas[v.key], f"--vary {v.key}={v.text}", run=i)
            params[v.key] = x
        overrides = {k: params[k] for k in model_keys}
        if overrides:
            try:
                perturb_model(nominal_model, overrides)
            except InputError as exc:
                shown = ", ".join(f"{k} = {params[k]:.6g}{'x' if isinstance(params[k], Scale) else ''}"
                                  for k in model_keys)
                raise InputError(f"run {i} ({shown}): {exc}", field=exc.field, rule=exc.rule) from None
        if "estimate_error" in params and b_nominal is not None:  # a pair: the estimate is known here
            b_true = params.get("stage1.backlash", params.get("backlash", b_nominal))  # stage1's over every stage's
            e = (1.0 + params["estimate_error"]) * float(b_true)
            _check_value("estimate", e, _KEYS["estimate"], f"--vary estimate_error={err_text}", run=i)
        jobs.append((i, params, noise_seed(seed, i)))
    head = ["gearctl", "track", str(model), str(controller), "--plant", plant, "--reference", reference_kind,
            "--duration", repr(dur)]
    iso = ["gearctl", "precision", str(model), str(controller), "--plant", plant]
    ctx = SweepContext(model=nominal_model, design=design, plant=plant, reference=reference(reference_kind),
                       duration=dur, precision=precision, command=tuple(head), precision_command=tuple(iso))
    settings = {"model": str(model), "controller": str(controller), "plant": plant, "reference": reference_kind,
                "duration": dur, "seed": seed, "grid": grid, "points": points, "runs": n, "precision": precision,
                "vary": {v.key: v.text for v in varies},
                "factors": [v.key for v in varies if v.scale],  # keys whose values are factors of each stage's
                "nominal": {k: x for k, x in ((v.key, _shown_nominal(v, nominal_model, spec)) for v in varies)
                            if x is not None},
                "design": ctrl.describe(),
                # what a resumed sweep (resume) checks: this gearctl (version and code), its numerical libraries, and
                # the model's and controller's files (their SHA-256)
                "gearctl": code_id(), "numerics": numerics_versions(), "files": file_hashes(model, controller)}
    return SweepPlan(context=ctx, jobs=jobs, vary=varies, grid=grid, points=points, seed=seed, settings=settings)


def _shown_nominal(v: Vary, model: GearModel, spec: Mapping[str, Any]) -> float | None:
    """The nominal value of a varied key for reports and plots (None where there is no single one)."""
    if v.nominal is not None:
        return v.nominal
    try:
        return _nominal(v.key, model, spec)
    except InputError:
        return None


def _uses_estimate(ctrl: Any) -> bool:
    d = ctrl.describe()
    return hasattr(ctrl, "set_backlash") or "backlash_estimate" in d or "backlash" in d


def _draw(varies: Sequence[Vary], n: int, points: int, grid: bool, seed: int) -> dict[str, np.ndarray]:
    if grid:
        axes = [v.grid(points) for v in varies]
        mesh = np.meshgrid(*axes, indexing="ij") if axes else []
        return {v.key: m.ravel() for v, m in zip(varies, mesh, strict=True)}
    return {v.key: v.quantile(np.array([_uniforms(seed, i, v.key) for i in range(n)])) for v in varies}


# --- the worker side ------------------------------------------------------------------------------------

def _build_run(ctx: SweepContext, job: Job) -> tuple[Run, float | None]:
    """The Run of a job: the perturbed true plant, the nominal design with the run's estimate."""
    index, params, seed = job
    overrides = {k: v for k, v in params.items() if _KEYS[k]["owner"] != "controller"}
    model = perturb_model(ctx.model, overrides) if overrides else ctx.model
    true = build_plant(model, ctx.plant)
    estimate = params.get("estimate")
    if "estimate_error" in params:
        estimate = (1.0 + params["estimate_error"]) * float(true.equivalent_pair().backlash)
    if estimate is not None:
        try:
            BACKLASH.check("estimate", estimate)
        except InputError as exc:  # a train's estimate is known here only: the row's command carries it
            raise _BadEstimate(str(exc), field="estimate", rule=exc.rule, estimate=float(estimate)) from None
    design = ctx.design if estimate is None else dataclasses.replace(ctx.design, backlash=float(estimate))
    run = Run(plant=true, design=design, reference=ctx.reference, duration=ctx.duration, seed=seed,
              sensors=model.sensors, tags={"index": index})
    return run, (None if estimate is None else float(estimate))


class _BadEstimate(InputError):
    """A run's estimate out of range (:func:`_build_run`), with the estimate: the failed run's command gives it to
    ``track``, which refuses it with the same words (without it the command ran the nominal estimate, healthy)."""

    def __init__(self, message: str, *, estimate: float, **kw: Any) -> None:
        super().__init__(message, **kw)
        self.estimate = estimate


def run_batch(runs: Sequence[Run], *, precision: bool = False) -> list[tuple[RunResult, dict[str, Any] | None]]:
    """Run closed loops: THE place a sweep runs them, in C for the linear controllers.

    The PID family (``pid``, ``reversal_offset``, ``deadzone_inverse``) runs in the compiled batch loop
    (:func:`gearctl.export.batch.run_compiled`: kernel and controller in C, the Python run's result to the
    last bit); every other controller, or a machine without a C compiler, through :func:`gearctl.runs.execute`.

    Parameters
    ----------
    runs : sequence of Run
        Each run's controller is built once per process per design; a run whose design differs from
        another only in the backlash estimate reuses that design through ``set_backlash`` where the
        controller has it (the dead-zone inverse: the same numbers as a fresh design, without the
        30 ms PID design each time).
    precision : bool
        Also run the ISO 230-2 test (``gearctl precision``'s defaults) on each run's plant.

    Returns
    -------
    list of (RunResult, dict or None)
        Each run's result (a failure is a result, never an exception) and, with ``precision``, the ISO
        figures ``reversal_value``, ``repeatability``, ``accuracy`` [rad] or ``{"error": message}``.
    """
    out = []
    for run in runs:
        base = run.design if run.design.backlash is None else dataclasses.replace(run.design, backlash=None)
        try:
            ctrl = design_controller(base)
        except GearctlError:
            ctrl = None
        shared = (ctrl is not None and run.design.backlash is not None and hasattr(ctrl, "set_backlash")
                  and hasattr(ctrl, "backlash"))
        old = getattr(ctrl, "backlash", None)
        try:
            if shared:
                ctrl.set_backlash(run.design.backlash)  # type: ignore[union-attr]
                run = dataclasses.replace(run, design=base)
            res = run_compiled(run)
            iso = _precision(run) if precision else None
        finally:
            if shared:
                ctrl.set_backlash(old)  # type: ignore[union-attr]
        out.append((res, iso))
    return out


def _precision(run: Run) -> dict[str, Any]:
    from .bench import ISO_SETTINGS
    from .precision import precision_test

    try:
        ctrl = design_controller(run.design)
        res = precision_test(run.plant, ctrl, sensors=run.sensors, seed=run.seed, **ISO_SETTINGS)
    except GearctlError as exc:
        return {"error": str(exc)}
    return {k: float(res.stats[k]) for k in ISO_FIGURES}


def _command(head: Sequence[str], job: Job, estimate: float | None) -> str:
    _, params, seed = job
    argv = [*head, "--seed", str(seed)]
    for k, v in params.items():
        if _KEYS[k]["owner"] != "controller":
            argv += ["--set", f"{k}={v!r}"]  # a Scale reads 1.5x
    if estimate is not None:
        argv += ["--estimate", repr(estimate)]
    return shlex.join(argv)


def _row(ctx: SweepContext, job: Job, res: RunResult | None, iso: dict[str, Any] | None, estimate: float | None,
         message: str | None = None) -> dict[str, Any]:
    index, params, seed = job
    row: dict[str, Any] = {"index": index, "params": dict(params), "seed": seed}
    if "estimate_error" in params or "estimate" in params:
        row["estimate"] = estimate
    m = res.metrics if res is not None else None
    row["status"] = "ok" if res is not None and res.ok else "failed"
    row["message"] = res.message if res is not None else message
    for k in METRICS:
        row[k] = None if m is None else m[k]
    for k in FLAGS:
        row[k] = None if m is None else bool(m.health[k])
    row["command"] = _command(ctx.command, job, estimate)
    if ctx.precision:
        for k in ISO_FIGURES:
            row[k] = None if not iso or "error" in iso else iso[k]
        row["precision_message"] = "ok" if iso and "error" not in iso else (iso or {}).get("error", message)
        row["precision_command"] = _command(ctx.precision_command, job, estimate)
    return row


def sweep_task(ctx: SweepContext, jobs: Sequence[Job]) -> list[dict[str, Any]]:
    """One Dask task: build a batch of runs, run them (:func:`run_batch`), return a small dict per run.

    Parameters
    ----------
    ctx : SweepContext
        What every run shares.
    jobs : sequence of tuple
        The batch's :data:`Job` s; a job whose run cannot be built gives a failed row with the message.
    """
    built: list[tuple[int, Run, float | None]] = []
    rows: list[dict[str, Any] | None] = [None] * len(jobs)
    for k, job in enumerate(jobs):
        try:
            run, est = _build_run(ctx, job)
        except GearctlError as exc:
            rows[k] = _row(ctx, job, None, None, getattr(exc, "estimate", None), message=str(exc))
            continue
        built.append((k, run, est))
    results = run_batch([r for _, r, _ in built], precision=ctx.precision)
    for (k, _, est), (res, iso) in zip(built, results, strict=True):
        rows[k] = _row(ctx, jobs[k], res, iso, est)
    return rows  # type: ignore[return-value]


# --- the engine -----------------------------------------------------------------------------------------

def batch_size(n: int, workers: int, duration: float, cost_per_s: float = 0.015) -> int:
    """Runs per task: about half a second of work, and at least four tasks per worker thread; 1 to 256.

    A task costs about 5 ms of CPU in the client and the scheduler (measured on the two-core machine;
    shipping the context by value or scattered once made no difference there). ``cost_per_s`` is the CPU
    time of one simulated second of a run (:func:`run_cost`): half a second of work per task keeps Dask's
    share near 1 %, four tasks per worker thread keep the workers evenly loaded to the end and make a lost worker
    cost little.

    Parameters
    ----------
    n : int
        Runs of the sweep.
    workers : int
        Worker threads in all (a process of the local cluster has one; ``dask worker`` starts one per core).
    duration : float
        Simulated time of each run [s].
    cost_per_s : float
        CPU time of one simulated second of a run [s/s].
    """
    work = math.ceil(0.5 / (max(cost_per_s, 1e-6) * max(duration, 1e-3)))
    return max(1, min(256, work, math.ceil(n / (4 * max(workers, 1)))))


def run_cost(ctx: SweepContext) -> float:
    """CPU seconds per simulated second of one run, roughly (for :func:`batch_size`), measured on the two-core
    machine: 4 ms for the compiled batch loop's controllers (PID family), 100 ms for the MPC, 15 ms else.

    Parameters
    ----------
    ctx : SweepContext
        The sweep's context; its design's controller kind sets the cost.
    """
    kind = (ctx.design.spec or {}).get("kind")
    if kind in BATCH_KINDS:
        return 0.004
    return 0.1 if kind == "mpc" else 0.015


def _run_jobs(plan: SweepPlan, *, engine: str, workers: int | None, scheduler: str | None, client: Any,
              batch: int | None, progress: Callable[[int, int], Any] | None) -> tuple[list[dict[str, Any]], dict]:
    jobs = plan.jobs
    n = len(jobs)
    rows: list[dict[str, Any] | None] = [None] * n  # by position in plan.jobs (a resumed sweep's are some indices)
    at = {job[0]: k for k, job in enumerate(jobs)}
    done = 0
    info: dict[str, Any] = {"engine": engine}
    if engine == "serial":
        size = batch or batch_size(n, 1, plan.context.duration, run_cost(plan.context))
        info.update(workers=1, where="this process", batch=size)
        try:
            for i0 in range(0, n, size):
                for r in sweep_task(plan.context, jobs[i0:i0 + size]):
                    rows[at[r["index"]]] = r
                done = min(n, i0 + size)
                if progress:
                    progress(done, n)
        except KeyboardInterrupt:  # Ctrl-C: the batches finished are handed over (none finished: a plain Ctrl-C)
            if not any(r is not None for r in rows):
                raise
            raise TasksInterrupted(rows, info) from None
        return rows, info  # type: ignore[return-value]
    if engine != "dask":
        raise InputError(f"engine = {engine!r}: expected 'dask' or 'serial'", field="engine")
    if client is None and not (scheduler or env_scheduler()):
        # a local cluster of no more processes than tasks (3 runs: 3, not 8; 2 runs in one --batch 1000 task: 1)
        workers = local_processes(math.ceil(n / batch) if batch else n, workers)
    # each local worker holds one run at once (a pair's 5000 s run is 4.2 GB: two of them fit no 8 GB machine)
    ctx = plan.context
    task_bytes = loop_bytes(ctx.design.nominal, ctx.duration, design_controller(ctx.design).Ts)
    eng = Engine(workers=workers, scheduler=scheduler, client=client, task_bytes=task_bytes)
    try:
        _run_on(eng, plan, rows, at, info, batch, progress)
    except KeyboardInterrupt:  # Ctrl-C (after the cluster's tasks were cancelled and it was closed, below)
        if not any(r is not None for r in rows):
            raise
        raise TasksInterrupted(rows, info) from None
    missing = [jobs[k][0] for k, r in enumerate(rows) if r is None]
    if missing:
        raise RuntimeError(f"runs {missing[:5]} never came back")
    return rows, info  # type: ignore[return-value]


def _run_on(eng: Engine, plan: SweepPlan, rows: list[dict[str, Any] | None], at: Mapping[int, int],
            info: dict[str, Any], batch: int | None, progress: Callable[[int, int], Any] | None) -> None:
    """Run ``plan``'s jobs on ``eng``'s cluster into ``rows`` (run index -> position: ``at``) and ``info``; close
    ``eng`` at the end, whatever ends it (a Ctrl-C too: the cluster's tasks cancelled first)."""
    from distributed import KilledWorker

    jobs, n, done = plan.jobs, len(plan.jobs), 0
    futures: dict[Any, Any] = {}
    try:
        w, threads = eng.workers, eng.threads
        # four tasks per thread: sized per worker, a cluster of `dask worker` (a thread per core) left most of its
        # threads idle (2 workers of 16 threads, 1000 runs: 8 tasks for 32 threads)
        size = batch or batch_size(n, threads, plan.context.duration, run_cost(plan.context))
        info.update(workers=w, threads=threads, where=eng.where, batch=size)
        dropped: list[dict[str, Any]] = list(eng.dropped)  # at the workers' check
        if dropped:
            info["dropped"] = dropped

        def on_drop(record: dict[str, Any]) -> None:
            dropped.append(record)
            info["dropped"] = dropped
        tag = uuid.uuid4().hex[:12]
        # each task checks them on its worker: one may join mid-sweep (parallel.checked)
        mine, stack = code_id(), numerics_versions()
        for b, i0 in enumerate(range(0, n, size)):
            part = jobs[i0:i0 + size]
            fut = eng.client.submit(checked, mine, sweep_task, plan.context, part, key=f"gearctl-sweep-{tag}-{b}",
                                    pure=False, numerics=stack)
            futures[fut] = part
        try:
            for fut, got, exc in completed(eng.client, list(futures), where=eng.where, on_drop=on_drop):
                part = futures.pop(fut)
                if isinstance(exc, KilledWorker):  # the batch killed its workers again and again: record, go on
                    got = [_row(plan.context, j, None, None, None, message=f"the batch of runs {part[0][0]}.."
                                f"{part[-1][0]} did not run: {killed_worker_text(exc)}") for j in part]
                elif exc is not None:
                    raise exc
                fut.release()
                for r in got:
                    if rows[at[r["index"]]] is not None:
                        raise RuntimeError(f"run {r['index']} came back twice")
                    rows[at[r["index"]]] = r
                done += len(got)
                if progress:
                    progress(done, n)
        except InputError as exc:  # the cluster failed mid-sweep: the runs finished are handed over, not lost
            if not done:
                raise
            raise _Unfinished(str(exc), rows=rows, info=info, field=exc.field) from None
    finally:
        eng.close(cancel=list(futures))  # (a Ctrl-C meanwhile is held until the cluster is closed)


class _Unfinished(InputError):
    """The cluster failed after some runs had finished: its message, and the rows so far (None: not finished)."""

    def __init__(self, message: str, *, rows: list[dict[str, Any] | None], info: dict[str, Any],
                 field: str | None) -> None:
        super().__init__(message, field=field)
        self.rows, self.info = rows, info


# --- results --------------------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class SweepResult:
    """A sweep's runs and summary.

    Attributes
    ----------
    settings : dict
        Model, controller, plant, reference, duration, seed, grid, points, runs, vary {key: spec},
        nominal {key: value}, the nominal design (``describe()``).
    vary : tuple of Vary
    runs : list of dict
        One per run, by index: ``index``, ``params`` {key: value}, ``seed`` (sensor noise), ``estimate``
        (when varied), ``status`` (``ok`` or ``failed``), ``message``, :data:`METRICS`, :data:`FLAGS`,
        ``command`` (the ``gearctl track`` line that reproduces the run alone) and with ``precision`` the
        ISO 230-2 figures and ``precision_command``. Failed runs keep the figures of their partial run
        where there is one, else None.
    summary : dict
        :func:`summarize`.
    engine : dict
        ``engine``, ``workers``, ``threads`` (theirs in all; on Dask), ``where``, ``batch`` (runs per task),
        ``wall_time`` [s]; ``dropped`` (on Dask, where a worker went silent holding tasks and was dropped from the
        scheduler, its tasks rerun on the others): ``[{"worker": address, "tasks": n, "restarted": bool}, ...]``
        (``restarted``: its nanny started a fresh worker in its place; else it was removed); ``interrupted``: true
        where a Ctrl-C stopped the sweep (a :class:`SweepInterrupted`'s result only).
    missing : tuple of int
        The indices of the runs that did not finish (a :class:`SweepIncomplete`'s or :class:`SweepInterrupted`'s
        result only; ``runs`` then holds the others); empty for a whole sweep.
    """

    settings: dict[str, Any]
    vary: tuple[Vary, ...]
    runs: list[dict[str, Any]]
    summary: dict[str, Any]
    engine: dict[str, Any]
    missing: tuple[int, ...] = ()

    @property
    def keys(self) -> list[str]:
        """The varied keys, in the order given."""
        return [v.key for v in self.vary]

    def column(self, name: str) -> np.ndarray:
        """A column over the runs as floats (a parameter or a figure; None -> nan).

        Parameters
        ----------
        name : str
            A varied key, or a figure of the runs (:data:`METRICS`, :data:`FLAGS`, ``estimate`` ...).
        """
        vals = [r["params"].get(name) if name in r["params"] else r.get(name) for r in self.runs]
        return np.array([np.nan if v is None else float(v) for v in vals])

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: ``settings``, ``engine``, ``summary``, ``runs``; and ``missing`` (the indices of the runs
        that did not finish) for a sweep that did not finish."""
        out: dict[str, Any] = {"settings": self.settings, "engine": self.engine, "summary": self.summary,
                               "runs": self.runs}
        if self.missing:
            out["missing"] = list(self.missing)
        return out

    def table(self) -> tuple[list[str], list[list[Any]]]:
        """The runs as a flat table: header and rows (parameters as columns, None for missing values)."""
        first = self.runs[0] if self.runs else {}
        head = ["index", "status", *self.keys, *(["estimate"] if "estimate" in first else []), *METRICS, *FLAGS,
                "seed"]
        if self.settings.get("precision"):
            head += [*ISO_FIGURES, "precision_message"]
        head += ["message", "command"] + (["precision_command"] if self.settings.get("precision") else [])
        rows = [[r["params"][h] if h in self.keys else r.get(h) for h in head] for r in self.runs]
        # a factor of each stage's value (Scale) is a plain number in a column named for it
        scaled = {h for h in self.keys if any(isinstance(r["params"].get(h), Scale) for r in self.runs)}
        rows = [[float(v) if isinstance(v, Scale) else v for v in row] for row in rows]
        return [f"{h}_factor" if h in scaled else h for h in head], rows


class SweepIncomplete(InputError):
    """A sweep the cluster could not finish (a silent worker holding tasks with no other worker left, the
    scheduler gone or silent, every worker gone), raised after some runs had finished: they are not lost.

    Parameters
    ----------
    message : str
        What happened, and how many runs did not finish.
    result : SweepResult
        The runs that finished (by index), their summary, and ``missing``: the indices of the others.
    field : str, optional
        As :class:`~gearctl.InputError` (``scheduler``).
    """

    def __init__(self, message: str, *, result: SweepResult, field: str | None = None) -> None:
        super().__init__(message, field=field)
        self.result = result


class SweepInterrupted(KeyboardInterrupt):
    """A sweep stopped by Ctrl-C (``KeyboardInterrupt``) after some runs had finished: they are not lost.

    A ``KeyboardInterrupt`` still (``except KeyboardInterrupt`` and a notebook's stop button see it as one; an
    ``except Exception`` or ``except InputError`` does not swallow it), carrying what finished. The cluster's tasks
    are cancelled and a local cluster closed before it is raised.

    Parameters
    ----------
    message : str
        How many runs finished, and how many did not.
    result : SweepResult
        The runs that finished (by index), their summary, ``missing`` (the indices of the others) and
        ``engine["interrupted"]`` true.
    """

    def __init__(self, message: str, *, result: SweepResult) -> None:
        super().__init__(message)
        self.result = result


def _quantiles(x: np.ndarray) -> dict[str, float] | None:
    x = x[np.isfinite(x)]
    if x.size == 0:
        return None
    q = np.percentile(x, [5, 50, 95, 99])
    return {"min": float(x.min()), "p5": float(q[0]), "median": float(q[1]), "p95": float(q[2]), "p99": float(q[3]),
            "max": float(x.max()), "mean": float(x.mean())}


def summarize(runs: Sequence[Mapping[str, Any]], keys: Sequence[str]) -> dict[str, Any]:
    """Summary of a sweep's runs.

    Parameters
    ----------
    runs : sequence of dict
        The runs' rows (:attr:`SweepResult.runs`).
    keys : sequence of str
        The varied keys (for ``sensitivity``).

    Returns
    -------
    dict
        ``runs``, ``ok``, ``failed`` (counts); ``rms_error`` and ``max_error``: {min, p5, median, p95,
        p99, max, mean} over the runs that ran to their end [rad]; ``fractions`` of all runs with a
        ``limit_cycle``, ``saturated`` actuator, ``impact_rate_high``, ``growing`` error, ``not_following``,
        ``falling_back``, ``chattering`` torque, ``failed``, and ``diverged`` (growing, or failed by divergence:
        not every failed run diverged); ``worst``: the
        run of largest RMS error (index, params, figures, command); ``failures``: the first ten failed runs
        (index, params, message, command); with the ISO 230-2 test (``precision``), ``reversal_value``,
        ``repeatability`` and ``accuracy``: their quantiles as ``rms_error``'s over the runs whose test ran [rad]
        (None where none did); ``sensitivity`` {key: {``rank_correlation``: Spearman's rho of the
        key with the RMS error, ``elasticity``: d ln(RMS) / d ln(key) from a joint least-squares fit of ln RMS on
        the ln of every positive varied key (None where a key takes non-positive values)}}.
    """
    from scipy.stats import rankdata

    n = len(runs)
    ok = [r for r in runs if r["status"] == "ok"]
    rms = np.array([r["rms_error"] for r in ok], dtype=float)
    mx = np.array([r["max_error"] for r in ok], dtype=float)
    flag = {k: sum(bool(r.get(k)) for r in runs) for k in FLAGS}
    failed = n - len(ok)
    # a failed run diverged where its message says so (a run may fail otherwise: an event budget spent, a solver's
    # fault); a run that ran to its end with a growing error counts too
    diverged = sum(bool(r.get("growing")) or (r["status"] != "ok" and "diverged" in str(r.get("message", "")))
                   for r in runs)
    out: dict[str, Any] = {"runs": n, "ok": len(ok), "failed": failed, "rms_error": _quantiles(rms),
                           "max_error": _quantiles(mx),
                           "fractions": {**{k: v / max(n, 1) for k, v in flag.items()}, "failed": failed / max(n, 1),
                                         "diverged": diverged / max(n, 1)}}
    if ok:
        w = ok[int(np.argmax(rms))]
        out["worst"] = {"index": w["index"], "params": w["params"], "rms_error": w["rms_error"],
                        "max_error": w["max_error"], "command": w["command"],
                        **({"estimate": w["estimate"]} if "estimate" in w else {})}
    else:
        out["worst"] = None
    for k in ISO_FIGURES:  # with --precision: the ISO 230-2 figures over the runs whose test ran [rad]
        if any(k in r for r in runs):
            out[k] = _quantiles(np.array([np.nan if r.get(k) is None else r[k] for r in runs], dtype=float))
    out["failures"] = [{"index": r["index"], "params": r["params"], "message": r["message"], "command": r["command"]}
                       for r in runs if r["status"] != "ok"][:10]
    sens: dict[str, Any] = {}
    good = rms > 0
    cols = {k: np.array([r["params"][k] for r in ok], dtype=float) for k in keys}
    logk = [k for k in keys if cols[k].size and np.all(cols[k] > 0) and np.ptp(cols[k]) > 0]
    elastic: dict[str, float] = {}
    if len(ok) > len(logk) + 1 and logk and np.all(good):
        A = np.column_stack([np.ones(len(ok)), *[np.log(cols[k]) for k in logk]])
        coef = np.linalg.lstsq(A, np.log(rms), rcond=None)[0]
        elastic = {k: float(c) for k, c in zip(logk, coef[1:], strict=True)}
    for k in keys:
        x = cols[k]
        rho = None
        if x.size > 2 and np.ptp(x) > 0 and np.ptp(rms) > 0:
            rho = float(np.corrcoef(rankdata(x), rankdata(rms))[0, 1])
        sens[k] = {"rank_correlation": rho, "elasticity": elastic.get(k)}
    out["sensitivity"] = sens
    return out


def grid_axes(result: SweepResult, metric: str = "rms_error") -> tuple[list[str], list[np.ndarray], np.ndarray]:
    """A grid sweep's figure as an array over its axes.

    Parameters
    ----------
    result : SweepResult
        A grid sweep's result.
    metric : str
        The figure (:meth:`SweepResult.column`), default ``"rms_error"``.

    Returns
    -------
    keys : list of str
    axes : list of ndarray
        The points of each key.
    values : ndarray
        ``metric`` of each grid point, shape ``[len(a) for a in axes]`` (nan where a run failed).

    Raises
    ------
    InputError
        If the sweep is not a grid.
    """
    if not result.settings.get("grid"):
        raise InputError("grid_axes needs a grid sweep (grid=True)", field="grid")
    axes = [v.grid(result.settings["points"]) for v in result.vary]
    vals = result.column(metric)
    fail = np.array([r["status"] != "ok" for r in result.runs])
    vals[fail] = np.nan
    return result.keys, axes, vals.reshape([a.size for a in axes])


def compare_grids(results: Mapping[str, SweepResult], baseline: str,
                  metric: str = "rms_error") -> dict[str, Any]:
    """Each controller's error over a baseline controller's, on grids that share their first key.

    Parameters
    ----------
    results : mapping
        Controller name -> grid sweep. The baseline's grid has one key ``x``; every other grid has ``x``
        as its first key, at the same points, and at most one more key ``y`` (e.g. ``estimate_error``).
    baseline : str
        The name of the baseline (e.g. ``pid``).
    metric : str
        The run figure compared.

    Returns
    -------
    dict
        ``x_key``, ``x`` (points), ``x_nominal``, ``baseline``, ``baseline_values`` (along x), and
        ``controllers`` {name: {``y_key``, ``y`` (None for a one-key grid), ``values`` and ``ratio``
        (controller over baseline at the same x), shaped (x,) or (x, y)}}.

    Raises
    ------
    InputError
        If the grids do not line up.
    """
    if baseline not in results:
        raise InputError(f"baseline {baseline!r} is not among the results ({', '.join(results)})", field="baseline")
    bkeys, baxes, bvals = grid_axes(results[baseline], metric)
    if len(bkeys) != 1:
        raise InputError(f"the baseline grid must vary one key, {baseline}'s varies {', '.join(bkeys)}",
                         field="baseline")
    out: dict[str, Any] = {"x_key": bkeys[0], "x": baxes[0], "baseline": baseline, "baseline_values": bvals,
                           "x_nominal": results[baseline].settings.get("nominal", {}).get(bkeys[0]),
                           "controllers": {}}
    for name, res in results.items():
        if name == baseline:
            continue
        keys, axes, vals = grid_axes(res, metric)
        if keys[0] != bkeys[0] or len(keys) > 2 or axes[0].shape != baxes[0].shape or \
                not np.allclose(axes[0], baxes[0], rtol=1e-12, atol=0.0):
            raise InputError(f"{name}'s grid ({', '.join(keys)}) does not share {baseline}'s points of {bkeys[0]}",
                             field="results")
        ratio = vals / (bvals[:, None] if vals.ndim == 2 else bvals)
        out["controllers"][name] = {"y_key": keys[1] if len(keys) == 2 else None,
                                    "y": axes[1] if len(keys) == 2 else None, "values": vals, "ratio": ratio}
    return out


# --- the entry point ------------------------------------------------------------------------------------

def sweep(model: str | Path = "shing1993_servo", controller: str | Path = "deadzone_inverse", *,
          vary: Sequence[str] | Mapping[str, str] = (), runs: int | None = None, grid: bool = False,
          reference_kind: str = "sine", duration: float | None = None, seed: int = 0, plant: str = "improved",
          precision: bool = False, workers: int | None = None, scheduler: str | None = None, client: Any = None,
          engine: str = "dask", batch: int | None = None,
          progress: Callable[[int, int], Any] | None = None) -> SweepResult:
    """Run a controller, designed once on the nominal model, on many perturbed plants.

    Parameters
    ----------
    model, controller : str or Path
        Catalog names or TOML paths.
    vary : str, sequence of str or mapping
        ``"KEY=SPEC"`` strings (one string: one key) or ``{key: spec}`` (module docstring). No key: every run is
        the nominal plant with its own sensor-noise seed.
    runs : int, optional
        Monte Carlo runs (default 100), or with ``grid`` the points per key (default 5).
    grid : bool
        A full grid (the product of every key's points) instead of Monte Carlo draws.
    reference_kind : str
        ``sine``, ``step``, ``ramp`` or ``move``.
    duration : float, optional
        Simulated time of each run [s] (default per reference).
    seed : int
        Seed of the draws and of each run's sensor noise.
    plant : str
        True plant kind (``improved``, ``yang-sun``, ``tvms``); the design is always on the improved one.
    precision : bool
        Also the ISO 230-2 test per run (much longer: about 30 s simulated per run).
    workers : int, optional
        Processes of the local cluster (default: the cores available).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); default ``DASK_SCHEDULER_ADDRESS``,
        else a local cluster.
    client : distributed.Client, optional
        Use this client (left open); not with ``scheduler``.
    engine : str
        ``dask``, or ``serial``: every batch in this process, one after the other (the plain loop).
    batch : int, optional
        Runs per task (default :func:`batch_size`).
    progress : callable, optional
        ``progress(done, total)`` after each batch.

    Returns
    -------
    SweepResult

    Raises
    ------
    SweepIncomplete
        An :class:`~gearctl.InputError` whose ``result`` holds the runs that finished and names the others
        (``missing``), where the cluster failed mid-sweep after some had finished: no worker left, the scheduler
        gone or silent, or a silent worker holding tasks that could not be dropped (a silent worker is dropped
        while another is left, and the sweep goes on: ``engine["dropped"]``).
    SweepInterrupted
        A ``KeyboardInterrupt`` (Ctrl-C) after some runs had finished, whose ``result`` holds them as
        :class:`SweepIncomplete`'s does (``engine["interrupted"]`` true); before any had finished, a plain
        ``KeyboardInterrupt``. Either way the cluster's tasks are cancelled first.
    InputError
        Before any run: a bad spec or setting, a draw outside its key's range, an invalid perturbed model,
        a design that fails on the nominal model, too many runs for the memory; a scheduler that cannot be
        reached or has no worker; both ``client`` and ``scheduler``; the cluster failing before any run finished.
    """
    t0 = time.perf_counter()
    check_one_cluster(client, scheduler)  # before the design, as every check
    plan = plan_sweep(model, controller, vary=vary, runs=runs, grid=grid, reference_kind=reference_kind,
                      duration=duration, seed=seed, plant=plant, precision=precision)
    if batch is not None:
        SWEEP_RUNS.check("batch", batch)
    return _execute(plan, t0=t0, engine=engine, workers=workers, scheduler=scheduler, client=client, batch=batch,
                    progress=progress)


def _execute(plan: SweepPlan, *, t0: float, engine: str, workers: int | None, scheduler: str | None, client: Any,
             batch: int | None, progress: Callable[[int, int], Any] | None, before: Sequence[dict[str, Any]] = (),
             record: Mapping[str, Any] | None = None) -> SweepResult:
    """Run ``plan``'s jobs and make the sweep's result: with ``before`` (the runs a resumed sweep reuses; ``plan``'s
    jobs are then its missing ones) merged in by index, the summary over them all, and ``record`` added to the
    engine's record. A Ctrl-C or a cluster failed mid-way: :class:`SweepInterrupted` or :class:`SweepIncomplete`
    carrying the runs finished, ``before`` included."""
    keys = [v.key for v in plan.vary]
    total = int(plan.settings["runs"])

    def whole(got: Sequence[dict[str, Any] | None], info: dict[str, Any]) -> SweepResult:
        done = sorted([*before, *(r for r in got if r is not None)], key=lambda r: r["index"])
        missing = tuple(plan.jobs[k][0] for k, r in enumerate(got) if r is None)
        info["wall_time"] = time.perf_counter() - t0
        info.update(record or {})
        return SweepResult(settings=plan.settings, vary=plan.vary, runs=done, summary=summarize(done, keys),
                           engine=info, missing=missing)

    try:
        rows, info = _run_jobs(plan, engine=engine, workers=workers, scheduler=scheduler, client=client,
                               batch=batch, progress=progress)
    except TasksInterrupted as exc:  # Ctrl-C: a KeyboardInterrupt still, with the runs that finished
        exc.info["interrupted"] = True
        partial = whole(exc.results, exc.info)
        raise SweepInterrupted(f"interrupted: {len(partial.runs)} of {total} runs finished, {len(partial.missing)} "
                               f"did not", result=partial) from None
    except _Unfinished as exc:  # the runs that finished, as a whole sweep's result with `missing`
        partial = whole(exc.rows, exc.info)
        missing = partial.missing
        shown = ", ".join(map(str, missing[:10])) + (", ..." if len(missing) > 10 else "")
        raise SweepIncomplete(f"{exc}; {len(missing)} of {total} runs did not finish (runs {shown}), "
                              f"{len(partial.runs)} did", result=partial, field=exc.field) from None
    return whole(rows, info)


# --- resuming a sweep that did not finish -------------------------------------------------------------------

#: The settings a sweep's JSON must hold to be resumed (:func:`resume`).
_RESUME_SETTINGS = ("model", "controller", "plant", "reference", "duration", "seed", "grid", "points", "runs",
                    "precision", "vary", "gearctl", "numerics", "files")


def file_hashes(model: str | Path, controller: str | Path) -> dict[str, str]:
    """SHA-256 of the model's and the controller's files (a catalog name's too), as a sweep's ``settings.files``
    records them: a sweep resumed after either file changed would run other plants or another controller.

    Parameters
    ----------
    model, controller : str or Path
        Catalog names or TOML paths, as the sweep was given them.

    Returns
    -------
    dict
        ``{"model": hex digest, "controller": hex digest}``.
    """
    import hashlib

    from .files import resolve

    return {kind[:-1]: hashlib.sha256(resolve(name, kind).read_bytes()).hexdigest()
            for kind, name in (("models", model), ("controllers", controller))}


def _as_json(obj: Any) -> Any:
    """``obj`` as its JSON reads back (as ``gearctl sweep --json`` writes it, dict keys as strings): what settings
    and draws are compared as."""
    import json

    return json.loads(json.dumps(json_ready(obj)))


#: Bytes of Python objects per byte of a sweep's JSON read back (measured 1.4 on a 200-run sweep's --json; headroom).
_JSON_GROWTH = 4


def _load_previous(previous: Any) -> tuple[dict[str, Any], str | None, SweepResult | None]:
    """The previous sweep as its JSON dict, the file it came from (None: not a file) and the result (a
    :class:`SweepResult` given)."""
    import json
    import os

    if isinstance(previous, SweepResult):
        return _as_json(previous.as_dict()), None, previous
    if isinstance(previous, Mapping):
        return dict(previous), None, None
    if not isinstance(previous, str | os.PathLike):
        raise InputError(f"previous = {type(previous).__name__}: expected a SweepResult, the dict of a sweep's JSON "
                         f"or the path of a `gearctl sweep --json` file", field="resume")
    path = str(previous)
    try:
        with open(path, encoding="utf-8") as fh:
            # read, a JSON text takes some _JSON_GROWTH times its size in Python objects: one that would not fit in
            # half the memory available is refused with the figure (a 1e6-run sweep's is some 0.85 GB of text)
            size, avail = os.fstat(fh.fileno()).st_size, available_memory()
            if avail is not None and _JSON_GROWTH * size > avail // 2:
                raise InputError(f"--resume {path}: {size / 1e9:.3g} GB of JSON would take about "
                                 f"{_JSON_GROWTH * size / 1e9:.3g} GB to read, more than half the memory available "
                                 f"({avail / 2e9:.3g} GB)", field="resume")
            data = json.load(fh)
    except OSError as exc:
        raise InputError(f"--resume {path}: cannot read it: {exc.strerror or exc}", field="resume") from None
    except UnicodeDecodeError:
        raise InputError(f"--resume {path}: not a gearctl sweep's JSON (not text)", field="resume") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"--resume {path}: not a gearctl sweep's JSON (not JSON: {exc.msg} at line {exc.lineno})",
                         field="resume") from None
    return data, path, None


def _refuse(what: str, why: str) -> InputError:
    return InputError(f"{what}: {why}", field="resume")


def resume(previous: SweepResult | Mapping[str, Any] | str | Path, *, workers: int | None = None,
           scheduler: str | None = None, client: Any = None, engine: str = "dask", batch: int | None = None,
           progress: Callable[[int, int], Any] | None = None) -> SweepResult:
    """Finish a sweep that did not: rerun only its ``missing`` runs and return the whole sweep.

    A sweep the cluster could not finish (:class:`SweepIncomplete`) or a Ctrl-C stopped (:class:`SweepInterrupted`)
    hands over the runs finished and ``missing``, the indices of the others; ``gearctl sweep --json`` writes them.
    Every setting (model, controller, plant, reference, duration, seed, grid, points, vary, precision) is the
    previous sweep's: the sweep is planned again from them (the draws of run ``i`` depend on the seed, ``i`` and the
    key alone, so run ``i`` is the very run it would have been), the reused runs' draws are checked against the plan,
    and the missing runs are run. The result is the sweep a whole run would have given: runs in index order (the
    same figures), the summary over all of them, ``missing`` empty or what still did not finish; its ``engine``
    records this part and ``resumed`` ``{"from": file or None, "reused": n, "rerun": n, "previous": the previous
    sweep's engine record}``.

    Parameters
    ----------
    previous : SweepResult, dict, str or Path
        The previous sweep: its result (``exc.result`` of the exception), the dict of its JSON, or the path of its
        ``--json`` file.
    workers, scheduler, client, engine, batch
        As :func:`sweep` (how the runs are run, not what they are). ``batch``: default sized for the runs rerun.
    progress : callable, optional
        ``progress(done, total)`` after each batch, over the runs rerun.

    Returns
    -------
    SweepResult

    Raises
    ------
    SweepIncomplete, SweepInterrupted
        As :func:`sweep`: their ``result`` holds the runs reused and those finished now, ``missing`` the others
        (resume that in turn).
    InputError
        ``field`` ``resume``, one line naming what is wrong, before any run: not a sweep's JSON; a sweep of another
        gearctl (``settings.gearctl``, its version and a hash of its code: the settings and figures could differ in
        meaning; one written before sweeps recorded it) or other numerical libraries (``settings.numerics``); a
        sweep with no ``missing`` runs; runs and ``missing`` that do not make up its runs; a model or controller
        file changed since (``settings.files``, their SHA-256), or settings or draws that differ from the plan
        made again from them. Else as :func:`sweep`.
    """
    t0 = time.perf_counter()
    check_one_cluster(client, scheduler)
    data, source, given = _load_previous(previous)
    what = f"--resume {source}" if source is not None else "the previous sweep"
    if not (isinstance(data, Mapping) and isinstance(data.get("settings"), Mapping)
            and isinstance(data.get("runs"), list) and isinstance(data.get("engine"), Mapping)):
        raise _refuse(what, "not a gearctl sweep's JSON (expected settings, engine, summary and runs, as `gearctl "
                            "sweep --json` writes them)")
    st = dict(data["settings"])
    if "gearctl" not in st:
        raise _refuse(what, "written by a gearctl that did not record its version and files (before sweeps could "
                            "be resumed): run the whole sweep again")
    lacking = [k for k in _RESUME_SETTINGS if k not in st]
    if lacking:
        raise _refuse(what, f"not a gearctl sweep's JSON: its settings lack {', '.join(lacking)}")
    if st["gearctl"] != code_id():
        raise _refuse(what, f"written by gearctl {st['gearctl']}, this is {code_id()} (version+code hash): its "
                            f"settings and figures may not mean the same here; resume it with that gearctl, or run "
                            f"the whole sweep again")
    here = numerics_versions()
    differ = ", ".join(f"{k} {v} (this process: {here.get(k, 'not reported')})"
                       for k, v in sorted(dict(st["numerics"]).items()) if here.get(k) != v)
    if differ:
        raise _refuse(what, f"run on {differ}: the runs rerun here would differ in their last digits; resume it "
                            f"where the sweep ran, or run the whole sweep again")
    runs_n = st["runs"]
    if not (type(runs_n) is int and isinstance(st["files"], Mapping) and isinstance(st["numerics"], Mapping)
            and isinstance(st["vary"], Mapping)):
        raise _refuse(what, "not a gearctl sweep's JSON: its settings runs, vary, numerics or files are not what "
                            "`gearctl sweep --json` writes")
    missing = data.get("missing")
    if not missing:
        raise _refuse(what, f"the sweep finished (no missing runs: all {runs_n} ran): nothing to resume")
    done = [dict(r) for r in (given.runs if given is not None else data["runs"])]
    ids = [r.get("index") if isinstance(r, Mapping) else None for r in done]
    if not (isinstance(missing, list | tuple) and all(type(i) is int for i in (*missing, *ids))
            and sorted([*missing, *ids]) == list(range(int(runs_n)))):
        raise _refuse(what, f"its runs ({len(done)}) and missing ({len(missing) if isinstance(missing, list) else '?'})"
                            f" do not make up its {runs_n} runs, each once")
    try:
        now = file_hashes(st["model"], st["controller"])
    except InputError as exc:
        raise _refuse(what, f"{exc}") from None
    for kind in ("model", "controller"):
        if dict(st["files"]).get(kind) != now[kind]:
            raise _refuse(what, f"the {kind} file {st[kind]} changed since the sweep (its SHA-256 differs): the "
                                f"runs rerun would not be the same {'plants' if kind == 'model' else 'controller'}; "
                                f"run the whole sweep again")
    try:
        plan = plan_sweep(st["model"], st["controller"], vary=dict(st["vary"]), runs=st["points"], grid=st["grid"],
                          reference_kind=st["reference"], duration=st["duration"], seed=st["seed"], plant=st["plant"],
                          precision=st["precision"])
    except InputError as exc:
        raise _refuse(what, f"its settings are refused here: {exc}") from None
    mine, theirs = _as_json(plan.settings), _as_json(st)
    changed = [k for k in sorted(set(mine) | set(theirs)) if mine.get(k) != theirs.get(k)]
    if changed:
        raise _refuse(what, f"its settings differ from those planned again from them ({', '.join(changed)}): the "
                            f"runs rerun would not be the sweep's; run the whole sweep again")
    jobs = {job[0]: job for job in plan.jobs}
    factors = set(st.get("factors") or ())
    for r in done:
        job = jobs[r["index"]]
        if _as_json([r.get("params"), r.get("seed")]) != _as_json([job[1], job[2]]):
            raise _refuse(what, f"run {r['index']}'s draws ({r.get('params')}, seed {r.get('seed')}) differ from "
                                f"those planned again ({job[1]}, seed {job[2]}): run the whole sweep again")
        if given is None:  # read back from JSON: a factor of each stage's value is a Scale again, as the run's own
            r["params"] = {k: Scale(v) if k in factors else v for k, v in r["params"].items()}
    if batch is not None:
        SWEEP_RUNS.check("batch", batch)
    todo = sorted(missing)
    record = {"resumed": {"from": source, "reused": len(done), "rerun": len(todo), "previous": dict(data["engine"])}}
    return _execute(dataclasses.replace(plan, jobs=[jobs[i] for i in todo]), t0=t0, engine=engine, workers=workers,
                    scheduler=scheduler, client=client, batch=batch, progress=progress, before=done, record=record)


def sweep_perf(controllers: Sequence[str] = ("pid", "deadzone_inverse", "mpc"), *, runs: int = 200,
               duration: float = 1.0, model: str = "shing1993_servo", workers: int | None = None,
               batch: int | None = None, python_runs: int = 40, slow_runs: int = 50,
               repeats: int = 3) -> dict[str, dict[str, Any]]:
    """Throughput of sweeps: the Dask path against a plain sequential loop of the same runs, in one call.

    Each controller runs ``runs`` sine runs (``slow_runs`` for a controller outside the compiled batch loop,
    e.g. the MPC) of ``duration`` seconds on plants with the backlash drawn from
    0.5x to 2x nominal: first a plain loop (:func:`sweep_task` over the batches, one after the other) in one
    worker process of a local Dask cluster started beforehand, then the same runs through that cluster. Both
    run in worker processes, so both see what a sweep sees: one BLAS thread (Dask's nanny sets that) and a
    controller designed before the clock starts. The two paths alternate chunk by chunk (an eighth of the runs
    through the plain loop, then the same through Dask), ``repeats`` times over: a drift of the machine's speed
    falls on both alike. ``dask_overhead`` compares the totals; the times per path are the least total over the
    repeats. The cluster's start-up is reported apart.

    Parameters
    ----------
    controllers : sequence of str
        Controller names or files.
    runs : int
        Runs per controller in the compiled batch loop.
    duration : float
        Simulated time of each run [s].
    model : str
        The nominal model's name or file.
    workers : int, optional
        Processes of the local cluster (default: the cores available).
    batch : int, optional
        Runs per task (default :func:`batch_size`).
    python_runs : int
        Runs timed through :func:`gearctl.runs.execute` for ``python_per_run_s``.
    slow_runs : int
        At most this many runs for a controller outside the compiled batch loop.
    repeats : int
        How often the alternation of the two paths is repeated.

    Returns
    -------
    dict
        controller -> {``per_run_s``: CPU seconds of one run in the plain loop (the compiled batch loop for
        the PID family); ``python_per_run_s``: the same runs through :func:`gearctl.runs.execute` (the Python
        loop around the compiled kernel; ``python_runs`` of them), and ``speedup``, their ratio;
        ``runs_per_s``: runs per second per worker through Dask (``runs / (dask wall time x workers)``);
        ``dask_overhead``: the CPU time Dask adds over the plain loop, ``(workers' + this process's CPU time
        during the Dask sweep) / loop CPU time - 1`` (this process hosts the scheduler);
        ``dask_overhead_wall``: ``workers x Dask wall time / loop wall time - 1``, which only means something
        on an otherwise idle machine; ``loop_s``, ``dask_s`` (wall), ``loop_cpu_s``, ``dask_cpu_s`` [s];
        ``client_cpu_s``: this process's share of ``dask_cpu_s`` (client and scheduler), the part of the
        overhead the worker's noise does not blur;
        ``runs``, ``workers``, ``batch``, ``duration``, ``cluster_start_s``; ``load``: the 1-minute load
        average after the measurement; ``identical``: whether both paths gave the same results}.

    Notes
    -----
    CPU times (``time.process_time`` of each process) are what this measures best: on a shared machine the
    wall times follow the other users' load, the CPU time a run needs much less.
    """
    import distributed

    from .kernel import compiled_available

    compiled_available()
    w = workers or default_workers()
    out: dict[str, dict[str, Any]] = {}
    t = time.perf_counter()
    with local_cluster(w) as cluster, distributed.Client(cluster, set_as_default=False) as client:
        client.run(_warm)  # import gearctl in every worker: start-up, not sweep
        start = time.perf_counter() - t
        first = sorted(client.scheduler_info()["workers"])[:1]
        for c in controllers:
            n = runs if controller_spec(c)[0].get("kind") in BATCH_KINDS else min(runs, slow_runs)
            plan = plan_sweep(model, c, vary=["backlash=0.5x:2x"], runs=n, duration=duration)
            client.run(_design, plan.context)
            size = batch or batch_size(n, w, duration, run_cost(plan.context))
            # the two paths alternate chunk by chunk (8 chunks of the runs, each through the plain loop, then through
            # Dask), ``repeats`` times: the machine's drifts fall on both alike, and the totals are compared
            step = max(size, math.ceil(n / 8))
            chunks = [dataclasses.replace(plan, jobs=[(j, prm, sd) for j, (_, prm, sd)
                                                      in enumerate(plan.jobs[i:i + step])])
                      for i in range(0, n, step)]  # numbered from 0 in each chunk (the runs keep their seeds)
            sums = {"loop_s": [0.0] * repeats, "loop_cpu": [0.0] * repeats, "dask_s": [0.0] * repeats,
                    "dask_cpu": [0.0] * repeats, "client": [0.0] * repeats}
            py_cpu, identical = math.nan, True
            for rep in range(repeats):
                for k, part in enumerate(chunks):
                    first_py = python_runs if (rep == 0 and k == 0) else 0
                    rows_l, _, ls, lc, py = client.submit(_plain_loop, part, size, first_py, w, workers=first,
                                                          pure=False).result()
                    if first_py:
                        py_cpu = py
                    w0 = client.run(time.process_time)
                    t, c0 = time.perf_counter(), time.process_time()
                    rows_d, info = _run_jobs(part, engine="dask", workers=None, scheduler=None, client=client,
                                             batch=size, progress=None)
                    ds, here = time.perf_counter() - t, time.process_time() - c0
                    w1 = client.run(time.process_time)
                    for key, v in (("loop_s", ls), ("loop_cpu", lc), ("dask_s", ds),
                                   ("dask_cpu", here + sum(w1[q] - w0[q] for q in w1)), ("client", here)):
                        sums[key][rep] += v
                    identical = identical and rows_l == rows_d
            loop_s, loop_cpu, dask_s = min(sums["loop_s"]), min(sums["loop_cpu"]), min(sums["dask_s"])
            client_cpu = min(sums["client"])
            overhead = sum(sums["dask_cpu"]) / sum(sums["loop_cpu"]) - 1.0
            dask_cpu = min(sums["dask_cpu"])
            out[c] = {"per_run_s": loop_cpu / n, "python_per_run_s": py_cpu, "speedup": py_cpu / (loop_cpu / n),
                      "runs_per_s": n / dask_s / w,
                      "dask_overhead": overhead, "dask_overhead_wall": w * dask_s / loop_s - 1.0,
                      "loop_s": loop_s, "dask_s": dask_s, "loop_cpu_s": loop_cpu, "dask_cpu_s": dask_cpu,
                      "client_cpu_s": client_cpu,
                      "runs": n, "workers": w, "batch": size, "duration": duration,
                      "cluster_start_s": start, "load": os.getloadavg()[0], "identical": identical,
                      "repeats": repeats}
    return out


def _plain_loop(plan: SweepPlan, batch: int | None, python_runs: int,
                workers: int) -> tuple[list, int, float, float, float]:
    """The plain loop of :func:`sweep_perf`, in a worker: rows, batch size, wall and CPU time; and the CPU
    time of one run built as the sweep builds it and run by :func:`gearctl.runs.execute` (the Python loop),
    median over ``python_runs``."""
    from .runs import execute

    sweep_task(plan.context, plan.jobs[:1])  # the design, once per process, as every worker does
    size = batch or batch_size(len(plan.jobs), workers, plan.context.duration, run_cost(plan.context))
    t, c0 = time.perf_counter(), time.process_time()
    rows, _ = _run_jobs(plan, engine="serial", workers=None, scheduler=None, client=None, batch=size, progress=None)
    loop_s, loop_cpu = time.perf_counter() - t, time.process_time() - c0
    cpu = []
    for job in plan.jobs[:python_runs]:
        c0 = time.process_time()
        run, _ = _build_run(plan.context, job)
        execute(run)
        cpu.append(time.process_time() - c0)
    return rows, size, loop_s, loop_cpu, float(np.median(cpu)) if cpu else math.nan


def _warm() -> None:
    from . import closedloop, runs  # noqa: F401


def _design(ctx: SweepContext) -> None:
    design_controller(ctx.design)
