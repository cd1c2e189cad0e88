"""Positioning test after ISO 230-2: reversal value, repeatability and accuracy of the load axis.

The load moves to ``m`` target positions, approaching each from the positive and from the negative
direction, over ``n`` cycles (the standard "linear cycle": P1↑ … Pm↑, overshoot, Pm↓ … P1↓, overshoot),
and dwells before each measurement. The measurement is the true load angle at the end of the dwell, as a
laser interferometer on the load would read it. Backlash shows up directly as the reversal value B.
"""

from __future__ import annotations

import bisect
import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .closedloop import ClosedLoopResult, check_controller, check_loop_memory, simulate_closed_loop
from .design.base import Controller
from .errors import InputError
from .params import Sensors
from .plant import Plant, check_plant
from .references import move_point, move_times, pointwise
from .units import DURATION, SEED

__all__ = ["MotionProgram", "PrecisionResult", "iso230_statistics", "precision_test"]


@dataclasses.dataclass(frozen=True, slots=True)
class MotionProgram:
    """A sequence of S-curve point-to-point moves with dwells: a reference like :class:`Reference`.

    Attributes
    ----------
    starts : tuple of float
        Start time of each move [s].
    origins, targets : tuple of float
        Load angle at the start and the end of each move [rad].
    velocity, accel : float
        Cruise velocity [rad/s] and peak acceleration [rad/s^2] of every move.
    settle : float
        Start of the error statistics [s] (0).
    """

    starts: tuple[float, ...]
    origins: tuple[float, ...]
    targets: tuple[float, ...]
    velocity: float
    accel: float
    settle: float = 0.0

    def duration(self, D: float) -> float:
        """Duration of one move over ``|D|`` [s].

        Parameters
        ----------
        D : float
            The move's travel, either sign [rad].
        """
        ta, tc, _ = move_times(abs(D), self.velocity, self.accel)
        return 2 * ta + tc

    def _move(self, k: int, tau: float) -> tuple[float, float, float]:
        D = self.targets[k] - self.origins[k]
        sgn = 1.0 if D >= 0 else -1.0
        p, dp, ddp = move_point(tau, abs(D), self.velocity, self.accel)
        return self.origins[k] + sgn * p, sgn * dp, sgn * ddp

    def at(self, t: Any) -> tuple[Any, Any, Any]:
        """``(r, r', r'')`` at time(s) ``t`` [rad, rad/s, rad/s^2].

        Before the first start the program rests at the first origin; between moves, at the last target.

        Parameters
        ----------
        t : float or array_like
            Time(s) [s].

        Returns
        -------
        tuple
            ``(r, r', r'')``: three floats for a scalar ``t``, else three arrays of ``t``'s shape.
        """
        return pointwise(self._at, t)

    def _at(self, t: float) -> tuple[float, float, float]:
        k = max(0, bisect.bisect_right(self.starts, t) - 1)
        return self._move(k, t - self.starts[k])

    def load_disturbance(self, t: float) -> float:
        """No disturbance during a positioning test.

        Parameters
        ----------
        t : float
            Time [s] (unused).

        Returns
        -------
        float
            0 [N m].
        """
        return 0.0


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class PrecisionResult:
    """Outcome of :func:`precision_test` (load angle in rad).

    Attributes
    ----------
    targets : ndarray, shape (m,)
        Target positions P_i.
    deviations_up, deviations_down : ndarray, shape (m, n)
        Deviations x_ij = measured - target approaching in the positive / negative direction.
    stats : dict
        :func:`iso230_statistics` of the deviations.
    run : ClosedLoopResult
        The whole closed-loop run.
    """

    targets: NDArray[np.float64]
    deviations_up: NDArray[np.float64]
    deviations_down: NDArray[np.float64]
    stats: dict[str, Any]
    run: ClosedLoopResult


