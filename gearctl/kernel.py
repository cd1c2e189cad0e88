"""The simulation kernel: advance a gear plant over an interval of constant torque, events located.

Two paths with one algorithm:

- compiled: ``_kernel.c`` built on first use with the system C compiler into a per-user cache and
  called through :mod:`ctypes` (no new runtime dependency);
- pure Python: the same algorithm written out below, used where no C compiler is present (or with
  ``GEARCTL_NO_COMPILE=1``) and as the oracle the tests compare the compiled path against.

The improved plant (without Coulomb friction) is affine inside each contact mode, ``x' = A x + a``, so
its solution between events is exact: full sub-steps apply the precomputed propagators
``Phi(h) = e^{A h}`` and ``Gamma(h) = int_0^h e^{A t} dt``; partial steps and event roots use the
Taylor series of the same solution, summed to 1e-17. Sub-steps are short enough (``rho h <= 0.6``
for the contact mode) that a crossing of ``|s| = b`` between grid points shows as a sign change or as
an interior minimum of the cubic Hermite model, and is then found to machine precision on the series.
The nonlinear plants (Yang–Sun, time-varying stiffness, Coulomb friction) use Dormand–Prince 5(4)
with error control and locate events on its dense output.
"""

from __future__ import annotations

import ctypes
import dataclasses
import functools
import hashlib
import math
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

import numpy as np
import scipy.linalg

from .plant import Plant, PlantKind

__all__ = [
    "Kernel", "EventKind", "compiled_available", "contact_matrices", "ZENO_VELOCITY", "cache_dir", "c_compiler",
]

#: Impacts slower than this along the line of action are made perfectly plastic (the Zeno rule) [m/s].
ZENO_VELOCITY = 1e-6

_SRC = Path(__file__).with_name("_kernel.c")


class EventKind:
    """Codes of the events the kernel records."""

    IMPACT = 1
    SEPARATION = 2
    LIFT = 3  # no_pull: contact force reached zero while the flanks still overlap
    RELOAD = 4
    PLASTIC = 5  # an impact below ZENO_VELOCITY, made perfectly plastic

    NAMES = {1: "impact", 2: "separation", 3: "lift", 4: "reload", 5: "plastic"}


_STATUS = {0: "ok", 2: "state became NaN or infinite", 3: "too many events (unresolved Zeno cascade)",
           4: "step size underflow", 5: "event buffer full"}
_BUFFER_FULL = 5

_EVENT_DTYPE = np.dtype([("t", "f8"), ("v", "f8"), ("kind", "i8"), ("side", "i8")])


class _Params(ctypes.Structure):
    _fields_ = [(n, ctypes.c_double) for n in (
        "J1", "J2", "rb1", "rb2", "b", "k", "c", "d1", "d2", "tc1", "tc2", "ws", "mesh_period",
        "mesh_phase", "zeno_v", "rtol", "atol_angle", "atol_rate", "h_max")] + [
        ("A", ctypes.c_double * 32), ("Phi", ctypes.c_double * 32), ("Gam", ctypes.c_double * 32),
        ("h", ctypes.c_double * 2), ("rho", ctypes.c_double * 2),
        ("table", ctypes.POINTER(ctypes.c_double)), ("n_table", ctypes.c_long),
        ("max_events", ctypes.c_long), ("law", ctypes.c_int), ("kind", ctypes.c_int)]


class _State(ctypes.Structure):
    _fields_ = [("x", ctypes.c_double * 4), ("t", ctypes.c_double), ("d_ys", ctypes.c_double),
                ("h_ode", ctypes.c_double), ("max_pen", ctypes.c_double), ("n_events", ctypes.c_long),
                ("n_steps", ctypes.c_long), ("mode", ctypes.c_int),
                ("u1", ctypes.c_double), ("u2", ctypes.c_double), ("T", ctypes.c_double),
                ("ev", ctypes.c_void_p), ("cap", ctypes.c_long)]


# --- compilation -----------------------------------------------------------------------------------------

_LIB: ctypes.CDLL | None | bool = False  # False: not tried yet


def cache_dir() -> Path:
    """Per-user folder of gearctl's compiled code (``$XDG_CACHE_HOME/gearctl`` or ``~/.cache/gearctl``)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "gearctl"


def c_compiler() -> str | None:
    """The C compiler to build gearctl's compiled code with, or None where there is none."""
    cc = os.environ.get("CC") or (sysconfig.get_config_var("CC") or "cc").split()[0]
    for cand in (cc, "cc", "gcc", "clang"):
        if shutil.which(cand):
            return cand
    return None


