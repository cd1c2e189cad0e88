"""The h3_sim logs the tests read: ``python make_logs.py OUTDIR [CASE ...]`` (numpy only, no gearctl).

``sim.py`` is h3's servo-rig simulator (Hertz-like mesh with damping only in contact, Stribeck friction with
stiction on both shafts, symplectic Euler at a few microseconds, its own PD loop on the quantised motor encoder,
the logger's own sample clock). The cases are gearctl's ``shing1993_servo_friction`` pair (base radii, inertias,
mesh stiffness) with the plant's own friction and inertias.
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
import sim  # noqa: E402

A = dict(rb1=0.0187939, rb2=0.0751754, J1=2.196e-4, J2=1.0019e-2, k=1.3854e8, c=798.6, d1=1e-4, d2=2e-3,
         Tc1=0.002, Tc2=0.2, umax=1.0, cpr1=2**20, cpr2=2**20, noise1=2e-6, noise2=2e-6, Kp=2.5, Kd=0.08, dt_in=4e-6)

CASES = {
    # a slow smooth triangle under a PD loop, 800 Hz, the load 20 % heavier than the model's, no motor Coulomb
    # friction: the motor crosses the gap at a steady acceleration (J1 theta1'' and tc1 sgn alike)
    "pd_tri_800hz_tc1_0": dict(A, b=50e-6, fs=800, J2=1.2e-2, Tc2=0.25, d2=3e-3, Tc1=0.0, amp=0.05, period=2.0,
                               dwell=0.3, duration=4.5),
    # the same with 2 mN m of motor Coulomb friction (h3's A8): with Stribeck friction on the load the regression put
    # 3.8 mN m on the motor, J1 at 0.14 of the truth, J2 26 % high; the re-simulated motor stalls mid-gap
    "A8_offnominal_b50_800hz": dict(A, b=50e-6, fs=800, J2=1.2e-2, Tc2=0.25, d2=3e-3, amp=0.05, period=2.0,
                                    dwell=0.3, duration=6),
}


def make(name: str, out: Path) -> Path:
    p = dict(CASES[name])
    tri = sim.smooth_triangle(p["amp"], p["period"], p["dwell"])
    p["ref"] = lambda t: tri(t + p["period"] / 4)  # starts at r = 0
    p["th2_0"] = -p["b"] / p["rb2"]  # resting on the front flank
    rows = sim.simulate(p, seed=sum(map(ord, name)))
    path = out / f"{name}.csv"
    with open(path, "w") as f:
        f.write(f"# h3_sim {name}: true b {p['b']:g} m, J1 {p['J1']:g}, J2 {p['J2']:g} kg m^2, Coulomb {p['Tc1']:g}, "
                f"{p['Tc2']:g} N m\n")
        f.write("t,torque,theta1,theta2\n")
        for t, u, m1, m2 in rows[:, :4]:
            f.write(f"{t:.9f},{u:.9g},{m1:.10g},{m2:.10g}\n")
    return path


if __name__ == "__main__":
    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    for name in sys.argv[2:] or list(CASES):
        print(make(name, out))
