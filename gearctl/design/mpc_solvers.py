"""The MPC's QP backends: gearctl's exact dense solver and CasADi's conic plugins behind one interface.

:class:`gearctl.design.mpc.MPC` builds its condensed QPs once (one per contact pattern) and, every sample, forms the
gradient and the rows' bounds from the plan's parameters and solves. This module holds what does the solving:

- :class:`_GearctlQP`, gearctl's own exact active-set solver (:class:`gearctl.qp.DenseQP`), compiled C that the
  exported controller runs too (the ``gearctl`` setting, the default);
- :class:`_QP`, a CasADi ``conic`` plugin (``daqp``, ``qrqp``, ``osqp``, ``proxqp``), compiled through CasADi's code
  generator where it can be and called through ctypes, or else called through ``casadi.conic``;
- :func:`_make_qp`, which picks one for a setting and falls back (stated in the solver's ``note``) where the
  compiled code cannot be built;
- :class:`_MutedStdout`, which keeps the plugins that print on standard output out of gearctl's own output.

Each backend checks the solution it returns (status and a KKT residual relative to the data); a failed solve is
reported to the MPC, which falls back on its shifted plan (see :mod:`gearctl.design.mpc`).
"""

from __future__ import annotations

import ctypes
import math
import os
import tempfile
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..build import CompileError, c_compiler, compile_disabled, shared_library
from ..errors import SolverError

if TYPE_CHECKING:
    from .mpc import _Pattern

__all__ = ["SOLVERS", "FALLBACK_SOLVER", "installed_solvers"]

#: QP solvers the MPC offers: gearctl's own exact dense solver (:class:`gearctl.qp.DenseQP`, the default:
#: the exported C controller runs the same code) and CasADi conic plugins (``daqp`` and ``qrqp`` compiled).
SOLVERS = ("daqp", "qrqp", "osqp", "proxqp", "gearctl")
#: The CasADi plugin the ``gearctl`` setting falls back to where the C solver cannot be built.
FALLBACK_SOLVER = "qrqp"
_COMPILABLE = ("daqp", "qrqp")
# quiet options per plugin, and the relative KKT tolerance a solution of that solver must meet
_PLUGIN_OPTIONS: dict[str, dict[str, Any]] = {
    "daqp": {},
    "qrqp": {"print_iter": False, "print_header": False, "print_info": False},
    "osqp": {"osqp": {"verbose": False, "eps_abs": 1e-8, "eps_rel": 1e-8, "polishing": True},
             "warm_start_primal": True, "warm_start_dual": True},
    "proxqp": {"proxqp": {"eps_abs": 1e-9}, "warm_start_primal": True, "warm_start_dual": True},
}
_KKT_TOL = {"daqp": 1e-4, "qrqp": 1e-4, "osqp": 1e-3, "proxqp": 1e-3}
#: CasADi plugins whose C code prints to the process's standard output whatever their options say: OSQP's polish step
#: prints "Polishing not needed - no active set detected at optimal point" on every solve without an active bound
#: (``verbose = False`` does not reach it). Their solves run with file descriptor 1 on the null device: before, the
#: lines went into ``gearctl track --json`` and ``--csv -`` output and broke it (a reviewer's ``solver = "osqp"``).
_MUTED_PLUGINS = ("osqp",)


def installed_solvers() -> tuple[str, ...]:
    """The entries of :data:`SOLVERS` usable in this installation.

    ``gearctl`` always is (compiled where a C compiler exists, else through CasADi's
    :data:`FALLBACK_SOLVER`, which :meth:`MPC.describe` then states); a CasADi plugin is if it loads.
    """
    return tuple(s for s in SOLVERS if _plugin_loads(s))


_PLUGIN_OK: dict[str, bool] = {}


def _plugin_loads(plugin: str) -> bool:
    if plugin == "gearctl":  # part of gearctl (with a CasADi fallback)
        return True
    if plugin not in _PLUGIN_OK:
        import casadi as ca

        try:
            ca.conic("probe", plugin, {"h": ca.Sparsity.dense(1, 1), "a": ca.Sparsity(0, 1)},
                     dict(_PLUGIN_OPTIONS.get(plugin, {})))
            _PLUGIN_OK[plugin] = True
        except RuntimeError:
            _PLUGIN_OK[plugin] = False
    return _PLUGIN_OK[plugin]

# --- the QP solver ---------------------------------------------------------------------------------------


