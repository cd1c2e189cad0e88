"""Write h6's identification campaign logs (h6sim.py, an independent simulator) and their truth.

    python tests/data/logs/h6_sim/make_logs.py OUTDIR [CASE ...]

Each case writes OUTDIR/CASE.csv and OUTDIR/CASE.json (the true b, inertias, friction, the model to use and
what the log's layout does). The geometry (base radii) is the model file's; the mesh stiffness is this
simulator's own (0.9x gearctl's mean), the damping its own.
"""
from __future__ import annotations

import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import h6sim  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
# base radii and gearctl's plant inertias (motor + gear) for the three models
MODELS = {
    "A": dict(model="shing1993_servo_friction", rb1=0.018793852415718168, rb2=0.07517540966287267,
              J1=2.1960353815840032e-4, J2=1.001850576855048e-2, k=0.9 * 1.3854467e8, c=600.0,
              d1=1e-4, d2=2e-3, Tc1=0.0, Tc2=0.2, umax=1.0, cpr=2**20, A=0.1),
    "B": dict(model=os.path.join(HERE, "h6_big.toml"), rb1=0.033828934348292705, rb2=0.10148680304487812,
              J1=1.4115802043432465e-3, J2=5.3337996551802935e-2, k=0.9 * 3.4758911e8, c=1500.0,
              d1=2e-4, d2=5e-3, Tc1=0.0, Tc2=0.5, umax=5.0, cpr=2**18, A=0.15),
    "C": dict(model=os.path.join(HERE, "h6_phm_out.toml"), rb1=0.022552622898861802, rb2=0.037587704831436336,
              J1=2.0409104729863185e-3, J2=2.3156672298327023e-3, k=0.9 * 1.477374e8, c=900.0,
              d1=9e-4, d2=1e-3, Tc1=0.0, Tc2=0.0, umax=3.0, cpr=2**20, A=0.1),
}


def reference(kind, t, A, rng):
    if kind == "sine":
        return A * np.sin(2 * np.pi * 1.5 * t)
    if kind == "tri":  # moves of 0.3 s between +-A (cosine velocity), dwells of 0.25 s
        T = 0.55
        ph = np.mod(t, 2 * T)
        def move(x):  # 0..1 over 0.3 s
            x = np.clip(x / 0.3, 0, 1)
            return x - np.sin(2 * np.pi * x) / (2 * np.pi)
        return np.where(ph < T, -A + 2 * A * move(ph), A - 2 * A * move(ph - T))
    if kind == "slow":  # one slow back and forth: the gap crossed twice
        return A * np.sin(np.pi * t / t[-1]) ** 2 * np.where(t < 0, 0, 1) - 0.5 * A * (t / t[-1])
    if kind == "steps":
        hold = 0.4
        k = np.floor(t / hold).astype(int)
        targets = rng.uniform(-A, A, k.max() + 2)
        r = targets[k]
        # 30 ms raised-cosine between targets
        x = np.clip((t - k * hold) / 0.03, 0, 1)
        prev = targets[np.maximum(k - 1, 0)]
        return prev + (r - prev) * (0.5 - 0.5 * np.cos(np.pi * x))
    raise ValueError(kind)


