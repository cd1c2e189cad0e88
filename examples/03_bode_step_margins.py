"""Bode, step and margins of the contact-mode models: the analysis script a servo designer writes.

Loads a servo (the benchmark servo unless ``--model`` names another catalog entry or TOML file, a pair or a
train), gets its linear models per contact mode as python-control objects, plots the Bode diagram of both modes
(and the rigid limit) on common axes and a step response, and prints the margins of the catalog PID on the
contact and the separation model (the loop must survive the gap). The signals are taken by the model's own
names: a pair's ``theta1, theta2, force``, a train's ``theta0, thetan, force1``.

    python examples/03_bode_step_margins.py --out out/analysis
    python examples/03_bode_step_margins.py --model servo_3stage_quanser_srv02 --out out/analysis_srv02
"""

from __future__ import annotations

import argparse
from pathlib import Path

import control as ct
import numpy as np

from gearctl import build_plant, load_model
from gearctl.catalog import load_controller
from gearctl.errors import GearctlError
from gearctl.modes import linearize_modes, loop_margins
from gearctl.plots import plot_bode, plot_step, save


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/analysis"),
                    help="folder for the Bode and step PNGs (default %(default)s)")
    ap.add_argument("--model", default="shing1993_servo", help="catalog name or TOML file (default shing1993_servo)")
    args = ap.parse_args(argv)

    # --- model, its linear modes and the catalog PID: a bad --model is a usage error before any figure -----
    try:
        model = load_model(args.model)
        plant = build_plant(model)
        modes = linearize_modes(plant)
        pid = load_controller("pid", plant, sensors=model.sensors)
    except GearctlError as exc:
        ap.error(f"--model {args.model}: {exc}")
    motor, load = modes.contact.output_labels[:2]  # theta1, theta2 on a pair; theta0, thetan on a train
    xi = modes.contact.input_labels[0]  # the motor torque: xi1 on a pair, xi0 on a train
    force = "force" if plant.n_stages == 1 else "force1"  # the motor's mesh
    print(f"mesh mode {modes.mesh.natural_frequency_hz:.1f} Hz (zeta {modes.mesh.damping_ratio:.3f}), "
          f"anti-resonance {modes.mesh.antiresonance_hz:.1f} Hz")
    print("motor torque -> load angle in contact:", modes.load_angle)

    # --- Bode of both modes on common axes, and a step ----------------------------------------------------
    systems = {"contact": modes.contact, "separation": modes.separation, "rigid (k -> inf)": modes.rigid}
    save(plot_bode(systems, output=motor, input=xi), args.out / "bode_motor_angle.png")
    save(plot_bode({"contact": modes.contact, "rigid (k -> inf)": modes.rigid}, output=load, input=xi),
         args.out / "bode_load_angle.png")
    # eight periods of the lowest resonance (an overdamped mesh has none: its undamped frequency)
    T = np.linspace(0.0, 8.0 / min(modes.resonances_hz, default=modes.mesh.natural_frequency_hz), 3000)
    save(plot_step({"contact": modes.contact}, output=force, input=xi, T=T), args.out / "step_force.png")

    # --- margins of the catalog PID (motor feedback, scaled to load units) in each mode -------------------
    # the controller that runs (PIDGains.sampled_tf: PID.step's own difference equation), as a state-space model:
    # a TF times a many-state mode model is multiplied out into a badly conditioned high-order TF
    C = ct.ss(pid.gains.sampled_tf(pid.Ts))
    for name in ("contact", "separation"):
        G = ct.c2d(ct.ss(modes.mode(name)[0, 0]) / plant.gear_ratio, pid.Ts, "zoh")
        m = loop_margins(C * G)
        print(f"PID on the {name:10s} model: phase margin {m['phase_margin']:6.1f} deg at "
              f"{m['gain_crossover_hz']:6.2f} Hz, gain margin {m['gain_margin_db']:6.1f} dB")
    print(f"figures in {args.out}")


if __name__ == "__main__":
    main()
