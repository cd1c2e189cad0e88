"""Commands on a model: ``models``, ``info``, ``stiffness``, ``simulate``, ``linearize``, ``describe``."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ..catalog import load_model, model_names
from ..errors import InputError, SimulationError
from ..geometry import pair_geometry
from ..limits import check_output_size
from ..units import DURATION
from .common import (
    OMEGA,
    POINTS,
    STAGE,
    TORQUE,
    dump_json,
    positive_quantity,
    progress_bar,
    save_figure,
    say_written,
    separated_past_flank,
    spec_arg,
    warn,
    write_csv_stream,
    yang_sun_notes,
)

__all__ = ["register"]




def _poles(modes: Any, name: str) -> list[complex]:
    """The poles of mode ``name``, the rigid bodies' exactly (:meth:`gearctl.modes.ContactModes.poles`: the free
    rotation's 0, a frictionless body's second 0, and a slow friction pole that rounding would have made 0)."""
    return [complex(p) for p in modes.poles(name)]


def _duration_text(t: float) -> str:
    """A duration as a person reads it: ms below a second (the free case's 20 ms), s above (not "1e+08 ms")."""
    return f"{t * 1e3:.4g} ms" if t < 1.0 else f"{t:.6g} s"

def _cmd_models(args: argparse.Namespace) -> int:
    rows, extra = [], []
    for name in model_names():
        m = load_model(name)
        if m.n_stages == 1:
            geo = pair_geometry(m.pair)
            teeth, mod, phi, eps = (f"{m.pair.teeth1}x{m.pair.teeth2}", f"{m.pair.module * 1e3:g}",
                                    f"{math.degrees(m.pair.pressure_angle):g}", f"{geo.contact_ratio:.3f}")
        else:
            ps = [s.pair for s in m.stages]
            teeth = "+".join(f"{p.teeth1}x{p.teeth2}" for p in ps)
            mod = "/".join(f"{p.module * 1e3:g}" for p in ps)
            phi = "/".join(f"{math.degrees(p.pressure_angle):g}" for p in ps)
            eps = "/".join(f"{pair_geometry(p).contact_ratio:.2f}" for p in ps)
        rows.append((name, teeth, mod, phi, eps, m.source.get("citation", "")))
        extra.append({"stages": m.n_stages, "contact_ratio": pair_geometry(m.pair).contact_ratio,
                      "contact_ratios": [pair_geometry(s.pair).contact_ratio for s in m.stages],
                      "module_mm": m.pair.module * 1e3, "pressure_angle_deg": math.degrees(m.pair.pressure_angle),
                      "modules_mm": [s.pair.module * 1e3 for s in m.stages],
                      "pressure_angles_deg": [math.degrees(s.pair.pressure_angle) for s in m.stages]})
    if args.json:
        keys = ("name", "teeth", "module_mm", "pressure_angle_deg", "contact_ratio", "source")
        # contact_ratio, module_mm, pressure_angle_deg: the first stage's (a pair's own), as numbers (the table's
        # text, "1/1" on a train, had been given); every stage's in contact_ratios, modules_mm, pressure_angles_deg
        print(dump_json([{**dict(zip(keys, r, strict=True)), **x} for r, x in zip(rows, extra, strict=True)]))
        return 0
    head = ("name", "teeth", "m [mm]", "phi [deg]", "eps", "source")
    widths = [max(len(str(r[i])) for r in [*rows, head]) for i in range(5)]
    print("  ".join(h.ljust(w) for h, w in zip(head[:5], widths, strict=True)) + "  " + head[5])
    for r in rows:
        src = r[5] if len(r[5]) <= 70 else r[5][:67] + "..."
        print("  ".join(str(v).ljust(w) for v, w in zip(r[:5], widths, strict=True)) + "  " + src)
    return 0


def _print_stage(s: dict[str, Any], indent: str = "  ") -> None:
    ms = s["mesh_stiffness"]
    loa = s["line_of_action"]
    print(f"{indent}contact ratio          {s['contact_ratio']:.6g}")
    if any(s["profile_shift"]):
        print(f"{indent}profile shift          x1 {s['profile_shift'][0]:g}, x2 {s['profile_shift'][1]:g}; operating "
              f"pressure angle {s['operating_pressure_angle_deg']:.5g} deg, centre distance "
              f"{s['centre_distance'] * 1e3:.6g} mm")
    print(f"{indent}base pitch             {s['base_pitch'] * 1e3:.6g} mm")
    print(f"{indent}pitch radius           {s['pitch_radius'][0] * 1e3:.6g}, {s['pitch_radius'][1] * 1e3:.6g} mm")
    print(f"{indent}base radius            {s['base_radius'][0] * 1e3:.6g}, {s['base_radius'][1] * 1e3:.6g} mm")
    print(f"{indent}line of action [mm]    " + ", ".join(f"{k} {v * 1e3:.4f}" for k, v in loa.items()))
    print(f"{indent}inertia                I1 {s['inertia'][0]:.5g}, I2 {s['inertia'][1]:.5g} kg m^2")
    shafts = s["plant_equivalent_mass"]
    with_shafts = abs(shafts - s["equivalent_mass"]) > 1e-9 * shafts  # a servo: motor and load on the shafts
    print(f"{indent}equivalent mass        {s['equivalent_mass']:.5g} kg (the gears alone, along the line of action)"
          + (f"; {shafts:.5g} kg with the shafts" if with_shafts else ""))
    print(f"{indent}mesh stiffness         mean {ms['mean']:.5g} N/m ({s['mesh_stiffness_per_width']:.3g} N/(mm um)), "
          f"C1 {ms['c1']:.4g}, C2 {ms['c2']:.4g}, min {ms['min']:.4g}, max {ms['max']:.4g}")
    if s.get("mesh_stiffness_given"):
        print(f"{indent}plant stiffness        {s['plant_stiffness']:.5g} N/m (given in the file; the computed mean "
              "above is not used)")
    how = "given in the file" if s.get("damping_coefficient_given") else \
        ("eq 38, consistent form" + (", on the equivalent mass with the shafts" if with_shafts else ""))
    print(f"{indent}damping coefficient    {s['damping_coefficient']:.5g} N s/m ({how})")
    print(f"{indent}Yang-Sun stiffness     {s['yang_sun_stiffness']:.5g} N/m (eq 39)")
    print(f"{indent}backlash               {s['backlash'] * 1e6:.4g} um along the line of action")


def _cmd_info(args: argparse.Namespace) -> int:
    from ..plant import build_plant
    from ..runs import unholdable_load_torque
    from ..summary import model_summary

    model = load_model(args.model)
    s = model_summary(model)
    stages = s["stages"] if s["stages_count"] > 1 else [s]
    warn("info", [(f"stage {i}: " if len(stages) > 1 else "") + st["stiffness_note"]
                  for i, st in enumerate(stages, start=1) if st["stiffness_note"]])
    warn("info", [w for w in (unholdable_load_torque(build_plant(model)),) if w])
    warn("info", [(f"stage {i}: " if len(stages) > 1 else "") + st["tip_note"]
                  for i, st in enumerate(stages, start=1) if st["tip_note"]], kind="note")
    if args.json:
        print(dump_json(s))
        return 0
    p = s["plant"]
    if s["stages_count"] == 1:
        print(f"{s['model']}: {s['teeth'][0]} x {s['teeth'][1]} teeth, module {s['module'] * 1e3:g} mm, "
              f"pressure angle {s['pressure_angle_deg']:g} deg, face width {s['face_width'] * 1e3:g} mm")
        _print_stage(s)
        print(f"  plant                  k {p['k']:.5g} N/m, c {p['c']:.5g} N s/m, J1 {p['J1']:.5g}, J2 {p['J2']:.5g} "
              f"kg m^2, mesh mode {p['natural_frequency_hz']:.5g} Hz, {p['contact_law']} contact law")
        _print_sensors(s["sensors"])
        return 0
    print(f"{s['model']}: {s['stages_count']}-stage train, ratio {p['gear_ratio']:.5g}, lost motion at the output "
          f"{s['lost_motion'] * 1e6:.4g} urad, stiffness at the output {s['equivalent_stiffness']:.4g} N m/rad")
    for i, st in enumerate(s["stages"], start=1):
        print(f"  stage {i}: {st['teeth'][0]} x {st['teeth'][1]} teeth, module {st['module'] * 1e3:g} mm, pressure "
              f"angle {st['pressure_angle_deg']:g} deg, face width {st['face_width'] * 1e3:g} mm, "
              f"ratio {st['ratio']:.4g}")
        _print_stage(st, indent="    ")
    print("  plant                  J " + ", ".join(f"{v:.4g}" for v in p["J"]) + " kg m^2 (motor first); k "
          + ", ".join(f"{v:.4g}" for v in p["k"]) + " N/m; resonances in contact "
          + ", ".join(f"{v:.5g}" for v in p["resonances_hz"]) + f" Hz (the mesh mode {p['natural_frequency_hz']:.5g}"
          f" Hz), {p['contact_law']} contact law")
    _print_sensors(s["sensors"])
    return 0


def _encoder_text(cpr: int | None, noise: float) -> str:
    text = f"{cpr} counts/rev" if cpr else "ideal"
    return text + (f", noise {noise:.3g} rad" if noise else "")


def _print_sensors(s: dict[str, Any]) -> None:
    load = _encoder_text(s["load_encoder_cpr"], s["load_noise"]) if s["load_encoder"] else "none"
    print(f"  encoders               motor {_encoder_text(s['motor_encoder_cpr'], s['motor_noise'])}; load {load}")


def _cmd_stiffness(args: argparse.Namespace) -> int:
    from ..stiffness import COMPONENTS, mesh_stiffness, mesh_stiffness_at, stiffness_note, tooth_deflections

    model = load_model(args.model)
    n = model.n_stages
    if not 1 <= args.stage <= n:
        raise InputError(f"--stage {args.stage} is out of range: {model.name} has {n} stage(s), expected 1 <= value <= "
                         f"{n}", field="stage")
    pair = model.stages[args.stage - 1].pair
    ms = mesh_stiffness(pair, points=args.points)
    note = stiffness_note(pair, ms.mean)
    if note:
        given = model.stages[args.stage - 1].dynamics.mesh_stiffness
        warn("stiffness", [("" if n == 1 else f"stage {args.stage}: ") + note
                           + (f" (the plant uses the file's {given:.4g} N/m)" if given is not None else "")])
    td = tooth_deflections(pair, points=args.points)
    if args.csv:
        K = mesh_stiffness_at(pair, td.theta1)
        header = ["theta1", "K"] + [f"{c}_{j}" for j in (1, 2) for c in (*COMPONENTS, "total")]
        header += ["k1", "k2", "k_pair"]
        cols = [td.theta1, K] + [d[c] for d in (td.gear1, td.gear2) for c in (*COMPONENTS, "total")]
        cols += [td.stiffness1, td.stiffness2, td.pair_stiffness]
        write_csv_stream(args.csv, header, lambda i0, i1: [c[i0:i1] for c in cols], td.theta1.size)
    if args.plot:
        from ..plots import plot_stiffness

        title = model.name if n == 1 else f"{model.name}, stage {args.stage}"
        save_figure(plot_stiffness(td, ms, title=title), args.plot)
    where = "" if n == 1 else f" stage {args.stage}"
    # the figures come from a quadrature over each smooth segment of the cycle, not from the --points samples
    print(f"{model.name}{where}: mesh stiffness over one mesh cycle: mean {ms.mean:.5g} N/m, C1 {ms.c1:.4g}, "
          f"C2 {ms.c2:.4g}, min {ms.min:.4g}, max {ms.max:.4g} N/m (the curves sampled at {args.points} points)")
    say_written((args.csv, "theta1 over the path of contact C->D, deflections per unit load [m/N]"),
                (args.plot, "report Figures 8-11"))
    return 0


def _simulate_summary(model: Any, plant: Any, args: argparse.Namespace, res: Any) -> dict[str, Any]:
    """The ``simulate --json`` object, from the result's arrays and counters (no per-sample objects)."""
    n, w = plant.n_stages, plant.nx // 2
    log = res.event_log
    imp = log[(log["kind"] == 1) | (log["kind"] == 5)]
    E0, E1 = (float(v) for v in plant.energy(res.x[:, [0, -1]]))
    fastest = float(np.max(res.counts["max_impact_velocity"])) if n else 0.0
    out: dict[str, Any] = {
        "model": model.name, "plant": plant.kind.value, "case": args.case, "duration": float(res.t[-1]),
        "solver": res.solver, "rows": int(res.t.size), "output_interval": float(res.t[1] - res.t[0]),
        "max_impact_velocity": fastest, "max_penetration": res.max_penetration,
        "separated_past_flank": separated_past_flank(plant, res.s, res.mode),
        "events_dropped": res.events_dropped, "energy": {"initial": E0, "final": E1},
        "mesh_stiffness": plant.k if n == 1 else [s.k for s in plant.stages],
        # the Yang-Sun plant has no viscous mesh damping (its damping is the restitution law, eqs 36-37): its c,
        # carried but unused, read as if it damped the run
        "damping_coefficient": (None if plant.kind.value == "yang-sun" else
                                plant.c if n == 1 else [s.c for s in plant.stages]),
    }
    if n == 1:
        out["impacts"] = res.impact_counts()
        out["impact_times"] = imp["t"].tolist()
        out["final"] = dict(zip(("theta1", "theta2", "omega1", "omega2"), res.x[:, -1].tolist(), strict=True))
        out["final_mode"] = res.mode_labels()[-1]
        out["backlash"] = plant.backlash
        out["lost_motion"] = plant.lost_motion  # as a train's (a pair's had none)
    else:
        out["impacts"] = res.stage_impacts()
        out["impact_times"] = [imp["t"][imp["where"] == i].tolist() for i in range(n)]
        out["final"] = {"theta": res.x[:w, -1].tolist(), "omega": res.x[w:, -1].tolist()}
        labels = {-1: "back", 0: "separation", 1: "front"}
        out["final_mode"] = [labels[int(m)] for m in res.mode[:, -1]]
        out["backlash"] = list(plant.backlashes)
        out["lost_motion"] = plant.lost_motion
    return out


def _write_simulation_csv(path: str, plant: Any, res: Any) -> None:
    n, w = plant.n_stages, plant.nx // 2
    labels = np.array(["back", "separation", "front"])
    if n == 1:
        header = ["t", "theta1", "theta2", "omega1", "omega2", "s", "mode", "force"]

        def cols(i0: int, i1: int) -> list[Any]:
            return [res.t[i0:i1], *res.x[:, i0:i1], res.s[i0:i1], labels[res.mode[i0:i1] + 1].tolist(),
                    res.force[i0:i1]]
    else:
        header = (["t"] + [f"theta{j}" for j in range(w)] + [f"omega{j}" for j in range(w)] + [f"s{i + 1}" for i in
                  range(n)] + [f"mode{i + 1}" for i in range(n)] + [f"force{i + 1}" for i in range(n)])

        def cols(i0: int, i1: int) -> list[Any]:
            return [res.t[i0:i1], *res.x[:, i0:i1], *res.s[:, i0:i1],
                    *[labels[res.mode[i, i0:i1] + 1].tolist() for i in range(n)], *res.force[:, i0:i1]]
    write_csv_stream(path, header, cols, res.t.size)


#: Penetration of the teeth (|s| - b) beyond which ``simulate`` warns, in modules (the smallest stage's).
PENETRATION_WARNING = 0.05


def _cmd_simulate(args: argparse.Namespace) -> int:
    from ..plant import build_plant
    from ..simulate import default_output_interval, output_steps, report_case

    model = load_model(args.model)
    plant = build_plant(model, args.plant)
    dt = args.dt if args.dt is not None else default_output_interval(args.duration)
    rows = output_steps(args.duration, dt, field="--dt") + 1
    check_output_size(rows, 3 * plant.nx + 3 * plant.n_stages + 4, field="--dt", fix="a larger --dt")
    # a rough figure for the progress bar: ~2 us per output row, 2 us per 10 us of simulated time
    expected = rows * 2e-6 + args.duration * 0.2
    with progress_bar("gearctl simulate", expected_s=expected) as bar:
        try:
            res = report_case(plant, args.case, args.duration, omega1=args.omega1, omega2=args.omega2,
                              torque1=args.torque1, torque2=args.torque2, dt=dt, progress=bar if bar.bar else None)
        except SimulationError as exc:
            if "diverged" not in str(exc):
                raise
            from ..simulate import CASES

            c = {**CASES[args.case], **{k: v for k in CASES[args.case] if (v := getattr(args, k, None)) is not None}}
            j = plant.shafts[0].J, plant.shafts[-1].J
            raise SimulationError(f"{exc}: the {args.case} case starts the motor at omega1 = {c['omega1']:g} rad/s "
                                  f"with torque1 = {c['torque1']:g}, torque2 = {c['torque2']:g} N m on shafts of "
                                  f"{j[0]:.3g} and {j[1]:.3g} kg m^2; for this model choose smaller --omega1, "
                                  "--torque1, --torque2", result=exc.result) from None
    from ..simulate import CASES

    tq = {k: v if (v := getattr(args, k, None)) is not None else CASES[args.case][k] for k in ("torque1", "torque2")}
    summary = _simulate_summary(model, plant, args, res)
    # the torques the run applied: the case's, and on the load the model's load_torque too (simulate adds it)
    summary["torque"] = {"motor": tq["torque1"], "load": tq["torque2"] + plant.load_torque}
    limit = plant.torque_limit
    # what the motor would have to hold on the load is the whole load torque: the case's and the model's
    on_load = summary["torque"]["load"]
    if math.isfinite(limit) and (abs(tq["torque1"]) > limit or abs(on_load) > plant.gear_ratio * limit):
        with_model = ("" if plant.load_torque == 0.0 else
                      f", {on_load:g} N m with the model's load_torque {plant.load_torque:g}")
        warn("simulate", [f"the {args.case} case's torques ({tq['torque1']:g} N m on the motor, {tq['torque2']:g} N m "
                          f"on the load{with_model}) exceed what this servo's motor gives ([servo] torque_limit = "
                          f"{limit:g} N m, "
                          f"{plant.gear_ratio * limit:.3g} N m at the load): the run is the report's open-loop "
                          "experiment, not the servo's; choose --torque1, --torque2 to match"])
    warn("simulate", yang_sun_notes(model, args.plant), kind="note")
    module = min(sm.pair.module for sm in model.stages)
    if res.max_penetration > PENETRATION_WARNING * module:  # a tooth deflects a few um at its rated load
        warn("simulate", [f"the teeth interpenetrate by up to {res.max_penetration * 1e6:.4g} um, "
                          f"{res.max_penetration / module:.0%} of the module: far beyond a tooth's elastic deflection, "
                          "so the contact law is extrapolated; choose a smaller --omega1, --torque1, --torque2"])
    if args.csv:
        _write_simulation_csv(args.csv, plant, res)
    if args.plot:
        from ..plots import plot_simulation

        save_figure(plot_simulation({plant.kind.value: res}, title=f"{model.name}, {args.case} case"), args.plot)
    if args.json:
        print(dump_json(summary))
        return 0
    f = summary["final"]
    print(f"{model.name} ({plant.kind.value} plant, {args.case} case, {_duration_text(summary['duration'])}, "
          f"{res.solver} solver, {summary['rows']} rows every {summary['output_interval']:.3g} s)")
    if plant.load_torque != 0.0:  # the case's torques are not the whole story: say what acted on the load
        print(f"  torques                motor {tq['torque1']:g} N m; load {summary['torque']['load']:g} N m (the "
              f"{args.case} case's {tq['torque2']:g} plus the model's load_torque {plant.load_torque:g})")
    if plant.n_stages == 1:
        counts = summary["impacts"]
        print(f"  impacts                front {counts['front']}, back {counts['back']}, fastest "
              f"{summary['max_impact_velocity']:.4g} m/s")
        print(f"  max penetration        {res.max_penetration * 1e6:.4g} um (|s| - b)")
        print(f"  final                  theta1 {f['theta1']:.6g} rad, theta2 {f['theta2']:.6g} rad, "
              f"omega1 {f['omega1']:.6g} rad/s, omega2 {f['omega2']:.6g} rad/s, {summary['final_mode']}")
    else:
        for i, c in enumerate(summary["impacts"], start=1):
            print(f"  stage {i} impacts        front {c['front']}, back {c['back']}, "
                  f"final {summary['final_mode'][i - 1]}")
        print(f"  fastest impact         {summary['max_impact_velocity']:.4g} m/s; max penetration "
              f"{res.max_penetration * 1e6:.4g} um (|s| - b)")
        print("  final                  theta " + ", ".join(f"{v:.6g}" for v in f["theta"]) + " rad; omega "
              + ", ".join(f"{v:.6g}" for v in f["omega"]) + " rad/s")
    print(f"  energy                 {summary['energy']['initial']:.6g} J -> {summary['energy']['final']:.6g} J")
    say_written((args.csv, "CSV"), (args.plot, "plot"))
    return 0


def _cmd_linearize(args: argparse.Namespace) -> int:
    from ..modes import linearize_modes
    from ..plant import build_plant

    model = load_model(args.model)
    modes = linearize_modes(build_plant(model))
    n = modes.plant.n_stages
    if args.mode.startswith("stage") and n == 1:  # name the model the user gave
        raise InputError(f"mode = {args.mode!r}: 'stageK' (stage K separated, the others in contact) needs a "
                         f"train; {args.model} is a pair: its modes are contact, separation and rigid", field="mode")
    sys_ = modes.mode(args.mode)
    if modes.plant.has_coulomb:  # the models carry the viscous friction only: say what they leave out
        tc = ", ".join(f"{sh.tc:g}" for sh in modes.plant.shafts)
        warn("linearize", [f"the linear models leave out the Coulomb friction ({tc} N m on the shafts, motor first; "
                           "viscous friction only): below the break-away torque the real plant does not move, and "
                           "margins read off these models do not see the friction"], kind="note")
    mesh = modes.mesh
    contact = args.mode == "contact"
    out = {
        "model": model.name,
        "mode": args.mode,
        "states": list(sys_.state_labels),
        "inputs": list(sys_.input_labels),
        "outputs": list(sys_.output_labels),
        "A": sys_.A.tolist(), "B": sys_.B.tolist(), "C": sys_.C.tolist(), "D": sys_.D.tolist(),
        "poles": [[float(p.real), float(p.imag)] for p in _poles(modes, args.mode)],
        "natural_frequency_hz": mesh.natural_frequency_hz if contact else None,
        "damping_ratio": mesh.damping_ratio if contact else None,
        "overdamped": mesh.overdamped if contact else None,
        "antiresonance_hz": mesh.antiresonance_hz if contact else None,
        "resonances_hz": list(modes.resonances_hz),
        "lost_motion": modes.lost_motion,
        "equivalent_stiffness": modes.equivalent_stiffness,
        "motor_angle_tf": {"num": np.asarray(modes.motor_angle.num[0][0]).tolist(),
                           "den": np.asarray(modes.motor_angle.den[0][0]).tolist()},
        "load_angle_tf": {"num": np.asarray(modes.load_angle.num[0][0]).tolist(),
                          "den": np.asarray(modes.load_angle.den[0][0]).tolist()},
    }
    if args.bode or args.step:
        from ..plots import plot_bode, plot_step

        both = {"contact": modes.contact, "separation": modes.separation, "rigid": modes.rigid}
        motor = list(modes.contact.output_labels)[0]
        if args.bode:
            save_figure(plot_bode(both, output=motor, input=list(modes.contact.input_labels)[0],
                                  title=f"{model.name}: motor torque to motor angle"), args.bode)
        if args.step:
            # eight periods of the lowest resonance (a train's, far below its mesh mode; an overdamped mesh has
            # none: its undamped frequency), at least 20 points per period of the highest mode, at most 20 000
            f_lo = min(modes.resonances_hz, default=mesh.natural_frequency_hz)
            T = np.linspace(0, 8 / max(f_lo, 1.0),
                            min(max(2000, math.ceil(160 * mesh.natural_frequency_hz / max(f_lo, 1.0)) + 1), 20000))
            s_out = "s" if n == 1 else "s1"
            save_figure(plot_step({"contact": modes.contact}, output=s_out, input=list(modes.contact.input_labels)[0],
                                  T=T, title=f"{model.name}: motor torque step, relative displacement"), args.step)
    if args.json:
        print(dump_json(out))
        return 0
    print(f"{model.name}: {args.mode} model, states {', '.join(out['states'])}; inputs {', '.join(out['inputs'])}; "
          f"outputs {', '.join(out['outputs'])}")
    print("  poles                  " + ", ".join(f"{p.real:.5g}{p.imag:+.5g}j" for p in _poles(modes, args.mode)))
    if contact:
        over = " (overdamped: real poles, no ringing)" if mesh.overdamped else ""
        print(f"  mesh mode              {mesh.natural_frequency_hz:.5g} Hz, damping ratio "
              f"{mesh.damping_ratio:.4g}{over}; anti-resonance {mesh.antiresonance_hz:.5g} Hz "
              f"(motor torque -> motor angle)")
        if n > 1:
            print("  resonances             " + ", ".join(f"{f:.5g}" for f in modes.resonances_hz) + " Hz")
    p = modes.plant
    J_eq = float(1.0 / modes.rigid.B[1, 0])
    print(f"  rigid train            J_eq {J_eq:.5g} kg m^2 on the motor, gear ratio {p.gear_ratio:.4g}")
    if n > 1:
        print(f"  lost motion            {p.lost_motion * 1e6:.4g} urad at the output; stiffness at the output "
              f"{p.equivalent_stiffness:.4g} N m/rad")
    say_written((args.bode, "Bode of contact, separation and rigid models"), (args.step, "step response"))
    return 0


def _cmd_describe(args: argparse.Namespace) -> int:
    from ..describe import describe

    d = describe(args.model, args.controller, duration=args.duration)
    warn("describe", [f"{d['controller']}: {n}" for n in d["design_notes"]], kind="note")
    if args.json:
        print(dump_json(d))
        return 0
    b = d.get("backlash")
    print(f"{d['model']}: {d['controller']} ({d['feedback']} feedback, Ts {d['sample_time'] * 1e3:g} ms), limit cycle "
          f"of the backlash loop")
    print(f"  {'':28s} {'f [Hz]':>9s} {'A/b':>8s} {'load [urad]':>12s} {'torque [N m]':>13s}  stable")
    rows = [("describing function", p) for p in d["prediction"] or []]
    rows += [("impact balance", p) for p in d.get("impact_prediction") or []]
    sim = d["simulation"]

    def fmt(v: float | None, scale: float = 1.0, spec: str = ".4g") -> str:
        return "—" if v is None else format(v * scale, spec)

    limit, beyond = d.get("torque_limit"), False
    for name, p in rows:
        a, tq = p.get("amplitude"), p.get("torque_amplitude")
        over = limit is not None and tq is not None and tq > limit  # a cycle the saturated motor cannot run
        beyond |= over
        print(f"  {name:28s} {fmt(p.get('frequency_hz')):>9s} {fmt(a / b if a and b else None):>8s} "
              f"{fmt(p.get('load_amplitude'), 1e6):>12s} {fmt(tq) + ('*' if over else ''):>13s}  {p.get('stable')}")
    if not rows:
        print("  (no limit cycle predicted)")
    a = sim.get("amplitude")
    print(f"  {'simulation':28s} {fmt(sim.get('frequency_hz')):>9s} {fmt(a / b if a and b else None):>8s} "
          f"{fmt(sim.get('load_amplitude'), 1e6):>12s} {fmt(sim.get('torque_amplitude')):>13s}  "
          f"{'limit cycle' if sim.get('limit_cycle') else 'too short' if sim.get('too_short') else 'none'} "
          f"({fmt(sim.get('impacts_per_second'))} impacts/s)")
    ratios = ", ".join(f"{k.replace('_ratio', '')} {v:.3g}" for k, v in d["agreement"].items() if v is not None)
    if ratios:
        print("  prediction / simulation    " + ratios)
    if beyond:
        print(f"  * beyond the servo's {limit:g} N m torque limit: the prediction, linear in the torque, does not "
              f"hold there")
    print("  " + d["verdict"])
    return 0


def register(sub: Any) -> dict[str, Callable[[argparse.Namespace], int]]:
    """Add the model commands to the subparsers; return name -> function.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``gearctl`` parser's subparsers.

    Returns
    -------
    dict
        Command name -> the function that runs it (given the parsed arguments, it returns the exit code).
    """
    dur = spec_arg(DURATION)
    p = sub.add_parser("models", help="list the catalog of gear models and trains")
    p.add_argument("--json", action="store_true", help="print JSON")

    p = sub.add_parser("info", help="geometry, mesh stiffness, damping and plant figures of a model")
    p.add_argument("model", help="catalog name (see `gearctl models`) or path to a TOML file")
    p.add_argument("--json", action="store_true", help="print one JSON object")

    p = sub.add_parser("stiffness", help="mesh stiffness and tooth deflections over the mesh cycle (Figs 8-11)")
    p.add_argument("model", help="catalog name or path to a TOML file")
    p.add_argument("--points", type=spec_arg(POINTS), default=401, help="sample points, 2..1e6 (default 401)")
    p.add_argument("--stage", type=spec_arg(STAGE), default=1, help="stage of a train, 1..6 (default 1)")
    p.add_argument("--csv", metavar="FILE", help="write theta1, K and the deflection components (-: stdout)")
    p.add_argument("--plot", metavar="FILE", help="write the figure (png, pdf, svg)")

    p = sub.add_parser("simulate", help="simulate the report's free-vibration or constant-load case")
    p.add_argument("model", help="catalog name or path to a TOML file")
    p.add_argument("--case", choices=("free", "load"), default="free",
                   help="free: omega1(0)=50 rad/s, no torque; load: plus xi1=1 N m, xi2=-1 N m (default free)")
    p.add_argument("--plant", choices=("improved", "yang-sun", "tvms"), default="improved",
                   help="mesh law (default improved)")
    p.add_argument("--duration", type=dur, default=0.02, help="simulated time [s] (default 0.02)")
    p.add_argument("--dt", type=positive_quantity("s"), default=None,
                   help="output interval [s] (default: 1 us up to 20 ms, then about 20 000 rows); value > 0, the "
                        "output at most 4 GB")
    p.add_argument("--omega1", type=spec_arg(OMEGA), help="initial velocity of the motor shaft [rad/s]")
    p.add_argument("--omega2", type=spec_arg(OMEGA), help="initial velocity of the load shaft [rad/s]")
    p.add_argument("--torque1", type=spec_arg(TORQUE), help="torque on the motor shaft [N m]")
    p.add_argument("--torque2", type=spec_arg(TORQUE), help="torque on the load shaft [N m]")
    p.add_argument("--csv", metavar="FILE", help="write the trajectory: t, angles, speeds, s, mode, force (-: stdout)")
    p.add_argument("--plot", metavar="FILE", help="write the figure (angles, velocities, s, force)")
    p.add_argument("--json", action="store_true", help="print one JSON object")

    p = sub.add_parser("linearize", help="linear model per contact mode (python-control), Bode and step")
    p.add_argument("model", help="catalog name or path to a TOML file")
    p.add_argument("--mode", default="contact", metavar="{contact,separation,rigid,stageK}",
                   choices=["contact", "separation", "rigid", *[f"stage{k}" for k in range(1, 7)]],
                   help="contact (every stage), separation, rigid (k -> inf), or stageK (a train's stage K "
                        "separated) (default contact)")
    p.add_argument("--json", action="store_true", help="print A, B, C, D, poles, mesh-mode figures as JSON")
    p.add_argument("--bode", metavar="FILE", help="write the Bode diagram of all modes on common axes")
    p.add_argument("--step", metavar="FILE", help="write the contact model's step response to a motor torque step: the "
                                                     "relative displacement s [m]")

    p = sub.add_parser("describe", help="describing-function limit cycle of a PID loop vs simulation (models "
                                        "with viscous friction only: Coulomb friction is refused by name)")
    p.add_argument("model", help="model (e.g. shing1993_servo)")
    p.add_argument("controller", help="a pid controller (e.g. pid_load: load-side feedback)")
    p.add_argument("--duration", type=dur, default=2.0,
                   help="simulated time [s] (default 2); 0 < value <= 100000 [s], at most 200 000 controller "
                        "samples (200 s at 1 ms)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    return {"models": _cmd_models, "info": _cmd_info, "stiffness": _cmd_stiffness, "simulate": _cmd_simulate,
            "linearize": _cmd_linearize, "describe": _cmd_describe}
