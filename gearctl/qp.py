"""Dense convex QP solver (Goldfarb–Idnani dual active set) in C, called through :mod:`ctypes`.

Solves ``min 1/2 x'Hx + g'x`` subject to ``lbx <= x <= ubx`` and ``lba <= A x <= uba`` exactly (an
active-set method: the solution satisfies the KKT conditions to rounding), with the C file
``csrc/qp/gearctl_qp.c`` that exported controllers carry as well, so that a controller in Python and
its exported C run the same solver code.

- :meth:`DenseQP.factor` factors a Hessian once (Cholesky, then the inverse factor); keep one
  :class:`QPFactor` per Hessian, a solve does no O(n^3) work.
- :meth:`DenseQP.solve` solves with the data in the object's preallocated buffers (``g``, ``a``,
  ``lbx``, ``ubx``, ``lba``, ``uba``) and writes ``x``, ``lam_x``, ``lam_a``, ``cost`` and ``active``
  in place; nothing is allocated per call.

Conventions
-----------
- ``a`` (or the array given to :meth:`DenseQP.use_rows`) is ``(m, n)`` in C (row-major) order.
- A bound whose magnitude is at least ``infinity`` (1e20 by default), or ``+-inf``, is absent;
  ``lb == ub`` makes an equality.
- Multipliers follow CasADi: ``H x + g + lam_x + A' lam_a = 0``; positive where the upper bound is
  active, negative where the lower bound is, exactly 0 where inactive.
- ``active`` (int8, bounds of x then rows): -1 at the lower bound, +1 at the upper, 2 an equality, 0
  inactive. With ``solve(..., warm=True)`` its -1/+1 entries are the working set to start from (any
  guess is safe: dependent entries are skipped, wrong-sign multipliers removed first).

References
----------
D. Goldfarb, A. Idnani, "A numerically stable dual method for solving strictly convex quadratic
programs", Math. Programming 27 (1983) 1-33.
"""

from __future__ import annotations

import ctypes
import enum
import functools
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .build import CompileError, compile_disabled, shared_library
from .errors import InputError, SolverError

__all__ = ["DenseQP", "QPFactor", "QPStatus", "SOURCE_DIR", "matvec_function"]

#: Folder of the solver's C sources (``gearctl_qp.h``, ``gearctl_qp.c``).
SOURCE_DIR = Path(__file__).parent / "csrc" / "qp"
_SOURCES = ("gearctl_qp.h", "gearctl_qp.c")
_CFLAGS = ("-std=c99", "-O3")  # ISO C: no FMA contraction (see gearctl_qp.h)


class QPStatus(enum.IntEnum):
    """Status codes of the C solver (``GEARCTL_QP_*`` in ``gearctl_qp.h``)."""

    SOLVED = 0
    INFEASIBLE = 1
    ITERATION_LIMIT = 2
    NUMERICAL = 3
    NOT_POSDEF = 4
    INVALID = 5


_STATUS = tuple(QPStatus)  # index -> member: cheaper per call than QPStatus(code)
_INVALID = int(QPStatus.INVALID)


class _Settings(ctypes.Structure):
    _fields_ = [("max_iter", ctypes.c_int), ("primal_tol", ctypes.c_double),
                ("dependence_tol", ctypes.c_double), ("infinity", ctypes.c_double)]


class _Problem(ctypes.Structure):
    _fields_ = [("n", ctypes.c_int), ("m", ctypes.c_int)] + [
        (name, ctypes.c_void_p) for name in ("factor", "g", "a", "lbx", "ubx", "lba", "uba")]


class _Result(ctypes.Structure):
    _fields_ = [(name, ctypes.c_void_p) for name in ("x", "lam_x", "lam_a", "cost", "active")] + [
        ("iterations", ctypes.c_int)]


# --- building and loading ------------------------------------------------------------------------------


def _library() -> ctypes.CDLL:
    """The compiled solver, built on first use through :mod:`gearctl.build` (one file per source version).

    Raises
    ------
    SolverError
        Without a C compiler, with ``GEARCTL_NO_COMPILE`` set, or when compiling fails.
    """
    if compile_disabled():
        raise SolverError("the QP solver is C only, and GEARCTL_NO_COMPILE forbids compiling it")
    sources = {f: (SOURCE_DIR / f).read_bytes() for f in _SOURCES}
    try:
        lib = shared_library("gearctl_qp", sources, flags=_CFLAGS, required=True)
    except CompileError as exc:
        raise SolverError(f"could not build the QP solver: {exc}") from exc
    assert lib is not None
    return lib


@functools.cache
def _lib() -> ctypes.CDLL:
    """Load the solver library once per process and declare its signatures."""
    lib = _library()
    lib.gearctl_qp_factor.restype = ctypes.c_int
    lib.gearctl_qp_factor.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p]
    lib.gearctl_qp_solve.restype = ctypes.c_int
    lib.gearctl_qp_solve.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int, ctypes.c_void_p,
                                     ctypes.c_void_p]
    lib.gearctl_qp_work_size.restype = ctypes.c_long
    lib.gearctl_qp_work_size.argtypes = [ctypes.c_int, ctypes.c_int]
    lib.gearctl_qp_factor_size.restype = ctypes.c_long
    lib.gearctl_qp_factor_size.argtypes = [ctypes.c_int]
    lib.gearctl_qp_matvec.restype = None
    lib.gearctl_qp_matvec.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p,
                                      ctypes.c_void_p]
    lib.gearctl_qp_default_settings.restype = None
    lib.gearctl_qp_default_settings.argtypes = [ctypes.c_void_p]
    return lib


