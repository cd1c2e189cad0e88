"""The dense QP solver (gearctl.qp, C source gearctl/csrc/qp): oracles, the MPC's own QPs, the C contract.

Oracles
-------
- Closed form: QPs built around a chosen optimum (a KKT point with strict complementarity and
  independent active normals, so ``x`` and the multipliers are unique) must be solved to it.
- Independent solver: CasADi's ``daqp`` plugin with ``primal_tol = 1e-12`` on seeded random strictly
  convex QPs (n = 5..60, bounds, one- and two-sided rows, equalities). With its default primal
  tolerance (1e-6) DAQP stops at points that violate a constraint by up to 1e-6, which is why the
  reference is tightened (see ``test_mpc_qps``).
- Invariants: the KKT conditions checked directly (stationarity, primal feasibility, complementarity,
  sign of the multipliers) to 1e-9 relative; warm starts from arbitrary working sets give the cold
  solution; infeasible problems are reported infeasible.
- The real MPC QPs: a 0.5 s closed loop of the benchmark MPC (``shing1993_servo``), every QP it solves
  captured with DAQP's answer, re-solved here.
- The C contract: ``-std=c99 -Wall -Wextra -pedantic`` compiles without a warning, and the object calls
  no allocator or I/O function and has no writable global data.

Tolerances: ``x`` to 1e-9 relative to ``max(1, |x|_inf)``; the cost to 1e-9 relative to
``max(1, |cost|)``; multipliers to 1e-7 relative to ``max(1, |lam|_inf)`` (they are the solution of
a linear system in the active normals, conditioned worse than ``x``; measured agreement is 1e-13 to
1e-10).
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from gearctl import build_plant, load_model
from gearctl import qp as qp_module
from gearctl.catalog import load_controller
from gearctl.closedloop import simulate_closed_loop
from gearctl.errors import InputError, SolverError
from gearctl.kernel import c_compiler
from gearctl.qp import SOURCE_DIR, DenseQP, QPStatus
from gearctl.references import reference

try:
    qp_module._lib()
except SolverError as exc:  # no C compiler (or GEARCTL_NO_COMPILE): the solver is C only, nothing here can run
    pytest.skip(f"QP solver not compiled: {exc}", allow_module_level=True)

ca = pytest.importorskip("casadi")

X_RTOL = 1e-9
COST_RTOL = 1e-9
LAM_RTOL = 1e-7
KKT_RTOL = 1e-9


# --- helpers -----------------------------------------------------------------------------------------------


def random_qp(rng: np.random.Generator, n: int, m: int, n_eq: int) -> dict[str, np.ndarray]:
    """A feasible strictly convex QP: a feasible point x0 is drawn first and the bounds placed around it."""
    M = rng.standard_normal((n, n))
    H = M @ M.T + 0.1 * np.eye(n)
    g = 3.0 * rng.standard_normal(n)
    A = rng.standard_normal((m, n))
    x0 = rng.standard_normal(n)
    ax = A @ x0
    lba, uba = ax - rng.uniform(0.0, 1.0, m), ax + rng.uniform(0.0, 1.0, m)
    side = rng.random(m)
    lba[side < 0.25] = -np.inf  # a quarter upper-only, a quarter lower-only, half two-sided
    uba[(side >= 0.25) & (side < 0.5)] = 1e20  # both spellings of "no bound"
    lba[:n_eq] = uba[:n_eq] = ax[:n_eq]
    lbx, ubx = x0 - rng.uniform(0.0, 1.0, n), x0 + rng.uniform(0.0, 1.0, n)
    side = rng.random(n)
    lbx[side < 0.3] = -1e20
    ubx[side > 0.7] = np.inf
    lbx[side > 0.95] = ubx[side > 0.95] = x0[side > 0.95]  # a few fixed variables (equality bounds)
    return dict(h=H, g=g, a=A, lbx=lbx, ubx=ubx, lba=lba, uba=uba)


def load(qp: DenseQP, d: dict[str, np.ndarray]) -> None:
    for key in ("g", "a", "lbx", "ubx", "lba", "uba"):
        getattr(qp, key)[...] = d[key]


def solve_ours(d: dict[str, np.ndarray], **settings) -> tuple[QPStatus, DenseQP]:
    n, m = d["a"].shape[1], d["a"].shape[0]
    qp = DenseQP(n, m, **settings)
    load(qp, d)
    return qp.solve(qp.factor(d["h"])), qp


_DAQP: dict[tuple[int, int], object] = {}


def solve_daqp(d: dict[str, np.ndarray]) -> tuple[bool, dict[str, np.ndarray]]:
    """DAQP through CasADi, primal tolerance 1e-12 (its default, 1e-6, leaves constraints violated)."""
    m, n = d["a"].shape
    if (n, m) not in _DAQP:
        _DAQP[n, m] = ca.conic("ref", "daqp", {"h": ca.Sparsity.dense(n, n), "a": ca.Sparsity.dense(m, n)},
                               {"daqp": {"primal_tol": 1e-12}, "error_on_fail": False})
    S = _DAQP[n, m]
    sol = S(**d)
    out = {k: np.asarray(sol[k]).ravel() for k in ("x", "lam_x", "lam_a")}
    out["cost"] = float(sol["cost"])
    return bool(S.stats()["success"]), out


def assert_same_solution(qp: DenseQP, ref: dict[str, np.ndarray], *, lam: bool = True) -> None:
    xs = max(1.0, float(np.max(np.abs(ref["x"]))))
    assert_allclose(qp.x, ref["x"], rtol=0, atol=X_RTOL * xs)
    assert_allclose(qp.cost[0], ref["cost"], rtol=0, atol=COST_RTOL * max(1.0, abs(ref["cost"])))
    if lam:
        ls = max(1.0, float(np.max(np.abs(np.concatenate([ref["lam_x"], ref["lam_a"]])))))
        assert_allclose(qp.lam_x, ref["lam_x"], rtol=0, atol=LAM_RTOL * ls)
        assert_allclose(qp.lam_a, ref["lam_a"], rtol=0, atol=LAM_RTOL * ls)


def assert_kkt(qp: DenseQP, d: dict[str, np.ndarray], rtol: float = KKT_RTOL) -> None:
    """Stationarity, primal feasibility, complementarity and dual signs, each relative to its data."""
    H, g, A = d["h"], d["g"], d["a"]
    x, lx, la = qp.x, qp.lam_x, qp.lam_a
    hx, ax, atl = H @ x, A @ x, A.T @ la
    scale = 1.0 + np.abs(g).max() + np.abs(hx).max() + np.abs(lx).max() + (np.abs(atl).max() if la.size else 0.0)
    assert np.abs(hx + g + lx + atl).max() <= rtol * scale, "stationarity"
    assert_allclose(qp.cost[0], 0.5 * x @ hx + g @ x, rtol=0, atol=rtol * max(1.0, abs(float(g @ x)),
                                                                                 abs(float(x @ hx))))
    xs = max(1.0, float(np.abs(x).max()))
    for val, lo, hi, lam, norms in ((x, d["lbx"], d["ubx"], lx, np.ones_like(x)),
                                    (ax, d["lba"], d["uba"], la, np.linalg.norm(A, axis=1))):
        tol = rtol * norms * xs
        has_lo, has_up = lo > -1e20, hi < 1e20
        assert np.all(~has_lo | (val >= lo - tol)), "primal feasibility (lower)"
        assert np.all(~has_up | (val <= hi + tol)), "primal feasibility (upper)"
        assert np.all(lam[~has_lo] >= 0.0) and np.all(lam[~has_up] <= 0.0), "multiplier of an absent bound"
        at_lo = np.abs(val - np.where(has_lo, lo, 0.0)) <= tol
        at_up = np.abs(val - np.where(has_up, hi, 0.0)) <= tol
        assert np.all((lam >= 0.0) | (has_lo & at_lo)), "a negative multiplier away from the lower bound"
        assert np.all((lam <= 0.0) | (has_up & at_up)), "a positive multiplier away from the upper bound"


# --- (a) against a closed-form optimum and against DAQP -------------------------------------------------


@pytest.mark.parametrize("seed", range(12))
def test_constructed_optimum(seed: int) -> None:
    # x*, the active set and positive multipliers are chosen; g follows from stationarity, the active
    # bounds pass through x*, the inactive ones keep a margin: the unique solution is known exactly
    rng = np.random.default_rng(1000 + seed)
    n = int(rng.integers(5, 41))
    m = int(rng.integers(1, 2 * n))
    M = rng.standard_normal((n, n))
    H = M @ M.T + 0.5 * np.eye(n)
    A = rng.standard_normal((m, n))
    x = rng.standard_normal(n)
    ax = A @ x
    n_act = int(rng.integers(1, n + 1))  # at most n independent active constraints
    act = rng.choice(n + m, size=n_act, replace=False)
    sign = rng.choice([-1.0, 1.0], size=n_act)  # -1: lower bound active, +1: upper
    lam = np.zeros(n + m)
    lam[act] = sign * rng.uniform(0.1, 2.0, n_act)
    lo = np.concatenate([x, ax]) - rng.uniform(0.1, 1.0, n + m)
    hi = np.concatenate([x, ax]) + rng.uniform(0.1, 1.0, n + m)
    val = np.concatenate([x, ax])
    lo[act[sign < 0]] = val[act[sign < 0]]
    hi[act[sign > 0]] = val[act[sign > 0]]
    g = -(H @ x + lam[:n] + A.T @ lam[n:])
    d = dict(h=H, g=g, a=A, lbx=lo[:n], ubx=hi[:n], lba=lo[n:], uba=hi[n:])
    status, qp = solve_ours(d)
    assert status == QPStatus.SOLVED
    ref = dict(x=x, lam_x=lam[:n], lam_a=lam[n:], cost=float(0.5 * x @ H @ x + g @ x))
    assert_same_solution(qp, ref)
    expected = np.zeros(n + m, dtype=np.int8)
    expected[act] = sign.astype(np.int8)
    assert_array_equal(qp.active, expected)


@pytest.mark.parametrize("seed", range(40))
def test_random_qps_match_daqp(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 61))
    m = int(rng.integers(0, 2 * n))
    n_eq = int(rng.integers(0, min(m, n // 2) + 1))
    d = random_qp(rng, n, m, n_eq)
    status, qp = solve_ours(d)
    ok, ref = solve_daqp(d)
    assert ok and status == QPStatus.SOLVED
    assert_same_solution(qp, ref)
    assert_kkt(qp, d)
    # inactive constraints have exact zero multipliers (an active-set method)
    lam = np.concatenate([qp.lam_x, qp.lam_a])
    assert np.all(lam[qp.active == 0] == 0.0)
    assert np.all(lam[qp.active == -1] <= 0.0) and np.all(lam[qp.active == 1] >= 0.0)


def test_unconstrained_and_m_zero() -> None:
    rng = np.random.default_rng(7)
    n = 9
    M = rng.standard_normal((n, n))
    H = M @ M.T + np.eye(n)
    g = rng.standard_normal(n)
    qp = DenseQP(n, 0)
    qp.g[:] = g
    assert qp.solve(qp.factor(H)) == QPStatus.SOLVED
    x = np.linalg.solve(H, -g)
    assert_allclose(qp.x, x, rtol=0, atol=1e-12 * max(1.0, np.abs(x).max()))
    assert_allclose(qp.cost[0], 0.5 * g @ x, rtol=1e-12)  # -1/2 g'H^-1 g
    assert qp.iterations == 0 and not qp.lam_x.any()


# --- degenerate problems ------------------------------------------------------------------------------------


def degenerate_qp(kind: str) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(5)
    n = 8
    M = rng.standard_normal((n, n))
    H, g = M @ M.T + np.eye(n), -10.0 * np.ones(n)
    A = rng.standard_normal((4, n))
    lbx, ubx = -np.ones(n), np.ones(n)
    lba, uba = np.full(4, -np.inf), np.full(4, 0.5)
    if kind == "duplicate rows":  # the same row twice, scaled: dependent active normals
        A[1] = 3.0 * A[0]
        uba[1] = 1.5
    elif kind == "row equals a bound":  # a row that repeats an upper bound of x
        A[0] = 0.0
        A[0, 2] = 1.0
        uba[0] = 1.0
    elif kind == "dependent equalities":  # three equalities of rank two, consistent
        A[2] = A[0] + 2.0 * A[1]
        lba[:3] = uba[:3] = [0.1, -0.2, 0.1 - 0.4]
    elif kind == "zero rows":  # empty rows with satisfied bounds (the MPC has them)
        A[1:3] = 0.0
        lba[1:3], uba[1:3] = 0.0, 1e20
    elif kind == "vertex":  # as many active constraints as variables
        g = -100.0 * np.ones(n)
        uba[:] = 1e20
    return dict(h=H, g=g, a=A, lbx=lbx, ubx=ubx, lba=lba, uba=uba)


@pytest.mark.parametrize("kind", ["duplicate rows", "row equals a bound", "dependent equalities", "zero rows",
                                  "vertex"])
def test_degenerate_problems(kind: str) -> None:
    d = degenerate_qp(kind)
    status, qp = solve_ours(d)
    if kind == "dependent equalities":  # DAQP fails on dependent equalities: ask it without the redundant one
        keep = [0, 1, 3]
        ok, ref = solve_daqp({**d, "a": d["a"][keep], "lba": d["lba"][keep], "uba": d["uba"][keep]})
        ref["lam_a"] = np.insert(ref["lam_a"], 2, 0.0)
        assert qp.active[len(d["g"]) + 2] == 0 and qp.lam_a[2] == 0.0  # reported as dependent
    else:
        ok, ref = solve_daqp(d)
    assert ok and status == QPStatus.SOLVED
    assert_same_solution(qp, ref, lam=False)  # with dependent active normals the multipliers are not unique
    assert_kkt(qp, d)
    if kind == "vertex":
        assert np.count_nonzero(qp.active) == len(d["g"])


# --- (b) KKT conditions, directly, over many random problems -------------------------------------------------


def test_kkt_conditions_on_random_problems() -> None:
    rng = np.random.default_rng(2024)
    for _ in range(150):
        n = int(rng.integers(2, 41))
        m = int(rng.integers(0, 3 * n))
        d = random_qp(rng, n, m, int(rng.integers(0, min(m, n // 2) + 1)))
        status, qp = solve_ours(d)
        assert status == QPStatus.SOLVED
        assert_kkt(qp, d)


def test_warm_start_from_any_working_set_gives_the_cold_solution() -> None:
    rng = np.random.default_rng(11)
    for _ in range(40):
        n = int(rng.integers(3, 31))
        m = int(rng.integers(0, 2 * n))
        d = random_qp(rng, n, m, int(rng.integers(0, min(m, n // 2) + 1)))
        status, qp = solve_ours(d)
        assert status == QPStatus.SOLVED
        cold = qp.x.copy(), qp.lam_x.copy(), qp.lam_a.copy(), qp.active.copy()
        f = qp.factor(d["h"])
        for guess in (cold[3], rng.integers(-1, 2, n + m).astype(np.int8), np.ones(n + m, np.int8)):
            qp.active[:] = guess
            assert qp.solve(f, warm=True) == QPStatus.SOLVED
            xs = max(1.0, np.abs(cold[0]).max())
            assert_allclose(qp.x, cold[0], rtol=0, atol=1e-10 * xs)
            assert_kkt(qp, d)
        qp.active[:] = cold[3]
        qp.solve(f, warm=True)
        assert_array_equal(qp.active, cold[3])  # from the optimal set: no change


# --- (c) infeasible problems -------------------------------------------------------------------------------


def infeasible_qp(kind: str) -> dict[str, np.ndarray]:
    n = 6
    H, g = np.eye(n) + 0.1, np.ones(n)
    A = np.zeros((3, n))
    A[0] = 1.0
    lbx, ubx = np.zeros(n), np.ones(n)
    lba, uba = np.full(3, -np.inf), np.full(3, np.inf)
    if kind == "box and row":  # 0 <= x <= 1 and sum(x) >= n + 1
        lba[0] = n + 1.0
    elif kind == "inconsistent equalities":  # sum(x) = 1 and 2 sum(x) = 3
        A[1] = 2.0
        lba[0] = uba[0] = 1.0
        lba[1] = uba[1] = 3.0
    elif kind == "opposite rows":  # sum(x) >= 2 and -3 sum(x) >= -3, scaled differently
        A[1] = -3.0
        lba[0], lba[1] = 2.0, -3.0
    elif kind == "lower above upper (x)":
        lbx[3], ubx[3] = 0.5, 0.4
    elif kind == "lower above upper (row)":
        lba[2], uba[2] = 1.0, 0.0
        A[2] = 1.0
    elif kind == "zero row":  # 0 x >= 1
        lba[2] = 1.0
    elif kind == "fixed variable against a row":  # x0 = 1 (bounds) and x0 <= 0.5 (row)
        lbx[0] = ubx[0] = 1.0
        A[1, 0] = 1.0
        uba[1] = 0.5
    return dict(h=H, g=g, a=A, lbx=lbx, ubx=ubx, lba=lba, uba=uba)


@pytest.mark.parametrize("kind", ["box and row", "inconsistent equalities", "opposite rows",
                                  "lower above upper (x)", "lower above upper (row)", "zero row",
                                  "fixed variable against a row"])
def test_infeasible_problems(kind: str) -> None:
    d = infeasible_qp(kind)
    status, qp = solve_ours(d)
    assert status == QPStatus.INFEASIBLE
    # the independent solver agrees where it can be asked: CasADi rejects lb > ub before calling DAQP, and
    # drops empty rows (so "0 x >= 1" is solved without it)
    if kind.startswith("lower above upper") or kind == "zero row":
        return
    ok, _ = solve_daqp(d)
    assert not ok


def test_random_infeasible_problems() -> None:
    # a feasible random QP plus a row that contradicts a combination of its constraints
    rng = np.random.default_rng(99)
    for _ in range(20):
        n = int(rng.integers(3, 21))
        d = random_qp(rng, n, n, 0)
        d["lbx"][:], d["ubx"][:] = -1.0, 1.0
        w = rng.standard_normal(n)
        d["a"] = np.vstack([d["a"], w])
        d["lba"] = np.append(d["lba"], np.abs(w).sum() + 0.1)  # w'x <= |w|_1 on the box
        d["uba"] = np.append(d["uba"], np.inf)
        status, _ = solve_ours(d)
        assert status == QPStatus.INFEASIBLE


# --- the binding: status codes, bad input, buffers --------------------------------------------------------


def test_iteration_limit_is_reported() -> None:
    d = degenerate_qp("vertex")
    status, qp = solve_ours(d, max_iter=2)
    assert status == QPStatus.ITERATION_LIMIT
    assert qp.iterations == 2


def test_bad_input_is_rejected() -> None:
    with pytest.raises(InputError, match="n = 0"):
        DenseQP(0, 1)
    with pytest.raises(InputError, match="m = -1"):
        DenseQP(2, -1)
    with pytest.raises(InputError, match="primal_tol"):
        DenseQP(2, 1, primal_tol=-1.0)
    qp = DenseQP(3, 1)
    with pytest.raises(InputError, match="positive definite"):
        qp.factor(np.diag([1.0, 0.0, 1.0]))
    with pytest.raises(InputError, match="positive definite"):
        qp.factor(np.diag([1.0, -1.0, 1.0]))
    with pytest.raises(InputError, match="shape"):
        qp.factor(np.eye(2))
    with pytest.raises(InputError, match="non-finite"):
        qp.factor(np.full((3, 3), np.nan))
    with pytest.raises(InputError, match=r"A must be"):
        qp.use_rows(np.zeros((1, 3), order="F").T)
    f = qp.factor(np.eye(3))
    with pytest.raises(InputError, match="n = 2"):
        qp.solve(DenseQP(2, 0).factor(np.eye(2)))
    qp.lbx[0] = np.nan
    with pytest.raises(InputError, match="NaN bound"):
        qp.solve(f)
    qp.lbx[0] = -np.inf
    qp.a[0] = np.nan
    qp.lba[0] = 0.0
    assert qp.solve(f) == QPStatus.NUMERICAL


def test_buffers_are_used_in_place_and_instances_are_independent() -> None:
    rng = np.random.default_rng(3)
    d1, d2 = random_qp(rng, 12, 10, 2), random_qp(rng, 12, 10, 0)
    q1, q2 = DenseQP(12, 10), DenseQP(12, 10)
    f1, f2 = q1.factor(d1["h"]), q2.factor(d2["h"])
    addresses = [b.ctypes.data for b in (q1.g, q1.a, q1.x, q1.lam_x, q1.lam_a, q1.cost, q1.active)]
    load(q1, d1)
    load(q2, d2)
    rows = np.ascontiguousarray(d1["a"])
    q1.use_rows(rows)
    q1.a[:] = 0.0  # no longer read
    for _ in range(3):  # interleaved: no state is shared between instances or kept between calls
        assert q1.solve(f1) == QPStatus.SOLVED
        assert q2.solve(f2) == QPStatus.SOLVED
    assert_kkt(q1, d1)
    assert_kkt(q2, d2)
    assert addresses == [b.ctypes.data for b in (q1.g, q1.a, q1.x, q1.lam_x, q1.lam_a, q1.cost, q1.active)]
    x1 = q1.x.copy()
    q1.use_rows(None)
    q1.a[:] = d1["a"]
    q1.solve(f1)
    assert_array_equal(q1.x, x1)  # bit for bit: the same data give the same numbers


# --- (d) the MPC's own QPs --------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def mpc_qps() -> list[dict]:
    """Every QP the benchmark MPC solves in a 0.5 s closed loop, with DAQP's answer (as the MPC calls it)."""
    model = load_model("shing1993_servo")
    plant = build_plant(model)
    ctrl = load_controller("mpc", plant)
    qp = ctrl._qp
    captured: list[dict] = []
    solve = qp.solve

    def capture() -> str:
        d = dict(h=np.array(qp.h), g=qp.g.copy(), a=np.array(qp.a), lbx=qp.lbx.copy(), ubx=qp.ubx.copy(),
                 lba=qp.lba.copy(), uba=qp.uba.copy())
        status = solve()
        d.update(status=status, x=qp.x.copy(), lam_x=qp.lam_x.copy(), lam_a=qp.lam_a.copy(), cost=float(qp.cost[0]))
        captured.append(d)
        return status

    qp.solve = capture
    simulate_closed_loop(plant, ctrl, reference("sine"), 0.5, sensors=model.sensors)
    assert len(captured) >= 500  # at least one QP per 1 ms sample
    return captured


