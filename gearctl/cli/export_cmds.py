"""Embedded export: ``export`` (a catalog controller as self-contained C99, with its Makefile and test vectors)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from ..units import BACKLASH, SEED
from .common import dump_json, progress_bar, spec_arg, unused_estimate, warn

__all__ = ["register"]


def _cmd_export(args: argparse.Namespace) -> int:
    from ..catalog import load_controller, load_model
    from ..export import export_controller
    from ..plant import build_plant

    model = load_model(args.model)
    plant = build_plant(model, backlash=args.backlash)
    with progress_bar("gearctl export: design", expected_s=None) as bar:
        ctrl = load_controller(args.controller, plant, backlash=args.estimate, sensors=model.sensors, progress=bar)
    info = export_controller(ctrl, args.out, plant=plant, sensors=model.sensors, vectors=not args.no_vectors,
                             seed=args.seed, model=model.name, prefix=args.prefix)
    summary = {"model": model.name, "controller": ctrl.name, "kind": info.kind, "out": str(info.path),
               "files": info.files, "table_bytes": info.table_bytes, "vector_steps": info.vector_steps,
               "Ts": ctrl.Ts, "preview": ctrl.preview, "uses_load_encoder": ctrl.uses_load_encoder,
               "prefix": info.prefix, "warnings": list(info.warnings),
               "design_notes": list(ctrl.describe().get("design_notes", ()))}
    warn("export", [f"{ctrl.name}: {n}" for n in summary["design_notes"]], kind="note")
    warn("export", unused_estimate(info.kind, args.estimate), kind="note")
    warn("export", info.warnings)
    if args.json:
        print(dump_json(summary))
        return 0
    p, P = info.prefix, info.prefix.upper()
    print(f"{model.name}: {ctrl.name} ({info.kind}) exported as C99 to {info.path}/")
    print(f"  API              {p}_ctrl.h: {P}_TS {ctrl.Ts:g} s, {P}_PREVIEW {ctrl.preview}, load encoder "
          f"{'used' if ctrl.uses_load_encoder else 'unused (pass NAN)'}; {p}_ctrl_step, see README.md")
    print(f"  parameters       {info.table_bytes / 1024:.4g} kB of static const data")
    if info.vector_steps:
        print(f"  test vectors     {info.vector_steps} steps recorded from the Python controller (3 s sine, move)")
        print(f"  next             make -C {info.path} && make -C {info.path} check   (lib{p}_ctrl.a; link with -lm)")
    else:
        print(f"  next             make -C {info.path}   (lib{p}_ctrl.a; link with -lm; no vectors for make check)")
    return 0


def register(sub: Any) -> dict[str, Callable[[argparse.Namespace], int]]:
    """Add the export command to the subparsers; return name -> function.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``gearctl`` parser's subparsers.

    Returns
    -------
    dict
        Command name -> the function that runs it (given the parsed arguments, it returns the exit code).
    """
    bl, seed = spec_arg(BACKLASH), spec_arg(SEED)
    p = sub.add_parser("export", help="export a catalog controller as self-contained C99 (header, sources, Makefile, "
                                      "test vectors)")
    p.add_argument("model", help="model the controller is designed on (catalog name or TOML path)")
    p.add_argument("controller", help="controller: catalog name (pid, deadzone_inverse, mpc, ...) or TOML path")
    p.add_argument("--out", required=True, metavar="DIR", help="folder to write (created)")
    p.add_argument("--backlash", type=bl, help="override the model's backlash [m] (the design plant's)")
    p.add_argument("--estimate", type=bl, help="the controller's backlash estimate [m] (default: the model's)")
    p.add_argument("--seed", type=seed, default=0, help="sensor-noise seed of the recorded vectors (default 0)")
    p.add_argument("--no-vectors", action="store_true", help="skip recording the test vectors (make check then "
                                                              "says there is nothing to replay)")
    p.add_argument("--prefix", default="gearctl", metavar="NAME",
                   help="prefix of the exported names and files (default gearctl: gearctl_ctrl_step, GEARCTL_TS, "
                        "gearctl_ctrl.h); another, e.g. axis1, lets several exports link into one program")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    return {"export": _cmd_export}
