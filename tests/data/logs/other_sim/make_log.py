"""Write ``../other_sim_j1_unconstrained.csv`` (seed 104) or any log of a reviewer's identification campaign.

Another simulator than gearctl's (``sim.c``, compiled here with ``cc``): symplectic Euler at a fixed 1 us
micro-step, Coulomb friction stepped implicitly, a linear or no-pull mesh with backlash, a PD(+I) loop of its own on
the quantised motor encoder. Each seed draws a servo around ``shing1993_servo_friction`` (J1 0.9-1.1x, J2
0.75-1.3x, b 22-132 um, viscous friction 0.5-2x, Coulomb friction, a load torque, mesh stiffness 0.85-1.15x), a
sample rate of 250 Hz to 4 kHz, a reference (``gearctl excite``'s identify or moves motion, a triangle, steps or a
sine), encoder counts and noise, time-stamp jitter and one of the file layouts ``read_log`` documents. Run from
anywhere (needs ``cc`` and the ``gearctl`` command):

    python tests/data/logs/other_sim/make_log.py [SEED] [OUT.csv]
"""

import ctypes
import json
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
_so = os.path.join(os.environ.get('TMPDIR', '/tmp'), 'gearctl_other_sim.so')
subprocess.run(['cc', '-O2', '-shared', '-fPIC', '-o', _so, os.path.join(HERE, 'sim.c'), '-lm'], check=True)
lib = ctypes.CDLL(_so)
dp = np.ctypeslib.ndpointer(dtype=np.float64, flags='C_CONTIGUOUS')
lib.run.argtypes = [ctypes.c_int, ctypes.c_double, ctypes.c_int, dp, dp, dp, dp, dp, dp, dp, dp, dp, dp, dp, dp]
lib.run.restype = ctypes.c_int

RB1, RB2 = 0.018793852415718168, 0.07517540966287267
K, C = 138544672.97790593, 798.5767215559957
NOM = dict(J1=0.00021960353815840032, J2=0.01001850576855048, b=5e-5, d1=1e-4, d2=2e-3, Tc1=0.0, Tc2=0.2)
REF = {}

def reference(kind, Ts, dur, amp=0.1, seed=0):
    t = np.arange(int(round(dur / Ts)) + 1) * Ts
    if kind in ('identify', 'moves'):
        key = (kind, dur, amp)
        if key not in REF:
            f = os.path.join(os.environ.get('TMPDIR', '/tmp'), f'gearctl_other_sim_ref_{kind}_{dur}_{amp}.csv')
            if not os.path.exists(f):
                subprocess.run(['gearctl', 'excite', 'shing1993_servo_friction', '--motion', kind,
                                '--duration', str(dur), '--amplitude', str(amp), '--reference-only', f],
                               check=True, capture_output=True)
            REF[key] = np.loadtxt(f, delimiter=',', skiprows=2)
        d = REF[key]
        return t, np.interp(t, d[:, 0], d[:, 1]), np.interp(t, d[:, 0], d[:, 2]), np.interp(t, d[:, 0], d[:, 3])
    if kind == 'triangle':  # smoothed triangle, period 2 s
        T = 2.0
        ph = (t % T) / T
        r = amp * (2 * np.abs(2 * ph - 1) - 1)
        r = np.convolve(r, np.ones(int(0.05 / Ts)) / int(0.05 / Ts), mode='same')
    elif kind == 'sine':
        r = amp * np.sin(2 * np.pi * 0.7 * t)
    elif kind == 'steps':
        rng = np.random.default_rng(seed)
        lv = rng.uniform(-amp, amp, size=int(dur / 0.5) + 2)
        r = lv[(t / 0.5).astype(int)]
        w = int(0.08 / Ts)
        r = np.convolve(r, np.ones(w) / w, mode='same')
        r = np.convolve(r, np.ones(w) / w, mode='same')
    v = np.gradient(r, Ts)
    a = np.gradient(v, Ts)
    return t, r, v, a

def simulate(truth, ctrl, Ts, dur, ref_kind, amp=0.1, seed=0, cpr1=2**20, noise1=0.0, s0=None, nsub=None, uol=None):
    t, r, v, a = reference(ref_kind, Ts, dur, amp, seed)
    n = len(t)
    rng = np.random.default_rng(seed + 1000)
    P = np.array([truth['J1'], truth['J2'], RB1, RB2, K * truth.get('kfac', 1.0), C, truth['b'], truth['d1'],
                  truth['d2'], truth['Tc1'], truth['Tc2'], truth.get('TL', 0.0), float(truth.get('nopull', 0)), 1.0,
                  2 * np.pi / cpr1 if cpr1 else 0.0])
    Ct = np.array([ctrl['Kp'], ctrl['Kd'], ctrl.get('Ki', 0.0), ctrl.get('Jff', 0.0), ctrl.get('dff', 0.0),
                   ctrl.get('alpha', 0.0), ctrl.get('cff', 0.0)])
    nz1 = rng.normal(0, noise1, n) if noise1 else np.zeros(n)
    # start: load at 0, motor placed so that s = s0 (s0=None: resting on the front flank)
    if s0 is None:
        s0 = truth['b']
    x0 = np.array([s0 / RB1 + 0.0, 0.0, 0.0, 0.0])
    uo = np.zeros(n) if uol is None else np.ascontiguousarray(uol[:n], dtype=float)
    if nsub is None:
        nsub = max(1, int(round(Ts / 1e-6)))
    out = [np.zeros(n) for _ in range(4)]
    rc = lib.run(n, Ts, nsub, P, Ct, r, v, a, uo, nz1, x0, *out)
    if rc != 0:
        raise RuntimeError(f'sim diverged at sample {-rc-1}')
    u, th1, th2, m1 = out
    return dict(t=t, u=u, th1=th1, th2=th2, m1=m1, r=r)