def iso230_statistics(up: NDArray[np.float64], down: NDArray[np.float64]) -> dict[str, Any]:
    """ISO 230-2 statistics from deviations ``up``, ``down`` of shape (targets, cycles).

    Parameters
    ----------
    up : ndarray, shape (m, n)
        Deviations ``x_ij = measured - target`` approaching target ``i`` in the positive direction, cycle ``j``
        [rad] (every figure returned is in the unit given).
    down : ndarray, shape (m, n)
        The same, approaching in the negative direction [rad].

    Returns
    -------
    dict
        Per target: ``mean_up``, ``mean_down``, ``s_up``, ``s_down`` (n-1 estimator), ``reversal`` B_i,
        ``mean_bidirectional``; overall: ``reversal_value`` B = max |B_i|, ``repeatability_up`` R↑ and
        ``repeatability_down`` R↓ (max 4 s_i), ``repeatability`` R (bidirectional, max of
        ``2 s_i↑ + 2 s_i↓ + |B_i|``, R_i↑, R_i↓), ``mean_reversal`` (mean of B_i),
        ``mean_bidirectional_deviation`` M (range of the mean bidirectional deviations),
        ``systematic_deviation`` E (range of all unidirectional means), ``accuracy`` A (range of
        ``mean ± 2 s`` over both directions); beside the standard's figures, ``mean_deviation`` (the mean of all
        deviations: a constant offset, which every range above leaves out) and ``largest_deviation`` (the
        largest ``|deviation|``).
    """
    n = up.shape[1]
    mu, md = up.mean(axis=1), down.mean(axis=1)
    su = up.std(axis=1, ddof=1) if n > 1 else np.zeros_like(mu)
    sd = down.std(axis=1, ddof=1) if n > 1 else np.zeros_like(md)
    B_i = mu - md
    R_up, R_down = 4 * su, 4 * sd
    R_i = np.maximum.reduce([2 * su + 2 * sd + np.abs(B_i), R_up, R_down])
    mean_bi = (mu + md) / 2
    A = max(np.max(mu + 2 * su), np.max(md + 2 * sd)) - min(np.min(mu - 2 * su), np.min(md - 2 * sd))
    every = np.concatenate([up.ravel(), down.ravel()])
    return {
        "mean_up": mu, "mean_down": md, "s_up": su, "s_down": sd, "reversal": B_i, "mean_bidirectional": mean_bi,
        "reversal_value": float(np.max(np.abs(B_i))),
        "mean_reversal": float(np.mean(B_i)),
        "repeatability_up": float(np.max(R_up)),
        "repeatability_down": float(np.max(R_down)),
        "repeatability": float(np.max(R_i)),
        "mean_bidirectional_deviation": float(np.max(mean_bi) - np.min(mean_bi)),
        "systematic_deviation": float(max(mu.max(), md.max()) - min(mu.min(), md.min())),
        "accuracy": float(A),
        "mean_deviation": float(np.mean(every)),
        "largest_deviation": float(np.max(np.abs(every))),
    }


def precision_health(res: PrecisionResult, lost_motion: float, travel: float) -> Any:
    """The ISO run's :class:`gearctl.metrics.LoopHealth`, its warnings followed by :func:`unreached_targets`' (what
    ``gearctl precision`` and the bench's ISO rows report)."""
    from .metrics import loop_health

    health = loop_health(res.run, settle=0.0)
    return dataclasses.replace(health, warnings=health.warnings + tuple(unreached_targets(res, lost_motion, travel)))


#: A reversal value B beyond this many lost motions is warned of (:func:`unreached_targets`).
REVERSAL_LIMIT = 2.0