CASES = {
    # name: model, b [m], motion, fs [Hz], duration [s], layout options
    "A01_tri_b50": dict(m="A", b=50e-6, motion="tri", fs=1000, dur=6),
    "A02_sine_b20_offset_extra": dict(m="A", b=20e-6, motion="sine", fs=1000, dur=6, t0=1234.5, extra=True,
                                       order=["theta2", "status", "t", "current", "theta1", "torque"]),
    "A03_steps_b120_jitter_2k": dict(m="A", b=120e-6, motion="steps", fs=2000, dur=5, jitter=20e-6),
    "A04_tri_b80_offsets_flip2": dict(m="A", b=80e-6, motion="tri", fs=1000, dur=6, off1=1.234, off2=-0.5, flip2=True),
    "A05_tri_b50_flip1": dict(m="A", b=50e-6, motion="tri", fs=1000, dur=6, flip1=True),
    "A06_tri_b50_ms": dict(m="A", b=50e-6, motion="tri", fs=1000, dur=6, ms=True),
    "A07_tri_b50_dropped": dict(m="A", b=50e-6, motion="tri", fs=1000, dur=6, drop=2345),
    "A08_tri_b50_units": dict(m="A", b=50e-6, motion="tri", fs=1000, dur=6, units=True),
    "A09_tri_b50_counts": dict(m="A", b=50e-6, motion="tri", fs=1000, dur=6, counts=True),
    "A10_sine_b60_midmotion": dict(m="A", b=60e-6, motion="sine", fs=1000, dur=7, cut=1.37),
    "A11_slow_b70_fewcross": dict(m="A", b=70e-6, motion="slow", fs=1000, dur=3),
    "A12_openloop_b100": dict(m="A", b=100e-6, motion="ol", fs=1000, dur=5),
    "A13_tri_b200_coarse16": dict(m="A", b=200e-6, motion="tri", fs=1000, dur=6, cpr=2**16, noise=5e-6),
    "A14_steps_b40_offnominal": dict(m="A", b=40e-6, motion="steps", fs=1000, dur=6, J1x=1.2, J2x=0.85, Tc2=0.3,
                                      Tc1=0.01),
    "A15_tri_b10": dict(m="A", b=10e-6, motion="tri", fs=1000, dur=6),
    "B01_tri_b1000": dict(m="B", b=1000e-6, motion="tri", fs=1000, dur=6),
    "B02_sine_b300_500hz": dict(m="B", b=300e-6, motion="sine", fs=500, dur=8, kd=0.3),
    "B03_steps_b600_loadtorque": dict(m="B", b=600e-6, motion="steps", fs=1000, dur=6, TL=0.8),
    "B04_openloop_b1000": dict(m="B", b=1000e-6, motion="ol", fs=1000, dur=5),
    "B06_bursts_hold_b1000": dict(m="B", b=1000e-6, motion="bursts", fs=1000, dur=4, Tc1=0.02),
    "B05_tri_b500_semicolon_bom": dict(m="B", b=500e-6, motion="tri", fs=1000, dur=6, semicolon=True),
    "C01_tri_b10_2k": dict(m="C", b=10e-6, motion="tri", fs=2000, dur=4),
    "C02_sine_b25": dict(m="C", b=25e-6, motion="sine", fs=1000, dur=6),
    "C03_steps_b40_jitter": dict(m="C", b=40e-6, motion="steps", fs=1000, dur=6, jitter=50e-6),
    "C04_tri_b15_coarse18": dict(m="C", b=15e-6, motion="tri", fs=1000, dur=6, cpr=2**18, noise=2e-6),
    "C05_tri_b30_trainmodel": dict(m="C", b=30e-6, motion="tri", fs=1000, dur=5, model="servo_2stage_phm09"),
}