def quant(x, cpr):
    q = 2 * np.pi / cpr
    return np.floor(x / q) * q

def write_csv(path, res, *, cpr2=2**20, noise2=0.0, t0=0.0, jitter=0.0, fmt='plain', seed=0, load=True,
              theta_offset=(0.0, 0.0), load_sign=1):
    rng = np.random.default_rng(seed + 2000)
    t = res['t']
    Ts = t[1] - t[0]
    ts = t0 + t + (rng.uniform(-jitter, jitter, len(t)) * Ts if jitter else 0.0)
    th1 = res['m1'] + theta_offset[0]
    th2 = quant(res['th2'] + (rng.normal(0, noise2, len(t)) if noise2 else 0.0), cpr2) * load_sign + theta_offset[1]
    cols = {'t': ts, 'torque': res['u'], 'theta1': th1}
    if load:
        cols['theta2'] = th2
    cols['reference'] = res['r']
    names = list(cols)
    delim = ','
    if fmt == 'shuffled':
        names = ['theta1', 'status', 'torque'] + (['theta2'] if load else []) + ['t']
    elif fmt == 'semicolon':
        delim = ';'
    elif fmt == 'tab':
        delim = '\t'
    with open(path, 'w', encoding='utf-8') as f:
        if fmt == 'bom':
            f.write('\ufeff')
        f.write('# log from an independent simulator\n')
        if fmt == 'quoted':
            f.write(delim.join(f'"{c}"' for c in names) + '\n')
        else:
            f.write(delim.join(names) + (',' if fmt == 'trailing' else '') + '\n')
        for i in range(len(t)):
            row = []
            for c in names:
                if c == 'status':
                    row.append('OK' if i % 7 else 'RUN')
                elif c == 't':
                    row.append(f'{cols[c][i]:.9f}')
                else:
                    row.append(repr(float(cols[c][i])))
            if fmt == 'quoted':
                row = [f'"{x}"' for x in row]
            f.write(delim.join(row) + (',' if fmt == 'trailing' else '') + '\n')
            if fmt == 'comments' and i % 1000 == 500:
                f.write('# a comment\n\n')


def main(seed: int, out: str) -> None:
    """One log of the campaign: the draws of ``seed``, in the campaign's order."""
    rng = np.random.default_rng(seed)
    truth = dict(J1=NOM['J1'] * rng.uniform(0.9, 1.1), J2=NOM['J2'] * rng.uniform(0.75, 1.3),
                 b=float(rng.choice([2.5e-5, 5e-5, 5e-5, 8e-5, 1.2e-4]) * rng.uniform(0.9, 1.1)),
                 d1=1e-4 * rng.uniform(0.5, 2), d2=2e-3 * rng.uniform(0.5, 2),
                 Tc1=float(rng.choice([0.0, rng.uniform(2e-4, 2e-3)])),
                 Tc2=float(rng.choice([0.0, rng.uniform(0.05, 0.3)])),
                 TL=float(rng.choice([0.0, 0.0, 0.0, rng.uniform(-0.1, 0.1)])), nopull=int(rng.integers(2)),
                 kfac=rng.uniform(0.85, 1.15))
    rate = int(rng.choice([250, 500, 1000, 2000, 4000]))
    Ts = 1.0 / rate
    fc = min(20.0, rate / 40)
    wc = 2 * np.pi * fc
    Jt = NOM['J1'] + NOM['J2'] / 16
    ctrl = dict(Kp=Jt * wc**2, Kd=2 * 0.7 * Jt * wc, Ki=float(rng.choice([0.0, Jt * wc**3 / 10])), Jff=Jt,
                alpha=0.5, cff=float(rng.choice([0.0, 0.05])))
    ref = str(rng.choice(['identify', 'identify', 'moves', 'triangle', 'steps', 'sine']))
    amp = float(rng.choice([0.05, 0.1, 0.2]))
    cpr = int(2 ** rng.integers(16, 21))
    noise = float(rng.choice([0.0, 1e-6, 3e-6]))
    s0 = 0.0 if rng.uniform() < 0.4 else None
    fmt = str(rng.choice(['plain', 'shuffled', 'semicolon', 'tab', 'quoted', 'bom', 'trailing', 'comments']))
    jitter = float(rng.choice([0.0, 0.05, 0.2]))
    t0 = float(rng.choice([0.0, 12.5, 1000.0]))
    res = simulate(truth, ctrl, Ts, 10.0, ref, amp, seed, cpr1=cpr, noise1=noise, s0=s0)
    write_csv(out, res, cpr2=cpr, noise2=noise, t0=t0, jitter=jitter, fmt=fmt, seed=seed)
    print(json.dumps(dict(seed=seed, rate=rate, ref=ref, fmt=fmt, truth=truth), default=float))


if __name__ == '__main__':
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 104,
         sys.argv[2] if len(sys.argv) > 2 else os.path.join(HERE, '..', 'other_sim_j1_unconstrained.csv'))
