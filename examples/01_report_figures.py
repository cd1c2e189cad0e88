"""Reproduce the report's figures: mesh stiffness (Figs 8-11) and both simulations (Figs 12-21).

Uses the catalog entry `shing1993_report` (the report's pair with the k and c its simulations used) and
draws the improved and the Yang-Sun plant on common axes, as the report does.

    python examples/01_report_figures.py --out out/figures
"""

from __future__ import annotations

import argparse
from pathlib import Path

from gearctl import build_plant, load_model, mesh_stiffness, tooth_deflections
from gearctl.errors import InputError
from gearctl.plots import plot_simulation, plot_stiffness, save
from gearctl.simulate import report_case
from gearctl.units import DURATION


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/figures"),
                    help="folder for the PNG files (default %(default)s)")
    ap.add_argument("--duration", type=float, default=0.01, help="simulated time [s] (report: about 10 ms)")
    args = ap.parse_args(argv)
    try:  # the arguments are checked before any work: a bad one is a usage error (exit 2) and writes nothing
        DURATION.check("--duration", args.duration)
    except InputError as exc:
        ap.error(str(exc))

    # --- model: the report's pair, with the k and c of its simulations --------------------------------
    model = load_model("shing1993_report")
    plants = {"improved": build_plant(model, "improved"), "Yang-Sun": build_plant(model, "yang-sun")}

    # --- Figures 8-11: tooth deflections and mesh stiffness --------------------------------------------
    ms = mesh_stiffness(model.pair)
    fig = plot_stiffness(tooth_deflections(model.pair), ms, title="TR 93-28 Figures 8-11")
    path = save(fig, args.out / "fig08-11_stiffness.png")
    print(f"mesh stiffness: mean {ms.mean:.5g} N/m, C1 {ms.c1:.4g}, C2 {ms.c2:.4g} "
          "(Table 1: 1.3868e8, 2.956e7, 1.684e7)")
    print(f"wrote {path}")

    # --- Figures 12-16 (free vibration) and 17-21 (constant load) --------------------------------------
    for case, figs in (("free", "12-16"), ("load", "17-21")):
        runs = {name: report_case(p, case, args.duration) for name, p in plants.items()}
        path = save(plot_simulation(runs, title=f"TR 93-28 Figures {figs}: {case} case"),
                    args.out / f"fig{figs.replace('-', '-')}_{case}.png")
        for name, r in runs.items():
            c = r.impact_counts()
            print(f"{case:>4} {name:>8}: impacts front {c['front']}, back {c['back']}, "
                  f"max penetration {r.max_penetration * 1e6:.3g} um")
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
