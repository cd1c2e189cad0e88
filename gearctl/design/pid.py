"""Position PID with filtered derivative, anti-windup and optional feedforward: the baseline.

The feedforward (on by default) is the rigid train's torque at the acceleration the sample's held torque
must give, with the model's Coulomb friction, and the derivative compares the measurement with the
reference speed sampled and filtered the same way (see :class:`PID`): on the backlash-free benchmark servo
it tracks the 1 Hz sine to 4.4e-7 rad RMS, against 2.0e-4 rad for the same gains without feedforward.

The PID works in load-angle units: with motor-side feedback it regulates ``theta1 / N`` (the motor
encoder scaled by the gear ratio), with load-side feedback ``theta2``. Its output is the motor torque.
Gains are given, or designed with python-control for a requested crossover and phase margin on the
rigid-train model and then checked on the sampled contact-mode model.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..controller import READING_LIMIT, ReferenceLike, check_reading
from ..errors import InputError, short_repr
from ..files import Binding, Layout, build_dataclass, spec_values
from ..units import SAMPLE_TIME, check_choice, check_number, quantity, validate_fields
from .base import Controller, LoopInfo, check_loop_info

if TYPE_CHECKING:
    import control as ct

__all__ = ["PIDGains", "PIDDesign", "LoopSettings", "PID", "design_pid", "KIND", "LAYOUT", "build",
           "LOOP_KEYS", "PID_TABLES", "pid_from_values", "restate", "gap_loop_stable", "gap_loop_pole",
           "gap_limited_bandwidth", "check_readings"]

#: The controller-file kind this module builds (:mod:`gearctl.design.registry`).
KIND = "pid"
#: The integral action's bound, in torque limits: it can hold any torque the motor gives against a feedforward
#: of up to the limit the other way, and a single wild reading (an encoder glitch) cannot wind it up beyond.
INTEGRAL_BOUND = 2.0


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class PIDGains:
    """Parallel PID ``C(s) = kp + ki / s + kd s / (1 + s / (2 pi f_d))`` on the load-angle error.

    Parameters
    ----------
    kp : float
        Proportional gain, 0..1e9 [N m/rad].
    ki : float
        Integral gain, 0..1e12 [N m/(rad s)] (default 0).
    kd : float
        Derivative gain, 0..1e9 [N m s/rad] (default 0).
    derivative_filter_hz : float
        Derivative filter corner ``f_d``, (0, 1e6] [Hz] (default 1000).

    Raises
    ------
    InputError
        For a gain out of its range (named).
    """

    kp: float = quantity(unit="N m/rad", doc="proportional gain", low=0.0, high=1e9)
    ki: float = quantity(unit="N m/(rad s)", doc="integral gain", low=0.0, high=1e12, default=0.0)
    kd: float = quantity(unit="N m s/rad", doc="derivative gain", low=0.0, high=1e9, default=0.0)
    derivative_filter_hz: float = quantity(
        unit="Hz", doc="derivative filter corner", low=0.0, low_open=True, high=1e6, default=1e3
    )

    def __post_init__(self) -> None:
        validate_fields(self)

    def tf(self, *, output: str = "xi1") -> ct.TransferFunction:
        """The continuous PID as a transfer function (error [rad] to torque [N m]), input ``e``, output ``output``.

        Parameters
        ----------
        output : str
            The name of the motor torque, ``xi1`` as a pair's mode models name it (``ct.interconnect``
            connects them by name); a train's mode models name it ``xi0`` (their first input,
            ``linearize_modes(plant).contact.input_labels[0]``): with ``xi1`` the PID's output is left unconnected
            there.

        Raises
        ------
        InputError
            If ``output`` is not a non-empty string.
        """
        import control as ct

        wf = 2 * math.pi * self.derivative_filter_hz
        s = ct.tf("s")
        return ct.tf(self.kp + self.ki / s + self.kd * s / (1 + s / wf), inputs="e", outputs=_signal(output),
                     name="pid")

    def discrete(self, Ts: float) -> tuple[float, float, float, float]:
        """``(kp, ki Ts, kd (1 - a) / Ts, a)``: the sampled PID :class:`PID` runs, ``a = T_f / (T_f + Ts)``.

        The one statement of the discretisation: :meth:`PID.torque` runs it, :meth:`sampled_tf` and
        :mod:`gearctl.describe` analyse it.

        Parameters
        ----------
        Ts : float
            Sample period [s].

        Raises
        ------
        InputError
            If ``Ts`` is not a sample period (1e-6..1 s, as a controller file's ``sample_time``).
        """
        Ts = SAMPLE_TIME.check("Ts", Ts)
        Tf = 1.0 / (2 * math.pi * self.derivative_filter_hz)
        a = Tf / (Tf + Ts)
        return self.kp, self.ki * Ts, self.kd * (1.0 - a) / Ts, a

    def sampled_tf(self, Ts: float, *, output: str = "xi1") -> ct.TransferFunction:
        """The sampled PID as a discrete transfer function, error to torque (dt = ``Ts``; input ``e``, output
        ``output``, ``xi0`` for a train's mode models, as :meth:`tf`).

        ``C(z) = kp + ki Ts / (z - 1) + kd (1 - a) (z - 1) / (Ts (z - a))``, ``a = T_f / (T_f + Ts)``,
        ``T_f = 1 / (2 pi f_d)``.

        Notes
        -----
        Derived from :meth:`PID.torque`: the integrator adds ``Ts ki e_k`` *after* forming ``u_k`` (so
        ``I_k = Ts ki sum_{i<k} e_i``: ``Ts ki / (z - 1)``); the derivative acts on the measurement through
        a backward-Euler filter, ``y_f,k = a y_f,k-1 + (1 - a) y_k``, ``dy_k = (y_f,k - y_f,k-1) / Ts``:
        ``(1 - a)(z - 1) / (Ts (z - a))``. With a constant reference the derivative of the measurement
        is minus that of the error. Anti-windup is inactive below the torque limit.

        Parameters
        ----------
        Ts : float
            Sample period [s].
        output : str
            The name of the output, the motor torque (``xi1``; ``xi0`` on a train).

        Raises
        ------
        InputError
            If ``Ts`` is not a sample period (1e-6..1 s), or ``output`` not a name.
        """
        import control as ct

        kp, kiT, kdT, a = self.discrete(Ts)
        z = ct.tf([1.0, 0.0], [1.0], Ts)
        return ct.tf(kp + kiT / (z - 1) + kdT * (z - 1) / (z - a), inputs="e", outputs=_signal(output), name="pid")


def check_readings(controller: Controller, t: float, y_motor: Any, y_load: Any, r: tuple[Any, Any, Any]) -> None:
    """The PID family's step: ``y_motor``, ``y_load`` if the controller feeds it back, and the reference ``r``
    (``(r, r', r'')``) are finite numbers within the exported API's limit, else an InputError naming them
    (:func:`gearctl.controller.check_reading`), before any state changes.

    Parameters
    ----------
    controller : Controller
        The controller stepping (its ``uses_load_encoder`` says whether ``y_load`` is read).
    t : float
        Sample time [s] (for the message).
    y_motor, y_load : float
        The encoder readings [rad].
    r : tuple of float
        ``(r, r', r'')`` of the reference at ``t`` [rad, rad/s, rad/s^2].

    Raises
    ------
    InputError
        Naming the first value that is not a finite number within the limit (``y_motor``, ``y_load``, ``ref``).
    """
    lim = READING_LIMIT
    try:  # the per-sample path: chained comparisons (a NaN fails them), a fraction of a microsecond
        if (-lim <= y_motor <= lim and -lim <= r[0] <= lim and -lim <= r[1] <= lim and -lim <= r[2] <= lim
                and (not controller.uses_load_encoder or -lim <= y_load <= lim)):
            return
    except (TypeError, ValueError):
        pass
    check_reading("y_motor", t, y_motor)
    if controller.uses_load_encoder:
        check_reading("y_load", t, y_load)
    for i, (v, unit) in enumerate(zip(r, ("rad", "rad/s", "rad/s^2"), strict=True)):
        check_reading(f"ref.at(t)[{i}]", t, v, unit, field="ref")


def _signal(name: Any) -> str:
    """A signal name for :meth:`PIDGains.tf` and :meth:`PIDGains.sampled_tf`: a non-empty string."""
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"output = {name!r} is not a signal name: expected a non-empty string such as 'xi1' or "
                         "'xi0'", field="output")
    return name


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class PIDDesign:
    """What a PID is designed for (the ``[design]`` table): crossover, phase margin, integral zero.

    The crossover must also lie below half the sample rate (checked by :func:`design_pid`).

    Parameters
    ----------
    bandwidth_hz : float
        Open-loop crossover, (0, 1e6] [Hz] (default 20).
    phase_margin_deg : float
        Phase margin, 1..79 [deg] (default 50).
    integral_ratio : float
        Integral zero over the crossover, 0..1 [1] (default 0.1).
    gap_gain_margin_db : float
        Gain margin the motor alone keeps under a motor-side PID when the load lets go in the gap, 0..40 [dB]
        (default 6; 0: not checked).
    """

    bandwidth_hz: float = quantity(unit="Hz", doc="open-loop crossover", low=0.0, low_open=True, high=1e6,
                                   default=20.0)
    phase_margin_deg: float = quantity(unit="deg", doc="phase margin", low=1.0, high=79.0, default=50.0)
    integral_ratio: float = quantity(unit="1", doc="integral zero over the crossover", low=0.0, high=1.0,
                                     default=0.1)
    gap_gain_margin_db: float = quantity(unit="dB", doc="gain margin the motor alone keeps under a motor-side PID "
                                         "when the load lets go in the gap (0: not checked)", low=0.0, high=40.0,
                                         default=6.0)

    def __post_init__(self) -> None:
        validate_fields(self)


def design_pid(info: LoopInfo, *, bandwidth_hz: float, phase_margin_deg: float = 50.0, Ts: float = 1e-3,
               integral_ratio: float = 0.1) -> tuple[PIDGains, dict[str, float]]:
    """PID gains for a crossover ``bandwidth_hz`` and phase margin on the rigid train.

    Parameters
    ----------
    info : LoopInfo
        Design-time plant knowledge.
    bandwidth_hz : float
        Open-loop crossover frequency [Hz].
    phase_margin_deg : float
        Phase margin [deg] the lead provides, on top of what the integral zero and half a sample of
        hold delay cost.
    Ts : float
        Sample period [s] (its zero-order hold costs ``omega_c Ts / 2`` of phase).
    integral_ratio : float
        Integral zero as a fraction of the crossover.

    Returns
    -------
    gains : PIDGains
    margins : dict
        Margins of the designed loop on the *sampled contact-mode* model (motor torque to motor angle
        scaled to load units, ZOH at ``Ts``): ``gain_margin_db``, ``phase_margin`` [deg],
        ``gain_crossover_hz``.

    Raises
    ------
    InputError
        If ``info`` is not a :class:`~gearctl.design.LoopInfo` (``gearctl.design.loop_info(plant)``), ``Ts`` not a
        sample period (1e-6..1 s), ``bandwidth_hz`` not in (0, half the sample rate), ``phase_margin_deg`` not in
        (0, 80) deg or ``integral_ratio`` not in 0..1 (the ranges of a controller file's ``[design]`` table), or
        the gains for them are out of range on the model's rigid train.

    Notes
    -----
    Lead–lag design on ``G(s) = 1 / (N J_eq s^2 + N d_eq s)``: the lead ``(1 + s/z)/(1 + s/p)`` centred
    on ``omega_c`` with ``p/z = (1 + sin phi) / (1 - sin phi)``, the integrator ``(s + omega_i)/s`` with
    ``omega_i = integral_ratio omega_c``, and the gain that puts ``|L(j omega_c)| = 1``; then written in
    parallel form with the lead pole as derivative filter.
    """
    info = check_loop_info(info)
    Ts = SAMPLE_TIME.check("Ts", Ts)
    spec = {f.name: f.metadata for f in dataclasses.fields(PIDDesign)}
    bandwidth_hz = check_number("bandwidth_hz", bandwidth_hz, spec["bandwidth_hz"])
    phase_margin_deg = check_number("phase_margin_deg", phase_margin_deg,
                                    {**spec["phase_margin_deg"], "low": 0.0, "high": 80.0, "low_open": True,
                                     "high_open": True})
    integral_ratio = check_number("integral_ratio", integral_ratio, spec["integral_ratio"])
    if not (0.0 < bandwidth_hz < 0.5 / Ts):
        raise InputError(f"bandwidth_hz = {bandwidth_hz!r} is out of range: expected 0 < value < "
                         f"{0.5 / Ts:g} (half the sample rate) [Hz]", field="bandwidth_hz")
    if not (0.0 < phase_margin_deg < 80.0):
        raise InputError(f"phase_margin_deg = {phase_margin_deg!r} is out of range: expected 0 < value < 80 "
                         f"[deg]", field="phase_margin_deg")
    import control as ct

    wc, wi, z, p = _lead_lag(bandwidth_hz, phase_margin_deg, integral_ratio, Ts)
    s = ct.tf("s")
    G = 1 / (info.N * info.J_eq * s**2 + info.N * info.d_eq * s)
    shape = (s + wi) / s * (1 + s / z) / (1 + s / p)
    kp, ki, kd, fd = _parallel(1.0 / abs(complex((shape * G)(1j * wc))), wi, z, p)
    try:
        gains = PIDGains(kp=kp, ki=ki, kd=max(kd, 0.0), derivative_filter_hz=fd)
    except InputError as exc:  # a designed gain out of range: name the design keys and the model's inertia
        designed = {"kp": kp, "ki": ki, "kd": kd, "derivative_filter_hz": fd}
        if exc.field is None or exc.field not in designed or exc.rule is None:
            raise
        if exc.field == "derivative_filter_hz":  # the lead's pole, sqrt(alpha) x the crossover: no train changes it
            raise InputError(f"bandwidth_hz = {bandwidth_hz:g} (phase_margin_deg = {phase_margin_deg:g}) needs "
                             f"derivative_filter_hz = {fd:.4g}, {exc.rule.removeprefix('is ')} (the lead's pole "
                             f"above the crossover): expected a lower bandwidth_hz or phase_margin_deg",
                             field="bandwidth_hz") from None
        raise InputError(f"bandwidth_hz = {bandwidth_hz:g} (phase_margin_deg = {phase_margin_deg:g}) needs "
                         f"{exc.field} = {designed[exc.field]:.4g}, {exc.rule.removeprefix('is ')}, "
                         f"on the model's rigid train (J_eq = {info.J_eq:.4g} kg m^2 at the motor from the gears and "
                         f"[servo] motor_inertia, load_inertia; gear ratio {info.N:.4g}): expected a lower "
                         f"bandwidth_hz or a lighter train", field="bandwidth_hz") from None
    return gains, sampled_margins(info, gains, Ts)


def _lead_lag(bandwidth_hz: float, phase_margin_deg: float, integral_ratio: float,
              Ts: float) -> tuple[float, float, float, float]:
    """:func:`design_pid`'s loop shape: the crossover, the integral zero and the lead's zero and pole [rad/s]."""
    wc = 2 * math.pi * bandwidth_hz
    wi = integral_ratio * wc
    phi = math.radians(phase_margin_deg) + math.atan(wi / wc) + wc * Ts / 2
    phi = min(phi, math.radians(80.0))
    alpha = (1 + math.sin(phi)) / (1 - math.sin(phi))
    return wc, wi, wc / math.sqrt(alpha), wc * math.sqrt(alpha)


def _parallel(K: float, wi: float, z: float, p: float) -> tuple[float, float, float, float]:
    """The loop shape of gain ``K`` in parallel form: ``(kp, ki, kd, derivative_filter_hz)`` (kd unclipped)."""
    ki = K * wi
    Tf = 1 / p
    kp = K * (1 + wi / z) - ki * Tf
    return kp, ki, K / z - kp * Tf, p / (2 * math.pi)


def _search_gains(info: LoopInfo, bandwidth_hz: float, phase_margin_deg: float, integral_ratio: float,
                  Ts: float) -> PIDGains | None:
    """:func:`design_pid`'s gains with the crossover gain by complex arithmetic (no python-control, no margins; equal
    to the last bits or so): the bandwidth search of :func:`gap_limited_bandwidth` (None for gains out of range)."""
    wc, wi, z, p = _lead_lag(bandwidth_hz, phase_margin_deg, integral_ratio, Ts)
    s = 1j * wc
    L = (s + wi) / s * (1 + s / z) / (1 + s / p) / (info.N * info.J_eq * s * s + info.N * info.d_eq * s)
    kp, ki, kd, fd = _parallel(1.0 / abs(L), wi, z, p)
    try:
        return PIDGains(kp=kp, ki=ki, kd=max(kd, 0.0), derivative_filter_hz=fd)
    except InputError:
        return None


def gap_loop_pole(info: LoopInfo, gains: PIDGains, Ts: float, *, gain: float = 1.0) -> tuple[float, float]:
    """Growth rate [1/s] and frequency [Hz] of the least damped mode of the motor alone, the load let go in the
    gap, under the sampled motor-side PID with its gains times ``gain`` (``log|z| / Ts`` and ``arg z / (2 pi Ts)``
    of its closed-loop eigenvalue of largest modulus; a negative growth rate: stable).

    Parameters
    ----------
    info : LoopInfo
        Design-time plant knowledge (:func:`~gearctl.design.loop_info`): its nominal plant's shaft 0 (the motor's
        inertia and viscous friction) and gear ratio ``N``.
    gains : PIDGains
        The PID's gains (run as :meth:`PIDGains.discrete` gives them).
    Ts : float
        Sample period [s].
    gain : float
        Factor on every gain (default 1; a gain margin ``g`` dB is checked with ``10**(g / 20)``) [1].

    Returns
    -------
    growth : float
        ``log|z| / Ts`` of the least damped closed-loop eigenvalue ``z`` [1/s] (negative: stable).
    frequency : float
        ``|arg z| / (2 pi Ts)`` of that eigenvalue [Hz].

    The motor shaft alone (the nominal plant's shaft 0: its inertia and viscous friction; on a train the first
    stage's gap is the one that lets it go) under the PID :meth:`PID.torque` runs (:meth:`PIDGains.discrete`:
    the integrator and the derivative filter as two states) on ``theta1 / N``, with the exact zero-order hold:
    every closed-loop eigenvalue ``z`` inside the unit circle for stability. A PID designed on the rigid train has
    ``J_eq / J_motor`` times the loop gain on the motor alone: on a light motor (a load-dominated servo) the
    loop that is well damped in contact is unstable in the gap, and it rattles between the flanks at the
    Nyquist frequency (``gearctl describe`` shows that cycle).

    Notes
    -----
    The test is on ``mu = z - 1``, the eigenvalues of the closed-loop matrix less the identity, formed without
    cancellation: ``|1 + mu| < 1`` is ``2 Re mu + |mu|^2 < 0``. A slow loop's eigenvalues crowd near ``z = 1``,
    where the roots of the characteristic polynomial (and python-control's poles) lose the digits that decide
    (a 0.3 Hz design at 0.1 ms was judged unstable).
    """
    import scipy.linalg

    shaft = info.nominal.shafts[0]
    J, d, N = shaft.J, shaft.d, info.N
    M = np.zeros((3, 3))
    M[0, 1], M[1, 1], M[1, 2] = 1.0, -d / J, 1.0 / J
    E = scipy.linalg.expm(M * Ts)
    Bd, Cp = E[:2, 2], np.array([1.0 / N, 0.0])
    kp, kiT, kdT, a = gains.discrete(Ts)
    # controller states: the integrator (xi+ = xi + e, torque kiT xi) and the derivative filter (eta+ = a eta + e,
    # torque kdT ((a - 1) eta + e)); e = -theta1 / N
    Dk = gain * (kp + kdT)
    Ck = gain * np.array([kiT, kdT * (a - 1.0)])
    D = np.zeros((4, 4))
    D[:2, :2] = E[:2, :2] - np.eye(2) - Dk * np.outer(Bd, Cp)
    D[:2, 2:] = np.outer(Bd, Ck)
    D[2:, :2] = -np.outer([1.0, 1.0], Cp)
    D[3, 3] = a - 1.0
    mu = np.linalg.eigvals(D)
    with np.errstate(divide="ignore"):
        growth = 0.5 * np.log1p(2.0 * mu.real + np.abs(mu) ** 2) / Ts  # log|1 + mu| without cancellation
    i = int(np.argmax(growth))
    return float(growth[i]), float(abs(np.angle(1.0 + mu[i])) / (2.0 * math.pi * Ts))


def gap_loop_stable(info: LoopInfo, gains: PIDGains, Ts: float, *, gain: float = 1.0) -> bool:
    """Whether the motor alone, the load let go in the gap, is stable under the sampled motor-side PID with its
    gains times ``gain`` (:func:`gap_loop_pole`'s growth rate below zero).

    Parameters
    ----------
    info : LoopInfo
        Design-time plant knowledge (:func:`~gearctl.design.loop_info`): its nominal plant's shaft 0 (the motor's
        inertia and viscous friction) and gear ratio ``N``.
    gains : PIDGains
        The PID's gains (run as :meth:`PIDGains.discrete` gives them).
    Ts : float
        Sample period [s].
    gain : float
        Factor on every gain (default 1; a gain margin ``g`` dB is checked with ``10**(g / 20)``) [1].

    Returns
    -------
    bool
        True when every closed-loop eigenvalue lies inside the unit circle.
    """
    return gap_loop_pole(info, gains, Ts, gain=gain)[0] < 0.0


def gap_limited_bandwidth(info: LoopInfo, *, bandwidth_hz: float, phase_margin_deg: float = 50.0,
                          integral_ratio: float = 0.1, Ts: float = 1e-3, gain_margin_db: float = 6.0) -> float:
    """The largest crossover up to ``bandwidth_hz`` [Hz] whose :func:`design_pid` gains leave the motor alone
    (the load let go in the gap) stable with ``gain_margin_db`` of gain margin (:func:`gap_loop_stable` with
    the gains and with them times the margin): ``bandwidth_hz`` itself when it does.

    Found by bisection on a logarithmic scale down to a hundredth of ``bandwidth_hz`` (to 0.1 %).

    Parameters
    ----------
    info : LoopInfo
        Design-time plant knowledge (:func:`~gearctl.design.loop_info`).
    bandwidth_hz : float
        The crossover asked for, the upper end of the search [Hz].
    phase_margin_deg : float
        Phase margin of the design [deg] (default 50), as in :func:`design_pid`.
    integral_ratio : float
        Integral zero over the crossover [1] (default 0.1), as in :func:`design_pid`.
    Ts : float
        Sample period [s] (default 1e-3).
    gain_margin_db : float
        Gain margin the motor alone must keep [dB] (default 6).

    Returns
    -------
    float
        The crossover [Hz]: ``bandwidth_hz`` itself, or the largest that passes, to 0.1 %.

    Raises
    ------
    InputError
        Not even a hundredth of ``bandwidth_hz`` does (field ``gap_gain_margin_db``): the motor is too light for
        a motor-side loop on this train.
    """
    k = 10.0 ** (gain_margin_db / 20.0)

    def ok(bw: float) -> bool:
        g = _search_gains(info, bw, phase_margin_deg, integral_ratio, Ts)
        return g is not None and gap_loop_stable(info, g, Ts) and gap_loop_stable(info, g, Ts, gain=k)

    if ok(bandwidth_hz):
        return bandwidth_hz
    lo, hi = bandwidth_hz / 100.0, bandwidth_hz
    if not ok(lo):
        J = info.nominal.shafts[0].J
        tau = info.J_eq / info.d_eq if info.d_eq > 0.0 else math.inf
        why = (f"; the rigid train's viscous time constant J_eq / d_eq = {tau * 1e3:.3g} ms is under two samples, so "
               f"the gains follow its damping, which the motor alone lacks" if tau < 2.0 * Ts else "")
        raise InputError(f"bandwidth_hz = {bandwidth_hz:g}: no crossover down to {lo:.3g} Hz leaves the motor shaft "
                         f"alone ({J:.3g} kg m^2, 1/{info.J_eq / J:.3g} of the rigid train) stable in the gap with "
                         f"gap_gain_margin_db = {gain_margin_db:g} dB{why}: expected feedback = \"load\", a heavier "
                         f"motor, or gap_gain_margin_db = 0 to accept a loop that rattles between the flanks",
                         field="gap_gain_margin_db")
    while hi / lo > 1.001:
        mid = math.sqrt(lo * hi)
        if ok(mid):
            lo = mid
        else:
            hi = mid
    return lo


def sampled_margins(info: LoopInfo, gains: PIDGains, Ts: float, *, feedback: str = "motor",
                    contact: Any = None) -> dict[str, float]:
    """Design margins: the continuous PID, discretised by Tustin, on the contact-mode model with its ZOH
    (``contact``: another contact-mode model with the same signals, e.g. a whole train's; default the design's).

    Notes
    -----
    These are the margins of the *design* (the loop-shaping target, as a textbook discretises it); the
    controller that runs is :meth:`PIDGains.sampled_tf`, whose phase margin is a few degrees lower at 1 kHz
    (47.3 deg against 50.1 deg for the catalog PID on ``shing1993_servo``): :func:`gearctl.describe` and
    ``examples/03_bode_step_margins.py`` analyse that one.
    """
    import control as ct

    from ..modes import loop_margins

    out = 0 if feedback == "motor" else 1
    scale = 1.0 / info.N if feedback == "motor" else 1.0
    model = info.modes.contact if contact is None else contact
    G = ct.c2d(ct.ss(model[out, 0]) * scale, Ts, "zoh")
    return loop_margins(ct.c2d(gains.tf(), Ts, "tustin") * G)


class PID(Controller):
    """Discrete position PID (filtered derivative on the measurement, back-calculation anti-windup).

    Parameters
    ----------
    info : LoopInfo
        Design-time plant knowledge (gear ratio, rigid-train inertia and friction for feedforward).
    gains : PIDGains
        The gains.
    Ts : float
        Sample period [s].
    feedback : str
        ``"motor"`` (motor encoder scaled by the gear ratio) or ``"load"`` (load encoder).
    feedforward : bool
        Add the rigid-train torque for the reference, ``N (J_eq a + d_eq r') - load_torque / N``, at the
        acceleration ``a`` the sample's held torque must give (see Notes), and take the derivative filter's
        lag off the derivative action.
    friction_feedforward : bool
        With ``feedforward``, add the model's Coulomb friction of the rigid train, ``(T_c1 + T_c2 / N)
        sign(r')`` [N m at the motor].
    name : str
        Label.

    Attributes
    ----------
    integral : float
        The integrator's torque ``I_k`` [N m].
    y_filtered : float or None
        The derivative filter's state, the filtered measurement [rad] (None before the first sample).
    dy : float
        The filtered measurement's rate of the last sample [rad/s].
    rdd_prev : float or None
        The reference acceleration of the last sample [rad/s^2] (None before the first sample).

    Raises
    ------
    InputError
        If ``info`` is not a :class:`~gearctl.design.LoopInfo`, ``gains`` not a :class:`PIDGains`, ``Ts`` not a
        sample period (1e-6..1 s), ``feedback`` neither ``"motor"`` nor ``"load"``, or ``feedforward`` or
        ``friction_feedforward`` not a bool.

    Notes
    -----
    The control law, per sample ``k`` (target ``r``, its speed ``v`` and acceleration ``a_k``; errors in
    load-angle units; ``Ts`` the sample time, ``alpha = T_f / (T_f + Ts)``, ``T_f = 1 / (2 pi f_d)``)::

        a_m   = a_k + (a_k - a_(k-1)) / 2                       (feedforward only; a_(-1) = a_0)
        yf_k  = alpha yf_(k-1) + (1 - alpha) y_k                (yf_(-1) = y_0)
        dy_k  = (yf_k - yf_(k-1)) / Ts
        u_fb  = kp e_p + I_k + kd (v - T_f a_m - dy_k)          (T_f a_m: feedforward only)
        u_ff  = N (J_eq a_m + d_eq v) + (T_c1 + T_c2 / N) sign(v) - load_torque / N
        u     = u_ff + u_fb,   u_sat = clip(u, -limit, limit)
        I_k+1 = I_k + Ts (ki e_i + (u_sat - u) / T_t),  T_t = sqrt(kd / ki)  (10 Ts without ki or kd)

    - *Mid-sample acceleration.* The torque computed at ``t_k`` is held over ``[t_k, t_k + Ts]``; the
      feedforward gives the acceleration at the middle of that sample, extrapolated from this sample's
      and the last one's (no preview: the PID reads ``r(t)`` only).
    - *Derivative lag.* The derivative acts on the filtered measurement, which lags the measurement by
      ``T_f``, but the reference speed is not filtered: while the target accelerates at ``a`` the
      derivative term would add ``kd T_f a`` of torque (a quarter of the inertia's feedforward for the
      catalog PID), so the loop led in every acceleration and lagged in every deceleration (0.5 mrad in
      the ISO 230-2 moves on the backlash-free plant). The reference speed is delayed by the same ``T_f``.
    - *Friction.* The model's Coulomb friction is fed forward while the reference moves; at rest the
      integrator holds what static friction does not.

    Without ``feedforward`` the law is the textbook one (``u_ff = 0``, ``a_m`` unused), whose sampled
    transfer function :meth:`PIDGains.sampled_tf` states. A wrapper (the dead-zone inverse, the
    reversal offset) calls :meth:`reference_update` once per sample and :meth:`torque` with its own
    target and, where the model is not the rigid train, its own feedforward and feedback scale.
    """

    def __init__(self, info: LoopInfo, gains: PIDGains, *, Ts: float = 1e-3, feedback: str = "motor",
                 feedforward: bool = True, friction_feedforward: bool = True, name: str = "pid") -> None:
        super().__init__()
        info = check_loop_info(info)
        if not isinstance(gains, PIDGains):
            raise InputError(f"gains = {short_repr(gains)} is not a PIDGains: expected e.g. "
                             "gearctl.design.pid.PIDGains(kp=..., ki=..., kd=...) or design_pid(info, ...)[0]",
                             field="gains")
        if feedback not in ("motor", "load"):
            raise InputError(f"feedback = {feedback!r}: expected 'motor' or 'load'", field="feedback")
        for flag, value in (("feedforward", feedforward), ("friction_feedforward", friction_feedforward)):
            if not isinstance(value, bool | np.bool_):  # a string such as "no" would read as True
                raise InputError(f"{flag} = {value!r} is not a bool: expected True or False", field=flag)
        self.info, self.gains, self.Ts, self.feedback, self.feedforward = info, gains, Ts, feedback, feedforward
        self.friction_feedforward = bool(friction_feedforward)
        self.name = name
        self.uses_load_encoder = feedback == "load"
        self.N = info.N
        self.limit = info.torque_limit
        p = info.plant
        #: Coulomb friction of the rigid train at the motor [N m] (0 without friction feedforward)
        self.friction = (p.tc1 + p.tc2 / self.N) if (feedforward and friction_feedforward) else 0.0
        # derivative filter (backward Euler) and the anti-windup tracking time
        self._a = gains.discrete(Ts)[3]
        self._Tt = math.sqrt(gains.kd / gains.ki) if gains.ki > 0 and gains.kd > 0 else 10 * Ts
        self.reset()

    def reset(self) -> None:
        """Zero the integrator, the derivative filter and the acceleration history."""
        self.integral = 0.0
        self.y_filtered: float | None = None
        self.v_filtered: float | None = None
        self.dy = 0.0
        self.rdd_prev: float | None = None
        self.moving = False
        self.integral_moving = 0.0
        self.solve_times, self.fallbacks = [], []

    def reference_update(self, rd: float, rdd: float) -> float:
        """Per-sample bookkeeping of the reference (call once per sample, before :meth:`torque`).

        Parameters
        ----------
        rd, rdd : float
            The reference's speed [rad/s] and acceleration [rad/s^2] at this sample.

        Returns
        -------
        float
            The acceleration to feed forward: ``rdd`` extrapolated to the middle of the sample the torque
            is held over, from this sample's and the last one's [rad/s^2].

        Notes
        -----
        When a move starts (``r'`` leaves 0) with friction feedforward, it releases what the integrator took on at
        rest against static friction (see Notes of :class:`PID`).
        """
        prev = self.rdd_prev if self.rdd_prev is not None else rdd
        self.rdd_prev = rdd
        moving = rd != 0.0
        if self.friction > 0.0:
            if moving and not self.moving:  # a move starts: at most the friction is released
                held = self.integral - self.integral_moving
                self.integral -= min(max(held, -self.friction), self.friction)
            if moving:
                self.integral_moving = self.integral
        self.moving = moving
        return rdd + 0.5 * (rdd - prev) if self.feedforward else rdd

    def feedforward_torque(self, v: float, a: float) -> float:
        """The rigid train's torque at the motor for the target speed ``v`` and acceleration ``a`` [N m]:
        ``N (J_eq a + d_eq v) + (T_c1 + T_c2 / N) sign(v) - load_torque / N`` (0 without feedforward).

        Parameters
        ----------
        v : float
            Target speed of the load [rad/s].
        a : float
            Target acceleration of the load [rad/s^2].
        """
        if not self.feedforward:
            return 0.0
        info = self.info
        u = self.N * (info.J_eq * a + info.d_eq * v) - info.plant.load_torque / self.N
        if self.friction > 0.0 and v != 0.0:
            u += math.copysign(self.friction, v)
        return u

    def torque(self, t: float, r: float, v: float, a: float, e_p: float, y_p: float, e_i: float, *,
               ff: float | None = None, scale: float = 1.0) -> float:
        """One PID update from the prepared errors (the wrappers' entry point).

        Parameters
        ----------
        t : float
            Sample time [s].
        r, v, a : float
            The target [rad], its speed [rad/s] and the acceleration to feed forward [rad/s^2] (from
            :meth:`reference_update`, plus the wrapper's own terms).
        e_p, y_p, e_i : float
            Proportional error, the signal differentiated, integral error, in load-angle units [rad].
        ff : float, optional
            Feedforward torque to use instead of :meth:`feedforward_torque` ``(v, a)`` [N m].
        scale : float
            Factor on the feedback (proportional, integral and derivative torque).

        Returns
        -------
        float
            The motor torque, clipped to the torque limit [N m].
        """
        g = self.gains
        if self.y_filtered is None:
            self.y_filtered = y_p
        yf_new = self._a * self.y_filtered + (1 - self._a) * y_p
        self.dy = (yf_new - self.y_filtered) / self.Ts
        self.y_filtered = yf_new
        if self.feedforward:  # the reference speed through the same sampling and filter as the measurement
            v_avg = v - 0.5 * self.Ts * a
            if self.v_filtered is None:
                self.v_filtered = v_avg
            self.v_filtered = self._a * self.v_filtered + (1 - self._a) * v_avg
            v_d = self.v_filtered
        else:
            v_d = v
        u_fb = g.kp * e_p + self.integral + g.kd * (v_d - self.dy)
        u_ff = self.feedforward_torque(v, a) if ff is None else ff
        u = u_ff + scale * u_fb
        u_sat = min(max(u, -self.limit), self.limit)
        bound = INTEGRAL_BOUND * self.limit
        self.integral = min(max(self.integral + self.Ts * (g.ki * e_i + (u_sat - u) / self._Tt), -bound), bound)
        return u_sat

    def step(self, t: float, y_motor: float, y_load: float | None, ref: ReferenceLike) -> float:
        r, rd, rdd = ref.at(t)
        check_readings(self, t, y_motor, y_load, (r, rd, rdd))
        a = self.reference_update(rd, rdd)
        y = y_motor / self.N if self.feedback == "motor" else float(y_load)  # type: ignore[arg-type]
        return self.torque(t, r, rd, a, r - y, y, r - y)

    def describe(self) -> dict[str, Any]:
        """Gains and settings."""
        return {"name": self.name, "kind": "pid", "Ts": self.Ts, "feedback": self.feedback,
                "feedforward": self.feedforward, "friction_feedforward": self.friction_feedforward,
                **dataclasses.asdict(self.gains), "design_notes": list(self.design_notes)}


# --- the controller file ---------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class LoopSettings:
    """What every PID-based controller file states at its top level (see :class:`PID`).

    Parameters
    ----------
    sample_time : float
        Sample period, 1e-6..1 [s] (default 1e-3).
    feedback : str
        ``"motor"`` (motor encoder scaled by the gear ratio) or ``"load"`` (load encoder) (default ``"motor"``).
    feedforward : bool
        Add the rigid-train torque for the reference (default True; see :class:`PID`).
    friction_feedforward : bool
        With ``feedforward``, add the model's Coulomb friction (default True; see :class:`PID`).

    Raises
    ------
    InputError
        For ``sample_time`` out of range, ``feedback`` not one of the two, or a flag not a bool (named).
    """

    sample_time: float = SAMPLE_TIME.field(default=1e-3)
    feedback: str = "motor"
    feedforward: bool = True
    friction_feedforward: bool = True

    def __post_init__(self) -> None:
        validate_fields(self)
        check_choice("feedback", self.feedback, ("motor", "load"))
        check_choice("feedforward", self.feedforward, (True, False))
        check_choice("friction_feedforward", self.friction_feedforward, (True, False))


#: top-level keys every PID-based file has, and the PID's tables
LOOP_KEYS: dict[str, tuple[type, str]] = {
    "sample_time": (LoopSettings, "sample_time"), "feedback": (LoopSettings, "feedback"),
    "feedforward": (LoopSettings, "feedforward"), "friction_feedforward": (LoopSettings, "friction_feedforward")}
PID_TABLES: dict[str, Mapping[str, tuple[type, str]]] = {
    "design": {f.name: (PIDDesign, f.name) for f in dataclasses.fields(PIDDesign)},
    "gains": {f.name: (PIDGains, f.name) for f in dataclasses.fields(PIDGains)}}
#: The keys of a ``pid`` controller file and the settings fields they feed.
LAYOUT: Layout = {"": LOOP_KEYS, **PID_TABLES}

#: ``field -> (binding, value)`` of one settings dataclass, as :func:`~gearctl.files.spec_values` sorts a file.
Values = Mapping[str, tuple[Binding, Any]]


def restate(path: Path, exc: InputError, values: Mapping[type, Values]) -> InputError:
    """An error raised by a design step, restated with the file and the key it came from.

    Parameters
    ----------
    path : Path
        The controller file, named first in the message.
    exc : InputError
        The error; its ``field`` is looked up among ``values``.
    values : mapping
        ``settings class -> {field: (binding, value)}`` as :func:`~gearctl.files.spec_values` sorted the file.

    Returns
    -------
    InputError
        A new error (not raised) naming ``path`` and the key (``[table] key``) that set ``exc.field``, or just
        ``path`` when no key did; same ``field`` and ``rule``.
    """
    for vals in values.values():
        if exc.field is not None and exc.field in vals:
            b = vals[exc.field][0]
            msg = str(exc)
            if msg.startswith(f"{exc.field} = "):  # the message names the key already: name it as the file does
                return InputError(f"{path}: {b.label()}{msg[len(exc.field):]}", field=exc.field, rule=exc.rule)
            return InputError(f"{path}: {b.label()}: {msg}", field=exc.field, rule=exc.rule)
    return InputError(f"{path}: {exc}", field=exc.field, rule=exc.rule)


def pid_from_values(path: Path, values: Mapping[type, Values], info: LoopInfo, loop: LoopSettings,
                    name: str) -> PID:
    """The PID of a file's ``[design]`` or ``[gains]`` (shared by every PID-based kind).

    With ``[design]`` and motor feedback the bandwidth is lowered where the motor alone would be unstable in the
    gap (:func:`gap_limited_bandwidth`), which the PID's ``design_notes`` then say.

    Parameters
    ----------
    path : Path
        The controller file (named in errors).
    values : mapping
        ``settings class -> {field: (binding, value)}`` as :func:`~gearctl.files.spec_values` sorted the file.
    info : LoopInfo
        Design-time plant knowledge.
    loop : LoopSettings
        The file's top-level settings.
    name : str
        The controller's label.

    Returns
    -------
    PID

    Raises
    ------
    InputError
        For both ``[gains]`` and ``[design]`` (field ``gains``), a value out of range, or a design that fails,
        restated with the file and key (:func:`restate`).
    """
    Ts = loop.sample_time
    notes: tuple[str, ...] = ()  # what the design changed of what the file asked (Controller.design_notes)
    if PIDGains in values and PIDDesign in values:
        raise InputError(f"{path}: give either [gains] or [design], not both", field="gains")
    if PIDGains in values:
        gains = build_dataclass(path, PIDGains, values[PIDGains])
    else:
        design = build_dataclass(path, PIDDesign, values.get(PIDDesign, {}))
        bw = design.bandwidth_hz
        gap_check = loop.feedback == "motor" and design.gap_gain_margin_db > 0.0 and 0.0 < bw < 0.5 / Ts
        try:
            if gap_check:
                bw = gap_limited_bandwidth(info, bandwidth_hz=bw, phase_margin_deg=design.phase_margin_deg,
                                           integral_ratio=design.integral_ratio, Ts=Ts,
                                           gain_margin_db=design.gap_gain_margin_db)
            gains, _ = design_pid(info, bandwidth_hz=bw, phase_margin_deg=design.phase_margin_deg,
                                  integral_ratio=design.integral_ratio, Ts=Ts)
            k = 10.0 ** (design.gap_gain_margin_db / 20.0)
            for _ in range(20):  # the search's gains and design_pid's differ in the last bits: the ones that run hold
                if not gap_check or bw == design.bandwidth_hz or (
                        gap_loop_stable(info, gains, Ts) and gap_loop_stable(info, gains, Ts, gain=k)):
                    break
                bw *= 0.999
                gains, _ = design_pid(info, bandwidth_hz=bw, phase_margin_deg=design.phase_margin_deg,
                                      integral_ratio=design.integral_ratio, Ts=Ts)
        except InputError as exc:
            raise restate(path, exc, values) from None
        if bw < design.bandwidth_hz:
            shaft = info.nominal.shafts[0]
            # enough digits to show the change (the gap search can shave off a tenth of a percent: "20 lowered to 20")
            shown = next((f"{bw:.{d}g}" for d in (3, 6, 10) if float(f"{bw:.{d}g}") < design.bandwidth_hz), repr(bw))
            notes = (f"bandwidth_hz = {design.bandwidth_hz:g} lowered to {shown} Hz. Designed on the rigid train, "
                     f"the PID has {info.J_eq / shaft.J:.3g}x the loop gain on the motor shaft alone "
                     f"({shaft.J:.3g} kg m^2), which the load leaves in the gap; above {shown} Hz the motor-alone "
                     f"loop is unstable, or within gap_gain_margin_db = {design.gap_gain_margin_db:g} dB of it, and "
                     f"the motor rattles between the flanks. To keep {design.bandwidth_hz:g} Hz anyway, and "
                     f"risk that rattle, set gap_gain_margin_db = 0 in [design]",)
    pid = PID(info, gains, Ts=Ts, feedback=loop.feedback, feedforward=loop.feedforward,
              friction_feedforward=loop.friction_feedforward, name=name)
    pid.design_notes = notes + train_margin_notes(info, gains, Ts, loop.feedback)
    return pid


#: Gain margin [dB] below which :func:`train_margin_notes` says a train's all-contact loop is close to unstable.
TRAIN_GAIN_MARGIN_DB = 6.0


def train_margin_notes(info: LoopInfo, gains: PIDGains, Ts: float, feedback: str) -> tuple[str, ...]:
    """A note where a train's PID keeps less than :data:`TRAIN_GAIN_MARGIN_DB` of gain margin on the whole
    train in contact (every intermediate shaft's mode), which the design's equivalent pair does not see.

    Why: on a four-stage train with a 398 Hz mode (``tests/data/h4_train4_review.toml``) the catalog PID, designed
    on the equivalent pair with 22 dB of gain margin, keeps 3.1 dB on the whole train, and no output said so. The
    margins are those of the controller that runs (:meth:`PIDGains.sampled_tf`), not of the design's Tustin image
    (:func:`sampled_margins`): near the Nyquist frequency the two differ (1.55 dB for the latter there, which a
    closed-loop pole check of the sampled loop does not confirm). (Its
    bandwidth is not lowered for it: at 7 Hz instead of 20 the train still rattles, 14 000 impacts in 3 s against
    24 000, and the backlash-free sine is 100x worse.) Empty for a pair, and where the margin holds.
    """
    if info.nominal.n_stages < 2:
        return ()
    import control as ct

    from ..modes import linearize_modes, loop_margins

    # the controller that runs (PIDGains.sampled_tf), not the design's Tustin image: the train's modes lie near the
    # Nyquist frequency, where the two differ (h4's train: 3.1 dB with the one that runs, 1.55 with the Tustin image,
    # which a closed-loop pole check of the sampled loop does not confirm)
    def running(contact: Any) -> dict[str, float]:
        out, scale = (0, 1.0 / info.N) if feedback == "motor" else (1, 1.0)
        G = ct.c2d(ct.ss(contact[out, 0]) * scale, Ts, "zoh")
        return loop_margins(gains.sampled_tf(Ts, output=str(contact.input_labels[0])) * G)

    m = running(linearize_modes(info.nominal).contact)
    gm = m.get("gain_margin_db", math.inf)
    if not (isinstance(gm, float) and gm < TRAIN_GAIN_MARGIN_DB):
        return ()
    design = running(info.modes.contact).get("gain_margin_db", math.inf)
    return (f"on the whole train in contact the PID keeps {gm:.3g} dB of gain margin, at "
            f"{m.get('phase_crossover_hz', math.nan):.4g} Hz (a mode of the train the equivalent pair leaves out; "
            f"on the pair it was designed on: {design:.3g} dB): the loop rings there when excited; a lower "
            f"bandwidth_hz in [design] raises it",)


def build(path: Path, spec: dict[str, Any], info: LoopInfo, *, name: str, backlash: float | None = None) -> PID:
    """The PID of a ``kind = "pid"`` file (``backlash`` is unused: a PID knows no gap).

    Parameters
    ----------
    path : Path
        The controller file (named in errors).
    spec : dict
        The parsed file.
    info : LoopInfo
        Design-time plant knowledge.
    name : str
        The controller's label.
    backlash : float, optional
        Unused [rad].

    Returns
    -------
    PID

    Raises
    ------
    InputError
        For an unknown table or key, or a value out of range (named with the file and key).
    """
    values = spec_values(path, spec, LAYOUT, kind=KIND)
    loop = build_dataclass(path, LoopSettings, values.get(LoopSettings, {}))
    return pid_from_values(path, values, info, loop, name)


