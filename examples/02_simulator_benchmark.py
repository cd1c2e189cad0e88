"""Simulator speed: gearctl's exact event-located kernel against python-control's input_output_response.

Prints, for the report's free vibration and a 1 kHz sampled PD loop, simulated seconds per wall second of
both, python-control at its default and at tight tolerances (rtol 1e-10), each one's error against an
independent tight reference (solve_ivp with events), and the ratios. The same figures as `gearctl perf`.

    python examples/02_simulator_benchmark.py
"""

from __future__ import annotations

import argparse

from gearctl.perf import sim_speed


def main(argv: list[str] | None = None) -> None:
    # --- arguments: none but --help (an unknown one is refused before the minute of runs) ---------------------
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.parse_args(argv)

    # --- both scenarios, gearctl against python-control ----------------------------------------------------
    for scenario in ("free", "pd"):
        r = sim_speed(scenario)
        print(f"{scenario}: {r['model']}, outputs every {r['output_interval'] * 1e6:g} us")
        print(f"  gearctl                     {r['gearctl_sim_per_wall']:10.4g} sim-s/wall-s, "
              f"error {r['gearctl_error']:.2e} b")
        print(f"  python-control (default)    {r['python_control_sim_per_wall']:10.4g} sim-s/wall-s, "
              f"error {r['python_control_error']:.2e} b   ratio {r['ratio']:.0f}x")
        print(f"  python-control (rtol 1e-10) {r['python_control_tight_sim_per_wall']:10.4g} sim-s/wall-s, "
              f"error {r['python_control_tight_error']:.2e} b   ratio {r['ratio_equal_accuracy']:.0f}x")


if __name__ == "__main__":
    main()
