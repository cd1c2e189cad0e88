"""Identification commands: ``excite`` (record a log of the simulated servo) and ``identify`` (backlash and
friction from a log)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from ..errors import InputError
from ..units import BACKLASH, DURATION, ENCODER_NOISE, SEED
from .common import dump_json, progress_bar, save_figure, say_written, spec_arg, warn

__all__ = ["register"]


def _cmd_excite(args: argparse.Namespace) -> int:
    from ..catalog import load_model
    from ..excite import AMPLITUDE, check_reference_duration, excitation, record_excitation, write_reference
    from ..logs import write_log

    if not args.out and not args.reference_only:
        raise InputError("nothing to write: give --out LOG.csv (the simulated servo's log) or --reference-only FILE "
                         "(the motion, to run on a real drive)", field="out")
    AMPLITUDE.check("amplitude", args.amplitude)
    model = load_model(args.model)
    if args.noise is not None:  # both encoders, or the motor's alone on a servo without a load encoder
        noise = {"motor_noise": args.noise} | ({"load_noise": args.noise} if model.sensors.load_encoder else {})
        model = load_model(args.model, **noise)
    program = excitation(args.motion, duration=args.duration, amplitude=args.amplitude)
    if args.reference_only:  # checked before anything is written or run
        check_reference_duration(args.duration)
    ex = None
    if args.out:  # run before the reference is written: a log record_excitation refuses leaves no file behind
        with progress_bar("gearctl excite", expected_s=args.duration * 0.05):
            ex = record_excitation(model, motion=args.motion, duration=args.duration, amplitude=args.amplitude,
                                   seed=args.seed, plant=args.plant, controller=args.controller,
                                   backlash=args.backlash)
    if args.reference_only:
        n = write_reference(args.reference_only, program, duration=args.duration)
        print(f"{model.name}: {args.motion} motion, {args.duration:g} s, amplitude {args.amplitude:g} rad")
        say_written((args.reference_only, f"reference, {n} samples: t, reference, velocity, acceleration"))
    if ex is None:
        return 0
    write_log(args.out, ex.log)
    run, p = ex.run, ex.plant
    modes = run.mode[run.mode != 0]
    crossings = int((modes[1:] != modes[:-1]).sum())
    print(f"{model.name}: {args.motion} motion on the {args.plant} plant under {ex.run.controller.get('name', '')}, "
          f"{args.duration:g} s, seed {args.seed}")
    print(f"  backlash               {p.backlash * 1e6:.4g} um (lost motion {p.lost_motion:.4g} rad at the load)")
    print(f"  gap crossings          {crossings} (flank changes), {run.impact_count} impacts")
    print(f"  torque                 max |u| {abs(run.torque).max():.3g} N m")
    say_written((args.out, f"log, {ex.log.n} samples: {', '.join(ex.log.columns)}"))
    return 0


def _cmd_identify(args: argparse.Namespace) -> int:
    from ..identify import identify, read_log, write_identified_model

    log = read_log(args.log, load_encoder=args.encoders != "motor")
    with progress_bar("gearctl identify", expected_s=3.0 if args.encoders == "motor" else 0.5):
        res = identify(log, args.model, encoders=args.encoders)
    warn("identify", res.warnings)
    if args.json:
        print(dump_json(res.as_dict()))
    else:
        _print_identification(res)
    # the results are shown before the files are written: a model refused (b not identified) loses nothing shown
    if args.plot:
        from ..plots import plot_identification

        save_figure(plot_identification(res), args.plot)
    if args.write_model:
        write_identified_model(args.write_model, res, args.model)
    if not args.json:
        say_written((args.write_model, "identified model"), (args.plot, "measured vs re-simulated motion"))
    return 0


def _print_identification(res: Any) -> None:
    b, (lo, hi) = res.backlash, res.backlash_ci
    f, J = res.friction, res.inertia
    nom = res.nominal
    enc = f"{res.encoders} encoder{'s' if '+' in res.encoders else ''}"
    print(f"{res.log}: {enc}, {res.samples} samples at {res.sample_time * 1e3:.4g} ms, "
          f"{res.switches} gap crossings; model {res.model}")
    print(f"  backlash b             {b * 1e6:.4g} um along the line of action (95 % CI {lo * 1e6:.4g} - "
          f"{hi * 1e6:.4g} um; model {nom['backlash'] * 1e6:.4g} um)")
    print(f"  lost motion            {res.lost_motion:.5g} rad at the load (95 % CI {res.lost_motion_ci[0]:.5g} - "
          f"{res.lost_motion_ci[1]:.5g})")
    print(f"  viscous friction       {f['viscous1']:.3g} (motor), {f['viscous2']:.3g} (load) N m s/rad; model "
          f"{nom['viscous1']:.3g}, {nom['viscous2']:.3g}")
    print(f"  Coulomb friction       {f['coulomb1']:.3g} (motor), {f['coulomb2']:.3g} (load) N m; model "
          f"{nom['coulomb1']:.3g}, {nom['coulomb2']:.3g}")
    print(f"  inertia                J1 {J['J1']:.4g}, J2 {J['J2']:.4g} kg m^2; model {nom['J1']:.4g}, {nom['J2']:.4g}")
    print(f"  rms residual           {res.rms_residual:.3g} rad (load angle) around {len(res.windows)} re-simulated "
          f"crossings")
    print(f"  method                 {res.method}")
    if res.not_identified:
        print(f"  not identified         {', '.join(res.not_identified)} (wide intervals; see the warning)")


def register(sub: Any) -> dict[str, Callable[[argparse.Namespace], int]]:
    """Add the identification commands to the subparsers; return name -> function.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``gearctl`` parser's subparsers.

    Returns
    -------
    dict
        Command name -> the function that runs it (given the parsed arguments, it returns the exit code).
    """
    p = sub.add_parser("excite", help="record a log of the simulated servo under a motion that shows backlash and "
                                      "friction (or write that motion for a real drive)")
    p.add_argument("model", help="the true model: catalog name or TOML path (its [sensors] quantise the angles)")
    p.add_argument("--duration", type=spec_arg(DURATION), default=10.0, help="length of the log [s] (default 10)")
    p.add_argument("--out", metavar="LOG.csv",
                   help="write the log: t, torque, theta1, theta2 (with a load encoder), reference")
    p.add_argument("--reference-only", metavar="FILE", help="write only the motion (t, reference, velocity, "
                                                            "acceleration), to run on a real drive")
    p.add_argument("--motion", choices=("identify", "moves"), default="identify",
                   help="identify: reversals at several accelerations, dwells, moves at two speeds; moves: plain "
                        "back-and-forth moves (default identify)")
    p.add_argument("--amplitude", type=float, default=0.1,
                   help="largest excursion of the load [rad] (default 0.1); 0 < value <= 10 [rad]")
    p.add_argument("--plant", choices=("improved", "yang-sun", "tvms"), default="improved",
                   help="true plant (default improved)")
    p.add_argument("--controller", default="pid", help="the position loop: catalog name or TOML path (default pid)")
    p.add_argument("--backlash", type=spec_arg(BACKLASH), help="the true backlash [m] (default: the model's)")
    p.add_argument("--noise", type=spec_arg(ENCODER_NOISE),
                   help="encoder noise (std) on both encoders (the motor's alone without a load encoder) [rad] "
                        "(default: the model's [sensors])")
    p.add_argument("--seed", type=spec_arg(SEED), default=0, help="encoder-noise seed (default 0)")

    p = sub.add_parser("identify", help="backlash, friction and inertias of a gear pair from a servo log")
    p.add_argument("log", help="CSV log: t, torque, theta1[, theta2] (other columns ignored)")
    p.add_argument("--model", required=True, help="what the drawings say: catalog name or TOML path of the pair")
    p.add_argument("--encoders", choices=("motor+load", "motor"),
                   help="encoders to use (default: motor+load when the log has theta2)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", metavar="FILE", help="write measured against re-simulated motion around the crossings")
    p.add_argument("--write-model", metavar="OUT.toml", help="write the model with the identified values")
    return {"excite": _cmd_excite, "identify": _cmd_identify}
