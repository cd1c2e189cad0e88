"""Bode, step and margins of the contact-mode models: the analysis script a servo designer writes.

Loads the benchmark servo, gets its linear models per contact mode as python-control objects, plots the
Bode diagram of both modes (and the rigid limit) on common axes and a step response, and prints the
margins of the catalog PID on the contact and the separation model (the loop must survive the gap).

    python examples/03_bode_step_margins.py --out out/analysis
"""

from __future__ import annotations

import argparse
from pathlib import Path

import control as ct
import numpy as np

from gearctl import build_plant, load_model
from gearctl.catalog import load_controller
from gearctl.modes import linearize_modes, loop_margins
from gearctl.plots import plot_bode, plot_step, save


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/analysis"))
    args = ap.parse_args(argv)

    # --- model and its linear modes ---------------------------------------------------------------------
    plant = build_plant(load_model("shing1993_servo"))
    modes = linearize_modes(plant)
    print(f"mesh mode {modes.mesh.natural_frequency_hz:.1f} Hz (zeta {modes.mesh.damping_ratio:.3f}), "
          f"anti-resonance {modes.mesh.antiresonance_hz:.1f} Hz")
    print("motor torque -> load angle in contact:", modes.load_angle)

    # --- Bode of both modes on common axes, and a step ----------------------------------------------------
    systems = {"contact": modes.contact, "separation": modes.separation, "rigid (k -> inf)": modes.rigid}
    save(plot_bode(systems, output="theta1"), args.out / "bode_motor_angle.png")
    save(plot_bode({"contact": modes.contact, "rigid (k -> inf)": modes.rigid}, output="theta2"),
         args.out / "bode_load_angle.png")
    T = np.linspace(0.0, 3e-3, 3000)
    save(plot_step({"contact": modes.contact}, output="force", T=T), args.out / "step_force.png")

    # --- margins of the catalog PID (motor feedback, scaled to load units) in each mode -------------------
    # the controller that runs (PIDGains.sampled_tf: PID.step's own difference equation), as a state-space model:
    # a TF times a many-state mode model is multiplied out into a badly conditioned high-order TF
    pid = load_controller("pid", plant)
    C = ct.ss(pid.gains.sampled_tf(pid.Ts))
    for name in ("contact", "separation"):
        G = ct.c2d(ct.ss(modes.mode(name)[0, 0]) / plant.gear_ratio, pid.Ts, "zoh")
        m = loop_margins(C * G)
        print(f"PID on the {name:10s} model: phase margin {m['phase_margin']:6.1f} deg at "
              f"{m['gain_crossover_hz']:6.2f} Hz, gain margin {m['gain_margin_db']:6.1f} dB")
    print(f"figures in {args.out}")


if __name__ == "__main__":
    main()
