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
- *At rest, no crossing.* A change decided at rest is no crossing: with the motor encoder the observer sees
  the load only through the mesh, so the load already rests on the new flank. The offset moves there at once
  and the jump of the motor's target is taken up in contact (the take-up's cubic, see *The landing*), braking at
  most :data:`TAKE_UP_ACCELERATION` of ``|load_torque + d_hat| / J2`` (what holds the load on that flank); the
  integrator lets go of the friction as when a move starts. Why: on a reviewer's 40 kg m^2 turntable the step's
  first decision (its motor still "centred") came while the motor dragged the overshot load back on the back
  flank; the half-gap crossing fed the free motor's ramp torque (-296 N m, then +277) to the whole train, the
  load slid back and rested one lost motion short (1.93 mrad; the PID's 0.97), now 0.09 mrad.
- *Pressing the other flank.* At rest, a motor that pushes against its held flank's direction harder than its own
  Coulomb friction can hold (by more than ``disturbance_threshold`` over the ratio) and does not move (less than
  :data:`PRESS_TRAVEL` of the half gap) for :data:`PRESS_TIME` can only be pressing the other flank: the change is
  made at rest, no crossing (above). It is a load that a dead stop sent across the gap, where static friction holds
  it: the observer sees the motor's torque held against friction, within what the friction explains, and before
  this rule the inverse kept the old flank and held the load a whole lost motion off (``gearctl track
  shing1993_servo_friction deadzone_inverse --reference ramp``: final error -1.33e-3 rad against the PID's
  -0.67e-3; now 2.7e-5, RMS 8.5e-4 against 1.46e-3). On a reviewer's servo with the friction on the motor shaft
  (``tests/data/motor_friction.toml``) ISO 230-2 A went from 1089 to 114 urad; moves, steps and sines of the catalog
  servos are unchanged to the last bit. (Read from the observer's disturbance alone, the same rule misfired on a
  reviewer's CNC table, whose motor pulls back off the flank for a few samples after a move: A 88 -> 2102 urad.)
- *Too late to land.* A flank change that the reference's end would overtake is not made: while the reference
  comes to rest through a fading deceleration (``r' r'' < 0``, ``|r''|`` below the last sample's), a change
  is skipped when the reference stops (in ``2 |r'| / |r''|``, an S-curve's end) before a crossing could land
  (``crossing_time``). It is the end of a move on a load with Coulomb friction: in the last milliseconds the
  friction decelerates the load more than the reference asks and the driving flank would have to push. The
  crossing lands after the load has stopped, so it cannot help, and on a reviewer's CNC table the motor that
  arrived on the driving flank held the load 30 urad short of the targets approached after the 0.02 rad
  overshoot moves (ISO A 178 urad against the PID's 86; 88 now). A sine's top is not a rest: its
  deceleration grows. Counted in ``late_changes_skipped``.
- *A braking need within friction's uncertainty.* On a load with Coulomb friction the torque the mesh must transmit
  in a deceleration dips below zero only where the reference's deceleration exceeds what friction gives the load.
  Where the two are about equal the dip is a few mN m against a friction of tenths of a N m: less than the friction
  is known to, and so brief that a change to the braking flank means two crossings within a few tens of ms with
  next to nothing pressing the load on the braking flank. The load floats off it, and the crossing back lands on a
  load that is not where it is predicted and kicks it across the gap. On a reviewer's robot joint
  (``tests/data/h5_robot_joint_15x60_shifted.toml``: 0.4 N m of friction, a braking need of at most 2 mN m over
  12 ms) the load was left up to a whole lost motion past the targets: ISO 230-2 A 3553 urad against the PID's
  1983, now 48. So a change to the braking flank in motion (``sigma r' > 0`` held) on a load with Coulomb friction
  waits while the braking need is under :data:`FRICTION_MARGIN` of ``T_c2``; the return to the driving flank, a
  reversal's change and the decisions at rest are as before. Meanwhile the inverse integrates the lead the load
  would take on the driving flank, free (``lead'' = -sigma T / J2``, held at zero while the flank pushes), and a
  crossing that follows starts from the load where it puts it. Counted in ``braking_changes_skipped``. Every catalog
  figure is unchanged to the last bit (their braking needs are none or far beyond the margin).
- *The crossing.* A flank change moves the offset from one flank to the other along a ``sin^2`` ramp of
  ``crossing_time`` (zero relative speed at both ends), aimed at where the load is predicted to be (its
  state when the motor left it, advanced with its inertia, friction and estimated load torque: a load
  stuck by friction stays put, an inertial one coasts; at start-up the load is at rest), not at the
  reference. While the motor is alone its feedforward is the free motor's, ``N (J1 a + d1 v)`` with ``a`` the
  mean acceleration of the target over the sample the torque is held (the ramp's and the free load's:
  the motor then follows the ramp to a few urad), and the PID's feedback is scaled by ``J1 / J_eq`` (the
  same loop on the 4x lighter motor rings across the gap). On a train ``J1``, ``d1`` and ``T_c1`` are what the
  motor moves: its own shaft until the first stage's gap closes, then with the intermediate shafts it has
  picked up (:func:`carried_by_motor`; the design pair lumps them all on the motor shaft, and on
  ``servo_2stage_phm09`` that feedforward drove the motor ahead of its ramp into the intermediate shaft, which it
  flung into the load: sine RMS 5.32e-4 rad, now 7.5e-5). A step of ``2 b / r_b2`` in the PID's target
  instead makes the PID ring at its bandwidth, and the load leaves the moves with the ring's speed.
- *Contact before the ramp's end.* With a backlash estimate that is too large the motor meets the load
  before its ramp ends, and then falls behind the motion its torques would give it alone (it pushes the load,
  or bounced off it). When, in the second half of a crossing that started from a settled flank, the motor
  lags that free motion by more than :data:`CONTACT_LAG` of half the lost motion, the crossing ends there:
  the offset stops at the furthest point the motor reached relative to the predicted load (the flank), and
  the contact control takes over. The free motion starts from the motor's state when it left the flank and is
  re-anchored on the measured motor at mid-crossing (the observer's start speed lags where friction stops the
  load); the ramp itself is no reference, since the loop follows it only as well as its bandwidth lets it (the
  check once stopped every crossing short at a friction load's reversals, see :meth:`_check_contact`).
  An estimate that is too small is kept (the motor stops short of the flank): the estimate bounds how far
  the motor goes. On a train the check is off: the motor meets the intermediate shafts before the load, and
  their impacts make it lag as a too large estimate would.
- *A prediction outside the gap.* The load cannot be farther from the motor than half the lost motion (plus the
  mesh's deflection): where the predicted free load is more than :data:`FREE_LOAD_REACH` half lost motions from
  the motor, now or a sample on (with the motor keeping pace with the load's present speed), it met a flank in
  truth, and the crossing ends there, on the new flank, the contact control taking over (counted in
  ``free_load_exits``). Why: on a fuzzed train whose load is 1.7e-10 kg m^2 the observer's disturbance of a few
  mN m accelerated the predicted load at 1e7 rad/s^2; it was predicted 6.6 rad away within a sample, the motor
  chased it at the torque limit and the sine ran at 154 rad RMS (the PID: 6.7e-3).
- *Below a count.* Where the model's backlash gives a lost motion under one count of the motor encoder (at the
  motor), the offset would move the motor by less than the loop resolves, and the crossings only disturb it: the
  inverse runs as its PID and says so in its design notes (a ``backlash`` in the file, or given by the caller,
  inverts it anyway). Why: on a fuzzed speed-up pair whose lost motion is a tenth of a count
  (``tests/data/speedup_light_load.toml``) the inverse's sine was 1.3x the PID's RMS (1.85e-3 against 1.43e-3 rad;
  4x before its crossings stopped at the gap's edge).
- *The landing.* After a landing the load's lag behind the reference is taken up along a cubic over
  ``crossing_time``, or longer so that it asks at most :data:`TAKE_UP_ACCELERATION` of the load
  acceleration the torque limit gives; a lag larger than half the lost motion is no landing residual
  (start-up, a disturbance) and is left to the PID.
- *The stop.* A flank pushes the load one way only. A load that comes to rest on its braking flank with
  nothing else to stop it (no Coulomb friction, no load torque the flank carries) must not be pushed back:
  the motor would stop and the load float off at the speed it was given (1e-3 rad/s after a 0.02 rad
  move of the frictionless ``shing1993_servo``: 300 urad over a 0.3 s dwell). So while the reference
  brakes on the held flank with a fading deceleration (an S-curve's end, and the rest after it; not a
  sine's top, after which the same flank drives the return), an error under half the lost motion that asks
  for that push gets no proportional or integral action, what the integrator holds that way is dropped with it,
  and the integrator is emptied once on arrival at rest: the load stops where it is, a few tens of urad past the
  target at worst, instead of drifting (:meth:`DeadzoneInverse._one_way`). (Without the drop, an integral built
  while the crossing's landing was corrected kept pushing: after the 0.02 rad overshoot moves with ``b = 5 um`` it
  launched the load off its flank at 1.1e-3 rad/s, across the whole gap. With it, ISO 230-2 A on
  ``shing1993_servo`` went from 218 to 171 urad, and with ``b = 10 um`` from 500 to 131, the PID's 282.) A dead
  stop (a ramp's or a trapezoid's end, which launches the load) and a larger error are corrected as in motion.
  Before the drop, on that servo's ISO 230-2 test the rule took A / B / R from 2125 / 712 / 1562 to 210 / 47 /
  139 urad (the shifted 17-tooth pinion's from 3952 / 960 / 2754 to 227 / 43 / 143, and 217 / 48 / 153 with its
  load-scaled width; with the drop 166 / 54 / 94); the
  sine, the step, the ramp and trapezoidal moves are unchanged to the last bit, the S-curve move is a little
  better, and every figure on a load with friction is unchanged.
- *Rattle guard.* A motor whose speed jumps by more than the torque explains (more than
  :attr:`DeadzoneInverse.jump_threshold`, half the speed at which it crosses the whole gap in two samples)
  is hitting a flank; when such jumps come in a run (a leaky count above :data:`RATTLE_LEVEL`) the motor is
  rattling between the flanks, which the PID's derivative action can feed on a nearly elastic mesh (the
  Yang-Sun law at high impact speed). The feedback in contact is then scaled by ``RATTLE_GAIN J1 / J_eq``
  until the jumps stop, but never while the motor's error exceeds :data:`RATTLE_MAX_ERROR` lost motions: the gap
  cannot explain it, and a reviewer's 5 um CNC table (``tests/data/cnc_table_tight.toml``) swung for a second after its
  start-up with the softened loop (2.87e-4 rad RMS, now 7.1e-6).
- *Feedforward.* The PID feeds the rigid train's torque forward (inertia at mid-sample, viscous and Coulomb
  friction, the load torque) and matches its derivative filter (see :class:`~gearctl.design.pid.PID`).
  When a move starts on a load with Coulomb friction, the PID's integrator is set to the disturbance the
  observer sees beyond the static friction: what it held against the stuck load at rest is released.

With ``backlash = 0`` the inverse is the PID it wraps (bit for bit: no offset, no observer). Its preview is
1 (it reads ``r(t)`` only, like the PID).

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

Limits (measured, see ``tests/test_compensation.py``): on a load without friction (``shing1993_servo``)
nothing holds the load once it rests on a flank with no force on it. ISO 230-2 there gives A / B / R of 171 /
57 / 96 urad (the PID's 1483 / 1317 / 1348; the backlash-free PID's 1.4 / 0.9 / 1.2). Two things leave the
load moving:

- *The short overshoot moves* (0.02 rad after each end target) cross to the braking flank in the middle of
  the deceleration, and the landing leaves the load some 50 urad past the target. The stop rule does not push
  it back: it rebounds off the flank at about 2e-4 rad/s;
- *The motor's hunting at rest.* The PID holds the motor to a few encoder counts, and its speed wanders by
  about 1e-3 rad/s. When the braking flank's force reaches zero, the load leaves at the motor's speed over
  the ratio, 1e-5 to 2e-4 rad/s, and drifts 3-60 urad over the 0.3 s dwell (its viscous time constant is
  2.5 s). Only impacts slower than the kernel's plastic limit (1e-6 m/s along the line of action, 1.3e-5
  rad/s at this load) leave it at rest.

Reaching the backlash-free figure on such a load would need a preloaded (anti-backlash) train, or a motor that
leaves the flank without hunting.

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
from ..params import Sensors
from ..plant import Plant
from ..units import BACKLASH, Spec, check_choice, quantity, validate_fields
from .base import Controller, LoopInfo
from .pid import LOOP_KEYS, PID, PID_TABLES, LoopSettings, check_readings, pid_from_values, restate

__all__ = ["DeadzoneInverse", "InverseSettings", "LoadObserver", "OffsetRamp", "RAMPS", "ramp_shape",
           "carried_by_motor", "offset_torque", "CROSSING_TIME", "KIND", "LAYOUT", "build"]

#: The controller-file kind this module builds (:mod:`gearctl.design.registry`).
KIND = "deadzone_inverse"

#: A crossing ends early when the motor lags its free motion by this share of half the lost motion (it met the load).
CONTACT_LAG = 0.05
#: A crossing ends at once where the predicted free load is farther than this many half lost motions from the
#: motor (outside the gap, where no load can be: it met a flank).
FREE_LOAD_REACH = 1.5
#: At rest, a motor pressing against its held flank's direction this long [s] without moving is on the other flank
#: (see *Pressing the other flank* in the module docstring) ...
PRESS_TIME = 0.02
#: ... where not moving is moving less than this share of the half gap (the load angle's ``offset``).
PRESS_TRAVEL = 0.05
#: Rattle guard: a motor speed jump above ``jump_threshold`` counts 1 in a level that decays by RATTLE_DECAY per
#: sample; above RATTLE_LEVEL the feedback in contact is scaled by RATTLE_GAIN J1 / J_eq until the level drops
#: below 1.
RATTLE_DECAY, RATTLE_LEVEL, RATTLE_GAIN = 0.9, 3.0, 0.25
#: ... but never while the motor's error exceeds this many lost motions (2 b / r_b2): a rattle in the gap cannot explain
#: it. On a 5 um CNC table the softened loop left the start-up's mrad error to swing for a second (the
#: ``tests/data/cnc_table_tight.toml`` test); on the Yang-Sun rattle of a 15 ms crossing half a lost motion was too
#: tight (1384 impacts in 3 s, 362 unbounded), two gave 420 impacts and 1.2e-4 rad RMS (unbounded 2.8e-4)
RATTLE_MAX_ERROR = 2.0
#: The torque scale of the default width and disturbance threshold: the load's inertial and viscous torque at the
#: peak of a sine of this amplitude [rad] and angular frequency [rad/s] (the catalog sine), and its value on the
#: benchmark servo [N m] (``shing1993_servo``: J2 = 0.010019 kg m^2, d2 = 2e-3 N m s/rad), where the defaults are
#: 5e-4 and 0.02 N m exactly.
_REF_AMPLITUDE, _REF_OMEGA = 0.1, 2.0 * math.pi
_BENCH_LOAD_TORQUE = 0.0408081125116859
#: A change to the braking flank in motion on a load with Coulomb friction waits while the braking need is under this
#: share of the friction ``T_c2``, less than a Coulomb friction is known to (see *A braking need within friction's
#: uncertainty*)
FRICTION_MARGIN = 0.05
#: A landing's lag is taken up asking at most this share of the load acceleration the torque limit gives.
TAKE_UP_ACCELERATION = 0.25

#: Shortest ramp of the offset [s], the shortest sample time; a shorter one (a tiny share of a crossing) is a step.
MIN_RAMP_TIME = 1e-6

#: A crossing time [s]: 0 (a step) or at least a microsecond, the shortest sample time. Shorter ones are a step in
#: effect, and a ramp of 1e-308 s started at t = 0 divided its acceleration by T^2 = 0 (a traceback).
CROSSING_TIME = Spec(unit="s", doc="time the motor takes to cross the gap (sin^2 ramp of the offset; 0: a step)",
                     low=0.0, high=1.0, floor=1e-6)

#: Shapes of the offset's ramp between the flanks (``sin2``: Beckhoff's; ``linear``: Heidenhain's speed
#: command held over the compensation time; ``step``: all in one sample).
RAMPS = ("sin2", "linear", "step")


def ramp_shape(shape: str, x: float) -> tuple[float, float, float]:
    """Ramp from 0 to 1 over ``0 <= x <= 1`` and its first two derivatives in ``x``.

    ``sin2``: ``sin^2(pi x / 2)`` (zero slope at both ends); ``linear``: ``x``; ``step``: 1 for ``x > 0``.

    Parameters
    ----------
    shape : str
        One of :data:`RAMPS`; any other name is taken as ``step``.
    x : float
        Share of the ramp covered [1]; below 0 the ramp is at 0, from 1 on at 1.

    Returns
    -------
    tuple of float
        The ramp, its first and its second derivative in ``x``.

    Examples
    --------
    >>> round(ramp_shape("sin2", 0.5)[0], 12), ramp_shape("linear", 0.25), ramp_shape("step", 0.1)
    (0.5, (0.25, 1.0, 0.0), (1.0, 0.0, 0.0))
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
        """Rest at ``value``.

        Parameters
        ----------
        value : float
            The offset to rest at [rad] (default 0).
        """
        self._o0 = self._o1 = value
        self._t0, self._T = 0.0, 0.0

    @property
    def target(self) -> float:
        """The value the offset is moving to (or rests at)."""
        return self._o1

    @property
    def origin(self) -> float:
        """The value the last ramp started from (the rest value after :meth:`reset`)."""
        return self._o0

    @property
    def end(self) -> float:
        """Time the last ramp ends [s]."""
        return self._t0 + self._T

    def progress(self, t: float) -> float:
        """Share of the ramp under way covered at ``t``, 0 to 1 (1 at rest).

        Parameters
        ----------
        t : float
            Time [s].
        """
        if not self.moving(t):
            return 1.0
        return min(max((t - self._t0) / self._T, 0.0), 1.0)

    def moving(self, t: float) -> bool:
        """Whether a ramp is under way at ``t``.

        Parameters
        ----------
        t : float
            Time [s].
        """
        return self._T > 0.0 and t < self._t0 + self._T

    def move_to(self, t: float, value: float) -> None:
        """Start a ramp at ``t`` from the present offset to ``value``.

        The ramp takes ``duration`` times the share of ``span`` it covers (at most the whole ``duration``); a ramp
        shorter than a microsecond, or of shape ``step``, is a step.

        Parameters
        ----------
        t : float
            Start time [s].
        value : float
            The offset to move to [rad].
        """
        o = self.at(t)[0]
        dist = abs(value - o)
        frac = dist / self.span if self.span > 0.0 else 1.0
        self._o0, self._o1, self._t0 = o, value, t
        T = self.duration * min(frac, 1.0) if self.shape != "step" else 0.0
        # a ramp shorter than MIN_RAMP_TIME is a step: within any sample it is one, and its acceleration d / T^2
        # (T^2 underflowing to 0 for T below 1e-162) read at its start would be a spike, or a division by zero
        self._T = T if T >= MIN_RAMP_TIME else 0.0

    def at(self, t: float) -> tuple[float, float, float]:
        """Offset, its rate and its acceleration at ``t`` [rad, rad/s, rad/s^2].

        The ramp has ended exactly when :meth:`moving` says so (``t >= t0 + T``): ``(t - t0) / T`` can round
        below 1 at that instant, and the ramp's last acceleration fed forward after the landing kicked the
        motor off the load (a 0.2 N m spike on the benchmark servo, one sine reversal in eight).

        Parameters
        ----------
        t : float
            Time [s].
        """
        if not self.moving(t):
            return self._o1, 0.0, 0.0
        x = (t - self._t0) / self._T
        s, ds, dds = ramp_shape(self.shape, x)
        d = self._o1 - self._o0
        return self._o0 + d * s, d * ds / self._T, d * dds / (self._T * self._T)


def offset_torque(pid: PID, t: float, r: float, rd: float, a: float, offset: tuple[float, float, float],
                  y_motor: float, y_load: float | None, *, free: bool = False, scale: float = 1.0,
                  one_way: float = 0.0, carried: tuple[float, float, float] | None = None) -> float:
    """The wrapped PID's torque for the target ``r + o``, with the rigid train's feedforward in contact and the
    free motor's in the gap.

    Parameters
    ----------
    pid : PID
        The position PID (motor or load feedback).
    t : float
        Sample time [s].
    r, rd : float
        Reference and its speed [rad, rad/s].
    a : float
        Acceleration to feed forward [rad/s^2] (the reference's at mid-sample,
        :meth:`PID.reference_update`).
    offset : tuple of float
        ``(o, o', o'')``: the motor's offset from the reference and its derivatives [rad, rad/s, rad/s^2].
    y_motor : float
        Motor encoder [rad].
    y_load : float or None
        Load encoder [rad] (with load feedback the integral acts on ``r - y_load``).
    free : bool
        The motor is crossing the gap: the load is not attached.
    scale : float
        Factor on the PID's feedback in contact [1] (default 1; in the gap the factor is ``J / J_eq`` of what the
        motor carries instead).
    one_way : float
        ``sigma`` of a flank whose push-back is withheld (:meth:`DeadzoneInverse._one_way`; 0: none): an error
        that asks the motor to push the load in direction ``sigma`` gives no proportional or integral action, and
        then an integral that pushes that way is dropped.
    carried : tuple of float, optional
        ``(J, d, T_c)`` of what the motor moves while it crosses [kg m^2, N m s/rad, N m, at the motor]: on a
        train the motor shaft and the intermediate shafts it has picked up (:func:`carried_by_motor`). Default:
        the design pair's motor side, ``(J1, d1, T_c1)``.

    Notes
    -----
    The PID is given the target ``r + o`` with speed ``v = r' + o'`` and acceleration ``a + o''``. In contact
    its own feedforward (the rigid train's, see :class:`PID`) holds. While the motor crosses the gap the
    feedforward is the free motor's, ``N (J1 (a + o'') + d1 v) + T_c1 sign(v)``, without the load's inertia,
    friction or load torque, and the feedback is scaled by ``J1 / J_eq``: the loop then drives the motor
    alone with the crossover and damping it was designed for on the train (unscaled, the free motor rings
    across the gap). With the offset at rest (``o' = o'' = 0``) the PID sees exactly the reference.
    """
    o, do, ddo = offset
    N = pid.N
    v, acc = rd + do, a + ddo
    target = r + o
    ym = y_motor / N
    e_i = target - ym if (pid.feedback == "motor" or y_load is None) else r - float(y_load)
    e_p = target - ym
    if one_way * e_p > 0.0:  # the flank would push a coasting load back: no correction that way
        e_p = 0.0
        if one_way * e_i > 0.0:
            e_i = 0.0
        if one_way * pid.integral > 0.0:  # nor what the integrator holds that way: it would push the load back too
            pid.integral = 0.0
    if not free:
        return pid.torque(t, target, v, acc, e_p, ym, e_i, scale=scale)
    p = pid.info.plant
    J1, d1, tc1 = carried if carried is not None else (p.J1, p.d1, p.tc1)
    ff = 0.0
    if pid.feedforward:
        ff = N * (J1 * acc + d1 * v)
        if pid.friction > 0.0 and tc1 > 0.0 and v != 0.0:
            ff += math.copysign(tc1, v)
    return pid.torque(t, target, v, acc, target - ym, ym, e_i, ff=ff, scale=J1 / pid.info.J_eq)


def carried_by_motor(plant: Plant) -> tuple[tuple[float, float, float, float], ...]:
    """What the motor moves at each stretch of a crossing of the whole lost motion: one row per stage,
    ``(end, J, d, T_c)``.

    ``end`` is the share of the lost motion crossed [0..1] when the stage's gap closes (the stages close in
    order from the motor's; each stage's share is its lost motion at the output, ``2 b_i / (r_b2,i prod_(j > i)
    N_j)``, over the train's); ``J``, ``d`` and ``T_c`` are the inertia, viscous and Coulomb friction of the
    motor shaft and the intermediate shafts picked up before it, reflected to the motor [kg m^2, N m s/rad, N m].
    A pair has one row, ``(1, J1, d1, T_c1)``: its motor shaft. A stage without backlash ends where the one before
    it does (its shaft is always carried); a train without any ends every row but the last at 0.

    Why: the design pair of a train (:meth:`~gearctl.plant.Plant.equivalent_pair`) puts every intermediate shaft
    on the motor shaft. While the motor crosses the first stage's gap it moves alone, and a feedforward with the
    intermediate shafts' inertia drove it ahead of its ramp into the first intermediate shaft: on
    ``servo_2stage_phm09`` (its intermediate shaft half the motor's inertia, reflected) the motor met it at
    0.2 rad/s at the load and flung it into the load, 2.3 mrad of error at every reversal.

    Parameters
    ----------
    plant : Plant
        The nominal plant, a pair or a train.

    Returns
    -------
    tuple of tuple of float
        One ``(end, J, d, T_c)`` row per stage [1, kg m^2, N m s/rad, N m].
    """
    ratio_to = [math.prod(s.ratio for s in plant.stages[:j]) for j in range(len(plant.shafts))]
    lost = plant.stage_lost_motions
    total = plant.lost_motion
    rows, end, J, d, tc = [], 0.0, 0.0, 0.0, 0.0
    for i in range(plant.n_stages):
        sh = plant.shafts[i]
        J += sh.J / ratio_to[i] ** 2
        d += sh.d / ratio_to[i] ** 2
        tc += sh.tc / ratio_to[i]
        if i == plant.n_stages - 1:
            end = 1.0
        elif total > 0.0:
            end += lost[i] / total
        else:  # no gap anywhere (a crossing of an estimate alone): the motor always moves every shaft
            end = 0.0
        rows.append((end, J, d, tc))
    return tuple(rows)


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

    __slots__ = ("A", "B", "L", "x", "N", "_tl", "innovation")

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
        self.innovation = 0.0

    def reset(self) -> None:
        """Forget the estimate (re-initialised from the first measurement)."""
        self.x = None
        self.innovation = 0.0

    @property
    def disturbance(self) -> float:
        """Estimated load-torque disturbance ``d`` [N m] (0 before the first update)."""
        return 0.0 if self.x is None else self.x[2]

    def update(self, theta: float, u: float, friction: float, freeze: bool) -> None:
        """Predict the next estimate from measurement ``theta`` [rad] and motor torque ``u`` [N m].

        The first call only initialises the estimate at ``theta`` (at rest, no disturbance).

        Parameters
        ----------
        theta : float
            Measured load angle [rad].
        u : float
            Motor torque applied over the sample [N m].
        friction : float
            The model's Coulomb torque on the load against the motion [N m].
        freeze : bool
            Keep ``d`` (the model does not hold: a crossing is under way).
        """
        if self.x is None:
            self.x = [theta, 0.0, 0.0]
            return
        th, om, d = self.x
        e = theta - th
        self.innovation = e
        (a00, a01, a02), (a10, a11, a12), _ = self.A
        b0, b1, _ = self.B
        l0, l1, l2 = self.L
        tau = self.N * u + self._tl - friction
        self.x = [a00 * th + a01 * om + a02 * d + b0 * tau + l0 * e,
                  a10 * th + a11 * om + a12 * d + b1 * tau + l1 * e,
                  d if freeze else d + l2 * e]


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class InverseSettings:
    """The inverse's own keys of a ``deadzone_inverse`` file (see :class:`DeadzoneInverse`).

    Parameters
    ----------
    rule : str
        ``"torque"`` (default) or ``"velocity"``: what decides the flank.
    width : float, optional
        Hysteresis of the flank decision, (0, 1e3] [N m or rad/s]: the transmitted torque (torque rule, N m) or
        the reference speed (velocity rule, rad/s) that changes the flank (default: :class:`DeadzoneInverse`'s).
    backlash : float, optional
        Backlash estimate ``b`` along the line of action, 0..0.01 [m] (default: the model's).
    crossing_time : float
        Time the motor takes to cross the gap, 0 or 1e-6..1 [s] (``sin^2`` ramp of the offset; 0: a step;
        default 0.01).
    observer_hz : float
        Bandwidth of the load-disturbance observer, 0..1e3 [Hz] (0: none, the flank follows the reference alone;
        default 5).
    disturbance_threshold : float, optional
        Load torque the observer must see beyond the load's static friction before it changes the flank, 0..1e3
        [N m] (default: 0.02 N m scaled as the width).

    Raises
    ------
    InputError
        For a ``rule`` other than the two, or a value of wrong type or out of range (named).
    """

    rule: str = "torque"
    width: float | None = quantity(unit="N m or rad/s", doc="hysteresis of the flank decision: the transmitted "
                                   "torque (torque rule: N m) or reference speed (velocity rule: rad/s) that "
                                   "changes the flank", low=0.0, low_open=True, high=1e3, optional=True,
                                   default=None)
    backlash: float | None = BACKLASH.field(default=None, optional=True, doc="backlash estimate (default: the "
                                            "model's)")
    crossing_time: float = CROSSING_TIME.field(default=0.01)
    observer_hz: float = quantity(unit="Hz", doc="bandwidth of the load-disturbance observer (0: none, the "
                                  "flank follows the reference alone)", low=0.0, high=1e3, default=5.0)
    disturbance_threshold: float | None = quantity(unit="N m", doc="load torque the observer must see beyond the "
                                                   "load's static friction before it changes the flank (default: "
                                                   "0.02 N m scaled as the width)", low=0.0, high=1e3, optional=True,
                                                   default=None)

    def __post_init__(self) -> None:
        check_choice("rule", self.rule, ("torque", "velocity"))
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
    jump_floor : float
        Least threshold of the rattle guard on the motor speed's change over a sample [rad/s] (default 0: the
        backlash sets it; the catalog build sets it from the encoders, :func:`jump_floor`).
    name : str
        Label.

    Raises
    ------
    InputError
        If ``pid`` is not a :class:`~gearctl.design.pid.PID`, ``rule`` not one of the two, or ``jump_floor``,
        ``backlash`` (0..0.01 m), ``width`` (> 0), ``crossing_time``, ``observer_hz`` (0 up to the Nyquist
        frequency) or ``disturbance_threshold`` (0..1e3 N m) out of range (named).

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
                 crossing_time: float = 0.01, observer_hz: float = 5.0, disturbance_threshold: float | None = None,
                 jump_floor: float = 0.0, name: str = "deadzone_inverse") -> None:
        super().__init__()
        _check_pid(pid)
        check_choice("rule", rule, ("torque", "velocity"))
        if isinstance(jump_floor, bool) or not (isinstance(jump_floor, int | float) and 0.0 <= jump_floor < math.inf):
            raise InputError(f"jump_floor = {jump_floor!r} is out of range: expected a finite number >= 0 [rad/s]",
                             field="jump_floor")
        BACKLASH.check("backlash", backlash)
        self.pid, self.backlash, self.rule, self.name = pid, backlash, rule, name
        # the torque rule's defaults follow the torque the load itself needs: the benchmark servo's 5e-4 and 0.02 N m,
        # scaled down by the load's inertial and viscous torque on the catalog sine against that servo's (never up).
        # Absolute values left a 1 mN m instrument servo's inverse with a flank that never changed, its PID without a
        # word; scaled by the motor's capacity, N x torque_limit, the three-stage train got a width below its sweet
        # spot (ISO A 2701 urad, worse than its PID's 1602; now 868)
        p0 = pid.info.plant
        load = p0.J2 * _REF_AMPLITUDE * _REF_OMEGA**2 + p0.d2 * _REF_AMPLITUDE * _REF_OMEGA
        scale = min(load / _BENCH_LOAD_TORQUE, 1.0) if load > 0.0 and math.isfinite(load) else 1.0
        self.width = width if width is not None else (5e-4 * scale if rule == "torque" else 1e-2)
        if disturbance_threshold is None:
            disturbance_threshold = 0.02 * scale
        if not (self.width > 0 and math.isfinite(self.width)):
            raise InputError(f"width = {self.width!r} is out of range: expected a number > 0", field="width")
        CROSSING_TIME.check("crossing_time", crossing_time)
        for key, v, hi, unit in (("observer_hz", observer_hz, 0.5 / pid.Ts,
                                  f" [Hz] (at most the Nyquist frequency 0.5 / sample_time, sample_time = "
                                  f"{pid.Ts:g} s)"),
                                 ("disturbance_threshold", disturbance_threshold, 1e3, " [N m]")):
            if not (0.0 <= v <= hi):
                raise InputError(f"{key} = {v!r} is out of range: expected 0 <= value <= {hi:g}{unit}", field=key)
        self.crossing_time, self.observer_hz = crossing_time, observer_hz
        self.disturbance_threshold = disturbance_threshold
        self.Ts = pid.Ts
        self.uses_load_encoder = pid.feedback == "load"
        p = pid.info.plant
        self._J2, self._d2, self._tl = p.J2, p.d2, p.load_torque
        #: what follows the motor when it backs off a flank at rest, on the load shaft [kg m^2]: the load and every
        #: intermediate shaft (the design pair puts them on the motor shaft), reflected; the load's J2 on a pair
        self._J_follow = p.J2 + pid.N ** 2 * (p.J1 - pid.info.nominal.shafts[0].J)
        self._tc2 = p.tc2
        self._a_limit = pid.limit / (pid.N * pid.info.J_eq)  # load acceleration at the torque limit [rad/s^2]
        self._J1, self._d1, self._tc1 = p.J1, p.d1, p.tc1
        self._jump_den = 2.0 * p.rb1 * pid.Ts  # the rattle guard's threshold is b / this (set_backlash)
        #: the rattle guard's threshold is never below what the motor encoder's counts and noise alone give the motor
        #: speed's change over a sample [rad/s] (:func:`jump_floor`)
        self.jump_floor = jump_floor
        # on a train the motor meets the intermediate shafts before the load: their impacts make it lag its ramp as
        # a too large estimate would (6 false contacts in 3 s on servo_3stage_quanser_srv02 with a 5 ms crossing,
        # each stopping the offset short: the PID's error), so the contact check is a pair's
        self._contact_lag = CONTACT_LAG if pid.info.nominal.n_stages == 1 else math.inf
        #: what the motor moves at each stretch of a crossing (:func:`carried_by_motor`: on a train the intermediate
        #: shafts join it as their gaps close)
        self._carried = carried_by_motor(pid.info.nominal)
        self._ramp = OffsetRamp("sin2" if crossing_time > 0.0 else "step", crossing_time, 0.0)
        self._sigma, self._t, self._cross_end = 0.0, 0.0, -math.inf
        self.set_backlash(backlash)
        self._observer = LoadObserver(pid.info, pid.Ts, observer_hz) if observer_hz > 0.0 else None
        self.reset()

    def set_backlash(self, backlash: float) -> None:
        """Change the backlash estimate ``b`` [m] (e.g. an adaptive law's), keeping every other state.

        The offset moves to the held flank of the new estimate along the crossing ramp.

        Parameters
        ----------
        backlash : float
            The new estimate, 0..0.01 [m].

        Raises
        ------
        InputError
            For ``backlash`` out of range.
        """
        BACKLASH.check("backlash", backlash)
        self.backlash = backlash
        #: motor speed jump [rad/s] that counts as an impact for the rattle guard: half the speed at which the
        #: motor crosses the whole gap of the estimate in two samples (a fresh design's, whatever the estimate)
        self.jump_threshold = max(backlash / self._jump_den, self.jump_floor) if backlash > 0.0 else math.inf
        self._offset = backlash / self.pid.info.plant.rb2  # half the lost motion, load angle [rad]
        self._ramp.span = 2.0 * self._offset
        if self._sigma != 0.0:  # in contact the motor follows the new offset; a crossing lands on it
            self._ramp.move_to(self._t, self._sigma * self._offset)
            if self._t < self._cross_end:
                self._cross_end = self._ramp.end

    def set_crossing_time(self, crossing_time: float) -> None:
        """Change the crossing time [s] (:data:`CROSSING_TIME`: 0, or 1e-6 to 1) and with it the ramp: ``sin^2`` for a
        positive time, a step for 0 (as at construction). Every other state is kept.

        Call it with the offset at rest (``not self.offset_moving(t)``, e.g. an adaptive law between
        crossings): a ramp under way would go on in the new shape.

        Parameters
        ----------
        crossing_time : float
            The new crossing time, 0 or 1e-6..1 [s].

        Raises
        ------
        InputError
            For ``crossing_time`` out of range.
        """
        CROSSING_TIME.check("crossing_time", crossing_time)
        self.crossing_time = crossing_time
        self._ramp.shape = "sin2" if crossing_time > 0.0 else "step"
        self._ramp.duration = crossing_time

    @property
    def held_flank(self) -> float:
        """The flank the inverse holds: +1 front, -1 back, 0 before its first decision (the centred start-up)."""
        return self._sigma

    def offset_moving(self, t: float) -> bool:
        """Whether the offset is on its ramp at ``t`` [s] (a crossing, or a change of the estimate).

        Parameters
        ----------
        t : float
            Time [s].
        """
        return self._ramp.moving(t)

    def reset(self) -> None:
        """Reset the wrapped PID, the observer, the offset (centred) and the held flank (the backlash estimate
        and the crossing time are kept)."""
        self.pid.reset()
        self._sigma = 0.0
        self._t = 0.0
        self._cross_end = -math.inf  # end of the crossing under way (the motor is off the load until then)
        self._free = [0.0, 0.0]
        self._was_free = False
        self._moving_ref = False
        self._rdd_prev = 0.0
        self._rdd_before = 0.0
        self._stopped = False
        self._one_way_prev = False
        self._press: tuple[float, float] | None = None
        self._lag: tuple[float, float, float, float] | None = None
        self.contacts = 0
        self.free_load_exits = 0  # crossings ended because the predicted free load left the gap
        self.late_changes_skipped = 0  # flank changes the reference's rest would have overtaken
        self.braking_changes_skipped = 0  # braking-flank changes within friction's uncertainty (_braking_needed)
        self._lead = [0.0, 0.0]  # the lead the load would take on the driving flank, free, and its speed
        self._y_hist: tuple[float | None, float | None] = (None, None)
        self._u_hist = (0.0, 0.0)
        self._rattle = 0.0
        self.rattling = False
        self._reach = -math.inf
        self._motor_free: list[float] | None = None  # the free motor's predicted [angle, speed] (load units)
        self._motor_free_new = False
        self._motor_free_since: float | None = None  # the crossing's start, until re-anchored (_check_contact)
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
        ``disturbance_threshold`` explain (the observer also sees the static friction's reaction at rest).

        Parameters
        ----------
        r_d : float
            Reference speed [rad/s].
        r_dd : float
            Reference acceleration [rad/s^2].

        Returns
        -------
        float
            The torque on the load shaft [N m] (positive: the front flank drives).
        """
        drive = self._J2 * r_dd + self._d2 * r_d - self._tl - self._disturbance_beyond_friction()
        if self._tc2 > 0.0 and r_d != 0.0:  # full Coulomb friction while the load moves
            drive += math.copysign(self._tc2, r_d)
        return drive

    def flank(self, t: float, ref: ReferenceLike) -> float:
        """The flank that must carry the load, +1 front or -1 back (0 before the first decision).

        While the reference moves, the flank changes when the transmitted torque (or, for the velocity
        rule, the reference speed) passes ``+-width``, unless the reference comes to rest before a crossing
        could land (see *Too late to land* in the module docstring); at rest (``r' = r'' = 0``), only when the
        estimated load torque exceeds the load's static friction by ``disturbance_threshold`` (torque rule).
        (:meth:`step` also changes it at rest where the motor presses the other flank: see *Pressing the other
        flank* in the module docstring.)

        The decision is kept: a call changes the held flank (:attr:`held_flank`).

        Parameters
        ----------
        t : float
            Time [s].
        ref : ReferenceLike
            The reference (its ``at(t)`` gives angle, speed and acceleration).

        Returns
        -------
        float
            +1, -1 or 0.
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
        sigma = 1.0 if drive > w else (-1.0 if drive < -w else self._sigma)
        if not self._braking_needed(sigma, rd, drive):
            sigma = self._sigma
        stops_first = (rd * rdd < 0.0 and abs(rdd) < self._rdd_before
                       and 2.0 * abs(rd) < abs(rdd) * self.crossing_time)
        if self._sigma != 0.0 and sigma != self._sigma and stops_first:
            self.late_changes_skipped += 1
        else:
            self._sigma = sigma
        return self._sigma

    def _braking_needed(self, sigma: float, rd: float, drive: float) -> bool:
        """Whether a change to ``sigma`` may be made as far as the load's friction goes (see *A braking need within
        friction's uncertainty* in the module docstring): always, but for a change to the braking flank in motion on a
        load with Coulomb friction (torque rule), which waits while the braking need ``-sigma drive`` is under
        :data:`FRICTION_MARGIN` of ``T_c2``.

        ``rd`` is the reference speed [rad/s] and ``drive`` the transmitted torque [N m]. Meanwhile the lead the load
        would take on the driving flank, free, and its speed integrate ``-sigma drive / J2`` over each sample the
        driving flank is held in motion (the flank holds them at zero: it pushes a load that falls back); a crossing
        that follows starts from the load where they put it (:meth:`_start_crossing`).
        """
        held = self._sigma
        if not (self.rule == "torque" and self._tc2 > 0.0 and held * rd > 0.0):
            self._lead = [0.0, 0.0]
            return True
        x, v = self._lead
        v_new = v - held * drive / self._J2 * self.Ts  # the free load's acceleration away from the driving flank
        x += 0.5 * (v + v_new) * self.Ts
        v = v_new
        if x <= 0.0:  # back on the driving flank, which pushes it
            x, v = 0.0, max(v, 0.0)
        self._lead = [x, v]
        if sigma == held or -held * drive >= FRICTION_MARGIN * self._tc2:
            return True
        self.braking_changes_skipped += 1
        return False

    def _presses_other_flank(self, t: float, y_motor: float, rd: float, rdd: float) -> bool:
        """Whether the motor, at rest, has pressed the flank opposite the held one for :data:`PRESS_TIME`: see
        *Pressing the other flank* in the module docstring.

        The last sample's torque pushes against the held flank ``sigma`` by more than the motor's Coulomb friction
        and ``disturbance_threshold / N``, while the reference rests, no crossing or take-up is under way and the
        motor encoder (``y_motor`` [rad]) has moved less than :data:`PRESS_TRAVEL` of the half gap since the
        pressing began. Motor feedback only: with the load encoder the PID sees the load's error itself.
        """
        u = self._u_hist[1]
        pressing = (rd == 0.0 and rdd == 0.0 and self._sigma != 0.0 and not self.uses_load_encoder
                    and t >= self._cross_end and self._lag is None
                    and self._sigma * u < -(self._tc1 + self.disturbance_threshold / self.pid.N))
        if not pressing:
            self._press = None
            return False
        if self._press is None:
            self._press = (t, y_motor)
            return False
        t0, y0 = self._press
        if abs(y_motor - y0) / self.pid.N > PRESS_TRAVEL * self._offset:
            self._press = (t, y_motor)
            return False
        if t - t0 < PRESS_TIME - 0.5 * self.Ts:
            return False
        self._press = None
        return True

    def _watch_rattle(self, y_motor: float, rd: float) -> None:
        """Update the rattle level from the motor encoder (see :attr:`rattling`).

        The motor's speed change over the last sample, less what the torque held over it explains (alone or
        with the load), is an impact's velocity jump; the level is a leaky count of jumps above
        :attr:`jump_threshold` (decay 0.9 per sample). With the load, the torque that moves the train is the
        motor's less what holds the load: the model's load torque and Coulomb friction (at reference speed
        ``rd`` [rad/s]) and the observer's disturbance, as the observer's own model has it. (Without them, a
        light train holding a load step the model does not give, 0.5 N m on a 2e-5 kg m^2 train, read each
        sample's held torque as a 14 rad/s jump: the guard stayed on and its softened loop dropped the load
        every few tens of ms, a 0.15 rad limit cycle where the PID held the step.)"""
        y1, y2 = self._y_hist
        self._y_hist = (y_motor, y1)
        if y1 is None or y2 is None:  # y1 is given whenever y2 is (a shift register): the first two samples
            return
        dv = (y_motor - 2.0 * y1 + y2) / self.Ts  # motor speed change [rad/s]
        u_mean = 0.5 * (self._u_hist[0] + self._u_hist[1])
        friction = math.copysign(self._tc2, rd) if (self._tc2 > 0.0 and rd != 0.0) else 0.0
        u_train = u_mean + (self._tl - friction + self.disturbance) / self.pid.N  # LoadObserver.update's torque
        jump = min(abs(dv - u_mean * self.Ts / self._J1), abs(dv - u_train * self.Ts / self.pid.info.J_eq))
        self._rattle = RATTLE_DECAY * self._rattle + (1.0 if jump > self.jump_threshold else 0.0)
        if self._rattle > RATTLE_LEVEL:
            self.rattling = True
        elif self._rattle < 1.0:
            self.rattling = False

    def _take_up(self, t: float) -> tuple[float, float, float]:
        """The part of the load's lag behind the reference still to be taken up, its speed and its acceleration
        at mid-sample [rad, rad/s, rad/s^2]: a cubic from the lag at the landing to zero (zeros when done)."""
        if self._lag is None:
            return 0.0, 0.0, 0.0
        d0, dd0, t0, T = self._lag
        x = (t - t0) / T
        if x >= 1.0:
            self._lag = None
            return 0.0, 0.0, 0.0
        x2 = x * x  # a product, not x ** 2: the C mirror's compiler makes pow(x, 2) a product (bit for bit)
        h00, h10 = 2 * x**3 - 3 * x2 + 1, x**3 - 2 * x2 + x
        h00d, h10d = 6 * x2 - 6 * x, 3 * x2 - 4 * x + 1
        xm = min(x + 0.5 * self.Ts / T, 1.0)
        h00dd, h10dd = 12 * xm - 6, 6 * xm - 4
        return d0 * h00 + T * dd0 * h10, (d0 * h00d + T * dd0 * h10d) / T, (d0 * h00dd + T * dd0 * h10dd) / (T * T)

    def _start_crossing(self, t: float, sigma_old: float, y_motor: float, y_load: float | None, rd: float) -> None:
        """Where the load is when the motor leaves its flank: the state the crossing lands on."""
        N = self.pid.N
        if self.uses_load_encoder and y_load is not None:
            theta = float(y_load)
        else:  # in contact with the old flank (or centred before the first decision), or the lead ahead of it
            theta = y_motor / N - self._ramp.at(t)[0] + sigma_old * self._lead[0]
        obs = self._observer
        if obs is not None:  # before the first update the observer starts at rest, as the plant does
            omega = obs.x[1] if obs.x is not None else 0.0
        else:
            omega = rd
        self._free = [theta, omega + sigma_old * self._lead[1]]
        # the motor alone from here on, under the torques it is given: what it does if it meets nothing
        self._motor_free = [y_motor / N, omega]
        self._motor_free_new = True
        self._motor_free_since = t

    def _advance_free_motor(self) -> None:
        """Advance the free motor's prediction over the last sample, under the torque held over it (load units:
        ``u = N (J1 a + d1 v) + T_c1 sign(v)``, the design pair's motor side: on a train it lumps the intermediate
        shafts, but the contact check this feeds is a pair's)."""
        if self._motor_free is None:
            return
        if self._motor_free_new:  # the crossing started this sample: its torque is yet to act
            self._motor_free_new = False
            return
        x, v = self._motor_free
        u = self._u_hist[1]
        if self._tc1 > 0.0 and v != 0.0:
            u -= math.copysign(self._tc1, v)
        acc = (u / self.pid.N - self._d1 * v) / self._J1
        v_new = v + self.Ts * acc
        self._motor_free = [x + 0.5 * self.Ts * (v + v_new), v_new]

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
        # the speed exactly over the sample (the viscous term's decay, the rest held): an explicit step diverges on
        # a load whose viscous time constant J2 / d2 is below Ts / 2 (a fuzzed 1.3e-8 kg m^2 load had 6e-6 s)
        a = self._d2 / J2
        om_new = om + Ts * alpha if a == 0.0 else om - alpha * math.expm1(-a * Ts) / a
        if om != 0.0 and om_new * om < 0.0 and abs(tau) <= self._tc2:  # friction stops it within the sample
            om_new, alpha = 0.0, -om / Ts
        self._free = [th + Ts * 0.5 * (om + om_new), om_new]
        return th, om, alpha

    def step(self, t: float, y_motor: float, y_load: float | None, ref: ReferenceLike) -> float:
        if self.backlash == 0.0:  # no gap to invert: the PID itself
            return self.pid.step(t, y_motor, y_load, ref)
        r, rd, rdd = ref.at(t)
        check_readings(self, t, y_motor, y_load, (r, rd, rdd))
        self._t = t
        self._watch_rattle(y_motor, rd)
        a = self.pid.reference_update(rd, rdd)  # at mid-sample (see PID)
        if self._tc2 > 0.0 and rd != 0.0 and not self._moving_ref:
            # a move starts: what the integrator held against the load's static friction at rest is released
            # (the friction feedforward takes over); it keeps the disturbance the observer sees beyond friction
            self.pid.integral = -self._disturbance_beyond_friction() / self.pid.N
        self._moving_ref = rd != 0.0
        rdd_prev, self._rdd_prev = self._rdd_prev, abs(rdd)
        self._rdd_before = rdd_prev  # for flank(): is the deceleration fading?
        sigma_old = self._sigma
        sigma = self.flank(t, ref)
        if sigma == sigma_old and self._presses_other_flank(t, y_motor, rd, rdd):
            sigma = self._sigma = -sigma_old
        if sigma != sigma_old and rd == 0.0 and rdd == 0.0 and t >= self._cross_end and not self.uses_load_encoder:
            self._shift_in_contact(t)  # decided at rest: the load is on the new flank already (see "At rest")
        elif sigma != sigma_old:
            # a contact met during this crossing is trusted only if it starts from a settled flank (the load it
            # lands on is then predicted from that flank): not at start-up, nor during a take-up or a rattle
            self._trusted = (sigma_old != 0.0 and self._lag is None and not self.rattling
                             and t >= self._cross_end + self.crossing_time)
            if t >= self._cross_end:
                self._start_crossing(t, sigma_old, y_motor, y_load, rd)
            self._lag = None  # the landing of the new crossing sets the lag to take up
            self._ramp.move_to(t, sigma * self._offset)
            self._cross_end = self._ramp.end
            self._reach = -math.inf
        lag, dlag, ddlag = self._take_up(t)  # the load's target is the reference less the lag still to take up
        off = self._ramp.at(t)
        if self._ramp.moving(t):  # the offset's acceleration fed forward: its mean over the sample the torque is held
            off = (off[0], off[1], (self._ramp.at(t + self.Ts)[1] - off[1]) / self.Ts)
        friction = math.copysign(self._tc2, rd) if (self._tc2 > 0.0 and rd != 0.0) else 0.0
        free = t < self._cross_end
        if free:
            r_c, rd_c, _ = self._free_load()
            # where the load is against the motor now, and a sample on if the motor keeps pace with the load's present
            # speed (the load's own speed change over the sample moves it 0.5 Ts (omega_new - omega) against it)
            rel, reach = y_motor / self.pid.N - r_c, FREE_LOAD_REACH * self._offset
            if not (abs(rel) <= reach and abs(rel - 0.5 * self.Ts * (self._free[1] - rd_c)) <= reach):
                # the predicted load left the gap: in truth it met a flank of the motor (see "The crossing"). The
                # crossing ends here, the load taken on the new flank at the reference's speed
                self._free = [y_motor / self.pid.N - self._sigma * self._offset, rd]
                self._cross_end = t
                self._ramp.reset(self._sigma * self._offset)
                off = self._ramp.at(t)
                self.free_load_exits += 1
                free = False
        if free:  # the motor lands on where the load is predicted to be, not on where the reference is
            self._was_free = True
            a_c = (self._free[1] - rd_c) / self.Ts  # the free load's mean acceleration over the sample
            u = offset_torque(self.pid, t, r_c, rd_c, a_c, off, y_motor, y_load, free=True,
                              carried=self._carried_now(off[0]))
            self._advance_free_motor()
            self._check_contact(t, y_motor / self.pid.N, r_c)
        else:
            if self._was_free:  # landed: the load's lag behind the reference is taken up smoothly
                self._was_free = False
                self._start_take_up(t, r, rd)
                lag, dlag, ddlag = self._take_up(t)
            err = r - lag + off[0] - y_motor / self.pid.N
            # rattling softens the feedback, but never against an error of more than RATTLE_MAX_ERROR lost motions:
            # the gap cannot explain it, and the softened loop would leave the load behind
            rattle = self.rattling and abs(err) < RATTLE_MAX_ERROR * 2.0 * self._offset
            scale = RATTLE_GAIN * self._J1 / self.pid.info.J_eq if rattle else 1.0
            u = offset_torque(self.pid, t, r - lag, rd - dlag, a - ddlag, off, y_motor, y_load, scale=scale,
                              one_way=self._one_way(t, rd, rdd, rdd_prev, err))
        self._u_hist = (self._u_hist[1], u)
        obs = self._observer
        if obs is not None:  # the train model does not hold while the motor crosses, nor just after a landing
            theta = float(y_load) if (self.uses_load_encoder and y_load is not None) else y_motor / self.pid.N - off[0]
            settling = free or t < self._cross_end + self.crossing_time
            obs.update(theta, u if not free else 0.0, friction, settling)
        return u

    def _carried_now(self, o: float) -> tuple[float, float, float] | None:
        """``(J, d, T_c)`` the motor moves at offset ``o`` of a crossing (None on a pair: the design pair's motor
        side).

        The share crossed is that of the ramp's own travel, from where it started: from a settled flank, the share
        of the lost motion; from the centred start-up, the share of the half gaps left, in which every stage has
        the same share. The stages' gaps close in that order from the motor's (:func:`carried_by_motor`)."""
        rows = self._carried
        if len(rows) == 1:
            return None
        travel = self._ramp.target - self._ramp.origin
        crossed = (o - self._ramp.origin) / travel if travel != 0.0 else 1.0
        for end, J, d, tc in rows:
            if crossed < end:
                return J, d, tc
        return rows[-1][1:]

    def _one_way(self, t: float, rd: float, rdd: float, rdd_prev: float, error: float) -> float:
        """The flank whose push-back is withheld (``sigma``), or 0: see *The stop* in the module docstring.

        A flank pushes the load one way only. When the load comes to a stop on the braking flank and nothing
        else can stop it (no Coulomb friction, no load torque or disturbance that the flank carries), a
        correction that pushes it back would launch it backwards: the motor stops, the load floats off. That
        is the case when four things hold:

        - the reference brakes on the held flank (``sigma r' <= 0``) with a deceleration that fades
          (``|r''|`` below the last sample's: an S-curve's end), or it rests after one. Towards a sine's top
          the deceleration grows, and the flank then drives the return. Through a trapezoid's constant
          deceleration the load still moves at speed, and its dead stop launches the load;
        - no crossing is under way;
        - the motor's error ``error`` [rad, load angle] is under half the lost motion. A larger one (the end
          of a ramp that stops dead, a load disturbance) is corrected as in motion;
        - nothing else stops the load (see above).
        """
        sigma = self._sigma
        need = -(self._tl + self.disturbance)
        coasts = self._tc2 <= 0.0 and sigma * need <= self.disturbance_threshold
        at_rest = rd == 0.0 and rdd == 0.0
        # at rest only when reached through a fading deceleration (a trapezoid's dead stop launches the load: its
        # error is corrected as in motion)
        stopping = sigma * rd <= 0.0 and (self._one_way_prev if at_rest else abs(rdd) < rdd_prev)
        small = abs(error) < self._offset
        one_way = sigma if (coasts and stopping and small and not self._ramp.moving(t)) else 0.0
        rest = one_way != 0.0 and at_rest
        if rest and not self._stopped:  # arrived: nothing to hold, what the integrator holds would push the train
            self.pid.integral = 0.0
        self._stopped = rest
        self._one_way_prev = one_way != 0.0
        return one_way

    def _check_contact(self, t: float, motor: float, load: float) -> None:
        """During a crossing: end it where the motor meets the load before the ramp's end.

        ``motor`` is the motor's angle and ``load`` the predicted free load's [rad, load units]. While the motor
        is free it moves as the torques it is given move the motor alone (:meth:`_advance_free_motor`, from its
        state when it left the flank); when it lags that free motion by more than :data:`CONTACT_LAG` of half
        the lost motion in the second half of a trusted crossing, it pushes the load (or bounced off it): the
        backlash estimate is too large. The offset then stops at the furthest point the motor reached relative
        to the load (the flank), and the contact control takes over from there.

        The free motion, not the ramp, is the reference: the loop follows the ramp only as well as its bandwidth
        lets it. On a load with Coulomb friction, whose flank changes at the reference's reversals, the motor
        lagged its 10 ms ramp by up to 9 % of half the lost motion with nothing in its way; taken for a contact,
        the crossing stopped short and the inverse held the load off its target by that share of the gap for the
        whole half-cycle (sine RMS 1.9e-4 rad on ``shing1993_servo_friction``, 3.7x below the PID's).
        """
        self._reach = max(self._reach, self._sigma * (motor - load))
        mf = self._motor_free
        if mf is None:
            return
        if self._motor_free_since is not None and self._ramp.progress(t) > 0.5:
            # the free motor's start speed is the observer's, which lags where friction stops the load (0.006 rad/s
            # on a 3.0e-4 kg m^2 motor: 7 % of half the lost motion over a 10 ms crossing). Over the first half the
            # motor cannot have reached the load (an estimate under twice the gap): what it did differently is the
            # speed's error, and the prediction goes on from the measured angle with the speed corrected
            elapsed = t - self._motor_free_since
            if elapsed > 0.0:
                mf[1] += (motor - mf[0]) / elapsed
            mf[0] = motor
            self._motor_free_since = None
        lag = self._sigma * (motor - mf[0])
        if (self._trusted and self._ramp.progress(t) > 0.5 and self._reach > 0.0
                and lag < -self._contact_lag * self._offset):
            self._cross_end = t
            self._ramp.reset(self._sigma * self._reach)
            self.contacts += 1

    def _shift_in_contact(self, t: float) -> None:
        """A flank change decided at rest: no crossing (see *At rest* in the module docstring)."""
        o_old, o_new = self._ramp.at(t)[0], self._sigma * self._offset
        lag, dlag, _ = self._take_up(t)
        d0 = lag + (o_new - o_old)  # the target r - lag + o is unchanged at this sample
        self._ramp.reset(o_new)
        self._was_free = False
        # a flank pulls one way only: the take-up brakes with at most what holds the load on it, |need| over the
        # inertia that follows (the load's and, on a train, the intermediate shafts')
        brake = abs(self._tl + self.disturbance) / self._J_follow  # > 0: the rule that changed the flank needs it
        self._lag = (d0, dlag, t, self._take_up_time(d0, dlag, min(self._a_limit, brake) if brake > 0.0 else None))
        if self._tc2 > 0.0:  # the load moves: as when a move starts, the friction feedforward takes over
            self.pid.integral = -self._disturbance_beyond_friction() / self.pid.N
        if self._observer is not None and self._observer.x is not None:  # its load angle moves with the offset
            self._observer.x[0] -= o_new - o_old

    def _take_up_time(self, d0: float, dd0: float, a_max: float | None = None) -> float:
        """Duration of a take-up of ``d0`` [rad] starting at speed ``dd0`` [rad/s]: ``crossing_time``, or longer so
        that it asks at most :data:`TAKE_UP_ACCELERATION` of ``a_max`` (default: the torque limit's acceleration)."""
        a_lim = TAKE_UP_ACCELERATION * (self._a_limit if a_max is None else a_max)
        T = max(self.crossing_time, self.Ts)
        if math.isfinite(a_lim):  # without a torque limit no acceleration bound lengthens the take-up
            T = max(T, (4.0 * abs(dd0) + math.sqrt(16.0 * dd0 * dd0 + 24.0 * abs(d0) * a_lim)) / (2.0 * a_lim))
        return T

    def _start_take_up(self, t: float, r: float, rd: float) -> None:
        """At a landing: the predicted load's lag behind the reference, taken up along a cubic over
        ``crossing_time``, or longer so that it asks at most :data:`TAKE_UP_ACCELERATION` of the torque limit's
        acceleration. A lag larger than half the lost motion is no landing residual (start-up, a disturbance):
        it is left to the PID."""
        th, om = self._free
        d0, dd0 = r - th, rd - om
        T = self._take_up_time(d0, dd0)
        self._lag = (d0, dd0, t, T) if abs(d0) + T * abs(dd0) < self._offset else None

    @property
    def design_notes(self) -> tuple[str, ...]:  # type: ignore[override]
        """The wrapped PID's design notes (:attr:`gearctl.design.pid.PID.design_notes`)."""
        return self.pid.design_notes

    def describe(self) -> dict[str, Any]:
        """Settings of the inverse and of the PID."""
        return {**self.pid.describe(), "name": self.name, "kind": "deadzone_inverse", "preview": self.preview,
                "rule": self.rule, "width": self.width, "backlash_estimate": self.backlash,
                "crossing_time": self.crossing_time, "observer_hz": self.observer_hz,
                "disturbance_threshold": self.disturbance_threshold,
                "contact_lag": self._contact_lag if math.isfinite(self._contact_lag) else None,  # None: off (a train)
                "jump_threshold": self.jump_threshold, "jump_floor": self.jump_floor}


#: The keys of a ``deadzone_inverse`` controller file and the settings fields they feed.
LAYOUT: Layout = {"": {**LOOP_KEYS, **{f.name: (InverseSettings, f.name) for f in dataclasses.fields(InverseSettings)}},
                  **PID_TABLES}


def _check_pid(pid: object) -> None:
    """The wrapped controller of the inverse and the reversal offset: a :class:`~gearctl.design.pid.PID`."""
    if not isinstance(pid, PID):
        raise InputError(f"pid = {pid!r} is not a PID: expected gearctl.design.pid.PID(info, gains, ...) (for gains "
                         "alone: PID(gearctl.design.loop_info(plant), gains))", field="pid")


def jump_floor(sensors: Sensors | None, Ts: float) -> float:
    """What the motor encoder's counts and noise alone make of the motor speed's change over a sample [rad/s]: a
    count's flicker up and down (two counts in the second difference) and three standard deviations of the noise
    in it (``sqrt(6) sigma``), over the sample period. Below it the rattle guard would count the encoder's flicker
    as impacts (0 without sensors)."""
    if sensors is None:
        return 0.0
    q = 2.0 * math.pi / sensors.motor_encoder_cpr if sensors.motor_encoder_cpr else 0.0
    return (2.0 * q + 3.0 * math.sqrt(6.0) * sensors.motor_noise) / Ts


def build(path: Path, spec: dict[str, Any], info: LoopInfo, *, name: str,
          backlash: float | None = None, sensors: Sensors | None = None) -> DeadzoneInverse:
    """The inverse of a ``kind = "deadzone_inverse"`` file; ``backlash`` overrides the file's estimate; ``sensors``
    (the model's encoders) set the rattle guard's floor (:func:`jump_floor`).

    Where neither ``backlash`` nor the file gives an estimate and the model's lost motion is under one count of the
    motor encoder, the estimate is 0 (the inverse runs as its PID) and a design note says so.

    Parameters
    ----------
    path : Path
        The controller file (named in errors).
    spec : dict
        The parsed file.
    info : LoopInfo
        Design-time plant knowledge.
    name : str
        The controller's label (its PID's is ``name + "/pid"``).
    backlash : float, optional
        Backlash estimate ``b`` [m], over the file's ``backlash`` and the model's.
    sensors : Sensors, optional
        The model's encoders.

    Returns
    -------
    DeadzoneInverse

    Raises
    ------
    InputError
        For an unknown table or key, or a value out of range (named with the file and key).
    """
    values = spec_values(path, spec, LAYOUT, kind=KIND)
    loop = build_dataclass(path, LoopSettings, values.get(LoopSettings, {}))
    settings = build_dataclass(path, InverseSettings, values.get(InverseSettings, {}))
    b = backlash if backlash is not None else (settings.backlash if settings.backlash is not None
                                               else info.plant.backlash)
    pid = pid_from_values(path, values, info, loop, name + "/pid")
    count = 2.0 * math.pi / sensors.motor_encoder_cpr if sensors is not None and sensors.motor_encoder_cpr else 0.0
    lost = 2.0 * b / info.plant.rb2 * info.N  # the lost motion at the motor [rad]
    if backlash is None and settings.backlash is None and 0.0 < lost < count:
        # the model's backlash is under a count of the motor encoder: the offset would move the motor by less than
        # the loop can resolve, and the crossings only disturb it (see "Below a count" in the module docstring)
        pid.design_notes = (*pid.design_notes, f"backlash: the lost motion, {lost:.3g} rad at the motor, is under one "
                            f"count of the motor encoder ({count:.3g} rad): nothing the loop can invert, the inverse "
                            f"runs as its PID (to invert it anyway, set backlash in the controller file)")
        b = 0.0
    try:
        return DeadzoneInverse(pid, backlash=b, rule=settings.rule, width=settings.width,
                               jump_floor=jump_floor(sensors, pid.Ts),
                               crossing_time=settings.crossing_time, observer_hz=settings.observer_hz,
                               disturbance_threshold=settings.disturbance_threshold,
                               name=name)
    except InputError as exc:
        raise restate(path, exc, values) from None
