"""h6's independent backlash-servo simulator (not gearctl's kernel).

Two inertias coupled by a gear mesh with a dead zone of +-b along the line of action and a stiff no-pull
contact spring-damper (F = max(0, k (|s| - b) + c s' sign)), Coulomb friction as a tanh law (velocity scale
``vs``) plus viscous friction on each shaft, integrated with SciPy's ``solve_ivp`` (DOP853) one torque
sample at a time (zero-order hold), with terminal events where the contact opens or closes so the
integrator never steps across the dead zone's corners. Encoders are quantised after additive noise.

    s = rb1 th1 - rb2 th2
    J1 th1'' = u  - d1 w1 - Tc1 tanh(w1/vs) - rb1 F
    J2 th2'' = rb2 F - d2 w2 - Tc2 tanh(w2/vs) - TL
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.integrate import solve_ivp


@dataclasses.dataclass
class Plant:
    rb1: float
    rb2: float
    J1: float
    J2: float
    b: float
    k: float
    c: float
    d1: float = 0.0
    d2: float = 0.0
    Tc1: float = 0.0
    Tc2: float = 0.0
    TL: float = 0.0
    vs: float = 2e-3

    @property
    def N(self) -> float:
        return self.rb2 / self.rb1


def _rhs(p: Plant, u: float, mode: int):
    def f(_t, x):
        th1, w1, th2, w2 = x
        s = p.rb1 * th1 - p.rb2 * th2
        sd = p.rb1 * w1 - p.rb2 * w2
        if mode > 0:
            F = max(0.0, p.k * (s - p.b) + p.c * sd)
        elif mode < 0:
            F = min(0.0, p.k * (s + p.b) + p.c * sd)
        else:
            F = 0.0
        a1 = (u - p.d1 * w1 - p.Tc1 * math.tanh(w1 / p.vs) - p.rb1 * F) / p.J1
        a2 = (p.rb2 * F - p.d2 * w2 - p.Tc2 * math.tanh(w2 / p.vs) - p.TL) / p.J2
        return [w1, a1, w2, a2]
    return f


def _mode(p: Plant, x) -> int:
    s = p.rb1 * x[0] - p.rb2 * x[2]
    return 1 if s > p.b else (-1 if s < -p.b else 0)


def _events(p: Plant, mode: int):
    if mode == 0:
        def hi(_t, x):
            return p.rb1 * x[0] - p.rb2 * x[2] - p.b
        def lo(_t, x):
            return p.rb1 * x[0] - p.rb2 * x[2] + p.b
        hi.terminal = lo.terminal = True
        hi.direction, lo.direction = 1, -1
        return [hi, lo]
    edge = p.b if mode > 0 else -p.b
    def out(_t, x):
        return p.rb1 * x[0] - p.rb2 * x[2] - edge
    out.terminal = True
    out.direction = -mode
    return [out]


def _rhs_any(p: Plant, u: float):
    """The right-hand side with the mode read from the state (for a stretch of grazing contacts)."""
    fs = {m: _rhs(p, u, m) for m in (-1, 0, 1)}

    def f(t, x):
        return fs[_mode(p, x)](t, x)
    return f


def step(p: Plant, x, u: float, T: float, max_step: float, max_events: int = 50):
    """Advance the state x over T with constant torque u.

    Each contact change is an event that restarts the integration in the new mode; a contact that grazes
    (more than ``max_events`` changes in one interval) finishes the interval with the mode read from the state.
    """
    t0 = 0.0
    x = np.asarray(x, float)
    for _ in range(max_events):
        mode = _mode(p, x)
        sol = solve_ivp(_rhs(p, u, mode), (t0, T), x, method="DOP853", rtol=1e-9, atol=1e-12,
                        events=_events(p, mode), max_step=max_step)
        x = sol.y[:, -1]
        t0 = float(sol.t[-1])
        if sol.status != 1:
            return x
        # an event: step a hair past the corner so the next mode is the new one
        h = 1e-10
        x = x + h * np.asarray(_rhs(p, u, mode)(t0, x))
        t0 += h
        if t0 >= T:
            return x
    sol = solve_ivp(_rhs_any(p, u), (t0, T), x, method="DOP853", rtol=1e-9, atol=1e-12, max_step=max_step / 10)
    return sol.y[:, -1]


def run(p: Plant, Ts: float, n: int, *, controller=None, torque=None, x0=(0.0, 0.0, 0.0, 0.0),
        umax: float = 1.0, substep: float = 5e-5):
    """Simulate n samples. controller(k, th1_meas, th2_meas) -> torque, or torque array (open loop).
    Returns arrays: torque[n], th1[n], th2[n] (true angles at the sample instants, before the torque of that row)."""
    x = np.array(x0, float)
    U = np.zeros(n)
    X = np.zeros((n, 4))
    for k in range(n):
        X[k] = x
        if controller is not None:
            u = controller(k, x)
        else:
            u = torque[k]
        u = float(np.clip(u, -umax, umax))
        U[k] = u
        x = step(p, x, u, Ts, substep)
    return U, X


class Encoder:
    def __init__(self, cpr: int, noise: float, rng, offset: float = 0.0):
        self.q = 2 * math.pi / cpr
        self.noise = noise
        self.rng = rng
        self.offset = offset

    def __call__(self, th):
        th = np.asarray(th, float) + self.offset
        th = th + self.noise * self.rng.standard_normal(np.shape(th))
        return np.round(th / self.q) * self.q


class PID:
    """A discrete PID on the motor encoder, load reference r(t) times N; derivative on a filtered difference."""

    def __init__(self, Kp, Ki, Kd, Ts, ref, N, enc, tau_d=2e-3, lag=0):
        self.Kp, self.Ki, self.Kd, self.Ts = Kp, Ki, Kd, Ts
        self.ref, self.N, self.enc = ref, N, enc
        self.i = 0.0
        self.prev = None
        self.d = 0.0
        self.a = Ts / (tau_d + Ts)
        self.meas = []

    def __call__(self, k, x):
        y = float(self.enc(x[0]))
        e = self.N * self.ref[k] - y
        if self.prev is None:
            self.prev = e
        self.d += self.a * ((e - self.prev) / self.Ts - self.d)
        self.prev = e
        self.i += e * self.Ts
        return self.Kp * e + self.Ki * self.i + self.Kd * self.d