def matvec_function() -> Any:
    """The C function ``gearctl_qp_matvec(rows, cols, a, x, y)``: ``y = A x`` for a C-order ``A``, each row
    summed in index order (arguments: two ints and three data addresses, e.g. ``arr.ctypes.data``).

    It gives the same rounding on every machine, where ``numpy.dot`` rounds as the CPU's BLAS kernel
    orders its sums; the MPC forms its QP gradient with it, so that the exported C MPC, which sums its
    rows in the same order, gives the same torques to the last bit.
    """
    return _lib().gearctl_qp_matvec


# --- the solver ----------------------------------------------------------------------------------------


class QPFactor:
    """Factor of one Hessian, from :meth:`DenseQP.factor`; pass it to :meth:`DenseQP.solve`.

    Attributes
    ----------
    n : int
        Number of variables.
    data : ndarray
        ``U = R^-1`` with ``H = R'R`` (Cholesky), ``(n, n)`` column-major upper triangular: what the C
        function ``gearctl_qp_factor`` writes, and what an exported controller stores per Hessian.
    """

    __slots__ = ("n", "data", "_ptr")

    def __init__(self, n: int, data: NDArray[np.float64]) -> None:
        self.n = n
        self.data = data
        self._ptr = data.ctypes.data


class DenseQP:
    """Dense QP ``min 1/2 x'Hx + g'x, lbx <= x <= ubx, lba <= A x <= uba`` with preallocated buffers.

    Parameters
    ----------
    n : int
        Number of variables, ``n >= 1``.
    m : int
        Number of general rows, ``m >= 0``.
    max_iter : int, optional
        Cap on working-set changes (additions and removals) per solve, ``>= 1``.
    primal_tol : float, optional
        A constraint counts as violated when its violation exceeds
        ``primal_tol * |a_i|_2 * max(1, |x|_inf)``.
    dependence_tol : float, optional
        Relative size below which a constraint's normal counts as dependent on the active ones.
    infinity : float, optional
        Bounds at or beyond ``+-infinity`` are absent.

    Attributes
    ----------
    g, lbx, ubx : ndarray
        ``(n,)`` inputs, filled by the caller in place (bounds start absent: ``-inf``/``+inf``).
    a : ndarray
        ``(m, n)`` rows in C (row-major) order, used unless :meth:`use_rows` points elsewhere.
    lba, uba : ndarray
        ``(m,)`` row bounds (start absent).
    x, lam_x, lam_a : ndarray
        ``(n,)``, ``(n,)``, ``(m,)`` outputs: solution and multipliers (CasADi's signs).
    cost : ndarray
        ``(1,)`` output: ``1/2 x'Hx + g'x``.
    active : ndarray
        ``(n + m,)`` int8 working set, output and (with ``warm=True``) input; see the module docstring.

    Raises
    ------
    InputError
        For a size or setting out of range.
    SolverError
        If the C solver cannot be compiled or loaded.

    Notes
    -----
    The per-call overhead is one ctypes call with pointers prepared in the constructor (about half a
    microsecond); the buffers must be modified in place, never rebound (``qp.g[:] = ...``, not
    ``qp.g = ...``), since the C side holds their addresses.

    Examples
    --------
    >>> qp = DenseQP(2, 1)
    >>> f = qp.factor(np.eye(2))
    >>> qp.g[:] = [-1.0, -1.0]
    >>> qp.a[:] = [[1.0, 1.0]]
    >>> qp.uba[:] = 1.0
    >>> qp.solve(f)
    <QPStatus.SOLVED: 0>
    >>> np.round(qp.x, 12).tolist(), np.round(qp.lam_a, 12).tolist()
    ([0.5, 0.5], [0.5])
    """

    def __init__(self, n: int, m: int, *, max_iter: int = 1000, primal_tol: float = 1e-12,
                 dependence_tol: float = 1e-10, infinity: float = 1e20) -> None:
        for name, v, lo in (("n", n, 1), ("m", m, 0), ("max_iter", max_iter, 1)):
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < lo:
                raise InputError(f"{name} = {v!r} is out of range: expected an integer >= {lo}", field=name)
        for name, tol in (("primal_tol", primal_tol), ("dependence_tol", dependence_tol)):
            if not (np.isfinite(tol) and tol >= 0.0):
                raise InputError(f"{name} = {tol!r} is out of range: expected a finite number >= 0", field=name)
        if not infinity > 0.0:
            raise InputError(f"infinity = {infinity!r} is out of range: expected a number > 0", field="infinity")
        lib = _lib()
        n, m = int(n), int(m)
        self.n, self.m = n, m
        self.g = np.zeros(n)
        self.a = np.zeros((m, n))
        self.lbx, self.ubx = np.full(n, -np.inf), np.full(n, np.inf)
        self.lba, self.uba = np.full(m, -np.inf), np.full(m, np.inf)
        self.x, self.lam_x, self.lam_a = np.zeros(n), np.zeros(n), np.zeros(m)
        self.cost = np.zeros(1)
        self.active = np.zeros(n + m, dtype=np.int8)
        self._work = np.zeros(max(int(lib.gearctl_qp_work_size(n, m)), 1))
        self._settings = _Settings(int(max_iter), float(primal_tol), float(dependence_tol), float(infinity))
        self._prob = _Problem(n, m, None, self.g.ctypes.data, self.a.ctypes.data, self.lbx.ctypes.data,
                              self.ubx.ctypes.data, self.lba.ctypes.data, self.uba.ctypes.data)
        self._res = _Result(self.x.ctypes.data, self.lam_x.ctypes.data, self.lam_a.ctypes.data,
                            self.cost.ctypes.data, self.active.ctypes.data, 0)
        self._rows: NDArray[np.float64] = self.a  # the rows the C side reads (kept alive here)
        self._factor: QPFactor | None = None
        self._args = (ctypes.byref(self._prob), ctypes.byref(self._settings))
        self._res_ref, self._work_ptr = ctypes.byref(self._res), ctypes.c_void_p(self._work.ctypes.data)
        self._solve = lib.gearctl_qp_solve

    @property
    def iterations(self) -> int:
        """Working-set changes of the last solve (equalities, warm start and removals included)."""
        return int(self._res.iterations)

    def factor(self, H: ArrayLike) -> QPFactor:
        """Factor a Hessian once, for any number of solves.

        Parameters
        ----------
        H : array_like
            ``(n, n)`` symmetric positive definite matrix (only its lower triangle in row-major order,
            i.e. ``H[i, j]`` with ``j <= i``, is read).

        Returns
        -------
        QPFactor
            The handle to pass to :meth:`solve`.

        Raises
        ------
        InputError
            If ``H`` has the wrong shape or a non-finite entry, or is not (numerically) positive definite.
        """
        h = np.ascontiguousarray(H, dtype=float)
        if h.shape != (self.n, self.n):
            raise InputError(f"H has shape {h.shape}: expected ({self.n}, {self.n})", field="H")
        data = np.zeros(self.n * self.n)
        # h in C order read as column-major is H', equal to H: the C side reads h[i + j n], i <= j
        code = _lib().gearctl_qp_factor(self.n, h.ctypes.data, data.ctypes.data)
        if code == QPStatus.NOT_POSDEF:
            raise InputError("H is not positive definite (a Cholesky pivot <= n * eps * its diagonal entry): "
                             "add a ridge or check the weights", field="H")
        if code != QPStatus.SOLVED:
            raise InputError("H has a non-finite entry", field="H")
        return QPFactor(self.n, data)

    def use_rows(self, A: NDArray[np.float64] | None) -> None:
        """Read the rows from ``A`` (kept alive by this object) instead of :attr:`a`; ``None`` restores :attr:`a`.

        Parameters
        ----------
        A : ndarray or None
            ``(m, n)`` float64 in C (row-major) order; the solver reads it in place at every solve.

        Raises
        ------
        InputError
            If ``A`` is not a C-contiguous float64 array of shape ``(m, n)``.
        """
        rows = self.a if A is None else A
        if (not isinstance(rows, np.ndarray) or rows.dtype != np.float64 or rows.shape != (self.m, self.n)
                or not rows.flags.c_contiguous):
            raise InputError(f"A must be a C-contiguous float64 array of shape ({self.m}, {self.n})", field="A")
        self._rows = rows
        self._prob.a = rows.ctypes.data

    def solve(self, factor: QPFactor, warm: bool = False) -> QPStatus:
        """Solve with the current buffers; the results land in ``x``, ``lam_x``, ``lam_a``, ``cost``, ``active``.

        Parameters
        ----------
        factor : QPFactor
            Factor of the Hessian, from :meth:`factor` of an object of the same ``n``.
        warm : bool, optional
            Start from the working set in :attr:`active` (e.g. the last one, shifted) instead of the
            unconstrained minimiser.

        Returns
        -------
        QPStatus
            ``SOLVED``, ``INFEASIBLE`` (also for some ``lb > ub``), ``ITERATION_LIMIT`` or ``NUMERICAL``;
            outside ``SOLVED`` the outputs describe the last iterate.

        Raises
        ------
        InputError
            For a factor of another size, or data the C solver rejects (a NaN bound, a non-finite entry
            of ``g`` or of the rows).
        """
        if factor is not self._factor:
            if factor.n != self.n:
                raise InputError(f"factor is for n = {factor.n}: expected n = {self.n}", field="factor")
            self._prob.factor = factor._ptr
            self._factor = factor
        code = self._solve(*self._args, warm, self._res_ref, self._work_ptr)
        if code == _INVALID:  # sizes and pointers are right by construction, so the data are not
            raise InputError("QP data rejected: a NaN bound or a non-finite entry of g or of the rows", field="g")
        return _STATUS[code]
