"""The MPC's tables for the exported C: the condensed QP of every mode pattern, read off the Python object.

For each pattern (separation from sample ``a``, landing at ``e``) the Python MPC holds the Hessian's factor
(:class:`gearctl.qp.QPFactor`, what the solver reads), the constraint rows per flank, the map ``M[sig]`` from
the parameter vector to the gradient and the rows' lower bounds, and ``K`` (the constant part of the cost).
The C stores them compactly, and :func:`mpc_values` checks that the compact form holds them exactly:

- the factor's upper triangle (the rest is zero), packed by columns;
- the rows and the bound map for the front flank only: for the back flank the mesh-torque rows change
  sign and the others are equal (checked bit for bit);
- the gradient part of ``M`` (the same for both flanks) by its nonzeros; its bound part reads only the first
  six parameters (the state, the load torque and the landing target: checked);
- ``K`` by its nonzeros.

Memory (the figures :func:`table_figures` gives) is dominated by the patterns: about ``N (n_cross + 2) + N``
of them, each ``O(N^2)`` numbers.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..design.mpc import MPC
from ..errors import InputError
from .cstruct import CArray

__all__ = ["mpc_values", "table_figures", "work_size"]


def work_size(n: int, m: int) -> int:
    """``GEARCTL_QP_WORK_SIZE(n, m)`` of gearctl_qp.h [doubles].

    Parameters
    ----------
    n : int
        Variables of the QP.
    m : int
        Constraints of the QP.

    Returns
    -------
    int
        The work array's length [doubles].

    Examples
    --------
    >>> work_size(2, 1)
    21
    """
    return 2 * n * n + 5 * n + m + (n + 1) // 2 + (n + m + 7) // 8


def mpc_values(c: MPC) -> tuple[dict[str, Any], dict[str, int]]:
    """The parameter struct's values and the compile-time sizes of an MPC.

    Parameters
    ----------
    c : MPC
        The MPC to export.

    Returns
    -------
    values : dict
        The ``gcx_mpc_p`` struct's values (tables as :class:`~gearctl.export.cstruct.CArray`).
    dims : dict of str to int
        The compile-time sizes (``#define``).

    Raises
    ------
    InputError
        If the MPC does not run gearctl's QP solver (a CasADi plugin cannot be exported: the C must run the
        solver the Python runs), or injects failures (a test hook).
    RuntimeError
        If a pattern does not have the structure the compact tables assume (a change of mpc.py the export
        does not know).
    """
    if getattr(c._qp, "plugin", None) != "gearctl" or not hasattr(c._qp, "_dqp"):
        raise InputError(f"MPC {c.name!r} solves with {getattr(c._qp, 'plugin', '?')!r}: only solver = \"gearctl\" "
                         "(gearctl's own QP solver, compiled) can be exported, so that the C runs the same solver",
                         field="solver")
    if c.inject_failures:
        raise InputError("an MPC with inject_failures cannot be exported (a test hook the C does not have)",
                         field="inject_failures")
    n, n_p, m = c.N, c.n_p, c.N + 2
    keys = sorted(c._patterns)
    index = {k: q for q, k in enumerate(keys)}
    pat_index = np.full((n + 1, n + 2), -1, dtype=np.int16)
    for k, q in index.items():
        pat_index[k] = q
    tri = np.triu_indices(n)
    order = np.lexsort((tri[0], tri[1]))  # by columns, rows ascending within a column
    rows_i, cols_i = tri[0][order], tri[1][order]
    factor, rows, Cr, mesh, gap, has_landing, land_row = [], [], [], [], [], [], []
    G_ptr, G_idx, G_val = [0], [], []
    K_ptr, K_row, K_col, K_val = [0], [], [], []
    for key in keys:
        pat = c._patterns[key]
        f_obj, A = pat.solver_data[:2]
        F = f_obj.data.reshape(n, n, order="F")  # column-major, upper triangular
        if np.any(np.tril(F, -1)):
            raise RuntimeError(f"pattern {key}: the factor is not upper triangular")
        factor.append(F[rows_i, cols_i])
        Ap, An = np.ascontiguousarray(A[1]), np.ascontiguousarray(A[-1])
        Mp, Mn = pat.M[1], pat.M[-1]
        if not np.array_equal(Mp[:n], Mn[:n]) or np.any(Mp[n:, 6:]) or np.any(Mn[n:, 6:]):
            raise RuntimeError(f"pattern {key}: the bound map reads beyond the first six parameters")
        flip = np.any(Ap != An, axis=1) | np.any(Mp[n:, :6] != Mn[n:, :6], axis=1)
        D = np.where(flip, -1.0, 1.0)
        if not (np.array_equal(An, D[:, None] * Ap) and np.array_equal(Mn[n:, :6], D[:, None] * Mp[n:, :6])):
            raise RuntimeError(f"pattern {key}: the back flank's rows are not the front's with the mesh rows negated")
        rows.append(Ap.ravel())
        Cr.append(Mp[n:, :6].ravel())
        mesh.append(flip.astype(np.int8))
        g = np.zeros(n, dtype=np.int8)
        g[pat.gap_rows] = 1
        gap.append(g)
        has_landing.append(int(pat.has_landing))
        land_row.append(int(pat.land_row))
        for i in range(n):
            nz = np.flatnonzero(Mp[i])
            G_idx.extend(nz.tolist())
            G_val.extend(Mp[i, nz].tolist())
            G_ptr.append(len(G_idx))
        ki, kj = np.nonzero(pat.K)
        K_row.extend(ki.tolist())
        K_col.extend(kj.tolist())
        K_val.extend(pat.K[ki, kj].tolist())
        K_ptr.append(len(K_val))
    md = c.model
    vals: dict[str, Any] = {
        "n_pat": len(keys), "n_p": n_p, "all_contact": index[c._all_contact], "rigid": int(c._rigid),
        "uses_load": int(c.uses_load_encoder), "n_cross": c.n_cross, "n_lead": c.n_lead,
        "bound_landing": int(c._bound_landing),
        "Ts": c.Ts, "b": c._b, "tol": c._tol, "umax": c._umax, "tau_load": c._tau_load, "rb1": c._rb1, "rb2": c._rb2,
        "kappa1": md.kappa1, "kappa2": md.kappa2, "ratio": c._ratio, "J_eq": c.info.J_eq, "d_eq": c.info.d_eq,
        "impact_innovation": c._impact_innovation,
        "flicker_innovation": c._flicker_innovation, "flicker_return": c._flicker_return,
        "a_max": c._a_max, "v_land": c._v_land, "f_land": c._f_land,
        "deadband": c.settings.standstill_deadband, "cross_share": _cross_share(),
        "learn_below": getattr(c, "_learn_below", c._b - c._tol), "tc1": c._tc1, "w_friction": c._w_friction,
        "tc2": c._tc2, "gap_limit": c.gap_limit,
        "gate_motor": c.reading_gate[0], "gate_load": c.reading_gate[1], "c_centre": c._c_centre,
        "gov_on": int(c._gov_on), "a_net": c._a_net, "a_gov": c._a_gov, "dp_pass": c._dp_pass, "dv_pass": c._dv_pass,
        "v_gov": c._v_gov,
        "gap_rows": list(c._gap_rows), "centre_rows": list(c._centre_rows), "Lc": list(c._Lc),
        "Lg_small": list(c._Lg[0]), "Lg_big": list(c._Lg[1]),
        "pat_index": CArray("gcx_pat_index", "int16_t", pat_index),
        "has_landing": CArray("gcx_has_landing", "int8_t", np.array(has_landing)),
        "land_row": CArray("gcx_land_row", "int16_t", np.array(land_row)),
        "gap_mask": CArray("gcx_gap_mask", "int8_t", np.concatenate(gap)),
        "mesh_mask": CArray("gcx_mesh_mask", "int8_t", np.concatenate(mesh)),
        "factor": CArray("gcx_factor", "double", np.concatenate(factor)),
        "rows": CArray("gcx_rows", "double", np.concatenate(rows)),
        "G_ptr": CArray("gcx_G_ptr", "int32_t", np.array(G_ptr)),
        "G_idx": CArray("gcx_G_idx", "uint16_t", np.array(G_idx)),
        "G_val": CArray("gcx_G_val", "double", np.array(G_val)),
        "Cr": CArray("gcx_Cr", "double", np.concatenate(Cr)),
        "K_ptr": CArray("gcx_K_ptr", "int32_t", np.array(K_ptr)),
        "K_row": CArray("gcx_K_row", "uint16_t", np.array(K_row)),
        "K_col": CArray("gcx_K_col", "uint16_t", np.array(K_col)),
        "K_val": CArray("gcx_K_val", "double", np.array(K_val)),
    }
    if md.N != c._ratio:
        raise RuntimeError("the gap model's gear ratio differs from the MPC's")
    dims = {"GCX_MPC_N": n, "GCX_MPC_NP": n_p, "GCX_MPC_WORK": work_size(n, m)}
    return vals, dims


def _cross_share() -> float:
    """The share of the torque limit a planned crossing uses (mpc.py's ``_CROSS_SHARE``; 0.25 before it had one)."""
    from ..design import mpc

    return float(getattr(mpc, "_CROSS_SHARE", 0.25))


def table_figures(values: dict[str, Any]) -> dict[str, int]:
    """Bytes of each MPC table, and the total.

    Parameters
    ----------
    values : dict
        The struct's values (:func:`mpc_values`); its :class:`~gearctl.export.cstruct.CArray` entries count.

    Returns
    -------
    dict of str to int
        ``name -> bytes`` per table, and ``total`` [bytes].
    """
    out = {k: v.nbytes for k, v in values.items() if isinstance(v, CArray)}
    out["total"] = sum(out.values())
    return out
