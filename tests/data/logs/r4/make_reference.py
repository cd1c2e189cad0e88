"""Reference motion for r4's eccentric-encoder log: cosine moves between +-A with dwells (load angle, 1 kHz).

``python make_reference.py A MOVE_S DWELL_S DURATION_S OUT.csv`` writes t, reference, velocity, acceleration in the
format of ``gearctl excite --reference-only``, which ``r4sim.c`` reads.
"""

import sys

import numpy as np


def main(argv: list[str]) -> None:
    A, T, D, dur = (float(v) for v in argv[:4])
    t = np.arange(0, dur + 1e-9, 1e-3)
    r, v, a = np.zeros_like(t), np.zeros_like(t), np.zeros_like(t)
    pts = [0.0] + [A * (-1) ** k for k in range(40)]
    t0 = 0.2
    for p0, p1 in zip(pts[:-1], pts[1:], strict=True):
        m = (t >= t0) & (t < t0 + T)
        tau = (t[m] - t0) / T
        r[m] = p0 + (p1 - p0) * 0.5 * (1 - np.cos(np.pi * tau))
        v[m] = (p1 - p0) * 0.5 * np.pi / T * np.sin(np.pi * tau)
        a[m] = (p1 - p0) * 0.5 * (np.pi / T) ** 2 * np.cos(np.pi * tau)
        r[(t >= t0 + T) & (t < t0 + T + D)] = p1
        t0 += T + D
        if t0 > dur:
            break
    with open(argv[4], "w") as f:
        f.write("# r4 reference\nt,reference,velocity,acceleration\n")
        for row in zip(t, r, v, a, strict=True):
            f.write(f"{row[0]:.3f},{row[1]:.9g},{row[2]:.9g},{row[3]:.9g}\n")


if __name__ == "__main__":
    main(sys.argv[1:])