def _load() -> ctypes.CDLL | None:
    """Compile (once per source version) and load the C kernel; None where that is not possible."""
    global _LIB
    if _LIB is not False:
        return _LIB  # type: ignore[return-value]
    _LIB = None
    if os.environ.get("GEARCTL_NO_COMPILE"):
        return None
    src = _SRC.read_bytes()
    tag = hashlib.sha256(src + sys.version.encode()).hexdigest()[:16]
    suffix = ".dll" if sys.platform == "win32" else ".so"
    target = cache_dir() / f"kernel-{tag}{suffix}"
    if not target.exists():
        cc = c_compiler()
        if cc is None:
            return None
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
                out = Path(tmp) / target.name
                subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(out), str(_SRC), "-lm"],
                               check=True, capture_output=True, timeout=120)
                os.replace(out, target)  # atomic: parallel processes may race here
        except (OSError, subprocess.SubprocessError):
            return None
    try:
        lib = ctypes.CDLL(str(target))
    except OSError:
        return None
    for fn in (lib.gc_advance_pwl, lib.gc_advance_ode):
        fn.restype = ctypes.c_int
        fn.argtypes = [ctypes.POINTER(_Params), ctypes.POINTER(_State), ctypes.c_double, ctypes.c_double,
                       ctypes.c_double, ctypes.c_void_p, ctypes.c_long]
    lib.gc_step.restype = ctypes.c_int
    lib.gc_step.argtypes = [ctypes.POINTER(_Params), ctypes.POINTER(_State)]
    lib.gc_run.restype = ctypes.c_int
    lib.gc_run.argtypes = [ctypes.POINTER(_Params), ctypes.POINTER(_State), ctypes.c_double, ctypes.c_double,
                           ctypes.c_double, ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p,
                           ctypes.c_void_p, ctypes.c_long, ctypes.POINTER(ctypes.c_long)]
    _LIB = lib
    return lib


def compiled_available() -> bool:
    """Whether the compiled kernel could be built and loaded on this machine."""
    return _load() is not None


# --- linear data of the improved plant -----------------------------------------------------------------


def contact_matrices(plant: Plant) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """State matrices of the improved plant: ``(A_contact, A_free, B)``.

    ``x' = A x + B u + e`` in each mode, with ``e`` the constant ``+-k b`` term of the contact modes.
    Shared by the kernel and :mod:`gearctl.modes`.
    """
    p = plant
    k, c = p.k, p.c
    A_free = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [0, 0, -p.d1 / p.J1, 0], [0, 0, 0, -p.d2 / p.J2]], float)
    A_contact = A_free.copy()
    A_contact[2] += np.array([-k * p.rb1**2, k * p.rb1 * p.rb2, -c * p.rb1**2, c * p.rb1 * p.rb2]) / p.J1
    A_contact[3] += np.array([k * p.rb1 * p.rb2, -k * p.rb2**2, c * p.rb1 * p.rb2, -c * p.rb2**2]) / p.J2
    B = np.array([[0, 0], [0, 0], [1 / p.J1, 0], [0, 1 / p.J2]], float)
    return A_contact, A_free, B


