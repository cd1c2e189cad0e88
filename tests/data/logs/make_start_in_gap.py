"""Write ``other_sim_start_in_gap.csv``: a motor-encoder log that starts with the motor leaving its flank for the
middle of the gap.

Another simulator than gearctl's (numpy-free, the math module only): the documented pair of
``shing1993_servo_friction`` (two inertias, a linear spring-damper mesh with a dead zone of half-width ``b``
along the line of action, viscous friction on both shafts, 0.2 N m of Coulomb friction on the load) integrated
by semi-implicit Euler at 10 us with the Coulomb friction implicit (a shaft sticks when one step's torque cannot
move it past the friction), under a PD loop of its own on the quantised motor encoder (2 urad of noise) at
1 kHz, the load's friction fed forward, the torque held over each sample, 1 N m limit. The motor starts at
rest on the front flank and the loop holds the motor angle at 0 for 0.5 s, so the log opens with the motor
swinging into the middle of the gap; then a 0.7 Hz sine of 0.05 rad at the load. Run from anywhere:

    python tests/data/logs/make_start_in_gap.py
"""

from __future__ import annotations

import math
import random
from pathlib import Path

RB1, RB2 = 0.018793852415718168, 0.07517540966287267  # base radii [m] of the 20 x 80 pair, module 2 mm, 20 deg
K, C = 1.3854e8, 798.6  # mesh stiffness [N/m] and damping [N s/m]
J1, J2, D1, D2, TC2, B = 2.196e-4, 1.00185e-2, 1e-4, 2e-3, 0.2, 5e-5
TS, SUB, CPR, DURATION = 1e-3, 100, 2**20, 5.0


def main() -> None:
    ratio, h, q = RB2 / RB1, TS / SUB, 2 * math.pi / CPR
    jt = J1 + J2 / ratio**2
    wc = 2 * math.pi * 20.0
    kp, kd = jt * wc**2, 1.4 * jt * wc
    th1, th2, w1, w2 = B / RB1, 0.0, 0.0, 0.0  # at rest on the front flank, no force
    prev, west = math.floor(th1 / q) * q, 0.0
    rng = random.Random(1)
    rows = ["t,torque,theta1"]
    for i in range(int(round(DURATION / TS)) + 1):
        t = i * TS
        m = math.floor((th1 + rng.gauss(0.0, 2e-6)) / q) * q
        west = 0.5 * west + 0.5 * (m - prev) / TS if i else 0.0
        prev = m
        tau = t - 0.5
        ref, vel, acc = ((0.05 * math.sin(4.4 * tau), 0.05 * 4.4 * math.cos(4.4 * tau),
                          -0.05 * 4.4**2 * math.sin(4.4 * tau)) if tau > 0 else (0.0, 0.0, 0.0))
        u = kp * (ratio * ref - m) + kd * (ratio * vel - west) + jt * ratio * acc
        u += math.copysign(TC2 / ratio, vel) if abs(vel) > 1e-6 else 0.0  # the load's friction, fed forward
        u = max(-1.0, min(1.0, u))
        rows.append(f"{t:.6f},{u:.12g},{m:.12g}")
        for _ in range(SUB):
            s, sd = RB1 * th1 - RB2 * th2, RB1 * w1 - RB2 * w2
            f = K * (s - B) + C * sd if s > B else (K * (s + B) + C * sd if s < -B else 0.0)
            w1 += h * (u - RB1 * f - D1 * w1) / J1
            w = w2 + h * (RB2 * f - D2 * w2) / J2
            stick = h * TC2 / J2
            w2 = 0.0 if abs(w) <= stick else w - math.copysign(stick, w)
            th1 += h * w1
            th2 += h * w2
    (Path(__file__).resolve().parent / "other_sim_start_in_gap.csv").write_text("\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
