"""Figures of merit of closed-loop runs: tracking error, impacts, solver timing, and the loop's health.

:func:`tracking_metrics` returns a :class:`TrackingMetrics` (a frozen dataclass that also reads like a
mapping, ``m.rms_error`` or ``m["rms_error"]``); :func:`loop_health` says what is wrong with a loop that
produced numbers: a sustained limit cycle, a saturated actuator, an impact rate above a threshold, a
growing error.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from typing import Any

import numpy as np

from .closedloop import ClosedLoopResult

__all__ = ["TrackingMetrics", "LoopHealth", "tracking_metrics", "loop_health", "HEALTH_LIMITS"]

#: Thresholds of :func:`loop_health`.
HEALTH_LIMITS = {
    "impact_rate": 100.0,  # impacts per second after the start-up
    "saturated_fraction": 0.2,  # of the samples after the start-up, at the torque limit
    "limit_cycle_impacts": 20,  # impacts in the last quarter of the run, on alternating flanks ...
    "limit_cycle_alternation": 0.6,  # ... this fraction of consecutive impact pairs on opposite flanks
    "growth": 10.0,  # error of the last quarter over that of the middle half and the reference's later change
}


class _Mapping:
    """Read a frozen dataclass like a mapping (``m["key"]``, ``dict(m)``, ``**m``)."""

    __slots__ = ()

    def keys(self) -> list[str]:
        """The field names."""
        return [f.name for f in dataclasses.fields(self)]  # type: ignore[arg-type]

    def __getitem__(self, key: str) -> Any:
        if key not in self.keys():
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self) -> Iterator[str]:
        return iter(self.keys())

    def __len__(self) -> int:
        return len(self.keys())

    def get(self, key: str, default: Any = None) -> Any:
        """``m[key]`` if it exists, else ``default``."""
        return getattr(self, key) if key in self.keys() else default

    def as_dict(self) -> dict[str, Any]:
        """A plain dict (nested dataclasses too), ready for JSON."""
        return {k: (v.as_dict() if isinstance(v, _Mapping) else v) for k, v in
                ((k, getattr(self, k)) for k in self.keys())}


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class LoopHealth(_Mapping):
    """What is wrong with a loop, if anything (:func:`loop_health`).

    Attributes
    ----------
    limit_cycle : bool
        Impacts go on to the end on alternating flanks: the loop hunts across the gap.
    saturated : bool
        The motor torque sits on its limit for more than a fifth of the run.
    impact_rate_high : bool
        More impacts per second than :data:`HEALTH_LIMITS` ``impact_rate``.
    growing : bool
        The error grows: the last quarter's is ten times the middle half's (second and third quarters) and ten
        times any change of the reference after the middle half (see :func:`loop_health`).
    impact_rate : float
        Impacts per second after the start-up [1/s].
    warnings : tuple of str
        One sentence per problem, for the user.
    """

    limit_cycle: bool
    saturated: bool
    impact_rate_high: bool
    growing: bool
    impact_rate: float
    warnings: tuple[str, ...]

    @property
    def ok(self) -> bool:
        """No problem found."""
        return not self.warnings


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class TrackingMetrics(_Mapping):
    """Tracking figures of a closed-loop run (load angle, SI units); see :func:`tracking_metrics`."""

    rms_error: float
    max_error: float
    final_error: float
    impacts: int
    impacts_front: int
    impacts_back: int
    max_impact_velocity: float
    fallbacks: int
    overruns: int
    solve_time: dict[str, float] | None
    torque_rms: float
    saturated_fraction: float
    duration: float
    wall_time: float
    health: LoopHealth


def loop_health(res: ClosedLoopResult, *, settle: float | None = None) -> LoopHealth:
    """Say what is wrong with a loop that ran to its end.

    Parameters
    ----------
    res : ClosedLoopResult
        The run.
    settle : float, optional
        Start-up time excluded [s] (default the reference's).

    Returns
    -------
    LoopHealth
        Flags and one warning sentence per problem (thresholds: :data:`HEALTH_LIMITS`).

    Notes
    -----
    Growing error: the largest error of the last quarter of the run, ``e_4``, against that of the middle half
    (second and third quarters), ``e_23``: half the run, so that an error that comes back once per period of
    a slower motion (a 1 Hz sine's reversal in a 3 s run) is seen in both. A reference that changes after
    the middle half (a step, the start of a ramp or a move) puts up to its own change into the error of a
    stable loop (right after a step of ``h`` the error is ``h``), which no earlier error foretells. So the
    yardstick is the larger of ``e_23`` and that change: the error grows when ``e_4 > growth x max(e_23, dr)``
    with ``dr = max(0, ptp(r, last quarter) - ptp(r, middle half))`` (``ptp``: the reference's range) and
    ``e_4 > 1 mrad``. A loop that cannot move at all (error = the step) is not growing; one that diverges
    passes ten times the step within a few of its time constants.
    """
    lim = HEALTH_LIMITS
    t0 = res.settle if settle is None else settle
    T = float(res.t[-1])
    span = max(T - t0, 1e-12)
    log = res.event_log
    imp = log[(log["kind"] == 1) | (log["kind"] == 5)]
    after = imp[imp["t"] >= t0]
    rate = float(res.impact_count * (after.size / max(imp.size, 1)) / span) if imp.size else 0.0
    late = imp[imp["t"] >= T - 0.25 * T]
    sides = late["side"]
    alternation = float(np.mean(sides[1:] != sides[:-1])) if sides.size > 1 else 0.0
    cycle = bool(late.size >= lim["limit_cycle_impacts"] and alternation >= lim["limit_cycle_alternation"])
    keep = res.t >= t0
    torque_lim = res.plant.torque_limit
    sat = float(np.mean(np.abs(res.torque[keep]) >= torque_lim * (1 - 1e-12))) if np.isfinite(torque_lim) and \
        np.any(keep) else 0.0
    e = np.abs(res.error)
    q = max(len(e) // 4, 1)
    early, last = float(np.max(e[q:3 * q])) if len(e) >= 4 else 0.0, float(np.max(e[-q:]))
    r = res.reference
    explained = max(float(np.ptp(r[3 * q:])) - float(np.ptp(r[q:3 * q])), 0.0) if len(r) >= 8 else 0.0
    growing = bool(len(e) >= 8 and last > lim["growth"] * max(early, explained, 1e-12) and last > 1e-3)
    warnings = []
    if cycle:
        warnings.append(f"sustained limit cycle: {late.size} impacts in the last {0.25 * T:.3g} s on alternating "
                        f"flanks ({alternation:.0%} of consecutive impacts change flank)")
    if sat > lim["saturated_fraction"]:
        warnings.append(f"saturated actuator: the motor torque is at its {torque_lim:g} N m limit {sat:.0%} of the "
                        f"time")
    if rate > lim["impact_rate"]:
        warnings.append(f"impact rate {rate:.4g} per s, above {lim['impact_rate']:g} per s")
    if growing:
        beyond = f" and the reference's own change of {explained:.3g} rad" if explained > 0 else ""
        warnings.append(f"growing error: {last:.3g} rad in the last quarter against {early:.3g} rad in the "
                        f"middle half{beyond}")
    return LoopHealth(limit_cycle=cycle, saturated=sat > lim["saturated_fraction"], impact_rate_high=rate >
                      lim["impact_rate"], growing=growing, impact_rate=rate, warnings=tuple(warnings))


def tracking_metrics(res: ClosedLoopResult, *, settle: float | None = None) -> TrackingMetrics:
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
    TrackingMetrics
        ``rms_error``, ``max_error``, ``final_error`` [rad] (load angle ``r - theta_load``; final: at the last
        sample), ``impacts`` (count, all flanks and stages, exact), ``impacts_front``, ``impacts_back``,
        ``max_impact_velocity`` [m/s] (relative velocity along the line of action), ``fallbacks``
        (count), ``overruns`` (solves over the controller's time budget),
        ``solve_time`` {``median``, ``p99``, ``max``} [s] or None for controllers that solve no
        optimisation, ``torque_rms`` [N m], ``saturated_fraction`` (samples at the torque limit),
        ``duration`` [s], ``wall_time`` [s], ``health`` (:func:`loop_health`).
    """
    e = res.error
    keep = res.t >= (res.settle if settle is None else settle)
    ek = e[keep] if np.any(keep) else e
    c = res.counts
    front = int(np.sum(c["impacts_front"] + c["plastic_front"]))
    back = int(np.sum(c["impacts_back"] + c["plastic_back"]))
    st = res.solve_times
    lim = res.plant.torque_limit
    return TrackingMetrics(
        rms_error=float(np.sqrt(np.mean(ek**2))),
        max_error=float(np.max(np.abs(ek))),
        final_error=float(e[-1]),
        impacts=front + back,
        impacts_front=front,
        impacts_back=back,
        max_impact_velocity=float(np.max(c["max_impact_velocity"])) if len(c["max_impact_velocity"]) else 0.0,
        fallbacks=len(res.fallbacks),
        overruns=res.overruns,
        solve_time=None if st.size == 0 else {
            "median": float(np.median(st)), "p99": float(np.percentile(st, 99)), "max": float(np.max(st)),
        },
        torque_rms=float(np.sqrt(np.mean(res.torque**2))),
        saturated_fraction=float(np.mean(np.abs(res.torque) >= lim * (1 - 1e-12))) if np.isfinite(lim) else 0.0,
        duration=float(res.t[-1]),
        wall_time=res.wall_time,
        health=loop_health(res, settle=settle),
    )
