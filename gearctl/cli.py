"""The ``gearctl`` command line. The only module that prints or exits.

A :class:`~gearctl.errors.GearctlError` becomes one line on stderr and exit code 2; argparse's own usage
errors also exit with 2. Anything else is a bug and surfaces as a traceback.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .catalog import load_model, model_names
from .errors import GearctlError, InputError
from .geometry import pair_geometry

__all__ = ["main"]


# --- helpers -------------------------------------------------------------------------------------------


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{v} must be >= 1")
    return v


def _finite_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"{text!r} must be finite")
    return v


def _positive_float(text: str) -> float:
    v = _finite_float(text)
    if v <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be > 0")
    return v


def _nonnegative_float(text: str) -> float:
    v = _finite_float(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be >= 0")
    return v


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _dump_json(obj: Any) -> str:
    def clean(o: Any) -> Any:  # JSON has no inf/nan: write null
        if isinstance(o, float) and not math.isfinite(o):
            return None
        if isinstance(o, dict):
            return {k: clean(v) for k, v in o.items()}
        if isinstance(o, list | tuple):
            return [clean(v) for v in o]
        return o

    return json.dumps(clean(json.loads(json.dumps(obj, default=_json_default))), indent=2)


def _write_csv(path: str, header: Sequence[str], columns: Sequence[Any]) -> None:
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        with open(p, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(header)
            for row in zip(*columns, strict=True):
                w.writerow([f"{v:.10g}" if isinstance(v, float | np.floating) else v for v in row])
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror}") from None


def _say_written(*pairs: tuple[str | None, str]) -> None:
    """Print ``wrote FILE (what)`` for each file the user asked for."""
    for path, what in pairs:
        if path:
            print(f"  wrote {path} ({what})")


def _save_figure(fig: Any, path: str) -> None:
    from .plots import save

    try:
        save(fig, path)
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot write plot {path}: {exc}") from None


# --- commands ------------------------------------------------------------------------------------------


def _cmd_models(args: argparse.Namespace) -> int:
    rows = []
    for name in model_names():
        m = load_model(name)
        geo = pair_geometry(m.pair)
        rows.append((name, f"{m.pair.teeth1}x{m.pair.teeth2}", f"{m.pair.module * 1e3:g}",
                     f"{math.degrees(m.pair.pressure_angle):g}", f"{geo.contact_ratio:.3f}",
                     m.source.get("citation", "")))
    if args.json:
        keys = ("name", "teeth", "module_mm", "pressure_angle_deg", "contact_ratio", "source")
        print(_dump_json([dict(zip(keys, r, strict=True)) for r in rows]))
        return 0
    head = ("name", "teeth", "m [mm]", "phi [deg]", "eps", "source")
    widths = [max(len(str(r[i])) for r in [*rows, head]) for i in range(5)]
    print("  ".join(h.ljust(w) for h, w in zip(head[:5], widths, strict=True)) + "  " + head[5])
    for r in rows:
        src = r[5] if len(r[5]) <= 70 else r[5][:67] + "..."
        print("  ".join(str(v).ljust(w) for v, w in zip(r[:5], widths, strict=True)) + "  " + src)
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    from .summary import model_summary

    s = model_summary(load_model(args.model))
    if args.json:
        print(_dump_json(s))
        return 0
    ms = s["mesh_stiffness"]
    loa = s["line_of_action"]
    p = s["plant"]
    print(f"{s['model']}: {s['teeth'][0]} x {s['teeth'][1]} teeth, module {s['module'] * 1e3:g} mm, "
          f"pressure angle {s['pressure_angle_deg']:g} deg, face width {s['face_width'] * 1e3:g} mm")
    print(f"  contact ratio          {s['contact_ratio']:.6g}")
    print(f"  base pitch             {s['base_pitch'] * 1e3:.6g} mm")
    print(f"  pitch radius           {s['pitch_radius'][0] * 1e3:.6g}, {s['pitch_radius'][1] * 1e3:.6g} mm")
    print(f"  base radius            {s['base_radius'][0] * 1e3:.6g}, {s['base_radius'][1] * 1e3:.6g} mm")
    print("  line of action [mm]    " + ", ".join(f"{k} {v * 1e3:.4f}" for k, v in loa.items()))
    print(f"  inertia                I1 {s['inertia'][0]:.5g}, I2 {s['inertia'][1]:.5g} kg m^2")
    print(f"  equivalent mass        {s['equivalent_mass']:.5g} kg (along the line of action)")
    print(f"  mesh stiffness         mean {ms['mean']:.5g} N/m ({s['mesh_stiffness_per_width']:.3g} N/(mm um)), "
          f"C1 {ms['c1']:.4g}, C2 {ms['c2']:.4g}, min {ms['min']:.4g}, max {ms['max']:.4g}")
    print(f"  damping coefficient    {s['damping_coefficient']:.5g} N s/m (eq 38, consistent form)")
    print(f"  Yang-Sun stiffness     {s['yang_sun_stiffness']:.5g} N/m (eq 39)")
    print(f"  backlash                {s['backlash'] * 1e6:.4g} um along the line of action")
    print(f"  plant                  k {p['k']:.5g} N/m, c {p['c']:.5g} N s/m, J1 {p['J1']:.5g}, J2 {p['J2']:.5g} "
          f"kg m^2, mesh mode {p['natural_frequency_hz']:.5g} Hz, {p['contact_law']} contact law")
    return 0


def _cmd_stiffness(args: argparse.Namespace) -> int:
    from .stiffness import COMPONENTS, mesh_stiffness, mesh_stiffness_at, tooth_deflections

    model = load_model(args.model)
    ms = mesh_stiffness(model.pair, points=args.points)
    td = tooth_deflections(model.pair, points=args.points)
    if args.csv:
        K = mesh_stiffness_at(model.pair, td.theta1)
        header = ["theta1", "K"] + [f"{c}_{j}" for j in (1, 2) for c in (*COMPONENTS, "total")]
        header += ["k1", "k2", "k_pair"]
        cols = [td.theta1, K] + [d[c] for d in (td.gear1, td.gear2) for c in (*COMPONENTS, "total")]
        cols += [td.stiffness1, td.stiffness2, td.pair_stiffness]
        _write_csv(args.csv, header, cols)
    if args.plot:
        from .plots import plot_stiffness

        _save_figure(plot_stiffness(td, ms, title=model.name), args.plot)
    print(f"{model.name}: mesh stiffness over one mesh cycle ({ms.theta1.size} points): "
          f"mean {ms.mean:.5g} N/m, C1 {ms.c1:.4g}, C2 {ms.c2:.4g}, min {ms.min:.4g}, max {ms.max:.4g} N/m")
    if args.csv:
        print(f"  wrote {args.csv} (theta1 over the path of contact C->D, deflections per unit load [m/N])")
    if args.plot:
        print(f"  wrote {args.plot} (report Figures 8-11)")
    return 0


def _cmd_simulate(args: argparse.Namespace) -> int:
    from .plant import build_plant
    from .simulate import report_case

    model = load_model(args.model)
    plant = build_plant(model, args.plant)
    res = report_case(plant, args.case, args.duration, omega1=args.omega1, omega2=args.omega2,
                      torque1=args.torque1, torque2=args.torque2, dt=args.dt)
    energy = res.energy()
    counts = res.impact_counts()
    summary = {
        "model": model.name,
        "plant": plant.kind.value,
        "case": args.case,
        "duration": float(res.t[-1]),
        "solver": res.solver,
        "impacts": counts,
        "impact_times": [e.t for e in res.impacts],
        "max_impact_velocity": max((abs(e.velocity) for e in res.impacts), default=0.0),
        "max_penetration": res.max_penetration,
        "final": dict(zip(("theta1", "theta2", "omega1", "omega2"), res.x[:, -1].tolist(), strict=True)),
        "final_mode": res.mode_labels()[-1],
        "energy": {"initial": float(energy[0]), "final": float(energy[-1])},
        "backlash": plant.backlash,
        "mesh_stiffness": plant.k,
        "damping_coefficient": plant.c,
    }
    if args.csv:
        _write_csv(args.csv, ["t", "theta1", "theta2", "omega1", "omega2", "s", "mode", "force"],
                   [res.t, *res.x, res.s, res.mode_labels(), res.force])
    if args.plot:
        from .plots import plot_simulation

        _save_figure(plot_simulation({plant.kind.value: res}, title=f"{model.name}, {args.case} case"), args.plot)
    if args.json:
        print(_dump_json(summary))
        return 0
    f = summary["final"]
    print(f"{model.name} ({plant.kind.value} plant, {args.case} case, {summary['duration'] * 1e3:.4g} ms, "
          f"{res.solver} solver)")
    print(f"  impacts                front {counts['front']}, back {counts['back']}, fastest "
          f"{summary['max_impact_velocity']:.4g} m/s")
    print(f"  max penetration        {res.max_penetration * 1e6:.4g} um (|s| - b)")
    print(f"  final                  theta1 {f['theta1']:.6g} rad, theta2 {f['theta2']:.6g} rad, "
          f"omega1 {f['omega1']:.6g} rad/s, omega2 {f['omega2']:.6g} rad/s, {summary['final_mode']}")
    print(f"  energy                 {energy[0]:.6g} J -> {energy[-1]:.6g} J")
    _say_written((args.csv, "CSV"), (args.plot, "plot"))
    return 0


def _cmd_linearize(args: argparse.Namespace) -> int:
    import numpy as np

    from .modes import linearize_modes
    from .plant import build_plant

    model = load_model(args.model)
    modes = linearize_modes(build_plant(model))
    sys = modes.mode(args.mode)
    mesh = modes.mesh
    contact = args.mode == "contact"
    out = {
        "model": model.name,
        "mode": args.mode,
        "states": list(sys.state_labels),
        "inputs": list(sys.input_labels),
        "outputs": list(sys.output_labels),
        "A": sys.A.tolist(), "B": sys.B.tolist(), "C": sys.C.tolist(), "D": sys.D.tolist(),
        "poles": [[float(p.real), float(p.imag)] for p in sys.poles()],
        "natural_frequency_hz": mesh.natural_frequency_hz if contact else None,
        "damping_ratio": mesh.damping_ratio if contact else None,
        "antiresonance_hz": mesh.antiresonance_hz if contact else None,
        "motor_angle_tf": {"num": np.asarray(modes.motor_angle.num[0][0]).tolist(),
                           "den": np.asarray(modes.motor_angle.den[0][0]).tolist()},
        "load_angle_tf": {"num": np.asarray(modes.load_angle.num[0][0]).tolist(),
                          "den": np.asarray(modes.load_angle.den[0][0]).tolist()},
    }
    if args.bode or args.step:
        from .plots import plot_bode, plot_step

        both = {"contact": modes.contact, "separation": modes.separation, "rigid": modes.rigid}
        if args.bode:
            _save_figure(plot_bode(both, output="theta1", title=f"{model.name}: motor torque to motor angle"),
                         args.bode)
        if args.step:
            T = np.linspace(0, 8 / max(mesh.natural_frequency_hz, 1.0), 2000)
            _save_figure(plot_step({"contact": modes.contact}, output="s", T=T,
                                   title=f"{model.name}: motor torque step, relative displacement"), args.step)
    if args.json:
        print(_dump_json(out))
        return 0
    print(f"{model.name}: {args.mode} model, states {', '.join(out['states'])}; inputs {', '.join(out['inputs'])}; "
          f"outputs {', '.join(out['outputs'])}")
    print("  poles                  " + ", ".join(f"{p.real:.5g}{p.imag:+.5g}j" for p in sys.poles()))
    if contact:
        print(f"  mesh mode              {mesh.natural_frequency_hz:.5g} Hz, damping ratio {mesh.damping_ratio:.4g}; "
              f"anti-resonance {mesh.antiresonance_hz:.5g} Hz (motor torque -> motor angle)")
    print(f"  rigid train            J_eq {modes.plant.J1 + modes.plant.J2 / modes.plant.gear_ratio ** 2:.5g} kg m^2 "
          f"on the motor, gear ratio {modes.plant.gear_ratio:.4g}")
    _say_written((args.bode, "Bode of contact, separation and rigid models"), (args.step, "step response"))
    return 0


def _cmd_describe(args: argparse.Namespace) -> int:
    from .describe import describe

    d = describe(args.model, args.controller, duration=args.duration)
    if args.json:
        print(_dump_json(d))
        return 0
    b = None
    try:
        from .plant import build_plant

        b = build_plant(load_model(args.model)).backlash
    except GearctlError:
        pass
    print(f"{d['model']}: {d['controller']} ({d['feedback']} feedback, Ts {d['sample_time'] * 1e3:g} ms), limit cycle "
          f"of the backlash loop")
    print(f"  {'':28s} {'f [Hz]':>9s} {'A/b':>8s} {'load [urad]':>12s} {'torque [N m]':>13s}  stable")
    rows = [("describing function", p) for p in d["prediction"] or []]
    rows += [("impact balance", p) for p in d.get("impact_prediction") or []]
    sim = d["simulation"]

    def fmt(v: float | None, scale: float = 1.0, spec: str = ".4g") -> str:
        return "—" if v is None else format(v * scale, spec)

    for name, p in rows:
        a = p.get("amplitude")
        print(f"  {name:28s} {fmt(p.get('frequency_hz')):>9s} {fmt(a / b if a and b else None):>8s} "
              f"{fmt(p.get('load_amplitude'), 1e6):>12s} {fmt(p.get('torque_amplitude')):>13s}  {p.get('stable')}")
    if not rows:
        print("  (no limit cycle predicted)")
    a = sim.get("amplitude")
    print(f"  {'simulation':28s} {fmt(sim.get('frequency_hz')):>9s} {fmt(a / b if a and b else None):>8s} "
          f"{fmt(sim.get('load_amplitude'), 1e6):>12s} {fmt(sim.get('torque_amplitude')):>13s}  "
          f"{'limit cycle' if sim.get('limit_cycle') else 'none'} ({fmt(sim.get('impacts_per_second'))} impacts/s)")
    ag = d["agreement"]
    print("  prediction / simulation    " + ", ".join(f"{k.replace('_ratio', '')} {v:.3g}" for k, v in ag.items()
                                                        if v is not None))
    return 0


def _run_track(model_name: str, controller_name: str, plant_kind: str, ref_kind: str, duration: float | None,
               backlash: float | None, seed: int, realtime: bool = False) -> tuple[Any, Any, Any]:
    """Build plant and controller and run one closed loop (shared by track and describe)."""
    from .catalog import load_controller
    from .closedloop import simulate_closed_loop
    from .plant import build_plant
    from .references import reference

    model = load_model(model_name)
    # --backlash changes the model: the plant and the controller's default estimate (a controller file's
    # own `backlash` key still wins, to test a wrong estimate)
    nominal = build_plant(model, backlash=backlash)  # controllers are designed on the improved plant
    plant = build_plant(model, plant_kind, backlash=backlash)
    ctrl = load_controller(controller_name, nominal)
    ctrl.realtime = realtime
    ref = reference(ref_kind)
    dur = duration if duration is not None else _DEFAULT_DURATION[ref_kind]
    res = simulate_closed_loop(plant, ctrl, ref, dur, sensors=model.sensors, seed=seed)
    return model, ctrl, res


_DEFAULT_DURATION = {"sine": 3.0, "step": 2.0, "ramp": 1.5, "move": 1.0}


def _cmd_track(args: argparse.Namespace) -> int:
    from .metrics import tracking_metrics

    model, ctrl, res = _run_track(args.model, args.controller, args.plant, args.reference, args.duration,
                                  args.backlash, args.seed, args.realtime)
    m = tracking_metrics(res)
    out = {"model": model.name, "controller": res.controller, "plant": args.plant, "reference": args.reference,
           "backlash": res.plant.backlash, "seed": args.seed, **m}
    if args.csv:
        _write_csv(args.csv, ["t", "reference", "theta1", "theta2", "omega1", "omega2", "s", "mode", "torque",
                              "y_motor", "y_load"],
                   [res.t, res.reference, *res.x, res.s, res.mode, res.torque, res.y_motor, res.y_load])
    if args.plot:
        from .plots import plot_tracking

        _save_figure(plot_tracking({ctrl.name: res}, title=f"{model.name}, {args.plant} plant, {args.reference}"),
                     args.plot)
    if args.json:
        print(_dump_json(out))
        return 0
    st = m["solve_time"]
    print(f"{model.name}: {ctrl.name} on the {args.plant} plant, {args.reference} reference, "
          f"{m['duration']:.3g} s (b = {res.plant.backlash * 1e6:.4g} um)")
    print(f"  load-angle error       RMS {m['rms_error']:.4g} rad, max {m['max_error']:.4g} rad, "
          f"final {m['final_error']:.3g} rad")
    print(f"  impacts                {m['impacts']} (front {m['impacts_front']}, back {m['impacts_back']}), "
          f"fastest {m['max_impact_velocity']:.3g} m/s")
    if st is not None:
        print(f"  solve time             median {st['median'] * 1e6:.0f} us, p99 {st['p99'] * 1e6:.0f} us, "
              f"max {st['max'] * 1e6:.0f} us (sample period {ctrl.Ts * 1e6:.0f} us); overruns {m['overruns']}, "
              f"fallbacks {m['fallbacks']}")
    print(f"  wall time              {m['wall_time']:.3g} s ({m['duration'] / max(m['wall_time'], 1e-9):.0f} "
          f"simulated s per wall s)")
    _say_written((args.csv, "CSV"), (args.plot, "plot"))
    return 0


def _cmd_precision(args: argparse.Namespace) -> int:
    from .catalog import load_controller
    from .plant import build_plant
    from .precision import precision_test

    model = load_model(args.model)
    nominal = build_plant(model, backlash=args.backlash)
    plant = build_plant(model, args.plant, backlash=args.backlash)
    ctrl = load_controller(args.controller, nominal)
    res = precision_test(plant, ctrl, targets=args.targets, cycles=args.cycles, travel=args.travel,
                         dwell=args.dwell, sensors=model.sensors, seed=args.seed)
    st = res.stats
    out = {
        "model": model.name, "controller": ctrl.describe(), "plant": args.plant, "backlash": plant.backlash,
        "lost_motion": 2 * plant.backlash / plant.rb2,
        "targets": res.targets.tolist(), "cycles": args.cycles,
        "reversal_value": st["reversal_value"], "repeatability": st["repeatability"],
        "repeatability_up": st["repeatability_up"], "repeatability_down": st["repeatability_down"],
        "accuracy": st["accuracy"], "mean_bidirectional_deviation": st["mean_bidirectional_deviation"],
        "systematic_deviation": st["systematic_deviation"], "mean_reversal": st["mean_reversal"],
        "per_target": [
            {"target": float(P), "mean_up": float(st["mean_up"][i]), "mean_down": float(st["mean_down"][i]),
             "s_up": float(st["s_up"][i]), "s_down": float(st["s_down"][i]), "reversal": float(st["reversal"][i]),
             "deviations_up": res.deviations_up[i].tolist(), "deviations_down": res.deviations_down[i].tolist()}
            for i, P in enumerate(res.targets)],
        "impacts": len(res.run.impacts),
    }
    if args.plot:
        from .plots import plot_precision

        _save_figure(plot_precision(res), args.plot)
    if args.json:
        print(_dump_json(out))
        return 0
    print(f"{model.name}: {ctrl.name} on the {args.plant} plant, ISO 230-2 linear cycle, {args.targets} targets "
          f"over {args.travel:g} rad, {args.cycles} cycles")
    print(f"  reversal value B       {st['reversal_value'] * 1e6:.4g} urad (lost motion 2b/r_b2 = "
          f"{out['lost_motion'] * 1e6:.4g} urad)")
    print(f"  repeatability R        {st['repeatability'] * 1e6:.4g} urad (R+ {st['repeatability_up'] * 1e6:.3g}, "
          f"R- {st['repeatability_down'] * 1e6:.3g})")
    print(f"  accuracy A             {st['accuracy'] * 1e6:.4g} urad")
    print(f"  mean bidirectional M   {st['mean_bidirectional_deviation'] * 1e6:.4g} urad")
    print("  target [rad]   mean+ [urad]  mean- [urad]  B_i [urad]")
    for row in out["per_target"]:
        print(f"  {row['target']:11.4f}  {row['mean_up'] * 1e6:12.2f}  {row['mean_down'] * 1e6:12.2f}  "
              f"{row['reversal'] * 1e6:10.2f}")
    if args.plot:
        print(f"  wrote {args.plot}")
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from .bench import BenchSpec, bench_table, error_traces, run_bench

    plants = tuple(p.strip() for p in args.plants.split(",") if p.strip())
    refs = tuple(r.strip() for r in args.references.split(",") if r.strip())
    spec = BenchSpec(models=tuple(args.models) or ("shing1993_servo",), controllers=tuple(args.controllers or ()),
                     plants=plants, references=refs, duration=args.duration, seed=args.seed,
                     realtime=args.realtime)
    n = len(spec.runs())
    bar = None
    if not args.quiet:
        from tqdm import tqdm

        bar = tqdm(total=n, desc="gearctl bench", unit="run", file=sys.stderr, leave=False, disable=None)

    def progress(done: int, total: int) -> None:
        if bar is not None:
            bar.update(1)

    import time

    t0 = time.perf_counter()
    result = run_bench(spec, jobs=args.jobs, progress=progress)
    wall = time.perf_counter() - t0
    if bar is not None:
        bar.close()
    result["wall_time"] = wall
    result["jobs"] = args.jobs or (os.cpu_count() or 1)
    text = bench_table(result)
    print(text, end="")
    print(f"{n} runs in {wall:.1f} s on {result['jobs']} process(es)")
    if args.json:
        try:
            Path(args.json).parent.mkdir(parents=True, exist_ok=True)
            Path(args.json).write_text(_dump_json(result))
        except OSError as exc:
            raise InputError(f"cannot write {args.json}: {exc.strerror}") from None
        print(f"wrote {args.json}")
    if args.out:
        from .plots import plot_bench_bars, plot_bench_errors

        out = Path(args.out)
        traces = error_traces(result)
        for ref in spec.references:
            _save_figure(plot_bench_errors(traces, reference=ref), str(out / f"errors_{ref}.png"))
        _save_figure(plot_bench_bars(result), str(out / "rms_by_controller.png"))
        md = ["# gearctl bench", "", f"{n} runs, {wall:.1f} s on {result['jobs']} process(es); models "
              f"{', '.join(spec.models)}; plants {', '.join(spec.plants)} and the backlash-free limit.", "",
              bench_table(result, markdown=True), "![RMS error by controller and plant](rms_by_controller.png)", ""]
        md += [f"![errors, {ref}](errors_{ref}.png)" for ref in spec.references]
        try:
            (out / "report.md").write_text("\n".join(md) + "\n")
        except OSError as exc:
            raise InputError(f"cannot write {out / 'report.md'}: {exc.strerror}") from None
        print(f"wrote {out}/report.md and plots")
    return 0


def _cmd_perf(args: argparse.Namespace) -> int:
    from .catalog import controller_names
    from .perf import bench_wall_time, mpc_timing, sim_speed

    out: dict[str, Any] = {}
    scen = {name: sim_speed(name) for name in ("free", "pd")}
    keys = ("gearctl_sim_per_wall", "python_control_sim_per_wall", "ratio", "gearctl_error", "python_control_error")
    # the contract keys at the top of "sim" are the harder case, the 1 kHz closed loop; both scenarios below
    out["sim"] = {**{k: scen["pd"][k] for k in keys}, "free": scen["free"], "pd": scen["pd"]}
    out["mpc"] = mpc_timing() if "mpc" in controller_names() else None
    out["bench"] = None if args.no_bench else bench_wall_time(jobs=args.jobs)
    if args.json:
        print(_dump_json(out))
        return 0
    for name, r in scen.items():
        label = {"free": "free vibration (shing1993)", "pd": "1 kHz PD loop on a sine (shing1993_servo)"}[name]
        print(f"{label}:")
        print(f"  gearctl                      {r['gearctl_sim_per_wall']:10.4g} sim-s/wall-s, "
              f"error {r['gearctl_error']:.1e} b")
        print(f"  python-control (default tol) {r['python_control_sim_per_wall']:10.4g} sim-s/wall-s, error "
              f"{r['python_control_error']:.1e} b -> {r['ratio']:.0f}x")
        print(f"  python-control (rtol 1e-10)  {r['python_control_tight_sim_per_wall']:10.4g} sim-s/wall-s, error "
              f"{r['python_control_tight_error']:.1e} b -> {r['ratio_equal_accuracy']:.0f}x at equal accuracy")
    m = out["mpc"]
    if m is not None:
        print(f"MPC solve per step ({m['steps']} steps, Ts {m['Ts'] * 1e6:.0f} us): median {m['median'] * 1e6:.0f} us, "
              f"p99 {m['p99'] * 1e6:.0f} us, max {m['max'] * 1e6:.0f} us; whole step p99 {m['step_p99'] * 1e6:.0f} us")
        print("  within budget: " + ", ".join(f"{k} {v * 100:.1f} %" for k, v in m["budgets"].items()))
    b = out["bench"]
    if b is not None:
        print(f"default bench: {b['runs']} runs, {b['simulated_time']:.0f} simulated s in {b['wall_time']:.1f} s wall "
              f"on {b['jobs']} process(es)")
    return 0


# --- parser --------------------------------------------------------------------------------------------

_COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {}


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="gearctl",
        description="Control design for geared servos with backlash (Shing, Tsai & Krishnaprasad, TR 93-28).",
    )
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("models", help="list the catalog of gear models")
    p.add_argument("--json", action="store_true", help="print JSON")
    _COMMANDS["models"] = _cmd_models

    p = sub.add_parser("info", help="geometry, mesh stiffness, damping and plant figures of a model")
    p.add_argument("model", help="catalog name (see `gearctl models`) or path to a TOML file")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    _COMMANDS["info"] = _cmd_info

    p = sub.add_parser("stiffness", help="mesh stiffness and tooth deflections over the mesh cycle (Figs 8-11)")
    p.add_argument("model", help="catalog name or path to a TOML file")
    p.add_argument("--points", type=_positive_int, default=401, help="sample points (default 401)")
    p.add_argument("--csv", metavar="FILE", help="write theta1, K and the deflection components")
    p.add_argument("--plot", metavar="FILE", help="write the figure (png, pdf, svg)")
    _COMMANDS["stiffness"] = _cmd_stiffness

    p = sub.add_parser("simulate", help="simulate the report's free-vibration or constant-load case")
    p.add_argument("model", help="catalog name or path to a TOML file")
    p.add_argument("--case", choices=("free", "load"), default="free",
                   help="free: omega1(0)=50 rad/s, no torque; load: plus xi1=1 N m, xi2=-1 N m (default free)")
    p.add_argument("--plant", choices=("improved", "yang-sun", "tvms"), default="improved",
                   help="mesh law (default improved)")
    p.add_argument("--duration", type=_positive_float, default=0.02, help="simulated time [s] (default 0.02)")
    p.add_argument("--dt", type=_positive_float, default=1e-6, help="output interval [s] (default 1e-6)")
    p.add_argument("--omega1", type=_finite_float, help="initial velocity of gear 1 [rad/s]")
    p.add_argument("--omega2", type=_finite_float, help="initial velocity of gear 2 [rad/s]")
    p.add_argument("--torque1", type=_finite_float, help="torque on gear 1 [N m], clockwise positive")
    p.add_argument("--torque2", type=_finite_float, help="torque on gear 2 [N m], counter-clockwise positive")
    p.add_argument("--csv", metavar="FILE", help="write t, theta1, theta2, omega1, omega2, s, mode, force")
    p.add_argument("--plot", metavar="FILE", help="write the figure (angles, velocities, s, force)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    _COMMANDS["simulate"] = _cmd_simulate

    p = sub.add_parser("linearize", help="linear model per contact mode (python-control), Bode and step")
    p.add_argument("model", help="catalog name or path to a TOML file")
    p.add_argument("--mode", choices=("contact", "separation", "rigid"), default="contact",
                   help="contact (front or back), separation or rigid (k -> inf) (default contact)")
    p.add_argument("--json", action="store_true", help="print A, B, C, D, poles, mesh-mode figures as JSON")
    p.add_argument("--bode", metavar="FILE", help="write the Bode diagram of all modes on common axes")
    p.add_argument("--step", metavar="FILE", help="write the contact-mode step response (s)")
    _COMMANDS["linearize"] = _cmd_linearize

    p = sub.add_parser("describe", help="describing-function limit cycle of a PID loop vs simulation")
    p.add_argument("model", help="model (e.g. shing1993_servo)")
    p.add_argument("controller", help="a pid controller (e.g. pid_load: load-side feedback)")
    p.add_argument("--duration", type=_positive_float, default=2.0, help="simulated time [s] (default 2)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    _COMMANDS["describe"] = _cmd_describe

    p = sub.add_parser("track", help="run a controller against the nonlinear plant on a reference")
    p.add_argument("model", nargs="?", default="shing1993_servo", help="model (default shing1993_servo)")
    p.add_argument("controller", nargs="?", default="deadzone_inverse",
                   help="controller: catalog name (pid, deadzone_inverse, mpc) or TOML path (default deadzone_inverse)")
    p.add_argument("--plant", choices=("improved", "yang-sun", "tvms"), default="improved",
                   help="plant (default improved)")
    p.add_argument("--reference", choices=("sine", "step", "ramp", "move"), default="sine",
                   help="sine: 0.1 rad 1 Hz; step: 0.05 rad + 0.5 N m load step; ramp; move: S-curve (default sine)")
    p.add_argument("--duration", type=_positive_float, help="simulated time [s] (default per reference)")
    p.add_argument("--backlash", type=_nonnegative_float, help="override the plant's backlash [m] (0: none)")
    p.add_argument("--seed", type=int, default=0, help="sensor-noise seed (default 0)")
    p.add_argument("--realtime", action="store_true",
                   help="an optimisation that overruns its time budget falls back, as on the target "
                        "(default: overruns are counted, results are deterministic)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--csv", metavar="FILE", help="write the run per sample")
    p.add_argument("--plot", metavar="FILE", help="write reference/load angle, error, torque and gap plot")
    _COMMANDS["track"] = _cmd_track

    p = sub.add_parser("precision", help="ISO 230-2 positioning test: reversal value, repeatability, accuracy")
    p.add_argument("model", nargs="?", default="shing1993_servo", help="model (default shing1993_servo)")
    p.add_argument("controller", nargs="?", default="deadzone_inverse", help="controller (default deadzone_inverse)")
    p.add_argument("--targets", type=_positive_int, default=5, help="target positions (default 5)")
    p.add_argument("--cycles", type=_positive_int, default=5, help="cycles (default 5, as ISO 230-2)")
    p.add_argument("--travel", type=_positive_float, default=0.5, help="span of the targets [rad] (default 0.5)")
    p.add_argument("--dwell", type=_positive_float, default=0.3, help="rest before each measurement [s] (default 0.3)")
    p.add_argument("--plant", choices=("improved", "yang-sun", "tvms"), default="improved", help="plant")
    p.add_argument("--backlash", type=_nonnegative_float, help="override the model's backlash [m]")
    p.add_argument("--seed", type=int, default=0, help="seed of sensor noise and target offsets")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", metavar="FILE", help="write the deviations per target and direction")
    _COMMANDS["precision"] = _cmd_precision

    p = sub.add_parser("bench", help="the tracking benchmark: every controller on every plant (the main job)")
    p.add_argument("models", nargs="*", help="models (default shing1993_servo)")
    p.add_argument("--controllers", nargs="+", metavar="FILE", help="controllers (default: every catalog entry)")
    p.add_argument("--plants", default="improved,yang-sun,tvms",
                   help="comma-separated plants; the backlash-free plant is always added "
                        "(default improved,yang-sun,tvms)")
    p.add_argument("--references", default="sine,move,step", help="comma-separated references (default sine,move,step)")
    p.add_argument("--duration", type=_positive_float, help="simulated time of every run [s] (default per reference)")
    p.add_argument("--jobs", type=_positive_int, help="worker processes (default: all cores)")
    p.add_argument("--seed", type=int, default=0, help="sensor-noise seed (default 0)")
    p.add_argument("--realtime", action="store_true",
                   help="optimisations that overrun their time budget fall back, as on the target "
                        "(default: overruns are counted, results are deterministic)")
    p.add_argument("--json", metavar="FILE", help="write every figure as JSON")
    p.add_argument("--out", metavar="DIR", help="write plots and a Markdown report")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    _COMMANDS["bench"] = _cmd_bench

    p = sub.add_parser("perf", help="speed: simulator vs python-control, MPC solve times, bench wall time")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--no-bench", action="store_true", help="skip timing the default bench")
    p.add_argument("--jobs", type=_positive_int, help="worker processes for the bench timing")
    _COMMANDS["perf"] = _cmd_perf

    return ap


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``gearctl`` command line; return the exit code (0 success, 2 bad input)."""
    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse: --help (0) or a usage error (2)
        return int(exc.code or 0)
    try:
        return _COMMANDS[args.command](args)
    except GearctlError as exc:
        print(f"gearctl {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
