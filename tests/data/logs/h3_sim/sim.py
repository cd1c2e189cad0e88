"""h3's servo-rig simulator (independent of gearctl): numpy only.

Two inertias coupled by a gear mesh with a backlash gap along the line of action:
  s = rb1*th1 - rb2*th2 (relative displacement), contact when |s| > b,
  mesh force F = kh*delta^1.5 + c*s' (Hertz-like, damping only in contact, no pull: F clipped at 0).
  kh is chosen so the tangent stiffness equals the model's linear k at force F0.
Friction on both shafts: viscous d*w + Stribeck Coulomb (Tc + (Ts - Tc) exp(-(w/vs)^2)) sgn w with exact
stiction (a shaft sticks when its speed crosses zero and the other torques stay under Ts).
Integration: semi-implicit (symplectic) Euler at a fixed inner step dt_in (default 2 us), with the
sampling instants on the logger's own clock: period T*(1+ppm) plus jitter; torque is computed at each
sample instant (PD on the quantised, noisy motor encoder following N * reference, or open-loop pulses) and
held until the next instant. Encoders: quantised to cpr counts/rev, gaussian noise, arbitrary zero.
"""
from __future__ import annotations

import math

import numpy as np


def simulate(p: dict, seed: int = 0):
    rng = np.random.default_rng(seed)
    rb1, rb2 = p["rb1"], p["rb2"]
    N = rb2 / rb1
    J1, J2 = p["J1"], p["J2"]
    b = p["b"]
    k = p["k"]
    F0 = p.get("F0", 5.0)
    # tangent stiffness 1.5 kh d^0.5 = k at F0 = kh d^1.5 -> d0 = 1.5 F0 / k, kh = F0 / d0^1.5
    d0 = 1.5 * F0 / k
    kh = F0 / d0 ** 1.5
    c = p["c"]
    d1, d2 = p["d1"], p["d2"]
    Tc1, Tc2 = p["Tc1"], p["Tc2"]
    Ts1, Ts2 = p.get("Ts1", 1.3 * p["Tc1"]), p.get("Ts2", 1.3 * p["Tc2"])
    vs = p.get("vs", 0.02)
    TL = p.get("TL", 0.0)
    umax = p.get("umax", 1.0)
    fs = p["fs"]
    T = (1.0 / fs) * (1.0 + p.get("ppm", 0.0) * 1e-6)
    jit = p.get("jitter", 0.0)
    dur = p["duration"]
    dt_in = p.get("dt_in", 2e-6)
    q1 = 2 * math.pi / p["cpr1"]
    q2 = 2 * math.pi / p["cpr2"]
    n1, n2 = p.get("noise1", 0.0), p.get("noise2", 0.0)
    z1, z2 = p.get("zero1", 0.0), p.get("zero2", 0.0)
    mode = p.get("mode", "pd")
    ref = p.get("ref")
    Kp, Kd = p.get("Kp", 0.0), p.get("Kd", 0.0)
    nsamp = int(dur * fs)
    # state
    th1 = p.get("th1_0", 0.0)
    th2 = p.get("th2_0", 0.0)
    w1 = w2 = 0.0
    st1 = st2 = True  # stuck
    rows = []
    prev_m = None
    wf = 0.0
    tk_nom = np.arange(nsamp + 1) * T + rng.normal(0, jit, nsamp + 1) if jit else np.arange(nsamp + 1) * T
    tk_nom[0] = 0.0
    tk_nom = np.maximum.accumulate(tk_nom)
    for i in range(nsamp):
        ti = tk_nom[i]
        m1 = q1 * round((th1 + z1 + rng.normal(0, n1)) / q1) if n1 else q1 * round((th1 + z1) / q1)
        m2 = q2 * round((th2 + z2 + rng.normal(0, n2)) / q2) if n2 else q2 * round((th2 + z2) / q2)
        if mode == "pd":
            r, rd = ref(ti)
            if prev_m is None:
                wm = 0.0
            else:
                wm = (m1 - prev_m) / max(tk_nom[i] - tk_nom[i - 1], 1e-9)
            wf = wf + 0.5 * (wm - wf)  # one-pole filter on the velocity
            prev_m = m1
            u = Kp * (N * r - (m1 - z1)) + Kd * (N * rd - wf)
        else:
            u = p["pulses"](ti)
        u = max(-umax, min(umax, u))
        rows.append((ti, u, m1, m2, th1, th2))
        # integrate to next instant
        t_end = tk_nom[i + 1]
        nst = max(1, int(math.ceil((t_end - ti) / dt_in)))
        h = (t_end - ti) / nst
        for _ in range(nst):
            s = rb1 * th1 - rb2 * th2
            sd = rb1 * w1 - rb2 * w2
            if s > b:
                F = kh * (s - b) ** 1.5 + c * sd
                if F < 0.0:
                    F = 0.0
            elif s < -b:
                F = -kh * (-s - b) ** 1.5 + c * sd
                if F > 0.0:
                    F = 0.0
            else:
                F = 0.0
            T1 = u - rb1 * F
            T2 = rb2 * F - TL
            # shaft 1
            if st1:
                if abs(T1) > Ts1:
                    st1 = False
                    w1 = w1 + (T1 - math.copysign(Ts1, T1)) / J1 * h
            else:
                sg = math.copysign(1.0, w1) if w1 != 0.0 else math.copysign(1.0, T1)
                Tf = (Tc1 + (Ts1 - Tc1) * math.exp(-(w1 / vs) ** 2)) * sg + d1 * w1
                wn = w1 + (T1 - Tf) / J1 * h
                if wn * w1 < 0.0 and abs(T1) <= Ts1 and Tc1 > 0.0:
                    wn = 0.0
                    st1 = True
                w1 = wn
            if st2:
                if abs(T2) > Ts2:
                    st2 = False
                    w2 = w2 + (T2 - math.copysign(Ts2, T2)) / J2 * h
            else:
                sg = math.copysign(1.0, w2) if w2 != 0.0 else math.copysign(1.0, T2)
                Tf = (Tc2 + (Ts2 - Tc2) * math.exp(-(w2 / vs) ** 2)) * sg + d2 * w2
                wn = w2 + (T2 - Tf) / J2 * h
                if wn * w2 < 0.0 and abs(T2) <= Ts2 and Tc2 > 0.0:
                    wn = 0.0
                    st2 = True
                w2 = wn
            th1 += w1 * h
            th2 += w2 * h
    return np.array(rows)


def smooth_triangle(amp: float, period: float, dwell: float = 0.0):
    """A reference that moves between +-amp with cosine-blended (slow) reversals and optional dwells."""
    def f(t: float):
        cyc = period + 2 * dwell
        # phases: move up (period/2), dwell, move down, dwell
        tp = t % cyc
        half = period / 2
        if tp < half:
            ph = tp / half
            return -amp + amp * (1 - math.cos(math.pi * ph)), amp * math.pi * math.sin(math.pi * ph) / half
        tp -= half
        if tp < dwell:
            return amp, 0.0
        tp -= dwell
        if tp < half:
            ph = tp / half
            return amp - amp * (1 - math.cos(math.pi * ph)), -amp * math.pi * math.sin(math.pi * ph) / half
        return -amp, 0.0
    return f


def pulse_train(A: float, on: float, off: float):
    def f(t: float):
        cyc = 2 * (on + off)
        tp = t % cyc
        if tp < on:
            return A
        if on + off <= tp < 2 * on + off:
            return -A
        return 0.0
    return f
