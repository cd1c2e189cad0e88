"""The simulation kernel: advance a gear train over an interval of constant torque, events located.

Two paths with one algorithm:

- compiled: ``_kernel.c`` built on first use with the system C compiler (:mod:`gearctl.build`) and
  called through :mod:`ctypes`;
- pure Python: the same algorithm written out below, used where no C compiler is present (or with
  ``GEARCTL_NO_COMPILE=1``) and as the oracle the tests compare the compiled path against.

The dynamics are not written here: :mod:`gearctl.plant` gives them as data (the matrix of each contact
pattern, the affine terms, the mode boundaries as linear event functions), which both paths integrate.
The improved plant is affine inside each pattern, ``x' = A x + a``, so its solution between events is
exact: full sub-steps apply the propagators ``Phi(h) = e^{A h}`` and ``Gamma(h) = int_0^h e^{A t} dt``,
built the first time a pattern is visited and cached; partial steps and event roots use the Taylor series
of the same solution, summed to 1e-17. Sub-steps are short enough (``rho h <= 0.6`` for a pattern with
contact) that a crossing between grid points shows as a sign change or as an interior minimum of the cubic
Hermite model, and is then found to machine precision on the series. On a train (two stages or more) the
fastest mesh mode makes those sub-steps many (about 200 per 1 ms sample on the three-stage catalog train),
so the solver first tries a *long step* of 2, 4, 8, ... sub-steps or the whole interval, exact with its own
propagators, which it takes only where a certificate proves that no event function of the current modes
reaches zero inside it (:func:`_long_data` gives the bound and why it is rigorous); where the certificate
refuses, the sub-steps above locate the event. A pair never takes long steps: its results are those of the
sub-steps, bit for bit. The nonlinear plants (Yang–Sun, time-varying stiffness, the smooth Coulomb law)
use Dormand–Prince 5(4) with error control and locate events on its dense output.

Shift invariance: the dynamics depend on the gaps and the speeds, not on how far the shafts have turned,
and so do the results. Each call integrates relative to an origin, the load angle rounded to a whole
:data:`ORIGIN_QUANTUM` carried to every shaft by the stages' ratios (every gap unchanged), and adds it back
at the end: sums over the angles (a stuck shaft's held torque and its rounding band, the event functions,
the propagators, the ODE's error norm) see angles of at most half a radian plus one call's travel, and not
``k rb^2 theta`` terms that cancel (at 3e4 rad the band exceeded a servo's break-away margin and the load
never moved). While the load stays within half a radian of zero the origin is zero (the results are those
of absolute coordinates, bit for bit); a run offset by whole radians is the run at zero with its angles
stored at the offset's precision, bit for bit (``tests/test_kernel_offset.py``). The time-varying stiffness
reads its mesh phase from the absolute angle (the origin added back).

The C structs are generated from :data:`PARAMS_FIELDS` and :data:`STATE_FIELDS` (one description, read by
both the C source and its :mod:`ctypes` mirror).

Bounded by construction: the events one :meth:`Kernel.advance` may locate are capped (``max_events``),
so are the events of a whole run per simulated second (``max_event_rate``), and the events kept in detail
(``max_records``; the counts per stage and flank stay exact beyond); every long step moves time on by at
least two sub-steps, and the long tries after a refusal are spaced out. Grazing contacts (a flank reached
with no relative speed and no acceleration to speak of) stay on their side instead of chattering.
"""

from __future__ import annotations

import ctypes
import dataclasses
import functools
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, cast

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from .build import c_compiler, cache_dir, compile_disabled, shared_library
from .errors import InputError
from .params import ContactLaw, FrictionLaw
from .plant import (
    EVENT_FORCE,
    EVENT_GEOMETRIC,
    MAX_STAGES,
    Plant,
    PlantKind,
    affine_terms,
    event_table,
    force_coefficients,
    input_matrix,
    mode_matrices,
)
from .stiffness import yang_sun_damping_factor
from .units import OUTPUT_INTERVAL

__all__ = [
    "Kernel", "EventKind", "compiled_available", "contact_matrices", "ZENO_VELOCITY", "cache_dir", "c_compiler",
    "EVENT_DTYPE", "COUNT_NAMES",
]

#: Impacts slower than this along the line of action are made perfectly plastic (the Zeno rule) [m/s].
ZENO_VELOCITY = 1e-6

#: Each call integrates relative to the load angle rounded to a multiple of this, carried to every shaft by
#: the ratios (``gc_step`` in ``_kernel.c``): the results do not depend on how far the axis has turned [rad].
ORIGIN_QUANTUM = 1.0

_SRC = Path(__file__).with_name("_kernel.c")


class EventKind:
    """Codes of the events the kernel records."""

    IMPACT = 1
    SEPARATION = 2
    LIFT = 3  # no_pull: contact force reached zero while the flanks still overlap
    RELOAD = 4
    PLASTIC = 5  # an impact below ZENO_VELOCITY, made perfectly plastic
    STICK = 6  # a shaft with stick-slip friction stopped and sticks (``where`` is the shaft)
    SLIP = 7  # a stuck shaft broke away

    NAMES = {1: "impact", 2: "separation", 3: "lift", 4: "reload", 5: "plastic", 6: "stick", 7: "slip"}


_STATUS = {0: "ok", 2: "state became NaN or infinite", 3: "too many events (unresolved Zeno cascade)",
           4: "step size underflow", 5: "event buffer full", 6: "pattern missing"}
_ST_EVENTS, _BUFFER_FULL, _PATTERN = 3, 5, 6

#: One recorded event: time, relative velocity (or the holding torque of a stick), kind, side, stage/shaft.
EVENT_DTYPE = np.dtype([("t", "f8"), ("v", "f8"), ("kind", "i8"), ("side", "i8"), ("where", "i8")])

#: Counters kept per stage by both paths (exact whatever ``max_records``).
COUNT_NAMES = ("impacts_front", "impacts_back", "plastic_front", "plastic_back", "separations", "other")
_NCOUNT = len(COUNT_NAMES)
_CT_IMPACT = {1: 0, -1: 1}
_CT_PLASTIC = {1: 2, -1: 3}
_NX_MAX = 2 * (MAX_STAGES + 1)

# --- the one description of the C structs ---------------------------------------------------------------------

PARAMS_FIELDS: tuple[tuple[str, str], ...] = (
    ("nx", "gc_int"), ("ns", "gc_int"), ("nsh", "gc_int"), ("max_events", "gc_int"),
    ("law", "int"), ("kind", "int"), ("friction", "int"), ("exact", "int"),
    ("zeno_v", "double"), ("rtol", "double"), ("atol_angle", "double"), ("atol_rate", "double"),
    ("h_max", "double"), ("ws", "double"),
    ("J", "double*"), ("d", "double*"), ("tc", "double*"),
    ("rb1", "double*"), ("rb2", "double*"), ("b", "double*"), ("k", "double*"), ("c", "double*"),
    ("mesh_period", "double*"), ("mesh_phase", "double*"), ("table", "double*"), ("table_off", "gc_int*"),
    ("aff", "double*"), ("fcoef", "double*"),
    ("ev_count", "gc_int*"), ("ev_cg", "double*"), ("ev_g0", "double*"), ("ev_target", "int*"),
    ("ev_type", "int*"), ("ev_ssign", "double*"),
    ("fbit", "gc_int*"), ("slot", "gc_int*"),
    ("A", "double*"), ("Phi", "double*"), ("Gam", "double*"), ("h", "double*"), ("rho", "double*"),
    # long steps (trains): per pattern slot, see _long_data
    ("lv_n", "gc_int*"), ("lv_mult", "gc_int*"), ("lv_Phi", "double*"), ("lv_Gam", "double*"), ("lv_E", "double*"),
    ("lv_e4", "double*"), ("fm_n", "gc_int*"), ("fm_lam", "double*"), ("fm_wt", "double*"), ("fm_W", "double*"),
    ("fm_V", "double*"), ("M3", "double*"), ("lv_dec", "double*"), ("rig", "double*"),
    ("ratio", "double*"),  # shaft j's angle per radian of the load's (the call's origin, see _origin)
)
STATE_FIELDS: tuple[tuple[str, str], ...] = (
    ("x", "double*"), ("t", "double"), ("t_end", "double"), ("d_ys", "double*"), ("h_ode", "double"),
    ("max_pen", "double*"), ("n_events", "gc_int"), ("n_steps", "gc_int"), ("events_total", "gc_int"),
    ("mode", "int*"), ("slip", "int*"), ("need", "gc_int"), ("u1", "double"), ("u2", "double"),
    ("ev", "gc_event*"), ("cap", "gc_int"), ("counts", "gc_int*"), ("vmax", "double*"),
    ("org", "double*"),  # the origin of the call under way (zeros between calls)
)
_EVENT_FIELDS = (("t", "double"), ("v", "double"), ("kind", "gc_int"), ("side", "gc_int"), ("where", "gc_int"))
_CTYPES: dict[str, type[ctypes._SimpleCData[Any]] | type[ctypes._Pointer[Any]]] = {
    "double": ctypes.c_double, "gc_int": ctypes.c_int64, "int": ctypes.c_int,
    "double*": ctypes.POINTER(ctypes.c_double), "gc_int*": ctypes.POINTER(ctypes.c_int64),
    "int*": ctypes.POINTER(ctypes.c_int), "gc_event*": ctypes.c_void_p}


def c_structs() -> str:
    """The C declarations of ``gc_params``, ``gc_state`` and ``gc_event`` (prepended to ``_kernel.c``)."""
    def struct(name: str, fields: tuple[tuple[str, str], ...]) -> str:
        body = "\n".join(f"    {ty.replace('*', ' *') if ty.endswith('*') else ty + ' '}{n};".replace("  ", " ")
                         for n, ty in fields)
        return f"typedef struct {{\n{body}\n}} {name};\n"

    return ("#include <stdint.h>\ntypedef int64_t gc_int;\n"
            f"#define GC_MAX_STAGES {MAX_STAGES}\n#define GC_NX_MAX {_NX_MAX}\n#define GC_NCOUNT {_NCOUNT}\n"
            f"#define GC_LMAX {_LMAX}\n"
            + struct("gc_event", _EVENT_FIELDS) + struct("gc_params", PARAMS_FIELDS) + struct("gc_state", STATE_FIELDS))


class _Params(ctypes.Structure):
    _fields_ = [(n, _CTYPES[t]) for n, t in PARAMS_FIELDS]


class _State(ctypes.Structure):
    _fields_ = [(n, _CTYPES[t]) for n, t in STATE_FIELDS]


assert EVENT_DTYPE.itemsize == 8 * len(_EVENT_FIELDS)

# --- compilation -----------------------------------------------------------------------------------------------

_LIB: ctypes.CDLL | None | bool = False  # False: not tried yet


def _load() -> ctypes.CDLL | None:
    """Compile (once per source version) and load the C kernel; None where that is not possible."""
    global _LIB
    if _LIB is not False:
        return _LIB  # type: ignore[return-value]
    _LIB = None
    if compile_disabled():
        return None
    src = _SRC.read_text().replace("/* @GC_STRUCTS@ (generated by gearctl/kernel.py) */", c_structs())
    lib = shared_library("kernel", {"_kernel.c": src.encode()})
    if lib is None:
        return None
    P, S = ctypes.POINTER(_Params), ctypes.POINTER(_State)
    lib.gc_step.restype = ctypes.c_int
    lib.gc_step.argtypes = [P, S]
    lib.gc_run.restype = ctypes.c_int
    lib.gc_run.argtypes = [P, S, ctypes.c_double, ctypes.c_int64, ctypes.c_void_p, ctypes.c_void_p,
                           ctypes.POINTER(ctypes.c_int64)]
    lib.gc_force.restype = ctypes.c_double
    lib.gc_force.argtypes = [P, ctypes.c_int64, ctypes.c_int, ctypes.c_double, ctypes.c_void_p]
    _LIB = lib
    return lib