#: Process-wide state of the muting (file descriptor 1 is the process's, shared by every thread): how many calls are
#: muted at once, the descriptor stdout had before the first of them, and the null device (opened once, kept open).
_MUTE_LOCK = threading.Lock()
_mute_depth = 0
_mute_saved: int | None = None
_mute_null: int | None = None


class _MutedStdout:
    """Runs calls with the process's standard output (file descriptor 1) on the null device, for C code that
    prints (:data:`_MUTED_PLUGINS`). Python's and C's buffers are flushed before and after, so that nothing else
    written to standard output before or after is lost or reordered. Where descriptors cannot be juggled the call
    runs as it is.

    Descriptor 1 belongs to the process, not to a thread: the muting is counted across threads (a Dask worker with
    several threads runs several MPCs at once), the first call in saves the descriptor and the last one out
    restores it, and one null device serves them all. (Each call saving and restoring its own let a call that
    began while another was muted save the null device as standard output and restore it last: the process's
    standard output stayed on /dev/null for good.) While any call is muted, whatever another thread writes to
    standard output is lost too."""

    def __init__(self) -> None:
        try:
            self._fflush: Any = ctypes.CDLL(None).fflush  # C's stdio buffer: flushed to the descriptor it was meant for
            self._fflush.argtypes = [ctypes.c_void_p]
        except (OSError, TypeError, AttributeError):
            self._fflush = None

    def _flush(self) -> None:
        import sys

        try:
            sys.stdout.flush()
        except (AttributeError, OSError, ValueError):
            pass
        if self._fflush is not None:
            self._fflush(None)

    def _mute(self) -> bool:
        """Point descriptor 1 at the null device (the first call in), count this call; False where it cannot."""
        global _mute_depth, _mute_saved, _mute_null
        with _MUTE_LOCK:
            if _mute_depth == 0:
                try:
                    if _mute_null is None:
                        _mute_null = os.open(os.devnull, os.O_WRONLY)
                    self._flush()
                    saved = os.dup(1)
                except OSError:
                    return False
                try:
                    os.dup2(_mute_null, 1)
                except OSError:
                    os.close(saved)
                    return False
                _mute_saved = saved
            _mute_depth += 1
            return True

    def _unmute(self) -> None:
        """Uncount this call; the last one out gives descriptor 1 back."""
        global _mute_depth, _mute_saved
        with _MUTE_LOCK:
            _mute_depth -= 1
            if _mute_depth == 0 and _mute_saved is not None:
                if self._fflush is not None:
                    self._fflush(None)  # what the C code buffered goes to the null device
                saved, _mute_saved = _mute_saved, None
                os.dup2(saved, 1)
                os.close(saved)

    def call(self, fn: Any, **kwargs: Any) -> Any:
        """``fn(**kwargs)`` with standard output muted."""
        if not self._mute():
            return fn(**kwargs)
        try:
            return fn(**kwargs)
        finally:
            self._unmute()