def _propagators(A: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """``Phi(h) = e^{A h}`` and ``Gamma(h) = int_0^h e^{A t} dt`` (cached: a bench builds the same ones often)."""
    return _propagators_cached(A.tobytes(), h)


@functools.lru_cache(maxsize=256)
def _propagators_cached(A_bytes: bytes, h: float) -> tuple[np.ndarray, np.ndarray]:
    M = np.zeros((8, 8))
    M[:4, :4] = np.frombuffer(A_bytes).reshape(4, 4)
    M[:4, 4:] = np.eye(4)
    E = scipy.linalg.expm(M * h)
    Phi, Gam = E[:4, :4].copy(), E[:4, 4:].copy()
    Phi.flags.writeable = False
    Gam.flags.writeable = False
    return Phi, Gam


# --- the kernel object ----------------------------------------------------------------------------------


@dataclasses.dataclass
class Kernel:
    """A plant's simulation state and the solver that advances it.

    Parameters
    ----------
    plant : Plant
        The plant.
    x0 : array_like, shape (4,)
        Initial state ``[theta1, theta2, omega1, omega2]``.
    dt : float
        The usual interval of one :meth:`advance` call [s] (a controller's sample time, an output
        step); sub-steps are chosen to divide it.
    rtol : float
        Relative tolerance of the nonlinear solver (the exact solver needs none).
    compiled : bool or None
        Force the compiled (True) or Python (False) path; None: compiled where available.
    max_events : int
        Events one :meth:`advance` call may locate before it gives up (Zeno guard).
    zeno_velocity : float
        Impacts slower than this are made perfectly plastic [m/s].
    t0 : float
        Initial time [s].
    """

    plant: Plant
    x0: np.ndarray
    dt: float
    rtol: float = 1e-9
    compiled: bool | None = None
    max_events: int = 200_000
    zeno_velocity: float = ZENO_VELOCITY
    t0: float = 0.0

    def __post_init__(self) -> None:
        p = self.plant
        self.exact = p.is_piecewise_linear
        lib = _load() if self.compiled in (None, True) else None
        if self.compiled and lib is None:
            raise RuntimeError("the compiled kernel is not available (no C compiler?)")
        self._lib = lib
        prm = _Params()
        for name, val in (("J1", p.J1), ("J2", p.J2), ("rb1", p.rb1), ("rb2", p.rb2), ("b", p.backlash),
                          ("k", p.k), ("c", p.c), ("d1", p.d1), ("d2", p.d2), ("tc1", p.tc1), ("tc2", p.tc2),
                          ("ws", p.coulomb_velocity), ("mesh_period", p.mesh_period),
                          ("mesh_phase", p.mesh_phase), ("zeno_v", self.zeno_velocity), ("rtol", self.rtol)):
            setattr(prm, name, float(val))
        # absolute tolerances: 1e-9 of the backlash (or of 1 um) in s, carried to the angles and rates
        scale = max(p.backlash, 1e-6) * 1e-9 / max(p.rb1, p.rb2)
        prm.atol_angle = scale
        prm.atol_rate = scale * p.natural_frequency
        prm.h_max = 0.25 * 2 * math.pi / math.sqrt(p.k * (p.rb1**2 / p.J1 + p.rb2**2 / p.J2))
        Ac, Af, self.B = contact_matrices(p)
        self._A = (Ac, Af)
        self._h = [0.0, 0.0]
        self._rho = [0.0, 0.0]
        for i, (A, lim) in enumerate(((Ac, 0.6), (Af, 0.5))):
            rho = float(np.max(np.abs(np.linalg.eigvals(A))))
            hmax = lim / rho if rho > 0 else math.inf
            n = max(1, math.ceil(self.dt / hmax - 1e-9))
            h = self.dt / n
            Phi, Gam = _propagators(A, h)
            prm.A[16 * i:16 * i + 16] = A.ravel().tolist()
            prm.Phi[16 * i:16 * i + 16] = Phi.ravel().tolist()
            prm.Gam[16 * i:16 * i + 16] = Gam.ravel().tolist()
            prm.h[i] = h
            prm.rho[i] = rho
            self._h[i], self._rho[i] = h, rho
            if i == 0:
                self._Phi, self._Gam = [Phi, None], [Gam, None]
            else:
                self._Phi[1], self._Gam[1] = Phi, Gam
        self._table = np.ascontiguousarray(p.kv_table if p.kv_table is not None else np.zeros(1))
        prm.table = self._table.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        prm.n_table = self._table.size
        prm.max_events = self.max_events
        prm.law = 1 if p.contact_law.value == "no_pull" else 0
        prm.kind = {PlantKind.IMPROVED: 0, PlantKind.YANG_SUN: 1, PlantKind.TVMS: 2}[p.kind]
        self._prm = prm
        st = _State()
        x0 = np.asarray(self.x0, dtype=float)
        if x0.shape != (4,) or not np.all(np.isfinite(x0)):
            from .errors import InputError

            raise InputError(f"x0 = {x0.tolist()!r} is not an initial state: expected 4 finite numbers "
                             f"[rad, rad, rad/s, rad/s]", field="x0")
        st.x[:] = x0.tolist()
        st.t = self.t0
        st.h_ode = 0.0
        st.mode = self.classify(x0)
        if not self.exact and st.mode != 0:  # a run that starts in contact: Yang-Sun's d from zero speed
            st.d_ys = _ys_damping(p, 0.0)
        self._st = st
        self._cap = 4096
        self._ev = np.zeros(self._cap, dtype=_EVENT_DTYPE)
        self.events: list[tuple[float, int, int, float]] = []
        self._fn = None
        if lib is not None:
            self._fn = lib.gc_advance_pwl if self.exact else lib.gc_advance_ode
            self._step = lib.gc_step
            self._pp, self._sp = ctypes.byref(prm), ctypes.byref(st)
            self._evp = self._ev.ctypes.data
            st.ev, st.cap = self._evp, self._cap

    # -- state access
    @property
    def x(self) -> np.ndarray:
        """Current state ``[theta1, theta2, omega1, omega2]``."""
        return np.array(self._st.x[:])

    @property
    def t(self) -> float:
        """Current time [s]."""
        return self._st.t

    @property
    def mode(self) -> int:
        """Current solver mode: -2, -1, 0, 1, 2 (±2: flanks overlapping without load, no_pull law)."""
        return self._st.mode

    @property
    def max_penetration(self) -> float:
        """Largest ``|s| - b`` so far [m] (0 if never in contact)."""
        return max(0.0, self._st.max_pen)

    @property
    def steps(self) -> int:
        """Sub-steps taken so far."""
        return self._st.n_steps

    @property
    def path(self) -> str:
        """``"compiled"`` or ``"python"``."""
        return "compiled" if self._fn is not None else "python"

    def classify(self, x: np.ndarray) -> int:
        """Contact mode of a state (``no_pull`` unloaded overlap as ±2 for the exact solver)."""
        p = self.plant
        s = p.rb1 * x[0] - p.rb2 * x[1]
        v = p.rb1 * x[2] - p.rb2 * x[3]
        b = p.backlash
        side = 1 if (s > b or (b == 0.0 and s == 0.0 and v >= 0.0)) else (-1 if (s < -b or (b == 0 and s == 0))
                                                                           else 0)
        if side and self.exact and p.contact_law.value == "no_pull":
            F = p.k * (side * s - b) + p.c * side * v
            if F <= 0.0:
                return 2 * side
        return side

    def set_state(self, x: np.ndarray) -> None:
        """Replace the state (e.g. a disturbance); the mode is re-classified."""
        self._st.x[:] = [float(v) for v in x]
        self._st.mode = self.classify(np.asarray(x, float))

    def advance(self, u1: float, u2: float, T: float) -> int:
        """Advance by ``T`` seconds with constant torques ``u1``, ``u2`` [N m]; return a status code.

        0 is success; events are appended to :attr:`events` as ``(t, kind, side, v)``.
        """
        if self._fn is not None:
            st = self._st
            t_end = st.t + T
            st.u1, st.u2, st.T = u1, u2, T
            status = self._step(self._pp, self._sp)  # two pointer arguments: the cheapest ctypes call
            while True:
                if st.n_events:
                    self._drain(min(st.n_events, self._cap))
                if status != _BUFFER_FULL:
                    return status
                st.T = t_end - st.t
                status = self._step(self._pp, self._sp)
        if self.exact:
            return _py_advance_pwl(self, u1, u2, T)
        return _py_advance_ode(self, u1, u2, T)

    def _drain(self, n: int) -> None:
        ev = self._ev[:n]
        self.events.extend(zip(ev["t"].tolist(), ev["kind"].tolist(), ev["side"].tolist(), ev["v"].tolist(),
                               strict=True))

    def run(self, u1: float, u2: float, dt: float, n: int) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
        """Advance ``n`` intervals of ``dt`` with constant torques; return ``(status, x, mode, d_ys)``.

        ``x`` has shape ``(4, m)`` with the state after each completed interval (``m <= n``; fewer on
        failure). One call into the compiled kernel for the whole run where available.
        """
        if self._fn is None:
            xs, modes, dys = np.empty((4, n)), np.empty(n, dtype=int), np.empty(n)
            status = 0
            for i in range(n):
                status = self.advance(u1, u2, dt)
                xs[:, i], modes[i], dys[i] = self._st.x, self._st.mode, self._st.d_ys
                if status or abs(xs[2, i]) > 1e6 or abs(xs[3, i]) > 1e6:
                    return status, xs[:, : i + 1], modes[: i + 1], dys[: i + 1]
            return status, xs, modes, dys
        out = np.empty((n, 4))
        modes = np.empty(n, dtype=np.intc)
        dys = np.empty(n)
        done = ctypes.c_long(0)
        m, t0 = 0, self._st.t
        status = 0
        while m < n:
            status = self._lib.gc_run(self._pp, self._sp, u1, u2, dt, n - m, out[m:].ctypes.data,
                                      modes[m:].ctypes.data, dys[m:].ctypes.data, self._evp, self._cap,
                                      ctypes.byref(done))
            self._drain(min(self._st.n_events, self._cap))
            m += done.value
            if status != _BUFFER_FULL:
                break
            # the buffer filled inside interval m: finish it event by event, then go on
            status = self.advance(u1, u2, t0 + (m + 1) * dt - self._st.t)
            out[m], modes[m], dys[m] = self._st.x[:], self._st.mode, self._st.d_ys
            m += 1
            if status != 0:
                break
        return status, out[:m].T.copy(), modes[:m].astype(int), dys[:m]

    @staticmethod
    def status_message(status: int) -> str:
        """Words for a status code of :meth:`advance`."""
        return _STATUS.get(status, f"status {status}")


def _ys_damping(p: Plant, v: float) -> float:
    from .stiffness import yang_sun_damping_factor

    return yang_sun_damping_factor(p.k, v)


# --- the pure-Python mirror of _kernel.c ------------------------------------------------------------------
# Written to follow the C line by line, so both paths give the same answers (tests compare them).

_NTAY = 48


def _mv(M: np.ndarray, x: list[float]) -> list[float]:
    return [M[i, 0] * x[0] + M[i, 1] * x[1] + M[i, 2] * x[2] + M[i, 3] * x[3] for i in range(4)]


def _event_functions(kn: Kernel, mode: int) -> list[tuple[list[float], float, int]]:
    p = kn.plant
    sv = [p.rb1, -p.rb2, 0.0, 0.0]
    vv = [0.0, 0.0, p.rb1, -p.rb2]
    no_pull = kn._prm.law == 1
    k, c, b = p.k, p.c, p.backlash
    if mode == 0:
        return [([-x for x in sv], b, 1), (sv[:], b, -1)]
    out = []
    if mode in (1, 2):
        out.append((sv[:], -b, 0))
        if no_pull:
            sg = 1.0 if mode == 1 else -1.0
            out.append(([sg * (k * sv[i] + c * vv[i]) for i in range(4)], -sg * k * b, 2 if mode == 1 else 1))
    else:
        out.append(([-x for x in sv], -b, 0))
        if no_pull:
            sg = 1.0 if mode == -1 else -1.0
            out.append(([-sg * (k * sv[i] + c * vv[i]) for i in range(4)], -sg * k * b, -2 if mode == -1 else -1))
    return out


def _transition(kn: Kernel, mode: int, target: int, x: list[float], t: float) -> int:
    p = kn.plant
    v = p.rb1 * x[2] - p.rb2 * x[3]
    side = int(math.copysign(1, mode if mode != 0 else target))
    if target == 0:
        if p.backlash > 0.0 or p.k <= 0.0:
            kn.events.append((t, EventKind.SEPARATION, side, v))
            return 0
        if kn._prm.law == 1:
            s = p.rb1 * x[0] - p.rb2 * x[1]
            fb = -side * (p.k * s + p.c * v)
            return -side if fb > 0.0 else -2 * side
        return -side
    if mode == 0:
        if abs(v) < kn.zeno_velocity:
            inv_m = p.rb1**2 / p.J1 + p.rb2**2 / p.J2
            P = v / inv_m
            x[2] -= p.rb1 * P / p.J1
            x[3] += p.rb2 * P / p.J2
            kn.events.append((t, EventKind.PLASTIC, side, v))
        else:
            kn.events.append((t, EventKind.IMPACT, side, v))
        return target
    kn.events.append((t, EventKind.RELOAD if target in (1, -1) else EventKind.LIFT, side, v))
    return target


def _affine(kn: Kernel, mode: int, u1: float, u2: float) -> list[float]:
    p = kn.plant
    a = [0.0, 0.0, u1 / p.J1, u2 / p.J2]
    if mode in (1, -1):
        a[2] += p.rb1 * p.k * mode * p.backlash / p.J1
        a[3] -= p.rb2 * p.k * mode * p.backlash / p.J2
    return a


def _taylor(A: np.ndarray, rho: float, x0: list[float], a: list[float], tmax: float) -> list[list[float]]:
    D = [list(x0)]
    t = _mv(A, x0)
    D.append([t[i] + a[i] for i in range(4)])
    bound = rho * tmax
    term = bound
    for n in range(2, _NTAY):
        t = _mv(A, D[n - 1])
        D.append([v / n for v in t])
        term *= bound / n
        if term < 1e-18 and n >= 4:
            break
    return D


def _taylor_eval(D: list[list[float]], tau: float) -> list[float]:
    out = []
    for i in range(4):
        acc = D[-1][i]
        for n in range(len(D) - 2, -1, -1):
            acc = acc * tau + D[n][i]
        out.append(acc)
    return out


def _poly(q: list[float], tau: float) -> tuple[float, float]:
    acc, dacc = q[-1], 0.0
    for n in range(len(q) - 2, -1, -1):
        dacc = dacc * tau + acc
        acc = acc * tau + q[n]
    return acc, dacc


def _poly_root(q: list[float], lo: float, hi: float) -> float:
    x = 0.5 * (lo + hi)
    for _ in range(100):
        f, df = _poly(q, x)
        if f > 0.0:
            lo = x
        else:
            hi = x
        xn = x - f / df if df != 0.0 else 0.5 * (lo + hi)
        if not (lo < xn < hi):
            xn = 0.5 * (lo + hi)
        if hi - lo <= 4e-16 * abs(hi) + 1e-300 or xn == x:
            break
        x = xn
    return hi


def _first_root(q: list[float], h: float, g1: float, dg0: float, dg1: float) -> float:
    if dg0 < 0.0 and dg1 > 0.0:
        dq = [(n + 1) * q[n + 1] for n in range(len(q) - 1)]
        lo, hi = 0.0, h
        for _ in range(200):
            if hi - lo <= 1e-15 * h:
                break
            x = 0.5 * (lo + hi)
            f, _ = _poly(dq, x)
            if f < 0.0:
                lo = x
            else:
                hi = x
        gm, _ = _poly(q, hi)
        if gm <= 0.0:
            return _poly_root(q, 0.0, hi)
        return _poly_root(q, hi, h) if g1 <= 0.0 else -1.0
    return _poly_root(q, 0.0, h) if g1 <= 0.0 else -1.0


def _py_advance_pwl(kn: Kernel, u1: float, u2: float, T: float) -> int:
    st, p = kn._st, kn.plant
    x = list(st.x)
    t = st.t
    mode = st.mode
    t_end = t + T
    n_before = len(kn.events)
    guard = 0
    max_pen = st.max_pen
    steps = 0
    status = 0
    while t < t_end:
        dyn = 0 if mode in (1, -1) else 1
        A = kn._A[dyn]
        a = _affine(kn, mode, u1, u2)
        x0 = x
        remaining = t_end - t
        h = kn._h[dyn]
        lands = abs(remaining - h) <= 1e-9 * h
        D = None
        if lands or remaining > h:
            x1 = [u + w for u, w in zip(_mv(kn._Phi[dyn], x0), _mv(kn._Gam[dyn], a), strict=True)]
        else:
            h = remaining
            lands = True
            D = _taylor(A, kn._rho[dyn], x0, a, h)
            x1 = _taylor_eval(D, h)
        dx0 = [u + w for u, w in zip(_mv(A, x0), a, strict=True)]
        dx1 = [u + w for u, w in zip(_mv(A, x1), a, strict=True)]
        best, which, target = -1.0, -1, 0
        no_events = p.backlash == 0.0 and kn._prm.law == 0  # one linear system on both flanks
        for cg, g0, tgt in ([] if no_events else _event_functions(kn, mode)):
            ga = g0 + sum(cg[i] * x0[i] for i in range(4))
            gb = g0 + sum(cg[i] * x1[i] for i in range(4))
            da = sum(cg[i] * dx0[i] for i in range(4))
            db = sum(cg[i] * dx1[i] for i in range(4))
            ga = max(ga, 0.0)
            if ga == 0.0 and abs(da) <= 1e-12 * sum(abs(cg[i] * dx0[i]) for i in range(4)):
                da = 0.0  # zero up to cancellation (see _kernel.c)
            if not (gb <= 0.0 or (da < 0.0 and db > 0.0) or (ga == 0.0 and da <= 0.0)):
                continue
            if ga == 0.0 and (da < 0.0 or (da == 0.0 and db < 0.0)):
                tau = 0.0
            else:
                if D is None:
                    D = _taylor(A, kn._rho[dyn], x0, a, h)
                q = [sum(cg[i] * Dn[i] for i in range(4)) for Dn in D]
                q[0] = ga
                tau = _first_root(q, h, gb, da, db)
            if tau >= 0.0 and (which < 0 or tau < best - 1e-12 * h):
                best, which, target = tau, 1, tgt
        steps += 1
        if which < 0:
            x = x1
            t = t_end if lands else t + h
            if no_events:
                mode = 1 if p.rb1 * x[0] - p.rb2 * x[1] >= 0.0 else -1
        else:
            if D is None:
                D = _taylor(A, kn._rho[dyn], x0, a, h)
            x = _taylor_eval(D, best)
            t = min(t + best, t_end)
            new = _transition(kn, mode, target, x, t)
            if len(kn.events) - n_before > kn.max_events or (guard := guard + 1) > 4 * kn.max_events:
                mode = new
                status = 3
                break
            if mode in (1, -1):
                max_pen = max(max_pen, abs(p.rb1 * x[0] - p.rb2 * x[1]) - p.backlash)
            mode = new
            continue
        if mode in (1, -1):
            s1 = p.rb1 * x1[0] - p.rb2 * x1[1]
            max_pen = max(max_pen, abs(s1) - p.backlash)
            va, vb = p.rb1 * x0[2] - p.rb2 * x0[3], p.rb1 * x1[2] - p.rb2 * x1[3]
            if va * vb < 0.0:
                sa = p.rb1 * x0[0] - p.rb2 * x0[1]
                th = va / (va - vb)
                h00, h10 = 2 * th**3 - 3 * th**2 + 1, th**3 - 2 * th**2 + th
                h01, h11 = -2 * th**3 + 3 * th**2, th**3 - th**2
                sm = h00 * sa + h10 * h * va + h01 * s1 + h11 * h * vb
                max_pen = max(max_pen, abs(sm) - p.backlash)
        if not all(math.isfinite(v) for v in x):
            status = 2
            break
    st.x[:] = x
    st.t = t
    st.mode = mode
    st.max_pen = max_pen
    st.n_steps += steps
    return status


# Dormand–Prince 5(4)
_A21 = 0.2
_A31, _A32 = 3 / 40, 9 / 40
_A41, _A42, _A43 = 44 / 45, -56 / 15, 32 / 9
_A51, _A52, _A53, _A54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
_A61, _A62, _A63, _A64, _A65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
_A71, _A73, _A74, _A75, _A76 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84
_E1, _E3, _E4, _E5, _E6, _E7 = 71 / 57600, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40
_D1, _D3, _D4 = -12715105075 / 11282082432, 87487479700 / 32700410799, -10690763975 / 1880347072
_D5, _D6, _D7 = 701980252875 / 199316789632, -1453857185 / 822651844, 69997945 / 29380423


def _force(kn: Kernel, mode: int, d_ys: float, x: list[float]) -> float:
    p = kn.plant
    if mode == 0:
        return 0.0
    s = p.rb1 * x[0] - p.rb2 * x[1]
    v = p.rb1 * x[2] - p.rb2 * x[3]
    sigma = 1.0 if mode > 0 else -1.0
    delta, ddelta = sigma * s - p.backlash, sigma * v
    if kn._prm.kind == 1:
        F = (d_ys * ddelta + p.k) * delta
    else:
        kk = float(p.stiffness_at(x[0])) if kn._prm.kind == 2 else p.k
        F = kk * delta + p.c * ddelta
    if kn._prm.law == 1 and F < 0.0:
        F = 0.0
    return sigma * F


def _rhs(kn: Kernel, mode: int, d_ys: float, u1: float, u2: float, x: list[float]) -> list[float]:
    p = kn.plant
    F = _force(kn, mode, d_ys, x)
    f1 = p.d1 * x[2]
    f2 = p.d2 * x[3]
    if p.tc1 > 0.0:
        f1 += p.tc1 * math.tanh(x[2] / p.coulomb_velocity)
    if p.tc2 > 0.0:
        f2 += p.tc2 * math.tanh(x[3] / p.coulomb_velocity)
    return [x[2], x[3], (u1 - p.rb1 * F - f1) / p.J1, (u2 + p.rb2 * F - f2) / p.J2]


def _py_advance_ode(kn: Kernel, u1: float, u2: float, T: float) -> int:
    st, p, prm = kn._st, kn.plant, kn._prm
    y = list(st.x)
    t = st.t
    mode = 1 if st.mode > 0 else (-1 if st.mode < 0 else 0)
    d_ys = st.d_ys
    t_end = t + T
    n_before = len(kn.events)
    h = st.h_ode if st.h_ode > 0.0 else prm.h_max * 0.1
    k1 = None
    rejects = 0
    steps = 0
    max_pen = st.max_pen
    sv = [p.rb1, -p.rb2, 0.0, 0.0]
    status = 0

    def stage(coefs: list[tuple[float, list[float]]]) -> list[float]:
        return [y[i] + h * sum(c * k[i] for c, k in coefs) for i in range(4)]

    while t < t_end:
        if k1 is None:
            k1 = _rhs(kn, mode, d_ys, u1, u2, y)
        h = min(h, prm.h_max)
        last = False
        if t + h >= t_end - 1e-15 * abs(t_end):
            h = t_end - t
            last = True
        k2 = _rhs(kn, mode, d_ys, u1, u2, stage([(_A21, k1)]))
        k3 = _rhs(kn, mode, d_ys, u1, u2, stage([(_A31, k1), (_A32, k2)]))
        k4 = _rhs(kn, mode, d_ys, u1, u2, stage([(_A41, k1), (_A42, k2), (_A43, k3)]))
        k5 = _rhs(kn, mode, d_ys, u1, u2, stage([(_A51, k1), (_A52, k2), (_A53, k3), (_A54, k4)]))
        k6 = _rhs(kn, mode, d_ys, u1, u2, stage([(_A61, k1), (_A62, k2), (_A63, k3), (_A64, k4), (_A65, k5)]))
        y1 = stage([(_A71, k1), (_A73, k3), (_A74, k4), (_A75, k5), (_A76, k6)])
        k7 = _rhs(kn, mode, d_ys, u1, u2, y1)
        err = 0.0
        for i in range(4):
            sk = (prm.atol_angle if i < 2 else prm.atol_rate) + prm.rtol * max(abs(y[i]), abs(y1[i]))
            ei = h * (_E1 * k1[i] + _E3 * k3[i] + _E4 * k4[i] + _E5 * k5[i] + _E6 * k6[i] + _E7 * k7[i]) / sk
            err += ei * ei
        err = math.sqrt(err / 4.0)
        if not math.isfinite(err):
            status = 2
            break
        fac = min(5.0, 0.9 * err**-0.2) if err > 0.0 else 5.0
        if err > 1.0:
            h *= max(fac, 0.2)
            rejects += 1
            if rejects > 100000 or h < 1e-16 * (abs(t) + 1e-9):
                status = 4
                break
            continue
        steps += 1
        if mode == 0:
            evs = [([-v for v in sv], p.backlash, 1), (sv, p.backlash, -1)]
        else:
            evs = [([mode * v for v in sv], -p.backlash, 0)]
        best, which, target = 2.0, -1, 0
        r = None
        for cg, g0, tgt in evs:
            ga = g0 + sum(cg[i] * y[i] for i in range(4))
            gb = g0 + sum(cg[i] * y1[i] for i in range(4))
            if not gb <= 0.0 or ga < 0.0:
                continue
            if r is None:
                r1 = [y1[i] - y[i] for i in range(4)]
                r2 = [h * k1[i] - r1[i] for i in range(4)]
                r3 = [r1[i] - h * k7[i] - r2[i] for i in range(4)]
                r4 = [h * (_D1 * k1[i] + _D3 * k3[i] + _D4 * k4[i] + _D5 * k5[i] + _D6 * k6[i] + _D7 * k7[i])
                      for i in range(4)]
                r = (y, r1, r2, r3, r4)

            def dense(th: float, r=r) -> list[float]:
                return [r[0][i] + th * (r[1][i] + (1 - th) * (r[2][i] + th * (r[3][i] + (1 - th) * r[4][i])))
                        for i in range(4)]

            lo, hi, flo, fhi = 0.0, 1.0, ga, gb
            if ga == 0.0:
                lo = 1e-12
                flo = g0 + sum(cg[i] * v for i, v in enumerate(dense(lo)))
                if flo <= 0.0:
                    best, which, target = 0.0, 1, tgt
                    break
            it = 0
            while it < 200 and hi - lo > 1e-15:
                th = hi - fhi * (hi - lo) / (fhi - flo)
                if not (lo < th < hi):
                    th = 0.5 * (lo + hi)
                ft = g0 + sum(cg[i] * v for i, v in enumerate(dense(th)))
                if ft > 0.0:
                    lo, flo, fhi = th, ft, fhi * 0.5
                else:
                    hi, fhi, flo = th, ft, flo * 0.5
                it += 1
            if hi < best:
                best, which, target = hi, 1, tgt
        if which >= 0:
            th = best
            y = [r[0][i] + th * (r[1][i] + (1 - th) * (r[2][i] + th * (r[3][i] + (1 - th) * r[4][i])))
                 for i in range(4)]
            t += best * h
            nm = _transition(kn, mode, target, y, t)
            nm = 1 if nm > 0 else (-1 if nm < 0 else 0)
            if prm.kind == 1 and nm != 0:
                d_ys = _ys_damping(p, abs(p.rb1 * y[2] - p.rb2 * y[3]))
            mode = nm
            k1 = None
            if len(kn.events) - n_before > kn.max_events:
                status = 3
                break
        else:
            y = y1
            k1 = k7
            t = t_end if last else t + h
            if not last:
                st.h_ode = h * fac
            h *= fac
        if mode != 0:
            max_pen = max(max_pen, abs(p.rb1 * y[0] - p.rb2 * y[1]) - p.backlash)
        if not all(math.isfinite(v) for v in y):
            status = 2
            break
    st.x[:] = y
    st.t = t
    st.mode = mode
    st.d_ys = d_ys
    st.max_pen = max_pen
    st.n_steps += steps
    return status