def make(name, outdir, seed=None):
    c = CASES[name]
    M = MODELS[c["m"]]
    rng = np.random.default_rng(seed if seed is not None else abs(hash(name)) % 2**32)
    p = h6sim.Plant(rb1=M["rb1"], rb2=M["rb2"], J1=M["J1"] * c.get("J1x", 1.0), J2=M["J2"] * c.get("J2x", 1.0),
                    b=c["b"], k=M["k"], c=M["c"], d1=M["d1"], d2=M["d2"], Tc1=c.get("Tc1", M["Tc1"]),
                    Tc2=c.get("Tc2", M["Tc2"]), TL=c.get("TL", 0.0))
    N = p.N
    Ts = 1.0 / c["fs"]
    n = int(round(c["dur"] / Ts))
    t = np.arange(n) * Ts
    cpr = c.get("cpr", M["cpr"])
    noise = c.get("noise", 1e-6)
    enc1 = h6sim.Encoder(cpr, noise, rng)
    enc2 = h6sim.Encoder(cpr, noise, rng)
    Jeq = p.J1 + p.J2 / N**2
    x0 = (0.0, 0.0, 0.0, 0.0)
    if c["motion"] == "bursts":  # open loop: a burst flings the motor across the gap, a small torque then holds
        u = np.zeros(n)  # it on the flank while the load's friction holds the load
        per = int(round(0.3 / Ts))
        for j, k0 in enumerate(range(int(0.05 / Ts), n, per)):
            sg = 1 if j % 2 == 0 else -1
            L = int(round((0.016 + 0.003 * (j % 3)) / Ts))
            u[k0:k0 + L] = sg * 0.25 * M["umax"]
            u[k0 + L:k0 + per] = sg * 0.5 * M["Tc2"] / N
        U, X = h6sim.run(p, Ts, n, torque=u, umax=M["umax"])
    elif c["motion"] == "ol":  # open-loop torque bursts, alternating sign, with rests
        u = np.zeros(n)
        per = int(round(0.25 / Ts))
        u0 = 0.25 * M["umax"]
        for j, k0 in enumerate(range(int(0.05 / Ts), n, per)):
            L = int(round((0.02 + 0.02 * (j % 3)) / Ts))
            u[k0:k0 + L] = u0 * (1 if j % 2 == 0 else -1) * (1 + 0.2 * (j % 3))
            u[k0 + L:k0 + 2 * L] = -0.8 * u0 * (1 if j % 2 == 0 else -1) * (1 + 0.2 * (j % 3))  # brake
        U, X = h6sim.run(p, Ts, n, torque=u, umax=M["umax"])
    else:
        r = reference(c["motion"], t, M["A"], rng)
        w = 2 * np.pi * 12
        pid = h6sim.PID(Jeq * w * w, Jeq * w**3 / 8, 2 * 0.9 * Jeq * w * c.get("kd", 1.0), Ts, r, N, enc1)
        if c.get("TL"):
            x0 = (0.0, 0.0, -p.b / p.rb2, 0.0)
        U, X = h6sim.run(p, Ts, n, controller=pid, umax=M["umax"], x0=x0)
    th1 = enc1(X[:, 0]) + c.get("off1", 0.0)
    th2 = enc2(X[:, 2]) + c.get("off2", 0.0)
    cut = int(round(c.get("cut", 0.0) / Ts))
    t, U, th1, th2 = t[cut:], U[cut:], th1[cut:], th2[cut:]
    tt = t + c.get("t0", 0.0)
    if c.get("jitter"):
        tt = tt + c["jitter"] * rng.standard_normal(tt.size)
    if c.get("flip1"):
        th1 = -th1
    if c.get("flip2"):
        th2 = -th2
    if c.get("counts"):
        th1 = np.round(th1 / (2 * np.pi / cpr))
        th2 = np.round(th2 / (2 * np.pi / cpr))
    if c.get("ms"):
        tt = tt * 1e3
    cols = {"t": tt, "torque": U, "theta1": th1, "theta2": th2}
    fmt = {"t": "%.9f" if not c.get("t0") else "%.6f", "torque": "%.6g", "theta1": "%.9g", "theta2": "%.9g"}
    if c.get("counts"):
        fmt["theta1"] = fmt["theta2"] = "%.0f"
    if c.get("extra"):
        cols["status"] = np.array(["OK"] * tt.size, dtype=object)
        cols["current"] = U / 0.08
        fmt["status"] = "%s"
        fmt["current"] = "%.4f"
    order = c.get("order", list(cols))
    keep = np.ones(tt.size, bool)
    if c.get("drop"):
        keep[c["drop"]] = False
    head = order
    if c.get("units"):
        head = [{"t": "t [s]", "torque": "torque [N m]", "theta1": "theta1 [rad]", "theta2": "theta2 [rad]"}.get(h, h)
                for h in order]
    delim = ";" if c.get("semicolon") else ","
    path = os.path.join(outdir, name + ".csv")
    with open(path, "w", encoding="utf-8") as fh:
        if c.get("semicolon"):
            fh.write("\ufeff# h6sim log\n")
        fh.write(delim.join(head) + "\n")
        for k in np.flatnonzero(keep):
            fh.write(delim.join((fmt[h] % cols[h][k]) for h in order) + "\n")
    s = p.rb1 * X[cut:, 0] - p.rb2 * X[cut:, 2]
    mode = np.where(s > p.b, 1, np.where(s < -p.b, -1, 0))
    mm = mode[mode != 0]
    truth = dict(model=c.get("model", M["model"]), b=p.b, J1=p.J1, J2=p.J2, d1=p.d1, d2=p.d2, Tc1=p.Tc1, Tc2=p.Tc2,
                 TL=p.TL, k=p.k, flank_changes=int((mm[1:] != mm[:-1]).sum()), umax_used=float(abs(U).max()),
                 case={k: v for k, v in c.items() if k != "order"})
    with open(os.path.join(outdir, name + ".json"), "w") as fh:
        json.dump(truth, fh, indent=1)
    return path, truth


if __name__ == "__main__":
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    names = sys.argv[2:] or list(CASES)
    for nm in names:
        path, tr = make(nm, out, seed=sorted(CASES).index(nm))
        print(nm, tr["flank_changes"], f"{tr['umax_used']:.3g}", flush=True)
