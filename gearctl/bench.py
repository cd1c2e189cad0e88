"""The closed-loop benchmark: every controller against every plant on the same references, and an ISO 230-2
positioning row per controller.

:meth:`BenchSpec.runs` turns the catalog names into :class:`~gearctl.runs.Run` values (plants and designs as
numbers, built once here), and :func:`run_bench` executes a list of them, spread over worker processes. Each
run is one controller (designed on the model's improved plant) against one plant (improved, Yang–Sun,
time-varying stiffness, or the backlash-free limit) on one reference. The result holds every run's figures
and the ratios that matter: compensated error over the PID's, each error over the backlash-free plant's
under the same controller, and the improved plant's error over Yang–Sun's (how much the choice of plant
model changes the prediction); plus, on the sine, each controller designed on the Yang–Sun plant and run on
the improved one (how a design on one model fares on the other); and the ISO 230-2 figures of each
controller on the improved plant against the backlash-free PID's.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TypedDict

import numpy as np

from .catalog import controller_names, load_model, resolve
from .closedloop import check_loop_duration, loop_bytes
from .errors import GearctlError, InputError
from .kernel import compiled_available
from .parallel import TasksInterrupted, check_one_cluster, map_tasks
from .plant import PlantKind, build_plant
from .references import DEFAULT_DURATION, REFERENCES, reference
from .runs import Design, Run, controller_spec, design_controller, execute, run_sample_time, unholdable_load_step
from .units import DURATION, SEED

__all__ = ["BenchSpec", "BenchInterrupted", "run_bench", "bench_table", "bench_notes", "bench_warnings",
           "grouped_warnings", "DEFAULT_DURATION", "FREE", "ISO_SETTINGS"]

#: Label of the backlash-free plant (the physical limit).
FREE = "backlash-free"


class IsoSettings(TypedDict):
    """The keyword arguments of :func:`gearctl.precision.precision_test` that the bench fixes."""

    targets: int
    cycles: int
    travel: float
    dwell: float


#: The ISO 230-2 cycle of the benchmark's positioning row (as ``gearctl precision`` runs it).
ISO_SETTINGS: IsoSettings = {"targets": 5, "cycles": 5, "travel": 0.5, "dwell": 0.3}


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class BenchSpec:
    """What to run.

    Attributes
    ----------
    models : tuple of str
        Model names or paths.
    controllers : tuple of str
        Controller names or paths.
    plants : tuple of str
        Plant kinds (``improved``, ``yang-sun``, ``tvms``); the backlash-free plant is always added.
    references : tuple of str
        Reference kinds.
    duration : float or None
        Simulated time of every run [s] (None: per reference, :data:`DEFAULT_DURATION`).
    seed : int
        Sensor-noise seed.
    cross_design : bool
        Also run each controller designed on the Yang–Sun plant against the improved plant (sine), where
        ``plants`` holds both.
    realtime : bool
        Optimisations that overrun their time budget fall back, as on the target (default False:
        overruns are counted and the results are deterministic for a seed).
    precision : bool
        Add an ISO 230-2 positioning row per controller (improved plant), and the backlash-free PID's.

    Raises
    ------
    InputError
        For no ``plants`` or ``references``, a name given twice, an unknown plant kind or reference, a
        ``duration`` or ``seed`` out of range, or a model or controller that is neither a catalog name nor a file
        (named).
    """

    models: tuple[str, ...] = ("shing1993_servo",)
    controllers: tuple[str, ...] = ()
    plants: tuple[str, ...] = ("improved", "yang-sun", "tvms")
    references: tuple[str, ...] = ("sine", "move", "step")
    duration: float | None = None
    seed: int = 0
    cross_design: bool = True
    realtime: bool = False
    precision: bool = True

    def __post_init__(self) -> None:
        # none asked for ran nothing (exit 0, empty tables), twice ran each run twice and named the controller its
        # own runner-up: both refused rather than changed
        kinds = (("plants", self.plants, ", ".join(k.value for k in PlantKind)),
                 ("references", self.references, ", ".join(REFERENCES)))
        for field, values, allowed in kinds:
            if not values:
                raise InputError(f"{field}: none given: expected one or more of {allowed}", field=field)
        for field, values in (*((f, v) for f, v, _ in kinds), ("models", self.models),
                              ("controllers", self.controllers)):
            twice = sorted({v for v in values if values.count(v) > 1})
            if twice:
                raise InputError(f"{field}: {', '.join(map(repr, twice))} given more than once: expected each once "
                                 "(every run would run twice)", field=field)
        for p in self.plants:
            try:
                PlantKind(p)
            except ValueError:
                raise InputError(f"plant = {p!r} is not a plant: expected one of "
                                 f"{', '.join(k.value for k in PlantKind)}", field="plants") from None
        for r in self.references:
            if r not in REFERENCES:
                raise InputError(f"reference = {r!r} is not a reference: expected one of {', '.join(REFERENCES)}",
                                 field="references")
        if self.duration is not None:
            DURATION.check("duration", self.duration)
        SEED.check("seed", self.seed)
        for m in self.models:
            resolve(m, "models")
        for c in self.controllers:
            resolve(c, "controllers")

    def skipped(self) -> list[dict[str, str]]:
        """Catalog controllers left out of a model's rows: ``{model, controller, reason}``.

        With the default controllers (every catalog entry), a model whose servo has no load encoder
        (``[sensors] load_encoder = false``) runs only those on the motor encoder; controllers named in
        :attr:`controllers` always run (and one that reads the missing encoder fails with the reason).
        """
        if self.controllers:
            return []
        out = []
        for m in self.models:
            model = load_model(m)
            if model.sensors.load_encoder:
                continue
            plant = build_plant(model)
            for c in controller_names():
                if design_controller(Design(spec=controller_spec(c)[0], nominal=plant)).uses_load_encoder:
                    out.append({"model": m, "controller": c,
                                "reason": "reads the load encoder, and the servo has none ([sensors] load_encoder = "
                                          "false)"})
        return out

    def _controllers(self, m: str, skipped: Sequence[dict[str, str]]) -> tuple[str, ...]:
        left_out = {s["controller"] for s in skipped if s["model"] == m}
        return tuple(c for c in (self.controllers or tuple(controller_names())) if c not in left_out)

    def runs(self, skipped: Sequence[dict[str, str]] | None = None) -> list[Run]:
        """The independent tracking runs, as values (plants and designs built once, here); ``skipped``:
        :meth:`skipped`, computed if not given.

        Parameters
        ----------
        skipped : sequence of dict, optional
            ``{model, controller, reason}`` rows of the controllers left out (:meth:`skipped`, computed if not
            given).

        Returns
        -------
        list of Run
        """
        skipped = self.skipped() if skipped is None else skipped
        out = []
        for m in self.models:
            model = load_model(m)
            ctrls = self._controllers(m, skipped)
            true = {p: build_plant(model, p) for p in self.plants}
            true[FREE] = build_plant(model, backlash=0.0)
            nominal = {"improved": build_plant(model), "yang-sun": build_plant(model, "yang-sun"), FREE: true[FREE]}
            for c in ctrls:
                spec, label = controller_spec(c)
                cells = [(p, "improved", r) for r in self.references for p in (*self.plants, FREE)]
                # on the improved plant beside its own design's run: both plants asked for (with yang-sun alone the
                # cross cell looked up an improved plant that was never built: KeyError)
                if (self.cross_design and "sine" in self.references and "yang-sun" in self.plants
                        and "improved" in self.plants):
                    cells.append(("improved", "yang-sun", "sine"))
                for p, d, r in cells:
                    design = Design(spec=spec, nominal=nominal[FREE] if p == FREE else nominal[d], label=label,
                                    sensors=model.sensors)
                    out.append(Run(plant=true[p], design=design, reference=reference(r),
                                   duration=self.duration or DEFAULT_DURATION[r], seed=self.seed, sensors=model.sensors,
                                   realtime=self.realtime,
                                   tags={"model": m, "controller": c, "plant": p, "design": d, "reference": r}))
        return out

    def precision_runs(self, skipped: Sequence[dict[str, str]] | None = None) -> list[dict[str, Any]]:
        """The ISO 230-2 rows: each controller on the improved plant, and the PID on the backlash-free one.

        Parameters
        ----------
        skipped : sequence of dict, optional
            ``{model, controller, reason}`` rows of the controllers left out (:meth:`skipped`, computed if not
            given).

        Returns
        -------
        list of dict
            One row per ISO run (model, controller, plant, true plant, sensors, design, seed); empty without
            :attr:`precision`.
        """
        if not self.precision:
            return []
        skipped = self.skipped() if skipped is None else skipped
        out = []
        for m in self.models:
            model = load_model(m)
            ctrls = self._controllers(m, skipped)
            plant, free = build_plant(model), build_plant(model, backlash=0.0)
            for c in ctrls:
                spec, label = controller_spec(c)
                out.append({"model": m, "controller": c, "plant": "improved", "true": plant, "sensors": model.sensors,
                            "design": Design(spec=spec, nominal=plant, label=label, sensors=model.sensors),
                            "seed": self.seed})
            if "pid" in ctrls:
                spec, label = controller_spec("pid")
                out.append({"model": m, "controller": "pid", "plant": FREE, "true": free, "sensors": model.sensors,
                            "design": Design(spec=spec, nominal=free, label=label, sensors=model.sensors),
                            "seed": self.seed})
        return out


def _row(run: Run) -> dict[str, Any]:
    """Worker: one tracking run as a JSON-ready row."""
    res = execute(run)
    out: dict[str, Any] = {**dict(run.tags), "duration": run.duration, "seed": run.seed, "realtime": run.realtime}
    out.update({"ok": res.ok, "message": res.message})
    if res.metrics is not None:
        m = res.metrics.as_dict()
        health = m.pop("health")
        out.update({"name": res.controller.get("name"), "Ts": res.controller.get("Ts"),
                    "preview": res.controller.get("preview", 1), **m, "warnings": list(health["warnings"]),
                    "design_notes": list(res.controller.get("design_notes", ()))})
    too_large = unholdable_load_step(run.plant, run.reference)  # the likely cause of a failure: say it
    out["unholdable_load_step"] = too_large  # the tables mark the row: its figures measure the load running away
    if too_large:
        out["warnings"] = [*out.get("warnings", ()), too_large]
        if not res.ok:
            out["message"] = f"{res.message}; {too_large}"
    if res.ok:
        out.update({"trace_t": res.trace_t.tolist(), "trace_error": res.trace_error.tolist()})
    return out


def _precision_row(job: dict[str, Any]) -> dict[str, Any]:
    """Worker: one ISO 230-2 test."""
    from .precision import precision_health, precision_test

    out = {k: job[k] for k in ("model", "controller", "plant", "seed")}
    try:
        ctrl = design_controller(job["design"])
        res = precision_test(job["true"], ctrl, sensors=job["sensors"], seed=job["seed"], **ISO_SETTINGS)
    except GearctlError as exc:
        out.update({"ok": False, "message": str(exc)})
        return out
    st = res.stats
    # the warnings `gearctl precision` gives: the loop's health, targets not reached, a constant offset
    warnings = list(precision_health(res, job["true"].lost_motion, ISO_SETTINGS["travel"]).warnings)
    out.update({"ok": True, "message": "ok", "accuracy": st["accuracy"], "reversal_value": st["reversal_value"],
                "repeatability": st["repeatability"], "mean_deviation": st["mean_deviation"],
                "largest_deviation": st["largest_deviation"], "lost_motion": job["true"].lost_motion,
                "warnings": warnings})
    return out


def _task(task: tuple[Callable[[Any], dict[str, Any]], Any]) -> dict[str, Any]:
    fn, arg = task
    return fn(arg)


def run_bench(spec: BenchSpec, *, jobs: int | None = None, progress: Callable[[int, int], Any] | None = None,
              runs: Sequence[Run] | None = None, scheduler: str | None = None) -> dict[str, Any]:
    """Run the benchmark.

    Parameters
    ----------
    spec : BenchSpec
        What to run.
    jobs : int, optional
        Worker processes of the local Dask cluster (default: the cores this process may use; 1 runs in
        this process).
    progress : callable, optional
        ``progress(done, total)`` after each run.
    runs : sequence of Run, optional
        The tracking runs (default ``spec.runs()``).
    scheduler : str, optional
        ``tcp://HOST:PORT`` of a running Dask scheduler (see :class:`gearctl.parallel.Engine`).

    Returns
    -------
    dict
        ``runs`` (every run's figures), ``precision`` (the ISO rows), ``ratios`` {``over_pid``,
        ``over_backlash_free``, ``improved_over_yang_sun``, ``cross_design``, ``iso_over_backlash_free``,
        ``iso_over_pid`` (A, B, R over the PID's on the improved plant)},
        ``spec``, ``skipped`` (:meth:`BenchSpec.skipped`); ``dropped`` where a silent worker was dropped from the
        Dask scheduler and its tasks rerun on the others: ``[{"worker": address, "tasks": n, "restarted": bool}, ...]``
        as a sweep's ``engine["dropped"]`` (:class:`gearctl.sweep.SweepResult`).

    Raises
    ------
    BenchInterrupted
        A Ctrl-C after some runs had finished (the cluster's tasks cancelled and a local cluster closed first): its
        ``result`` is this function's, over the runs finished, with ``interrupted`` true and ``not_run``, the cells
        that did not finish. Before any had finished, a plain ``KeyboardInterrupt``.
    """
    check_one_cluster(None, scheduler)  # an empty address, before the designs
    skipped = spec.skipped()
    runs = list(runs if runs is not None else spec.runs(skipped))
    iso = spec.precision_runs(skipped)
    for r in runs:  # a run of no sample is refused before any starts (each failed alone, and the bench ended exit 0)
        check_loop_duration(r.duration, run_sample_time(r), who=f" of {Path(r.design.label).stem}")
    compiled_available()  # compile the kernel once before the workers start
    tasks: list[tuple[Callable[[Any], dict[str, Any]], Any]] = [(_row, r) for r in runs]
    tasks += [(_precision_row, j) for j in iso]
    # each local worker holds one run at once: the largest, at its controller file's sample time
    task_bytes = max((loop_bytes(r.plant, r.duration, run_sample_time(r)) for r in runs), default=0)
    dropped: list[dict[str, Any]] = []  # silent workers dropped from the scheduler, their tasks rerun elsewhere
    try:
        results = map_tasks(_task, tasks, workers=jobs, scheduler=scheduler, progress=progress, name="gearctl-bench",
                            task_bytes=task_bytes, on_drop=dropped.append)
    except TasksInterrupted as exc:  # Ctrl-C: the cells that finished, as a whole bench's result, and those not run
        out = _bench_result(spec, runs, exc.results, skipped, len(tasks), dropped)
        out["interrupted"] = True
        out["not_run"] = [_cell(runs, iso, i) for i in exc.missing]
        raise BenchInterrupted(f"interrupted: {len(tasks) - len(exc.missing)} of {len(tasks)} runs finished, "
                               f"{len(exc.missing)} did not", result=out) from None
    return _bench_result(spec, runs, results, skipped, len(tasks), dropped)


def _cell(runs: Sequence[Run], iso: Sequence[dict[str, Any]], i: int) -> dict[str, Any]:
    """Task ``i`` of the bench (its tracking runs, then its ISO rows) as the cell it fills: ``{model, controller,
    plant, design, reference}``, an ISO row's reference ``"ISO 230-2"``."""
    if i < len(runs):
        return {k: runs[i].tags.get(k) for k in ("model", "controller", "plant", "design", "reference")}
    job = iso[i - len(runs)]
    return {"model": job["model"], "controller": job["controller"], "plant": job["plant"], "design": job["plant"],
            "reference": "ISO 230-2"}


def _bench_result(spec: BenchSpec, runs: Sequence[Run], results: Sequence[dict[str, Any] | None],
                  skipped: list[dict[str, str]], tasks: int, dropped: list[dict[str, Any]]) -> dict[str, Any]:
    """:func:`run_bench`'s result from its tasks' results (None: a task that did not finish, left out)."""
    rows = [r for r in results[:len(runs)] if r is not None]
    rows.sort(key=lambda r: (r["model"], r["controller"], r["reference"], r["design"], r["plant"]))
    iso_rows = [r for r in results[len(runs):] if r is not None]
    _warn_worse_than_pid(iso_rows)
    _warn_tracks_worse_than_pid(rows)
    spec_d = dataclasses.asdict(spec)
    out = {"spec": spec_d, "runs": rows, "precision": iso_rows, "ratios": _ratios(rows, iso_rows),
           "skipped": skipped, "tasks": tasks}
    if dropped:
        out["dropped"] = dropped
    return out


class BenchInterrupted(KeyboardInterrupt):
    """A bench stopped by Ctrl-C (``KeyboardInterrupt``) after some runs had finished: they are not lost, as a
    sweep's (:class:`gearctl.sweep.SweepInterrupted`).

    A ``KeyboardInterrupt`` still (an ``except Exception`` does not swallow it), raised once the cluster's tasks are
    cancelled and a local cluster closed.

    Parameters
    ----------
    message : str
        How many runs (ISO rows included) finished, and how many did not.
    result : dict
        :func:`run_bench`'s result over the runs finished, with ``interrupted`` true and ``not_run``: the cells that
        did not finish, ``{model, controller, plant, design, reference}`` each (an ISO row's reference
        ``"ISO 230-2"``).
    """

    def __init__(self, message: str, *, result: dict[str, Any]) -> None:
        super().__init__(message)
        self.result = result


#: An ISO accuracy A this many times the PID's on the same plant is warned of even where the PID's constant offset
#: makes its largest deviation the larger.
ISO_WORSE_FACTOR = 3.0


def _warn_worse_than_pid(iso: Sequence[dict[str, Any]]) -> None:
    """Add a warning to each ISO row that positions worse than the PID on the same model and plant: a larger
    accuracy A and a larger largest deviation from the targets.

    A compensator is built to position better than the PID; where it does not (a train whose intermediate shafts
    the one-gap controllers do not see, a load the flanks cannot hold), the bench's warnings and the row's
    ``warnings`` in ``--json`` say so. Both figures, since A leaves a constant offset out: under a gravity load a
    reviewer's PID missed every target by 569 urad with A 6.58, the inverse by 1-2 urad with A 6.83, and was
    warned of as the worse.
    """
    pid = {(r["model"], r["plant"]): r for r in iso if r["controller"] == "pid" and r.get("ok")}
    for r in iso:
        ref = pid.get((r["model"], r["plant"]))
        if r["controller"] == "pid" or not r.get("ok") or ref is None:
            continue
        if r["accuracy"] > ref["accuracy"] and r["largest_deviation"] > ref["largest_deviation"]:
            r["warnings"] = [*r.get("warnings", ()), (
                f"positions worse than the pid: ISO A {r['accuracy']:.3g} rad and largest deviation "
                f"{r['largest_deviation']:.3g} rad against the pid's {ref['accuracy']:.3g} and "
                f"{ref['largest_deviation']:.3g} rad on the same plant")]
        elif r["accuracy"] > ISO_WORSE_FACTOR * ref["accuracy"]:
            # the PID's constant offset is the larger deviation, but this one scatters: a load torque along the move
            # left a review's inverse at 1446 urad (230x the PID's 6.3) with no word
            r["warnings"] = [*r.get("warnings", ()), (
                f"repeats worse than the pid: ISO A {r['accuracy']:.3g} rad, {r['accuracy'] / ref['accuracy']:.3g} "
                f"times the pid's {ref['accuracy']:.3g} rad on the same plant (its largest deviation "
                f"{r['largest_deviation']:.3g} rad against the pid's {ref['largest_deviation']:.3g}, a constant "
                f"offset A leaves out)")]


def _warn_tracks_worse_than_pid(rows: Sequence[dict[str, Any]]) -> None:
    """Add a warning to each tracking row whose RMS error exceeds the PID's on the same model, plant, reference and
    design.

    The ISO rows had such a warning and the tracking rows had only their ratio in the table: a review's servo with
    a tight torque limit ran the MPC at 1.32x and 1.57x the PID's RMS error on the sine and the move with no word
    but an impact rate.
    """
    pid = {(r["model"], r["plant"], r["reference"], r["design"]): r for r in rows
           if r["controller"] == "pid" and r.get("ok") and r.get("rms_error") is not None}
    for r in rows:
        ref = pid.get((r["model"], r["plant"], r["reference"], r["design"]))
        if r["controller"] == "pid" or not r.get("ok") or r.get("rms_error") is None or ref is None:
            continue
        if r.get("unholdable_load_step"):  # both ran away (warned of as such): 1.591e+08 against 1.562e+08 urad on an
            continue  # instrument servo's step said the MPC tracks worse than the PID where neither can hold
        if r["rms_error"] > ref["rms_error"]:
            r["warnings"] = [*r.get("warnings", ()), (
                f"tracks worse than the pid: RMS error {r['rms_error']:.3g} rad against the pid's "
                f"{ref['rms_error']:.3g} rad ({r['rms_error'] / ref['rms_error']:.3g}x) on the same plant and "
                f"reference")]


def _warning_kind(message: str) -> str:
    """A warning's kind, without its figures: ``"sustained limit cycle: 56 impacts ..."`` -> ``"sustained limit
    cycle"``, ``"impact rate 112 per s, above 100 per s"`` -> ``"impact rate above 100 per s"``."""
    import re

    base = re.sub(r"\s*\(stage 1:.*\)$", "", message)  # a train's rates per stage
    if ":" in base:
        return base.split(":")[0].strip()
    return (re.split(r"\s[-+]?\d", base)[0] + (f" {base.rsplit(', ', 1)[1]}" if ", " in base else "")).strip()


def grouped_warnings(rows: Sequence[dict[str, Any]], *, iso: bool = False) -> list[str]:
    """One line per kind of loop warning (limit cycle, impact rate, ...) naming the runs that have it.

    Parameters
    ----------
    rows : sequence of dict
        Rows of :func:`run_bench`'s ``runs`` (or, ``iso``, its ``precision`` rows).
    iso : bool
        The rows are ISO 230-2 rows (labelled so).

    Returns
    -------
    list of str
        ``"<kind> in <n> run(s): <run>, <run> (figures: --json FILE)"``.
    """
    groups: dict[str, list[str]] = {}
    several = len({r.get("model") for r in rows}) > 1
    for r in rows:
        design = "" if r.get("design", r["plant"]) in ("improved", r["plant"]) else f", designed on {r['design']}"
        model = f"{r.get('model')}: " if several else ""
        label = f"{model}{r['controller']} on {r['plant']}{design} ({'ISO 230-2' if iso else r['reference']})"
        for wmsg in r.get("warnings", ()):
            kind = _warning_kind(wmsg)
            if label not in groups.setdefault(kind, []):
                groups[kind].append(label)
    return [f"{kind} in {len(labels)} run(s): {', '.join(labels)} (figures: --json FILE)"
            for kind, labels in groups.items()]


def bench_warnings(result: dict[str, Any]) -> list[str]:
    """The bench's warnings, grouped per kind: the tracking runs', then the ISO rows' (see :func:`grouped_warnings`).

    ``gearctl bench`` prints them on standard error and writes them into ``report.md``: a report that left them out
    showed a 0.5 N m load step no controller could hold as figures of 156 rad, and an inverse positioning 1.8x
    worse than the PID, without a word.

    Parameters
    ----------
    result : dict
        What :func:`run_bench` returned (or its JSON read back).

    Returns
    -------
    list of str
    """
    return grouped_warnings(result["runs"]) + grouped_warnings(result.get("precision") or [], iso=True)


def bench_notes(result: dict[str, Any]) -> list[str]:
    """The design notes of the bench's controllers, one line per model and note naming the controllers that have it,
    and a note where ``--controllers`` left out the PID every comparison is made against.

    Four controllers of the PID family share their loop's design note; it came four times, 400 characters each.

    Parameters
    ----------
    result : dict
        What :func:`run_bench` returned (or its JSON read back).

    Returns
    -------
    list of str
    """
    groups: dict[tuple[str, str], list[str]] = {}
    for r in result["runs"]:
        for n in r.get("design_notes", ()):
            ctrls = groups.setdefault((r["model"], n), [])
            if r["controller"] not in ctrls:
                ctrls.append(r["controller"])
    out = [f"{m}, {', '.join(c)}: {n}" for (m, n), c in groups.items()]
    chosen = (result.get("spec") or {}).get("controllers") or ()
    if chosen and "pid" not in chosen:  # the baseline every comparison is made against
        out.append("--controllers without pid: no PID baseline, so no ratios over the PID, no backlash-free ISO "
                   "row and no 'worse than the pid' warnings; add pid to --controllers to compare with it")
    return out


def _ratios(results: Sequence[dict[str, Any]], iso: Sequence[dict[str, Any]] = ()) -> dict[str, Any]:
    cell = {(r["model"], r["controller"], r["reference"], r["plant"], r["design"]): r for r in results}

    def rms(m: str, c: str, ref: str, p: str, d: str = "improved") -> float | None:
        r = cell.get((m, c, ref, p, d))
        return r.get("rms_error") if r and r.get("ok") else None

    def ratio(a: float | None, b: float | None) -> float | None:
        return a / b if a is not None and b not in (None, 0.0) else None

    over_pid: dict[str, Any] = {}
    over_free: dict[str, Any] = {}
    imp_ys: dict[str, Any] = {}
    cross: dict[str, Any] = {}
    for (m, c, ref, p, d) in cell:
        if d != "improved":
            continue
        key = f"{m}/{c}/{ref}"
        if p != FREE:
            over_free.setdefault(key, {})[p] = ratio(rms(m, c, ref, p), rms(m, c, ref, FREE))
        if any(k[1] == "pid" for k in cell):
            over_pid.setdefault(key, {})[p] = ratio(rms(m, c, ref, p), rms(m, "pid", ref, p))
        if p == "improved":
            imp_ys[key] = ratio(rms(m, c, ref, "improved"), rms(m, c, ref, "yang-sun"))
        if ref == "sine" and p == "improved" and (m, c, ref, "improved", "yang-sun") in cell:
            cross[f"{m}/{c}"] = {
                "designed_improved_on_improved": rms(m, c, ref, "improved"),
                "designed_improved_on_yang_sun": rms(m, c, ref, "yang-sun"),
                "designed_yang_sun_on_improved": rms(m, c, ref, "improved", "yang-sun"),
            }
    def iso_over(base: dict[str, Any]) -> dict[str, Any]:
        """Each ISO row's A, B and R over its model's row in ``base`` (the backlash-free rows are no compensator's)."""
        return {f"{r['model']}/{r['controller']}": {k: ratio(r[k], base[r["model"]][k])
                                                     for k in ("accuracy", "reversal_value", "repeatability")}
                for r in iso if r["plant"] != FREE and r.get("ok") and r["model"] in base}

    iso_ratios = iso_over({r["model"]: r for r in iso if r["plant"] == FREE and r.get("ok")})
    # over the PID on the same (improved) plant: what a compensator gains in positioning, as over_pid in tracking
    iso_over_pid = iso_over({r["model"]: r for r in iso
                             if r["plant"] == "improved" and r["controller"] == "pid" and r.get("ok")})
    return {"over_pid": over_pid, "over_backlash_free": over_free, "improved_over_yang_sun": imp_ys,
            "cross_design": cross, "iso_over_backlash_free": iso_ratios, "iso_over_pid": iso_over_pid}


def _fmt(v: float | None, scale: float = 1e6, digits: int = 4) -> str:
    return "—" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v * scale:.{digits}g}"


def bench_table(result: dict[str, Any], *, markdown: bool = False) -> str:
    """The benchmark's tables as text (or Markdown): errors per cell, the ratios, the ISO rows, and the best
    controller per reference on the improved plant (its gain over the PID, the runner-up, its warnings).

    Parameters
    ----------
    result : dict
        What :func:`run_bench` returned (or its JSON read back).
    markdown : bool
        Markdown tables instead of plain text (default False).

    Returns
    -------
    str
    """
    runs = [r for r in result["runs"] if r["design"] == "improved"]
    plants = list(dict.fromkeys(r["plant"] for r in runs))
    rows = list(dict.fromkeys((r["model"], r["controller"], r["reference"]) for r in runs))
    cell = {(r["model"], r["controller"], r["reference"], r["plant"]): r for r in runs}
    ratios = result["ratios"]
    lines: list[str] = []
    several = len({r["model"] for r in result["runs"]} | {r["model"] for r in result.get("precision") or []}) > 1
    mhead = ["model"] if several else []

    def named(m: str, c: str) -> list[str]:  # the model column where the bench ran several
        return [m, c] if several else [c]

    def table(head: list[str], body: list[list[str]]) -> None:
        if markdown:
            lines.append("| " + " | ".join(head) + " |")
            lines.append("|" + "|".join("---" for _ in head) + "|")
            lines.extend("| " + " | ".join(r) + " |" for r in body)
        else:
            w = [max(len(x) for x in col) for col in zip(head, *body, strict=True)]
            lines.append("  ".join(h.ljust(n) for h, n in zip(head, w, strict=True)))
            lines.extend("  ".join(x.ljust(n) for x, n in zip(r, w, strict=True)) for r in body)
        lines.append("")

    def runaway(m: str, c: str, ref: str, p: str) -> str:  # the mark of a load step no controller can hold
        return " *" if (cell.get((m, c, ref, p)) or {}).get("unholdable_load_step") else ""

    # under the tables that mark a cell: such figures are the same for every controller, and a ratio of 1 over the
    # PID reads as a tie (an instrument servo's step: 156 rad RMS everywhere, every ratio '1 / 1')
    held = sorted({r["unholdable_load_step"].split(":")[0] for r in runs if r.get("unholdable_load_step")})
    footnote = (("\\* " if markdown else "* ") + "; ".join(held) + ": no controller can hold it, the load runs away, "
                "and the marked figures measure that, not the controller" if held else "")

    lines.append("Load-angle error, RMS / max [urad], impacts (controller designed on the improved plant):")
    lines.append("")
    body = []
    for m, c, ref in rows:
        row = [*named(m, c), ref]
        for p in plants:
            r = cell.get((m, c, ref, p))
            if r is None:
                row.append("—")
            elif not r.get("ok"):
                row.append("FAILED" + runaway(m, c, ref, p))
            else:
                row.append(f"{_fmt(r['rms_error'])} / {_fmt(r['max_error'])}, {r['impacts']}{runaway(m, c, ref, p)}")
        ok = [cell[(m, c, ref, p)] for p in plants if cell.get((m, c, ref, p), {}).get("solve_time")]
        p99 = max((r["solve_time"]["p99"] for r in ok), default=None)  # the worst plant's
        row.append(f"{p99 * 1e6:.0f} / {ok[0]['Ts'] * 1e6:.0f}" if p99 is not None else "—")
        prev = [cell[(m, c, ref, p)].get("preview") for p in plants if cell.get((m, c, ref, p), {}).get("preview")]
        row.append(str(prev[0]) if prev else "1")
        body.append(row)
    table([*mhead, "controller", "reference", *plants, "solve p99 (worst plant) / Ts [us]", "preview"], body)
    if footnote:
        lines.extend([footnote, ""])

    lines.append("Ratios of RMS error, per plant: over the PID's on the same plant / over the backlash-free plant's "
                 "under the same controller:")
    lines.append("")
    body = []
    for m, c, ref in rows:
        key = f"{m}/{c}/{ref}"
        row = [*named(m, c), ref]
        for p in plants:
            if p == FREE:
                continue
            a = ratios["over_pid"].get(key, {}).get(p)
            b = ratios["over_backlash_free"].get(key, {}).get(p)
            row.append(f"{_fmt(a, 1, 3)} / {_fmt(b, 1, 3)}{runaway(m, c, ref, p)}")
        q = ratios["improved_over_yang_sun"].get(key)
        row.append(_fmt(q, 1, 3) + (runaway(m, c, ref, "improved") if q is not None else ""))
        body.append(row)
    table([*mhead, "controller", "reference", *[p for p in plants if p != FREE], "improved / yang-sun"], body)
    if footnote:
        lines.extend([footnote, ""])
    if ratios["cross_design"]:
        lines.append("Designed on one plant, run on another (sine, RMS [urad]):")
        lines.append("")
        body = [[*named(*k.rsplit("/", 1)), _fmt(v["designed_improved_on_improved"]),
                 _fmt(v["designed_improved_on_yang_sun"]), _fmt(v["designed_yang_sun_on_improved"])]
                for k, v in ratios["cross_design"].items()]
        table([*mhead, "controller", "improved -> improved", "improved -> yang-sun", "yang-sun -> improved"], body)
    iso = result.get("precision") or []
    if iso:
        lines.append("ISO 230-2 positioning on the improved plant (5 targets, 5 cycles; load angle [urad]); ratios "
                     "over the PID's on the same plant and over the backlash-free PID's:")
        lines.append("")
        body = []
        for r in iso:
            key = f"{r['model']}/{r['controller']}"
            if not r.get("ok"):
                body.append([*named(r["model"], r["controller"]), r["plant"], "FAILED", "", "", "", ""])
                continue
            q = ratios.get("iso_over_backlash_free", {}).get(key, {})
            qp = ratios.get("iso_over_pid", {}).get(key, {})
            abr = ("accuracy", "reversal_value", "repeatability")
            body.append([*named(r["model"], r["controller"]), r["plant"], _fmt(r["accuracy"]),
                         _fmt(r["reversal_value"]), _fmt(r["repeatability"]),
                         "—" if r["plant"] == FREE else " / ".join(_fmt(qp.get(k), 1, 3) for k in abr),
                         "—" if r["plant"] == FREE else " / ".join(_fmt(q.get(k), 1, 3) for k in abr)])
        table([*mhead, "controller", "plant", "A", "B", "R", "A / B / R over the pid's",
               "A / B / R over backlash-free PID"], body)
    best = _best(result)
    if best:
        lines.append("Best on the improved plant (lowest RMS error per reference; ISO 230-2: lowest A), load angle "
                     "[urad]; against the pid and the runner-up, with the best run's warnings:")
        lines.append("")
        body = [[*([b["model"]] if several else []), *(b[k] for k in ("reference", "best", "error", "over_pid",
                                                                       "runner_up", "warnings"))] for b in best]
        table([*mhead, "reference", "best", "RMS or A", "over the pid", "runner-up", "its warnings"], body)
    failed = [r for r in result["runs"] if not r.get("ok")]
    for r in failed:
        how = "" if r["design"] == "improved" else f", designed on {r['design']}"
        model = f"{r['model']}, " if several else ""
        lines.append(f"FAILED: {r['controller']} on {model}{r['plant']} ({r['reference']}{how}): {r['message']}")
    for r in result.get("precision") or ():  # the ISO row's FAILED had no reason anywhere but --json
        if not r.get("ok"):
            model = f"{r['model']}, " if several else ""
            lines.append(f"FAILED: {r['controller']} on {model}{r['plant']} (ISO 230-2): {r.get('message')}")
    for s in result.get("skipped", ()):
        lines.append(f"not run: {s['controller']} on {s['model']}: {s['reason']}")
    if result.get("not_run"):  # an interrupted bench: its cells read "—" (the list is in --json)
        lines.append(f"interrupted: {len(result['not_run'])} of {result['tasks']} runs did not run (their cells read "
                     f"—; not_run in --json)")
    return "\n".join(lines).rstrip() + "\n"


def _best(result: dict[str, Any]) -> list[dict[str, str]]:
    """Per model and reference (and ISO 230-2), the controller with the lowest error on the improved plant, its
    figure [urad], its ratio over the pid's, the runner-up and the best run's warnings, as table cells.

    The tables held every figure but not the answer a machine builder reads them for: which compensator, by how much,
    and whether its figure can be trusted. A reference whose load step no controller can hold has no best.
    """
    out: list[dict[str, str]] = []

    def entry(model: str, ref: str, rows: list[dict[str, Any]], key: str) -> None:
        ranked = sorted((r for r in rows if r.get("ok") and r.get(key) is not None and math.isfinite(r[key])),
                        key=lambda r: r[key])
        if not ranked:
            return
        if any(r.get("unholdable_load_step") for r in ranked):
            out.append({"model": model, "reference": ref, "best": "—", "error": "—", "over_pid": "—",
                        "runner_up": "—", "warnings": "no controller can hold the load step"})
            return
        b = ranked[0]
        pid = next((r for r in ranked if r["controller"] == "pid"), None)
        ratio = f"{b[key] / pid[key]:.3g}x" if pid is not None and pid[key] > 0 else "—"
        runner = f"{ranked[1]['controller']} {_fmt(ranked[1][key])}" if len(ranked) > 1 else "—"
        kinds = list(dict.fromkeys(_warning_kind(w) for w in b.get("warnings", ())))
        out.append({"model": model, "reference": ref, "best": b["controller"], "error": _fmt(b[key]),
                    "over_pid": ratio, "runner_up": runner, "warnings": "; ".join(kinds) or "none"})

    runs = [r for r in result["runs"] if r["design"] == "improved" and r["plant"] == "improved"]
    for m, ref in dict.fromkeys((r["model"], r["reference"]) for r in runs):
        entry(m, ref, [r for r in runs if r["model"] == m and r["reference"] == ref], "rms_error")
    iso = [r for r in result.get("precision") or () if r["plant"] == "improved"]
    for m in dict.fromkeys(r["model"] for r in iso):
        entry(m, "ISO 230-2", [r for r in iso if r["model"] == m], "accuracy")
    order = list(dict.fromkeys(b["model"] for b in out))
    return sorted(out, key=lambda b: order.index(b["model"]))  # each model's rows together, its ISO row last


def error_traces(result: dict[str, Any]) -> dict[tuple[str, str], dict[str, tuple[Any, Any]]]:
    """``(controller, reference) -> {plant: (t, error)}`` for plotting."""
    out: dict[tuple[str, str], dict[str, tuple[Any, Any]]] = {}
    for r in result["runs"]:
        if r.get("ok") and r["design"] == "improved" and "trace_t" in r:
            out.setdefault((r["controller"], r["reference"]), {})[r["plant"]] = (
                np.asarray(r["trace_t"]), np.asarray(r["trace_error"]))
    return out