def unreached_targets(res: PrecisionResult, lost_motion: float, travel: float) -> list[str]:
    """Warnings for measurements that missed their target by more than backlash can explain, and for a constant
    offset the ISO figures leave out.

    A deviation beyond three times the lost motion plus a thousandth of the travel (rad, load side) means the
    loop did not position: an uncompensated gap leaves at most about the lost motion. One warning names the
    largest such deviation and how many measurements were that far off. A reversal value B beyond
    :data:`REVERSAL_LIMIT` times the lost motion (plus a thousandth of the travel) is the loop's, not the gap's (a
    review's four-stage train under the MPC: B 4.3 times its lost motion, with no deviation past the first limit).
    A mean deviation larger than the accuracy A (and than a hundredth of the lost motion) is a constant offset that
    A, B and R do not show: a load torque that holds the load on one flank leaves the motor-encoder PID half the
    lost motion off.
    """
    dev = np.concatenate([res.deviations_up.ravel(), res.deviations_down.ravel()])
    limit = 3.0 * lost_motion + 1e-3 * travel
    far = np.abs(dev) > limit
    out = []
    if far.any():
        worst = float(dev[np.argmax(np.abs(dev))])
        out.append(f"targets not reached: {int(far.sum())} of {dev.size} measurements deviate by more than "
                   f"{limit:.3g} rad (3 x the lost motion + travel / 1000), the largest by {worst:.3g} rad")
    B = res.stats["reversal_value"]
    if B > REVERSAL_LIMIT * lost_motion + 1e-3 * travel:
        # (a train without lost motion: no ratio to give; B / 0 raised ZeroDivisionError out of the test's health)
        size = (f"{B / lost_motion:.3g} x the lost motion {lost_motion:.3g} rad (an uncompensated gap reverses by "
                f"about the lost motion)" if lost_motion > 0.0 else "on a train without lost motion")
        out.append(f"reversal beyond the gap: B = {B:.3g} rad is {size}: the loop itself lands the load on "
                   "different sides of the targets in the two directions")
    offset, A = res.stats["mean_deviation"], res.stats["accuracy"]
    if abs(offset) > max(A, 0.01 * lost_motion):
        out.append(f"constant offset: the load misses the targets by {offset:.3g} rad on average, more than the "
                   f"accuracy A = {A:.3g} rad (ISO 230-2's A, B and R leave a constant offset out; a load torque "
                   f"holding the load on one flank leaves one)")
    if res.deviations_up.shape[1] < 2:
        # one approach per target and direction: the standard's s_i (n - 1 estimator) is not defined, and the zeros
        # taken for it print as R+ 0, R- 0, a repeatability nobody measured
        out.append("one cycle: a single approach per target and direction gives no spread, so s_i is taken as 0: "
                   "R+ = R- = 0 and R, A hold only the reversal and the means, no repeatability (ISO 230-2 runs 5 "
                   "cycles): use --cycles 2 or more")
    return out


