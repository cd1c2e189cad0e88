"""Figures of merit of closed-loop runs: tracking error, impacts, solver timing, and the loop's health.

:func:`tracking_metrics` returns a :class:`TrackingMetrics` (a frozen dataclass that also reads like a
mapping, ``m.rms_error`` or ``m["rms_error"]``); :func:`loop_health` says what is wrong with a loop that
produced numbers: a load that does not follow the reference, a controller that keeps falling back, a
sustained limit cycle, a saturated actuator, an impact rate above a threshold, a growing error or one beyond the
reference's excursion.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from typing import Any

import numpy as np

from .closedloop import ClosedLoopResult
from .errors import InputError

__all__ = ["TrackingMetrics", "LoopHealth", "tracking_metrics", "loop_health", "HEALTH_LIMITS"]

#: Thresholds of :func:`loop_health` (see its Notes for what each compares and why these values).
HEALTH_LIMITS = {
    "impact_rate": 100.0,  # impacts per second after the start-up
    "saturated_fraction": 0.2,  # of the samples after the start-up, at the torque limit
    "limit_cycle_impacts": 20,  # impacts in the last quarter of the run, on alternating flanks ...
    "limit_cycle_alternation": 0.6,  # ... this fraction of consecutive impact pairs on opposite flanks
    "growth": 10.0,  # error of the last quarter over that of the middle half and the reference's later change
    # the error of a load that stays where it started is the reference's excursion r - theta_load(0):
    "tracking": 0.5,  # median |error| after the settle time over the RMS excursion there (standing still: ~1)
    "runaway": 2.0,  # largest |error| of the last quarter over the reference's largest excursion (standing still: 1)
    "fallback_share": 0.05,  # of the controller's steps that fell back to a safe command
    # a sawtooth torque: samples (after the start-up) where the torque turns back, by more than chatter_step of the
    # limit on each side; over chatter_share of them the loop chatters (see loop_health)
    "chatter_step": 0.05,
    "chatter_share": 0.2,
}


class UnknownKeyError(InputError, KeyError):
    """A key that is not a figure of a metrics mapping: an :class:`InputError` naming it (with the keys there are)
    and a ``KeyError``, as the mapping protocol asks (``except KeyError`` keeps working)."""

    __str__ = BaseException.__str__  # KeyError's would print the message in quotes


class _Mapping:
    """Read a frozen dataclass like a mapping (``m["key"]``, ``dict(m)``, ``**m``)."""

    __slots__ = ()

    def keys(self) -> list[str]:
        """The field names."""
        return [f.name for f in dataclasses.fields(self)]  # type: ignore[arg-type]

    def __getitem__(self, key: str) -> Any:
        if key not in self.keys():
            import difflib

            close = ([k for k in self.keys() if k.startswith(str(key))]
                     or difflib.get_close_matches(str(key), self.keys(), n=1))
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise UnknownKeyError(f"{key!r} is not a figure of {type(self).__name__}: expected one of "
                                  f"{', '.join(self.keys())}{hint}", field=str(key))
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
    """What is wrong with a loop, if anything (:func:`loop_health`; thresholds :data:`HEALTH_LIMITS`).

    Attributes
    ----------
    not_following : bool
        The load does not follow the reference: after the settle time the error is above half the
        reference's RMS excursion more than half of the time (``tracking_ratio > tracking``).
    falling_back : bool
        The controller fell back to a safe command on more than ``fallback_share`` of its steps.
    limit_cycle : bool
        Impacts go on to the end on alternating flanks: the loop hunts across the gap.
    saturated : bool
        The motor torque sits on its limit for more than a fifth of the run.
    impact_rate_high : bool
        More impacts per second than :data:`HEALTH_LIMITS` ``impact_rate``.
    growing : bool
        The error grows or ran away: the last quarter's is ten times the middle half's (second and third
        quarters) and ten times any change of the reference after the middle half, or it is more than twice
        the reference's largest excursion (an error that grew early and stayed; see :func:`loop_health`).
    chattering : bool
        The torque saws from sample to sample: ``torque_chatter`` above ``chatter_share``.
    impact_rate : float
        Impacts per second after the start-up [1/s].
    tracking_ratio : float or None
        Median ``|error|`` after the settle time over the RMS excursion of the reference there [1]; about 1
        for a load that never moves; None when there is nothing to follow (no sample after the settle time,
        or a reference that stays where the load started).
    fallback_share : float
        Fallbacks per controller step [1].
    torque_chatter : float
        Share of the samples after the start-up where the torque turns back by more than ``chatter_step`` of the
        torque limit on each side (a sample-to-sample sawtooth) [1].
    warnings : tuple of str
        One sentence per problem, for the user.
    """

    not_following: bool
    falling_back: bool
    limit_cycle: bool
    saturated: bool
    impact_rate_high: bool
    growing: bool
    impact_rate: float
    tracking_ratio: float | None
    fallback_share: float
    warnings: tuple[str, ...]
    chattering: bool = False
    torque_chatter: float = 0.0

    @property
    def ok(self) -> bool:
        """No problem found."""
        return not self.warnings


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class TrackingMetrics(_Mapping):
    """Tracking figures of a closed-loop run (load angle, SI units); see :func:`tracking_metrics`.

    Read as a mapping too (``m["rms_error"]``, ``dict(m)``, :meth:`as_dict`); an unknown key raises an
    :class:`~gearctl.errors.InputError` that is also a ``KeyError``.

    Attributes
    ----------
    rms_error : float
        RMS of the load-angle error ``r - theta_load`` over the scored samples (from the settle time on) [rad].
    max_error : float
        Largest ``|r - theta_load|`` over the scored samples [rad].
    final_error : float
        ``r - theta_load`` at the last sample, signed [rad].
    impacts : int
        Impacts on every flank and stage, plastic ones included (``impacts_front + impacts_back``).
    impacts_front : int
        Impacts on the front flanks.
    impacts_back : int
        Impacts on the back flanks.
    impacts_per_stage : tuple of int
        Impacts on each stage, motor side first (one entry for a pair).
    max_impact_velocity : float
        Largest relative velocity along the line of action at an impact [m/s] (0 without impacts).
    fallbacks : int
        Controller steps that fell back to a safe command.
    overruns : int
        Solves over the controller's time budget.
    solve_time : dict or None
        ``median``, ``p99`` and ``max`` of the controller's per-step solve times [s]; None for a controller that
        solves no optimisation.
    torque_rms : float
        RMS of the motor torque over the whole run [N m].
    saturated_fraction : float
        Share of all samples with the torque at its limit [1] (0 without a limit).
    duration : float
        Simulated time, the last sample's time [s].
    wall_time : float
        Wall-clock time of the run [s].
    health : LoopHealth
        What is wrong with the loop, if anything (:func:`loop_health`).
    """

    rms_error: float
    max_error: float
    final_error: float
    impacts: int
    impacts_front: int
    impacts_back: int
    impacts_per_stage: tuple[int, ...]
    max_impact_velocity: float
    fallbacks: int
    overruns: int
    solve_time: dict[str, float] | None
    torque_rms: float
    saturated_fraction: float
    duration: float
    wall_time: float
    health: LoopHealth


def scored_from(res: ClosedLoopResult, settle: float | None = None) -> float:
    """Start of the interval the error statistics cover [s]: ``settle`` as given, else the reference's settle time,
    or 0 where the run leaves less than a tenth of that after it (a 0.5 s sine, whose settle time is 0.5 s, was
    scored on its last sample alone: RMS and max equal, a "not following" warning at 5e13 times the reference's
    excursion there). A tenth, not more: a 0.85 s step run scored whole would count the step itself (0.05 rad)."""
    if settle is not None:
        return settle
    t0 = res.settle
    end = float(res.t[-1]) if res.t.size else 0.0
    return 0.0 if t0 > 0.0 and end - t0 < 0.1 * t0 else t0


def _check_run(res: Any, settle: Any) -> None:
    """The :class:`InputError` of a ``res`` that is no closed-loop run or a ``settle`` outside it."""
    if not isinstance(res, ClosedLoopResult):
        from .errors import short_repr

        raise InputError(f"res = {short_repr(res)} is not a closed-loop run (a {type(res).__name__}): expected the "
                         "ClosedLoopResult of simulate_closed_loop (or a precision test's .run)", field="res")
    end = float(res.t[-1]) if res.t.size else 0.0
    if settle is not None and not (isinstance(settle, int | float | np.floating) and 0.0 <= settle <= end):
        raise InputError(f"settle = {settle!r} is out of range: expected 0 <= value <= {end:g} [s] (the run's end: "
                         "past it nothing would be scored)", field="settle")


def loop_health(res: ClosedLoopResult, *, settle: float | None = None) -> LoopHealth:
    """Say what is wrong with a loop that ran to its end.

    Parameters
    ----------
    res : ClosedLoopResult
        The run (a tracking run, or a positioning program such as ISO 230-2's with ``settle=0``).
    settle : float, optional
        Start-up time excluded [s] (default the reference's).

    Returns
    -------
    LoopHealth
        Flags, figures and one warning sentence per problem (thresholds: :data:`HEALTH_LIMITS`).

    Notes
    -----
    *Yardstick.* A load that stays where it started, at ``theta_load(0)``, has the error
    ``x(t) = r(t) - theta_load(0)``, the reference's *excursion*; the checks of the tracking error measure it
    against that, so they hold for any reference (a sine, a step, a move, a positioning program) and any
    amplitude. A reference that never leaves the load's start gives no yardstick: those checks are skipped.

    *Not following* (``tracking``): over the samples after the settle time, the median ``|e|`` against the
    RMS of ``x``, so ``tracking_ratio > 0.5`` reads "the error is above half the reference's RMS excursion
    more than half of the time". A load that never moves scores 1 on a sine or a step (``median |sin|`` is
    ``1/sqrt 2`` of the amplitude, as the RMS) and about 0.8 on the ISO 230-2 program; the catalog's
    healthy runs score at most 0.18 (track) and 0.031 (precision). The median, not the RMS: a load
    disturbance the loop rejects puts a short error of its own size into a step's hold (once 0.16 rad for 0.3 s
    on a 0.05 rad step, ``servo_3stage_quanser_srv02`` with ``deadzone_inverse`` and an absolute disturbance
    threshold: RMS ratio 1.19, as bad as standing still, while the loop was fine: median ratio 0.04; now 0.08 rad
    at most). The final error is not used: one sample,
    it is large at the end of any run that ends while the reference moves.

    *Falling back* (``fallback_share``): fallbacks per controller step (``len(t) - 1`` steps); an
    optimisation that fails on one step in twenty no longer controls the loop it was designed for.

    *Growing error* (``growth``): the largest error of the last quarter of the run, ``e_4``, against that of
    the middle half (second and third quarters), ``e_23``: half the run, so that an error that comes back
    once per period of a slower motion (a 1 Hz sine's reversal in a 3 s run) is seen in both. A reference
    that changes after the middle half (a step, the start of a ramp or a move) puts up to its own change
    into the error of a stable loop (right after a step of ``h`` the error is ``h``), which no earlier error
    foretells. So the yardstick is the larger of ``e_23`` and that change: the error grows when
    ``e_4 > growth x max(e_23, dr)`` with ``dr = max(0, ptp(r, last quarter) - ptp(r, middle half))``
    (``ptp``: the reference's range) and ``e_4 > 1 mrad``. That misses an error that grew early and stayed
    (``e_23`` is already large), so the error also counts as growing when ``e_4 > runaway x max|x|``: a load
    that never moves scores 1, a loop that ran the load off beyond the reference's whole excursion more
    (the catalog's healthy runs score at most 0.30).

    Raises
    ------
    InputError
        If ``res`` is not a :class:`~gearctl.closedloop.ClosedLoopResult` (a ``settle`` past the run's end is no
        error here: the checks that need the time after it are skipped).
    """
    _check_run(res, None)
    lim = HEALTH_LIMITS
    t0 = scored_from(res, settle)
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
    # the reference's excursion: the error of a load that stays where it started
    x = r - res.load_angle[0]
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    runaway = bool(peak > 0.0 and last > lim["runaway"] * peak)
    ratio = None
    if np.any(keep):
        x_rms = float(np.sqrt(np.mean(x[keep] ** 2)))
        if x_rms > 0.0:
            ratio = float(np.median(e[keep]) / x_rms)
    not_following = bool(ratio is not None and ratio > lim["tracking"])
    chatter = torque_chatter(res, t0)
    chattering = chatter > lim["chatter_share"]
    steps = max(res.t.size - 1, 1)
    share = len(res.fallbacks) / steps
    falling_back = share > lim["fallback_share"]
    warnings = []
    if not_following:
        warnings.append(f"not following the reference: after {t0:.3g} s the median error is {ratio:.3g} times the "
                        f"reference's RMS excursion of {x_rms:.3g} rad (a load that stays still scores about 1)")
    if falling_back:
        reason = res.fallbacks[0].get("reason", "") if res.fallbacks else ""
        warnings.append(f"controller falling back: {len(res.fallbacks)} of {steps} steps ({share:.0%}) used the "
                        f"fallback command" + (f" (first: {reason})" if reason else ""))
    if cycle:
        warnings.append(f"sustained limit cycle: {late.size} impacts in the last {0.25 * T:.3g} s on alternating "
                        f"flanks ({alternation:.0%} of consecutive impacts change flank)")
    if sat > lim["saturated_fraction"]:
        warnings.append(f"saturated actuator: the motor torque is at its {torque_lim:g} N m limit {sat:.0%} of the "
                        f"time" + (f" after the start-up ({t0:.3g} s; saturated_fraction counts the whole run)"
                                   if t0 > 0.0 else ""))
    if rate > lim["impact_rate"]:
        per_stage = ""
        if res.plant.n_stages > 1 and after.size:  # which meshes rattle: a train's intermediate shafts float too
            scale = rate / after.size
            per_stage = " (" + ", ".join(f"stage {k + 1}: {np.count_nonzero(after['where'] == k) * scale:.3g}"
                                         for k in range(res.plant.n_stages)) + ")"
        warnings.append(f"impact rate {rate:.4g} per s, above {lim['impact_rate']:g} per s{per_stage}")
    if chattering:
        # (the scale torque_chatter measured with: without a torque limit, the run's largest torque)
        scale_words = (f"its {torque_lim:g} N m limit" if np.isfinite(torque_lim) else
                       f"the run's largest torque, {float(np.max(np.abs(res.torque))):.3g} N m (no torque limit)")
        warnings.append(f"chattering torque: on {chatter:.0%} of the samples after {t0:.3g} s the torque turns back by "
                        f"more than {lim['chatter_step']:.0%} of {scale_words} each way (a "
                        f"sample-to-sample sawtooth): the loop's gains are too high for its encoders' counts and "
                        f"noise, or for dynamics its model leaves out (a train's intermediate shafts); "
                        f"{_chatter_remedy(res.controller)}")
    if growing:
        beyond = f" and the reference's own change of {explained:.3g} rad" if explained > 0 else ""
        warnings.append(f"growing error: {last:.3g} rad in the last quarter against {early:.3g} rad in the "
                        f"middle half{beyond}")
    elif runaway:
        # a load run off, or one that swings that far in a sustained oscillation: the last quarter cannot tell
        warnings.append(f"error beyond the reference: {last:.3g} rad in the last quarter, {last / peak:.3g} times "
                        f"the reference's largest excursion of {peak:.3g} rad from where the load started (the load "
                        f"ran off, or swings that far)")
    return LoopHealth(not_following=not_following, falling_back=falling_back, limit_cycle=cycle,
                      saturated=sat > lim["saturated_fraction"], impact_rate_high=rate > lim["impact_rate"],
                      growing=growing or runaway, impact_rate=rate, tracking_ratio=ratio, fallback_share=share,
                      warnings=tuple(warnings), chattering=chattering, torque_chatter=chatter)


def _chatter_remedy(controller: Any) -> str:
    """What to try against a chattering torque, by the controller's kind (its ``describe()``)."""
    kind = controller.get("kind") if isinstance(controller, dict) else None
    if kind == "mpc":
        return ("compare with the PID and the deadzone_inverse (gearctl bench MODEL): the MPC's plan does not suit "
                "this plant's encoders or the dynamics its model leaves out (a train's intermediate shafts)")
    if kind in ("pid", "deadzone_inverse", "adaptive_inverse", "reversal_offset"):
        return "lower its [design] bandwidth_hz, or use finer encoders"
    return "lower its gains, or use finer encoders"


def torque_chatter(res: ClosedLoopResult, settle: float = 0.0) -> float:
    """Share of the samples from ``settle`` [s] on where the torque turns back by more than
    :data:`HEALTH_LIMITS` ``chatter_step`` of the torque limit on each side (``u[k] - u[k-1]`` and ``u[k+1] - u[k]``
    of opposite signs, both that large): a sample-to-sample sawtooth [1].

    Measured on the catalog's runs (sine, step and move; PID, inverse, reversal offset, MPC): at most 0.08 where the
    loop is sound, 0.45 for the MPC on ``servo_2stage_phm09`` (1.07x the PID's sine RMS). On a reviewer's pair with
    a 65536-count load encoder beside a 2^18-count motor encoder (``tests/data/reviewer_pair_24x72.toml``) the MPC
    scored 0.51 and tracked the sine 2.8x worse than the PID, until its observer weighed the load reading by its own
    error (0.10 now; see *Coarse load encoders* in :mod:`gearctl.design.mpc`); on a 14-bit instrument drive
    (``tests/data/h5_instrument_coarse_14bit.toml``) it scores 0.22 and is 6x worse than the PID.
    Without a torque limit the largest torque of the run is the scale.
    """
    u = np.asarray(res.torque, dtype=float)
    if u.size < 3:
        return 0.0
    scale = res.plant.torque_limit if np.isfinite(res.plant.torque_limit) else float(np.max(np.abs(u)))
    if not scale > 0.0:
        return 0.0
    d = np.diff(u)
    big = np.abs(d) > HEALTH_LIMITS["chatter_step"] * scale
    saw = (d[1:] * d[:-1] < 0.0) & big[1:] & big[:-1]
    keep = res.t[1:-1] >= settle
    return float(np.mean(saw[keep])) if keep.any() else 0.0


def tracking_metrics(res: ClosedLoopResult, *, settle: float | None = None) -> TrackingMetrics:
    """Tracking figures of a closed-loop run (load angle, SI units).

    Parameters
    ----------
    res : ClosedLoopResult
        The run.
    settle : float, optional
        Time [s] excluded at the start from the RMS and max error (start-up transient), 0 up to the run's end;
        default the reference's ``settle``; none where the run is shorter than 1.1 times it (:func:`scored_from`).

    Returns
    -------
    TrackingMetrics
        ``rms_error``, ``max_error``, ``final_error`` [rad] (load angle ``r - theta_load``; final: at the last
        sample), ``impacts`` (count, all flanks and stages, exact), ``impacts_front``, ``impacts_back``,
        ``impacts_per_stage``,
        ``max_impact_velocity`` [m/s] (relative velocity along the line of action), ``fallbacks``
        (count), ``overruns`` (solves over the controller's time budget),
        ``solve_time`` {``median``, ``p99``, ``max``} [s] or None for controllers that solve no
        optimisation, ``torque_rms`` [N m], ``saturated_fraction`` (samples at the torque limit),
        ``duration`` [s], ``wall_time`` [s], ``health`` (:func:`loop_health`).

    Raises
    ------
    InputError
        If ``res`` is not a :class:`~gearctl.closedloop.ClosedLoopResult`, or ``settle`` not a number in 0 up to
        the run's end.
    """
    _check_run(res, settle)
    e = res.error
    keep = res.t >= scored_from(res, settle)
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
        impacts_per_stage=tuple(int(v) for v in c["impacts_front"] + c["impacts_back"] + c["plastic_front"]
                                + c["plastic_back"]),
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
