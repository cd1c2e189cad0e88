"""Dead-zone inverse: cross the backlash gap on purpose, on the flank that must carry the load.

Seen from the motor, the backlash is a dead zone of width ``2 b`` along the line of action, i.e.
``2 b / r_b2`` of load angle (the lost motion). The inverse offsets the motor's position target by
``sigma b / r_b2`` (load units) so that the flank ``sigma`` (+1 front, -1 back) is closed and the load
follows as if there were no gap. ``sigma`` follows the sign of either

- the torque the mesh must transmit to the load (the default, ``rule = "torque"``),
  ``J2 r'' + d2 r' + T_c2 sign(r') - load_torque - d_hat``, where ``d_hat`` is the load-torque disturbance
  estimated by an observer on the motor encoder (so a load step, a gravity load or a cutting force
  chooses the flank too). On an inertia-dominated load the decelerating half of every move is carried
  by the back flank although the motion is still forward; or
- the reference velocity ``r'`` (``rule = "velocity"``, the textbook rule, which is wrong over half of
  each cycle for an inertial load).

How a flank change is made, and how a move is finished
------------------------------------------------------
- *Hysteresis.* The flank changes only when the transmitted torque passes ``+-width`` (torque rule; the
  reference speed for the velocity rule). In between, and at standstill, the last flank is held: the
  load finishes a move on the flank that stopped it (the back flank after a forward move on an inertial
  load, the driving flank on a load that friction stops) and the motor stays there, so that the load's
  rest position is defined by that flank, not by where it happens to float. At standstill the flank
  changes only when the estimated load torque exceeds what the load's static friction can hold
  (``|load_torque + d_hat| > T_c2 + disturbance_threshold``): a disturbance that pushes the load through
  the gap is met on the flank that must carry it, and one that friction holds does not make the motor
  cross for nothing.
- *The crossing.* A flank change moves the offset from one flank to the other along a ``sin^2`` ramp of
  ``crossing_time`` (zero relative speed at both ends), aimed at where the load is predicted to be (its
  state when the motor left it, advanced with its inertia, friction and estimated load torque: a load
  stuck by friction stays put, an inertial one coasts), not at the reference; the free motor's torque
  ``N (J1 a + d1 v)`` is fed forward and the PID's feedback is scaled by ``J1 / J_eq`` while the motor is
  alone (the same loop on the 4x lighter motor rings across the gap). After the landing the load's lag
  behind the reference is taken up along a cubic over another ``crossing_time``. A step of ``2 b / r_b2``
  in the PID's target instead makes the PID ring at its bandwidth, and the load leaves the moves with
  the ring's speed.
- *Feedforward.* With ``friction_feedforward`` the model's Coulomb friction of the load, ``T_c2 sign(r')``,
  is fed forward with the rest of the transmitted torque, so the load does not stop short of the target
  by the friction over the PID's stiffness; the acceleration fed forward is the one at the middle of the
  sample the torque is held over (extrapolated from the last two samples: no preview), and the torque the
  PID's derivative filter lag would add in every acceleration is taken off (see :func:`offset_torque`).
  When a move starts on a load with Coulomb friction, the PID's integrator is set to the disturbance the
  observer sees beyond the static friction: what it held against the stuck load at rest is released,
  instead of being added to the friction feedforward.

With ``backlash = 0`` the inverse is the PID it wraps with these feedforward corrections (no offset, no
observer). Its preview is 1 (it reads ``r(t)`` only, like the PID).

The observer is the rigid train seen from the motor encoder (``[theta, omega, d]`` in load units,
input the motor torque, measurement the motor angle less the offset), with three poles at
``observer_hz``; its disturbance state is frozen while a crossing is under way and for one
``crossing_time`` after it (the load is not attached, then settling). With ``feedback = "load"`` it
measures the load encoder instead.

When it wins over the reversal offset, and when it loses
--------------------------------------------------------
See :mod:`gearctl.design.reversal` (the CNC baseline): the inverse wins on inertia-dominated loads (the
decelerating flank) and with load torques (the observer), both of which the reversal offset cannot see;
the reversal offset needs no model at all, and on a friction-dominated load with a correct backlash value
it is as good as the PID on the backlash-free plant.

Limits (measured, see ``tests/test_compensation.py``): on a load without friction
(``shing1993_servo``) the motor encoder cannot see a load that bounces off its flank at the end of a
move; the short ISO 230-2 overshoot moves (0.02 rad) end with the load floating, so B and R there stay
near the lost motion. A load encoder (``feedback = "load"``, or the MPC) is needed for that load.

References
----------
G. Tao, P. V. Kokotovic, *Adaptive Control of Systems with Actuator and Sensor Nonlinearities*, Wiley
(1996), ch. 4 (backlash inverse). M. Nordin, P.-O. Gutman, "Controlling mechanical systems with
backlash - a survey", Automatica 38 (2002) 1633-1649 (switching between the flanks; a soft crossing).
K. Ohnishi, M. Shibata, T. Murakami, "Motion control for advanced mechatronics", IEEE/ASME Trans.
Mechatronics 1 (1996) 56-67 (disturbance observer). Beckhoff TwinCAT CNC axis parameter P-AXIS-00243
(backlash distributed over cycles along a ``sin^2`` function: the same ramp shape).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg

from ..controller import ReferenceLike
from ..errors import InputError
from ..files import Layout, build_dataclass, spec_values
from ..units import BACKLASH, check_choice, quantity, validate_fields
from .base import Controller, LoopInfo
from .pid import LOOP_KEYS, PID, PID_TABLES, LoopSettings, pid_from_values, restate

__all__ = ["DeadzoneInverse", "InverseSettings", "LoadObserver", "OffsetRamp", "RAMPS", "ramp_shape",
           "offset_torque", "KIND", "LAYOUT", "build"]

#: The controller-file kind this module builds (:mod:`gearctl.design.registry`).
KIND = "deadzone_inverse"

#: Shapes of the offset's ramp between the flanks (``sin2``: Beckhoff's; ``linear``: Heidenhain's speed
#: command held over the compensation time; ``step``: all in one sample).
RAMPS = ("sin2", "linear", "step")


def ramp_shape(shape: str, x: float) -> tuple[float, float, float]:
    """Ramp from 0 to 1 over ``0 <= x <= 1`` and its first two derivatives in ``x``.

    ``sin2``: ``sin^2(pi x / 2)`` (zero slope at both ends); ``linear``: ``x``; ``step``: 1 for ``x > 0``.

    Examples
    --------
    >>> ramp_shape("sin2", 0.5)[0], ramp_shape("linear", 0.25), ramp_shape("step", 0.1)
    (0.5000000000000001, (0.25, 1.0, 0.0), (1.0, 0.0, 0.0))
    """
    if x >= 1.0:
        return 1.0, 0.0, 0.0
    if x <= 0.0:
        return 0.0, 0.0, 0.0
    if shape == "sin2":
        return 0.5 * (1.0 - math.cos(math.pi * x)), 0.5 * math.pi * math.sin(math.pi * x), \
            0.5 * math.pi**2 * math.cos(math.pi * x)
    if shape == "linear":
        return x, 1.0, 0.0
    return 1.0, 0.0, 0.0


class OffsetRamp:
    """A position offset [rad, load angle] that moves between values along a ramp (the motor's crossing).

    Parameters
    ----------
    shape : str
        One of :data:`RAMPS`.
    duration : float
        Time a full move between the flanks takes [s] (``0``: a step). A shorter move (from part-way)
        takes the same fraction of it.
    span : float
        Offset change of a full move (the lost motion ``2 b / r_b2``, times any gain) [rad].
    """

    __slots__ = ("shape", "duration", "span", "_o0", "_o1", "_t0", "_T")

    def __init__(self, shape: str, duration: float, span: float) -> None:
        self.shape, self.duration, self.span = shape, duration, span
        self.reset()

    def reset(self, value: float = 0.0) -> None:
        """Rest at ``value``."""
        self._o0 = self._o1 = value
        self._t0, self._T = 0.0, 0.0

    @property
    def target(self) -> float:
        """The value the offset is moving to (or rests at)."""
        return self._o1

    @property
    def end(self) -> float:
        """Time the last ramp ends [s]."""
        return self._t0 + self._T

    def moving(self, t: float) -> bool:
        """Whether a ramp is under way at ``t``."""
        return self._T > 0.0 and t < self._t0 + self._T

    def move_to(self, t: float, value: float) -> None:
        """Start a ramp at ``t`` from the present offset to ``value``."""
        o = self.at(t)[0]
        dist = abs(value - o)
        frac = dist / self.span if self.span > 0.0 else 1.0
        self._o0, self._o1, self._t0 = o, value, t
        self._T = self.duration * min(frac, 1.0) if self.shape != "step" else 0.0

    def at(self, t: float) -> tuple[float, float, float]:
        """Offset, its rate and its acceleration at ``t`` [rad, rad/s, rad/s^2]."""
        if self._T <= 0.0:
            return self._o1, 0.0, 0.0
        x = (t - self._t0) / self._T
        if x >= 1.0:
            return self._o1, 0.0, 0.0
        s, ds, dds = ramp_shape(self.shape, x)
        d = self._o1 - self._o0
        return self._o0 + d * s, d * ds / self._T, d * dds / self._T**2


def offset_torque(pid: PID, t: float, r: float, rd: float, rdd: float, offset: tuple[float, float, float],
                  extra: float, y_motor: float, y_load: float | None, *, free: bool = False,
                  lag: bool = True) -> float:
    """The wrapped PID's torque for the target ``r + o``, with the right feedforward in contact and in the gap.

    Parameters
    ----------
    pid : PID
        The position PID (motor or load feedback).
    t : float
        Sample time [s].
    r, rd, rdd : float
        Reference and its derivatives [rad, rad/s, rad/s^2].
    offset : tuple of float
        ``(o, o', o'')``: the motor's offset from the reference and its derivatives [rad, rad/s, rad/s^2].
    extra : float
        Further motor torque to feed forward in contact [N m] (e.g. the load's Coulomb friction over ``N``).
    y_motor : float
        Motor encoder [rad].
    y_load : float or None
        Load encoder [rad] (with load feedback the integral acts on ``r - y_load``).
    free : bool
        The motor is crossing the gap: the load is not attached.
    lag : bool
        Feed forward the torque the derivative filter's lag would take (see Notes).

    Notes
    -----
    The PID's own feedforward is ``N (J_eq a + d_eq v) - load_torque / N`` for the acceleration ``a`` and
    speed ``v`` it is given (the rigid train in contact). The wrapper hands it ``v = r' + o'`` and
    ``a = r'' + T_x / (N J_eq)``, so that the feedforward becomes the rigid train's plus ``T_x``: in contact
    ``T_x = extra`` (the offset is at rest); while the motor crosses the gap the feedforward is the free
    motor's, ``N (J1 (r'' + o'') + d1 (r' + o'))``, without the load's inertia, friction or load torque,
    and the feedback (the PID's torque less its feedforward) is scaled by ``J1 / J_eq``: the loop then drives
    the motor alone with the crossover and damping it was designed for on the train (unscaled, the free
    motor rings across the gap).

    The PID differentiates the *filtered* measurement (time constant ``T_f = a Ts / (1 - a)``) but takes the
    reference speed unfiltered, so while the target accelerates at ``a`` its derivative term adds about
    ``kd T_f a`` of torque: 25 % of the inertia's feedforward for the catalog PID, which makes it lead
    in every acceleration and lag in every deceleration (about 0.5 mrad in the ISO moves, measured on
    the backlash-free plant). With ``lag`` that torque is taken off the feedforward.
    With the offset at rest, ``extra = 0`` and ``lag = False`` the PID sees exactly ``r'`` and ``r''``.
    """
    o, do, ddo = offset
    info = pid.info
    N = pid.N
    v = rd + do
    if free:
        p = info.plant
        tx = N * (p.J1 * (rdd + ddo) + p.d1 * v) - N * (info.J_eq * rdd + info.d_eq * v) + p.load_torque / N
    else:
        tx = extra
    if lag:  # the derivative acts on the filtered measurement: its lag T_f would cost kd T_f a of torque
        a_f = pid._a
        tx -= pid.gains.kd * a_f * pid.Ts / (1.0 - a_f) * (rdd + ddo) * (info.plant.J1 / info.J_eq if free else 1.0)
    a = rdd if tx == 0.0 else rdd + tx / (N * info.J_eq)
    target = r + o
    ym = y_motor / N
    if pid.feedback == "motor" or y_load is None:
        u = pid.torque(t, target, v, a, target - ym, ym, target - ym)
    else:
        u = pid.torque(t, target, v, a, target - ym, ym, r - float(y_load))
    if free:  # the loop drives the motor alone: feedback scaled by J1 / J_eq keeps its crossover and damping
        ff = N * (info.J_eq * a + info.d_eq * v) - info.plant.load_torque / N
        u = ff + (info.plant.J1 / info.J_eq) * (u - ff)
        u = min(max(u, -pid.limit), pid.limit)
    return u


class LoadObserver:
    """Load-torque disturbance observer on the rigid train (load-angle units), three poles at ``bandwidth``.

    Model (ZOH at ``Ts``): ``J theta'' = N u - D theta' + load_torque - f_c + d``, ``d' = 0``, with
    ``J = N^2 J_eq``, ``D = N^2 d_eq``; measured ``theta``.

    Parameters
    ----------
    info : LoopInfo
        Design-time plant knowledge.
    Ts : float
        Sample period [s].
    bandwidth : float
        Observer poles at ``exp(-2 pi bandwidth Ts)`` [Hz].
    """

    __slots__ = ("A", "B", "L", "x", "N", "_tl")

    def __init__(self, info: LoopInfo, Ts: float, bandwidth: float) -> None:
        N = info.N
        J, D = N * N * info.J_eq, N * N * info.d_eq
        Ac = np.array([[0.0, 1.0, 0.0], [0.0, -D / J, 1.0 / J], [0.0, 0.0, 0.0]])
        Bc = np.array([[0.0], [1.0 / J], [0.0]])
        M = np.zeros((4, 4))
        M[:3, :3], M[:3, 3:] = Ac, Bc
        E = scipy.linalg.expm(M * Ts)
        A, B = E[:3, :3], E[:3, 3]
        p = math.exp(-2 * math.pi * bandwidth * Ts)
        C = np.array([1.0, 0.0, 0.0])
        obs = np.vstack([C, C @ A, C @ A @ A])  # observability matrix
        phi = (A - p * np.eye(3)) @ (A - p * np.eye(3)) @ (A - p * np.eye(3))  # Ackermann, triple pole
        L = phi @ np.linalg.solve(obs, np.array([0.0, 0.0, 1.0]))
        self.A = tuple(tuple(float(v) for v in row) for row in A)
        self.B = tuple(float(v) for v in B)  # input: load-side torque [N m]
        self.L = tuple(float(v) for v in L)
        self.N = N
        self._tl = info.plant.load_torque
        self.x: list[float] | None = None

    def reset(self) -> None:
        """Forget the estimate (re-initialised from the first measurement)."""
        self.x = None

    @property
    def disturbance(self) -> float:
        """Estimated load-torque disturbance ``d`` [N m] (0 before the first update)."""
        return 0.0 if self.x is None else self.x[2]

    def update(self, theta: float, u: float, friction: float, freeze: bool) -> None:
        """Predict the next estimate from measurement ``theta`` [rad] and motor torque ``u`` [N m].

        ``friction``: the model's Coulomb torque on the load against the motion [N m]; ``freeze``: keep
        ``d`` (the model does not hold: a crossing is under way).
        """
        if self.x is None:
            self.x = [theta, 0.0, 0.0]
            return
        th, om, d = self.x
        e = theta - th
        (a00, a01, a02), (a10, a11, a12), _ = self.A
        b0, b1, _ = self.B
        l0, l1, l2 = self.L
        tau = self.N * u + self._tl - friction
        self.x = [a00 * th + a01 * om + a02 * d + b0 * tau + l0 * e,
                  a10 * th + a11 * om + a12 * d + b1 * tau + l1 * e,
                  d if freeze else d + l2 * e]


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class InverseSettings:
    """The inverse's own keys of a ``deadzone_inverse`` file."""

    rule: str = "torque"
    width: float | None = quantity(unit="N m or rad/s", doc="hysteresis of the flank decision: the transmitted "
                                   "torque (torque rule: N m) or reference speed (velocity rule: rad/s) that "
                                   "changes the flank", low=0.0, low_open=True, high=1e3, optional=True,
                                   default=None)
    backlash: float | None = BACKLASH.field(default=None, optional=True, doc="backlash estimate (default: the "
                                            "model's)")
    crossing_time: float = quantity(unit="s", doc="time the motor takes to cross the gap (sin^2 ramp of the "
                                    "offset; 0: a step)", low=0.0, high=1.0, default=0.01)
    observer_hz: float = quantity(unit="Hz", doc="bandwidth of the load-disturbance observer (0: none, the "
                                  "flank follows the reference alone)", low=0.0, high=1e3, default=5.0)
    disturbance_threshold: float = quantity(unit="N m", doc="load torque the observer must see beyond the load's "
                                            "static friction before it changes the flank", low=0.0, high=1e3,
                                            default=0.02)
    friction_feedforward: bool = True

    def __post_init__(self) -> None:
        check_choice("rule", self.rule, ("torque", "velocity"))
        check_choice("friction_feedforward", self.friction_feedforward, (True, False))
        validate_fields(self)


class DeadzoneInverse(Controller):
    """A PID wrapped in a backlash (dead-zone) inverse.

    Parameters
    ----------
    pid : PID
        The position PID it wraps (its feedback setting decides the structure, see Notes).
    backlash : float
        Backlash estimate ``b`` along the line of action [m] (from the model or the controller file,
        so that a wrong estimate can be tested).
    rule : str
        ``"torque"`` (default) or ``"velocity"``: what decides the flank.
    width : float, optional
        Hysteresis of the flank decision: [N m] for the torque rule (default 5e-4), [rad/s] for the
        velocity rule (default 1e-2).
    crossing_time : float
        Duration of a crossing of the whole gap, ``sin^2`` ramp [s] (0: a step of the target).
    observer_hz : float
        Bandwidth of the load-disturbance observer [Hz] (0: no observer; the torque rule then uses
        the model's known load torque alone).
    disturbance_threshold : float
        Estimated load torque beyond the static friction that enters the flank decision [N m].
    friction_feedforward : bool
        Feed the model's load Coulomb friction ``T_c2 sign(r') / N`` forward.
    name : str
        Label.

    Notes
    -----
    With motor-side feedback the PID regulates ``theta1 / N`` to ``r + o``, ``o`` the offset moving
    between ``-b / r_b2`` and ``+b / r_b2``. With load-side feedback the proportional and derivative action
    stay on the motor encoder (collocated, so the loop is stable in the gap too, where the load is not
    connected), aimed at ``r + o``, and the integral acts on the load error ``r - theta2``, which removes
    what the offset misses (a wrong backlash estimate, mesh deflection). Before the first flank decision
    the offset is 0 (the motor centred in the gap, as the plant starts).
    """

    def __init__(self, pid: PID, *, backlash: float, rule: str = "torque", width: float | None = None,
                 crossing_time: float = 0.01, observer_hz: float = 5.0, disturbance_threshold: float = 0.02,
                 friction_feedforward: bool = True, name: str = "deadzone_inverse") -> None:
        super().__init__()
        check_choice("rule", rule, ("torque", "velocity"))
        BACKLASH.check("backlash", backlash)
        self.pid, self.backlash, self.rule, self.name = pid, backlash, rule, name
        self.width = width if width is not None else (5e-4 if rule == "torque" else 1e-2)
        if not (self.width > 0 and math.isfinite(self.width)):
            raise InputError(f"width = {self.width!r} is out of range: expected a number > 0", field="width")
        for key, v, hi in (("crossing_time", crossing_time, 1.0), ("observer_hz", observer_hz, 0.5 / pid.Ts),
                           ("disturbance_threshold", disturbance_threshold, 1e3)):
            if not (0.0 <= v <= hi):
                raise InputError(f"{key} = {v!r} is out of range: expected 0 <= value <= {hi:g}", field=key)
        self.crossing_time, self.observer_hz = crossing_time, observer_hz
        self.disturbance_threshold = disturbance_threshold
        self.friction_feedforward = bool(friction_feedforward)
        self.Ts = pid.Ts
        self.uses_load_encoder = pid.feedback == "load"
        p = pid.info.plant
        self._J2, self._d2, self._tl = p.J2, p.d2, p.load_torque
        self._tc2 = p.tc2
        self._ramp = OffsetRamp("sin2" if crossing_time > 0.0 else "step", crossing_time, 0.0)
        self._sigma, self._t, self._cross_end = 0.0, 0.0, -math.inf
        self.set_backlash(backlash)
        self._observer = LoadObserver(pid.info, pid.Ts, observer_hz) if observer_hz > 0.0 else None
        self.reset()

    def set_backlash(self, backlash: float) -> None:
        """Change the backlash estimate ``b`` [m] (e.g. an adaptive law's), keeping every other state.

        The offset moves to the held flank of the new estimate along the crossing ramp.
        """
        BACKLASH.check("backlash", backlash)
        self.backlash = backlash
        self._offset = backlash / self.pid.info.plant.rb2  # half the lost motion, load angle [rad]
        self._ramp.span = 2.0 * self._offset
        if self._sigma != 0.0:  # in contact the motor follows the new offset; a crossing lands on it
            self._ramp.move_to(self._t, self._sigma * self._offset)
            if self._t < self._cross_end:
                self._cross_end = self._ramp.end

    def reset(self) -> None:
        """Reset the wrapped PID, the observer, the offset (centred) and the held flank."""
        self.pid.reset()
        self._sigma = 0.0
        self._t = 0.0
        self._cross_end = -math.inf  # end of the crossing under way (the motor is off the load until then)
        self._free = [0.0, 0.0]
        self._was_free = False
        self._moving_ref = False
        self._rdd_prev = 0.0
        self._lag: tuple[float, float, float] | None = None
        self._ramp.reset(0.0)
        if self._observer is not None:
            self._observer.reset()
        self.solve_times, self.fallbacks = [], []

    @property
    def disturbance(self) -> float:
        """The observer's load-torque disturbance estimate [N m] (0 without an observer)."""
        return 0.0 if self._observer is None else self._observer.disturbance

    def _disturbance_beyond_friction(self) -> float:
        """The estimated disturbance less what the load's static friction and the threshold explain [N m]."""
        d = self.disturbance
        lim = self._tc2 + self.disturbance_threshold
        return math.copysign(abs(d) - lim, d) if abs(d) > lim else 0.0

    def transmitted_torque(self, r_d: float, r_dd: float) -> float:
        """Torque the mesh must give the load to follow ``(r', r'')`` [N m]: the model's inertia, friction and
        load torque, and the estimated disturbance beyond what the load's static friction and
        ``disturbance_threshold`` explain (the observer also sees the static friction's reaction at rest)."""
        drive = self._J2 * r_dd + self._d2 * r_d - self._tl - self._disturbance_beyond_friction()
        if self._tc2 > 0.0 and r_d != 0.0:  # full Coulomb friction while the load moves
            drive += math.copysign(self._tc2, r_d)
        return drive

    def flank(self, t: float, ref: ReferenceLike) -> float:
        """The flank that must carry the load, +1 front or -1 back (0 before the first decision).

        While the reference moves, the flank changes when the transmitted torque (or, for the velocity
        rule, the reference speed) passes ``+-width``; at rest (``r' = r'' = 0``), only when the estimated
        load torque exceeds the load's static friction by ``disturbance_threshold`` (torque rule).
        """
        _, rd, rdd = ref.at(t)
        w = self.width
        if rd == 0.0 and rdd == 0.0:  # at rest: only a load torque friction cannot hold changes the flank
            if self.rule == "torque":
                need = -(self._tl + self.disturbance)
                if abs(need) > self._tc2 + self.disturbance_threshold:
                    self._sigma = 1.0 if need > 0.0 else -1.0
            return self._sigma
        drive = self.transmitted_torque(rd, rdd) if self.rule == "torque" else rd
        if drive > w:
            self._sigma = 1.0
        elif drive < -w:
            self._sigma = -1.0
        return self._sigma

    def _start_crossing(self, t: float, sigma_old: float, y_motor: float, y_load: float | None, rd: float) -> None:
        """Where the load is when the motor leaves its flank: the state the crossing lands on."""
        N = self.pid.N
        if self.uses_load_encoder and y_load is not None:
            theta = float(y_load)
        else:  # in contact with the old flank (or centred before the first decision)
            theta = y_motor / N - self._ramp.at(t)[0]
        obs = self._observer
        omega = obs.x[1] if (obs is not None and obs.x is not None) else rd
        self._free = [theta, omega]

    def _free_load(self) -> tuple[float, float, float]:
        """Advance the free load's predicted state one sample (its friction, load torque and estimated
        disturbance; static friction holds it at rest) and return ``(theta, omega, alpha)``."""
        th, om = self._free
        Ts, J2 = self.Ts, self._J2
        tau = self._tl + self.disturbance - self._d2 * om
        if om == 0.0 and abs(tau) <= self._tc2:
            return th, 0.0, 0.0
        f = math.copysign(self._tc2, om if om != 0.0 else tau)
        alpha = (tau - f) / J2
        om_new = om + Ts * alpha
        if om != 0.0 and om_new * om < 0.0 and abs(tau) <= self._tc2:  # friction stops it within the sample
            om_new, alpha = 0.0, -om / Ts
        self._free = [th + Ts * 0.5 * (om + om_new), om_new]
        return th, om, alpha

    def step(self, t: float, y_motor: float, y_load: float | None, ref: ReferenceLike) -> float:
        r, rd, rdd = ref.at(t)
        self._t = t
        rdd_prev, self._rdd_prev = self._rdd_prev, rdd
        if self.backlash == 0.0:  # no gap to invert: the PID with the inverse's feedforward corrections
            return offset_torque(self.pid, t, r, rd, rdd + 0.5 * (rdd - rdd_prev), (0.0, 0.0, 0.0), 0.0, y_motor,
                                 y_load)
        if self._tc2 > 0.0 and rd != 0.0 and not self._moving_ref:
            # a move starts: what the integrator held against the load's static friction at rest is released
            # (the friction feedforward takes over); it keeps the disturbance the observer sees beyond friction
            self.pid._i = -self._disturbance_beyond_friction() / self.pid.N
        self._moving_ref = rd != 0.0
        sigma_old = self._sigma
        sigma = self.flank(t, ref)
        if sigma != sigma_old:
            if t >= self._cross_end:
                self._start_crossing(t, sigma_old, y_motor, y_load, rd)
            self._ramp.move_to(t, sigma * self._offset)
            self._cross_end = self._ramp.end
        off = self._ramp.at(t)
        friction = math.copysign(self._tc2, rd) if (self._tc2 > 0.0 and rd != 0.0) else 0.0
        extra = friction / self.pid.N if self.friction_feedforward else 0.0
        free = t < self._cross_end
        if free:  # the motor lands on where the load is predicted to be, not on where the reference is
            r_c, rd_c, rdd_c = self._free_load()
            self._was_free = True
            u = offset_torque(self.pid, t, r_c, rd_c, rdd_c, off, 0.0, y_motor, y_load, free=True)
        else:
            if self._was_free:  # landed: the load's lag behind the reference is taken up smoothly
                self._was_free = False
                th, om = self._free
                self._lag = (r - th, rd - om, t)
            if self._lag is not None:
                d0, dd0, t0 = self._lag
                T = max(self.crossing_time, self.Ts)
                x = (t - t0) / T
                if x >= 1.0:
                    self._lag = None
                else:  # cubic Hermite from (d0, d0') to (0, 0)
                    h00, h10 = 2 * x**3 - 3 * x**2 + 1, x**3 - 2 * x**2 + x
                    h00d, h10d = 6 * x**2 - 6 * x, 3 * x**2 - 4 * x + 1
                    h00dd, h10dd = 12 * x - 6, 6 * x - 4
                    r -= d0 * h00 + T * dd0 * h10
                    rd -= (d0 * h00d + T * dd0 * h10d) / T
                    rdd -= (d0 * h00dd + T * dd0 * h10dd) / T**2
            # the torque is held over the coming sample: feed forward the acceleration at its middle,
            # extrapolated from the last two samples (no preview)
            u = offset_torque(self.pid, t, r, rd, rdd + 0.5 * (rdd - rdd_prev), off, extra, y_motor, y_load)
        obs = self._observer
        if obs is not None:  # the train model does not hold while the motor crosses, nor just after a landing
            theta = float(y_load) if (self.uses_load_encoder and y_load is not None) else y_motor / self.pid.N - off[0]
            settling = free or t < self._cross_end + self.crossing_time
            obs.update(theta, u if not free else 0.0, friction, settling)
        return u

    def describe(self) -> dict[str, Any]:
        """Settings of the inverse and of the PID."""
        return {**self.pid.describe(), "name": self.name, "kind": "deadzone_inverse", "preview": self.preview,
                "rule": self.rule, "width": self.width, "backlash_estimate": self.backlash,
                "crossing_time": self.crossing_time, "observer_hz": self.observer_hz,
                "disturbance_threshold": self.disturbance_threshold, "friction_feedforward": self.friction_feedforward}


#: The keys of a ``deadzone_inverse`` controller file and the settings fields they feed.
LAYOUT: Layout = {"": {**LOOP_KEYS, **{f.name: (InverseSettings, f.name) for f in dataclasses.fields(InverseSettings)}},
                  **PID_TABLES}


def build(path: Path, spec: dict[str, Any], info: LoopInfo, *, name: str,
          backlash: float | None = None) -> DeadzoneInverse:
    """The inverse of a ``kind = "deadzone_inverse"`` file; ``backlash`` overrides the file's estimate."""
    values = spec_values(path, spec, LAYOUT, kind=KIND)
    loop = build_dataclass(path, LoopSettings, values.get(LoopSettings, {}))
    settings = build_dataclass(path, InverseSettings, values.get(InverseSettings, {}))
    b = backlash if backlash is not None else (settings.backlash if settings.backlash is not None
                                               else info.plant.backlash)
    pid = pid_from_values(path, values, info, loop, name + "/pid")
    try:
        return DeadzoneInverse(pid, backlash=b, rule=settings.rule, width=settings.width,
                               crossing_time=settings.crossing_time, observer_hz=settings.observer_hz,
                               disturbance_threshold=settings.disturbance_threshold,
                               friction_feedforward=settings.friction_feedforward, name=name)
    except InputError as exc:
        raise restate(path, exc, values) from None
