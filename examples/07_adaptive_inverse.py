"""Adaptive dead-zone inverse: the backlash estimate converging from -50 % and +50 % on both plants.

Runs the catalog's adaptive inverse (controllers/adaptive_inverse.toml) on the benchmark servo's 1 Hz sine,
started with the backlash estimate at 0.5x and 1.5x the true b, on the improved and the Yang-Sun plant,
beside the catalog dead-zone inverse told the true b. Prints the estimate after each gap crossing, the crossings it
needs to come within 5 % and the RMS error once converged, and draws the convergence plot of the README.

    python examples/07_adaptive_inverse.py --out docs/adaptive
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from gearctl import build_plant, load_model
from gearctl.catalog import load_controller
from gearctl.closedloop import simulate_closed_loop
from gearctl.errors import InputError
from gearctl.plots import save
from gearctl.references import reference
from gearctl.units import DURATION


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/adaptive"),
                    help="folder for adaptive_inverse.png (default %(default)s)")
    ap.add_argument("--duration", type=float, default=6.0, help="simulated time of each run [s]")
    args = ap.parse_args(argv)
    try:  # the arguments are checked before any work: a bad one is a usage error (exit 2) and writes nothing
        DURATION.check("--duration", args.duration)
    except InputError as exc:
        ap.error(str(exc))

    # --- the servo, the sine, the two controllers ---------------------------------------------------------
    model = load_model("shing1993_servo")
    nominal = build_plant(model)
    b = nominal.backlash
    ref = reference("sine")
    settle = min(3.0, args.duration / 2)  # RMS error from here on (converged)

    fig, axs = plt.subplots(2, 2, figsize=(11, 7), sharex=True, layout="constrained")
    for col, kind in enumerate(("improved", "yang-sun")):
        plant = build_plant(model, kind)
        # --- the inverse told the true b: the reference figure ------------------------------------------------
        # the catalog's dead-zone inverse (sin^2 crossings), which the adaptive one switches to once converged
        true_b = simulate_closed_loop(plant, load_controller("deadzone_inverse", nominal, backlash=b), ref,
                                      args.duration, sensors=model.sensors)
        rms_true = float(np.sqrt(np.mean(true_b.error[true_b.t >= settle] ** 2)))
        axs[1, col].plot(true_b.t, np.abs(true_b.error) * 1e6, color="k", lw=0.8, label="inverse, true b")
        print(f"{kind}: inverse told the true b = {b * 1e6:.4g} um: RMS error {rms_true:.4g} rad after {settle:g} s")
        # --- the adaptive inverse from -50 % and +50 % ---------------------------------------------------------
        for start, color in ((0.5, "C0"), (1.5, "C3")):
            ctrl = load_controller("adaptive_inverse", nominal, backlash=start * b)
            run = simulate_closed_loop(plant, ctrl, ref, args.duration, sensors=model.sensors)
            h = np.array(ctrl.history).reshape(-1, 3)
            t = np.concatenate(([0.0], h[:, 0], [run.t[-1]]))
            est = np.concatenate(([start * b], h[:, 2], [ctrl.backlash])) / b
            axs[0, col].step(t, est, where="post", color=color, label=f"start {start:g} b")
            axs[0, col].plot(h[:, 0], h[:, 1] / b, "x", color=color, ms=5)
            outside = np.flatnonzero(np.abs(est - 1.0) > 0.05)  # est[-1] is the final estimate, held to the end
            rms = float(np.sqrt(np.mean(run.error[run.t >= settle] ** 2)))
            axs[1, col].plot(run.t, np.abs(run.error) * 1e6, color=color, lw=0.8, label=f"adaptive from {start:g} b")
            if outside.size and outside[-1] == est.size - 1:  # still off at the end (a run too short to converge)
                when = f"not within 5 % in {run.t[-1]:.3g} s ({h.shape[0]} updates)"
            else:
                t_in = t[outside[-1] + 1] if outside.size else 0.0
                updates = int(np.sum(h[:, 0] <= t_in))
                v = ref.at(run.t[run.t <= t_in])[1]
                reversals = int(np.sum(np.sign(v[1:]) * np.sign(v[:-1]) < 0))
                when = f"within 5 % after {reversals} reversals ({updates} updates, t = {t_in:.3g} s)"
            print(f"  start {start:g} b: {when}, final {ctrl.backlash / b:.4f} b; RMS error {rms:.4g} rad = "
                  f"{rms / rms_true:.3f} x the true-b inverse's")
        axs[0, col].axhspan(0.95, 1.05, color="k", alpha=0.1)
        axs[0, col].set(ylabel="backlash estimate / true b", title=f"{kind} plant (x: measurement at a crossing)")
        axs[1, col].set(xlabel="time [s]", ylabel="|load-angle error| [urad]", yscale="log")
        for ax in axs[:, col]:
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=8)

    # --- the figure -------------------------------------------------------------------------------------------
    path = save(fig, args.out / "adaptive_inverse.png")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