def compiled_available() -> bool:
    """Whether the compiled kernel could be built and loaded on this machine."""
    return _load() is not None


# --- linear data of the improved plant ------------------------------------------------------------------------


def contact_matrices(plant: Plant) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """State matrices of the improved plant: ``(A_contact, A_free, B)`` (every stage in contact / none).

    ``x' = A x + B u + e`` in each mode, with ``e`` the constant ``+-k b`` term of the contact modes. A
    thin view of :func:`gearctl.plant.mode_matrices`.

    Parameters
    ----------
    plant : Plant
        A pair or a train.
    """
    n = plant.n_stages
    return mode_matrices(plant, [True] * n), mode_matrices(plant, [False] * n), input_matrix(plant)


def _propagators(A: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """``Phi(h) = e^{A h}`` and ``Gamma(h) = int_0^h e^{A t} dt`` (cached: a bench builds the same ones often)."""
    return _propagators_cached(A.tobytes(), A.shape[0], h)


@functools.lru_cache(maxsize=512)
def _propagators_cached(A_bytes: bytes, n: int, h: float) -> tuple[np.ndarray, np.ndarray]:
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = np.frombuffer(A_bytes).reshape(n, n)
    M[:n, n:] = np.eye(n)
    E = scipy.linalg.expm(M * h)
    Phi, Gam = E[:n, :n].copy(), E[:n, n:].copy()
    Phi.flags.writeable = False
    Gam.flags.writeable = False
    return Phi, Gam


# --- long steps: the certificate's data ------------------------------------------------------------------------

#: Most long-step levels a pattern keeps (lengths 2, 4, 8, ... sub-steps and the whole interval).
_LMAX = 24
#: Long steps on trains by default (``Kernel(long_steps=...)`` overrides; a pair never takes them).
LONG_STEPS = True
#: Largest first-order error of the modal split a level may carry, times ``3 + rho H`` (see _long_data).
_DEC_TOL = 1e-6


@dataclasses.dataclass(frozen=True)
class _LongData:
    """One pattern's data for long steps (see :func:`_long_data`)."""

    mults: tuple[int, ...]  # level lengths in sub-steps h
    phis: tuple[np.ndarray, ...]
    gams: tuple[np.ndarray, ...]
    E: np.ndarray  # (levels, nf) complex: exp(lambda_k H_l)
    e4: np.ndarray  # (levels,): exp(||T11|| H) H^4 / 384
    lam: np.ndarray  # (nf,) complex fast eigenvalues, one of each conjugate pair
    wt: np.ndarray  # (nf,) 2 for a pair, 1 for a real eigenvalue
    W: np.ndarray  # (nf, nx) complex left eigenvectors (rows), W V = I on the fast subspace
    V: np.ndarray  # (nf, nx) complex right eigenvectors (row k is v_k)
    M3: np.ndarray  # (nx, nx) real: Q_s T11^3 (slow basis times the slow block cubed; zero columns beyond)
    dec: np.ndarray  # (levels,): (3 + rho H) eps_dec, the split's error as it can move the certificate
    rig: np.ndarray  # (w, w): projector on the rigid displacements (angles A maps to zero)
    eps_dec: float  # first-order error of the split
    kappa: float  # condition number of the scaled basis [Q_s V_f]


def _long_data(A: np.ndarray, dt: float, h: float, m: int) -> _LongData | None:
    """The long-step data of pattern matrix ``A`` (cached: a bench or a sweep builds the same ones often)."""
    return _long_data_cached(A.tobytes(), A.shape[0], dt, h, m)


@functools.lru_cache(maxsize=256)
def _long_data_cached(A_bytes: bytes, nx: int, dt: float, h: float, m: int) -> _LongData | None:
    """The modal split of a pattern's ``A`` that certifies long steps, or None where it cannot be trusted.

    The solution of ``x' = A x + a`` splits along the invariant subspaces of A into a *slow* part (eigenvalues
    with ``|lambda| dt <= 1``: rigid-body motion, the viscously damped rigid modes, any stuck shaft; it may be
    defective, e.g. a free shaft's Jordan block at 0, and is never diagonalised) and a *fast* part (the mesh
    modes, diagonalised: ``x_f = sum_k v_k eta_k`` with ``eta_k' = lambda_k eta_k + w_k a``). An event
    function ``g = l.x + g0`` is then ``g(t) = S(t) + F(t)`` on a step ``[0, H]``, with

    - ``F(t) = sum_k (l.v_k) gamma_k exp(lambda_k t)``, ``gamma_k = w_k x(0) + w_k a / lambda_k`` (the fast
      modes about their steady state), so ``|F(t)| <= B = sum_k |l.v_k| |gamma_k| max(1, |exp(lambda_k H)|)``;
    - ``S = g - F``: ``g0`` plus the slow part and the fast modes' steady state. With ``Q_s`` an orthonormal
      basis of the slow subspace, ``T11 = Q_s^T A Q_s`` and ``y = P_s x'(0)`` (``P_s`` the projector on it
      along the fast one), ``S''''(t) = l^T Q_s T11^3 exp(T11 t) Q_s^T y``, so
      ``|S''''| <= ||l^T Q_s T11^3||_2 exp(||T11||_2 H) ||y||_2`` on the step, and S is within
      ``E4 = max|S''''| H^4 / 384`` of its cubic Hermite interpolant (end values and slopes), which is known
      exactly from ``g`` and ``F`` at both ends. A Jordan block at 0 (a free shaft) is a polynomial of degree
      2 or 3 there: its ``T11^3`` vanishes and so does its share of E4.

    Hence ``min g >= min(cubic) - E4 - B`` over the step, exactly in real arithmetic, with no assumption on
    the number of extrema. Floating point: the split is computed on the balanced matrix (angles scaled by
    rho); its first-order error is ``eps_dec = kappa (|A V - V L| + |A Q - Q T| + eps) |A| / gap`` (residuals
    relative to ``|A|``; kappa the condition of the basis ``[Q_s V_f]``, gap the distance between the slow
    and fast spectra), and a fast component leaked into S can move its cubic by ``3 + rho H`` times its size,
    so the certificate subtracts ``(3 + rho H) eps_dec |l|_bal (|x_d|_bal + sum |eta_k|)`` (balanced norms;
    ``x_d`` the state less its rigid displacement: the angles of many radians the fast modes do not see are
    taken out before the modal amplitudes are formed: null vectors of A, which w_k annihilates, so only their
    rounding goes), plus 1e-11 of the event function's terms (rounding of g and of the propagators, measured
    at 3e-14), 1e-6 of B and 1e-12 of the cubic's terms (``long_try`` in ``_kernel.c``). A level whose
    ``(3 + rho H) eps_dec`` exceeds :data:`_DEC_TOL`, a basis with kappa above 1e8, a spectrum without a gap
    around ``1 / dt`` or a conjugate pair split across it: no long steps. Levels: ``2, 4, 8, ...`` sub-steps
    below ``m``, and ``m`` (the whole interval), by squaring the sub-step's propagators.
    """
    A = np.frombuffer(A_bytes).reshape(nx, nx)
    w = nx // 2
    if m < 4 or not np.all(np.isfinite(A)):
        return None
    mags = np.abs(np.linalg.eigvals(A))
    rho = float(np.max(mags))
    if not rho > 0.0:
        return None
    tau = 1.0 / dt
    while np.any((mags > 0.5 * tau) & (mags < 2.0 * tau)) and tau * dt > 1e-3:  # the split sits in a gap
        tau *= 0.5
    if np.any((mags > 0.5 * tau) & (mags < 2.0 * tau)):
        return None
    sc = np.array([rho] * w + [1.0] * w)  # balanced: angles times rho, speeds as they are
    At = sc[:, None] * A / sc[None, :]
    try:
        _, Z, sdim = scipy.linalg.schur(At, output="real", sort=lambda re, im: re * re + im * im <= tau * tau)
        lt, Vt = scipy.linalg.eig(At)
    except (np.linalg.LinAlgError, ValueError):
        return None
    fast = np.abs(lt) > tau
    if sdim != nx - int(fast.sum()) or sdim != int(np.sum(mags <= tau)):
        return None
    lf = lt[fast]
    Vf = Vt[:, fast]
    Vf = Vf / np.linalg.norm(Vf, axis=0)
    Qt = Z[:, :sdim]
    basis = np.hstack([Qt.astype(complex), Vf])
    kappa = float(np.linalg.cond(basis))
    if not kappa < 1e8:
        return None
    Wf = np.linalg.inv(basis)[sdim:]
    nA = float(np.linalg.norm(At, 2))
    r1 = float(np.linalg.norm(At @ Vf - Vf * lf[None, :], 2)) / nA if lf.size else 0.0
    r2 = float(np.linalg.norm(At @ Qt - Qt @ (Qt.T @ At @ Qt), 2)) / nA if sdim else 0.0
    slow_max = float(np.max(mags[mags <= tau])) if sdim else 0.0
    gap = float(np.min(np.abs(lf))) - slow_max if lf.size else math.inf
    eps_dec = kappa * (r1 + r2 + 2.3e-16) * nA / gap
    # back to the state's own coordinates
    V = (Vf / sc[:, None]).T  # row k: v_k
    W = Wf * sc[None, :]
    M3, t11 = np.zeros((nx, nx)), 0.0
    if sdim:
        Qs, _ = np.linalg.qr(Z[:, :sdim] / sc[:, None])
        T11 = Qs.T @ A @ Qs
        M3[:, :sdim] = Qs @ np.linalg.matrix_power(T11, 3)
        t11 = float(np.linalg.norm(T11, 2))
    # one of each conjugate pair, weight 2; real fast eigenvalues weight 1
    if sum(1 for v in lf if v.imag > 0.0) != sum(1 for v in lf if v.imag < 0.0):
        return None
    keep = [k for k in range(lf.size) if lf[k].imag >= 0.0]
    lam = lf[keep]
    wt = np.array([2.0 if v.imag > 0.0 else 1.0 for v in lam])
    # propagators of 2^j sub-steps by squaring Phi(h), Gamma(h) (the sub-steps' own), and of m by their product:
    # Phi(s + r) = Phi(s) Phi(r), Gamma(s + r) = Gamma(s) + Phi(s) Gamma(r)
    mults = [2**j for j in range(1, _LMAX) if 2**j < m][: _LMAX - 1] + [m]
    P, G = (M.copy() for M in _propagators(A, h))
    pows = [(P, G)]
    while 2 ** len(pows) <= m:
        P, G = P @ P, G + P @ G
        pows.append((P, G))
    phis, gams, Es, e4s, decs = [], [], [], [], []
    for n_sub in mults:
        H = float(n_sub) * h
        if not (eps_dec * (3.0 + rho * H) <= _DEC_TOL and t11 * H < 700.0 and np.all(lam.real * H < 700.0)):
            break
        if n_sub & (n_sub - 1) == 0:
            Phi, Gam = pows[n_sub.bit_length() - 1]
        else:
            Phi, Gam = np.eye(nx), np.zeros((nx, nx))
            for j in range(n_sub.bit_length()):
                if n_sub >> j & 1:
                    Phi, Gam = pows[j][0] @ Phi, pows[j][1] + pows[j][0] @ Gam
        phis.append(Phi)
        gams.append(Gam)
        Es.append(np.exp(lam * H))
        e4s.append(math.exp(t11 * H) * H**4 / 384.0)
        decs.append(eps_dec * (3.0 + rho * H))
    if not phis:
        return None
    # the rigid displacements (angles the pattern's A maps to zero): the state's large common angles, taken out
    # before the fast modes' amplitudes are formed (w_k annihilates them; rounding would not, at 1e-16 of them)
    U, sv, _ = np.linalg.svd(A[:, :w].T)
    null = U[:, sv <= 1e-12 * sv[0]] if sv[0] > 0.0 else np.eye(w)
    rig = null @ null.T
    nl = len(phis)
    return _LongData(mults=tuple(mults[:nl]), phis=tuple(phis), gams=tuple(gams),
                     E=np.array(Es, dtype=complex).reshape(nl, lam.size), e4=np.array(e4s), lam=lam, wt=wt,
                     W=W[keep], V=V[keep], M3=M3, dec=np.array(decs), rig=rig, eps_dec=eps_dec, kappa=kappa)


def _ptr(a: np.ndarray, ctype: Any) -> Any:
    return a.ctypes.data_as(ctypes.POINTER(ctype))


# --- the kernel object ----------------------------------------------------------------------------------------


@dataclasses.dataclass
class Kernel:
    """A plant's simulation state and the solver that advances it.

    Parameters
    ----------
    plant : Plant
        The plant (a pair or a train).
    x0 : array_like, shape (nx,)
        Initial state ``[theta_0..theta_n, omega_0..omega_n]``.
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
    max_event_rate : float
        Events a whole run may locate per simulated second, on top of ``max_events`` [1/s]: a cascade
        that never settles ends the run instead of eating the machine.
    max_records : int
        Events kept in detail (:attr:`event_log`); later ones are only counted (:attr:`counts`).
    long_steps : bool or None
        Let the exact solver of a train cross a quiet stretch in one long step where a certificate proves
        that no event function can reach zero in it (see :func:`_long_data`); None: :data:`LONG_STEPS`. A
        pair never takes long steps (its results stay those of the short sub-steps, bit for bit).
    """

    plant: Plant
    x0: ArrayLike
    dt: float
    rtol: float = 1e-9
    compiled: bool | None = None
    max_events: int = 200_000
    zeno_velocity: float = ZENO_VELOCITY
    t0: float = 0.0
    max_event_rate: float = 2e5
    max_records: int = 1_000_000
    long_steps: bool | None = None

    def __post_init__(self) -> None:
        p = self.plant
        n, w = p.n_stages, len(p.shafts)
        nx = 2 * w
        try:
            x0 = np.asarray(self.x0, dtype=float)
        except (TypeError, ValueError):
            x0 = None
        if x0 is None or x0.shape != (nx,) or not np.all(np.isfinite(x0)):
            shown = self.x0 if x0 is None else x0.tolist()
            raise InputError(f"x0 = {shown!r} is not an initial state: expected {nx} finite numbers "
                             f"[rad x {w}, rad/s x {w}]", field="x0")
        OUTPUT_INTERVAL.check("dt", self.dt)  # a string or a bool is named as such, not 'out of range'
        self.exact = p.is_piecewise_linear
        lib = _load() if self.compiled in (None, True) else None
        if self.compiled and lib is None:
            raise RuntimeError("the compiled kernel is not available (no C compiler?)")
        self._lib = lib
        self.nx, self.ns, self.nsh = nx, n, w
        f64 = np.float64
        # -- parameter arrays (kept alive here; the C struct points at them)
        self._J = np.array([s.J for s in p.shafts], f64)
        self._d = np.array([s.d for s in p.shafts], f64)
        self._tc = np.array([s.tc for s in p.shafts], f64)
        self._rb1 = np.array([s.rb1 for s in p.stages], f64)
        self._rb2 = np.array([s.rb2 for s in p.stages], f64)
        self._b = np.array([s.backlash for s in p.stages], f64)
        self._k = np.array([s.k for s in p.stages], f64)
        self._c = np.array([s.c for s in p.stages], f64)
        self._period = np.array([s.mesh_period for s in p.stages], f64)
        self._phase = np.array([s.mesh_phase for s in p.stages], f64)
        tables = [s.kv_table if s.kv_table is not None else np.zeros(1) for s in p.stages]
        self._table = np.ascontiguousarray(np.concatenate(tables), f64)
        self._table_off = np.cumsum([0] + [t.size for t in tables]).astype(np.int64)
        self._aff = np.ascontiguousarray(affine_terms(p).reshape(-1))
        fco = np.zeros((n, 2, nx + 1))
        for i in range(n):
            for sg in (-1, 1):
                fc, f0 = force_coefficients(p, i, sg)
                fco[i, int(sg > 0), :nx], fco[i, int(sg > 0), nx] = fc, f0
        self._fcoef = np.ascontiguousarray(fco.reshape(-1))
        ev = event_table(p)
        self._ev_count = ev["count"].astype(np.int64)
        self._ev_cg = np.ascontiguousarray(ev["cg"])
        self._ev_g0 = ev["g0"]
        self._ev_target = ev["target"].astype(np.intc)
        self._ev_type = ev["type"].astype(np.intc)
        self._ev_ssign = ev["ssign"]
        # shaft j's angle per radian of the load's: the origin of each call (see _origin) leaves every gap as it is
        ratio = [1.0] * w
        for j in range(n - 1, -1, -1):
            ratio[j] = ratio[j + 1] * p.stages[j].rb2 / p.stages[j].rb1
        self._ratio = np.array(ratio, f64)
        self._ratio_list = ratio
        stick = p.friction_law is FrictionLaw.STICK_SLIP and p.has_coulomb
        self.friction = 1 if stick else (2 if p.has_coulomb else 0)
        fshafts = [j for j in range(w) if stick and p.shafts[j].tc > 0]
        self._fbit = np.full(w, -1, np.int64)
        for q, j in enumerate(fshafts):
            self._fbit[j] = n + q
        self._slot = np.full(1 << (n + len(fshafts)), -1, np.int64)
        self._pool_cap = 0
        self._n_slots = 0
        # the pattern pool (allocated and grown by _ensure_pattern; the C struct points at them)
        self._A: NDArray[np.float64]
        self._Phi: NDArray[np.float64]
        self._Gam: NDArray[np.float64]
        self._h: NDArray[np.float64]
        self._rho: NDArray[np.float64]
        self._lv_n: NDArray[np.int64]
        self._lv_mult: NDArray[np.int64]
        self._lv_Phi: NDArray[np.float64]
        self._lv_Gam: NDArray[np.float64]
        self._lv_E: NDArray[np.float64]
        self._lv_e4: NDArray[np.float64]
        self._fm_n: NDArray[np.int64]
        self._fm_lam: NDArray[np.float64]
        self._fm_wt: NDArray[np.float64]
        self._fm_W: NDArray[np.float64]
        self._fm_V: NDArray[np.float64]
        self._M3: NDArray[np.float64]
        self._lv_dec: NDArray[np.float64]
        self._rig: NDArray[np.float64]
        self._long = bool(self.exact and n >= 2 and (LONG_STEPS if self.long_steps is None else self.long_steps))
        self._long_info: dict[int, _LongData | None] = {}
        # -- tolerances of the nonlinear solver: 1e-9 of the backlash (or of 1 um) in s, carried to the
        #    angles and rates
        scale = min(max(s.backlash, 1e-6) * 1e-9 / max(s.rb1, s.rb2) for s in p.stages)
        h_max = min(0.25 * 2 * math.pi / math.sqrt(s.k * (s.rb1**2 / p.shafts[i].J + s.rb2**2 / p.shafts[i + 1].J))
                    for i, s in enumerate(p.stages))
        prm = _Params()
        prm.nx, prm.ns, prm.nsh = nx, n, w
        prm.law = 1 if p.contact_law is ContactLaw.NO_PULL else 0
        prm.kind = {PlantKind.IMPROVED: 0, PlantKind.YANG_SUN: 1, PlantKind.TVMS: 2}[p.kind]
        prm.friction, prm.exact = self.friction, int(self.exact)
        prm.zeno_v, prm.rtol = float(self.zeno_velocity), float(self.rtol)
        prm.atol_angle, prm.atol_rate, prm.h_max = scale, scale * p.natural_frequency, h_max
        prm.ws = p.coulomb_velocity
        for name in ("J", "d", "tc", "rb1", "rb2", "b", "k", "c", "table", "aff", "fcoef", "ev_cg", "ev_g0",
                     "ev_ssign", "ratio"):
            setattr(prm, name, _ptr(getattr(self, "_" + name), ctypes.c_double))
        prm.mesh_period, prm.mesh_phase = _ptr(self._period, ctypes.c_double), _ptr(self._phase, ctypes.c_double)
        for name in ("table_off", "ev_count", "fbit", "slot"):
            setattr(prm, name, _ptr(getattr(self, "_" + name), ctypes.c_int64))
        prm.ev_target, prm.ev_type = _ptr(self._ev_target, ctypes.c_int), _ptr(self._ev_type, ctypes.c_int)
        prm.max_events = self.max_events
        self._prm = prm
        # the patterns every run meets: all stages free and all in contact (a pair has no other)
        if self.exact:
            self._ensure_pattern(0)
            self._ensure_pattern((1 << n) - 1)
        # -- state arrays
        self._x = x0.copy()
        self._mode = np.zeros(n, np.intc)
        self._slip = np.full(w, 2, np.intc)
        self._dys = np.zeros(n)
        self._max_pen = np.full(n, -np.inf)
        self._counts = np.zeros(n * _NCOUNT, np.int64)
        self._vmax = np.zeros(n)
        st = _State()
        st.x = _ptr(self._x, ctypes.c_double)
        st.d_ys, st.max_pen, st.vmax = (_ptr(a, ctypes.c_double) for a in (self._dys, self._max_pen, self._vmax))
        st.mode, st.slip = _ptr(self._mode, ctypes.c_int), _ptr(self._slip, ctypes.c_int)
        st.counts = _ptr(self._counts, ctypes.c_int64)
        self._org = np.zeros(w)
        st.org = _ptr(self._org, ctypes.c_double)
        st.t = st.t_end = float(self.t0)
        st.h_ode = 0.0
        self._st = st
        self._mode[:] = self.classify_all(self._x)
        if not self.exact:  # a run that starts in contact: Yang-Sun's d from zero speed
            for i in range(n):
                if self._mode[i] != 0:
                    self._dys[i] = yang_sun_damping_factor(p.stages[i].k, 0.0)
        self._classify_slip(0.0, 0.0)
        self._cap = 4096
        self._ev = np.zeros(self._cap, dtype=EVENT_DTYPE)
        st.ev, st.cap = self._ev.ctypes.data, self._cap
        self._chunks: list[np.ndarray] = []
        self._n_recorded = 0
        self.dropped_events = 0
        self._fn: Callable[[Any, Any], int] | None = None  # gc_step, where the library is loaded
        if lib is not None:
            self._fn = lib.gc_step
            self._pp, self._sp = ctypes.byref(prm), ctypes.byref(st)

    # -- patterns
    def _ensure_pattern(self, pat: int) -> None:
        """Build (once) the propagators of pattern ``pat`` (loaded-stage and stuck-shaft bits)."""
        if self._slot[pat] >= 0:
            return
        p = self.plant
        n, nx = self.ns, self.nx
        loaded = [bool(pat >> i & 1) for i in range(n)]
        stuck = [bool(self._fbit[j] >= 0 and pat >> int(self._fbit[j]) & 1) for j in range(self.nsh)]
        A = mode_matrices(p, loaded, stuck)
        rho = float(np.max(np.abs(np.linalg.eigvals(A))))
        lim = 0.6 if any(loaded) else 0.5
        hmax = lim / rho if rho > 0 else math.inf
        m = max(1, math.ceil(self.dt / hmax - 1e-9))
        h = self.dt / m
        Phi, Gam = _propagators(A, h)
        if self._n_slots == self._pool_cap:  # grow the pool (the C struct's pointers follow)
            cap = max(4, 2 * self._pool_cap)
            L = _LMAX if self._long else 1  # a pair keeps no long-step data
            nxl = nx if self._long else 1
            for name, shape, dtype in (
                    ("_A", (cap, nx, nx), np.float64), ("_Phi", (cap, nx, nx), np.float64),
                    ("_Gam", (cap, nx, nx), np.float64), ("_h", (cap,), np.float64), ("_rho", (cap,), np.float64),
                    ("_lv_n", (cap,), np.int64), ("_lv_mult", (cap, L), np.int64),
                    ("_lv_Phi", (cap, L, nxl, nxl), np.float64), ("_lv_Gam", (cap, L, nxl, nxl), np.float64),
                    ("_lv_E", (cap, L, nxl, 2), np.float64), ("_lv_e4", (cap, L), np.float64),
                    ("_fm_n", (cap,), np.int64), ("_fm_lam", (cap, nxl, 2), np.float64),
                    ("_fm_wt", (cap, nxl), np.float64), ("_fm_W", (cap, nxl, nxl, 2), np.float64),
                    ("_fm_V", (cap, nxl, nxl, 2), np.float64), ("_M3", (cap, nxl, nxl), np.float64),
                    ("_lv_dec", (cap, L), np.float64), ("_rig", (cap, nxl, nxl), np.float64)):
                new = np.zeros(shape, dtype)
                if self._pool_cap:
                    new[: self._pool_cap] = getattr(self, name)
                setattr(self, name, new)
            self._pool_cap = cap
            for name in ("A", "Phi", "Gam", "h", "rho", "lv_Phi", "lv_Gam", "lv_E", "lv_e4", "fm_lam", "fm_wt",
                         "fm_W", "fm_V", "M3", "lv_dec", "rig"):
                setattr(self._prm, name, _ptr(getattr(self, "_" + name), ctypes.c_double))
            for name in ("lv_n", "lv_mult", "fm_n"):
                setattr(self._prm, name, _ptr(getattr(self, "_" + name), ctypes.c_int64))
        q = self._n_slots
        self._A[q], self._Phi[q], self._Gam[q], self._h[q], self._rho[q] = A, Phi, Gam, h, rho
        ld = _long_data(A, self.dt, h, m) if self._long else None
        self._long_info[pat] = ld
        if ld is not None:
            nl, nf = len(ld.mults), ld.lam.size
            self._lv_n[q] = nl
            self._lv_mult[q, :nl] = ld.mults
            self._lv_Phi[q, :nl], self._lv_Gam[q, :nl] = ld.phis, ld.gams
            self._lv_E[q, :nl, :nf, 0], self._lv_E[q, :nl, :nf, 1] = ld.E.real, ld.E.imag
            self._lv_e4[q, :nl] = ld.e4
            self._fm_n[q] = nf
            self._fm_lam[q, :nf, 0], self._fm_lam[q, :nf, 1] = ld.lam.real, ld.lam.imag
            self._fm_wt[q, :nf] = ld.wt
            self._fm_W[q, :nf, :, 0], self._fm_W[q, :nf, :, 1] = ld.W.real, ld.W.imag
            self._fm_V[q, :nf, :, 0], self._fm_V[q, :nf, :, 1] = ld.V.real, ld.V.imag
            self._M3[q] = ld.M3
            self._lv_dec[q, :nl] = ld.dec
            self._rig[q, : self.nsh, : self.nsh] = ld.rig
        self._n_slots += 1
        self._slot[pat] = q

    # -- state access
    @property
    def x(self) -> np.ndarray:
        """Current state."""
        return self._x.copy()

    @property
    def t(self) -> float:
        """Current time [s]."""
        return self._st.t

    @property
    def mode(self) -> int:
        """Solver mode of the first stage: -2, -1, 0, 1, 2 (±2: flanks overlapping without load, no_pull)."""
        return int(self._mode[0])

    @property
    def modes(self) -> tuple[int, ...]:
        """Solver mode of every stage."""
        return tuple(int(m) for m in self._mode)

    @property
    def slip(self) -> tuple[int, ...]:
        """Per shaft: -1 / +1 slipping, 0 stuck (stick-slip friction), 2 without Coulomb friction."""
        return tuple(int(s) for s in self._slip)

    @property
    def d_ys(self) -> np.ndarray:
        """Yang–Sun damping factor of each stage's current contact [N s/m^2]."""
        return self._dys.copy()

    @property
    def max_penetration(self) -> float:
        """Largest ``|s| - b`` of any stage so far [m] (0 if never in contact).

        Estimated at the sub-steps and at the interior peaks of their cubic model; a train's long step may
        raise it only to its certified upper bound, and only where that bound is within 0.1 % of the peak
        (a slow loading), else the sub-steps estimate the peak as they do on a pair."""
        return max(0.0, float(np.max(self._max_pen)))

    @property
    def stage_penetration(self) -> np.ndarray:
        """Largest ``|s| - b`` of each stage so far [m]."""
        return np.maximum(self._max_pen, 0.0)

    @property
    def steps(self) -> int:
        """Steps taken so far (sub-steps, and a train's long steps, one each)."""
        return self._st.n_steps

    @property
    def events_total(self) -> int:
        """Events located so far (recorded or not)."""
        return self._st.events_total

    @property
    def path(self) -> str:
        """``"compiled"`` or ``"python"``."""
        return "compiled" if self._fn is not None else "python"

    @property
    def counts(self) -> dict[str, np.ndarray]:
        """Exact event counts per stage: :data:`COUNT_NAMES` -> array of length n, plus ``max_impact_velocity``."""
        c = self._counts.reshape(self.ns, _NCOUNT)
        return {**{k: c[:, j].copy() for j, k in enumerate(COUNT_NAMES)}, "max_impact_velocity": self._vmax.copy()}

    @property
    def event_log(self) -> np.ndarray:
        """The recorded events, a structured array (:data:`EVENT_DTYPE`) in time order."""
        if not self._chunks:
            return np.zeros(0, dtype=EVENT_DTYPE)
        if len(self._chunks) > 1:  # one array (filled in place: concatenate promotes the fields of each chunk)
            out = np.empty(sum(c.size for c in self._chunks), dtype=EVENT_DTYPE)
            pos = 0
            for c in self._chunks:
                out[pos:pos + c.size] = c
                pos += c.size
            self._chunks = [out]
        return self._chunks[0]

    @property
    def events(self) -> list[tuple[float, int, int, float]]:
        """The recorded mesh events as ``(t, kind, side, v)`` tuples (:attr:`event_log` has the stage too)."""
        log = self.event_log
        log = log[log["kind"] <= EventKind.PLASTIC]
        return list(zip(log["t"].tolist(), log["kind"].tolist(), log["side"].tolist(), log["v"].tolist(),
                        strict=True))

    def _origin(self, x: list[float]) -> list[float] | None:
        """The angles a call integrates from (``gc_step`` in ``_kernel.c``): the load's angle rounded to a whole
        multiple of :data:`ORIGIN_QUANTUM`, carried to each shaft by the stages' ratios (every gap unchanged);
        None where it is zero (or the angle not finite)."""
        o = math.floor(float(x[self.nsh - 1]) / ORIGIN_QUANTUM + 0.5) * ORIGIN_QUANTUM if math.isfinite(
            float(x[self.nsh - 1])) else 0.0
        if o == 0.0:
            return None
        return [o * r for r in self._ratio_list]

    def _relative(self, x: np.ndarray) -> list[float]:
        """State ``x`` with the angles relative to its origin (:meth:`_origin`)."""
        xr = [float(v) for v in x]
        org = self._origin(xr)
        if org is not None:
            for j, o in enumerate(org):
                xr[j] -= o
        return xr

    def classify_all(self, x: np.ndarray) -> list[int]:
        """Contact mode of every stage for state ``x`` (``no_pull`` unloaded overlap as ±2 for the exact solver).

        Parameters
        ----------
        x : ndarray, shape (nx,)
            State [rad, rad/s].

        Returns
        -------
        list of int
            Per stage: +1 front, -1 back, 0 in the gap (±2, see above).
        """
        p = self.plant
        w = self.nsh
        xr = self._relative(x)
        out = []
        for i, st in enumerate(p.stages):
            s = st.rb1 * xr[i] - st.rb2 * xr[i + 1]
            v = st.rb1 * xr[w + i] - st.rb2 * xr[w + i + 1]
            b = st.backlash
            side = 1 if (s > b or (b == 0.0 and s == 0.0 and v >= 0.0)) else (
                -1 if (s < -b or (b == 0 and s == 0)) else 0)
            if side and self.exact and p.contact_law is ContactLaw.NO_PULL:
                F = st.k * (side * s - b) + st.c * side * v
                if F <= 0.0:
                    side = 2 * side
            out.append(side)
        return out

    def classify(self, x: np.ndarray) -> int:
        """Contact mode of the first stage for state ``x`` (a pair's mode).

        Parameters
        ----------
        x : ndarray, shape (nx,)
            State [rad, rad/s].
        """
        return self.classify_all(x)[0]

    def _hold_torque(self, j: int, x: np.ndarray, u1: float, u2: float) -> float:
        """Torque shaft ``j`` needs from friction to stay at rest (everything but Coulomb's) [N m]."""
        p, w = self.plant, self.nsh
        xr = self._relative(x)
        T = -p.shafts[j].d * xr[w + j] + (u1 if j == 0 else 0.0) + (u2 if j == self.ns else 0.0)
        modes = self._mode
        if j >= 1 and modes[j - 1] in (1, -1):
            fc, f0 = force_coefficients(p, j - 1, int(modes[j - 1]))
            T += p.stages[j - 1].rb2 * (float(fc @ xr) + f0)
        if j < self.ns and modes[j] in (1, -1):
            fc, f0 = force_coefficients(p, j, int(modes[j]))
            T -= p.stages[j].rb1 * (float(fc @ xr) + f0)
        return T

    def _classify_slip(self, u1: float, u2: float) -> None:
        """Slip state of each shaft from its speed (and, at rest, from the torque friction must hold)."""
        w = self.nsh
        for j in range(w):
            if self.friction != 1 or self.plant.shafts[j].tc <= 0.0:
                self._slip[j] = 2
                continue
            om = self._x[w + j]
            if om != 0.0:
                self._slip[j] = 1 if om > 0 else -1
            else:
                T = self._hold_torque(j, self._x, u1, u2)
                tc = self.plant.shafts[j].tc
                self._slip[j] = 0 if abs(T) <= tc else (1 if T > 0 else -1)

    def set_state(self, x: np.ndarray) -> None:
        """Replace the state (e.g. a disturbance); the modes are re-classified.

        Parameters
        ----------
        x : ndarray, shape (nx,)
            State [rad, rad/s].
        """
        self._x[:] = np.asarray(x, dtype=float)
        self._mode[:] = self.classify_all(self._x)
        self._classify_slip(0.0, 0.0)

    # -- advancing
    def _budget(self, t_end: float, already: int = 0) -> int:
        """Events a call may locate: per call, and for the run per simulated second (``already``: events of
        this call counted in ``events_total`` so far)."""
        run = self.max_event_rate * max(t_end - self.t0, 0.0) + self.max_events - (self._st.events_total - already)
        return int(max(0, min(self.max_events, run)))

    def advance(self, u1: float, u2: float, T: float) -> int:
        """Advance by ``T`` seconds with constant torques ``u1`` (motor), ``u2`` (load) [N m]; return a status.

        0 is success; events are recorded in :attr:`event_log`. The call stops with status 3 when it has
        located ``max_events`` events, or the run more than ``max_events + max_event_rate * (t - t0)``.

        Parameters
        ----------
        u1 : float
            Torque on the motor shaft [N m].
        u2 : float
            Torque on the load shaft [N m] (the plant's ``load_torque`` is not added here).
        T : float
            Interval [s].

        Returns
        -------
        int
            The status (:meth:`status_message` words it).
        """
        st = self._st
        st.u1, st.u2 = u1, u2
        st.t_end = st.t + T
        if self._fn is None:
            return self._py_advance()
        # the per-call cap is set once (max_events); the run's rate is checked after the call, cheaply
        status = self._fn(self._pp, self._sp)  # two pointer arguments: the cheapest ctypes call
        if status == 0 and st.n_events == 0:
            return 0
        return self.finish_call(status)

    def finish_call(self, status: int) -> int:
        """After a call of the compiled ``gc_step`` that stopped early (``status``) or located events: drain the
        events, build the pattern it asks for, call again until the interval ends; return the final status.

        :meth:`advance` and the compiled batch loop (:mod:`gearctl.export.batch`, which calls ``gc_step``
        from C) both end their calls here, so the event budget and the patterns are handled in one place.

        Parameters
        ----------
        status : int
            The status the call returned.

        Returns
        -------
        int
        """
        st = self._st
        fn = cast("Callable[[Any, Any], int]", self._fn)  # a compiled call ended here: gc_step is loaded
        budget = self._budget(st.t_end, st.n_events)  # what this call could locate when it started
        used = 0
        while True:
            if st.n_events:
                used += st.n_events
                self._drain(min(st.n_events, self._cap))
            if used > budget:
                return _ST_EVENTS
            if status == _PATTERN:
                self._ensure_pattern(st.need)
            elif status != _BUFFER_FULL:
                return status
            self._prm.max_events = max(min(budget - used, self.max_events), 0)
            status = fn(self._pp, self._sp)
            self._prm.max_events = self.max_events

    def _drain(self, n: int) -> None:
        room = self.max_records - self._n_recorded
        keep = min(n, max(room, 0))
        if keep:
            self._chunks.append(self._ev[:keep].copy())
            self._n_recorded += keep
        self.dropped_events += n - keep

    def run(self, u1: float, u2: float, dt: float, n: int) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
        """Advance ``n`` intervals of ``dt`` with constant torques; return ``(status, x, modes, d_ys)``.

        ``x`` has shape ``(nx, m)`` with the state after each completed interval (``m <= n``; fewer on
        failure or divergence), ``modes`` and ``d_ys`` shape ``(n_stages, m)``. The compiled path runs
        stretches of intervals in one call.

        Parameters
        ----------
        u1 : float
            Torque on the motor shaft [N m].
        u2 : float
            Torque on the load shaft [N m] (the plant's ``load_torque`` is not added here).
        dt : float
            Interval [s].
        n : int
            Number of intervals.
        """
        nx, ns, w = self.nx, self.ns, self.nsh
        xs = np.empty((n, nx))
        modes = np.empty((n, ns), dtype=np.intc)
        dys = np.empty((n, ns))
        st = self._st
        st.u1, st.u2 = u1, u2
        m, status = 0, 0
        done = ctypes.c_int64(0)
        lib = cast(ctypes.CDLL, self._lib)  # called only where gc_step, and so the library, is loaded
        while m < n:
            if self._fn is None:
                status = self.advance(u1, u2, dt)
                xs[m], modes[m], dys[m] = self._x, self._mode, self._dys
                m += 1
                if status != 0 or not np.all(np.abs(self._x[w:]) <= 1e6):
                    break
                continue
            budget = self._budget(st.t + dt * (n - m))
            self._prm.max_events = budget
            before = self._dys.copy()
            status = lib.gc_run(self._pp, self._sp, dt, n - m, xs[m:].ctypes.data, modes[m:].ctypes.data,
                                      ctypes.byref(done))
            k = int(done.value)
            if k:  # d_ys changes only at a contact onset, and only the last interval of a call has events
                dys[m:m + k - 1] = before
                dys[m + k - 1] = self._dys
            m += k
            used = st.n_events
            if used:
                self._drain(min(used, self._cap))
            if status == 0:
                if k and not np.all(np.abs(xs[m - 1, w:]) <= 1e6):
                    break
                continue
            while status in (_PATTERN, _BUFFER_FULL):  # finish the interrupted interval (st.t_end is set)
                if status == _PATTERN:
                    self._ensure_pattern(st.need)
                elif used > budget:
                    status = _ST_EVENTS
                    break
                self._prm.max_events = max(budget - used, 0)
                status = self._fn(self._pp, self._sp)
                if st.n_events:
                    used += st.n_events
                    self._drain(min(st.n_events, self._cap))
            if status != 0:
                break
            xs[m], modes[m], dys[m] = self._x, self._mode, self._dys
            m += 1
            if not np.all(np.abs(self._x[w:]) <= 1e6):
                break
        return status, xs[:m].T.copy(), modes[:m].T.astype(int), dys[:m].T.copy()

    @staticmethod
    def status_message(status: int) -> str:
        """Words for a status code of :meth:`advance`.

        Parameters
        ----------
        status : int
            The code (an unknown one is worded ``status N``).

        Returns
        -------
        str
        """
        return _STATUS.get(status, f"status {status}")

    def run_message(self, status: int) -> str:
        """Words for a status of this kernel's run: :meth:`budget_message` for a spent event budget (3), else
        :meth:`status_message`.

        Parameters
        ----------
        status : int
            The code :meth:`advance` returned.

        Returns
        -------
        str
        """
        return self.budget_message() if status == _ST_EVENTS else self.status_message(status)

    def budget_message(self) -> str:
        """Words for status 3 (the run's event budget spent), from the events located so far.

        Two kinds of run spend it. A *cascade*: the events crowd towards one instant (every Zeno cascade the
        kernel meets it resolves, so one that does not settle is the kernel's fault). A *steady rate*: a motion
        that repeats faster than the run may locate events (:attr:`max_event_rate`), e.g. stick-slip friction
        driven by a mesh mode that never rings down; that is the model's, and the message says at what rate,
        which events, and the plant's fastest mesh mode beside it.

        Returns
        -------
        str
            One line: ``event cascade: ...`` or ``event rate: ...``.
        """
        t = self.event_log["t"]
        n = self.events_total
        head = f"{n} by t = {self.t:.6g} s"
        if self.dropped_events:  # the log is full (max_records), its tail old: a run this long has a steady rate
            wider = n / max(self.t - self.t0, 1e-300)
        elif t.size < 256 or t[-1] <= t[-256]:  # too few recorded to tell, or all at one instant
            return (f"event cascade: more contact events than the run may locate ({head}); the contact chatters "
                    "without settling")
        else:
            wider = 255 / (t[-1] - t[-256])
        if not self.dropped_events and 64 / max(t[-1] - t[-65], 1e-300) > 4.0 * wider:  # faster and faster
            return (f"event cascade: more contact events than the run may locate ({head}, the last 64 within "
                    f"{t[-1] - t[-65]:.3g} s); the contact chatters without settling")
        kinds = self.event_log["kind"][-256:]  # (with a full log: the last recorded)
        friction = 2 * int(np.count_nonzero(kinds >= EventKind.STICK)) > kinds.size
        what = "stick and slip of the friction" if friction else "impacts and separations of the meshes"
        mode = f"the fastest mesh mode {self.plant.natural_frequency / (2 * math.pi):.3g} Hz"
        if self.plant.kind is not PlantKind.YANG_SUN:  # (Yang-Sun's damping is its restitution law, eq 37)
            zeta = min(s.c / (2.0 * math.sqrt(s.k * self.plant.stage_m_eq(i))) for i, s in enumerate(self.plant.stages))
            mode += f", damping ratio {zeta:.3g}"
        return (f"event rate: the run's events come at a steady {wider:.3g} per s ({what}), more than it may "
                f"locate ({self.max_event_rate:.3g} per simulated s on top of {self.max_events}; {head}): a motion "
                f"repeating that fast never settles ({mode}); not a Zeno cascade: more damping or a shorter run")

    def c_force(self, i: int, mode: int, d_ys: float, x: np.ndarray) -> float:
        """The C kernel's force law for stage ``i`` (for the test that it agrees with :func:`mesh_force`).

        Parameters
        ----------
        i : int
            Stage index, 0 at the motor.
        mode : int
            The stage's mode (the sign counts: 0 in the gap).
        d_ys : float
            Yang–Sun damping factor of the stage's contact [N s/m^2].
        x : ndarray, shape (nx,)
            State [rad, rad/s].

        Returns
        -------
        float
            The force along the line of action [N], signed as the front flank's.

        Raises
        ------
        RuntimeError
            Without the compiled kernel.
        """
        if self._lib is None:
            raise RuntimeError("the compiled kernel is not available")
        xa = np.ascontiguousarray(x, dtype=float)
        return float(self._lib.gc_force(ctypes.byref(self._prm), i, mode, d_ys, xa.ctypes.data))

    # -- the pure-Python mirror -----------------------------------------------------------------------------
    def _py_advance(self) -> int:
        budget = self._budget(self._st.t_end)
        mirror = _Mirror(self, budget)
        status = mirror.advance_pwl() if self.exact else mirror.advance_ode()
        mirror.finish()
        return status


# --- the pure-Python mirror of _kernel.c -------------------------------------------------------------------------
# Written to follow the C line by line, so both paths give the same answers (tests compare them).

_NTAY = 48
_BREAKAWAY = 1e-9  # see _kernel.c
_HOLD_ROUNDING = 1e-10  # see _kernel.c


def _taylor(A: list[list[float]], rho: float, x0: list[float], a: list[float], tmax: float) -> list[list[float]]:
    n = len(x0)
    D = [list(x0)]
    t = [sum(A[i][j] * x0[j] for j in range(n)) for i in range(n)]
    D.append([t[i] + a[i] for i in range(n)])
    bound = rho * tmax
    term = bound
    for k in range(2, _NTAY):
        prev = D[k - 1]
        D.append([sum(A[i][j] * prev[j] for j in range(n)) / k for i in range(n)])
        term *= bound / k
        if term < 1e-18 and k >= 4:
            break
    return D


def _taylor_eval(D: list[list[float]], tau: float) -> list[float]:
    out = []
    for i in range(len(D[0])):
        acc = D[-1][i]
        for k in range(len(D) - 2, -1, -1):
            acc = acc * tau + D[k][i]
        out.append(acc)
    return out


def _poly(q: list[float], tau: float) -> tuple[float, float]:
    acc, dacc = q[-1], 0.0
    for k in range(len(q) - 2, -1, -1):
        dacc = dacc * tau + acc
        acc = acc * tau + q[k]
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
        dq = [(k + 1) * q[k + 1] for k in range(len(q) - 1)]
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


_M_SCALE, _M_FAST, _M_CUBIC = 1e-11, 1e-6, 1e-12  # the certificate's margins (see _kernel.c)
_PEN_REL = 1e-3  # a long step may raise a penetration record to its bound where that is this tight
_BACKOFF = (2, 16)  # sub-steps before the next long try after a refusal: first, most (doubling)


def _clearly_past(cg: list[float], D: list[list[float]], h: float, gb: float, db: float, thr0: float,
                  thr2: float) -> float:
    """The first time in [0, h] that an event function starting on its boundary is clearly past it:
    g(tau) = -(thr0 + thr2 tau^2); -1 if not by h (``clearly_past`` in _kernel.c)."""
    nx = len(cg)
    qp = [sum(cg[i] * Dn[i] for i in range(nx)) for Dn in D]
    qp[0] = thr0
    if len(qp) > 2:
        qp[2] += thr2
    return _first_root(qp, h, gb + thr2 * h * h + thr0, qp[1], db + 2.0 * thr2 * h)


def _cubic_range(s0: float, s1: float, d0: float, d1: float, umax: float = 1.0) -> tuple[float, float]:
    """Range on [0, umax] of the cubic Hermite interpolant on [0, 1] of values s0, s1, scaled slopes d0, d1."""
    c1, c2, c3 = d0, -3.0 * s0 - 2.0 * d0 + 3.0 * s1 - d1, 2.0 * s0 + d0 - 2.0 * s1 + d1
    send = s1 if umax == 1.0 else ((c3 * umax + c2) * umax + c1) * umax + s0
    mn, mx = min(s0, send), max(s0, send)
    qa, qb, qc = 3.0 * c3, 2.0 * c2, c1
    roots = []
    if qa == 0.0:
        if qb != 0.0:
            roots.append(-qc / qb)
    else:
        disc = qb * qb - 4.0 * qa * qc
        if disc >= 0.0:
            q = -0.5 * (qb + math.copysign(math.sqrt(disc), qb))
            roots.append(q / qa)
            if q != 0.0:
                roots.append(qc / q)
    for u in roots:
        if 0.0 < u < umax:
            v = ((c3 * u + c2) * u + c1) * u + s0
            mn, mx = min(mn, v), max(mx, v)
    return mn, mx


def _long_fraction(s0: float, s1: float, d0: float, d1: float, c: float, upper: bool) -> float:
    """After a refused long step: the largest fraction 2^-j (j >= 1) of it the slow cubic keeps clear of c."""
    if (not s0 < c) if upper else (not s0 > c):
        return 0.0
    f = 0.5
    while f >= 1.0 / 4096.0:
        lo, hi = _cubic_range(s0, s1, d0, d1, f)
        if (hi < c) if upper else (lo > c):
            return f
        f *= 0.5
    return 0.0


def _mv(M: list[list[float]], x: list[float]) -> list[float]:
    return [sum(row[j] * x[j] for j in range(len(x))) for row in M]


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


@dataclasses.dataclass
class _EvFun:
    cg: list[float]
    g0: float
    type: int  # 0 geometric, 1 force (no_pull), 2 slip reaches zero speed, 3 stuck shaft breaks away
    target: int
    idx: int
    ssign: float


class _Mirror:
    """One :meth:`Kernel.advance` call on the Python path (the C's locals as attributes)."""

    def __init__(self, kn: Kernel, budget: int) -> None:
        self.kn, self.p, self.budget = kn, kn.plant, budget
        st = kn._st
        self.u1, self.u2, self.t_end = st.u1, st.u2, st.t_end
        self.t = st.t
        self.x = kn._x.tolist()
        # the call's origin (gc_step in _kernel.c): the angles relative to it, the same operations as the C
        org = kn._origin(self.x)
        self.shifted = org is not None
        self.org = org if org is not None else [0.0] * kn.nsh
        if org is not None:
            for j, o in enumerate(org):
                self.x[j] -= o
        self.mode = kn._mode.tolist()
        self.slip = kn._slip.tolist()
        self.dys = kn._dys.tolist()
        self.max_pen = kn._max_pen.tolist()
        self.n_events = 0
        self.steps = 0
        self.events: list[tuple[float, float, int, int, int]] = []
        self.w, self.ns, self.nx = kn.nsh, kn.ns, kn.nx
        self.rb1, self.rb2, self.b = kn._rb1.tolist(), kn._rb2.tolist(), kn._b.tolist()
        self.k, self.c = kn._k.tolist(), kn._c.tolist()
        self.J, self.d, self.tc = kn._J.tolist(), kn._d.tolist(), kn._tc.tolist()
        self.law = kn._prm.law
        self.zeno_v = kn.zeno_velocity

    def finish(self) -> None:
        kn, st = self.kn, self.kn._st
        if self.shifted:
            for j, o in enumerate(self.org):
                self.x[j] += o
        kn._x[:] = self.x
        kn._mode[:] = self.mode
        kn._slip[:] = self.slip
        kn._dys[:] = self.dys
        kn._max_pen[:] = self.max_pen
        st.t = self.t
        st.n_steps += self.steps
        st.events_total += self.n_events
        if self.events:
            n = len(self.events)
            room = max(kn.max_records - kn._n_recorded, 0)
            keep = min(n, room)
            if keep:
                arr = np.array(self.events[:keep], dtype=EVENT_DTYPE)
                kn._chunks.append(arr)
                kn._n_recorded += keep
            kn.dropped_events += n - keep

    # -- shared pieces
    def flank_is_label(self, i: int, ode: bool) -> bool:
        """No gap and the linear law: the mode is only a label (``flank_is_label`` in _kernel.c)."""
        return self.b[i] == 0.0 and self.law == 0 and (not ode or self.p.kind is not PlantKind.YANG_SUN)

    def s_of(self, i: int, x: list[float]) -> float:
        return self.rb1[i] * x[i] - self.rb2[i] * x[i + 1]

    def v_of(self, i: int, x: list[float]) -> float:
        return self.rb1[i] * x[self.w + i] - self.rb2[i] * x[self.w + i + 1]

    def record(self, t: float, kind: int, side: int, v: float, where: int) -> None:
        self.events.append((t, v, kind, side, where))
        self.n_events += 1

    def count(self, i: int, slot: int, v: float) -> None:
        kn = self.kn
        kn._counts[_NCOUNT * i + slot] += 1
        if slot <= 3 and abs(v) > kn._vmax[i]:
            kn._vmax[i] = abs(v)

    def force(self, i: int, mode: int, d_ys: float, x: list[float]) -> float:
        if mode == 0:
            return 0.0
        p = self.p
        s, v = self.s_of(i, x), self.v_of(i, x)
        sigma = 1.0 if mode > 0 else -1.0
        delta, ddelta = sigma * s - self.b[i], sigma * v
        if p.kind is PlantKind.YANG_SUN:
            F = (d_ys * ddelta + self.k[i]) * delta
        else:
            # the stiffness follows the absolute angle: the call's origin added back
            kk = float(p.stiffness_at(x[i] + self.org[i], i, sigma)) if p.kind is PlantKind.TVMS else self.k[i]
            F = kk * delta + self.c[i] * ddelta
        if self.law == 1 and F < 0.0:
            F = 0.0
        return sigma * F

    def free_gap_accel(self, i: int, x: list[float]) -> float:
        w = self.w
        acc = []
        for q in (0, 1):
            j = i + q
            if self.kn.friction == 1 and self.slip[j] == 0:
                acc.append(0.0)
                continue
            T = -self.d[j] * x[w + j]
            if j == 0:
                T += self.u1
            if j == self.ns:
                T += self.u2
            if self.kn.friction == 1 and self.slip[j] in (1, -1):
                T -= self.tc[j] * self.slip[j]
            if j >= 1 and j - 1 != i:
                T += self.rb2[j - 1] * self.force(j - 1, self.mode[j - 1], self.dys[j - 1], x)
            if j < self.ns and j != i:
                T -= self.rb1[j] * self.force(j, self.mode[j], self.dys[j], x)
            acc.append(T / self.J[j])
        return self.rb1[i] * acc[0] - self.rb2[i] * acc[1]

    def grazing_leaves(self, f: _EvFun, x: list[float], h: float) -> bool:
        return f.ssign * self.free_gap_accel(f.idx, x) < -(1e-3 * self.zeno_v / h)

    def hold_coef(self, j: int) -> tuple[list[float], float]:
        p, nx = self.p, self.nx
        cg = [0.0] * nx
        g0 = 0.0
        cg[self.w + j] = -self.d[j]
        if j == 0:
            g0 += self.u1
        if j == self.ns:
            g0 += self.u2
        if j >= 1 and self.mode[j - 1] in (1, -1):
            fc, f0 = force_coefficients(p, j - 1, self.mode[j - 1])
            cg = [cg[q] + self.rb2[j - 1] * fc[q] for q in range(nx)]
            g0 += self.rb2[j - 1] * f0
        if j < self.ns and self.mode[j] in (1, -1):
            fc, f0 = force_coefficients(p, j, self.mode[j])
            cg = [cg[q] - self.rb1[j] * fc[q] for q in range(nx)]
            g0 -= self.rb1[j] * f0
        return cg, g0

    def collect(self, ode: bool) -> list[_EvFun]:
        kn, out = self.kn, []
        for i in range(self.ns):
            if self.flank_is_label(i, ode):  # no flank change to locate
                continue
            slot = 5 * i + self.mode[i] + 2
            for e in range(int(kn._ev_count[slot])):
                row = 2 * slot + e
                if ode and kn._ev_type[row] != EVENT_GEOMETRIC:
                    continue
                out.append(_EvFun(kn._ev_cg[row].tolist(), float(kn._ev_g0[row]), int(kn._ev_type[row]),
                                  int(kn._ev_target[row]), i, float(kn._ev_ssign[row])))
        if kn.friction == 1:
            for j in range(self.w):
                sl = self.slip[j]
                if sl in (1, -1):
                    cg = [0.0] * self.nx
                    cg[self.w + j] = float(sl)
                    out.append(_EvFun(cg, 0.0, 2, 0, j, 0.0))
                elif sl == 0:
                    cg, g0 = self.hold_coef(j)
                    for sd in (1, -1):
                        out.append(_EvFun([-sd * c for c in cg], self.tc[j] * (1.0 + _BREAKAWAY) - sd * g0, 3, sd,
                                          j, 0.0))
        return out

    def plastic(self, i: int, x: list[float]) -> None:
        w = self.w
        v = self.v_of(i, x)
        inv_m = self.rb1[i] * self.rb1[i] / self.J[i] + self.rb2[i] * self.rb2[i] / self.J[i + 1]
        P = v / inv_m
        x[w + i] -= self.rb1[i] * P / self.J[i]
        x[w + i + 1] += self.rb2[i] * P / self.J[i + 1]

    def transition(self, f: _EvFun, x: list[float], t: float) -> None:
        i = f.idx
        if f.type == 2:
            x[self.w + i] = 0.0
            if self.kn.exact:  # the linear form the exact path's break-away events use
                cg, g0 = self.hold_coef(i)
                T = g0 + sum(cg[q] * x[q] for q in range(self.nx))
                scale = abs(g0) + sum(abs(cg[q] * x[q]) for q in range(self.nx))
            else:  # the ODE path's own force law, as its break-away events (ode_g)
                T, scale = self.held_torque(i, x)
            if abs(T) <= self.tc[i] + _HOLD_ROUNDING * scale:  # sticks unless the torque clearly exceeds tc
                self.slip[i] = 0
                self.record(t, EventKind.STICK, 0, T, i)
            else:  # slips on the other way without stopping: an event too (it counts against the budget)
                self.slip[i] = 1 if T > 0.0 else -1
                self.record(t, EventKind.SLIP, self.slip[i], T, i)
            return
        if f.type == 3:
            self.slip[i] = f.target
            self.record(t, EventKind.SLIP, f.target, 0.0, i)
            return
        mode, target = self.mode[i], f.target
        v = self.v_of(i, x)
        side = int(math.copysign(1, mode if mode != 0 else target))
        if target == 0:
            if self.b[i] > 0.0 or self.k[i] <= 0.0:
                self.record(t, EventKind.SEPARATION, side, v, i)
                self.count(i, 4, v)
                self.mode[i] = 0
                return
            if self.law == 1:
                fb = -side * (self.k[i] * self.s_of(i, x) + self.c[i] * v)
                self.mode[i] = -side if fb > 0.0 else -2 * side
                return
            self.mode[i] = -side
            return
        if mode == 0:
            if abs(v) < self.zeno_v:
                self.plastic(i, x)
                self.record(t, EventKind.PLASTIC, side, v, i)
                self.count(i, _CT_PLASTIC[side], v)
            else:
                self.record(t, EventKind.IMPACT, side, v, i)
                self.count(i, _CT_IMPACT[side], v)
            self.mode[i] = target
            return
        self.record(t, EventKind.RELOAD if target in (1, -1) else EventKind.LIFT, side, v, i)
        self.count(i, 5, v)
        self.mode[i] = target

    def affine(self) -> list[float]:
        kn, w = self.kn, self.w
        a = [0.0] * self.nx
        a[w] = self.u1 / self.J[0]
        a[w + self.ns] += self.u2 / self.J[self.ns]
        aff = kn._aff
        for i in range(self.ns):
            m = self.mode[i]
            if m in (1, -1):
                base = (2 * i + (m > 0)) * 2
                a[w + i] += float(aff[base])
                a[w + i + 1] += float(aff[base + 1])
        if kn.friction == 1:
            for j in range(w):
                sl = self.slip[j]
                if sl == 0:
                    a[w + j] = 0.0
                elif sl in (1, -1):
                    a[w + j] -= self.tc[j] * sl / self.J[j]
        return a

    def pattern(self) -> int:
        kn = self.kn
        pat = 0
        for i in range(self.ns):
            if self.mode[i] in (1, -1):
                pat |= 1 << i
        if kn.friction == 1:
            for j in range(self.w):
                if kn._fbit[j] >= 0 and self.slip[j] == 0:
                    pat |= 1 << int(kn._fbit[j])
        return pat

    # -- long steps (trains; see long_try in _kernel.c)
    def long_prepare(self, ld: _LongData, a: list[float], fns: list[_EvFun]) -> dict[str, Any]:
        nx, nf = self.nx, ld.lam.size
        W, V, lam, M3 = ld.W.tolist(), ld.V.tolist(), ld.lam.tolist(), ld.M3.tolist()
        eta = []
        for k in range(nf):
            wr = wi = 0.0
            for i in range(nx):
                wr += W[k][i].real * a[i]
                wi += W[k][i].imag * a[i]
            lr, li = lam[k].real, lam[k].imag
            d = lr * lr + li * li
            eta.append((-(wr * lr + wi * li) / d, -(wi * lr - wr * li) / d))
        wt = ld.wt.tolist()
        rho = float(self.kn._rho[self.kn._slot[self.pattern()]])
        eta_n = 0.0
        for k in range(nf):
            eta_n += wt[k] * math.sqrt(eta[k][0] * eta[k][0] + eta[k][1] * eta[k][1])
        cv, r4, ls = [], [], []
        for f in fns:
            row = []
            for k in range(nf):
                cr = ci = 0.0
                for i in range(nx):
                    cr += f.cg[i] * V[k][i].real
                    ci += f.cg[i] * V[k][i].imag
                row.append((cr, ci))
            cv.append(row)
            r = 0.0
            for j in range(nx):
                acc = 0.0
                for i in range(nx):
                    acc += f.cg[i] * M3[i][j]
                r += acc * acc
            r4.append(math.sqrt(r))
            r = 0.0
            for i in range(nx):
                c = f.cg[i] / rho if i < self.w else f.cg[i]
                r += c * c
            ls.append(math.sqrt(r))
        return {"eta": eta, "cv": cv, "r4": r4, "ls": ls, "eta_n": eta_n, "rho": rho, "gam_a": {}, "lam": lam,
                "W": W, "V": V, "wt": wt, "E": ld.E.tolist(), "e4": ld.e4.tolist(), "dec": ld.dec.tolist(),
                "rig": ld.rig.tolist(), "phis": [P.tolist() for P in ld.phis], "gams": [G.tolist() for G in ld.gams]}

    def long_try(self, ld: _LongData, L: dict[str, Any], lvl: int, fns: list[_EvFun], x0: list[float],
                 dx0: list[float], a: list[float], h_pat: float, pen: list[float]
                 ) -> tuple[float, tuple[list[float], list[float]] | None]:
        nx = self.nx
        H = float(ld.mults[lvl]) * h_pat
        if lvl not in L["gam_a"]:
            L["gam_a"][lvl] = _mv(L["gams"][lvl], a)
        Phi = L["phis"][lvl]
        x1 = [u + v for u, v in zip(_mv(Phi, x0), L["gam_a"][lvl], strict=True)]
        dx1 = _mv(Phi, dx0)
        lam, W, V, wt, E = L["lam"], L["W"], L["V"], L["wt"], L["E"][lvl]
        nf = len(lam)
        w, rho, rig = self.w, L["rho"], L["rig"]
        xd, xn = [], 0.0
        for i in range(w):
            acc = x0[i]
            for j in range(w):
                acc -= rig[i][j] * x0[j]
            xd.append(acc)
            xn += rho * acc * rho * acc
        for i in range(w, nx):
            xd.append(x0[i])
            xn += x0[i] * x0[i]
        xn = math.sqrt(xn) + L["eta_n"]
        gam, lg, emax = [], [], []
        y = list(dx0)
        for k in range(nf):
            re, im = -L["eta"][k][0], -L["eta"][k][1]
            for i in range(nx):
                re += W[k][i].real * xd[i]
                im += W[k][i].imag * xd[i]
            lr = lam[k].real * re - lam[k].imag * im
            li = lam[k].real * im + lam[k].imag * re
            gam.append((re, im))
            lg.append((lr, li))
            for i in range(nx):
                y[i] -= wt[k] * (V[k][i].real * lr - V[k][i].imag * li)
            emax.append(max(1.0, math.sqrt(E[k].real * E[k].real + E[k].imag * E[k].imag)))
        e4f = float(ld.e4[lvl]) * math.sqrt(sum(v * v for v in y))
        for e, f in enumerate(fns):
            cg = f.cg
            ga = gb = f.g0
            da = db = 0.0
            scale, dsc = abs(f.g0), 0.0
            for i in range(nx):
                if cg[i] == 0.0:
                    continue
                ga += cg[i] * x0[i]
                gb += cg[i] * x1[i]
                da += cg[i] * dx0[i]
                db += cg[i] * dx1[i]
                scale += abs(cg[i] * x0[i]) + abs(cg[i] * x1[i])
                dsc += abs(cg[i] * dx0[i]) + abs(cg[i] * dx1[i])
            F0 = F1 = dF0 = dF1 = B = 0.0
            for k in range(nf):
                cr, ci = L["cv"][e][k]
                gr, gi = gam[k]
                lr, li = lg[k]
                ar, ai = cr * gr - ci * gi, cr * gi + ci * gr
                br, bi = cr * lr - ci * li, cr * li + ci * lr
                er, ei = E[k].real, E[k].imag
                F0 += wt[k] * ar
                F1 += wt[k] * (ar * er - ai * ei)
                dF0 += wt[k] * br
                dF1 += wt[k] * (br * er - bi * ei)
                B += wt[k] * math.sqrt(ar * ar + ai * ai) * emax[k]
            S0, S1, D0, D1 = ga - F0, gb - F1, H * (da - dF0), H * (db - dF1)
            lo, hi = _cubic_range(S0, S1, D0, D1, 1.0)
            e4 = L["r4"][e] * e4f
            delta = (_M_SCALE * (scale + H * dsc) + L["dec"][lvl] * L["ls"][e] * xn + _M_FAST * B
                     + _M_CUBIC * (abs(S0) + abs(S1) + abs(D0) + abs(D1)))
            if not (lo - e4 - B - delta > 0.0):
                return _long_fraction(S0, S1, D0, D1, e4 + B + delta, False), None
            if f.type == EVENT_GEOMETRIC and self.mode[f.idx] in (1, -1):
                i = f.idx
                up, slack = hi + e4 + B + delta, 2.0 * (e4 + B + delta)
                if not up <= self.max_pen[i]:
                    if not slack <= _PEN_REL * up:
                        return _long_fraction(S0, S1, D0, D1, self.max_pen[i] - (e4 + B + delta), True), None
                    pen[i] = max(pen[i], up)
        return 1.0, (x1, dx1)

    # -- the exact solver
    def advance_pwl(self) -> int:
        kn, nx = self.kn, self.nx
        guard = 0
        cached, have_dx = False, False
        # set on the first pass (cached and have_dx start False)
        a: list[float]
        gam_a: list[float]
        dx0: list[float]
        dx1: list[float]
        fns: list[_EvFun] = []
        L: dict[str, Any] | None = None  # long steps: per pattern and affine term (see long_try in _kernel.c)
        lcur, wait, backoff = _LMAX, 0, 0
        while self.t < self.t_end:
            pat = self.pattern()
            kn._ensure_pattern(pat)
            q = int(kn._slot[pat])
            A, Phi, Gam = kn._A[q].tolist(), kn._Phi[q].tolist(), kn._Gam[q].tolist()
            rho, h_pat = float(kn._rho[q]), float(kn._h[q])
            if not cached:
                a = self.affine()
                gam_a = _mv(Gam, a)
                fns = self.collect(False)
                cached, have_dx = True, False
            x0 = self.x
            if not have_dx:
                dx0 = [u + v for u, v in zip(_mv(A, x0), a, strict=True)]
            ld = kn._long_info.get(pat) if kn._lv_n[q] > 0 else None
            if ld is not None:  # a train: the longest certified step first
                if L is None:
                    L = self.long_prepare(ld, a, fns)
                if wait > 0:
                    wait -= 1
                else:
                    rem = self.t_end - self.t
                    lvl = -1
                    for j in range(len(ld.mults)):
                        if float(ld.mults[j]) * h_pat <= rem + 1e-9 * h_pat:
                            lvl = j
                    lvl = min(lvl, lcur)
                    got = None
                    pen: list[float] = []
                    while lvl >= 0:
                        pen = [-math.inf] * self.ns
                        frac, got = self.long_try(ld, L, lvl, fns, x0, dx0, a, h_pat, pen)
                        if got is not None:
                            break
                        cap = frac * float(ld.mults[lvl])
                        lvl -= 1
                        while lvl >= 0 and float(ld.mults[lvl]) > cap:
                            lvl -= 1
                    if got is not None:
                        H = float(ld.mults[lvl]) * h_pat
                        self.x, dx0 = got
                        have_dx = True
                        self.t = self.t_end if abs(rem - H) <= 1e-9 * h_pat else self.t + H
                        self.steps += 1
                        lcur, backoff = lvl + 1, 0
                        self.max_pen = [max(m_, q_) for m_, q_ in zip(self.max_pen, pen, strict=True)]
                        for i in range(self.ns):
                            if self.flank_is_label(i, False):
                                self.mode[i] = 1 if self.s_of(i, self.x) >= 0.0 else -1
                        if not all(math.isfinite(v) for v in self.x):
                            return 2
                        continue
                    backoff = min(2 * backoff if backoff else _BACKOFF[0], _BACKOFF[1])
                    wait, lcur = backoff, 0
            remaining = self.t_end - self.t
            h = h_pat
            lands = abs(remaining - h) <= 1e-9 * h
            D = None
            if lands or remaining > h:
                x1 = [u + v for u, v in zip(_mv(Phi, x0), gam_a, strict=True)]
                dx1 = _mv(Phi, dx0)
            else:
                h = remaining
                lands = True
                D = _taylor(A, rho, x0, a, h)
                x1 = _taylor_eval(D, h)
                dx1 = [u + v for u, v in zip(_mv(A, x1), a, strict=True)]
            best, which = -1.0, -1
            for e, f in enumerate(fns):
                cg = f.cg
                ga = f.g0 + sum(cg[i] * x0[i] for i in range(nx))
                gb = f.g0 + sum(cg[i] * x1[i] for i in range(nx))
                da = sum(cg[i] * dx0[i] for i in range(nx))
                db = sum(cg[i] * dx1[i] for i in range(nx))
                dscale = sum(abs(cg[i] * dx0[i]) for i in range(nx))
                if f.type == 3:  # the breakaway threshold clears the rounding of the torques held (_kernel.c)
                    margin = _HOLD_ROUNDING * (sum(abs(cg[i] * x0[i]) for i in range(nx)) + abs(f.g0))
                    ga, gb = ga + margin, gb + margin
                if f.type == 3 and ga < 0.0:
                    tau = 0.0
                else:
                    ga = max(ga, 0.0)
                    if ga == 0.0 and abs(da) <= 1e-12 * dscale:
                        da = 0.0
                    if not (gb <= 0.0 or (da < 0.0 and db > 0.0) or (ga == 0.0 and da <= 0.0)):
                        continue
                    if gb > 0.0 and ga > 0.0 and min(ga, gb) > h * (abs(da) + abs(db)):
                        continue  # an interior minimum that cannot reach zero (see _kernel.c)
                    if ga == 0.0 and da == 0.0 and f.type == EVENT_GEOMETRIC:
                        if self.grazing_leaves(f, x0, h_pat):
                            tau = 0.0
                        else:
                            gscale = sum(abs(cg[i] * x0[i]) for i in range(nx))
                            acc_tol = 1e-3 * self.zeno_v / h_pat
                            thr0, thr2 = 4e-16 * gscale, 0.5 * acc_tol
                            if not (gb < -(thr2 * h * h + thr0)):
                                continue
                            # it stays now, but is clearly past by the step's end (a train's other stages
                            # moved it): the first time it is clearly past (see _kernel.c)
                            if D is None:
                                D = _taylor(A, rho, x0, a, h)
                            tau = _clearly_past(cg, D, h, gb, db, thr0, thr2)
                            if tau < 0.0:
                                tau = h
                    elif ga == 0.0 and f.type == EVENT_FORCE and da <= 0.0:
                        # just switched onto a no_pull force boundary and heading back: wait until the force
                        # is clearly past zero (the rate's sign is rounding there; see _kernel.c)
                        gscale = sum(abs(cg[i] * x0[i]) for i in range(nx))
                        if D is None:
                            D = _taylor(A, rho, x0, a, h)
                        tau = _clearly_past(cg, D, h, gb, db, 4e-16 * gscale,
                                            0.5e-3 * self.zeno_v / h_pat * self.k[f.idx])
                    elif ga == 0.0 and (da < 0.0 or (da == 0.0 and db < 0.0)):
                        tau = 0.0
                    else:
                        if D is None:
                            D = _taylor(A, rho, x0, a, h)
                        qp = [sum(cg[i] * Dn[i] for i in range(nx)) for Dn in D]
                        qp[0] = ga
                        tau = _first_root(qp, h, gb, da, db)
                if tau >= 0.0 and (which < 0 or tau < best - 1e-12 * h):
                    best, which = tau, e
            self.steps += 1
            was = list(self.mode)
            if which < 0:
                self.x = x1
                dx0 = dx1
                have_dx = True
                self.t = self.t_end if lands else self.t + h
                for i in range(self.ns):
                    if self.flank_is_label(i, False):
                        self.mode[i] = 1 if self.s_of(i, x1) >= 0.0 else -1
            else:
                have_dx = False
                cached = False
                L, lcur, wait, backoff = None, _LMAX, 0, 0
                if D is None:
                    D = _taylor(A, rho, x0, a, h)
                self.x = _taylor_eval(D, best)
                self.t = min(self.t + best, self.t_end)
                self.transition(fns[which], self.x, self.t)
                guard += 1
                if self.n_events > self.budget or guard > 4 * max(self.budget, 1):
                    return _ST_EVENTS
            for i in range(self.ns):
                if was[i] not in (1, -1):
                    continue
                self.max_pen[i] = max(self.max_pen[i], abs(self.s_of(i, self.x)) - self.b[i])
                va, vb = self.v_of(i, x0), self.v_of(i, x1)
                if which < 0 and va * vb < 0.0:
                    sa, sb = self.s_of(i, x0), self.s_of(i, x1)
                    th = va / (va - vb)
                    h00, h10 = 2 * th**3 - 3 * th**2 + 1, th**3 - 2 * th**2 + th
                    h01, h11 = -2 * th**3 + 3 * th**2, th**3 - th**2
                    sm = h00 * sa + h10 * h * va + h01 * sb + h11 * h * vb
                    self.max_pen[i] = max(self.max_pen[i], abs(sm) - self.b[i])
            if not all(math.isfinite(v) for v in self.x):
                return 2
        return 0

    # -- the nonlinear solver
    def rhs(self, x: list[float]) -> list[float]:
        w, ns = self.w, self.ns
        F = [self.force(i, self.mode[i], self.dys[i], x) for i in range(ns)]
        dx = [0.0] * self.nx
        fr_kind = self.kn.friction
        for j in range(w):
            dx[j] = x[w + j]
            if fr_kind == 1 and self.slip[j] == 0:
                dx[j] = 0.0
                dx[w + j] = 0.0
                continue
            T = self.u1 if j == 0 else (self.u2 if j == ns else 0.0)
            if j < ns:
                T = T - self.rb1[j] * F[j]
            if j >= 1:
                T = T + self.rb2[j - 1] * F[j - 1]
            fr = self.d[j] * x[w + j]
            if fr_kind == 2 and self.tc[j] > 0.0:
                fr += self.tc[j] * math.tanh(x[w + j] / self.p.coulomb_velocity)
            if fr_kind == 1 and self.slip[j] in (1, -1):
                fr += self.tc[j] * self.slip[j]
            dx[w + j] = (T - fr) / self.J[j]
        return dx

    def held_torque(self, j: int, x: list[float]) -> tuple[float, float]:
        """Torque shaft j needs from friction to stay at rest, from the plant's own force law, and the sum of
        the magnitudes of its terms (their rounding)."""
        T = -self.d[j] * x[self.w + j] + (self.u1 if j == 0 else 0.0) + (self.u2 if j == self.ns else 0.0)
        scale = abs(T)
        if j >= 1:
            tq = self.rb2[j - 1] * self.force(j - 1, self.mode[j - 1], self.dys[j - 1], x)
            T += tq
            scale += abs(tq)
        if j < self.ns:
            tq = self.rb1[j] * self.force(j, self.mode[j], self.dys[j], x)
            T -= tq
            scale += abs(tq)
        return T, scale

    def ode_g(self, f: _EvFun, x: list[float]) -> float:
        if f.type != 3:
            return f.g0 + sum(f.cg[i] * x[i] for i in range(self.nx))
        j = f.idx
        T, scale = self.held_torque(j, x)
        return self.tc[j] * (1.0 + _BREAKAWAY) + _HOLD_ROUNDING * scale - f.target * T

    def advance_ode(self) -> int:
        kn, prm, nx, w = self.kn, self.kn._prm, self.nx, self.w
        st = kn._st
        h = st.h_ode if st.h_ode > 0.0 else prm.h_max * 0.1
        k1 = None
        rejects = guard = 0
        while self.t < self.t_end:
            y = self.x
            if k1 is None:
                k1 = self.rhs(y)
            h = min(h, prm.h_max)
            last = False
            if self.t + h >= self.t_end - 1e-15 * abs(self.t_end):
                h = self.t_end - self.t
                last = True

            def stage(coefs: list[tuple[float, list[float]]], h: float = h, y: list[float] = y) -> list[float]:
                return [y[i] + h * sum(c * k[i] for c, k in coefs) for i in range(nx)]

            k2 = self.rhs(stage([(_A21, k1)]))
            k3 = self.rhs(stage([(_A31, k1), (_A32, k2)]))
            k4 = self.rhs(stage([(_A41, k1), (_A42, k2), (_A43, k3)]))
            k5 = self.rhs(stage([(_A51, k1), (_A52, k2), (_A53, k3), (_A54, k4)]))
            k6 = self.rhs(stage([(_A61, k1), (_A62, k2), (_A63, k3), (_A64, k4), (_A65, k5)]))
            y1 = stage([(_A71, k1), (_A73, k3), (_A74, k4), (_A75, k5), (_A76, k6)])
            k7 = self.rhs(y1)
            err = 0.0
            for i in range(nx):
                sk = (prm.atol_angle if i < w else prm.atol_rate) + prm.rtol * max(abs(y[i]), abs(y1[i]))
                ei = h * (_E1 * k1[i] + _E3 * k3[i] + _E4 * k4[i] + _E5 * k5[i] + _E6 * k6[i] + _E7 * k7[i]) / sk
                err += ei * ei
            err = math.sqrt(err / nx)
            if not math.isfinite(err):
                return 2
            fac = min(5.0, 0.9 * err**-0.2) if err > 0.0 else 5.0
            if err > 1.0:
                h *= max(fac, 0.2)
                rejects += 1
                if rejects > 100000 or h < 1e-16 * (abs(self.t) + 1e-9):
                    return 4
                continue
            self.steps += 1
            fns = self.collect(True)
            best, which = 2.0, -1
            r = None

            def dense_of(r: tuple[list[float], ...], th: float) -> list[float]:
                return [r[0][i] + th * (r[1][i] + (1 - th) * (r[2][i] + th * (r[3][i] + (1 - th) * r[4][i])))
                        for i in range(nx)]

            def make_dense(h: float = h, y: list[float] = y, y1: list[float] = y1, k1: list[float] = k1,
                           k3: list[float] = k3, k4: list[float] = k4, k5: list[float] = k5, k6: list[float] = k6,
                           k7: list[float] = k7) -> tuple[list[float], ...]:
                r1 = [y1[i] - y[i] for i in range(nx)]
                r2 = [h * k1[i] - r1[i] for i in range(nx)]
                r3 = [r1[i] - h * k7[i] - r2[i] for i in range(nx)]
                r4 = [h * (_D1 * k1[i] + _D3 * k3[i] + _D4 * k4[i] + _D5 * k5[i] + _D6 * k6[i] + _D7 * k7[i])
                      for i in range(nx)]
                return (y, r1, r2, r3, r4)

            for e, f in enumerate(fns):
                ga, gb = self.ode_g(f, y), self.ode_g(f, y1)
                if f.type == 3 and ga < 0.0:
                    best, which = 0.0, e
                    break
                if f.type == EVENT_GEOMETRIC and ga >= 0.0 and gb <= 0.0:
                    da = sum(f.cg[i] * k1[i] for i in range(nx))
                    dscale = sum(abs(f.cg[i] * k1[i]) for i in range(nx))
                    gscale = sum(abs(f.cg[i] * y[i]) for i in range(nx))
                    if ga <= 4e-16 * gscale and abs(da) <= 1e-12 * dscale:
                        if self.grazing_leaves(f, y, h):
                            best, which = 0.0, e
                            break
                        acc_tol = 1e-3 * self.zeno_v / h
                        if gb >= -(0.5 * acc_tol * h * h + 4e-16 * gscale):
                            continue
                if f.type == EVENT_GEOMETRIC and ga < 0.0:
                    # already past this flank at the step's start: a grazing approach the rule above let go on
                    # (it stays on its side only within the band) that then crept past. Contact now, once clearly
                    # past the band; else no root would ever be found again and the teeth would pass through
                    gscale = sum(abs(f.cg[i] * y[i]) for i in range(nx))
                    if ga < -(0.5e-3 * self.zeno_v * h + 4e-16 * gscale):
                        best, which = 0.0, e
                        break
                    continue
                if not gb <= 0.0 or ga < 0.0:
                    continue
                if r is None:
                    r = make_dense()
                lo, hi, flo, fhi = 0.0, 1.0, ga, gb
                if ga == 0.0:
                    lo = 1e-12
                    flo = self.ode_g(f, dense_of(r, lo))
                    if flo <= 0.0:
                        best, which = 0.0, e
                        break
                it = 0
                while it < 200 and hi - lo > 1e-15:
                    th = hi - fhi * (hi - lo) / (fhi - flo)
                    if not (lo < th < hi):
                        th = 0.5 * (lo + hi)
                    ft = self.ode_g(f, dense_of(r, th))
                    if ft > 0.0:
                        lo, flo, fhi = th, ft, fhi * 0.5
                    else:
                        hi, fhi, flo = th, ft, flo * 0.5
                    it += 1
                if hi < best:
                    best, which = hi, e
            if which >= 0:
                if best > 0.0:  # a root on the dense output (an exit at once, best = 0, needs none)
                    assert r is not None
                    self.x = dense_of(r, best)
                    self.t += best * h
                f = fns[which]
                self.transition(f, self.x, self.t)
                if f.type <= 1:
                    i = f.idx
                    self.mode[i] = 1 if self.mode[i] > 0 else (-1 if self.mode[i] < 0 else 0)
                    if self.p.kind is PlantKind.YANG_SUN and self.mode[i] != 0:
                        self.dys[i] = yang_sun_damping_factor(self.k[i], abs(self.v_of(i, self.x)))
                k1 = None
                guard += 1
                if self.n_events > self.budget or guard > 4 * max(self.budget, 1):
                    return _ST_EVENTS
            else:
                self.x = y1
                k1 = k7
                self.t = self.t_end if last else self.t + h
                if not last:
                    st.h_ode = h * fac
                h *= fac
            for i in range(self.ns):
                if self.flank_is_label(i, True):
                    self.mode[i] = 1 if self.s_of(i, self.x) >= 0.0 else -1
            for i in range(self.ns):
                if self.mode[i] != 0:
                    self.max_pen[i] = max(self.max_pen[i], abs(self.s_of(i, self.x)) - self.b[i])
            if not all(math.isfinite(v) for v in self.x):
                return 2
        return 0
