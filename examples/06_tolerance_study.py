"""Tolerance study: where does backlash compensation stop paying as the gear wears and the estimate drifts?

The PID, the dead-zone inverse and the MPC of the catalog are designed once on the nominal
shing1993_servo and run on plants whose backlash goes from 0.5x (a tight new pair) to 3x nominal (worn).
The two compensators also meet an estimate that is off by -50 % .. +50 % of each plant's true backlash.
Their RMS error over the PID's at the same backlash tells where each stops being worth it (ratio 1).

    python examples/06_tolerance_study.py --out docs/tolerance
    python examples/06_tolerance_study.py --scheduler tcp://HOST:8786   # on a running Dask cluster
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from gearctl.errors import InputError
from gearctl.parallel import Engine, check_local_workers
from gearctl.plots import plot_sweep_compare, save
from gearctl.sweep import GRID_POINTS, compare_grids, sweep
from gearctl.units import DURATION, Spec

MODEL = "shing1993_servo"
WORKERS = Spec(unit="1", doc="local worker processes", low=1, high=1024, integer=True)


def _verdict(x: np.ndarray, ratio: np.ndarray) -> str:
    """Where along the backlash (x nominal) the compensator does no better than the baseline."""
    worse = ~(ratio < 1.0)  # a failed run (nan) does not pay either
    if not worse.any():
        return "pays everywhere"
    if worse.all():
        return "never pays"
    return "loses at " + ", ".join(f"{v:.2g}x" for v in x[worse])


def _advance(bar: tqdm, done: int, total: int) -> None:
    bar.total = total
    bar.update(done - bar.n)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("docs/tolerance"),
                    help="folder for tolerance.png and report.md (default %(default)s)")
    ap.add_argument("--points", type=int, default=6, help="backlash points from 0.5x to 3x nominal (default 6)")
    ap.add_argument("--errors", default="-0.5,-0.25,0,0.25,0.5",
                    help="relative errors of the backlash estimate (default -0.5,-0.25,0,0.25,0.5)")
    ap.add_argument("--duration", type=float, default=None, help="simulated time per run [s] (default: the sine's)")
    ap.add_argument("--workers", type=int, default=None, help="local worker processes (default: all cores)")
    ap.add_argument("--scheduler", default=None, help="a running Dask scheduler (default: a local cluster)")
    args = ap.parse_args(argv)
    try:  # the arguments are checked before any work: a bad one is a usage error (exit 2) and writes nothing
        if args.duration is not None:
            DURATION.check("--duration", args.duration)
        GRID_POINTS.check("--points", args.points)
        if args.workers is not None:
            WORKERS.check("--workers", args.workers)
            check_local_workers(args.workers)  # a thousand processes would not fit in memory
    except InputError as exc:
        ap.error(str(exc))

    # --- one Dask client for the three sweeps (gearctl's local cluster, or the one at --scheduler) ----------
    # (gearctl's: workers' logs quiet, Ctrl-C handled; a scheduler probed first, one line if it does not answer)
    try:
        engine = Engine(workers=args.workers, scheduler=args.scheduler)
    except InputError as exc:
        ap.error(str(exc))
    with engine:
        # --- the sweeps: the PID over backlash, the compensators over backlash x estimate error ---------------
        wear = "backlash=0.5x:3x"
        common = {"grid": True, "runs": args.points, "duration": args.duration, "client": engine.client}
        results = {}
        for name in ("pid", "deadzone_inverse", "mpc"):
            vary = [wear] if name == "pid" else [wear, f"estimate_error={args.errors}"]
            runs = args.points * (1 if name == "pid" else len(args.errors.split(",")))
            # a progress bar on a terminal, none in a pipe (tqdm's disable=None)
            with tqdm(desc=name, total=runs, unit="run", file=sys.stderr, leave=False, disable=None) as bar:
                results[name] = sweep(MODEL, name, vary=vary, progress=lambda d, n, b=bar: _advance(b, d, n),
                                      **common)

    # --- where each stops being worth it -------------------------------------------------------------------
    cmp = compare_grids(results, baseline="pid")
    x = cmp["x"] / cmp["x_nominal"]
    lines = ["| controller | estimate error | RMS / PID's at 0.5x .. 3x nominal backlash | verdict |",
             "|---|---:|---|---|"]
    for name, d in cmp["controllers"].items():
        for j, err in enumerate(d["y"]):
            r = d["ratio"][:, j]
            lines.append(f"| {name} | {err:+.0%} | {' '.join(f'{v:.2f}' for v in r)} | {_verdict(x, r)} |")
    table = "\n".join(lines)
    print(table)

    # --- the figure and the report -------------------------------------------------------------------------
    save(plot_sweep_compare(cmp), args.out / "tolerance.png")
    runs = sum(len(r.runs) for r in results.values())
    (args.out / "report.md").write_text(
        f"# Tolerance study ({MODEL})\n\nRegenerated by `python examples/06_tolerance_study.py`: {runs} runs, "
        f"each controller designed once on the nominal model. Ratio < 1: the compensator beats the PID.\n\n"
        f"{table}\n\n![RMS error over the PID's](tolerance.png)\n")
    print(f"wrote {args.out}/tolerance.png and report.md ({runs} runs)")


if __name__ == "__main__":
    main()