def test_mpc_qps(mpc_qps: list[dict]) -> None:
    n, m = mpc_qps[0]["a"].shape[1], mpc_qps[0]["a"].shape[0]
    ours = DenseQP(n, m)
    factors: dict[bytes, object] = {}
    n_loose = 0
    for d in mpc_qps:
        data = {k: d[k] for k in ("h", "g", "a", "lbx", "ubx", "lba", "uba")}
        key = d["h"].tobytes()
        if key not in factors:
            factors[key] = ours.factor(d["h"])
        load(ours, data)
        status = ours.solve(factors[key])
        # status: the MPC's DAQP reports its failures (an infeasible landing) as a flag
        assert (status == QPStatus.SOLVED) == (d["status"] == "ok"), d["status"]
        ok, ref = solve_daqp(data)
        assert ok == (status == QPStatus.SOLVED)
        if status != QPStatus.SOLVED:
            assert status == QPStatus.INFEASIBLE
            continue
        assert_same_solution(ours, ref)  # DAQP at primal_tol 1e-12: x to 1e-9
        assert_kkt(ours, data)
        # DAQP as the MPC calls it (default primal_tol 1e-6): the same x unless DAQP stopped at a point that
        # violates a constraint by up to its tolerance, which applies to the rows scaled to unit length in the
        # metric of H^-1 (|L^-1 a_i|, H = L L'); such a stop moves x by about that much
        xs = max(1.0, np.abs(d["x"]).max())
        ax = d["a"] @ d["x"]
        scaled = np.linalg.norm(np.linalg.solve(np.linalg.cholesky(d["h"]), d["a"].T), axis=0)
        viol = np.concatenate([d["lbx"] - d["x"], d["x"] - d["ubx"], d["lba"] - ax, ax - d["uba"]])
        if viol.max() <= 1e-12:
            assert_allclose(ours.x, d["x"], rtol=0, atol=X_RTOL * xs)
        else:
            n_loose += 1
            scale = np.concatenate([np.ones(2 * n), scaled, scaled])
            assert np.all(viol <= 1e-6 * scale)
            assert_allclose(ours.x, d["x"], rtol=0, atol=1e-4 * xs)
    assert n_loose <= 0.02 * len(mpc_qps)  # a handful (3 of 555 when written)


