"""The closed-loop tracking benchmark: every controller against every plant on the same references.

Each run is one controller (designed on the model's improved plant) against one plant (improved,
Yang–Sun, time-varying stiffness, or the backlash-free limit) on one reference. Runs are independent
and spread over worker processes. The result holds every run's figures and the ratios that matter:
compensated error over the PID's, each error over the backlash-free plant's under the same controller,
and the improved plant's error over Yang–Sun's (how much the choice of plant model changes the
prediction); plus, on the sine, each controller designed on the Yang–Sun plant and run on the improved
one (how a design on one model fares on the other).
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any

import numpy as np

from .catalog import controller_names, load_controller, load_model, resolve
from .closedloop import simulate_closed_loop
from .errors import GearctlError, InputError
from .kernel import compiled_available
from .metrics import tracking_metrics
from .plant import PlantKind, build_plant
from .references import REFERENCES, reference

__all__ = ["BenchSpec", "run_bench", "bench_table", "DEFAULT_DURATION", "FREE"]

#: Label of the backlash-free plant (the physical limit).
FREE = "backlash-free"

#: Simulated time per reference [s].
DEFAULT_DURATION = {"sine": 3.0, "move": 1.0, "step": 2.0, "ramp": 1.5}


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
        Also run each controller designed on the Yang–Sun plant against the improved plant (sine).
    realtime : bool
        Optimisations that overrun their time budget fall back, as on the target (default False:
        overruns are counted and the results are deterministic for a seed).
    """

    models: tuple[str, ...] = ("shing1993_servo",)
    controllers: tuple[str, ...] = ()
    plants: tuple[str, ...] = ("improved", "yang-sun", "tvms")
    references: tuple[str, ...] = ("sine", "move", "step")
    duration: float | None = None
    seed: int = 0
    cross_design: bool = True
    realtime: bool = False

    def __post_init__(self) -> None:
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
        if self.duration is not None and not (self.duration > 0 and math.isfinite(self.duration)):
            raise InputError(f"duration = {self.duration!r} is out of range: expected a number > 0 [s]",
                             field="duration")
        for m in self.models:
            resolve(m, "models")
        for c in self.controllers:
            resolve(c, "controllers")

    def runs(self) -> list[dict[str, Any]]:
        """The independent runs, as picklable dicts."""
        ctrls = self.controllers or tuple(controller_names())
        out = []
        for m in self.models:
            for c in ctrls:
                for r in self.references:
                    for p in (*self.plants, FREE):
                        out.append({"model": m, "controller": c, "plant": p, "design": "improved", "reference": r,
                                    "duration": self.duration or DEFAULT_DURATION[r], "seed": self.seed,
                                    "realtime": self.realtime})
                if self.cross_design and "sine" in self.references and "yang-sun" in self.plants:
                    out.append({"model": m, "controller": c, "plant": "improved", "design": "yang-sun",
                                "reference": "sine", "duration": self.duration or DEFAULT_DURATION["sine"],
                                "seed": self.seed, "realtime": self.realtime})
        return out


def _run_one(run: dict[str, Any]) -> dict[str, Any]:
    """Worker: one closed-loop run; returns its figures and a decimated error trace."""
    model = load_model(run["model"])
    free = run["plant"] == FREE
    backlash = 0.0 if free else None
    plant = build_plant(model, "improved" if free else run["plant"], backlash=backlash)
    nominal = build_plant(model, run["design"], backlash=backlash)
    out = dict(run)
    try:
        ctrl = load_controller(run["controller"], nominal)
        ctrl.realtime = run.get("realtime", False)
        res = simulate_closed_loop(plant, ctrl, reference(run["reference"]), run["duration"],
                                   sensors=model.sensors, seed=run["seed"])
    except GearctlError as exc:  # a diverging run is a result too, not a crash of the benchmark
        out.update({"ok": False, "message": str(exc)})
        part = getattr(exc, "result", None)
        if part is not None:
            out.update(tracking_metrics(part))
        return out
    step = max(1, res.t.size // 600)
    out.update({"ok": True, "message": "ok", "name": ctrl.name, "Ts": ctrl.Ts, **tracking_metrics(res),
                "trace_t": res.t[::step].tolist(), "trace_error": res.error[::step].tolist()})
    return out


def run_bench(spec: BenchSpec, *, jobs: int | None = None,
              progress: Callable[[int, int], Any] | None = None) -> dict[str, Any]:
    """Run the benchmark.

    Parameters
    ----------
    spec : BenchSpec
        What to run.
    jobs : int, optional
        Worker processes (default: all cores; 1 runs in this process).
    progress : callable, optional
        ``progress(done, total)`` after each run.

    Returns
    -------
    dict
        ``runs`` (every run's figures), ``ratios`` {``over_pid``, ``over_backlash_free``,
        ``improved_over_yang_sun``, ``cross_design``}, ``spec``.
    """
    runs = spec.runs()
    compiled_available()  # compile the kernel once before the workers start
    jobs = jobs or os.cpu_count() or 1
    results: list[dict[str, Any]] = []
    if jobs == 1 or len(runs) == 1:
        for i, r in enumerate(runs):
            results.append(_run_one(r))
            if progress:
                progress(i + 1, len(runs))
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(_run_one, r): k for k, r in enumerate(runs)}
            done = [None] * len(runs)
            for n, fut in enumerate(as_completed(futures)):
                done[futures[fut]] = fut.result()
                if progress:
                    progress(n + 1, len(runs))
            results = done  # type: ignore[assignment]
    results.sort(key=lambda r: (r["model"], r["controller"], r["reference"], r["design"], r["plant"]))
    return {"spec": dataclasses.asdict(spec), "runs": results, "ratios": _ratios(results)}


