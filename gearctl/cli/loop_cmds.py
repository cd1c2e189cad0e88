"""Closed-loop commands: ``track``, ``precision``, ``bench``, ``perf``."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..errors import GearctlError, InputError
from ..units import BACKLASH, DURATION, SEED, Spec
from .common import (
    CYCLES,
    JOBS,
    TARGETS,
    check_writable,
    dropped_notes,
    dump_json,
    earlier_plots,
    format_rate,
    positive_quantity,
    progress_bar,
    quiet_unawaited_coroutines,
    ratio_changed,
    remove_earlier_plots,
    save_figure,
    say_written,
    separated_past_flank,
    sigterm_as_ctrl_c,
    spec_arg,
    unused_estimate,
    warn,
    write_csv_stream,
    write_whole,
    yang_sun_notes,
)

__all__ = ["register"]


def _refuse_backlash_twice(args: argparse.Namespace) -> None:
    """``--backlash`` beside ``--set backlash=...`` (or a stage's), or a ``--set`` key given twice: two values for one
    key, refused by name.

    ``--backlash`` sets the plant's backlash after the ``--set`` keys, so the ``--set`` value was dropped without a
    word (``track ... --backlash 1e-5 --set backlash=2e-5`` ran the 10 um plant).
    """
    seen: set[str] = set()
    for k, _ in args.set:  # a key twice: the last value won, the first was dropped without a word
        if k in seen:
            raise InputError(f"--set {k} is given twice: give each key once", field=k)
        seen.add(k)
    keys = [k for k, _ in args.set if k == "backlash" or k.endswith(".backlash")]
    if args.backlash is not None and keys:
        raise InputError(f"--backlash {args.backlash:g} and --set {keys[0]}=...: both set the true plant's backlash "
                         "(--backlash the model's, design included; --set the true plant's alone): give one; for a "
                         "design estimate other than the true backlash use --estimate B with --set backlash=...",
                         field="backlash")


def _true_model(args: argparse.Namespace) -> Any:
    """The model of ``args`` with its ``--set`` keys: the true plant's (the design's is the file's)."""
    from ..catalog import load_model
    from ..runs import true_model

    model = load_model(args.model)
    return true_model(args.model, model, dict(args.set), args.plant) if args.set else model


def _cmd_track(args: argparse.Namespace) -> int:
    from ..runs import design_controller, execute, make_run, unholdable_load_step, unholdable_load_torque

    _refuse_backlash_twice(args)
    if args.exported is not None and args.estimate is not None:
        raise InputError("--estimate and --exported: an exported controller runs with the numbers it was exported "
                         "with; export it again with `gearctl export ... --estimate B`", field="estimate")
    if args.exported is not None and args.realtime:
        raise InputError("--realtime and --exported: the exported C keeps no clock and never falls back on an overrun "
                         "(max_solve_time has no effect in C); without --realtime the steps longer than it are counted "
                         "as overruns", field="realtime")
    if args.controller is None:  # not named: the exported folder's controller, else the catalog's inverse
        args.controller = "deadzone_inverse"
        if args.exported is not None:
            from ..export.sil import exported_name

            args.controller = exported_name(args.exported)
    run = make_run(args.model, args.controller, plant=args.plant, reference_kind=args.reference,
                   duration=args.duration, seed=args.seed, backlash=args.backlash, estimate=args.estimate,
                   realtime=args.realtime, overrides=dict(args.set))
    if args.exported is None:  # the design first, with its own bar: an MPC's long horizon takes minutes
        with progress_bar("gearctl track: design", expected_s=None) as bar, contextlib.suppress(GearctlError):
            design_controller(run.design, progress=bar)  # (a design that fails is reported by execute)
    with progress_bar("gearctl track", expected_s=run.duration * 0.02) as bar:  # (it stood at 0 % when not passed)
        if args.exported is None:
            out, res = execute(run, keep=True, progress=bar if bar.bar else None)
        else:  # software in the loop: the folder's C in place of the Python controller, the same closed loop
            from ..export.sil import execute_exported, exported_notes

            out, res = execute_exported(run, args.exported, keep=True, progress=bar if bar.bar else None)
            warn("track", exported_notes(args.exported, run.tags["model"], args.backlash), kind="note")
    if res is None or out.metrics is None:
        raise InputError(out.message)
    m = out.metrics
    ctrl = out.controller
    plant = run.plant
    n, w = plant.n_stages, plant.nx // 2
    summary = {"model": run.tags["model"], "controller": ctrl, "plant": args.plant, "reference": args.reference,
               "backlash": plant.backlash if n == 1 else list(plant.backlashes), "seed": args.seed,
               "preview": ctrl.get("preview", 1), "ok": out.ok, "message": out.message, **m.as_dict()}
    summary["separated_past_flank"] = separated_past_flank(plant, plant.gaps(res.x), res.mode.reshape(n, -1))
    warn("track", [f"{ctrl['name']}: {n}" for n in ctrl.get("design_notes", ())], kind="note")
    warn("track", unused_estimate(ctrl.get("kind"), args.estimate), kind="note")
    warn("track", ratio_changed(run.design.nominal, plant), kind="note")
    warn("track", yang_sun_notes(_true_model(args), args.plant), kind="note")
    warn("track", m.health.warnings)
    too_large = unholdable_load_step(plant, run.reference) or unholdable_load_torque(plant)
    if too_large:
        warn("track", [too_large])
    if not out.ok:
        warn("track", [f"the run stopped early: {out.message}"])
    if args.csv:
        names = (["theta1", "theta2", "omega1", "omega2"] if n == 1 else
                 [f"theta{j}" for j in range(w)] + [f"omega{j}" for j in range(w)])
        s_names = ["s"] if n == 1 else [f"s{i + 1}" for i in range(n)]
        m_names = ["mode"] if n == 1 else [f"mode{i + 1}" for i in range(n)]
        s_all = plant.gaps(res.x)
        mode = res.mode.reshape(n, -1)

        def cols(i0: int, i1: int) -> list[Any]:
            return [res.t[i0:i1], res.reference[i0:i1], *res.x[:, i0:i1], *s_all[:, i0:i1], *mode[:, i0:i1],
                    res.torque[i0:i1], res.y_motor[i0:i1], res.y_load[i0:i1]]

        write_csv_stream(args.csv, ["t", "reference", *names, *s_names, *m_names, "torque", "y_motor", "y_load"],
                         cols, res.t.size)
    if args.plot:
        from ..plots import plot_tracking

        save_figure(plot_tracking({ctrl["name"]: res}, title=f"{run.tags['model']}, {args.plant} plant, "
                                                               f"{args.reference}"), args.plot)
    if args.json:
        print(dump_json(summary))
        return 0 if out.ok else 2
    st = m.solve_time
    bl = (f"b = {plant.backlash * 1e6:.4g} um" if n == 1 else
          f"lost motion {plant.lost_motion * 1e6:.4g} urad at the output")
    print(f"{run.tags['model']}: {ctrl['name']} on the {args.plant} plant, {args.reference} reference, "
          f"{m.duration:.3g} s ({bl})")
    print(f"  load-angle error       RMS {m.rms_error:.4g} rad, max {m.max_error:.4g} rad, "
          f"final {m.final_error:.3g} rad")
    print(f"  impacts                {m.impacts} (front {m.impacts_front}, back {m.impacts_back}), "
          f"fastest {m.max_impact_velocity:.3g} m/s")
    if st is not None:
        print(f"  solve time             median {st['median'] * 1e6:.0f} us, p99 {st['p99'] * 1e6:.0f} us, "
              f"max {st['max'] * 1e6:.0f} us (sample period {ctrl['Ts'] * 1e6:.0f} us); overruns {m.overruns}, "
              f"fallbacks {m.fallbacks}")
    if ctrl.get("preview", 1) > 1:
        ahead = (ctrl["preview"] - 1) * ctrl["Ts"] * 1e3
        print(f"  preview                {ctrl['preview']} reference samples ({ahead:.3g} ms ahead)")
    print(f"  wall time              {m.wall_time:.3g} s ({format_rate(m.duration, m.wall_time)} "
          f"simulated s per wall s)")
    say_written((args.csv, "CSV"), (args.plot, "plot"))
    return 0 if out.ok else 2


def _cmd_precision(args: argparse.Namespace) -> int:
    from ..catalog import load_controller, load_model
    from ..plant import build_plant
    from ..precision import precision_health, precision_test
    from ..runs import true_model as true_model_of
    from ..runs import unholdable_load_torque

    _refuse_backlash_twice(args)
    model = load_model(args.model)
    true_model = true_model_of(args.model, model, dict(args.set), args.plant) if args.set else model
    nominal = build_plant(model, backlash=args.backlash)
    plant = build_plant(true_model, args.plant, backlash=args.backlash)
    with progress_bar("gearctl precision: design", expected_s=None) as bar:
        ctrl = load_controller(args.controller, nominal, backlash=args.estimate, sensors=model.sensors, progress=bar)
    TARGETS.check("targets", args.targets)
    CYCLES.check("cycles", args.cycles)
    with progress_bar("gearctl precision", expected_s=None) as bar:  # shown once the run has taken 2 s
        res = precision_test(plant, ctrl, targets=args.targets, cycles=args.cycles, travel=args.travel,
                             dwell=args.dwell, sensors=true_model.sensors, seed=args.seed,
                             progress=bar if bar.bar else None)
    st = res.stats
    health = precision_health(res, plant.lost_motion, args.travel)
    out = {
        "model": model.name, "controller": ctrl.describe(), "plant": args.plant,
        "backlash": plant.backlash if plant.n_stages == 1 else list(plant.backlashes),
        "lost_motion": plant.lost_motion,
        "targets": res.targets.tolist(), "cycles": args.cycles,
        "reversal_value": st["reversal_value"], "repeatability": st["repeatability"],
        "repeatability_up": st["repeatability_up"], "repeatability_down": st["repeatability_down"],
        "accuracy": st["accuracy"], "mean_bidirectional_deviation": st["mean_bidirectional_deviation"],
        "systematic_deviation": st["systematic_deviation"], "mean_reversal": st["mean_reversal"],
        "mean_deviation": st["mean_deviation"], "largest_deviation": st["largest_deviation"],
        "per_target": [
            {"target": float(P), "mean_up": float(st["mean_up"][i]), "mean_down": float(st["mean_down"][i]),
             "s_up": float(st["s_up"][i]), "s_down": float(st["s_down"][i]), "reversal": float(st["reversal"][i]),
             "deviations_up": res.deviations_up[i].tolist(), "deviations_down": res.deviations_down[i].tolist()}
            for i, P in enumerate(res.targets)],
        "impacts": res.run.impact_count,
        "health": health.as_dict(),
    }
    warn("precision", [f"{ctrl.name}: {n}" for n in out["controller"].get("design_notes", ())], kind="note")
    warn("precision", unused_estimate(out["controller"].get("kind"), args.estimate), kind="note")
    warn("precision", ratio_changed(nominal, plant), kind="note")
    warn("precision", yang_sun_notes(true_model, args.plant), kind="note")
    warn("precision", health.warnings)
    warn("precision", [w for w in (unholdable_load_torque(plant),) if w])
    if args.plot:
        from ..plots import plot_precision

        save_figure(plot_precision(res), args.plot)
    if args.json:
        print(dump_json(out))
        return 0
    print(f"{model.name}: {ctrl.name} on the {args.plant} plant, ISO 230-2 linear cycle, {args.targets} targets "
          f"over {args.travel:g} rad, {args.cycles} cycle{'' if args.cycles == 1 else 's'}")
    print(f"  reversal value B       {st['reversal_value'] * 1e6:.4g} urad (lost motion = "
          f"{out['lost_motion'] * 1e6:.4g} urad)")
    print(f"  repeatability R        {st['repeatability'] * 1e6:.4g} urad (R+ {st['repeatability_up'] * 1e6:.3g}, "
          f"R- {st['repeatability_down'] * 1e6:.3g})")
    print(f"  accuracy A             {st['accuracy'] * 1e6:.4g} urad")
    print(f"  mean bidirectional M   {st['mean_bidirectional_deviation'] * 1e6:.4g} urad")
    print(f"  systematic E           {st['systematic_deviation'] * 1e6:.4g} urad (range of the one-way means)")
    print(f"  mean deviation         {st['mean_deviation'] * 1e6:.4g} urad (a constant offset, outside A, B, R; "
          f"largest |deviation| {st['largest_deviation'] * 1e6:.4g} urad)")
    print("  target [rad]   mean+ [urad]  mean- [urad]  B_i [urad]")
    for row in out["per_target"]:
        print(f"  {row['target']:11.4f}  {row['mean_up'] * 1e6:12.2f}  {row['mean_down'] * 1e6:12.2f}  "
              f"{row['reversal'] * 1e6:10.2f}")
    if args.plot:
        print(f"  wrote {args.plot}")
    return 0


def _refuse_models_among_controllers(names: list[str]) -> None:
    """``--controllers`` takes every word after it: a model named after the list was read as a controller and refused
    as an unknown one, without a word of why. Say so."""
    from ..catalog import controller_names, model_names

    models, ctrls = set(model_names()), set(controller_names())
    for name in names:
        if name in models and name not in ctrls and not Path(name).exists():
            raise InputError(f"--controllers {' '.join(names)}: {name!r} is a model, not a controller: give the "
                             f"models before --controllers (gearctl bench MODEL ... --controllers CONTROLLER ...)",
                             field="controllers")


def _cmd_bench(args: argparse.Namespace) -> int:
    from .. import bench as benches
    from ..bench import BenchInterrupted, BenchSpec, bench_notes, bench_table, bench_warnings, error_traces
    from ..parallel import env_scheduler

    quiet_unawaited_coroutines()  # what a Ctrl-C leaves of Dask's requests (see there)
    if (args.scheduler or env_scheduler()) and args.jobs:  # as sweep's --workers
        warn("bench", ["--jobs sizes the local cluster; with --scheduler (or DASK_SCHEDULER_ADDRESS) the cluster's "
                       "own workers run the bench"])
    _refuse_models_among_controllers(args.controllers or [])
    plants = tuple(p.strip() for p in args.plants.split(",") if p.strip())
    refs = tuple(r.strip() for r in args.references.split(",") if r.strip())
    spec = BenchSpec(models=tuple(args.models) or ("shing1993_servo",), controllers=tuple(args.controllers or ()),
                     plants=plants, references=refs, duration=args.duration, seed=args.seed,
                     realtime=args.realtime, precision=not args.no_precision)
    skipped = spec.skipped()
    runs = spec.runs(skipped)
    n = len(runs)
    tasks = n + len(spec.precision_runs(skipped))  # what the bar counts: the ISO rows are tasks too
    from ..closedloop import check_loop_duration, check_loop_memory
    from ..runs import run_sample_time as sample_time  # the file's (a 0.1 ms PID's 1000 s runs all failed, exit 0)

    # a run that would not fit: refused first (and all the local workers' runs at once, in run_bench)
    for r in {(id(run.plant), run.duration, sample_time(run)): run for run in runs}.values():
        check_loop_memory(r.plant, r.duration, sample_time(r))
    for r in runs:  # and a run of no sample (each failed alone, exit 0)
        check_loop_duration(r.duration, sample_time(r), field="--duration", who=f" of {Path(r.design.label).stem}")
    to_stdout = args.json == "-"  # the JSON on standard output, the tables then on standard error
    if args.json and not to_stdout:  # checked before the runs, as the sweep's
        check_writable(args.json, key="json")
    if args.out:
        check_writable(args.out, directory=True, key="out",
                       files=["report.md", "rms_by_controller.png", *(f"errors_{r}.png" for r in refs)])
    bar = None
    if not args.quiet:
        from tqdm import tqdm

        bar = tqdm(total=tasks, desc="gearctl bench", unit="run", file=sys.stderr, leave=False, disable=None)

    def progress(done: int, total: int) -> None:
        if bar is not None:
            bar.total = total
            bar.update(done - bar.n)

    t0 = time.perf_counter()
    interrupted: BenchInterrupted | None = None
    try:
        with sigterm_as_ctrl_c():  # a SIGTERM (kill, a batch system's end of time) as a Ctrl-C, as the sweep's
            result = benches.run_bench(spec, jobs=args.jobs, progress=progress, runs=runs, scheduler=args.scheduler)
    except BenchInterrupted as exc:  # Ctrl-C: the cells that finished are written as a whole bench's are, then one
        interrupted, result = exc, exc.result  # line and exit 130 (a second Ctrl-C while writing ends it at once)
    finally:
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - t0
    result["wall_time"] = wall
    from ..parallel import local_processes

    where = args.scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS")
    # the processes the runs had: never more than the runs (bench --jobs 256 with 2 runs started 2)
    result["jobs"] = None if where else local_processes(result["tasks"], args.jobs)
    text = bench_table(result)
    # (interrupted: the runs that finished of those asked for; the ISO rows are not counted, as before)
    ran = f"{len(result['runs'])} of {n}" if interrupted is not None else str(n)
    notes, warnings = bench_notes(result), bench_warnings(result)
    notes = dropped_notes(result.get("dropped", ())) + notes  # as the sweep says it (and in report.md's notes)
    from ..catalog import load_model
    from ..plant import build_plant
    from ..runs import unholdable_load_torque

    if "yang-sun" in spec.plants:  # a plant of another material than its restitution law's (steel)
        notes += [f"{name}: {n}" for name in spec.models for n in yang_sun_notes(load_model(name), "yang-sun")]
    # a model no controller can hold: its figures are a runaway's
    warnings += [f"{name}: {w}" for name in spec.models if (w := unholdable_load_torque(build_plant(load_model(name))))]
    tables = sys.stderr if to_stdout else sys.stdout
    # the files first, what is printed after: a reader that closed standard output early (`| head`) ends the
    # command quietly at the first print, and the JSON file and the --out report written after it were lost
    wrote = []
    if args.json and not to_stdout:
        try:
            Path(args.json).parent.mkdir(parents=True, exist_ok=True)
            write_whole(args.json, dump_json(result))
        except OSError as exc:
            raise InputError(f"cannot write {args.json}: {exc.strerror}") from None
        wrote.append(f"wrote {args.json}")
    gone: list[str] = []
    if args.out:
        from ..plots import plot_bench_bars, plot_bench_errors

        out = Path(args.out)
        earlier = earlier_plots(out / "report.md", "# gearctl bench", ("rms_by_controller.png", "errors_*.png"))
        traces = error_traces(result)
        for ref in spec.references:
            save_figure(plot_bench_errors(traces, reference=ref), str(out / f"errors_{ref}.png"))
        save_figure(plot_bench_bars(result), str(out / "rms_by_controller.png"))
        on = where or f"{result['jobs']} process(es)"
        md = ["# gearctl bench", "", f"{ran} runs, {wall:.1f} s on {on}; models "
              f"{', '.join(spec.models)}; plants {', '.join(spec.plants)} and the backlash-free limit.", "",
              bench_table(result, markdown=True)]
        # what the command says on standard error belongs to the figures: a report without it showed runs that no
        # controller could hold, and compensators worse than the PID, as plain figures
        for title, items in (("Warnings", warnings), ("Notes", notes)):
            if items:
                md += [f"## {title}", "", *(f"- {w}" for w in items), ""]
        md += ["![RMS error by controller and plant](rms_by_controller.png)", ""]
        md += [f"![errors, {ref}](errors_{ref}.png)" for ref in spec.references]
        try:  # whole or not at all (a Ctrl-C while it is written)
            write_whole(out / "report.md", "\n".join(md) + "\n")
        except OSError as exc:
            raise InputError(f"cannot write {out / 'report.md'}: {exc.strerror}") from None
        wrote.append(f"wrote {out}/report.md and plots")
        gone = remove_earlier_plots(out, earlier, ["rms_by_controller.png",
                                                   *(f"errors_{ref}.png" for ref in spec.references)])
    print(text, end="", file=tables)
    print(f"{ran} runs in {wall:.1f} s " + (f"on the Dask cluster at {where}" if where else
                                          f"on {result['jobs']} process(es)"), file=tables)
    if interrupted is not None:  # the files and the tables of what finished, then the one line (as the sweep's)
        warn("bench", dropped_notes(result.get("dropped", ())), kind="note")
        if to_stdout:
            tables.flush()
            print(dump_json(result))
        sys.stdout.flush()
        named = [f"--json {args.json}" if args.json and not to_stdout else "", f"--out {args.out}" if args.out else "",
                 "the JSON on standard output" if to_stdout else ""]
        there = " and ".join(filter(None, named)) or "the tables above (no --json or --out given)"
        print(f"gearctl bench: {interrupted}; the finished runs are in {there}", file=sys.stderr)
        return 130
    warn("bench", notes, kind="note")
    warn("bench", warnings)
    if gone:
        warn("bench", [f"--out {args.out}: removed {', '.join(gone)}, which an earlier bench wrote there and this "
                       f"one does not (its references differ)"], kind="note")
    for line in wrote:
        print(line, file=tables)
    if to_stdout:  # last: a reader that closed the pipe early (`| head`) lost the --out report written after it
        tables.flush()
        print(dump_json(result))
    return 0


def _cmd_perf(args: argparse.Namespace) -> int:
    from ..catalog import controller_names
    from ..export import export_timing
    from ..perf import bench_wall_time, mpc_timing, sim_speed, standstill_cost, train_speed
    from ..sweep import sweep_perf

    out: dict[str, Any] = {}
    # several minutes, printed at the end: a bar on a terminal counts the sections done (it said nothing for 4 min)
    with progress_bar("gearctl perf", expected_s=60.0, total=8) as bar:
        scen = {}
        for k, name in enumerate(("free", "pd"), start=1):
            scen[name] = sim_speed(name)
            bar(k / 8)
        keys = ("gearctl_sim_per_wall", "python_control_sim_per_wall", "ratio", "gearctl_error",
                "python_control_error")
        # the contract keys at the top of "sim" are the harder case, the 1 kHz closed loop; both scenarios below
        out["sim"] = {**{k: scen["pd"][k] for k in keys}, "free": scen["free"], "pd": scen["pd"]}
        out["trains"] = train_speed()
        bar(3 / 8)
        out["standstill"] = standstill_cost()
        bar(4 / 8)
        out["mpc"] = mpc_timing() if "mpc" in controller_names() else None
        bar(5 / 8)
        out["export"] = export_timing(batch=False) if "mpc" in controller_names() else None
        bar(6 / 8)
        # one worker: the Dask path's own cost against the plain loop (two workers on a machine whose two cores give
        # about one core of throughput inflate each other's CPU time, which is not Dask's)
        out["sweep"] = None if args.no_sweep else sweep_perf(("pid", "reversal_offset", "deadzone_inverse", "mpc"),
                                                             runs=args.sweep_runs, workers=1)
        bar(7 / 8)
        out["bench"] = None if args.no_bench else bench_wall_time(jobs=args.jobs)
        bar(1.0)
    if args.json:
        print(dump_json(out))
        return 0
    for name, r in scen.items():
        label = {"free": "free vibration (shing1993)", "pd": "1 kHz PD loop on a sine (shing1993_servo)"}[name]
        print(f"{label}:")
        print(f"  gearctl                      {r['gearctl_sim_per_wall']:10.4g} sim-s/wall-s, "
              f"error {r['gearctl_error']:.1e} b")
        print(f"  python-control (default tol) {r['python_control_sim_per_wall']:10.4g} sim-s/wall-s, error "
              f"{r['python_control_error']:.1e} b -> {r['ratio']:.0f}x")
        print(f"  python-control (rtol 1e-10)  {r['python_control_tight_sim_per_wall']:10.4g} sim-s/wall-s, error "
              f"{r['python_control_tight_error']:.1e} b -> {r['ratio_equal_accuracy']:.0f}x, still the less accurate")
    print("1 kHz catalog PID loop, simulated s per wall s: the loop in Python around the compiled kernel | the "
          "compiled batch loop:")
    for name, r in out["trains"].items():
        print(f"  {name:32s} {r['stages']} stage(s)  {r['sim_per_wall']:8.4g}  "
              f"({r['per_sample_s'] * 1e6:.3g} us per sample) | {r['compiled_sim_per_wall']:8.4g}")
    sc = out["standstill"]
    print(f"Coulomb friction at standstill ({sc['standstill']['model']}, backlash-free, stick-slip): "
          f"{sc['standstill']['sim_per_wall']:.4g} sim-s/wall-s held at rest vs {sc['motion']['sim_per_wall']:.4g} "
          f"on the sine (ratio {sc['ratio']:.3g}; in the compiled loop {sc['compiled_ratio']:.3g}); ISO 230-2 one "
          f"cycle: {sc['precision']['backlash_free']:.3g} s "
          f"backlash-free, {sc['precision']['backlash']:.3g} s with backlash")
    m = out["mpc"]
    if m is not None:
        print(f"MPC solve per step ({m['steps']} steps, Ts {m['Ts'] * 1e6:.0f} us): median {m['median'] * 1e6:.0f} us, "
              f"p99 {m['p99'] * 1e6:.0f} us, max {m['max'] * 1e6:.0f} us; whole step p99 {m['step_p99'] * 1e6:.0f} us")
        print("  within budget: " + ", ".join(f"{k} {v * 100:.1f} %" for k, v in m["budgets"].items()))
    e = out["export"]
    if e is not None:
        c_fig = (f"median {e['step_median'] * 1e6:.3g} us, p99 {e['step_p99'] * 1e6:.3g} us"
                 if e["step_median"] is not None else "not measured (no make or C compiler)")
        print(f"exported MPC, whole step (observer, QP, fallback): C {c_fig}; from Python through the SIL path "
              f"median {e['sil']['step_median'] * 1e6:.3g} us, p99 {e['sil']['step_p99'] * 1e6:.3g} us "
              f"({e['sil']['within_8kHz'] * 100:.1f} % within 125 us); the Python MPC's step p99 "
              f"{e['python']['step_p99'] * 1e6:.3g} us")
    sw = out["sweep"]
    if sw is not None:
        print("sweep, 1 s sine runs of shing1993_servo with b from 0.5x to 2x, CPU per run (in a worker):")
        for name, r in sw.items():
            print(f"  {name:18s} {r['per_run_s'] * 1e3:7.3g} ms ({r['speedup']:.3g}x the Python loop's "
                  f"{r['python_per_run_s'] * 1e3:.3g} ms); Dask over the plain loop at {r['runs']} runs: "
                  f"{r['dask_overhead'] * 100:+.1f} % CPU on {r['workers']} workers, {r['runs_per_s']:.4g} runs/s "
                  f"per worker")
    b = out["bench"]
    if b is not None:
        print(f"default bench: {b['runs']} runs, {b['simulated_time']:.0f} simulated s in {b['wall_time']:.1f} s wall "
              f"on {b['jobs']} process(es)")
    return 0


SWEEP_RUNS = Spec(unit="1", doc="runs per controller", low=10, high=100_000, integer=True)


def _set_arg(text: str) -> tuple[str, float | int]:
    """``KEY=VALUE``: a model key changed on the true plant (the reading the sweeps' commands use)."""
    from ..sweep import parse_set

    try:
        return parse_set(text)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


#: the references' default durations, as the help states them (gearctl.runs.DEFAULT_DURATION, which imports numpy;
#: tests/test_h3_cli_help.py holds the two equal)
_DURATIONS = "sine 3 s, step 2 s, ramp 1.5 s, move 1 s"


def register(sub: Any) -> dict[str, Callable[[argparse.Namespace], int]]:
    """Add the closed-loop commands to the subparsers; return name -> function.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``gearctl`` parser's subparsers.

    Returns
    -------
    dict
        Command name -> the function that runs it (given the parsed arguments, it returns the exit code).
    """
    dur, seed, bl = spec_arg(DURATION), spec_arg(SEED), spec_arg(BACKLASH)
    plants = ("improved", "yang-sun", "tvms")
    p = sub.add_parser("track", help="run a controller against the nonlinear plant on a reference")
    p.add_argument("model", nargs="?", default="shing1993_servo", help="model (default shing1993_servo)")
    p.add_argument("controller", nargs="?", default=None,
                   help="controller: catalog name (pid, deadzone_inverse, mpc, ...) or TOML path "
                        "(default deadzone_inverse; with --exported, the exported one)")
    p.add_argument("--plant", choices=plants, default="improved", help="plant (default improved)")
    p.add_argument("--reference", choices=("sine", "step", "ramp", "move"), default="sine",
                   help="sine: 0.1 rad, 1 Hz; step: 0.05 rad at 0.1 s, a 0.5 N m load step against it at 1 s; ramp: "
                        "0.5 rad/s to 0.2 rad; move: 0.2 rad S-curve, 1 rad/s, 10 rad/s^2 (default sine)")
    p.add_argument("--duration", type=dur, help=f"simulated time [s] (default per reference: {_DURATIONS})")
    p.add_argument("--backlash", type=bl, help="override the plant's backlash [m], every stage (0: none)")
    p.add_argument("--estimate", type=bl, help="the controller's backlash estimate [m] (default: the model's; for "
                                                "a train, the equivalent half-gap on the last stage's line of action)")
    p.add_argument("--set", action="append", type=_set_arg, default=[], metavar="KEY=VALUE",
                   help="change a model key on the true plant only (repeatable; the controller is designed on the "
                        "unchanged model): what a sweep's per-run command uses. On a train a stage key sets every "
                        "stage, stageN.KEY (e.g. stage2.backlash=3e-5) stage N's alone")
    p.add_argument("--seed", type=seed, default=0, help="sensor-noise seed (default 0)")
    p.add_argument("--realtime", action="store_true",
                   help="an optimisation that overruns its time budget falls back, as on the target "
                        "(default: overruns are counted, results are deterministic)")
    p.add_argument("--exported", metavar="DIR",
                   help="software in the loop: run the C controller of a `gearctl export` folder (compiled here) "
                        "in place of the Python one; CONTROLLER names the same kind")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--csv", metavar="FILE", help="write the run per sample (- for standard output)")
    p.add_argument("--plot", metavar="FILE", help="write reference/load angle, error, torque and gap plot")

    p = sub.add_parser("precision", help="ISO 230-2 positioning test: reversal value, repeatability, accuracy")
    p.add_argument("model", nargs="?", default="shing1993_servo", help="model (default shing1993_servo)")
    p.add_argument("controller", nargs="?", default="deadzone_inverse", help="controller (default deadzone_inverse)")
    # whole numbers here; their ranges are checked by the test itself (one line naming the key)
    p.add_argument("--targets", type=spec_arg(TARGETS), default=5, help="target positions, 2..50 (default 5)")
    p.add_argument("--cycles", type=spec_arg(CYCLES), default=5, help="cycles, 1..50 (default 5, as ISO 230-2)")
    p.add_argument("--travel", type=positive_quantity("rad"), default=0.5,
                   help="span of the targets [rad] (default 0.5); value > 0, the whole program at most 100000 s")
    p.add_argument("--dwell", type=positive_quantity("s"), default=0.3,
                   help="rest before each measurement [s] (default 0.3); value > 0, the whole program at most 100000 s")
    p.add_argument("--plant", choices=plants, default="improved", help="plant (default improved)")
    p.add_argument("--backlash", type=bl, help="override the model's backlash [m]")
    p.add_argument("--estimate", type=bl, help="the controller's backlash estimate [m] (default: the model's)")
    p.add_argument("--set", action="append", type=_set_arg, default=[], metavar="KEY=VALUE",
                   help="change a model key on the true plant only (repeatable; stageN.KEY: stage N's alone)")
    p.add_argument("--seed", type=seed, default=0, help="seed of sensor noise and target offsets")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", metavar="FILE", help="write the deviations per target and direction")

    p = sub.add_parser("bench", help="the tracking benchmark: every controller on every plant (the main job)")
    p.add_argument("models", nargs="*", help="models (default shing1993_servo)")
    p.add_argument("--controllers", nargs="+", metavar="CONTROLLER",
                   help="catalog names or TOML files (default: every catalog entry); the models go before it")
    p.add_argument("--plants", default="improved,yang-sun,tvms",
                   help="comma-separated plants; the backlash-free plant is always added "
                        "(default improved,yang-sun,tvms)")
    p.add_argument("--references", default="sine,move,step", help="comma-separated references (default sine,move,step)")
    p.add_argument("--duration", type=dur,
                   help=f"simulated time of every run [s] (default per reference: {_DURATIONS})")
    p.add_argument("--jobs", "--workers", dest="jobs", type=spec_arg(JOBS),
                   help="worker processes of the local Dask cluster (default: all cores; 1: in this process; "
                        "--workers as in sweep)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="a running Dask scheduler, tcp://HOST:PORT (default DASK_SCHEDULER_ADDRESS, else local)")
    p.add_argument("--seed", type=seed, default=0, help="sensor-noise seed (default 0)")
    p.add_argument("--realtime", action="store_true",
                   help="optimisations that overrun their time budget fall back, as on the target "
                        "(default: overruns are counted, results are deterministic)")
    p.add_argument("--no-precision", action="store_true", help="skip the ISO 230-2 row per controller")
    p.add_argument("--json", metavar="FILE", help="write every figure as JSON (- for standard output; the tables then "
                                                  "go to standard error)")
    p.add_argument("--out", metavar="DIR", help="write plots and a Markdown report")
    p.add_argument("--quiet", action="store_true", help="no progress bar")

    p = sub.add_parser("perf", help="speed: simulator vs python-control, MPC and exported C step times, sweeps, bench")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--no-bench", action="store_true", help="skip timing the default bench")
    p.add_argument("--no-sweep", action="store_true", help="skip timing the sweeps (plain loop against Dask)")
    p.add_argument("--sweep-runs", type=spec_arg(SWEEP_RUNS), default=1000,
                   help="runs per controller of the sweep timing (the MPC: at most 50; default 1000)")
    p.add_argument("--jobs", type=spec_arg(JOBS), help="worker processes for the bench timing")
    return {"track": _cmd_track, "precision": _cmd_precision, "bench": _cmd_bench, "perf": _cmd_perf}