class _QP:
    """One dense QP ``min 1/2 x'Hx + g'x, lbx <= x <= ubx, lba <= A x <= uba`` per call, built once.

    The CasADi Function ``qp(h, g, lbx, ubx, x0, lam_x0, a, lba, uba) -> (x, lam_x, lam_a, cost, kkt)``
    wraps the conic and appends a check (``kkt``: the larger of the primal infeasibility and the
    stationarity residual relative to the data). It is compiled and called through ctypes where
    possible; the caller fills the input buffers in place and points ``h`` and ``a`` at arrays it keeps.
    """

    def __init__(self, n: int, m: int, plugin: str, *, compiled: bool | None = None) -> None:
        import casadi as ca

        self.n, self.m, self.plugin = n, m, plugin
        self._new_conic = lambda: ca.conic("mpc_conic", plugin, {"h": ca.Sparsity.dense(n, n),
                                                                  "a": ca.Sparsity.dense(m, n)},
                                           {**_PLUGIN_OPTIONS[plugin], "error_on_fail": False})
        self._conic = conic = self._new_conic()
        h, g, a = ca.MX.sym("h", n, n), ca.MX.sym("g", n), ca.MX.sym("a", m, n)
        lbx, ubx, x0, l0 = (ca.MX.sym(s, n) for s in ("lbx", "ubx", "x0", "lam_x0"))
        lba, uba = ca.MX.sym("lba", m), ca.MX.sym("uba", m)
        sol = conic(h=h, g=g, a=a, lba=lba, uba=uba, lbx=lbx, ubx=ubx, x0=x0, lam_x0=l0)
        x, lam_x, lam_a = sol["x"], sol["lam_x"], sol["lam_a"]
        hx, ax = ca.mtimes(h, x), ca.mtimes(a, x)
        stat = hx + g + lam_x + ca.mtimes(a.T, lam_a)  # stationarity of the Lagrangian
        pinf = ca.fmax(ca.fmax(ca.mmax(ca.fmax(lbx - x, x - ubx)), ca.mmax(ca.fmax(lba - ax, ax - uba))), 0)
        kkt = ca.fmax(ca.norm_inf(stat) / (1 + ca.norm_inf(g) + ca.norm_inf(hx)), pinf)
        fname = f"gearctl_mpc_{plugin}_{n}_{m}"
        self.function = ca.Function(fname, [h, g, lbx, ubx, x0, l0, a, lba, uba],
                                    [x, lam_x, lam_a, sol["cost"], kkt],
                                    ["h", "g", "lbx", "ubx", "x0", "lam_x0", "a", "lba", "uba"],
                                    ["x", "lam_x", "lam_a", "cost", "kkt"])
        # buffers the caller fills in place (h and a are replaced by the caller's arrays)
        self.h = np.zeros((n, n))
        self.a = np.zeros((m, n), order="F")  # CasADi stores dense matrices column-major
        self.lbx, self.ubx, self.x0, self.lam_x0 = (np.zeros(n) for _ in range(4))
        self.gl = np.zeros(n + m)  # the gradient and the rows' lower bounds, filled by one product
        self.g, self.lba = self.gl[:n], self.gl[n:]
        self.uba = np.zeros(m)
        self.x, self.lam_x, self.lam_a = np.zeros(n), np.zeros(n), np.zeros(m)
        self.cost, self.kkt = np.zeros(1), np.zeros(1)
        self.tol = _KKT_TOL[plugin]
        self._dm: dict[tuple[int, int], tuple[Any, Any]] = {}  # CasADi path: H and A as DM, per pattern
        self._h_dm: Any  # the pair of the pattern in use (set by set_matrices)
        self._a_dm: Any
        self._muted = _MutedStdout() if plugin in _MUTED_PLUGINS else None
        self.compiled = False
        self.note = ""
        want = compiled if compiled is not None else not compile_disabled()
        if want and plugin in _COMPILABLE:
            try:
                self._load(self._build(fname))
                self.compiled = True
            except (OSError, CompileError, RuntimeError, AttributeError) as exc:
                if compiled:
                    raise SolverError(f"could not compile the {plugin} QP: {exc}") from exc
                self.note = f"compiled path unavailable ({type(exc).__name__}: {exc}); calling CasADi"
        elif plugin not in _COMPILABLE:
            self.note = f"{plugin} is called through CasADi (no code generation)"

    def reset(self) -> None:
        """Forget every earlier solve, as a new instance would: the warm-start buffers are zeroed and, on the
        CasADi path, the conic is made anew. (OSQP keeps its workspace in the conic between calls, its adaptive
        step size rho among it: an MPC reused for another run after ``reset`` solved from the last run's state and
        its run differed from a fresh MPC's, by 25 % of the RMS error in a 0.3 s run. A sweep builds its controllers
        once per worker thread, so its results hung on which runs a thread had run before: a sweep on a running
        cluster differed from the same sweep run locally, and from itself when run again.)"""
        for buf in (self.x0, self.lam_x0, self.x, self.lam_x, self.lam_a, self.cost, self.kkt):
            buf[:] = 0.0
        if not self.compiled:
            self._conic = self._new_conic()

    def _build(self, fname: str) -> ctypes.CDLL:
        """Generate C for :attr:`function` and build it (once per source) through :mod:`gearctl.build`."""
        import casadi as ca

        if c_compiler() is None:
            raise OSError("no C compiler found")
        casadi_dir = Path(ca.__file__).parent
        with tempfile.TemporaryDirectory() as tmp:
            gen = ca.CodeGenerator(f"{fname}.c", {"with_header": False})
            gen.add(self.function)
            src = Path(gen.generate(tmp + os.sep)).read_bytes()  # the prefix: a directory
        libs = ["-lm"]
        if self.plugin == "daqp":  # the wheel ships libdaqp.so next to CasADi's own libraries
            libs = [f"-L{casadi_dir}", "-ldaqp", f"-Wl,-rpath,{casadi_dir}", "-lm"]
        lib = shared_library(fname, {f"{fname}.c": src}, libs=libs, include=[casadi_dir / "include"],
                             required=True)
        assert lib is not None
        return lib

    def _load(self, lib: ctypes.CDLL) -> None:
        fname = self.function.name()
        sizes = [ctypes.c_longlong() for _ in range(4)]
        getattr(lib, f"{fname}_work")(*[ctypes.byref(s) for s in sizes])
        n_arg, n_res, n_iw, n_w = (s.value for s in sizes)
        getattr(lib, f"{fname}_incref")()
        self._mem = getattr(lib, f"{fname}_checkout")()
        ins = [self.h, self.g, self.lbx, self.ubx, self.x0, self.lam_x0, self.a, self.lba, self.uba]
        outs = [self.x, self.lam_x, self.lam_a, self.cost, self.kkt]
        self._arg = (ctypes.c_void_p * n_arg)(*[x.ctypes.data for x in ins])
        self._res = (ctypes.c_void_p * n_res)(*[x.ctypes.data for x in outs])
        self._iw = (ctypes.c_longlong * max(n_iw, 1))()
        self._w = (ctypes.c_double * max(n_w, 1))()
        fn = getattr(lib, fname)
        fn.restype = ctypes.c_int
        fn.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_int]
        self._fn, self._lib = fn, lib

    def prepare(self, pat: _Pattern) -> None:
        """Per-pattern work done once (nothing here: the compiled path reads ``pat.ptr``)."""

    def form(self, pat: _Pattern, sig: int, p: NDArray[np.float64]) -> None:
        """The gradient and the rows' lower bounds of pattern ``pat`` (flank ``sig``): ``gl = M[sig] p``."""
        np.dot(pat.M[sig], p, out=self.gl)

    def use(self, pat: _Pattern, sig: int) -> None:
        """Use the Hessian and the rows of pattern ``pat`` (flank ``sig``) for the next solves."""
        self.set_matrices(pat.H, pat.A[sig], pat.ptr[sig])

    def set_matrices(self, H: NDArray[np.float64], A: NDArray[np.float64], ptr: tuple[int, int]) -> None:
        """Use ``H`` (symmetric) and ``A`` (Fortran order, data addresses ``ptr``) for the next solves.

        The caller keeps both arrays alive.
        """
        if self.compiled:
            self._arg[0], self._arg[6] = ptr
        else:  # CasADi converts a numpy matrix on every call (~40 us each here): convert once per pattern
            dm = self._dm.get(ptr)
            if dm is None:
                import casadi as ca

                dm = self._dm[ptr] = (ca.DM(H), ca.DM(np.ascontiguousarray(A)))
            self._h_dm, self._a_dm = dm
        self.h, self.a = H, A

    def solve(self) -> str:
        """Solve with the current buffers; the solution lands in ``x``, ``lam_x``, ``lam_a``, ``cost``.

        Returns ``"ok"`` or why the solution is rejected.
        """
        if self.compiled:
            flag = self._fn(self._arg, self._res, self._iw, self._w, self._mem)
            if flag:
                return f"{self.plugin} returned flag {flag}"
        else:  # through CasADi: the conic itself (its stats carry the solver's status), the check in numpy
            args = dict(h=self._h_dm, g=self.g, a=self._a_dm, lba=self.lba, uba=self.uba, lbx=self.lbx, ubx=self.ubx,
                        x0=self.x0, lam_x0=self.lam_x0)
            sol = self._conic(**args) if self._muted is None else self._muted.call(self._conic, **args)
            stats = self._conic.stats()
            for buf, name in ((self.x, "x"), (self.lam_x, "lam_x"), (self.lam_a, "lam_a"), (self.cost, "cost")):
                buf[:] = np.asarray(sol[name]).ravel()
            if not stats.get("success", False):
                return f"{self.plugin}: {stats.get('return_status', 'failed')}"
            x, hx, ax = self.x, self.h @ self.x, self.a @ self.x
            stat = hx + self.g + self.lam_x + self.a.T @ self.lam_a
            pinf = max(float(np.max(self.lbx - x)), float(np.max(x - self.ubx)), float(np.max(self.lba - ax)),
                       float(np.max(ax - self.uba)), 0.0)
            scale = 1.0 + float(np.max(np.abs(self.g))) + float(np.max(np.abs(hx)))
            self.kkt[0] = max(float(np.max(np.abs(stat))) / scale, pinf)
        k = self.kkt[0]
        if not k <= self.tol:  # also catches NaN
            return f"{self.plugin} solution fails the KKT check ({k:.2g} > {self.tol:g})"
        return "ok"