def _ratios(results: Sequence[dict[str, Any]]) -> dict[str, Any]:
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
    return {"over_pid": over_pid, "over_backlash_free": over_free, "improved_over_yang_sun": imp_ys,
            "cross_design": cross}


def _fmt(v: float | None, scale: float = 1e6, digits: int = 4) -> str:
    return "—" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v * scale:.{digits}g}"


def bench_table(result: dict[str, Any], *, markdown: bool = False) -> str:
    """The benchmark's tables as text (or Markdown): errors per cell, then the ratios."""
    runs = [r for r in result["runs"] if r["design"] == "improved"]
    plants = list(dict.fromkeys(r["plant"] for r in runs))
    rows = list(dict.fromkeys((r["model"], r["controller"], r["reference"]) for r in runs))
    cell = {(r["model"], r["controller"], r["reference"], r["plant"]): r for r in runs}
    ratios = result["ratios"]
    lines: list[str] = []

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

    lines.append("Load-angle error, RMS / max [urad], impacts (controller designed on the improved plant):")
    lines.append("")
    body = []
    for m, c, ref in rows:
        row = [f"{c}", ref]
        for p in plants:
            r = cell.get((m, c, ref, p))
            if r is None:
                row.append("—")
            elif not r.get("ok"):
                row.append("FAILED")
            else:
                row.append(f"{_fmt(r['rms_error'])} / {_fmt(r['max_error'])}, {r['impacts']}")
        ok = [cell[(m, c, ref, p)] for p in plants if cell.get((m, c, ref, p), {}).get("solve_time")]
        p99 = max((r["solve_time"]["p99"] for r in ok), default=None)  # the worst plant's
        row.append(f"{p99 * 1e6:.0f} / {ok[0]['Ts'] * 1e6:.0f}" if p99 is not None else "—")
        body.append(row)
    table(["controller", "reference", *plants, "solve p99 (worst plant) / Ts [us]"], body)

    lines.append("Ratios of RMS error: over the PID's on the same plant | over the backlash-free plant's under the "
                 "same controller:")
    lines.append("")
    body = []
    for m, c, ref in rows:
        key = f"{m}/{c}/{ref}"
        row = [c, ref]
        for p in plants:
            if p == FREE:
                continue
            a = ratios["over_pid"].get(key, {}).get(p)
            b = ratios["over_backlash_free"].get(key, {}).get(p)
            row.append(f"{_fmt(a, 1, 3)} | {_fmt(b, 1, 3)}")
        row.append(_fmt(ratios["improved_over_yang_sun"].get(key), 1, 3))
        body.append(row)
    table(["controller", "reference", *[p for p in plants if p != FREE], "improved / yang-sun"], body)
    if ratios["cross_design"]:
        lines.append("Designed on one plant, run on another (sine, RMS [urad]):")
        lines.append("")
        body = [[k.split("/")[-1], _fmt(v["designed_improved_on_improved"]), _fmt(v["designed_improved_on_yang_sun"]),
                 _fmt(v["designed_yang_sun_on_improved"])] for k, v in ratios["cross_design"].items()]
        table(["controller", "improved -> improved", "improved -> yang-sun", "yang-sun -> improved"], body)
    failed = [r for r in result["runs"] if not r.get("ok")]
    for r in failed:
        how = "" if r["design"] == "improved" else f", designed on {r['design']}"
        lines.append(f"FAILED: {r['controller']} on {r['plant']} ({r['reference']}{how}): {r['message']}")
    return "\n".join(lines).rstrip() + "\n"


def error_traces(result: dict[str, Any]) -> dict[tuple[str, str], dict[str, tuple[np.ndarray, np.ndarray]]]:
    """``(controller, reference) -> {plant: (t, error)}`` for plotting."""
    out: dict[tuple[str, str], dict[str, tuple[np.ndarray, np.ndarray]]] = {}
    for r in result["runs"]:
        if r.get("ok") and r["design"] == "improved" and "trace_t" in r:
            out.setdefault((r["controller"], r["reference"]), {})[r["plant"]] = (
                np.asarray(r["trace_t"]), np.asarray(r["trace_error"]))
    return out