# --- (e) the C contract --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def compiled_object(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    cc = c_compiler()
    if cc is None:
        pytest.skip("no C compiler")
    obj = tmp_path_factory.mktemp("qp") / "gearctl_qp.o"
    proc = subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic", "-c", "-o", str(obj),
                           str(SOURCE_DIR / "gearctl_qp.c")], capture_output=True, text=True, check=True)
    return obj, proc.stderr


def test_c_source_compiles_without_warnings(compiled_object: tuple[Path, str]) -> None:
    assert compiled_object[1].strip() == ""


def test_c_object_has_no_allocation_io_or_globals(compiled_object: tuple[Path, str]) -> None:
    if shutil.which("nm") is None:
        pytest.skip("nm not found")
    obj = str(compiled_object[0])
    undefined = set(subprocess.run(["nm", "-u", obj], capture_output=True, text=True, check=True).stdout.split())
    undefined -= {"U"}
    forbidden = {"malloc", "calloc", "realloc", "free", "printf", "fprintf", "puts", "putchar", "fwrite",
                 "sprintf", "snprintf", "abort", "exit"}
    assert not {s.split("@")[0] for s in undefined} & forbidden, undefined
    assert {s.split("@")[0] for s in undefined} <= {"sqrt", "memcpy", "memset", "memmove"}, undefined
    # writable data (D/d: initialised, B/b: zero-initialised, C: common): none, so instances cannot interfere
    symbols = subprocess.run(["nm", obj], capture_output=True, text=True, check=True).stdout.splitlines()
    assert not [s for s in symbols if len(s.split()) == 3 and s.split()[1] in "DdBbC"], symbols
