"""Trace of a gap crossing on a gear train: every stage's gap, every shaft's speed, the controller's flank.

Runs a catalog controller on a model's 1 Hz sine and prints, sample by sample around one reversal of the
reference, the load-angle error, each stage's gap ``s_i / b_i`` (+1: front flank in contact, -1: back flank),
each shaft's speed reflected to the load shaft (what a rigid train would give them all), the motor's place in the
train's whole lost motion (``q``, +1 and -1 at its ends), the flank the controller holds and whether its offset is
on its crossing ramp (the dead-zone inverse), and the motor torque. Before that, one line per reversal: the error's
extremes around it and the impacts per stage. The whole run goes to ``--out/trace.csv``.

    python examples/08_train_crossing_trace.py --out out/trace
    python examples/08_train_crossing_trace.py --crossing-time 0.015 --reversal 4 --out out/trace
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from gearctl import build_plant, load_model
from gearctl.catalog import load_controller
from gearctl.closedloop import simulate_closed_loop
from gearctl.design.deadzone import CROSSING_TIME
from gearctl.errors import GearctlError, InputError
from gearctl.references import reference
from gearctl.units import DURATION

BEFORE, AFTER = 0.010, 0.040  # the window around a reversal [s]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="servo_3stage_quanser_srv02", help="catalog name or TOML file")
    ap.add_argument("--controller", default="deadzone_inverse", help="catalog name or TOML file")
    ap.add_argument("--crossing-time", type=float, default=None, help="the inverse's crossing time [s]")
    ap.add_argument("--duration", type=float, default=3.0, help="simulated time [s]")
    ap.add_argument("--reversal", type=int, default=3, help="which reversal of the reference to print (1, 2, ...)")
    ap.add_argument("--out", type=Path, default=Path("out/trace"),
                    help="folder for trace.csv (default %(default)s)")
    args = ap.parse_args(argv)
    # --- the arguments, the model and the controller: checked before any work (a usage error, exit 2) ----------
    try:
        DURATION.check("--duration", args.duration)
        if args.crossing_time is not None:
            CROSSING_TIME.check("--crossing-time", args.crossing_time)
        model = load_model(args.model)
        plant = build_plant(model)
        if plant.lost_motion <= 0.0:
            raise InputError(f"--model {args.model}: no stage has backlash (backlash = 0 on every stage): there is no "
                             "crossing to trace; expected a model with a backlash > 0", field="--model")
        ctrl = load_controller(args.controller, plant, sensors=model.sensors)
        if args.crossing_time is not None:
            if not hasattr(ctrl, "set_crossing_time"):
                raise InputError(f"--crossing-time: the controller {args.controller!r} has no crossing time (a "
                                 "deadzone_inverse has)", field="--crossing-time")
            ctrl.set_crossing_time(args.crossing_time)
    except GearctlError as exc:
        ap.error(str(exc))
    ref = reference("sine")
    t = np.arange(round(args.duration / ctrl.Ts) + 1) * ctrl.Ts
    v = np.array([ref.at(ti)[1] for ti in t])
    reversals = t[1:][np.sign(v[1:]) * np.sign(v[:-1]) < 0]
    if not 1 <= args.reversal <= len(reversals):
        ap.error(f"--reversal = {args.reversal} is out of range: the {args.duration:g} s run holds "
                 f"{len(reversals)} reversals of the reference (1 to {len(reversals)})")

    # --- the run, with the controller's flank and crossing logged at each sample -----------------------------
    flank, crossing = np.full(t.size, np.nan), np.full(t.size, np.nan)
    step = ctrl.step

    def logged_step(ti: float, y_motor: float, y_load: float | None, r: object) -> float:
        u = step(ti, y_motor, y_load, r)
        k = round(ti / ctrl.Ts)
        if k < t.size and hasattr(ctrl, "held_flank"):
            flank[k], crossing[k] = ctrl.held_flank, float(ctrl.offset_moving(ti))
        return u

    ctrl.step = logged_step  # type: ignore[method-assign]
    run = simulate_closed_loop(plant, ctrl, ref, args.duration, sensors=model.sensors)
    n, w = plant.n_stages, len(plant.shafts)
    to_load = [plant.gear_ratio / math.prod(s.ratio for s in plant.stages[:j]) for j in range(w)]
    # each stage's gap over its backlash; a stage without backlash (it cannot separate) is left out
    loose = [i for i in range(n) if plant.backlashes[i] > 0.0]
    gaps = plant.gaps(run.x)[loose] / np.array([plant.backlashes[i] for i in loose]).reshape(-1, 1)
    speeds = run.x[w:] / np.array(to_load).reshape(-1, 1)  # each shaft's speed reflected to the load shaft
    q = (run.x[0] / plant.gear_ratio - run.x[n]) / (0.5 * plant.lost_motion)
    error = run.reference - run.x[n]
    m = t.size
    cols = {"t": run.t, "reference": run.reference, "error": error,
            **{f"s{i + 1}_over_b": gaps[j] for j, i in enumerate(loose)},
            **{f"omega{j}_at_load": speeds[j] for j in range(w)},
            "q": q, "flank": flank[:m], "crossing": crossing[:m], "torque": run.torque}

    # --- one line per reversal, then the samples around the chosen one ---------------------------------------
    ev = run.event_log
    print(f"{args.model}: {args.controller}, sine, {args.duration:g} s; lost motion {plant.lost_motion:.4g} rad at "
          f"the load, stages {', '.join(f'{x:.3g}' for x in plant.stage_lost_motions)} rad"
          + ("" if len(loose) == n else "; no backlash on stage "
             f"{', '.join(str(i + 1) for i in range(n) if i not in loose)} (its gap is left out)"))
    for k, tr in enumerate(reversals, 1):
        near = (run.t >= tr - BEFORE) & (run.t <= tr + AFTER)
        hits = [int(np.sum((ev["t"] >= tr - BEFORE) & (ev["t"] <= tr + AFTER) & (ev["kind"] == 1) & (ev["where"] == i)))
                for i in range(n)]
        print(f"  reversal {k} at {tr:.3f} s: error {error[near].min() * 1e6:+.0f} .. {error[near].max() * 1e6:+.0f} "
              f"urad; impacts per stage {hits}")
    tr = reversals[args.reversal - 1]
    names = ["t[ms]", "err[urad]", *(f"s{i + 1}/b" for i in loose), *(f"w{j}@load" for j in range(w)), "q",
             "flank", "cross", "u[mNm]"]
    print(" ".join(f"{h:>8s}" for h in names))
    for k in np.flatnonzero((run.t >= tr - BEFORE) & (run.t <= tr + AFTER)):
        row = [run.t[k] * 1e3, error[k] * 1e6, *gaps[:, k], *speeds[:, k], q[k], flank[k], crossing[k],
               run.torque[k] * 1e3]
        print(" ".join(f"{x:8.1f}" if j < 2 else f"{x:+8.4f}" for j, x in enumerate(row)))
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "trace.csv"
    np.savetxt(path, np.column_stack(list(cols.values())), delimiter=",", header=",".join(cols), comments="")
    print(f"trace in {path}")


if __name__ == "__main__":
    main()
