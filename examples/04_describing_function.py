"""Describing function of the backlash: predicted against simulated limit cycle of a load-side PID.

Loads the benchmark servo and the catalog's limit-cycle demonstration (a PID on the load encoder, tuned
too stiff for the gap), solves the harmonic balance 1 + N(A) H(jw) = 0 with the mesh contact law's
describing function and the sampled loop around it, plots the Nyquist curve of k H against -1/eta(A),
runs the event-located closed loop and prints prediction against simulation.

    python examples/04_describing_function.py --out out/describing_function
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import control as ct
import matplotlib.pyplot as plt
import numpy as np

from gearctl import build_plant, load_model
from gearctl.catalog import load_controller
from gearctl.describe import (
    MeshBacklash,
    dead_zone_factor,
    loop_frequency_response,
    predict_limit_cycle,
    run_limit_cycle,
    simulate_limit_cycle,
)
from gearctl.errors import InputError
from gearctl.plots import save
from gearctl.units import DURATION


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/describing_function"),
                    help="folder for the Nyquist and limit-cycle PNGs (default %(default)s)")
    ap.add_argument("--duration", type=float, default=2.0, help="simulated time [s]")
    args = ap.parse_args(argv)
    try:  # the arguments are checked before any work: a bad one is a usage error (exit 2) and writes nothing
        DURATION.check("--duration", args.duration)
    except InputError as exc:
        ap.error(str(exc))

    # --- plant, controller and the element ------------------------------------------------------------
    plant = build_plant(load_model("shing1993_servo"))
    pid = load_controller("pid_load", plant)
    element = MeshBacklash(k=plant.k, b=plant.backlash, c=plant.c)
    b = plant.backlash
    print(f"mesh k = {plant.k:.4g} N/m, c = {plant.c:.4g} N s/m, b = {b * 1e6:.1f} um; "
          f"PID on the {pid.feedback} encoder at {1 / pid.Ts:g} Hz: kp {pid.gains.kp:g}, ki {pid.gains.ki:g}, "
          f"kd {pid.gains.kd:g}")

    # --- harmonic balance: describing function and impact balance -----------------------------------------
    df = predict_limit_cycle(plant, pid)
    imp = predict_limit_cycle(plant, pid, method="impact")
    for c in df:
        N = element.describing_function_at(c["amplitude"], 2 * math.pi * c["frequency_hz"])
        print(f"DF solution: {c['frequency_hz']:.1f} Hz, A = {c['amplitude'] / b:.4f} b, "
              f"{'stable' if c['stable'] else 'unstable'}, c w / k = {c['damping_ratio']:.2g}, "
              f"N / k = {N / plant.k:.3g}")

    # --- Nyquist of k H with -1/eta(A) (python-control's describing-function plot) ------------------------
    # H is ~1e-7 m/N: scaled by k (and the element by 1/k) so python-control's intersection test works
    w = 2 * math.pi * np.geomspace(60.0, 0.98 / (2 * pid.Ts), 800)
    kH = ct.frd(plant.k * loop_frequency_response(plant, pid, w, mesh_damping=True), w, smooth=True)
    A = b * (1 + np.geomspace(1e-3, 3.0, 200))
    resp = ct.describing_function_response(kH, MeshBacklash(k=1.0, b=b), A, omega=w, refine=False)
    # max_curve_magnitude: draw |k H| up to 1e5 unscaled (python-control compresses beyond it)
    cplt = ct.describing_function_plot(resp, point_label=None, max_curve_magnitude=1e5,
                                       title="k H(jw), 60 Hz to Nyquist, and -1/eta(A)")
    ax = cplt.axes[0, 0]
    for a_mark in (1.01, 1.02, 1.05, 1.2):
        ax.plot(-1 / dead_zone_factor(a_mark * b, b), 0.0, "k|", ms=12)
        ax.annotate(f"A = {a_mark:g} b", (-1 / dead_zone_factor(a_mark * b, b), 0.0), textcoords="offset points",
                    xytext=(0, 10), ha="center", fontsize=8)
    for c in df:
        ax.plot(-1 / c["eta"], 0.0, "ro")
    if df:  # zoom on the crossing
        ax.set_xlim(-1.3 / df[0]["eta"], 0.1 / df[0]["eta"])
        ax.set_ylim(-0.1 / df[0]["eta"], 0.1 / df[0]["eta"])
    save(cplt.figure, args.out / "nyquist_describing_function.png")

    # --- the simulated cycle ----------------------------------------------------------------------------
    sim = simulate_limit_cycle(plant, pid, duration=args.duration)
    run = run_limit_cycle(plant, pid, duration=args.duration)  # the same run, for the trace
    last = run.t >= run.t[-1] - 0.03
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    ax1.plot(run.t[last] * 1e3, run.s[last] / b, label="simulation")
    if df:
        t = run.t[last]
        ax1.plot(t * 1e3, df[0]["amplitude"] / b * np.sin(2 * math.pi * df[0]["frequency_hz"] * (t - t[0])), "--",
                 label=f"DF: {df[0]['frequency_hz']:.0f} Hz")
    ax1.axhline(1.0, color="k", lw=0.5)
    ax1.axhline(-1.0, color="k", lw=0.5)
    ax1.set_ylabel("s / b")
    ax1.legend(loc="upper right")
    ax2.plot(run.t[last] * 1e3, run.x[1, last] * 1e3)
    ax2.set_ylabel("theta2 [mrad]")
    ax2.set_xlabel("t [ms]")
    save(fig, args.out / "limit_cycle.png")

    # --- prediction against simulation ------------------------------------------------------------------
    print(f"{'':22s}{'f [Hz]':>10s}{'A / b':>10s}{'theta2 [urad]':>15s}{'torque [N m]':>14s}")
    rows = [("describing function", df[0] if df else None), ("impact balance", imp[0] if imp else None),
            ("simulation", sim if sim["limit_cycle"] else None)]
    for name, r in rows:
        if r is None:
            print(f"{name:22s}{'no cycle':>10s}")
            continue
        print(f"{name:22s}{r['frequency_hz']:10.1f}{r['amplitude'] / b:10.4f}{r['load_amplitude'] * 1e6:15.1f}"
              f"{r['torque_amplitude']:14.3f}")
    if sim["limit_cycle"]:
        print(f"simulation: {sim['impacts_per_second']:.0f} impacts/s")
    print(f"figures in {args.out}")


if __name__ == "__main__":
    main()
