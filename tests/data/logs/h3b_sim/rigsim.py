"""h3's independent rig simulator driver (own code): Hunt-Crossley contact, LuGre/Stribeck friction, current lag,
quantised encoders of its own counts, jittered and drifting sample clock, several excitations, log format variants."""
from __future__ import annotations

import ctypes
import json
import math
import subprocess
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
_lib = ctypes.CDLL(str(HERE / "librig.so"))


class Rig(ctypes.Structure):
    _fields_ = [(n, ctypes.c_double) for n in (
        "rb1 rb2 b K n alpha J1 J2 d1 Tc1 Ts1 vs1 s01 s11 d2 Tc2 Ts2 vs2 s02 s12 TL tau h umax "
        "kp kd ki kff_v kff_a").split()] + [("mode", ctypes.c_int)] + [
        (n, ctypes.c_double) for n in ("q1", "q2", "N")]


_P = ctypes.POINTER(ctypes.c_double)
_lib.rig_run.argtypes = [ctypes.POINTER(Rig), ctypes.c_int] + [_P] * 11
_lib.rig_run.restype = ctypes.c_int


def model_info(model: str) -> dict:
    cli = "import sys; from gearctl.cli import main; sys.exit(main(sys.argv[1:]))"
    out = subprocess.run([sys.executable, "-c", cli, "info", model, "--json"], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(out)


@dataclass
class Truth:
    b: float
    J1: float
    J2: float
    d1: float
    d2: float
    Tc1: float
    Tc2: float
    Ts_ratio1: float = 1.5   # Stribeck static / Coulomb
    Ts_ratio2: float = 1.3
    vs1: float = 0.05        # Stribeck speed [rad/s]
    vs2: float = 0.01
    TL: float = 0.0


@dataclass
class Setup:
    model: str
    truth: Truth
    fs: float = 1000.0
    duration: float = 8.0
    excitation: str = "moves"        # moves | gearref | chirp | prbs_steps | ol_torque
    cpr1: int = 1 << 17
    cpr2: int = 1 << 19
    noise1: float = 1e-6
    noise2: float = 1e-6
    jitter_act: float = 0.0          # RMS jitter of the true sample instants [s]
    jitter_stamp: float = 0.0        # RMS jitter of the logged stamps [s]
    drift_ppm: float = 0.0
    t0: float = 0.0
    tau: float = 1e-4                # current-loop lag [s]
    umax: float = 1.0
    amp: float = 0.1                 # load-angle motion amplitude [rad]
    feedback: int = 0                # 0 motor encoder, 1 load encoder
    hertz_n: float = 1.5
    seed: int = 0
    h: float = 1e-6
    extra: dict = field(default_factory=dict)


def reference(setup: Setup, t: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Load-angle reference with velocity and acceleration."""
    A = setup.amp
    ex = setup.excitation
    if ex == "gearref":
        d = np.loadtxt(setup.extra["ref"], delimiter=",", comments="#", skiprows=2)
        tr, r, v, a = d.T
        return np.interp(t, tr, r), np.interp(t, tr, v), np.interp(t, tr, a)
    if ex == "moves":
        # trapezoid-ish moves (smooth cosine velocity) between random targets with dwells
        r = np.zeros_like(t)
        tt, pos = 0.3, 0.0
        segs = []
        while tt < t[-1]:
            target = rng.uniform(-A, A)
            if abs(target - pos) < 0.2 * A:
                target = -pos if abs(pos) > 0.2 * A else A
            T = max(0.08, math.sqrt(abs(target - pos) / (A / 0.04)) * 0.4 * rng.uniform(0.7, 1.6))
            segs.append((tt, T, pos, target))
            pos = target
            tt += T + rng.uniform(0.15, 0.4)
        for (ts, T, p0, p1) in segs:
            m = t >= ts
            s = np.clip((t[m] - ts) / T, 0, 1)
            r[m] = p0 + (p1 - p0) * (s - np.sin(2 * np.pi * s) / (2 * np.pi))
        v = np.gradient(r, t)
        a = np.gradient(v, t)
        return r, v, a
    if ex == "chirp":
        f0, f1 = 0.5, 6.0
        T = t[-1]
        ph = 2 * np.pi * (f0 * t + (f1 - f0) * t ** 2 / (2 * T))
        env = np.minimum(1, t / 0.3) * A * (f0 / (f0 + (f1 - f0) * t / T)) ** 0.7
        r = env * np.sin(ph)
        v = np.gradient(r, t)
        return r, v, np.gradient(v, t)
    if ex == "prbs_steps":
        # PRBS levels, each held 0.25-0.6 s, passed through a 2nd-order 15 Hz filter so the loop can follow
        r = np.zeros_like(t)
        tt, lev = 0.2, 0.0
        while tt < t[-1]:
            hold = rng.uniform(0.25, 0.6)
            lev = A * (1 if rng.random() < 0.5 else -1) * rng.uniform(0.4, 1.0)
            r[t >= tt] = lev
            tt += hold
        wn = 2 * np.pi * 8
        y = np.zeros_like(r)
        yd = 0.0
        dt = t[1] - t[0]
        for i in range(1, len(t)):
            ydd = wn * wn * (r[i - 1] - y[i - 1]) - 2 * wn * yd
            yd += ydd * dt
            y[i] = y[i - 1] + yd * dt
        v = np.gradient(y, t)
        return y, v, np.gradient(v, t)
    raise ValueError(ex)


def simulate(setup: Setup) -> dict:
    rng = np.random.default_rng(setup.seed)
    info = model_info(setup.model)
    rb1, rb2 = info["base_radius"]
    N = rb2 / rb1
    k = info["plant"]["k"]
    tr = setup.truth
    # Hunt-Crossley: match the model's stiffness as a secant at 30 N
    F0 = 30.0
    d0 = F0 / k
    K = F0 / d0 ** setup.hertz_n
    alpha = 1.5 * (1 - 0.6) / 0.02
    Jeff = tr.J2 + N * N * tr.J1
    wc = 2 * np.pi * setup.extra.get("bw_hz", 8.0)
    p = Rig()
    p.rb1, p.rb2, p.b, p.K, p.n, p.alpha = rb1, rb2, tr.b, K, setup.hertz_n, alpha
    p.J1, p.J2 = tr.J1, tr.J2
    zc1, zc2 = 2e-5, 5e-6
    p.d1, p.Tc1, p.Ts1, p.vs1 = tr.d1, tr.Tc1, tr.Tc1 * tr.Ts_ratio1, tr.vs1
    p.s01 = tr.Tc1 / zc1 if tr.Tc1 > 0 else 0.0
    p.s11 = 2 * 0.5 * math.sqrt(p.s01 * tr.J1)
    p.d2, p.Tc2, p.Ts2, p.vs2 = tr.d2, tr.Tc2, tr.Tc2 * tr.Ts_ratio2, tr.vs2
    p.s02 = tr.Tc2 / zc2 if tr.Tc2 > 0 else 0.0
    p.s12 = 2 * 0.5 * math.sqrt(p.s02 * tr.J2)
    if setup.extra.get("tanh"):  # plain smooth Coulomb, its slope Tc / vs at standstill
        p.s01, p.s02 = -1.0, -1.0
        p.vs1 = p.vs2 = setup.extra["tanh"]
    p.TL = tr.TL
    p.tau, p.h, p.umax = setup.tau, setup.h, setup.umax
    p.kp = Jeff * wc * wc / N
    p.kd = 2 * 0.8 * wc * Jeff / N
    p.ki = p.kp * setup.extra.get("ki_hz", 1.5) * 2 * np.pi / 4
    p.kff_v = (tr.d2 + N * N * tr.d1) / N
    p.kff_a = Jeff / N
    p.mode = 2 if setup.excitation == "ol_torque" else setup.feedback
    p.q1 = 2 * np.pi / setup.cpr1
    p.q2 = 2 * np.pi / setup.cpr2
    p.N = N
    T = 1.0 / setup.fs
    ns = int(round(setup.duration * setup.fs)) + 1
    kk = np.arange(ns + 1)
    tk = kk * T * (1 + setup.drift_ppm * 1e-6)
    if setup.jitter_act > 0:
        tk = tk + np.clip(rng.normal(0, setup.jitter_act, ns + 1), -0.2 * T, 0.2 * T)
        tk[0] = 0.0
        tk = np.maximum.accumulate(tk)
    tnom = kk[:ns] * T
    if setup.excitation == "ol_torque":
        # open-loop: PRBS torque cells of 30 ms with a slow sine, enough to cross the gap
        cells = rng.choice([-1.0, 1.0], size=int(setup.duration / 0.03) + 2)
        u = setup.extra.get("ol_amp", 0.05) * cells[(tnom / 0.03).astype(int)] + 0.5 * setup.extra.get(
            "ol_amp", 0.05) * np.sin(2 * np.pi * 1.3 * tnom)
        r, rv, ra = u, np.zeros(ns), np.zeros(ns)
    else:
        r, rv, ra = reference(setup, tnom, rng)
        r = np.where(tnom < 0.05, 0.0, r)
    n1 = rng.normal(0, setup.noise1, ns)
    n2 = rng.normal(0, setup.noise2, ns)
    out = {name: np.zeros(ns) for name in ("u", "th1", "th2", "fc")}
    # start resting on the front flank
    st = np.array([tr.b / rb1, 0.0, 0.0, 0.0])
    arr = [np.ascontiguousarray(a, dtype=float) for a in (tk, r, rv, ra, n1, n2)]
    ptr = lambda a: a.ctypes.data_as(_P)  # noqa: E731
    rc = _lib.rig_run(ctypes.byref(p), ns, *[ptr(a) for a in arr], *[ptr(out[n]) for n in ("u", "th1", "th2", "fc")],
                      ptr(st))
    if rc != 0:
        raise RuntimeError("simulation diverged")
    # encoders as read: own counts, noise, arbitrary zero
    z1, z2 = rng.uniform(-3, 3), rng.uniform(-3, 3)
    q1, q2 = 2 * np.pi / setup.cpr1, 2 * np.pi / setup.cpr2
    # interpolation error of a sine/cosine encoder: amplitude `interp` of a line pitch, period one line
    l1, l2 = setup.extra.get("lines", (2048, 4096))
    ie = setup.extra.get("interp", 0.0)
    x1 = out["th1"] + z1
    x2 = out["th2"] + z2
    x1 = x1 + ie * (2 * np.pi / l1) * np.sin(l1 * x1)
    x2 = x2 + ie * (2 * np.pi / l2) * np.sin(l2 * x2 + 0.7)
    e1 = np.floor((x1 + n1) / q1) * q1
    e2 = np.floor((x2 + n2) / q2) * q2
    stamps = setup.t0 + tnom
    if setup.jitter_stamp > 0:
        stamps = stamps + np.clip(rng.normal(0, setup.jitter_stamp, ns), -0.2 * T, 0.2 * T)
    s = rb1 * out["th1"] - rb2 * out["th2"]
    return dict(t=stamps, torque=out["u"], theta1=e1, theta2=e2, fc=out["fc"], s=s, ref=r, N=N, rb1=rb1, rb2=rb2,
                info=info)


def write_csv(path, d, *, order=("t", "torque", "theta1", "theta2"), extra=(), comments=(), crlf=False, delim=",",
              units_row=None, fmt="%.9g", tfmt="%.9f", load_sign=1.0, nan_rows=(), rows=None):
    nl = "\r\n" if crlf else "\n"
    cols = {"t": d["t"], "torque": d["torque"], "theta1": d["theta1"], "theta2": load_sign * d["theta2"],
            "reference": d["ref"], "status": None, "current_A": d["torque"] / 0.12, "s_true": d["s"]}
    names = list(order) + list(extra)
    lines = [f"# {c}" for c in comments]
    lines.append(delim.join(names))
    if units_row:
        lines.append(delim.join(units_row))
    n = len(d["t"]) if rows is None else rows
    for i in range(n):
        f = []
        for c in names:
            if c == "status":
                f.append("OK" if i % 7 else "RUN")
            elif c == "t":
                f.append(tfmt % cols[c][i])
            else:
                v = cols[c][i]
                f.append("nan" if i in nan_rows and c == "theta1" else fmt % v)
        lines.append(delim.join(f))
    Path(path).write_bytes((nl.join(lines) + nl).encode())
    return path


def truth_from_model(info: dict, *, b, j1=1.0, j2=1.0, d1=None, d2=None, tc1=0.0, tc2=0.0, TL=0.0, **kw) -> Truth:
    J1 = info["plant"]["J1"] * j1
    J2 = info["plant"]["J2"] * j2
    return Truth(b=b, J1=J1, J2=J2, d1=1e-4 if d1 is None else d1, d2=2e-3 if d2 is None else d2, Tc1=tc1,
                 Tc2=tc2, TL=TL, **kw)


if __name__ == "__main__":  # a quick look at one log
    info = model_info("shing1993_servo_friction")
    tr = truth_from_model(info, b=5e-5, tc2=0.2, tc1=0.002)
    st = Setup(model="shing1993_servo_friction", truth=tr)
    import time
    t0 = time.time()
    d = simulate(st)
    print("sim", time.time() - t0, "s")
    print(asdict(tr))
    write_csv("try.csv", d)
    s = d["s"]
    print("s range", s.min(), s.max(), "max|u|", abs(d["torque"]).max())