def precision_test(
    plant: Plant,
    controller: Controller,
    *,
    targets: int = 5,
    cycles: int = 5,
    travel: float = 0.5,
    overshoot: float = 0.02,
    dwell: float = 0.3,
    velocity: float = 1.0,
    accel: float = 10.0,
    sensors: Sensors | None = None,
    seed: int = 0,
    progress: Callable[[float], Any] | None = None,
) -> PrecisionResult:
    """Run the ISO 230-2 linear cycle on the load axis and compute its statistics.

    Parameters
    ----------
    plant : Plant
        The true plant.
    controller : Controller
        The position controller.
    targets : int
        Number of target positions m (ISO: at least 5 per metre of travel, here per travel).
    cycles : int
        Number of cycles n (ISO: 5).
    travel : float
        Span of the targets [rad of load angle].
    overshoot : float
        Distance moved past the end targets before reversing [rad].
    dwell : float
        Rest before each measurement [s].
    velocity, accel : float
        Move profile (S-curve) [rad/s, rad/s^2].
    sensors : Sensors, optional
        Encoders (noise makes the repeatability non-zero).
    seed : int
        Seed of the sensor noise and of the target offsets.
    progress : callable, optional
        Called with the fraction of the closed-loop run done (given to
        :func:`~gearctl.closedloop.simulate_closed_loop`).

    Returns
    -------
    PrecisionResult

    Notes
    -----
    Targets are spread over the travel with seeded offsets of up to a tenth of their spacing, as ISO
    230-2 asks (so periodic errors are not sampled in phase). The measurement is the true load angle at
    the end of each dwell.

    Raises
    ------
    InputError
        If ``plant`` is not a Plant or ``controller`` not a controller; a count, the seed or a length of the test
        is out of range; the test program would last longer than the longest simulated duration or its run would
        not fit in memory (both naming ``travel``); or, from :func:`~gearctl.closedloop.simulate_closed_loop`,
        ``controller`` reads a load encoder ``sensors`` say is missing.
    """
    plant = check_plant(plant)
    check_controller(controller)
    for name, v, low in (("targets", targets, 2), ("cycles", cycles, 1)):
        is_int = isinstance(v, int | np.integer) and not isinstance(v, bool)
        if not (is_int and low <= v <= 50):
            rule = "is out of range" if is_int else "is not a whole number"
            raise InputError(f"{name} = {v!r} {rule}: expected a whole number in [{low}, 50]", field=name)
    SEED.check("seed", seed)
    for name, length in (("travel", travel), ("dwell", dwell), ("velocity", velocity), ("accel", accel),
                    ("overshoot", overshoot)):
        if not (length > 0 and math.isfinite(length)):
            raise InputError(f"{name} = {length!r} is out of range: expected a number > 0", field=name)
    if (travel + 2 * overshoot) / velocity > DURATION.upper:  # before the program's sums overflow (travel = 1e308)
        raise InputError(f"travel = {travel:g} rad at velocity = {velocity:g} rad/s: the test program would last more "
                         f"than {DURATION.high:g} s; lower travel", field="travel")
    rng = np.random.default_rng(seed)
    spacing = travel / (targets - 1)
    P = np.arange(targets, dtype=np.float64) * spacing
    P[1:-1] += rng.uniform(-0.1, 0.1, targets - 2) * spacing
    seq: list[tuple[float, int, int]] = []  # (position, target index or -1, direction +1 / -1)
    for _ in range(cycles):
        seq.append((P[0] - overshoot, -1, 0))
        seq += [(P[i], i, +1) for i in range(targets)]
        seq.append((P[-1] + overshoot, -1, 0))
        seq += [(P[i], i, -1) for i in reversed(range(targets))]
    starts, origins, ends = [], [], []
    t, pos = 0.2, 0.0
    measure: list[tuple[float, int, int]] = []
    prog = MotionProgram((), (), (), velocity, accel)
    for target, idx, direction in seq:
        starts.append(t)
        origins.append(pos)
        ends.append(target)
        t += prog.duration(target - pos) + dwell
        if idx >= 0:
            measure.append((t - 0.5 * controller.Ts, idx, direction))
        pos = target
    program = MotionProgram(tuple(starts), tuple(origins), tuple(ends), velocity, accel)
    if t > DURATION.upper:
        raise InputError(f"the test program lasts {t:.6g} s ({targets} targets, {cycles} cycles over travel = "
                         f"{travel:g} rad at velocity = {velocity:g} rad/s, dwell = {dwell:g} s): expected at most "
                         f"{DURATION.high:g} s; lower travel, dwell, cycles or targets", field="travel")
    check_loop_memory(plant, t + controller.Ts, controller.Ts, field="travel",
                      fix=f"the test program lasts {t:.6g} s; lower travel, dwell, cycles or targets")
    run = simulate_closed_loop(plant, controller, program, t + controller.Ts, sensors=sensors, seed=seed,
                               progress=progress)
    up = np.zeros((targets, cycles))
    down = np.zeros((targets, cycles))
    count_up = np.zeros(targets, dtype=int)
    count_down = np.zeros(targets, dtype=int)
    for tm, idx, direction in measure:
        k = int(np.searchsorted(run.t, tm))
        x = run.load_angle[min(k, run.t.size - 1)] - P[idx]
        if direction > 0:
            up[idx, count_up[idx]] = x
            count_up[idx] += 1
        else:
            down[idx, count_down[idx]] = x
            count_down[idx] += 1
    return PrecisionResult(targets=P, deviations_up=up, deviations_down=down, stats=iso230_statistics(up, down),
                           run=run)
