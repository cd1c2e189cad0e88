"""Figures of merit of closed-loop runs: tracking error, impacts, solver timing."""

from __future__ import annotations

from typing import Any

import numpy as np

from .closedloop import ClosedLoopResult

__all__ = ["tracking_metrics"]


def tracking_metrics(res: ClosedLoopResult, *, settle: float | None = None) -> dict[str, Any]:
    """Tracking figures of a closed-loop run (load angle, SI units).

    Parameters
    ----------
    res : ClosedLoopResult
        The run.
    settle : float, optional
        Time [s] excluded at the start from the RMS and max error (start-up transient); default the
        reference's ``settle``.

    Returns
    -------
    dict
        ``rms_error``, ``max_error``, ``final_error`` [rad] (load angle ``r - theta2``; final: at the last
        sample), ``impacts`` (count, both flanks), ``impacts_front``, ``impacts_back``,
        ``max_impact_velocity`` [m/s] (relative velocity along the line of action), ``fallbacks``
        (count), ``overruns`` (solves over the controller's time budget),
        ``solve_time`` {``median``, ``p99``, ``max``} [s] or None for controllers that solve no
        optimisation, ``torque_rms`` [N m], ``saturated_fraction`` (samples at the torque limit),
        ``duration`` [s], ``wall_time`` [s].
    """
    e = res.error
    keep = res.t >= (res.settle if settle is None else settle)
    ek = e[keep] if np.any(keep) else e
    imp = res.impacts
    st = res.solve_times
    lim = res.plant.torque_limit
    return {
        "rms_error": float(np.sqrt(np.mean(ek**2))),
        "max_error": float(np.max(np.abs(ek))),
        "final_error": float(e[-1]),
        "impacts": len(imp),
        "impacts_front": sum(1 for i in imp if i.side == "front"),
        "impacts_back": sum(1 for i in imp if i.side == "back"),
        "max_impact_velocity": float(max((abs(i.velocity) for i in imp), default=0.0)),
        "fallbacks": len(res.fallbacks),
        "overruns": res.overruns,
        "solve_time": None if st.size == 0 else {
            "median": float(np.median(st)), "p99": float(np.percentile(st, 99)), "max": float(np.max(st)),
        },
        "torque_rms": float(np.sqrt(np.mean(res.torque**2))),
        "saturated_fraction": float(np.mean(np.abs(res.torque) >= lim * (1 - 1e-12))) if np.isfinite(lim) else 0.0,
        "duration": float(res.t[-1]),
        "wall_time": res.wall_time,
    }
