"""Write h2's logs (``CASE.csv`` in OUTDIR) from an independent simulator: ``sim.c``, compiled here with ``cc``.

Two inertias along the line of action through a dead zone of half-width b with a linear spring-damper mesh (the
stiffness and damping of ``shing1993_servo_friction``'s pair), symplectic Euler at a 1 us micro-step, Karnopp
stick-slip or LuGre friction (with a Stribeck rise to 1.5 times the Coulomb level) on each shaft, a PD loop of its
own on the quantised motor encoder (P 13 N m/rad on the motor angle, D 0.15 N m s/rad, 1 N m limit) tracking a
load-angle reference, 2^20-count encoders with 1 urad of noise. Run from anywhere (needs ``cc``; no gearctl):

    python tests/data/logs/h2_sim/make_logs.py OUTDIR [CASE ...]

Cases (the truth in each file's comment lines):

- ``triangle_5khz``: a 0.5 Hz triangle of 0.05 rad at the load for 3 s, logged at 5 kHz, the plant of
  ``shing1993_servo_friction`` (Karnopp friction: 0.2 N m on the load, none on the motor).
- ``lugre_sine_1khz``: a 0.7 Hz sine of 0.05 rad for 5 s at 1 kHz, a plant off the model (b 40 um, J1 1.8e-4, J2 0.012
  kg m^2, LuGre friction of 1 mN m on the motor and 0.25 N m on the load, bristle stiffness 1000 N m/rad).
"""

import ctypes
import math
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
RB1, RB2 = 0.018793852415718168, 0.07517540966287267
K, C = 1.3854e8, 798.6
NOMINAL = dict(b=5e-5, J1=2.196e-4, J2=1.00185e-2, d1=1e-4, d2=2e-3, tc1=0.0, tc2=0.2)
CASES = {
    "triangle_5khz": dict(truth={}, law=0, ref="triangle", fs=5000, duration=3.0, hz=0.5),
    "lugre_sine_1khz": dict(truth=dict(J1=1.8e-4, J2=0.012, d1=5e-5, d2=4e-3, tc1=1e-3, tc2=0.25, b=4e-5), law=1,
                            ref="sine", fs=1000, duration=5.0),
}
CPR, NOISE = 2**20, 1e-6


def _lib() -> ctypes.CDLL:
    so = os.path.join(os.environ.get("TMPDIR", "/tmp"), "gearctl_h2_sim.so")
    subprocess.run(["cc", "-O2", "-shared", "-fPIC", "-o", so, os.path.join(HERE, "sim.c"), "-lm"], check=True)
    return ctypes.CDLL(so)


def simulate(lib: ctypes.CDLL, case: dict) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    truth = dict(NOMINAL, **case["truth"])
    Ts = 1.0 / case["fs"]
    n = int(round(case["duration"] / Ts)) + 1
    t = np.arange(n) * Ts
    if case["ref"] == "triangle":
        ref = 0.05 * (2 / math.pi) * np.arcsin(np.sin(2 * math.pi * case["hz"] * t))
    else:
        ref = 0.05 * np.sin(2 * math.pi * 0.7 * t)
    # rb1 rb2 k c b J1 J2 d1 d2 tc1 tc2 law sigma0 sigma1 vs ts_ratio TL nopull
    p = np.array([RB1, RB2, K, C, truth["b"], truth["J1"], truth["J2"], truth["d1"], truth["d2"], truth["tc1"],
                  truth["tc2"], case["law"], 1e3, 3.0, 1e-3, 1.5, 0.0, 0.0])
    # mode kp kd umax quantum N delay
    ctrl = np.array([1.0, 13.0, 0.15, 1.0, 2 * math.pi / CPR, RB2 / RB1, 0.0])
    U, T1, T2 = np.zeros(n), np.zeros(n), np.zeros(n)
    dp = ctypes.POINTER(ctypes.c_double)
    lib.simulate(p.ctypes.data_as(dp), ctrl.ctypes.data_as(dp), n, int(round(Ts / 1e-6)), ctypes.c_double(Ts),
                 ref.ctypes.data_as(dp), U.ctypes.data_as(dp), T1.ctypes.data_as(dp), T2.ctypes.data_as(dp))
    rng = np.random.default_rng(0)
    q = 2 * math.pi / CPR
    e1 = np.floor((T1 + 0.3 + rng.normal(0, NOISE, n)) / q) * q
    e2 = np.floor((T2 - 0.7 + rng.normal(0, NOISE, n)) / q) * q
    return truth, t, U, e1, e2


def main(argv: list[str]) -> None:
    out, names = argv[0], argv[1:] or list(CASES)
    lib = _lib()
    for name in names:
        truth, t, U, e1, e2 = simulate(lib, CASES[name])
        with open(os.path.join(out, f"{name}.csv"), "w") as fh:
            fh.write(f"# h2_sim/make_logs.py {name}: truth " + ", ".join(f"{k}={v:g}" for k, v in truth.items()) +
                     " (J total per shaft [kg m^2], b [m], friction [N m s/rad, N m])\n")
            fh.write("t,torque,theta1,theta2\n")
            np.savetxt(fh, np.column_stack([t, U, e1, e2]), fmt=["%.8g", "%.8g", "%.10g", "%.10g"], delimiter=",")


if __name__ == "__main__":
    main(sys.argv[1:])
