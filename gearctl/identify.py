"""Backlash and friction identification from encoder logs: the estimate.

The log (``t``, ``torque``, ``theta1``, optionally ``theta2``; read by :func:`read_log`, written by
:func:`write_log`, both re-exported here) is defined in :mod:`gearctl.logs`.

:func:`identify` estimates from a log of ordinary closed-loop operation (moves, sines, reversals) and a
model of the gear pair (geometry, mesh stiffness, nominal inertias and friction): the backlash ``b`` with a
95 % interval, the viscous and Coulomb friction of each shaft and the shaft inertias, and it re-simulates
the motion around the gap crossings (:class:`Identification`). With both encoders ``b`` is read off the
plateaus of ``r_b1 theta1 - r_b2 theta2`` (gap-crossing geometry); with the motor encoder alone the exact
piecewise-linear plant is re-simulated around each crossing and fitted by least squares (output error).
The Notes of :func:`identify` give the method and the literature. :func:`identified_model` and
:func:`write_identified_model` turn the result into a model file for ``track``, ``precision`` and ``bench``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .errors import InputError
from .files import toml_dumps
from .logs import (
    JITTER_TOLERANCE,
    MAX_LOG_BYTES,
    MAX_LOG_SAMPLES,
    MIN_LOG_SAMPLES,
    PERIOD_TOLERANCE,
    EncoderLog,
    _grid_deviation,
    _missing_sample,
    read_log,
    sample_period,
    write_log,
)
from .units import SAMPLE_TIME

__all__ = ["EncoderLog", "read_log", "write_log", "Identification", "ReversalWindow", "identify", "identified_model",
           "write_identified_model", "ENCODERS", "MAX_LOG_BYTES", "MAX_LOG_SAMPLES", "MIN_LOG_SAMPLES",
           "PERIOD_TOLERANCE", "JITTER_TOLERANCE", "MIN_SWITCHES", "MAX_WINDOWS", "sample_period"]

# --- identification ------------------------------------------------------------------------------------------

#: What ``encoders`` may say: both encoders, or the motor encoder alone.
ENCODERS = ("motor+load", "motor")
#: Fewest changes of the flank in contact (gap crossings) a log must show.
MIN_SWITCHES = 2
#: Most gap crossings fitted by re-simulation (spread evenly over a longer log).
MAX_WINDOWS = 16
#: Gap crossings whose re-simulation the result keeps for the plot.
MAX_PLOT_WINDOWS = 12
#: Gap crossings fitted to split the Coulomb friction between the shafts from the motor encoder alone.
SPLIT_WINDOWS = 4
#: Time the flanks take to settle after an impact (bounces) before a plateau of ``s`` counts [s].
SETTLE_TIME = 0.015
#: A re-simulated window starts this long before a gap crossing and ends this long after it [s].
WINDOW_BEFORE, WINDOW_AFTER = 0.03, 0.06
#: Relative 95 % uncertainty of the model's motor-shaft inertia (motor rotor from its data sheet, pinion from
#: the drawing), used when only the motor encoder is read: the log gives the lumped inertia, not which part
#: of it turns with the motor (the motor's free flights in the gap are short and cut by impacts).
MOTOR_INERTIA_TOLERANCE = 0.1
#: The re-simulated crossings may miss the log by this share of b (RMS along the line of action) before the
#: motor-only b, or with both encoders the friction and inertias, count as not identified.
MISFIT_SHARE = 0.25
#: With both encoders the motor's re-simulated free flight in the gap may miss the motor encoder by this share of b
#: (the largest miss inside the gap, median over the crossings) before the inertias and the motor's friction count
#: as not identified: an RMS over whole windows, mostly contact, hides a crossing that stalls mid-gap (h3's 800 Hz log
#: A8: 0.55 b in the gap, 0.15 b RMS). On the test logs and h3's corpus the RMS gate leaves it at most 0.29 b
#: where the motor's friction is right (0.49 b on one where J1, J2 and tc1 were already not identified).
GAP_MISS_SHARE = 0.4
#: A motor-only b whose 95 % half-width is above this share of it is not identified.
MAX_RELATIVE_HALF_WIDTH = 1 / 3
#: A motor-only b is not identified where more than DISAGREE_SHARE of the crossings' estimates lie more than
#: DISAGREE_BAND from their median: the crossings measure different things (a load that floated off its flank
#: before some of them), which their mean and its Student t interval would take for one sample.
DISAGREE_BAND, DISAGREE_SHARE = 0.2, 0.25
#: Relative floor of the 95 % half-width of each friction and inertia (what the idealised laws cannot represent;
#: on an independent simulator's logs, tanh or Karnopp friction and RK4: inertias off by up to 0.7 %, Coulomb
#: friction by up to 5 %, viscous friction by up to 28 %).
SYSTEMATIC_FLOOR = {"J1": 0.02, "J2": 0.02, "d1": 0.3, "d2": 0.3, "tc1": 0.05, "tc2": 0.05}
#: A parameter whose variance after the fit is above this share of its prior's is not identified by the log.
PRIOR_SHARE = 0.25
#: The plateaus' b must be at least this share of the half-span of ``s`` (else the flanks never rest in contact).
SPAN_SHARE = 0.8
#: Runs of plateaus (in time order) whose means bound the backlash interval from below (batch means).
BATCHES = 5
#: Width of the load-angle bins in which the flanks are compared at the same angle [rad]: an encoder's error that
#: depends on the angle (a once-per-turn eccentricity) moves ``s`` by under 1 % of its amplitude within one.
POSITION_BIN = 0.02
#: Fewest load-angle bins with contact on both flanks for the position-matched estimate of b.
POSITION_SHARED = 5
#: Load-angle bins averaged (running mean) before the range a flank moves over along the travel is taken.
POSITION_RUN = 5
#: A load-angle bin counts only where the top tenth of its samples lies within this many flank widths above its flank.
POSITION_PULL = 4.0
#: Order of the friction and inertia parameters.
PARAMS = ("J1", "J2", "d1", "d2", "tc1", "tc2")


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class ReversalWindow:
    """Measured and re-simulated motion around one gap crossing (for the plot and the residual).

    Attributes
    ----------
    t_switch : float
        When the flank in contact changed [s] (the middle of the crossing).
    flanks : tuple of int
        Flank before and after (+1 front, -1 back).
    t : ndarray
        Sample times of the window [s].
    theta1, theta1_sim : ndarray
        Motor angle measured and re-simulated [rad].
    theta2, theta2_sim : ndarray or None
        Load angle measured (in the simulation's zero, see :attr:`Identification.offset`) and re-simulated
        [rad]; ``theta2`` is None without a load encoder.
    backlash : float
        The backlash this window was simulated with [m] (its own estimate with the motor encoder alone).
    rms : float
        RMS of measured minus re-simulated angles in this window, in load-angle units [rad].
    """

    t_switch: float
    flanks: tuple[int, int]
    t: NDArray[np.float64]
    theta1: NDArray[np.float64]
    theta1_sim: NDArray[np.float64]
    theta2: NDArray[np.float64] | None
    theta2_sim: NDArray[np.float64]
    backlash: float
    rms: float


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class Identification:
    """What :func:`identify` found in a log.

    Attributes
    ----------
    backlash : float
        Backlash ``b`` along the line of action [m] (half the gap).
    backlash_ci : tuple of float
        95 % confidence interval of ``b`` [m].
    lost_motion, lost_motion_ci : float, tuple
        The same as lost motion at the load, ``2 b / r_b2`` [rad].
    friction : dict
        ``viscous1``, ``viscous2`` [N m s/rad], ``coulomb1``, ``coulomb2`` [N m] (1 motor shaft, 2 load shaft).
    friction_ci : dict
        95 % intervals of the same.
    inertia, inertia_ci : dict
        ``J1``, ``J2``: total inertia of the motor and the load shaft [kg m^2], estimate and 95 % interval.
    nominal : dict
        The model's values of the same quantities (``backlash``, ``J1``, ``J2``, ``viscous1`` ...).
    encoders : str
        ``"motor+load"`` or ``"motor"``.
    rms_residual : float
        RMS of measured minus re-simulated angles around the gap crossings, in load-angle units (motor angle
        divided by the gear ratio) [rad].
    residual_motor, residual_load : float
        The same per encoder, in its own shaft's angle [rad] (``residual_load`` NaN without a load encoder).
    estimates : ndarray
        Backlash estimate of each crossing (motor encoder alone) or of each pair of plateaus [m].
    estimate_times : ndarray
        Times of those estimates [s].
    switches : int
        Gap crossings found in the log.
    offset : float
        Zero of the measured relative displacement ``r_b1 theta1 - r_b2 theta2`` [m] (the middle of the gap;
        0 without a load encoder).
    sample_time : float
        The log's period [s].
    samples : int
        Samples in the log.
    method : str
        How ``b`` and the friction were estimated, in words.
    model : str
        The model's name.
    log : str
        The log file.
    windows : tuple of ReversalWindow
        Re-simulated motion around up to :data:`MAX_PLOT_WINDOWS` crossings.
    gear_ratio : float
        ``r_b2 / r_b1``.
    base_radius : tuple of float
        ``r_b1, r_b2`` [m].
    warnings : tuple of str
        What the figures should be read with (a re-simulation that does not fit the log, what is not identified).
    not_identified : dict
        Quantities (``backlash``, ``J1``, ``J2``, ``viscous1`` ...) the log does not identify, with the reason.
        Their value is the fit's or the model's, and their interval is wide on purpose: the model's 95 % range, every
        split between the shafts, or for ``backlash`` anything a model allows (0 to 0.5 module).
    inertia_sum : float
        ``J1 + J2 / N^2`` as the fit found it [kg m^2, at the motor], before an inertia at the fit's bound is
        reported at the model's value: what the log sees of the inertias (NaN: not given).
    """

    backlash: float
    backlash_ci: tuple[float, float]
    lost_motion: float
    lost_motion_ci: tuple[float, float]
    friction: dict[str, float]
    friction_ci: dict[str, tuple[float, float]]
    inertia: dict[str, float]
    inertia_ci: dict[str, tuple[float, float]]
    nominal: dict[str, float]
    encoders: str
    rms_residual: float
    residual_motor: float
    residual_load: float
    estimates: NDArray[np.float64]
    estimate_times: NDArray[np.float64]
    switches: int
    offset: float
    sample_time: float
    samples: int
    method: str
    model: str
    log: str
    windows: tuple[ReversalWindow, ...]
    gear_ratio: float
    base_radius: tuple[float, float]
    warnings: tuple[str, ...] = ()
    not_identified: dict[str, str] = dataclasses.field(default_factory=dict)
    #: ``J1 + J2 / N^2`` as the fit found it [kg m^2, at the motor], before an inertia at the fit's bound is reported
    #: at the model's value: what the log sees of the inertias (NaN: not given, the two inertias' sum is taken)
    inertia_sum: float = math.nan

    def as_dict(self) -> dict[str, Any]:
        """The figures as plain data (JSON; the windows' arrays are left out)."""
        return {
            "log": self.log, "model": self.model, "encoders": self.encoders,
            "backlash": self.backlash, "backlash_ci": list(self.backlash_ci),
            "lost_motion": self.lost_motion, "lost_motion_ci": list(self.lost_motion_ci),
            "friction": dict(self.friction), "friction_ci": {k: list(v) for k, v in self.friction_ci.items()},
            "inertia": dict(self.inertia), "inertia_ci": {k: list(v) for k, v in self.inertia_ci.items()},
            "inertia_sum": self.inertia_sum,
            "nominal": dict(self.nominal), "rms_residual": self.rms_residual,
            "residual_motor": self.residual_motor, "residual_load": self.residual_load,
            "switches": self.switches, "estimates": self.estimates.tolist(),
            "estimate_times": self.estimate_times.tolist(), "offset": self.offset,
            "sample_time": self.sample_time, "samples": self.samples, "method": self.method,
            "gear_ratio": self.gear_ratio, "base_radius": list(self.base_radius), "warnings": list(self.warnings),
            "not_identified": dict(self.not_identified),
        }


# --- signals ----------------------------------------------------------------------------------------------


def _odd(x: float, lo: int, hi: int) -> int:
    """An odd whole number near ``x`` within ``[lo, hi]`` (filter lengths)."""
    n = int(min(max(round(x), lo), hi))
    return n if n % 2 else n - 1 if n > lo else n + 1


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """``[i0, i1)`` of each run of True in ``mask``."""
    d = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def _hann(W: int) -> NDArray[np.float64]:
    """A Hann window of ``W`` samples, normalised to unit sum (the smoother of every signal)."""
    h = np.hanning(W + 2)[1:-1]
    return h / h.sum()


def _smooth(x: NDArray[np.float64], h: NDArray[np.float64]) -> NDArray[np.float64]:
    from scipy.ndimage import convolve1d

    return convolve1d(x, h, mode="nearest")


#: Samples per block of the noise estimate (:func:`_noise_level`).
NOISE_BLOCK = 64


def _noise_level(theta: NDArray[np.float64], *, quietest: bool = False) -> float:
    """White-noise level [rad] of a reading, from its third differences, robust to the motion.

    The third difference of white noise of level ``sigma`` has the spread ``sqrt(20) sigma``; smooth motion
    adds ``jerk Ts^3``, which at a slow sampling (500 Hz) or in a loop that slams across the gap outweighs the
    noise wherever the shaft moves. The noise is stationary and the motion is not: the robust spread (MAD) is
    taken over the whole log (MAD) and in blocks of :data:`NOISE_BLOCK` samples (RMS: a block's median of
    quantised readings is itself quantised), and the level is the lower of the whole log's and the quietest
    blocks': the 5th percentile of the blocks' RMS divided by 0.79, where it lies for stationary noise
    (measured on white noise with and without 2^20-count quantisation: 0.78-0.80, 1.04 for quantisation alone).
    A loop that hunts all the time at 500 Hz still rests in a few blocks (its start); a log with fewer than 20
    blocks keeps the whole log's level. ``quietest``: the quietest block's RMS (a lower bound, for a test
    whether a signal stands out of the noise at all).
    """
    d3 = np.diff(theta, 3)
    if d3.size == 0:
        return 0.0
    whole = 1.4826 * float(np.median(np.abs(d3 - np.median(d3))))
    nb = d3.size // NOISE_BLOCK
    if nb >= 20:
        rms = np.sqrt(np.mean(d3[:nb * NOISE_BLOCK].reshape(nb, NOISE_BLOCK) ** 2, axis=1))
        whole = min(whole, float(rms.min()) if quietest else float(np.percentile(rms, 5)) / 0.79)
    return whole / math.sqrt(20.0)


class _Encoder:
    """One encoder's reading, smoothed, with its velocity and acceleration.

    Derivatives are difference quotients smoothed by a Hann window ``S``: ``a = S[(theta_k+1 - 2 theta_k +
    theta_k-1) / Ts^2]``, ``w = S[(theta_k+1 - theta_k-1) / (2 Ts)]``. The torque is smoothed by the same
    ``S`` (``S[(u_k-1 + u_k) / 2]``), so that a torque balance holds for the smoothed signals exactly as for
    the samples: for an inertia under a held torque the second difference is exactly ``Ts^2 (u_k-1 + u_k)
    / (2 J)``, and for two shafts the mesh force cancels in the total balance even across an impact.
    Two windows: ``W`` samples (about 21 ms) for whole motions, ``Wg`` for the short free flights inside the
    gap (1: the raw quotients, whose three samples must all lie inside the gap; a loop that slams across the
    gap bounces, and its free flights last a few samples). ``sigma`` is the reading's noise (the robust
    scatter of third differences, which smooth motion leaves alone, or the quantisation's ``q / sqrt(12)`` if
    larger); a shaft counts as moving where its velocity stays beyond five times the velocity noise.
    """

    def __init__(self, theta: NDArray[np.float64], Ts: float, W: int, Wg: int) -> None:
        self.raw = theta
        d1 = np.gradient(theta, Ts)
        d2 = np.zeros_like(theta)
        d2[1:-1] = (theta[2:] - 2 * theta[1:-1] + theta[:-2]) / Ts**2
        h, hg = _hann(W), _hann(Wg)
        self.p = _smooth(theta, h)
        self.w, self.a = _smooth(d1, h), _smooth(d2, h)
        self.wg, self.ag = _smooth(d1, hg), _smooth(d2, hg)
        steps = np.abs(np.diff(theta))
        steps = steps[steps > 0]
        self.q = float(steps.min()) if steps.size else 0.0
        # white noise from the third difference (which smooth motion leaves at jerk Ts^3); robust to impacts
        self.sigma = max(_noise_level(theta), self.q / math.sqrt(12.0), 1e-12)
        hv = float(np.linalg.norm(np.convolve(h, [0.5, 0.0, -0.5]))) / Ts
        hvg = float(np.linalg.norm(np.convolve(hg, [0.5, 0.0, -0.5]))) / Ts
        ha = float(np.linalg.norm(np.convolve(h, [1.0, -2.0, 1.0]))) / Ts**2
        hag = float(np.linalg.norm(np.convolve(hg, [1.0, -2.0, 1.0]))) / Ts**2
        #: variances of the reading's noise in (a, w) and (ag, wg): what it adds to a regression's normal matrix
        self.noise = (self.sigma**2 * ha**2, self.sigma**2 * hv**2)
        self.noise_g = (self.sigma**2 * hag**2, self.sigma**2 * hvg**2)
        self.v_thr = 5.0 * self.sigma * hv
        self.vg_thr = 5.0 * self.sigma * hvg

    @staticmethod
    def moving(w: NDArray[np.float64], thr: float, W: int) -> NDArray[np.bool_]:
        """Samples whose velocity keeps one sign beyond ``thr`` over ``W`` samples around them."""
        from scipy.ndimage import maximum_filter1d, minimum_filter1d

        return (minimum_filter1d(w, W, mode="nearest") > thr) | (maximum_filter1d(w, W, mode="nearest") < -thr)


# --- the friction and inertia regression ---------------------------------------------------------------


Block = tuple[NDArray[np.float64], NDArray[np.float64], float, NDArray[np.float64] | None, NDArray[np.int64]]


def _noise_cov(columns: tuple[tuple[NDArray[np.float64], float], ...]) -> NDArray[np.float64]:
    """Covariance of a row's regressor noise: ``sum_j var_j v_j v_j^T`` for noise of variance ``var_j`` entering
    the regressors along ``v_j`` (e.g. an acceleration's noise in the ``J1`` and ``J2 / N^2`` columns)."""
    return sum((var * np.outer(v, v) for v, var in columns), np.zeros((len(columns[0][0]),) * 2))


def _contact_noise(m: _Encoder, N: float) -> NDArray[np.float64]:
    """Regressor noise of a contact row ``[a, a / N^2, w, w / N^2, sign w, sign w / N]`` (the motor's signals)."""
    return _noise_cov(((np.array([1.0, 1.0 / N**2, 0.0, 0.0, 0.0, 0.0]), m.noise[0]),
                       (np.array([0.0, 0.0, 1.0, 1.0 / N**2, 0.0, 0.0]), m.noise[1])))


def _regress(blocks: list[Block], mean: NDArray[np.float64], sd: NDArray[np.float64],
             lower: NDArray[np.float64], floors: Sequence[float] | None = None
             ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Bounded least squares of torque balances with a prior, corrected for noisy regressors:
    ``(theta, covariance)``.

    Each block ``(A, y, correlation, noise)`` holds rows ``A theta = y`` of one kind (their noise is estimated
    from their own residuals, robustly, and rows beyond five times it are dropped); ``correlation`` is
    the number of samples a filtered residual stays correlated over, by which the information of a row
    is divided so that the covariance is honest. The prior ``N(mean, sd^2)`` keeps the directions the
    data do not see (e.g. how the viscous friction splits between the shafts when they always move
    together) at the model's values.

    ``noise`` (or None) is the covariance of one row's regressor noise: the accelerations and speeds are
    differences of noisy encoder readings, and that noise adds ``n noise`` to ``A^T A`` on ``n`` rows, which
    pulls the inertias towards zero (regression dilution: 34 % low on the motor's free flights of a 2 kHz
    log, whose raw second differences are 4x noisier than at 1 kHz). It is subtracted from the normal
    matrix (the errors-in-variables correction of Fuller, *Measurement Error Models*, 1987, ch. 2), halved
    until the matrix stays positive definite. ``floors`` (one per block, or None) holds each block's noise at
    least at that level (the load's free flights under a load torque, :func:`identify`).

    The covariance is the larger, parameter by parameter, of the model's (rows independent beyond
    ``correlation`` samples) and a cluster-robust sandwich (Liang & Zeger 1986; White 1980): the last
    element of a block holds each row's sample index, a run of consecutive samples (one steady motion in
    contact, one free flight in the gap) is one cluster, and the scores of a cluster are summed before their
    spread is taken, with the small-sample factor ``G / (G - 1)`` for ``G`` clusters. A residual that drifts
    over a plateau or along a closed-loop log (a friction law unlike the model's, a loop that hunts) widens
    the interval; white residuals leave it as it was. The correlations are the sandwich's.
    """
    from scipy.optimize import lsq_linear

    fl = [0.0] * len(blocks) if floors is None else list(floors)
    fl = [f for blk, f in zip(blocks, fl, strict=True) if len(blk[1]) >= 10]
    blocks = [blk for blk in blocks if len(blk[1]) >= 10]
    theta = mean.copy()
    keeps = [np.ones(len(blk[1]), bool) for blk in blocks]
    sig = []
    for A, y, _, _, _ in blocks:
        r = y - A @ mean
        sig.append(max(1.4826 * float(np.median(np.abs(r - np.median(r)))), 1e-12))
    # a block's noise never falls below a thousandth of its first estimate: a block of a dozen rows kept only the
    # few the fit passed through exactly, its noise fell to the 1e-12 floor and its rows outweighed the prior by
    # 1e23 (a reviewer's log with the torque one sample late: the normal matrix lost its definiteness to rounding)
    sig_floor = [max(1e-3 * s0, f) for s0, f in zip(sig, fl, strict=True)]
    sig = [max(s0, f) for s0, f in zip(sig, fl, strict=True)]
    D = np.diag(sd)

    def normal(with_rhs: bool) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        G = np.eye(len(mean))
        h = mean / sd
        E = np.zeros_like(G)
        for (A, y, corr, noise, _), s, keep in zip(blocks, sig, keeps, strict=True):
            wgt2 = 1.0 / (s * s * corr)
            As = A[keep] @ D
            G = G + wgt2 * (As.T @ As)
            if with_rhs:
                h = h + wgt2 * (As.T @ y[keep])
            if noise is not None:
                E = E + wgt2 * int(keep.sum()) * (D @ noise @ D)
        return G, h, E

    def corrected(G: NDArray[np.float64], E: NDArray[np.float64]) -> NDArray[np.float64]:
        """A square root ``L`` of ``G - f E`` (``L L^T``), with the largest ``f`` of 1, 1/2, ... 0 that is positive
        definite."""
        for f in (1.0, 0.5, 0.25, 0.125, 0.0):
            try:
                return np.asarray(np.linalg.cholesky(G - f * E), dtype=np.float64)
            except np.linalg.LinAlgError:
                continue
        # G = I + sum w A^T A has every eigenvalue >= 1, but rounding can lose that where a block's rows weigh 1e20
        # times the prior (a torque column one sample late: a reviewer's log raised LinAlgError here): its
        # eigenvalues, held at 1 from below
        w, V = np.linalg.eigh(0.5 * (G + G.T))
        return V * np.sqrt(np.maximum(w, 1.0))

    for _ in range(4):
        G, h, E = normal(True)
        L = corrected(G, E)
        # min x^T G x - 2 h^T x = |L^T x - L^-1 h|^2 + const, over x = theta / sd >= lower / sd
        sol = lsq_linear(L.T, np.linalg.solve(L, h), bounds=(lower / sd, np.full(len(mean), np.inf)))
        theta = sol.x * sd
        for j, (A, y, _, _, _) in enumerate(blocks):
            r = y - A @ theta
            s = max(1.4826 * float(np.median(np.abs(r[keeps[j]]))), sig_floor[j], 1e-12)
            sig[j] = s
            keeps[j] = np.abs(r) < 5 * s
    G, _, E = normal(False)
    L = corrected(G, E)
    D_inv = np.diag(1.0 / sd)
    info = D_inv @ (L @ L.T) @ D_inv
    cov = np.linalg.inv(info)
    # the cluster-robust sandwich, in the scaled coordinates x = theta / sd
    x = theta / sd
    meat = np.zeros_like(G)
    n_cl = 0
    for (A, y, corr, _, idx), s, keep in zip(blocks, sig, keeps, strict=True):
        if not keep.any():
            continue
        As = A[keep] @ D
        r = y[keep] - As @ x
        score = As * (r / (s * s * corr))[:, None]
        ik = idx[keep]
        label = np.concatenate(([0], np.cumsum(np.diff(ik) > 1)))
        sums = np.zeros((int(label[-1]) + 1, len(mean)))
        np.add.at(sums, label, score)
        meat += sums.T @ sums
        n_cl += sums.shape[0]
    if n_cl > 1:
        Binv = np.linalg.inv(L @ L.T)
        robust = D @ (Binv @ (meat * n_cl / (n_cl - 1)) @ Binv) @ D
        # the data's share of the model covariance: the prior's part (which the sandwich leaves out) is added back
        prior_part = D @ (Binv @ Binv) @ D
        robust = robust + prior_part
        sd_m, sd_r = np.sqrt(np.diag(cov)), np.sqrt(np.maximum(np.diag(robust), 0.0))
        sd_f = np.maximum(sd_m, sd_r)
        # the sandwich's correlations with the larger standard deviations
        scale = np.divide(sd_f, sd_r, out=np.zeros_like(sd_f), where=sd_r > 0)
        cov = robust * np.outer(scale, scale)
        cov[np.diag_indices_from(cov)] = sd_f**2
        w, V = np.linalg.eigh(0.5 * (cov + cov.T))  # positive semi-definite whatever the rounding
        cov = (V * np.maximum(w, 0.0)) @ V.T
    return theta, np.asarray(cov, dtype=np.float64)  # (numpy's stubs: inv, @ of floating)


#: The prior's spread is widened by this factor to see how far the prior pulls the estimate (:func:`_with_prior_pull`)
PRIOR_PULL_WIDENING = 10.0


def _with_prior_pull(blocks: list[Block], mean: NDArray[np.float64], sd: NDArray[np.float64],
                     lower: NDArray[np.float64], theta: NDArray[np.float64],
                     cov: NDArray[np.float64], floors: Sequence[float] | None = None) -> NDArray[np.float64]:
    """``cov`` with the prior's pull on each parameter added to its variance, as a systematic error.

    The weak prior keeps the directions the data hardly see at the model's values, but it also pulls the ones
    they see weakly: on slow triangle motions (little acceleration) a load inertia 27-34 % below the model's
    came out between the truth and the model's value, beyond its interval (a reviewer's simulator, 3 logs). The
    same regression with the prior :data:`PRIOR_PULL_WIDENING` times wider moves each parameter by what the prior
    held it at; that shift, as a 95 % half-width, is added in quadrature.
    """
    weak, _ = _regress(blocks, mean, PRIOR_PULL_WIDENING * sd, lower, floors)
    pull = np.abs(weak - theta) / 1.96
    out = cov.copy()
    out[np.diag_indices_from(out)] += pull**2
    return out


def _prior(plant: Any, ubar: NDArray[np.float64], w1: NDArray[np.float64], N: float) -> tuple[NDArray, NDArray]:
    """The model's values of ``J1, J2, d1, d2, tc1, tc2`` and a weak prior spread about them.

    Inertias: 30 % (a data sheet's and a drawing's figures). Friction: 100 % of the model's value, or where
    the model has none, the log's own scale (its RMS torque; that over its RMS motor speed for viscous
    friction), carried to the load shaft by the gear ratio. So a friction the model lacks is found from
    the log, and what the log cannot split between the shafts is split as the model does.
    """
    mean = np.array([plant.J1, plant.J2, plant.d1, plant.d2, plant.tc1, plant.tc2])
    u_rms = max(float(np.sqrt(np.mean(ubar**2))), 1e-9)
    w_rms = max(float(np.sqrt(np.mean(w1**2))), 1e-9)
    scale = np.array([0.0, 0.0, u_rms / w_rms, N * N * u_rms / w_rms, u_rms, N * u_rms])
    sd = np.where(mean > 0, mean, scale)
    sd[:2] = 0.3 * mean[:2]
    return mean, sd


# --- re-simulating a gap crossing ---------------------------------------------------------------------------


def _with_values(nominal: Any, theta: NDArray[np.float64], b: float, floor: tuple[float, float] = (0.0, 0.0)) -> Any:
    """The nominal pair with identified inertias, friction (stick-slip) and backlash, no torque limit.

    A Coulomb friction below ``floor`` [N m, motor and load shaft] is left out: it changes nothing a log can
    show, and a vanishing stick-slip friction makes the solver locate a stick and a slip at every turn.
    """
    from .params import FrictionLaw
    from .plant import Plant, PlantKind, Shaft

    tc1 = theta[4] if theta[4] > floor[0] else 0.0
    tc2 = theta[5] if theta[5] > floor[1] else 0.0
    st = dataclasses.replace(nominal.stages[0], backlash=b, kv_table=None)
    return Plant(kind=PlantKind.IMPROVED, shafts=(Shaft(J=theta[0], d=theta[2], tc=tc1),
                                                  Shaft(J=theta[1], d=theta[3], tc=tc2)),
                 stages=(st,), contact_law=nominal.contact_law, friction_law=FrictionLaw.STICK_SLIP,
                 coulomb_velocity=nominal.coulomb_velocity, torque_limit=math.inf, load_torque=nominal.load_torque)


def _simulate(plant: Any, x0: NDArray[np.float64], torque: NDArray[np.float64], Ts: float,
              kernel: Any = None) -> NDArray[np.float64]:
    """Angles ``(2, m + 1)`` of the plant from ``x0`` under the held torques (NaN after a failure).

    ``kernel``: a :class:`~gearctl.kernel.Kernel` of this plant to reuse (its state is replaced).
    """
    from .kernel import Kernel

    out = np.full((2, torque.size + 1), np.nan)
    out[:, 0] = x0[:2]
    if kernel is None:
        kn = Kernel(plant, x0, dt=Ts)
    else:
        kn = kernel
        kn.set_state(x0)
    tl = plant.load_torque
    for j, u in enumerate(torque.tolist()):
        if kn.advance(u, tl, Ts) != 0:
            break
        x = kn.x
        if not (math.isfinite(x[0]) and math.isfinite(x[1])):
            break
        out[0, j + 1], out[1, j + 1] = x[0], x[1]
    return out


@dataclasses.dataclass
class _Window:
    """A gap crossing: samples ``[k0, k1]``, flank before and after, transmitted force at ``k0``."""

    k0: int
    k1: int
    before: int
    after: int
    force0: float
    t_switch: float


def _start_state(plant: Any, th1: float, w1: float, flank: int, force: float) -> NDArray[np.float64]:
    """A state in contact on ``flank`` carrying ``force`` [N] with the motor at ``th1``, ``w1``."""
    s0 = flank * plant.backlash + force / plant.k
    return np.array([th1, (plant.rb1 * th1 - s0) / plant.rb2, w1, w1 / plant.gear_ratio])


# --- the estimate ---------------------------------------------------------------------------------------


def _t95(dof: int) -> float:
    from scipy import stats

    return float(stats.t.ppf(0.975, max(dof, 1)))


def _spread_evenly(items: list[Any], n: int) -> list[Any]:
    """At most ``n`` of ``items``, evenly spread (all of them if there are fewer)."""
    if len(items) <= n:
        return list(items)
    idx = np.unique(np.round(np.linspace(0, len(items) - 1, n)).astype(int))
    return [items[i] for i in idx]


class _Problem:
    """Everything the estimate works on: the log's signals, the model's pair, the filters."""

    def __init__(self, log: EncoderLog, nominal: Any, encoders: str, module: float) -> None:
        self.log, self.nominal, self.encoders, self.module = log, nominal, encoders, module
        self.Ts = Ts = log.sample_time
        self.n = log.n
        self.N = nominal.gear_ratio
        self.W = _odd(0.021 / Ts, 7, min(2001, max(7, self.n // 8)))
        self.Wg = 1  # the free flights between bounces last a few samples: raw difference quotients
        u = log.torque
        # the torque over [t_k-1, t_k+1] seen by a central second difference at t_k (zero-order hold)
        self.ubar = np.concatenate(([u[0]], 0.5 * (u[1:] + u[:-1])))
        #: Coulomb friction too small to matter in a re-simulation [N m, motor and load shaft]: 0.1 % of the RMS torque
        u_rms = float(np.sqrt(np.mean(self.ubar**2)))
        self.tc_floor = (1e-3 * u_rms, 1e-3 * u_rms * self.N)
        self.uf = _smooth(self.ubar, _hann(self.W))
        #: the model's constant load torque [N m] (gearctl adds it to the load shaft's balance, as the re-simulation
        #: does): the load's own balance in free flight is J2 theta2'' + d2 theta2' + T_c2 sgn = T_L, and the total
        #: balance in contact takes it at the motor as T_L / N, so ``uc = uf + T_L / N`` is the contact rows' torque
        self.tl = float(nominal.load_torque)
        self.uc = self.uf + self.tl / self.N
        self.ug = _smooth(self.ubar, _hann(self.Wg))
        self.m = _Encoder(log.theta1, Ts, self.W, self.Wg)
        #: viscous friction too small to be seen [N m s/rad, motor and load shaft]: its torque at the RMS motor speed
        #: 0.1 % of the RMS torque (as for the Coulomb friction; a frictionless pair's excite log gave d1 9.5e-12
        #: [3.9e-12, 1.5e-11] N m s/rad, the truth 0 outside a purely relative floor)
        d_floor = 1e-3 * u_rms / max(float(np.sqrt(np.mean(self.m.w**2))), 1e-9)
        self.d_floor = (d_floor, d_floor * self.N**2)
        theta2 = log.theta2 if encoders == "motor+load" else None  # (identify refuses motor+load without the column)
        self.l = _Encoder(theta2, Ts, self.W, self.Wg) if theta2 is not None else None
        self.before = max(1, int(round(WINDOW_BEFORE / Ts)))
        self.after = max(2, int(round(WINDOW_AFTER / Ts)))
        self.settle = max(1, int(round(SETTLE_TIME / Ts)))

    def transmitted(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """Torque the mesh takes from the motor, ``r_b1 F = u - J1 theta1'' - d1 theta1' - T_c1 sign`` [N m]."""
        m = self.m
        mv = _Encoder.moving(m.w, m.v_thr, self.W)
        return self.uf - theta[0] * m.a - theta[2] * m.w - theta[4] * np.where(mv, np.sign(m.w), 0.0)


def _gap_column(p: _Problem) -> str:
    """The log column the gap's crossings are read from (the load encoder's, or the motor's alone)."""
    return "theta2" if p.encoders == "motor+load" else "theta1"


def _no_switch(p: _Problem, found: int, what: str) -> InputError:
    col = _gap_column(p)
    m = p.m
    w = m.w[_Encoder.moving(m.w, m.v_thr, p.W)]
    reversals = int(np.count_nonzero(np.sign(w[1:]) != np.sign(w[:-1])))
    if reversals < MIN_SWITCHES:
        advice = "record a motion that reverses (moves back and forth, a sine)"
    elif found >= 1 and reversals <= found + 1:  # nearly every reversal crossed: the log reverses too seldom (a
        # reviewer's slow log, told that the load never rested on a flank, rested 1.5 s on each and crossed once)
        advice = (f"the motor reversed {reversals} times, but only {found} of its reversals took the load from one "
                  f"flank to the other: record more reversals, each travelling well over the lost motion")
    elif abs(p.tl) > p.nominal.tc2:  # the load torque holds the load on one flank: the motor reverses, the load not
        size = " in size" if p.tl < 0 else ""
        way = "increasing" if p.tl > 0 else "decreasing"
        advice = (f"the motor reversed {reversals} times, but the model's load_torque ({p.tl:g} N m) exceeds the "
                  f"load's Coulomb friction ({p.nominal.tc2:g} N m){size}: it keeps the load on one flank wherever "
                  f"the motor does not push it across; record motions that accelerate the load side in the load "
                  f"torque's direction ({way} theta2; against it any acceleration leaves the load on that flank) "
                  f"faster than the load torque alone can, (|load_torque| - friction) / J2 = "
                  f"{(abs(p.tl) - p.nominal.tc2) / p.nominal.J2:.3g} rad/s^2, or check the model's load_torque")
    else:
        advice = (f"the motor reversed {reversals} times, but the load never rested on a flank long enough to be "
                  f"seen there (a loop that hunts or rattles, or a sample rate too low for the crossings): record "
                  f"slower reversals with a calmer loop, or at a higher rate")
    return InputError(f"{p.log.name}: column {col}: {found} gap crossing(s) found ({what}); identification needs at "
                      f"least {MIN_SWITCHES}: {advice}", field=col)


def _check_motion(p: _Problem) -> None:
    """The motor must move and turn back at least once."""
    w = p.m.w
    mv = _Encoder.moving(w, p.m.v_thr, p.W)
    signs = np.sign(w[mv])
    span = float(np.ptp(p.log.theta1))
    if p.n * p.Ts < MIN_LOG_DURATION and span > MOVES_NOISE * p.m.sigma:
        # the motion of a log this short never keeps one way for the window a motion is read over: a clock in
        # the wrong unit (it was refused as a motor that does not move, or turns one way only, naming theta1)
        raise InputError(f"{p.log.name}: column t: the log lasts {p.n * p.Ts:.3g} s ({p.n} samples at "
                         f"{p.Ts:.3g} s), too short for a motion from flank to flank (expected t in seconds and a "
                         f"log of at least {MIN_LOG_DURATION:g} s; the motor's reading changes by {span:.3g} rad) "
                         f"(t in ks, or scaled down 1000x?)", field="t")
    if signs.size == 0:
        if span > MOVES_NOISE * p.m.sigma:  # it moves, but never one way for a window: no motion to read
            raise InputError(f"{p.log.name}: column theta1: the motor's reading changes by {span:.3g} rad but it "
                             f"never turns one way for {p.W} samples ({p.W * p.Ts:.3g} s): it dithers or hunts, "
                             f"no motion from flank to flank to identify", field="theta1")
        raise InputError(f"{p.log.name}: column theta1: the motor does not move (its reading changes by "
                         f"{span:.3g} rad): no reversal in the log", field="theta1")
    if np.all(signs == signs[0]):
        raise InputError(f"{p.log.name}: column theta1: the motor turns one way only ({span:.3g} rad): no reversal in "
                         f"the log", field="theta1")


#: A motor reading that changes by more than this many times its noise moves (below it is said not to move).
MOVES_NOISE = 100.0
#: A log that moves and lasts less than this [s] is a clock in the wrong unit: a gap crossing lasts milliseconds,
#: a motion is read over 21 ms of steady travel, and 500 samples last at least 0.05 s up to 10 kHz.
MIN_LOG_DURATION = 0.02
#: Longest sample period identify accepts [s]: a gap crossing lasts milliseconds; a log at 20 Hz or slower cannot
#: show one (and a period of 1 s is a clock in ms).
MAX_IDENTIFY_PERIOD = 0.02
#: A torque beyond the model's torque_limit by more than this factor is not the motor's torque in N m.
TORQUE_MARGIN = 1.5
#: The lumped inertia the log's torque balance gives may be this factor from the model's, either way (a data
#: sheet's and a drawing's figures are not that far off; angles in degrees are 57x, a torque in mN m 1000x).
INERTIA_FACTOR = 3.0
#: The lowest lumped inertia allowed is the motor's own J1 (a motor moving alone in a wide gap) over INERTIA_FACTOR,
#: but at least this share of J1 + J2/N^2 over INERTIA_FACTOR (so angles in degrees, 1/57, stay refused).
INERTIA_FREE_SHARE = 0.1
#: The load encoder must move at the model's ratio within this factor while both shafts move.
RATIO_FACTOR = 1.25
#: ... checked over a travel of at least this many of the model's lost motions (a log dithering in the gap is not)
RATIO_TRAVEL = 20.0
#: The backlash a model file allows, in modules (gearctl.units.BACKLASH).
MAX_BACKLASH_MODULES = 0.5


def _unit_hint(ratio: float, hints: tuple[tuple[float, str], ...]) -> str:
    """`` (cause?)`` for the first of ``hints`` (factor, cause) within 1.5x of ``ratio``, or ''."""
    for f, what in hints:
        if ratio > 0 and abs(math.log(ratio / f)) < math.log(1.5):
            return f" ({what}?)"
    return ""


#: Likely causes of a lumped inertia this factor from the model's.
INERTIA_HINTS = ((math.pi / 180, "theta1 in degrees"), (2 * math.pi, "theta1 in revolutions"), (1e3, "torque in mN m"),
                 (1e6, "t in ms"), (1e-6, "t scaled down 1000x"),
                 (1e-3, "theta1 in mrad, or torque in kN m"),
                 (2 * math.pi / 2**20, "theta1 in counts of a 2^20 encoder"),
                 (2 * math.pi / 2**16, "theta1 in counts of a 2^16 encoder"))
#: An encoder column whose values are all whole numbers reaching this far [its unit] holds counts, not radians.
COUNTS_MIN = 100.0
#: Likely causes of a load encoder moving this factor from theta1 / N.
RATIO_HINTS = ((1 / (2 * math.pi), "theta2 in revolutions"), (180 / math.pi, "theta2 in degrees"),
               (1e3, "theta2 in mrad"), (1e-3, "theta1 in mrad"))


def _check_signals(p: _Problem, torque_limit: float) -> None:
    """Refuse a log whose columns cannot be what they say (units, swapped or dead columns), naming the column.

    - ``t``: a period longer than :data:`MAX_IDENTIFY_PERIOD`;
    - ``torque``: all zero; beyond the model's ``torque_limit`` by more than :data:`TORQUE_MARGIN`; not driving
      the motion (the torque balance ``u = J a + d w + T sgn w`` over the samples where the motor moves, fitted
      by least squares without a prior, gives a lumped inertia ``J <= 0``: a torque negated or unrelated);
    - ``t``, ``torque`` or ``theta1`` in other units: that lumped inertia more than :data:`INERTIA_FACTOR` above
      the model's, or below the motor's own ``J1`` (at least :data:`INERTIA_FREE_SHARE` of the model's) by more
      (the message guesses degrees, revolutions, counts, mN m or ms from the factor; a factor it does not know
      names ``theta1``);
    - ``theta2`` (with both encoders): the least-squares slope of ``N theta2`` on ``theta1`` outside ``1 /
      RATIO_FACTOR .. RATIO_FACTOR`` (swapped columns give ``N^2``, a dead encoder 0, revolutions ``1 / 2 pi``),
      where the motor travels at least :data:`RATIO_TRAVEL` lost motions (over less the gap itself moves the ratio).
    """
    lg, name = p.log, p.log.name
    if p.Ts > MAX_IDENTIFY_PERIOD:
        hint = " (t in ms?)" if p.Ts >= 0.1 else ""
        raise InputError(f"{name}: column t: sample period {p.Ts:g} s is too long for identification (expected at "
                         f"most {MAX_IDENTIFY_PERIOD:g} s: a gap crossing lasts milliseconds){hint}", field="t")
    u_max = float(np.max(np.abs(lg.torque)))
    if u_max == 0.0:
        raise InputError(f"{name}: column torque: all zero: expected the motor torque command [N m] that drives the "
                         f"motion", field="torque")
    if math.isfinite(torque_limit) and u_max > TORQUE_MARGIN * torque_limit:
        hint = " (torque in mN m?)" if u_max > 100 * torque_limit else ""
        raise InputError(f"{name}: column torque: |torque| reaches {u_max:.4g} N m, beyond the model's torque_limit "
                         f"{torque_limit:g} N m (allowed up to {TORQUE_MARGIN:g}x, "
                         f"{TORQUE_MARGIN * torque_limit:g} N m){hint}", field="torque")
    for col, v in (("theta1", lg.theta1), ("theta2", lg.theta2 if p.l is not None else None)):
        if v is not None and float(np.max(np.abs(v))) >= COUNTS_MIN and bool(np.all(v == np.round(v))):
            raise InputError(f"{name}: column {col}: every value is a whole number (up to "
                             f"{float(np.max(np.abs(v))):.6g}): encoder counts? expected radians (counts times "
                             f"2 pi / counts per revolution)", field=col)
    m = p.m
    mv = _Encoder.moving(m.w, m.v_thr, p.W)
    pl = p.nominal
    J_model = pl.J1 + pl.J2 / p.N**2
    lost = pl.lost_motion  # the model's [rad at the load]
    # the load's travel, as either encoder reads it (swapped columns must not hide the check)
    travel = max(float(np.ptp(lg.theta1)) / p.N, float(np.ptp(p.l.raw)) if p.l is not None else 0.0)
    if p.l is not None and travel >= RATIO_TRAVEL * lost:
        # over a travel of many lost motions the load follows the motor at 1 / N whatever the gap does: the
        # least-squares slope of N theta2 on theta1 (a median of N theta2' / theta1' over the samples where the motor
        # moves read 0 on a PRBS log whose motor dithers in the gap while friction holds the load)
        x = lg.theta1 - float(np.mean(lg.theta1))
        ratio = p.N * float(np.dot(x, p.l.raw - float(np.mean(p.l.raw)))) / float(np.dot(x, x))
        if not 1 / RATIO_FACTOR <= ratio <= RATIO_FACTOR:
            hint = (" (theta1 and theta2 swapped?)" if abs(math.log(max(ratio, 1e-300) / p.N**2)) < math.log(1.5) else
                    _unit_hint(ratio, RATIO_HINTS) or (" (a dead load encoder?)" if abs(ratio) < 0.05 else ""))
            raise InputError(f"{name}: column theta2: moves {ratio:.3g} times as far as theta1 / N over the log "
                             f"(least-squares slope of N theta2 on theta1 over {travel:.3g} rad of travel at the "
                             f"load; expected 1 at the model's ratio N = {p.N:.4g}, allowed "
                             f"{1 / RATIO_FACTOR:.3g}-{RATIO_FACTOR:g}){hint}", field="theta2")
    if mv.sum() >= 20:
        A = np.column_stack([m.a, m.w, np.sign(m.w)])[mv]
        y = p.uc[mv]  # the balance in contact, with the load torque at the motor
        keep = np.ones(y.size, bool)
        for _ in range(3):  # drop the gap crossings' outliers
            sol = np.linalg.lstsq(A[keep], y[keep], rcond=None)[0]
            r = y - A @ sol
            s = 1.4826 * float(np.median(np.abs(r[keep]))) + 1e-300
            keep = np.abs(r) < 5 * s
        J = float(sol[0])
        if J <= 0.0:
            raise InputError(f"{name}: column torque: does not drive the motion (the torque balance u = J theta1'' + "
                             f"d theta1' + T sgn theta1' gives J = {J:.3g} kg m^2; expected about the model's "
                             f"{J_model:.3g}): a negated torque or theta1 (an encoder counting against the "
                             f"torque), or not the motor's torque", field="torque")
        ratio = J / J_model
        # a motor that crosses a wide gap often moves alone, with its own inertia J1: the fit over every moving sample
        # then lies between J1 and J1 + J2/N^2 (an open-loop log of a 1 mm gap gave 0.25x and was refused as units)
        low = max(min(pl.J1 / J_model, 1.0), INERTIA_FREE_SHARE) / INERTIA_FACTOR
        if not low <= ratio <= INERTIA_FACTOR:
            hint = _unit_hint(ratio, INERTIA_HINTS)
            field = "t" if hint.startswith(" (t ") else "torque" if hint.startswith(" (torque") else "theta1"
            raise InputError(f"{name}: column {field}: the torque balance gives a lumped inertia {J:.3g} kg m^2, "
                             f"{ratio:.3g} times the model's {J_model:.3g} (allowed {low:.3g}-"
                             f"{INERTIA_FACTOR:g}x){hint}: expected t [s], torque [N m], theta1 [rad]", field=field)


def _episodes(p: _Problem) -> tuple[float, float, list[tuple[int, int, int]]]:
    """Contact plateaus of the measured ``s = r_b1 theta1 - r_b2 theta2``: centre, half-gap, episodes.

    An episode is a run of samples near one extreme of ``s`` (beyond 60 % of the half-range from the
    middle, after a 5-sample median filter removes impact spikes, 3 samples below 1 kHz); neighbouring runs
    on one flank are one episode (a bounce that dipped), so episodes alternate between the flanks.
    """
    from scipy.ndimage import median_filter

    pl = p.nominal
    assert p.l is not None
    s = pl.rb1 * p.log.theta1 - pl.rb2 * p.log.theta2
    # a 5-sample median removes an impact's spike at 1 kHz and faster; at slower sampling a loop's contacts may last
    # 3-4 samples (500 Hz, a loop that floats in the gap between brief contacts): 3 samples there
    sm = median_filter(s, size=5 if p.Ts <= 1.001e-3 else 3, mode="nearest")
    hi, lo = float(sm.max()), float(sm.min())
    c0, b0 = 0.5 * (hi + lo), 0.5 * (hi - lo)
    # the noise of s in its quietest block (a loop that hunts at 500 Hz moves in nearly every block and its
    # encoders' levels count that motion as noise), at least the quantisation's
    noise = max(_noise_level(s, quietest=True), math.hypot(pl.rb1 * p.m.q, pl.rb2 * p.l.q) / math.sqrt(12.0))
    if b0 <= 10 * noise:
        col = _gap_column(p)
        raise InputError(f"{p.log.name}: column {col}: 0 gap crossing(s) found: r_b1 theta1 - r_b2 theta2 "
                         f"spans {2 * b0:.3g} m, its half {b0 / noise:.3g} times the encoders' noise on it "
                         f"({noise:.3g} m; at least 10 needed): the gap does not stand out of the noise (the shafts "
                         f"turn together, or the encoders are too coarse or noisy to show the gap)", field=col)
    eps = [(i0, i1, 1) for i0, i1 in _runs(sm - c0 > 0.6 * b0)] + \
          [(i0, i1, -1) for i0, i1 in _runs(sm - c0 < -0.6 * b0)]
    eps.sort()
    merged: list[tuple[int, int, int]] = []
    for e in eps:
        if merged and merged[-1][2] == e[2]:
            merged[-1] = (merged[-1][0], e[1], e[2])
        else:
            merged.append(e)
    _check_driven(p, merged)
    return c0, b0, merged


#: On each flank the load must move by this many times its encoder's noise while the gap sits there.
DRIVEN_NOISE = 10.0


def _check_driven(p: _Problem, eps: list[tuple[int, int, int]]) -> None:
    """Refuse a log whose extremes of ``s`` are not flanks: the load must move while ``s`` sits at each.

    The extremes of ``s`` are the flanks only where the motor meets the load there. A motor that turns back
    inside the gap (an excitation too small to cross it) makes extremes too, and their half-span is then only
    how far it swung: a reviewer's log whose motor dithered 0.9 mrad inside a 3.5 mrad gap gave b at 23 % of the
    truth, with a confident interval. At a flank the motor pushes the load, or the flank stops it: on each side,
    the load moves by more than :data:`DRIVEN_NOISE` times its encoder's noise during at least one episode.
    Checked on logs whose motor travels less than :data:`RATIO_TRAVEL` lost motions (beyond, the ratio check of
    :func:`_check_signals` names a load encoder that does not follow the motor).
    """
    ld = p.l
    assert ld is not None
    th2 = p.log.theta2
    assert th2 is not None
    if float(np.ptp(p.log.theta1)) / p.N >= RATIO_TRAVEL * p.nominal.lost_motion:
        return  # over that travel the motor drives the load; a load encoder that does not follow is the ratio check's
    noise = max(_noise_level(th2, quietest=True), ld.q / math.sqrt(12.0), 1e-12 * float(np.max(np.abs(th2))), 1e-300)
    sm = _smooth(th2, _hann(p.W))  # the noise's own range over a long episode would be several times its level
    for side, name in ((1, "front"), (-1, "back")):
        moved = max((float(np.ptp(sm[i0:i1])) for i0, i1, sd in eps if sd == side), default=0.0)
        if moved <= DRIVEN_NOISE * noise:
            raise InputError(
                f"{p.log.name}: column theta2: the load does not move where the gap reaches its {name} extreme (at "
                f"most {moved:.3g} rad, {moved / noise:.3g} times the load encoder's noise {noise:.3g} rad; more "
                f"than {DRIVEN_NOISE:g} needed): the motor turns back inside the gap, so its extremes are not the "
                f"flanks and say nothing of b. Excite with moves that drive the load both ways (gearctl excite)",
                field="theta2")


def _flank_value(v: NDArray[np.float64], width: float, need: int) -> tuple[float, float]:
    """Where the flank is, from ``v = sigma (s - F/k)`` of samples that may touch it.

    In contact ``v`` sits at the flank (up to the encoders' flicker); a sample inside the gap has ``v``
    below it. The flank is the densest window of width ``width`` in the top of the distribution (within 20
    widths of the largest value; a sliding window, so that a rest's samples are not split by where fixed bins'
    edges fall; of equally dense windows the highest), refined as the median of the samples within 1.5 widths
    of its centre; NaN if that window holds fewer than ``need`` samples. Also returns the plateau's pull into the
    gap: how far the 90th percentile of those top samples lies above it (0 at least).
    """
    top = float(v.max())
    v = np.sort(v[v >= top - 20 * width])
    counts = np.searchsorted(v, v + width, side="right") - np.arange(v.size)
    best = int(counts.max())
    if best < need:
        return math.nan, math.nan
    j = int(np.flatnonzero(counts == best)[-1])
    c = v[j] + 0.5 * width
    value = float(np.median(v[np.abs(v - c) <= 1.5 * width]))
    return value, max(float(np.percentile(v, 90)) - value, 0.0)


def _position_check(p: _Problem, contact: dict[int, list[NDArray[np.int_]]], s: NDArray[np.float64],
                    force: NDArray[np.float64], width: float, need: int) -> tuple[float, int, float]:
    """The flanks compared at the same load angle: b from the angles with contact on both flanks.

    An encoder's error that depends on the angle (a once-per-turn eccentricity: a sine of a few counts) moves
    ``s = r_b1 theta1 - r_b2 theta2`` on both flanks alike at one angle, so it cancels from half the distance between
    the flanks there, but not between plateaus at different angles: a load that rests on the front flank at one end
    of its travel and on the back flank at the other reads the difference of the error between the ends. The samples
    in contact on each flank (those the plateaus use) are binned by the load angle (:data:`POSITION_BIN`), each bin's
    flank found as a plateau's (:func:`_flank_value`; a bin pulled into the gap by more than :data:`POSITION_PULL`
    widths is left out). Returns the median over the bins with both flanks of half their sum (NaN with fewer than
    :data:`POSITION_SHARED` such bins), the number of those bins, and how far the flanks move along the travel (the
    sum of the two flanks' ranges of a running mean over :data:`POSITION_RUN` bins) [m].
    """
    pl = p.nominal
    x = p.log.theta2
    assert x is not None
    prof: dict[int, dict[int, float]] = {}
    for sg in (1, -1):
        idx = np.concatenate(contact[sg]) if contact[sg] else np.zeros(0, int)
        v = sg * (s[idx] - force[idx] / pl.k)
        k = np.floor(x[idx] / POSITION_BIN).astype(np.int64)
        order = np.argsort(k, kind="stable")
        keys, starts = np.unique(k[order], return_index=True)
        prof[sg] = {}
        for key, sel in zip(keys, np.split(v[order], starts[1:]), strict=True):
            if sel.size >= need:
                value, pull = _flank_value(sel, width, need)
                # a bin whose samples spread far into the gap holds no resting flank (a load coasting off it under a
                # load torque near its friction: tests/test_identify_load_torque.py's log, pulls of 5.5 and 11 um,
                # bins 6-12 um inside the flank)
                if math.isfinite(value) and pull <= POSITION_PULL * width:
                    prof[sg][int(key)] = value
    # how far each flank moves along the travel: the range of its bins' running mean over POSITION_RUN bins in the
    # order of the angle (an eccentricity moves a flank smoothly from bin to bin; a loop that rattles scatters single
    # bins by as much, 1.3 um on other_sim_rattling_pd.csv, whose b is right); a flank with fewer bins shows none
    spread = 0.0
    for pr in prof.values():
        if len(pr) >= POSITION_RUN:
            vals = np.array([pr[key] for key in sorted(pr)])
            spread += float(np.ptp(np.convolve(vals, np.full(POSITION_RUN, 1.0 / POSITION_RUN), mode="valid")))
    shared = sorted(set(prof[1]) & set(prof[-1]))
    if len(shared) < POSITION_SHARED:
        return math.nan, len(shared), spread
    return float(np.median([0.5 * (prof[1][key] + prof[-1][key]) for key in shared])), len(shared), spread


def _plateau_backlash(p: _Problem, theta: NDArray[np.float64], eps: list[tuple[int, int, int]]
                      ) -> tuple[float, tuple[float, float], float, NDArray, NDArray, float, tuple[int, int],
                                 tuple[str | None, str | None]]:
    """Backlash from the plateaus of ``s`` on either flank, corrected for the mesh deflection ``F / k``.

    Returns ``b``, its 95 % interval, the centre of the gap, the estimate of each neighbouring pair of
    plateaus with its time, the mean deflection correction, how many rests on the front and the back flank
    it used, and where the flanks move with the load angle (:func:`_position_check`) by more than the interval's
    half-width a warning (the position-matched b differs) or the reason b is not identified (no angles to compare
    the flanks at), each None otherwise.
    """
    pl = p.nominal
    ld = p.l
    assert ld is not None
    s = pl.rb1 * p.log.theta1 - pl.rb2 * p.log.theta2
    tau = p.transmitted(theta)
    force = tau / pl.rb1
    h = max(0.15 * float(np.percentile(np.abs(tau), 75)), 1e-12)
    # in contact s moves only by the deflection and the encoders' flicker; inside the gap it travels. The travel is
    # taken over +-1 ms (one sample at 1 kHz and slower): at 5 kHz a sample's travel through the gap, 1 um, is
    # within the flicker, and a load bouncing in the gap would count as resting
    m = max(1, int(round(1e-3 / p.Ts)))
    ds = np.abs(np.gradient(s)) if m == 1 else 0.5 * np.abs(np.concatenate([s[m:], np.repeat(s[-1], m)])
                                                             - np.concatenate([np.repeat(s[0], m), s[:-m]]))
    # and no sample of a sustained oscillation at the Nyquist frequency rests: a travel over +-m samples is blind to
    # it (s[k+m] and s[k-m] in one phase). r4's PD loop hunting at 500 Hz across a 10 um gap at 1 kHz, s alternating
    # +5.5 / -6.5 um from sample to sample, read as rests on the back flank at -6 um: b 7.93 um [7.28, 8.58] for the
    # true 10. The Nyquist component |s[k+1] - 2 s[k] + s[k-1]| / 4, beyond the threshold at a sample and both its
    # neighbours (a single touch between bounces of a rattling loop is a rest: asking each sample's own steps took
    # another simulator's rattling PD log from 49.8 um [49.2, 50.4] to 48.9 [48.1, 49.7] for the true 50)
    thr = (pl.rb1 * p.m.q + pl.rb2 * ld.q) + 6 * math.hypot(pl.rb1 * p.m.sigma, pl.rb2 * ld.sigma)
    alt = np.zeros_like(s)
    alt[1:-1] = np.abs(s[2:] - 2.0 * s[1:-1] + s[:-2]) / 4.0
    hunt = alt > thr
    hunt[1:-1] &= hunt[:-2] & hunt[2:]
    hunt[[0, -1]] = False
    still = (ds <= thr) & ~hunt
    width = max(0.5 * (pl.rb1 * p.m.q + pl.rb2 * ld.q), 2 * math.hypot(pl.rb1 * p.m.sigma, pl.rb2 * ld.sigma))
    vals: list[tuple[int, float, float]] = []  # (flank, plateau, time)
    corr = []
    pulls = []  # how far the top tenth of each plateau's samples lies above it (towards the flank)
    need = max(3, int(round(0.003 / p.Ts)))
    contact: dict[int, list[NDArray[np.int_]]] = {1: [], -1: []}
    for i0, i1, sg in eps:
        a = i0 + p.settle
        # contact for sure: the mesh carries torque towards this flank and the flanks do not move apart
        idx = a + np.flatnonzero((sg * tau[a:i1] > h) & still[a:i1]) if i1 > a else np.zeros(0, int)
        contact[sg].append(idx)
        v = sg * (s[idx] - force[idx] / pl.k)
        value, pull = _flank_value(v, width, need) if idx.size >= need else (math.nan, math.nan)
        if not math.isfinite(value):
            vals.append((sg, math.nan, float(p.log.t[i0])))
            continue
        corr.append(float(np.mean(np.abs(force[idx] / pl.k))))
        pulls.append(pull)
        vals.append((sg, sg * value, float(p.log.t[(a + i1) // 2])))
    # a plateau can only be pulled into the gap (by samples of a contact too brief to settle), never out of
    # it: on each side keep the plateaus within 4 bins of the upper quartile
    for sign in (1, -1):
        side = np.array([sign * v for sg, v, _ in vals if sg == sign and math.isfinite(v)])
        if side.size:
            ref = float(np.percentile(side, 75))
            vals = [(sg, v if sg != sign or not math.isfinite(v) or sign * v >= ref - 4 * width else math.nan, t)
                    for sg, v, t in vals]
    front = np.array([v for sg, v, _ in vals if sg > 0 and math.isfinite(v)])
    back = np.array([v for sg, v, _ in vals if sg < 0 and math.isfinite(v)])
    if front.size == 0 or back.size == 0:
        col = _gap_column(p)
        missing = "either flank" if front.size == back.size == 0 else f"the {'back' if front.size else 'front'} flank"
        raise InputError(f"{p.log.name}: column {col}: {len(eps) - 1} gap crossing(s), but no rest on {missing}: "
                         f"no stretch of {need} samples ({need * p.Ts * 1e3:.3g} ms) with the mesh carrying "
                         f"torque towards it and the flanks still (the loop rattles in the gap or the load floats); "
                         f"record moves with dwells in contact on both flanks", field=col)
    b = 0.5 * (float(front.mean()) - float(back.mean()))
    centre = 0.5 * (float(front.mean()) + float(back.mean()))
    var = 0.0
    for arr in (front, back):
        var += float(arr.var(ddof=1)) / arr.size if arr.size > 1 else 0.0
    se = 0.5 * math.sqrt(var)
    dof = min(front.size, back.size) - 1
    # quantisation of a flank at rest does not average out: a flank resting between two counts reads the same
    # count at every visit (without noise to dither it), so one count of s is a systematic error of b
    q_s = math.hypot(pl.rb1 * p.m.q, pl.rb2 * p.l.q)  # type: ignore[union-attr]
    defl = float(np.mean(corr)) if corr else 0.0
    # a loop that rattles across the gap leaves the load floating just off its flank, and such samples can outnumber
    # those in contact: the densest window then lies inside the gap, below the samples that touch the flank. The
    # mean distance from each plateau up to the 90th percentile of its samples bounds that pull (about the flicker,
    # 0.1 um, on a log that rests in contact; 0.4 um on a rattling PD loop of the frictionless servo from another
    # simulator, whose b came out 1.2 % low with an interval of 1.0 %), a systematic error of b
    pull = float(np.mean(pulls)) if pulls else 0.0
    half = math.sqrt((_t95(dof) * se) ** 2 + q_s**2 + (0.3 * defl) ** 2 + pull**2)
    est, times = [], []
    for (s1, v1, t1), (s2, v2, t2) in zip(vals[:-1], vals[1:], strict=True):
        if s1 != s2 and math.isfinite(v1) and math.isfinite(v2):
            est.append(0.5 * s1 * (v1 - v2))
            times.append(0.5 * (t1 + t2))
    # lack of fit: plateaus that drift along the log (contacts that never settle as a chirp speeds up, the
    # deflection F/k misjudged at high acceleration) are not scatter about b. Batch means (the estimates of
    # neighbouring pairs of plateaus in BATCHES runs, in time order): the interval is at least the Student t
    # interval of the batches' means, which a drift widens and independent scatter leaves about as it was
    if len(est) >= 2 * BATCHES:
        means = np.array([float(np.mean(c)) for c in np.array_split(np.array(est), BATCHES)])
        half = max(half, _t95(BATCHES - 1) * float(means.std(ddof=1)) / math.sqrt(BATCHES))
    # an encoder's error that depends on the angle is no scatter of the plateaus where each flank rests at its own
    # angles: r4's simulator with a load encoder 5 counts eccentric (2.2 um along the line of action) and moves of
    # +-1.5 rad gave b 11.5 um [9.5, 13.5] for a true 10 where the flanks compared at the same angles give 10.01, and
    # 6.70 um [6.07, 7.32] for a true 5 (tests/data/logs/r4/), where too few angles hold contact on both flanks to
    # compare them at. The difference from the position-matched b enters the interval as a systematic error; without
    # that b, flanks that move over the travel by more than the interval leave b not identified
    b_pos, n_pos, spread = _position_check(p, contact, s, force, width, need)
    note = unmatched = None
    moves = (f"the flanks move with the load angle: r_b1 theta1 - r_b2 theta2 in contact varies by {spread * 1e6:.3g} "
             f"um along the line of action over the travel, both flanks' ranges added (an encoder's error that "
             f"depends on the angle, such as an eccentricity), and the plateaus lie at different angles on the two "
             f"flanks")
    if math.isfinite(b_pos):
        sys_pos = abs(b - b_pos)
        if sys_pos > half:
            note = (f"{moves}; compared at the same angles ({n_pos} bins of {POSITION_BIN:g} rad) b is "
                    f"{b_pos * 1e6:.4g} um against the plateaus' {b * 1e6:.4g} um: the interval includes the "
                    f"difference")
        half = math.hypot(half, sys_pos)
    elif 0.5 * spread > half:
        unmatched = (f"{moves}; fewer than {POSITION_SHARED} angles hold contact on both flanks to compare them at "
                     f"(the plateaus give {b * 1e6:.4g} um with a half-width of {half * 1e6:.3g} um); record moves "
                     f"that rest on both flanks at the same angles")
    return (b, (b - half, b + half), centre, np.array(est), np.array(times), defl, (front.size, back.size),
            (note, unmatched))


def _gap_windows(p: _Problem, eps: list[tuple[int, int, int]], theta: NDArray[np.float64]) -> list[_Window]:
    """Windows around the changes of plateau (both encoders)."""
    tau = p.transmitted(theta)
    out = []
    for (a0, a1, sa), (b0, b1, sb) in zip(eps[:-1], eps[1:], strict=True):
        k0 = max(a0 + p.settle, a1 - p.before)
        k1 = min(b1 - 1, b0 + p.after)
        if k1 - k0 < 10 or k0 >= a1:
            continue
        f0 = float(tau[k0]) / p.nominal.rb1
        out.append(_Window(k0, k1, sa, sb, sa * max(sa * f0, 0.0), float(0.5 * (p.log.t[a1 - 1] + p.log.t[b0]))))
    return out


def _torque_windows(p: _Problem) -> tuple[list[_Window], NDArray[np.bool_]]:
    """Gap crossings seen from the motor alone: sign changes of the torque the mesh takes from the motor.

    The torque is computed with the model's motor-shaft values; a crossing is where it passes from below
    ``-h`` to above ``+h`` (or back), ``h`` 15 % of its 75th percentile. A window starts
    :data:`WINDOW_BEFORE` before the last sample beyond ``-h`` but not more than three times that before the
    first beyond ``+h`` (a dwell in between is not re-simulated), and ends :data:`WINDOW_AFTER` after it.
    Returns the windows and the samples with a steady transmitted torque (beyond ``h``), where the two
    shafts move as one.
    """
    pl = p.nominal
    theta0 = np.array([pl.J1, pl.J2, pl.d1, pl.d2, pl.tc1, pl.tc2])
    tau = p.transmitted(theta0)
    h = 0.15 * float(np.percentile(np.abs(tau), 75))
    h = max(h, 1e-12)
    state, last = 0, -1
    raw: list[tuple[int, int, int, int]] = []
    for k in np.flatnonzero(np.abs(tau) > h).tolist():
        sg = 1 if tau[k] > 0 else -1
        if state and sg != state:
            raw.append((last, k, state, sg))
        state, last = sg, k
    out = []
    for j, (a, b, s0, s1) in enumerate(raw):
        lo = 0 if j == 0 else (raw[j - 1][1] + a) // 2
        hi = p.n - 1 if j == len(raw) - 1 else (b + raw[j + 1][0]) // 2
        # start in contact on the old flank: at most a few window lengths before the new torque (a dwell between)
        k0, k1 = max(lo, a - p.before, b - 3 * p.before), min(hi, b + p.after)
        if k1 - k0 < 10:
            continue
        f0 = float(tau[k0]) / pl.rb1
        out.append(_Window(k0, k1, s0, s1, s0 * max(s0 * f0, 0.0), float(0.5 * (p.log.t[a] + p.log.t[b]))))
    return out, np.abs(tau) > h


@dataclasses.dataclass
class _Fit:
    """One window's fit: parameters, the simulated angles, residual RMS per encoder [rad], the solution."""

    b: float
    phi: float
    sim: NDArray[np.float64]
    res_motor: float
    res_load: float
    cost: float
    z: NDArray[np.float64]


def _lumped(theta: NDArray[np.float64], N: float) -> tuple[float, float, float]:
    """``J_eq, d_eq, T_eq`` on the motor shaft of ``theta = (J1, J2, d1, d2, tc1, tc2)``."""
    return theta[0] + theta[1] / N**2, theta[2] + theta[3] / N**2, theta[4] + theta[5] / N


def _split(theta: NDArray[np.float64], N: float, *, phi: float | None = None, kappa: float | None = None,
           psi: float | None = None) -> NDArray[np.float64]:
    """``theta`` with the lumped values kept and their split between the shafts changed.

    ``phi``: share of the Coulomb friction on the motor (``tc1 = phi T_eq``, ``tc2 = N (1 - phi) T_eq``);
    ``kappa``: the motor inertia scaled (``J1 = kappa J1``, ``J2 = N^2 (J_eq - J1)``); ``psi``: share of the
    viscous friction on the motor.
    """
    th = theta.copy()
    J_eq, d_eq, T_eq = _lumped(theta, N)
    if phi is not None:
        th[4], th[5] = phi * T_eq, N * (1.0 - phi) * T_eq
    if kappa is not None:
        th[0] = kappa * theta[0]
        th[1] = N**2 * (J_eq - th[0])
    if psi is not None:
        th[2], th[3] = psi * d_eq, N**2 * (1.0 - psi) * d_eq
    return th


class _WindowModel:
    """The re-simulation of one window as a function of its free parameters (in noise units).

    Always free: the motor's angle and speed at the window's start. ``free`` may add ``"b"`` (the
    backlash, relative to ``b``) and ``"phi"`` (the share of the lumped Coulomb friction on the motor
    shaft). The load angle follows from the flank in contact at the start.
    """

    def __init__(self, p: _Problem, w: _Window, theta: NDArray[np.float64], b: float, *, free: tuple[str, ...] = (),
                 phi: float | None = None, offset: float = 0.0) -> None:
        m = p.m
        self.p, self.w, self.theta, self.b, self.free, self.phi = p, w, theta, b, free, phi
        self.names = ["dtheta", "domega", *free]
        self.seg = p.log.torque[w.k0:w.k1]
        self.y1 = p.log.theta1[w.k0:w.k1 + 1]
        self.y2 = None if p.l is None else p.l.raw[w.k0:w.k1 + 1] + offset / p.nominal.rb2
        self.sw = max(m.v_thr, 1e-3 * abs(float(m.w[w.k0])), 1e-9)
        self.cache: dict[tuple[float, float], tuple[Any, Any]] = {}
        wlim = max(50.0, 0.3 * abs(float(m.w[w.k0])) / self.sw)
        bounds = {"dtheta": (-50.0, 50.0), "domega": (-wlim, wlim), "b": (1e-8 / b, min(0.5 * p.module, 0.0099) / b),
                  "phi": (0.0, 1.0)}
        self.lo = np.array([bounds[k][0] for k in self.names])
        self.hi = np.array([bounds[k][1] for k in self.names])
        start = {"dtheta": 0.0, "domega": 0.0, "b": 1.0, "phi": phi if phi is not None else 0.5}
        self.start = np.array([start[k] for k in self.names])

    def values(self, z: NDArray[np.float64]) -> dict[str, float]:
        """Physical values of a parameter vector."""
        v = dict(zip(self.names, np.asarray(z).tolist(), strict=True))
        return {"dth": v["dtheta"] * self.p.m.sigma, "dw": v["domega"] * self.sw, "b": v.get("b", 1.0) * self.b,
                "phi": v.get("phi", self.phi if self.phi is not None else math.nan)}

    def _plant(self, v: dict[str, float]) -> tuple[Any, Any]:
        from .kernel import Kernel

        key = (v["b"], v["phi"])
        if key not in self.cache:
            if len(self.cache) > 2 + len(self.names):  # the current point and the Jacobian's steps
                self.cache.pop(next(iter(self.cache)))
            th = self.theta if "phi" not in self.free else _split(self.theta, self.p.N, phi=v["phi"])
            q = _with_values(self.p.nominal, th, v["b"], self.p.tc_floor)
            self.cache[key] = (q, Kernel(q, np.zeros(4), dt=self.p.Ts))
        return self.cache[key]

    def simulate(self, z: NDArray[np.float64]) -> NDArray[np.float64]:
        """Angles ``(2, m + 1)`` re-simulated with the parameters ``z``."""
        v = self.values(z)
        q, kn = self._plant(v)
        m, k0 = self.p.m, self.w.k0
        x0 = _start_state(q, float(m.p[k0]) + v["dth"], float(m.w[k0]) + v["dw"], self.w.before, self.w.force0)
        return _simulate(q, x0, self.seg, self.p.Ts, kn)

    def resid(self, z: NDArray[np.float64]) -> NDArray[np.float64]:
        """Measured minus re-simulated angles, in noise units."""
        sim = self.simulate(z)
        r = (sim[0] - self.y1) / self.p.m.sigma
        if self.y2 is not None:
            r = np.concatenate((r, (sim[1] - self.y2) / self.p.l.sigma))  # type: ignore[union-attr]
        return np.nan_to_num(r, nan=1e3, posinf=1e3, neginf=-1e3)

    def fit(self, z0: NDArray[np.float64] | None = None, *, max_nfev: int = 80) -> _Fit:
        """Bounded least squares (SciPy ``least_squares``, trust region reflective)."""
        from scipy.optimize import least_squares

        z = self.start if z0 is None else np.asarray(z0, dtype=float)
        z = np.clip(z, self.lo + 1e-9 * (self.hi - self.lo), self.hi - 1e-9 * (self.hi - self.lo))
        sol = least_squares(self.resid, z, bounds=(self.lo, self.hi), diff_step=1e-3, max_nfev=max_nfev,
                            x_scale=1.0, ftol=1e-6, xtol=1e-6)
        v = self.values(sol.x)
        sim = self.simulate(sol.x)
        rm = float(np.sqrt(np.nanmean((sim[0] - self.y1) ** 2)))
        rl = float(np.sqrt(np.nanmean((sim[1] - self.y2) ** 2))) if self.y2 is not None else math.nan
        return _Fit(b=v["b"], phi=v["phi"], sim=sim, res_motor=rm, res_load=rl,
                    cost=float(np.sum(sol.fun**2)), z=sol.x)


def _fit_window(p: _Problem, w: _Window, theta: NDArray[np.float64], b: float, *, free: tuple[str, ...] = (),
                phi: float | None = None, offset: float = 0.0) -> _Fit:
    """Fit one window's re-simulation to the encoders (:class:`_WindowModel`)."""
    return _WindowModel(p, w, theta, b, free=free, phi=phi, offset=offset).fit()


def _profile_start(p: _Problem, wins: list[_Window], theta: NDArray[np.float64], b_nom: float,
                   split: bool) -> tuple[float, float]:
    """Start of the motor-only fits: the backlash (and Coulomb share) of least profiled cost.

    For each backlash on a log grid from ``b_nom / 5`` to ``5 b_nom`` (and each share 0, 0.5, 1), the
    motor's initial angle and speed of each window are fitted by one Gauss-Newton step (the motion is
    nearly linear in them): a least-squares fit started from the best grid point does not get caught in the
    local minima a gap crossing's timing makes. Each window picks its own best grid point and the start is
    their median (geometric for ``b``): a window that is no crossing from flank to flank (a log that starts
    with the motor inside the gap) does not set every fit's start, as it did when the costs were summed.
    """
    from .kernel import Kernel

    b_hi = min(0.5 * p.module, 0.0099)
    grid = np.geomspace(b_nom / 5, min(5 * b_nom, b_hi), 9)
    phis = (0.0, 0.5, 1.0) if split else (None,)
    m = p.m
    costs = np.full((len(phis), grid.size, len(wins)), np.inf)
    for i_ph, ph in enumerate(phis):
        th = theta if ph is None else _split(theta, p.N, phi=ph)
        for i_b, bb in enumerate(grid.tolist()):
            q = _with_values(p.nominal, th, bb, p.tc_floor)
            kn = Kernel(q, np.zeros(4), dt=p.Ts)
            for i_w, w in enumerate(wins):
                seg = p.log.torque[w.k0:w.k1]
                y = p.log.theta1[w.k0:w.k1 + 1]
                sw = max(m.v_thr, 1e-3 * abs(float(m.w[w.k0])), 1e-9)

                def r(dth: float, dw: float, w: _Window = w, seg: NDArray = seg, y: NDArray = y, q: Any = q,
                      kn: Any = kn) -> NDArray:
                    x0 = _start_state(q, float(m.p[w.k0]) + dth, float(m.w[w.k0]) + dw, w.before, w.force0)
                    return np.nan_to_num((_simulate(q, x0, seg, p.Ts, kn)[0] - y) / m.sigma, nan=1e3)

                r0 = r(0.0, 0.0)
                J = np.column_stack([(r(10 * m.sigma, 0.0) - r0) / 10, (r(0.0, 10 * sw) - r0) / 10])
                step = np.linalg.lstsq(J, -r0, rcond=None)[0]
                costs[i_ph, i_b, i_w] = min(float(np.sum(r(step[0] * m.sigma, step[1] * sw) ** 2)),
                                            float(np.sum(r0**2)))
    i_ph, i_b = np.unravel_index(np.argmin(costs.reshape(-1, len(wins)), axis=0), costs.shape[:2])
    b_start = float(np.exp(np.median(np.log(grid[i_b]))))
    return b_start, float(np.median([phis[i] or 0.0 for i in i_ph]))


def _systematic(p: _Problem, wins: list[_Window], fits: list[_Fit], theta: NDArray[np.float64],
                spreads: dict[str, float]) -> tuple[float, dict[str, float]]:
    """How far the motor-only backlash moves when the friction and inertia move within their uncertainty.

    The windows are refitted (warm-started) with, in turn, the lumped inertia, viscous and Coulomb
    friction raised by their 95 % half-widths (``spreads``: ``J_eq``, ``d_eq``, ``T_eq`` [SI]), the motor's
    share of the inertia raised by ``kappa`` and the motor's share of the Coulomb friction by ``phi``
    [relative], and with the viscous friction all on the motor and all on the load (the split contact
    cannot see). The shift of a group is the median over the windows (a crossing with many bounces can
    refit into another minimum); the 95 % half-width adds the groups in quadrature. Returns it and the
    shift per group [m].
    """
    N = p.N
    J_eq, d_eq, T_eq = _lumped(theta, N)
    variants: dict[str, list[NDArray[np.float64]]] = {}
    for key, idx, lump in (("J_eq", (0, 1), J_eq), ("d_eq", (2, 3), d_eq), ("T_eq", (4, 5), T_eq)):
        if lump > 0 and spreads.get(key, 0.0) > 0:
            th = theta.copy()
            th[list(idx)] *= 1.0 + spreads[key] / lump
            variants[key] = [th]
    variants["viscous split"] = [_split(theta, N, psi=0.0), _split(theta, N, psi=1.0)]
    if spreads.get("kappa", 0.0) > 0:
        # a heavier motor takes its inertia from the load's share of the lumped one: never all of it (a load that
        # reflects less than the motor inertia's tolerance would get a negative inertia)
        kappa = min(1.0 + spreads["kappa"], 1.0 + 0.5 * (J_eq - theta[0]) / theta[0])
        variants["kappa"] = [_split(theta, N, kappa=kappa)]
    if spreads.get("phi", 0.0) > 0 and T_eq > 0:
        phi0 = theta[4] / T_eq
        variants["phi"] = [_split(theta, N, phi=min(phi0 + spreads["phi"], 1.0) if phi0 < 0.5 else
                                  max(phi0 - spreads["phi"], 0.0))]
    shifts = {}
    for key, ths in variants.items():
        worst = 0.0
        for th in ths:
            d = [_WindowModel(p, w, th, f.b, free=("b",)).fit(np.array([f.z[0], f.z[1], 1.0]), max_nfev=12).b - f.b
                 for w, f in zip(wins, fits, strict=True)]
            worst = max(worst, abs(float(np.median(d))))
        shifts[key] = worst
    return math.sqrt(sum(v * v for v in shifts.values())), shifts


def _windows_out(p: _Problem, wins: list[_Window], fits: list[_Fit], offset: float) -> tuple[ReversalWindow, ...]:
    out = []
    for w, f in _spread_evenly(list(zip(wins, fits, strict=True)), MAX_PLOT_WINDOWS):
        sl = slice(w.k0, w.k1 + 1)
        th2 = None if p.l is None else p.l.raw[sl] + offset / p.nominal.rb2
        r = [(f.sim[0] - p.log.theta1[sl]) / p.N]
        if th2 is not None:
            r.append(f.sim[1] - th2)
        out.append(ReversalWindow(t_switch=w.t_switch, flanks=(w.before, w.after), t=p.log.t[sl].copy(),
                                  theta1=p.log.theta1[sl].copy(), theta1_sim=f.sim[0], theta2=th2,
                                  theta2_sim=f.sim[1], backlash=f.b,
                                  rms=float(np.sqrt(np.nanmean(np.concatenate(r) ** 2)))))
    return tuple(out)


def _gap_misfit(p: _Problem, wins: list[_Window], fits: list[_Fit], offset: float, b: float) -> float:
    """How far the re-simulated crossings miss the motor's free flight in the gap (both encoders) [m, along the line
    of action].

    Only the samples inside the gap count: those where the re-simulated or the measured relative displacement
    ``s = r_b1 theta1 - r_b2 theta2`` lies within ``b`` (the measured one less three times its noise). Per window the
    largest miss of the motor, ``r_b1 |theta1 - theta1_sim|``, over those samples; returned: its median over the
    windows (0 without such samples). (The load's miss is not gated: on a reviewer's log it reached 0.33 b with the
    load's quantities right.) A re-simulation that
    failed part-way (NaN from there on, :func:`_simulate`) counts over its samples before the failure, as in the RMS
    residual (a NaN miss made the median NaN, and ``NaN > GAP_MISS_SHARE * b`` let every crossing pass).
    """
    pl = p.nominal
    ld = p.l
    assert ld is not None
    edge = b - 3.0 * math.hypot(pl.rb1 * p.m.sigma, pl.rb2 * ld.sigma)
    worst = []
    for w, f in zip(wins, fits, strict=True):
        sl = slice(w.k0, w.k1 + 1)
        th2 = ld.raw[sl] + offset / pl.rb2
        s_sim = pl.rb1 * f.sim[0] - pl.rb2 * f.sim[1]
        gap = (np.abs(s_sim) < b) | (np.abs(pl.rb1 * p.log.theta1[sl] - pl.rb2 * th2) < edge)
        gap &= np.isfinite(f.sim[0]) & np.isfinite(f.sim[1])
        if gap.any():
            worst.append(float(np.abs(pl.rb1 * (p.log.theta1[sl] - f.sim[0]))[gap].max()))
    return float(np.median(worst)) if worst else 0.0


def _residuals(p: _Problem, fits: list[_Fit]) -> tuple[float, float, float]:
    """RMS residual in load-angle units over all fitted windows, and per encoder in its own angle."""
    if not fits:
        return math.nan, math.nan, math.nan
    rm = math.sqrt(float(np.mean([f.res_motor**2 for f in fits])))
    if p.l is None:
        return rm / p.N, rm, math.nan
    rl = math.sqrt(float(np.mean([f.res_load**2 for f in fits])))
    return math.sqrt(0.5 * ((rm / p.N) ** 2 + rl**2)), rm, rl


#: A torque column is read as rows off the motion when, shifted by those rows, its steps correlate with the motor's
#: acceleration steps by at least LAG_MIN_CORRELATION, while as logged they do not correlate positively at all (at
#: most LAG_MAX_LOGGED): a torque that drives the motion always does, whatever the loop, the rates or the holds.
LAG_MIN_CORRELATION, LAG_MAX_LOGGED = 0.3, 0.0
#: ... and the best shift must stand out of every other by this much (a loop hunting with a period of a few rows
#: correlates as well at several shifts: a two-row shift of such a log was named one row the other way).
LAG_MARGIN = 0.1
#: The shifts tried, rows either way.
LAG_ROWS = 2


def torque_lag(lg: EncoderLog) -> tuple[int, dict[int, float]]:
    """Whether the torque column is logged rows off the motion it drives: ``(lag, correlations)``.

    Under a torque held from each row to the next, the motor angle's second difference at row ``k`` is
    ``Ts^2 (u_(k-1) + u_k) / (2 J)`` plus the mesh's and the friction's slower terms; its change from row to row
    follows ``(u_k - u_(k-2)) / 2``. The correlation of the two over the log, with the torque shifted by ``lag``
    rows (``u_(k-lag)``, ``|lag| <= LAG_ROWS``), is highest at the lag the log has: 0 as it should be, ``+1`` where
    a row's torque acts a sample later (the drive logs its command a sample before it acts), ``-1`` where it acted a
    sample earlier (the row is written a sample late). Returns the best lag where the logged torque does not
    correlate positively (at most :data:`LAG_MAX_LOGGED`), the best reaches :data:`LAG_MIN_CORRELATION` and stands
    :data:`LAG_MARGIN` above every other shift, else 0; and the correlations.

    Why: a reviewer's log with the torque column one row late gave J1 21 % low with a tight interval, unflagged
    (correlations at -1: 0.59, as logged: -0.35; the stored ``reviewer_triangle_torque_late.csv``: 0.83 and
    -0.42). Why so strict: on correct logs the logged row need not lead. A second reviewer found a 500 Hz PID
    logged at 1 kHz (each torque held two rows) at 0.48 a row up against 0.29 as logged, and gearctl's own 250 Hz
    closed loops at 0.17 against -0.02: a margin over the logged row alone named shifts there that were not; none of
    them has a shift's signature, a logged torque uncorrelated with the motion and a shifted one that is. Shifts of
    two rows are looked for too (a one-row test named a two-row shift as one row the other way).
    """
    th, u = lg.theta1, lg.torque
    n = th.size
    out: dict[int, float] = {}
    m = LAG_ROWS + 2
    if n < 2 * m + 8:
        return 0, out
    d2 = th[2:] - 2.0 * th[1:-1] + th[:-2]  # d2[j] is row j + 1's
    k = np.arange(m, n - m)
    dd2 = d2[k - 1] - d2[k - 2]
    sa = float(np.std(dd2))
    for lag in range(-LAG_ROWS, LAG_ROWS + 1):
        du = 0.5 * (u[k - lag] - u[k - 2 - lag])
        sb = float(np.std(du))
        out[lag] = float(np.mean((dd2 - dd2.mean()) * (du - du.mean())) / (sa * sb)) if sa > 0.0 and sb > 0.0 else 0.0
    ranked = sorted(out, key=lambda j: out[j], reverse=True)
    best, second = ranked[0], ranked[1]
    clear = out[best] - out[second] >= LAG_MARGIN
    lag = best if (best != 0 and clear and out[0] <= LAG_MAX_LOGGED and out[best] >= LAG_MIN_CORRELATION) else 0
    return lag, out


def _as_arrays(lg: EncoderLog) -> EncoderLog:
    """A log made in Python with its columns as 1-D float arrays (lists, integer arrays): one that holds something
    else (text, nested rows) is refused naming the column."""
    cols: dict[str, Any] = {}  # the log's array fields by name (for dataclasses.replace)
    for name in ("t", "torque", "theta1", "theta2"):
        v = getattr(lg, name)
        if v is None and name == "theta2":
            continue
        try:
            a = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"{lg.name}: column {name} holds {type(v).__name__} values that are not numbers: expected "
                             f"a 1-D array of floats", field=name) from None
        if a.ndim != 1:
            raise InputError(f"{lg.name}: column {name} has shape {a.shape}: expected a 1-D array (one value per "
                             f"sample)", field=name)
        cols[name] = a
    try:
        Ts = float(lg.sample_time)
    except (TypeError, ValueError):
        raise InputError(f"{lg.name}: sample_time = {lg.sample_time!r} is not a number: expected the period [s]",
                         field="sample_time") from None
    return dataclasses.replace(lg, sample_time=Ts, **cols)


def _check_log(lg: EncoderLog) -> None:
    """What :func:`read_log` guarantees, for a log made in Python: equal lengths, finite, enough samples, time
    stamps increasing on the grid of ``sample_time``."""
    cols = {"t": lg.t, "torque": lg.torque, "theta1": lg.theta1}
    if lg.theta2 is not None:
        cols["theta2"] = lg.theta2
    for name, v in cols.items():
        v = np.asarray(v)
        if v.shape != (lg.n,):
            raise InputError(f"{lg.name}: column {name} has {v.size} samples, column t {lg.n}", field=name)
        if not np.all(np.isfinite(v)):
            raise InputError(f"{lg.name}: column {name} has a value that is not a finite number (sample "
                             f"{int(np.flatnonzero(~np.isfinite(v))[0])})", field=name)
    if lg.n < MIN_LOG_SAMPLES:
        raise InputError(f"{lg.name}: {lg.n} samples is too short: expected at least {MIN_LOG_SAMPLES}", field="log")
    SAMPLE_TIME.check("sample_time", lg.sample_time)
    # the time stamps as read_log refuses them from a file: increasing, on the grid of sample_time
    t = np.asarray(lg.t, dtype=float)
    bad = np.flatnonzero(np.diff(t) <= 0.0)
    if bad.size:
        k = int(bad[0]) + 1
        raise InputError(f"{lg.name}: column t: sample {k} (t = {float(t[k]):.10g}) does not increase (previous "
                         f"sample t = {float(t[k - 1]):.10g}): expected time in increasing order", field="t")
    Ts = sample_period(t)
    if abs(Ts - lg.sample_time) > PERIOD_TOLERANCE * lg.sample_time:
        raise InputError(f"{lg.name}: column t: its period {Ts:.6g} s differs from sample_time = "
                         f"{lg.sample_time:.6g} s by more than {PERIOD_TOLERANCE:.0%}: expected t [s] sampled at "
                         f"sample_time", field="t")
    # the grid of the stamps' own period, as read_log takes it from a file: a sample_time within PERIOD_TOLERANCE of
    # the stamps' period (a drive's nominal period, stamped by a clock some ppm off) is no grid error; on the grid of
    # sample_time itself such a clock drifted a quarter period off within a few thousand samples and was refused
    dev = _grid_deviation(t, Ts)
    k = int(np.argmax(np.abs(dev)))
    if abs(dev[k]) > JITTER_TOLERANCE * Ts:
        off = _missing_sample(np.diff(t), lg.sample_time)
        if off is not None:  # a sample missing or doubled: named where it is, not where the grid ends up furthest
            k = off + 1
            raise InputError(f"{lg.name}: column t: sample {k} (t = {float(t[k]):.10g}) is "
                             f"{float(t[k] - t[k - 1]):.6g} s after the previous sample; sample_time = "
                             f"{lg.sample_time:.6g} s: expected samples at a fixed period (a sample missing or "
                             f"doubled: each interval within {2 * JITTER_TOLERANCE:.0%} of it, the stamps within "
                             f"{JITTER_TOLERANCE:.0%} of a fixed grid)", field="t")
        raise InputError(f"{lg.name}: column t: sample {k} (t = {float(t[k]):.10g}) is {abs(dev[k]):.3g} s off the "
                         f"grid of sample_time = {lg.sample_time:.6g} s (at the stamps' own period, {Ts:.9g} s): "
                         f"expected samples at a fixed period (time stamps within {JITTER_TOLERANCE:.0%} of it)",
                         field="t")


#: Largest angle a reading may hold [rad] (160 000 revolutions): beyond it a value is no encoder angle
MAX_ANGLE = 1e6
#: A reading that leaves its neighbours by more than this many times the log's 99th-percentile step and comes back
#: within a sample is an encoder glitch
SPIKE_FACTOR = 20.0


def _check_readings(lg: EncoderLog) -> None:
    """Refuse encoder columns holding values no encoder gives: beyond :data:`MAX_ANGLE`, or a one-sample glitch
    (a jump out and back of more than :data:`SPIKE_FACTOR` times the 99th percentile of the steps), naming the
    column and the sample."""
    for col, v in (("theta1", lg.theta1), ("theta2", lg.theta2)):
        if v is None:
            continue
        big = np.flatnonzero(np.abs(v) > MAX_ANGLE)
        if big.size:
            k = int(big[0])
            raise InputError(f"{lg.name}: column {col}: {float(v[k]):.6g} at sample {k} (t = {float(lg.t[k]):.6g} s) "
                             f"is beyond {MAX_ANGLE:g} rad: expected the encoder's angle in rad", field=col)
        d = np.diff(v)
        if d.size < 3:
            continue
        thr = SPIKE_FACTOR * float(np.percentile(np.abs(d), 99.0))
        out, back = d[:-1], d[1:]
        spike = ((np.abs(out) > thr) & (np.abs(back) > thr) & (out * back < 0.0)
                 & (np.abs(out + back) < 0.1 * np.minimum(np.abs(out), np.abs(back))))
        if thr > 0.0 and spike.any():
            k = int(np.flatnonzero(spike)[0]) + 1
            raise InputError(f"{lg.name}: column {col}: sample {k} (t = {float(lg.t[k]):.6g} s) jumps "
                             f"{float(out[k - 1]):.3g} rad from its neighbours and back (an encoder glitch: the "
                             f"log's steps are at most {thr / SPIKE_FACTOR:.3g} rad in 99 % of the samples); repair "
                             f"or cut the log there",
                             field=col)
        # a single-turn encoder wrapping round: a step of whole revolutions that stays (named as a dead or swapped
        # load encoder before, under theta2 also when theta1 wrapped). Its step is whole revolutions plus the sample's
        # own motion: the steps' scale is taken with whole revolutions removed, since a turning motor's wraps, over 1 %
        # of the samples, made the 99th percentile of the raw steps a revolution (and a wrap no larger than 20 x it),
        # and a wrap is whole revolutions within the motion of a sample (0.2 rad at 100 rad/s and 500 Hz: 3 % of one)
        rev = np.abs(d) / (2.0 * math.pi)
        rest = np.abs(d - 2.0 * math.pi * np.round(d / (2.0 * math.pi)))
        step = float(np.percentile(rest, 99.0))
        near = max(0.02 * 2.0 * math.pi, min(2.0 * step, 0.25 * math.pi))
        # (steps that are no angle's, e.g. a log in encoder counts, leave no whole revolutions to see: not a wrap)
        wrap = np.flatnonzero((np.abs(d) > max(SPIKE_FACTOR * step, math.pi)) & (rest <= near)) \
            if step <= 0.125 * math.pi else np.zeros(0, dtype=int)
        if wrap.size:
            k = int(wrap[0]) + 1
            raise InputError(f"{lg.name}: column {col}: sample {k} (t = {float(lg.t[k]):.6g} s) jumps "
                             f"{float(d[k - 1]):.4g} rad ({int(round(rev[k - 1]))} revolution(s)) and stays (a "
                             f"single-turn encoder wrapping round?): expected a continuous angle in rad (unwrap it, "
                             f"as numpy.unwrap does)", field=col)


def _load_encoder_direction(log: EncoderLog) -> tuple[EncoderLog, bool]:
    """The log with ``theta2`` counting in gearctl's direction (the load turning with the motor, the gap
    ``r_b1 theta1 - r_b2 theta2``), and whether it had to be turned round.

    A spur pair turns its gears in opposite directions, and a simulator or a drive may count the load that
    way: the load's increments then run against the motor's. The least-squares slope of the load's angle on
    the motor's tells (``+1/N`` in gearctl's convention, ``-1/N`` in the other), with a correlation below -0.5.
    """
    assert log.theta2 is not None
    x, y = log.theta1 - np.mean(log.theta1), log.theta2 - np.mean(log.theta2)
    sxx, syy, sxy = float(np.dot(x, x)), float(np.dot(y, y)), float(np.dot(x, y))
    # turned round only when the two angles clearly move against each other (correlation below -0.5): a log in
    # which the load barely moves leaves its encoder as it is
    if sxx <= 0.0 or syy <= 0.0 or sxy >= -0.5 * math.sqrt(sxx * syy):
        return log, False
    return dataclasses.replace(log, theta2=-log.theta2), True


def _disagreeing(est: NDArray[np.float64]) -> int:
    """How many of the crossings' backlash estimates lie more than :data:`DISAGREE_BAND` from their median."""
    med = float(np.median(est))
    return int(np.count_nonzero(np.abs(est - med) > DISAGREE_BAND * med))


def identify(log: EncoderLog | str | Path, model: Any, *, encoders: str | None = None) -> Identification:
    """Estimate backlash, friction and inertias of a gear pair from a servo log.

    Parameters
    ----------
    log : EncoderLog, str or Path
        The log (:func:`read_log` reads a file).
    model : GearModel, str or Path
        What is known from drawings and data sheets: the gear pair (base radii, ratio, mesh stiffness),
        nominal inertias and friction. Its backlash and friction are the starting values, nothing more.
    encoders : str, optional
        ``"motor+load"`` (the default when the log has ``theta2``) or ``"motor"`` (the motor encoder alone).

    Returns
    -------
    Identification

    Raises
    ------
    InputError
        A train instead of a pair, ``encoders`` not allowed or asking for a column the log lacks, a log
        whose motor does not move or turn back, fewer than :data:`MIN_SWITCHES` gap crossings, flanks that
        never rest in contact (a loop that hunts), columns that cannot be what they say
        (:func:`_check_signals`: period, torque, angle units, load-encoder ratio), or a backlash beyond
        0.5 module (angles not in rad); each one line naming the column.

    Notes
    -----
    *Both encoders* (gap-crossing geometry). The relative displacement ``s = r_b1 theta1 - r_b2 theta2``
    rests at ``+b + F/k`` while the front flanks carry the load and at ``-b + F/k`` on the back flanks, with
    any encoder zero adding a constant. Half the distance between the mean plateaus, each corrected for the
    mesh deflection ``F / k`` (``F`` from the motor's torque balance, ``k`` the model's mesh stiffness), is
    ``b``, whatever the zero; its interval combines the scatter of the plateaus (Student t), the
    quantisation of one reading per plateau and 30 % of the deflection correction. It needs no friction
    model and no simulation.

    *Motor encoder alone* (output error). Where the torque the mesh takes from the motor changes sign the
    motor crosses the gap alone, with only its own inertia; each such crossing is re-simulated from the
    logged torque with the exact piecewise-linear plant (stick-slip friction) and fitted to the motor
    encoder by SciPy's bounded least squares, free: ``b`` and the motor's initial angle and speed, started
    from a profiled grid over ``b`` (a crossing's timing makes local minima). ``b`` is the mean over the
    crossings; its interval is the Student t interval of their scatter, a floor for the motor encoder's
    quantisation, and how far ``b`` moves when the crossings are refitted with the friction and inertias at
    the ends of their own intervals (the motor's share of the inertia within
    :data:`MOTOR_INERTIA_TOLERANCE`, the viscous split at either extreme).

    *Friction and inertias*: a regression of the torque balances on smoothed difference quotients (the total
    balance ``u = J1 theta1'' + d1 theta1' + T_c1 sgn + (J2 theta2'' + ...) / N`` while the shafts move as
    one in contact, and with both encoders the motor's and the load's own balances in free flight inside
    the gap), Karnopp's stick-slip law (samples near a standstill are left out), with the model's values as
    a weak prior so that what the log cannot separate stays at the model's. Contact alone gives the lumped
    values on the motor shaft; how the Coulomb friction splits between the shafts (whether the load sticks
    or coasts while the motor crosses) comes from fits of :data:`SPLIT_WINDOWS` re-simulated crossings that
    leave the split free. With the motor encoder alone the motor's own inertia stays the model's.

    *Intervals, and what the log does not identify* (``not_identified``, one warning naming each quantity
    and why). Residuals of a closed-loop log are correlated (a plateau that drifts, a loop that hunts), so no
    interval assumes independent samples: b's interval with both encoders is at least the Student t interval
    of batch means of the plateau pairs (:data:`BATCHES` runs in time order), plus one count of ``s`` (a flank
    resting between two counts reads the same one at every visit); the friction and inertias take the larger
    of the model-based and a cluster-robust sandwich covariance (clusters: runs of consecutive samples, i.e.
    one motion in contact, one free flight), and a floor for what the idealised laws cannot represent
    (:data:`SYSTEMATIC_FLOOR`) plus, for a friction, the level below which the log does not see it (its torque 0.1 %
    of the log's RMS torque, a viscous one at the RMS motor speed). The re-simulated crossings' RMS misfit, as a
    displacement along the line of action, is the gate (calibrated against b, not against the noise: what matters
    is whether the misfit could move b): with the motor encoder alone it is added to b's interval as a systematic
    error, and beyond :data:`MISFIT_SHARE` of b, or with a 95 % half-width beyond :data:`MAX_RELATIVE_HALF_WIDTH` of
    b, b is *not identified* (its interval 0 to 0.5 module, and ``--write-model`` refuses); with both encoders
    b does not depend on it, and beyond :data:`MISFIT_SHARE` of b the friction and inertias are not
    identified; nor, where the re-simulated motor misses its encoder inside the gap by more than
    :data:`GAP_MISS_SHARE` of b (:func:`_gap_misfit`: an RMS over windows that are mostly contact hides a motor
    that stalls mid-gap), are the inertias and the motor's friction. A parameter at its bound (an inertia at
    the model's / 1000) is the model's value with the model's range; one whose variance stays above
    :data:`PRIOR_SHARE` of the prior's is the prior's; with
    the motor encoder alone ``J1`` and the viscous and Coulomb split are named not identified (their
    intervals span every split). The log is checked first (:func:`_check_signals`): a period, torque, angle
    scale or load-encoder ratio that cannot be the motor's and the load's in SI units is refused, naming the
    column.

    This follows the two routes the literature gives: the gap read off motor and load encoders around
    reversals (Nordin & Gutman's survey, Automatica 38, 2002; the ISO 230-2 reversal value), and an
    output-error fit of the piecewise model where only the motor is measured (Lagerberg & Egardt,
    "Backlash estimation with application to automotive powertrains", IEEE TCST 15, 2007, estimate the
    same from the motor side with a Kalman filter on a rigid-contact model; re-simulating the exact plant
    with its impacts and stick-slip friction is affordable here, needs no linearisation, and keeps the
    bounces that a loop slamming across the gap makes).
    """
    from .catalog import GearModel, load_model
    from .geometry import pair_geometry
    from .plant import build_plant

    lg = _as_arrays(log) if isinstance(log, EncoderLog) else read_log(log)
    _check_log(lg)
    _check_readings(lg)
    if not isinstance(model, GearModel | str | Path):
        raise InputError(f"model = {model!r} is not a model: expected a GearModel, a catalog name or a TOML file's "
                         f"path", field="model")
    mdl = model if isinstance(model, GearModel) else load_model(model)
    if mdl.n_stages != 1:
        raise InputError(f"{mdl.name}: a train of {mdl.n_stages} stages; identify handles a gear pair (one stage)",
                         field="model")
    if encoders is None:
        encoders = "motor+load" if lg.theta2 is not None else "motor"
    if encoders not in ENCODERS:
        raise InputError(f"encoders = {encoders!r} is not allowed: expected one of {', '.join(ENCODERS)}",
                         field="encoders")
    if encoders == "motor+load" and lg.theta2 is None:
        raise InputError(f"{lg.name}: missing column 'theta2' (load encoder) for --encoders motor+load: give the "
                         f"load encoder's column or use --encoders motor", field="theta2")
    nominal = build_plant(mdl)
    notes: list[str] = []
    if lg.jitter[1] > 0.0:
        notes.append(f"the time stamps jitter by {lg.jitter[0] * 1e6:.3g} us RMS (at most {lg.jitter[1] * 1e6:.3g} us, "
                     f"{lg.jitter[1] / lg.sample_time:.1%} of the period) around a fixed period: read as samples at "
                     f"{lg.sample_time:.6g} s, the torque held over each")
    if encoders == "motor+load" and not mdl.sensors.load_encoder:
        notes.append(f"{mdl.name} says the servo has no load encoder ([sensors] load_encoder = false), but the log "
                     f"has a theta2 column: identified with both encoders (--encoders motor ignores it)")
    if lg.theta2 is not None:
        lg, flipped = _load_encoder_direction(lg)
        if flipped:
            notes.append("the load encoder counts against the motor's direction (another convention than gearctl's, "
                         "where r_b1 theta1 - r_b2 theta2 is the gap): read as -theta2")
    p = _Problem(lg, nominal, encoders, mdl.pair.module)
    _check_motion(p)
    # a load encoder that never leaves the motor's line (s within the noise: no gap crossing) is said first
    pos_unmatched: str | None = None  # (both encoders) why b is not identified, where the flanks move with the angle
    episodes = _episodes(p) if encoders == "motor+load" else None
    _check_signals(p, mdl.servo.torque_limit)
    N = p.N
    m = p.m
    mean, sd = _prior(nominal, p.ubar, m.w, N)
    lower = np.array([1e-3 * nominal.J1, 1e-3 * nominal.J2, 0.0, 0.0, 0.0, 0.0])
    from scipy.ndimage import minimum_filter1d

    mv1 = _Encoder.moving(m.w, m.v_thr, p.W)
    sg1 = np.sign(m.w)
    if encoders == "motor+load":
        ld = p.l
        assert ld is not None
        assert episodes is not None
        c0, b0, eps = episodes
        if len(eps) - 1 < MIN_SWITCHES:
            raise _no_switch(p, max(len(eps) - 1, 0), "changes of the flank in contact")
        mv2 = _Encoder.moving(ld.w, ld.v_thr, p.W)
        # the total balance in steady contact: inside a plateau, clear of its ends by the bounces and the filter
        steady = np.zeros(p.n, bool)
        for i0, i1, _ in eps:
            steady[i0 + p.settle + p.W // 2:max(i0 + p.settle + p.W // 2, i1 - p.W // 2)] = True
        both = mv1 & mv2 & steady
        # in contact the shafts move as one: the motor's (finer) signals for both, so that contact data say
        # nothing about the split between the shafts (the gap's free flights and the prior do)
        A_c = np.column_stack([m.a, m.a / N**2, m.w, m.w / N**2, sg1, sg1 / N])[both]
        s = nominal.rb1 * lg.theta1 - nominal.rb2 * lg.theta2
        inside = minimum_filter1d((np.abs(s - c0) < 0.6 * b0).astype(np.int8), p.Wg + 2, mode="nearest") > 0
        g1 = inside & _Encoder.moving(m.wg, m.vg_thr, p.Wg)
        g2 = inside & _Encoder.moving(ld.wg, ld.vg_thr, p.Wg)
        z = np.zeros(int(g1.sum()))
        A_g = np.column_stack([m.ag[g1], z, m.wg[g1], z, np.sign(m.wg[g1]), z])
        z2 = np.zeros(int(g2.sum()))
        A_l = np.column_stack([z2, ld.ag[g2], z2, ld.wg[g2], z2, np.sign(ld.wg[g2])])
        e = np.eye(len(PARAMS))
        blocks: list[Block] = [(A_c, p.uc[both], float(p.W), _contact_noise(m, N), np.flatnonzero(both))]
        floors = [0.0]
        if g1.sum() >= 10:
            blocks.append((A_g, p.ug[g1], float(p.Wg + 2), _noise_cov(((e[0], m.noise_g[0]), (e[2], m.noise_g[1]))),
                           np.flatnonzero(g1)))
            floors.append(0.0)
        if g2.sum() >= 10:
            noise_l = _noise_cov(((e[1], ld.noise_g[0]), (e[3], ld.noise_g[1])))
            blocks.append((A_l, np.full(int(g2.sum()), p.tl), float(p.Wg + 2), noise_l, np.flatnonzero(g2)))
            # the load's free-flight rows are raw second differences of its encoder: where the load coasts at a steady
            # speed most of them read 0 counts, and the robust scale of the block's residuals falls onto those rows.
            # Every row with a count of acceleration was then cut as an outlier (beyond five times that scale), J2 went
            # to its bound and T_c2 to T_L with a tight interval (T_L = 0.045, T_c2 = 0.05 N m: the load coasted one
            # way where T_c2 matched T_L exactly), and without a load torque the rows left said d2 theta2' + T_c2 sgn =
            # 0: an outside user's heavy viscous load (J2 / d2 = 11.5 s) gave d2 6.9e-9 N m s/rad [0, 4.1e-7] against a
            # true 1e-3, unflagged, the total viscous torque 4x low and traded against Coulomb friction where there is
            # none. The block's noise is held at least at what the encoder's noise (quantisation included) puts into
            # its rows at the model's values, sqrt(theta0^T E theta0)
            floors.append(math.sqrt(max(float(mean @ noise_l @ mean), 0.0)))
        theta, cov = _regress(blocks, mean, sd, lower, floors)
        cov = _with_prior_pull(blocks, mean, sd, lower, theta, cov, floors)
        # an inertia at its bound leaves the other holding J1 + J2/N^2, and the torque the mesh takes from the motor,
        # u - J1 theta1'' - ..., loses the load's inertia: with a load torque the rests on a flank were then not found
        # (h3: "no rest on the front flank", T_L = 0.045 near T_c2 = 0.05 N m). With a load torque the flank rests and
        # the crossings' start are read with the model's inertias wherever a fitted one sits at its bound (without
        # one, as before)
        at_bound = bool(theta[0] <= 1.01 * lower[0] or theta[1] <= 1.01 * lower[1])
        theta_tx = theta.copy()
        if at_bound and p.tl != 0.0:
            theta_tx[:2] = mean[:2]
        b, ci, centre, est, times, _, rests, (pos_note, pos_unmatched) = _plateau_backlash(p, theta_tx, eps)
        if pos_note is not None:
            notes.append(pos_note)
        if b < SPAN_SHARE * b0:
            # s reaches +-b0 (a median removes the impacts' spikes): plateaus well inside are not resting contact
            raise InputError(f"{lg.name}: column theta2: {len(eps) - 1} gap crossings, but the flanks never rest "
                             f"in contact (the plateaus of r_b1 theta1 - r_b2 theta2 give b = {b * 1e6:.3g} um, its "
                             f"half-span is {b0 * 1e6:.3g} um): the loop rattles in the gap or hunts; record moves "
                             f"with dwells in contact", field="theta2")
        wins = _gap_windows(p, eps, theta_tx)
        # the share of the Coulomb friction on each shaft: the free flights may be too short to tell (a loop
        # that crosses fast and bounces); whether the load sticks or coasts in the re-simulated crossings does
        J_eq, d_eq, teq = _lumped(theta, N)
        n_split = 0
        if teq > 1e-3 * float(np.sqrt(np.mean(p.ubar**2))) and wins:
            sub = _spread_evenly(wins, SPLIT_WINDOWS)
            phis = np.array([_fit_window(p, w, theta, b, free=("phi",), phi=float(theta[4] / teq), offset=centre).phi
                             for w in sub])
            phi = float(np.median(phis))
            # the spread of a few crossings' shares: a 95 % half-width of 1.96 sd_phi is the Student t interval's
            # for phis.size - 1 degrees of freedom once sd_phi is scaled by t95 / 1.96 (3.18 / 1.96 for 4 crossings)
            sd_phi = (float(phis.std(ddof=1)) / math.sqrt(phis.size) * _t95(phis.size - 1) / 1.96 if phis.size > 1
                      else 0.5)
            # the crossings are refitted with the motor's inertia held: in free flight J1 theta1'' and tc1 sgn
            # trade against each other, so J1's own uncertainty moves the split too (h3's simulator: a PD loop
            # crossing at a steady acceleration, J1 not identified, gave the motor's Coulomb friction 1.46 mN m
            # with a 9 % interval where the truth was 0). The split is refitted with J1 at the ends of its 95 %
            # interval as it is reported (J1 + J2/N^2 kept; with the prior's range where the log hardly constrains
            # J1), the larger shift added as a systematic error
            hw_J1 = 1.96 * math.sqrt(max(cov[0, 0], 0.0))
            ends_J1 = [theta[0] - hw_J1, theta[0] + hw_J1]
            if cov[0, 0] > PRIOR_SHARE * sd[0] ** 2:
                ends_J1 = [min(ends_J1[0], mean[0] - 1.96 * sd[0]), max(ends_J1[1], mean[0] + 1.96 * sd[0])]
            shift_phi = 0.0
            for J1x in ends_J1:
                J1x = min(max(J1x, lower[0]), theta[0] + 0.9 * (J_eq - theta[0]))
                if J1x == theta[0]:
                    continue
                thx = _split(theta, N, kappa=J1x / theta[0])
                phx = np.array([_fit_window(p, w, thx, b, free=("phi",), phi=phi, offset=centre).phi for w in sub])
                shift_phi = max(shift_phi, abs(float(np.median(phx)) - phi))
            sd_phi = math.hypot(sd_phi, shift_phi / 1.96)
            g = np.array([0, 0, 0, 0, 1.0, 1.0 / N])
            var_t = float(g @ cov @ g)
            theta = _split(theta, N, phi=phi)
            cov = cov.copy()
            cov[4, 4] = phi**2 * var_t + teq**2 * sd_phi**2
            cov[5, 5] = N**2 * ((1 - phi) ** 2 * var_t + teq**2 * sd_phi**2)
            n_split = len(sub)
        fit_wins = _spread_evenly(wins, MAX_PLOT_WINDOWS)
        fits = [_fit_window(p, w, theta, b, offset=centre) for w in fit_wins]
        switches = len(eps) - 1
        ci_fr = {k: 1.96 * math.sqrt(max(cov[i, i], 0.0)) for i, k in enumerate(PARAMS)}
        method = (f"gap-crossing geometry: b is half the distance between the plateaus of r_b1 theta1 - r_b2 theta2 "
                  f"on the front and the back flank ({sum(1 for e in eps if e[2] > 0)} and "
                  f"{sum(1 for e in eps if e[2] < 0)} plateaus), each corrected for the mesh deflection F/k; "
                  f"friction and inertias from the torque balances (total balance while both shafts move in steady "
                  f"contact, Hann-smoothed differences over {p.W} samples; each shaft's own in free flight inside "
                  f"the gap, raw differences) with the model's values as a weak prior" +
                  (f", the share of the Coulomb friction on each shaft from fits of {n_split} re-simulated crossings"
                   if n_split else "") +
                  f"; motion around {len(fits)} crossings re-simulated with the exact piecewise-linear plant")
        offset = centre
    else:
        wins, steady = _torque_windows(p)
        if len(wins) < MIN_SWITCHES:
            raise _no_switch(p, len(wins), "sign changes of the torque the mesh takes from the motor")
        excl = np.zeros(p.n, bool)
        for w in wins:
            excl[max(0, w.k0 - p.W):min(p.n, w.k1 + p.W)] = True
        rows = mv1 & ~excl & (minimum_filter1d(steady.astype(np.int8), p.W, mode="nearest") > 0)
        if rows.sum() < 10 * len(PARAMS):
            raise InputError(f"{lg.name}: column theta1: only {int(rows.sum())} samples of steady motion in "
                             f"contact; the friction cannot be estimated (record longer moves)", field="theta1")
        A_c = np.column_stack([m.a, m.a / N**2, m.w, m.w / N**2, sg1, sg1 / N])[rows]
        theta, cov = _regress([(A_c, p.uc[rows], float(p.W), _contact_noise(m, N), np.flatnonzero(rows))], mean, sd,
                              lower)
        # the motor's own inertia is the model's (see sd_kappa below), J2 what is left of the J1 + J2/N^2 the log sees:
        # the regression's split is the prior's pull (a reviewer's J1 12 % off the model's, with an interval of the
        # model's tolerance about it that left the model's value out)
        if 0.0 < mean[0] < _lumped(theta, N)[0]:
            theta = _split(theta, N, kappa=float(mean[0] / theta[0]))
        # contact sees only the lumped values: the share of the Coulomb friction on each shaft comes from fits of
        # a few crossings that leave it free
        J_eq, d_eq, teq = _lumped(theta, N)
        gJ = np.array([1.0, 1.0 / N**2, 0, 0, 0, 0])
        gd = np.array([0, 0, 1.0, 1.0 / N**2, 0, 0])
        gT = np.array([0, 0, 0, 0, 1.0, 1.0 / N])
        var = {k: float(g @ cov @ g) for k, g in (("J_eq", gJ), ("d_eq", gd), ("T_eq", gT))}
        u_rms = float(np.sqrt(np.mean(p.ubar**2)))
        split = teq > 1e-3 * u_rms
        b_nom = nominal.backlash if nominal.backlash > 0 else 1e-3 * p.module
        sub = _spread_evenly(wins, SPLIT_WINDOWS)
        b_start, phi = _profile_start(p, sub, theta, b_nom, split)
        sfits = [_fit_window(p, w, theta, b_start, free=("b", "phi") if split else ("b",), phi=phi) for w in sub]
        if split:
            theta = _split(theta, N, phi=float(np.median([f.phi for f in sfits])))
        b_start = float(np.median([f.b for f in sfits]))
        phi = theta[4] / teq if split else 0.0
        sd_phi = float(np.std([f.phi for f in sfits], ddof=1)) / math.sqrt(len(sfits)) if split and len(sfits) > 1 \
            else 0.0
        # the motor's own inertia is the model's (data sheet and drawing): its free flights seen through the motor
        # encoder alone are too short and too often cut by impacts to weigh it; its tolerance enters the interval
        sd_kappa = MOTOR_INERTIA_TOLERANCE / 1.96
        fit_wins = _spread_evenly(wins, MAX_WINDOWS)
        fits = [_fit_window(p, w, theta, b_start, free=("b",)) for w in fit_wins]
        costs = np.array([f.res_motor for f in fits])
        good = [i for i, f in enumerate(fits) if f.res_motor <= 5 * float(np.median(costs)) and
                1.01e-8 < f.b < 0.98 * min(0.5 * p.module, 0.0099)]
        if len(good) < MIN_SWITCHES:
            raise _no_switch(p, len(good), "crossings the re-simulation fits")
        fit_wins = [fit_wins[i] for i in good]
        fits = [fits[i] for i in good]
        est = np.array([f.b for f in fits])
        times = np.array([w.t_switch for w in fit_wins])
        b = float(est.mean())
        stat = _t95(est.size - 1) * float(est.std(ddof=1)) / math.sqrt(est.size)
        # crossings at the same positions share one quantisation error of the motor reading: a floor
        q_b = nominal.rb1 * m.q / math.sqrt(12.0)
        spreads = {k: 1.96 * math.sqrt(max(v, 0.0)) for k, v in var.items()}
        spreads.update(kappa=1.96 * sd_kappa, phi=1.96 * sd_phi)
        probe = _spread_evenly(list(range(len(fits))), 3)
        sys_half, shifts = _systematic(p, [fit_wins[i] for i in probe], [fits[i] for i in probe], theta, spreads)
        half = math.sqrt(stat**2 + (1.96 * q_b) ** 2 + sys_half**2)
        ci = (b - half, b + half)
        switches = len(wins)
        cov = cov.copy()
        cov[0, 0] = (theta[0] * sd_kappa) ** 2
        cov[1, 1] = N**4 * (var["J_eq"] + cov[0, 0])
        cov[4, 4] = phi**2 * var["T_eq"] + teq**2 * sd_phi**2
        cov[5, 5] = N**2 * ((1 - phi) ** 2 * var["T_eq"] + teq**2 * sd_phi**2)
        ci_fr = {k: 1.96 * math.sqrt(max(cov[i, i], 0.0)) for i, k in enumerate(PARAMS)}
        # the viscous split is not seen from the motor alone: anywhere between all on one shaft and all on the other
        d_hi = d_eq + spreads["d_eq"]
        ci_fr["d1"] = max(theta[2], d_hi - theta[2])
        ci_fr["d2"] = max(theta[3], N**2 * d_hi - theta[3])
        biggest = max(shifts, key=lambda k: shifts[k]) if shifts else ""
        method = (f"output-error fit of the re-simulated piecewise-linear plant (stick-slip friction) to the motor "
                  f"encoder around {len(fits)} of {len(wins)} gap crossings (SciPy bounded least squares; free: b "
                  f"and the motor's initial angle and speed per crossing" +
                  (f"; the share of the Coulomb friction on each shaft from {len(sub)} crossings" if split else "") +
                  f"); lumped inertia and friction from the torque balance in steady contact (Hann-smoothed "
                  f"differences, {p.W} samples, the model's values as a weak prior), the motor's own inertia the "
                  f"model's within {MOTOR_INERTIA_TOLERANCE:.0%}; the interval adds how far b moves with them "
                  f"(largest: {biggest}, {shifts.get(biggest, 0.0) * 1e6:.3g} um)")
        offset = 0.0
    rms, rm, rl = _residuals(p, fits)
    warnings = list(notes)
    lag, corr = torque_lag(lg)
    rb2 = nominal.rb2
    b_max = min(MAX_BACKLASH_MODULES * p.module, 0.0099)
    if b > b_max:
        col = "theta1 or theta2" if encoders == "motor+load" else "theta1"
        raise InputError(f"{lg.name}: column {col}: the log gives a backlash of {b:.4g} m, more than a model allows "
                         f"({MAX_BACKLASH_MODULES:g} module = {b_max:.4g} m): expected angles in rad", field="theta1")
    lo, hi = max(ci[0], 0.0), ci[1]
    names = {"J1": "J1", "J2": "J2", "d1": "viscous1", "d2": "viscous2", "tc1": "coulomb1", "tc2": "coulomb2"}
    val = {names[k]: float(theta[i]) for i, k in enumerate(PARAMS)}
    cis = {names[k]: (max(float(theta[i]) - ci_fr[k], 0.0), float(theta[i]) + ci_fr[k]) for i, k in enumerate(PARAMS)}
    # what the idealised friction and contact laws cannot represent (another friction law, a compliant shaft):
    # a floor under each interval, relative, and for the friction the level below which it is not seen
    seen = {"d1": p.d_floor[0], "d2": p.d_floor[1], "tc1": p.tc_floor[0], "tc2": p.tc_floor[1]}
    for k in PARAMS:
        key = names[k]
        floor = SYSTEMATIC_FLOOR[k] * abs(val[key]) + seen.get(k, 0.0)
        cis[key] = (max(min(cis[key][0], val[key] - floor), 0.0), max(cis[key][1], val[key] + floor))
    # what the log does not identify: named, with the reason, and an interval that says so (not a tight one)
    ni: dict[str, str] = {}
    if encoders == "motor+load" and max(rests) < 2:
        # one rest on each flank: nothing shows how far the rests scatter (a load that floats off its flank, a rest
        # cut short), and the interval held only the quantisation and the deflection: h2's simulator, a frictionless
        # load under a loop with a sample's delay, gave 28.6 um [27.9, 29.3] for a true 30
        ni["backlash"] = (f"one rest on each flank: how far the rests scatter is not seen (b = {b * 1e6:.3g} um from "
                          f"a single pair of plateaus); record more reversals with dwells in contact")
        lo, hi = 0.0, b_max
    elif encoders == "motor+load" and pos_unmatched is not None:
        ni["backlash"] = pos_unmatched
        lo, hi = 0.0, b_max
    prior = {names[k]: (max(float(mean[i] - 1.96 * sd[i]), 0.0), float(mean[i] + 1.96 * sd[i]))
             for i, k in enumerate(PARAMS)}

    def widen(key: str, why: str, *, to_model: bool = False) -> None:
        ni.setdefault(key, why)
        if to_model:
            val[key] = float(mean[PARAMS.index([k for k, v in names.items() if v == key][0])])
            cis[key] = prior[key]
        else:
            cis[key] = (min(cis[key][0], prior[key][0], val[key]), max(cis[key][1], prior[key][1], val[key]))

    for i, k in enumerate(PARAMS):
        key = names[k]
        if i < 2 and theta[i] <= 1.01 * lower[i]:
            widen(key, "at the fit's bound (the model's / 1000): the model's value and 95 % range reported",
                  to_model=True)
        elif cov[i, i] > PRIOR_SHARE * sd[i] ** 2 and not (encoders == "motor" and k in ("d1", "d2", "tc1", "tc2")):
            widen(key, f"the log hardly constrains it: variance {cov[i, i] / sd[i] ** 2:.0%} of the prior's")
    for i, (key, other) in enumerate((("J1", "J2"), ("J2", "J1"))):
        # one inertia at its bound: the other took the whole J1 + J2/N^2 the log sees (a reviewer's J1 41 % high with
        # a 2 % interval, the load's at the bound), so it is not identified either
        if theta[1 - i] <= 1.01 * lower[1 - i]:
            widen(key, f"{other} is at the fit's bound: {key} holds what the log sees of J1 + J2/N^2")
    for key, other in (("J1", "J2"), ("J2", "J1")):
        # one inertia not identified: the other holds the rest of the J1 + J2/N^2 the log sees, and what the first
        # missed with it (another simulator's log: J1 flagged at 0.12 of the truth, J2 32 % high with a 12 % interval
        # that missed the truth, unflagged)
        if other in ni and key not in ni:
            widen(key, f"{other} is not identified: {key} holds the rest of the J1 + J2/N^2 the log sees")
    if encoders == "motor+load" and p.tl != 0.0 and theta[1] <= 1.01 * lower[1]:
        # the load's free flights did not show its inertia: its own balance J2 theta2'' + d2 theta2' + T_c2 sgn = T_L
        # was met by its friction alone, which then holds what the acceleration should (T_c2 went to T_L)
        for key in ("viscous2", "coulomb2"):
            widen(key, "J2 is at the fit's bound: the load's friction holds what its acceleration should in its "
                       "balance with the load torque")
    if encoders == "motor":
        ni.setdefault("J1", f"the model's within {MOTOR_INERTIA_TOLERANCE:.0%}: the motor encoder sees J1 + J2/N^2")
        # J2 = N^2 (J_eq - J1): a motor inertia off the model's by more than its tolerance moves J2 N^2 times as much
        ni.setdefault("J2", f"from J1 + J2/N^2 with J1 the model's within {MOTOR_INERTIA_TOLERANCE:.0%}: a motor "
                            f"inertia further off moves J2 N^2 = {N**2:.4g} times as much")
        for key in ("viscous1", "viscous2"):
            ni.setdefault(key, "the motor encoder sees d1 + d2/N^2: the interval spans every split")
        teq_hi = teq + spreads["T_eq"]
        cis["coulomb1"] = (0.0, max(teq_hi, val["coulomb1"]))
        cis["coulomb2"] = (0.0, max(N * teq_hi, val["coulomb2"]))
        for key in ("coulomb1", "coulomb2"):
            ni.setdefault(key, "the motor encoder sees tc1 + tc2/N: the interval spans every split")
    # lack of fit of the re-simulated crossings, as a displacement along the line of action [m]
    misfit = rms * rb2 if math.isfinite(rms) else 0.0
    if encoders == "motor":
        # the motor-only b rests on the re-simulation: its misfit enters the interval as a systematic error, and a
        # misfit beyond MISFIT_SHARE of b leaves b not identified (its interval: anything a model allows). The RMS
        # misfit is a standard deviation, the other terms 95 % half-widths: it enters as 1.96 of it (added as it
        # was, h2's simulator with LuGre friction, whose bristles let the motor travel on after it meets a stuck
        # load, gave b 27-40 % high on 6 of 6 logs with intervals that missed: 56.6 um [43.8, 69.5] for 40)
        half = math.sqrt(max(b - lo, hi - b) ** 2 + (1.96 * misfit) ** 2)
        lo, hi = max(b - half, 0.0), b + half
        if misfit > MISFIT_SHARE * b:
            ni["backlash"] = (f"the re-simulated crossings miss the motor encoder by {misfit * 1e6:.3g} um RMS along "
                              f"the line of action, more than {MISFIT_SHARE:.0%} of b = {b * 1e6:.3g} um: the motion "
                              f"does not show the free travel as the model would (record with the load encoder)")
            for key in ("J2", "viscous1", "viscous2", "coulomb1", "coulomb2"):
                widen(key, "the re-simulation does not fit the log")
        elif half > MAX_RELATIVE_HALF_WIDTH * b:
            ni["backlash"] = (f"its 95 % half-width {half * 1e6:.3g} um is more than {MAX_RELATIVE_HALF_WIDTH:.2g} of "
                              f"b = {b * 1e6:.3g} um: the crossings' fits disagree or move with the friction, beyond "
                              f"where the interval's linearisation holds (record with the load encoder)")
        elif (off := _disagreeing(est)) > DISAGREE_SHARE * est.size:
            # a reviewer's 2 kHz log of a frictionless stage: clean crossings at 9.3-9.7 um, six after the load had
            # floated off its flank at 1.9-7.4 um; their mean, 8.2 um [6.8, 9.6], missed the true 10 and was written
            med = float(np.median(est))
            ni["backlash"] = (f"the crossings disagree: {off} of {est.size} give a b more than {DISAGREE_BAND:.0%} "
                              f"from their median {med * 1e6:.3g} um (from {est.min() * 1e6:.3g} to "
                              f"{est.max() * 1e6:.3g} um): a load that floats off its flank between crossings (no "
                              f"friction holds it) or a loop that rattles (record with the load encoder)")
        if "backlash" in ni:
            lo, hi = 0.0, b_max
    elif misfit > MISFIT_SHARE * b:
        warnings.append(f"the re-simulation does not fit the log: the crossings re-simulated with the identified "
                        f"friction and inertias miss it by {misfit * 1e6:.3g} um RMS along the line of action, more "
                        f"than {MISFIT_SHARE:.0%} of b; b, read off the plateaus, does not depend on it; the friction "
                        f"and inertias are not identified (intervals widened to the model's range)")
        for key in ("J1", "J2", "viscous1", "viscous2", "coulomb1", "coulomb2"):
            widen(key, "the re-simulation does not fit the log")
    elif (gap_miss := _gap_misfit(p, fit_wins, fits, offset, b)) > GAP_MISS_SHARE * b:
        # the RMS over whole windows is mostly contact, which the lumped values fit whatever their split: a motor that
        # stalls mid-gap in the re-simulation (h3's 800 Hz log, Stribeck friction on the load: tc1 3.8 mN m against
        # 2, J1 3.1e-5 against 2.2e-4, J2 26 % high, all with tight intervals) missed the gap by 0.55 b, 0.15 b RMS
        why = (f"the re-simulated motor misses the motor encoder inside the gap by {gap_miss * 1e6:.3g} um along the "
               f"line of action (the largest miss in free flight, median over the crossings), more than "
               f"{GAP_MISS_SHARE:.0%} of b = {b * 1e6:.3g} um: the motor's free flight does not follow the identified "
               f"inertias and friction")
        for key in ("J1", "J2", "viscous1", "coulomb1"):
            widen(key, why)
        if n_split:
            # the Coulomb split comes from fits of those re-simulated crossings, and contact sees only tc1 + tc2/N:
            # with the motor's share not identified the load's holds the rest of it (h2's 5 kHz triangle log: the
            # motor's 5.5 mN m flagged, the load's 0.178 N m [0.167, 0.189] unflagged against a true 0.2 and 0)
            widen("coulomb2", why + "; the load's Coulomb friction holds the rest of the tc1 + tc2/N the log sees, "
                              "split between the shafts by those crossings")
    if lag:
        rows = f"{abs(lag)} sample{'s' if abs(lag) > 1 else ''}"
        when = (f"acts {rows} after its row (logged before it acts)" if lag > 0
                else f"acted {rows} before its row (logged late)")
        warnings.append(f"the torque column looks {abs(lag)} row{'s' if abs(lag) > 1 else ''} off the motion: the "
                        f"motor's acceleration follows the "
                        f"torque as if each row's {when} (correlation {corr[lag]:.2f} against {corr[0]:.2f} as "
                        f"logged); "
                        f"the torque balances are not identified (intervals widened to the model's range)"
                        + (" and neither is b, which the motor encoder alone reads off the re-simulation"
                           if encoders == "motor" else "; b, read off the plateaus, does not depend on it")
                        + f": shift the torque column {'down' if lag > 0 else 'up'} {abs(lag)} row"
                        + ("s" if abs(lag) > 1 else "") + " and identify again")
        for key in ("J1", "J2", "viscous1", "viscous2", "coulomb1", "coulomb2"):
            widen(key, "the torque column is a sample off the motion")
        if encoders == "motor" and "backlash" not in ni:
            ni["backlash"] = "the torque column is a sample off the motion, and the re-simulation rests on it"
            lo, hi = 0.0, b_max
    if ni:
        order = sorted(ni, key=lambda k: k != "backlash")  # the backlash first
        warnings.append("not identified from this log: " + "; ".join(f"{k} ({ni[k]})" for k in order
                                                                      if not ni[k].startswith(("the re-simulation",
                                                                                               "the torque column"))))
        if warnings[-1] == "not identified from this log: ":
            warnings.pop()
    nom = {"backlash": nominal.backlash, "J1": nominal.J1, "J2": nominal.J2, "viscous1": nominal.d1,
           "viscous2": nominal.d2, "coulomb1": nominal.tc1, "coulomb2": nominal.tc2}
    geo = pair_geometry(mdl.pair)
    return Identification(
        backlash=b, backlash_ci=(lo, hi), lost_motion=2 * b / rb2, lost_motion_ci=(2 * lo / rb2, 2 * hi / rb2),
        friction={k: val[k] for k in ("viscous1", "viscous2", "coulomb1", "coulomb2")},
        friction_ci={k: cis[k] for k in ("viscous1", "viscous2", "coulomb1", "coulomb2")},
        inertia={"J1": val["J1"], "J2": val["J2"]}, inertia_ci={"J1": cis["J1"], "J2": cis["J2"]}, nominal=nom,
        encoders=encoders, rms_residual=rms, residual_motor=rm, residual_load=rl, estimates=est,
        estimate_times=times, switches=switches, offset=offset, sample_time=lg.sample_time, samples=lg.n,
        method=method, model=mdl.name, log=lg.name, windows=_windows_out(p, fit_wins, fits, offset),
        gear_ratio=N, base_radius=tuple(geo.base_radius), warnings=tuple(warnings),  # type: ignore[arg-type]
        not_identified=ni, inertia_sum=float(theta[0] + theta[1] / N**2),
    )


# --- the identified model as a model file ------------------------------------------------------------------------


def _unidentified(result: Identification) -> list[str]:
    """One line per quantity the log did not identify, for the written model's header and ``[source]`` notes."""
    fit = "the fit's best value, kept: it holds the sums the log sees"
    kept = {"J1": "the model's value, its data sheet's", "J2": "from the sum J1 + J2/N^2 the log sees, with J1 as "
            "written"}  # (_written_inertias)
    return [f"Not identified from this log ({kept.get(k, fit)}): {k}: {why}"
            for k, why in result.not_identified.items()]


def _written_inertias(result: Identification) -> tuple[float, float]:
    """The shaft inertias a written model gets [kg m^2]: the identified ones; where either is not identified, the
    motor's from the model (its data sheet) unless the log identified it, and the load's from the sum the log sees
    (:attr:`Identification.inertia_sum`), ``J2 = N^2 (J1 + J2/N^2 - J1)``; where that leaves less than a thousandth of
    the model's load, the model's split scaled to the sum. The sum is kept in every case.

    Why: the fit's split of an unidentified pair of inertias is the prior's pull and the noise's, not the log's. A
    reviewer's written models had the motor 36 % low and the load 19 % high (model 4) or the motor 41 % high beside
    the model's load (the sum 29 % high): the dead-zone inverse on them positioned worse than the PID (ISO A 1.29e-2
    rad against 1.11e-2), and with the model's inertias 2.0e-5.
    """
    J1, J2 = float(result.inertia["J1"]), float(result.inertia["J2"])
    ni = result.not_identified
    if "J1" not in ni and "J2" not in ni:
        return J1, J2
    N2 = result.gear_ratio ** 2
    # what the log sees in contact: the fit's own sum (an inertia at its bound is reported at the model's value, and the
    # reported pair would count it twice: a reviewer's written sums came out 26 % and 74 % high)
    total = result.inertia_sum if math.isfinite(result.inertia_sum) else J1 + J2 / N2
    J1n, J2n = float(result.nominal["J1"]), float(result.nominal["J2"])
    J1w = J1 if "J1" not in ni else J1n
    J2w = N2 * (total - J1w)
    if J2w < 1e-3 * J2n:  # the log sees less than that motor inertia: the model's split, scaled to the sum
        scale = total / (J1n + J2n / N2)
        return J1n * scale, J2n * scale
    return J1w, J2w


def identified_model(result: Identification, model: Any) -> dict[str, dict[str, Any]]:
    """A complete model document (the tables of a model file): ``model`` with the identified values.

    The backlash, the friction of both shafts and the inertias are the identified ones (inertias not identified:
    :func:`_written_inertias`, the motor's from the model, the load's from the sum the log sees); the inertia a
    motor or load adds is the shaft inertia less its gear's (where that would be negative, the
    gear's inertia is set to the shaft's and nothing is added). A Coulomb friction whose 95 % interval
    reaches zero is written as zero: it cannot be told from none, and a vanishing stick-slip friction
    only makes the simulator locate stick and slip events. Everything else is the model's (also the
    ``[source]``'s ``url`` and ``doi``), and the ``[source]`` names the log and the method.

    Parameters
    ----------
    result : Identification
    model : GearModel, str or Path
        The model the identification started from (a pair).
    """
    from .catalog import PAIR_TABLES, GearModel, load_model
    from .geometry import pair_geometry
    from .params import Servo

    mdl = model if isinstance(model, GearModel) else load_model(model)
    pair = mdl.pair
    doc: dict[str, dict[str, Any]] = {}
    src = dict(mdl.source)
    notes = (f"Identified by gearctl identify from the log {result.log} ({result.encoders} encoders, {result.samples} "
             f"samples at {result.sample_time:g} s, {result.switches} gap crossings): backlash {result.backlash:.6g} m "
             f"(95 % CI {result.backlash_ci[0]:.6g} - {result.backlash_ci[1]:.6g} m), RMS residual "
             f"{result.rms_residual:.3g} rad. Method: {result.method}. Model before identification: {mdl.name}"
             + "".join(f". {line}" for line in _unidentified(result))
             + (f"; its notes: {src['notes']}" if src.get("notes") else ""))
    # the source's other keys (url, doi) are the user's and kept as given
    doc["source"] = {"citation": f"gearctl identify ({result.log}) on {mdl.name}: {src.get('citation', '')}",
                     **({"table": src["table"]} if "table" in src else {}), "notes": notes,
                     **{k: v for k, v in src.items() if k not in ("citation", "table", "notes")}}
    for table, (cls, keymap, _) in PAIR_TABLES.items():
        obj = pair if cls.__name__ == "GearPair" else mdl.dynamics
        keys: dict[str, Any] = {}
        for key, field in keymap.items():
            v = getattr(obj, field)
            if v is None:
                continue
            if key.endswith("_deg"):
                v = math.degrees(v)
            if hasattr(v, "value"):  # an enum (contact law)
                v = v.value
            keys[key] = v
        doc[table] = keys
    doc["pair"]["backlash"] = float(result.backlash)
    geo = pair_geometry(pair)
    servo = {f.name: getattr(mdl.servo, f.name) for f in dataclasses.fields(Servo)}
    inertia = _written_inertias(result)
    for j, (gear, add) in enumerate((("gear1", "motor_inertia"), ("gear2", "load_inertia")), start=1):
        J = inertia[j - 1]
        g = geo.inertia[j - 1]
        if J >= g:
            servo[add] = J - g
        else:
            doc[gear]["inertia"] = J
            servo[add] = 0.0
    servo["viscous_friction1"] = float(result.friction["viscous1"])
    servo["viscous_friction2"] = float(result.friction["viscous2"])
    for j in (1, 2):  # a Coulomb friction whose interval reaches zero is none (and costs a simulator stick events);
        key = f"coulomb{j}"  # one not identified (its interval spans every split) keeps the fit's best value
        keep = result.friction_ci[key][0] > 0.0 or key in result.not_identified
        servo[f"coulomb_friction{j}"] = float(result.friction[key]) if keep else 0.0
    doc["servo"] = {k: (v.value if hasattr(v, "value") else (list(v) if isinstance(v, tuple) else v))
                    for k, v in servo.items() if not (isinstance(v, tuple) and not v)}
    doc["sensors"] = {k: v for k, v in dataclasses.asdict(mdl.sensors).items() if v is not None}
    if not mdl.sensors.load_encoder:  # no load encoder: nothing of one is written
        doc["sensors"].pop("load_noise", None)
        doc["sensors"].pop("load_encoder_cpr", None)
    return doc


def write_identified_model(path: str | Path, result: Identification, model: Any) -> Path:
    """Write :func:`identified_model` as a model file and check that it loads.

    The document is checked before anything is written (loaded from a temporary file next to ``path``, then
    renamed into place), so a refused model leaves no file; the folder must exist (it is not created). A link is
    written through; a device or a FIFO (``/dev/null``) is written into, never replaced (as root the rename replaced
    ``/dev/full`` itself with a regular file).

    Parameters
    ----------
    path : str or Path
        The model file to write (``.toml``); a link is written through.
    result : Identification
        What :func:`identify` found.
    model : GearModel, str or Path
        The model the identification started from (a pair; a name or file is loaded); its other values are kept
        (:func:`identified_model`).

    Returns
    -------
    Path
        The file written (a link's target).

    Raises
    ------
    InputError
        If ``path`` is a folder, its folder does not exist or the file cannot be written; if the backlash is not
        identified (:attr:`Identification.not_identified`); or if an identified value lies outside what a model file
        allows (the message names the log the value came from and the key).
    """
    import os

    from .catalog import load_model
    from .files import write_whole

    path = Path(path)
    if path.is_symlink():  # written through the link, as a shell's redirection does
        path = Path(os.path.realpath(path))
    if path.is_dir():
        raise InputError(f"cannot write {path}: it is a folder; expected a file name (OUT.toml)", field="write_model")
    if not path.parent.is_dir():
        what = "is not a folder" if path.parent.exists() else "does not exist (create it first)"
        raise InputError(f"cannot write {path}: {path.parent} {what}", field="write_model")
    if "backlash" in result.not_identified:
        raise InputError(f"{result.log}: not writing {path}: the backlash is not identified from this log "
                         f"({result.not_identified['backlash']})", field="backlash")
    doc = identified_model(result, model)
    text = toml_dumps(doc, header=(f"{path.stem}: written by gearctl identify from {result.log}.",
                                    "SI units, radians inside; degrees only in keys ending _deg.",
                                    *_unidentified(result)))
    def loads(tmp: Path) -> None:  # the identified model must be one gearctl reads (range errors name the key)
        try:
            load_model(tmp)
        except InputError as exc:
            rule = str(exc).split(": ", 1)[-1]
            raise InputError(f"{result.log}: the identified model is not valid, not writing {path}: {rule}",
                             field=exc.field) from None

    try:
        return write_whole(path, text, check=loads)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror}") from None