class _GearctlQP:
    """The same interface as :class:`_QP` on gearctl's exact dense solver (:class:`gearctl.qp.DenseQP`).

    One :class:`~gearctl.qp.QPFactor` per pattern Hessian and the pattern's rows in C order are prepared
    once (:meth:`prepare`); a solve copies the gradient and the row bounds into the solver's buffers and
    calls it cold (from the unconstrained minimiser): no primal warm start, so the solution does not
    depend on the history of solves, as in the exported C controller. The solver is exact (an active-set
    method): its status replaces CasADi's KKT check, and inactive multipliers are exact zeros.

    Raises
    ------
    SolverError
        Where the C solver cannot be built (no compiler, ``GEARCTL_NO_COMPILE``).
    """

    plugin = "gearctl"
    compiled = True
    tol = 0.0  # ``kkt`` is 0 for a solved QP, inf otherwise

    def __init__(self, n: int, m: int) -> None:
        from ..qp import DenseQP, matvec_function

        self._dqp = q = DenseQP(n, m)
        self.n, self.m = n, m
        self.lbx, self.ubx = q.lbx, q.ubx
        self.x0, self.lam_x0 = np.zeros(n), np.zeros(n)  # the shifted plan: the fallback (not a warm start)
        self.gl = np.zeros(n + m)
        self.g, self.lba = self.gl[:n], self.gl[n:]
        self._gl_ptr, self._matvec = self.gl.ctypes.data, matvec_function()
        self.uba = q.uba
        self.x, self.lam_x, self.lam_a, self.cost = q.x, q.lam_x, q.lam_a, q.cost
        self.kkt = np.zeros(1)
        self.h: NDArray[np.float64] = np.eye(n)
        self.a: NDArray[np.float64] = q.a
        self._factor: Any = None
        self.note = "gearctl dense QP (Goldfarb-Idnani dual active set, C99), cold start"

    def reset(self) -> None:
        """Forget every earlier solve (the solver itself starts cold each time: only the fallback plan's buffers)."""
        self.x0[:] = 0.0
        self.lam_x0[:] = 0.0

    def prepare(self, pat: _Pattern) -> None:
        """Factor the pattern's Hessian, keep its rows and its gradient maps in C order (once per pattern)."""
        maps = {sig: np.ascontiguousarray(M) for sig, M in pat.M.items()}
        pat.solver_data = (self._dqp.factor(pat.H), {sig: np.ascontiguousarray(A) for sig, A in pat.A.items()},
                           {sig: (M.shape[0], M.shape[1], M.ctypes.data, M) for sig, M in maps.items()})

    def form(self, pat: _Pattern, sig: int, p: NDArray[np.float64]) -> None:
        """``gl = M[sig] p``, each row summed in index order in C (:func:`gearctl.qp.matvec`): the same
        rounding on every machine and in the exported controller, which sums its rows the same way."""
        rows, cols, ptr, _ = pat.solver_data[2][sig]
        self._matvec(rows, cols, ptr, p.ctypes.data, self._gl_ptr)

    def use(self, pat: _Pattern, sig: int) -> None:
        """Use the Hessian factor and the rows of pattern ``pat`` (flank ``sig``) for the next solves."""
        factor, rows = pat.solver_data[:2]
        self._factor = factor
        self.h, self.a = pat.H, rows[sig]
        self._dqp.use_rows(self.a)

    def solve(self) -> str:
        """Solve with the current buffers; ``"ok"`` or the solver's status name."""
        q, n = self._dqp, self.n
        q.g[:] = self.gl[:n]
        q.lba[:] = self.gl[n:]
        status = q.solve(self._factor)
        if status:  # not SOLVED: the outputs describe the last iterate
            self.kkt[0] = math.inf
            return f"gearctl QP: {status.name.lower().replace('_', ' ')}"
        self.kkt[0] = 0.0
        return "ok"


def _make_qp(n: int, m: int, solver: str, compiled: bool | None) -> _QP | _GearctlQP:
    """The QP backend of a solver setting (``gearctl`` falls back to CasADi's :data:`FALLBACK_SOLVER`).

    ``compiled``: True forces compiled code (an error if it cannot be built), False forbids it (``gearctl``
    then runs the fallback through CasADi), None takes compiled code where a C compiler exists.
    """
    if solver != "gearctl":
        return _QP(n, m, solver, compiled=compiled)
    if compiled is not False:
        try:
            return _GearctlQP(n, m)
        except SolverError as exc:
            if compiled:
                raise
            why = str(exc)
    else:
        why = "compiled code not wanted (compiled=False)"
    qp = _QP(n, m, FALLBACK_SOLVER, compiled=False)
    qp.note = (f"gearctl QP solver unavailable ({why}); solving with CasADi's {FALLBACK_SOLVER} plugin "
               f"through casadi.conic instead")
    return qp


