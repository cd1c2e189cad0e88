"""Reversal offset: the CNC's backlash compensation, on the motor-side PID (the industrial baseline).

A machine builder compensates backlash in the numerical control, not in the servo loop: on each reversal
of the *commanded* direction the control adds the backlash value to the position command of the motor,
spread over a take-up time (or a number of position-control cycles) along a ramp, scaled by a gain
factor per parameter set. This module is that function, with the parameters the controls name:

==========================  =====================================  ==================================
gearctl key                 HEIDENHAIN (iTNC 530)                  SIEMENS / BECKHOFF
==========================  =====================================  ==================================
``backlash`` [m, b]         MP750.x backlash                       MD32450 BACKLASH / P-AXIS-00103
``take_up_time`` [s]        MP752.x compensation time (0-1000 ms)  --
``take_up_cycles``          --                                     P-AXIS-00243 n_backlash_cyc
``ramp``                    ``"linear"`` (a speed command held     ``"sin2"`` (P-AXIS-00243), ``"step"``
                            over the compensation time)            (0 or 1 cycle)
``gain``                    --                                     MD32452 BACKLASH_FACTOR
==========================  =====================================  ==================================

The backlash value at the load is the lost motion ``L = 2 b / r_b2``; the motor's target is ``r + o`` with
``o = +-gain L / 2`` for the last commanded direction (the plant starts with the flanks centred, as a
machine referenced to the middle of its play; the first move takes up half the value), the offset's speed
``o'`` fed to the PID with the reference's (the control's speed command), its acceleration not.

When it wins, and when the torque-sign inverse does
---------------------------------------------------
The reversal offset assumes the flank that carries the load is the one the command moves towards. That
holds when the load's friction (or a load torque against the motion) is larger than the torque its
inertia needs to decelerate: the load then never runs ahead into the gap and stops on the driving flank
(``shing1993_servo_friction``: 0.2 N m of friction against the 0.1 N m a 10 rad/s^2 stop needs). There it
needs nothing but the backlash value -- no inertia, friction or disturbance model, no observer -- and is
what a machine builder can tune on the machine (gain, take-up time) from a reversal measurement. The
torque-sign inverse (:mod:`gearctl.design.deadzone`) wins on an inertia-dominated load
(``shing1993_servo``): the decelerating half of every move is carried by the back flank while the command
still moves forward, so the reversal offset holds the motor on the wrong side of the gap for the whole
deceleration and the load ends the move against the back flank, a full lost motion past where the offset
assumed it (worse than no compensation); and with a load torque that reverses the flank without a
reversal of the command (a load step, gravity past the vertical), which only a torque estimate sees.

References
----------
HEIDENHAIN, Technical Manual iTNC 530 HSCI: MP750.x backlash, MP752.x compensation time for reversal
error. SIEMENS, SINUMERIK 808D Parameter Manual: MD32450 $MA_BACKLASH, MD32452 $MA_BACKLASH_FACTOR.
Beckhoff / ISG, TwinCAT CNC axis parameters: P-AXIS-00103 size of backlash, P-AXIS-00243 distribution of
the backlash on multiple cycles (``sin^2``). M. Nordin, P.-O. Gutman, "Controlling mechanical systems
with backlash - a survey", Automatica 38 (2002) 1633-1649.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

from ..controller import ReferenceLike
from ..errors import InputError
from ..files import Layout, build_dataclass, spec_values
from ..units import BACKLASH, Spec, check_choice, quantity, validate_fields
from .base import Controller, LoopInfo
from .deadzone import RAMPS, OffsetRamp, _check_pid, offset_torque
from .pid import LOOP_KEYS, PID, PID_TABLES, LoopSettings, check_readings, pid_from_values, restate

__all__ = ["ReversalOffset", "ReversalSettings", "KIND", "LAYOUT", "build"]

#: The controller-file kind this module builds (:mod:`gearctl.design.registry`).
KIND = "reversal_offset"

#: A take-up time [s]: 0 (a step) or at least a microsecond, the shortest sample time, as the inverse's crossing
#: time (a shorter one is a step in effect; 1e-308 s divided the ramp's acceleration by T^2 = 0).
TAKE_UP_TIME = Spec(unit="s", doc="time a reversal's offset is spread over (0: a step)", low=0.0, high=1.0,
                    floor=1e-6)

#: Default take-up time when a file gives neither ``take_up_time`` nor ``take_up_cycles`` [s].
DEFAULT_TAKE_UP_TIME = 0.01


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class ReversalSettings:
    """The reversal offset's own keys of a ``reversal_offset`` file (see the module docstring).

    Parameters
    ----------
    backlash : float, optional
        Backlash estimate ``b``, 0..0.01 [m] (the backlash value at the load is ``2 b / r_b2``; default: the
        model's).
    take_up_time : float, optional
        Time a reversal's offset is spread over, 0 or 1e-6..1 [s] (0: a step; default
        :data:`DEFAULT_TAKE_UP_TIME` when ``take_up_cycles`` is not given either).
    take_up_cycles : int, optional
        Position-control cycles a reversal's offset is spread over, 0..1000 [cycles] (the take-up time is
        ``take_up_cycles x sample_time``, at most 1 s).
    ramp : str
        Shape of the take-up: one of :data:`gearctl.design.deadzone.RAMPS` (default ``"sin2"``).
    gain : float
        Gain factor on the backlash value, 0..2 [1] (default 1).

    Raises
    ------
    InputError
        For a value of wrong type or out of range (named), an unknown ``ramp``, or both ``take_up_time`` and
        ``take_up_cycles`` (field ``take_up_cycles``).
    """

    backlash: float | None = BACKLASH.field(default=None, optional=True, doc="backlash estimate b (the backlash "
                                            "value at the load is 2 b / r_b2; default: the model's)")
    take_up_time: float | None = TAKE_UP_TIME.field(default=None, optional=True)
    take_up_cycles: int | None = quantity(unit="cycles", doc="position-control cycles a reversal's offset is "
                                          "spread over", low=0, high=1000, integer=True, optional=True, default=None)
    ramp: str = "sin2"
    gain: float = quantity(unit="1", doc="gain factor on the backlash value", low=0.0, high=2.0, default=1.0)

    def __post_init__(self) -> None:
        validate_fields(self)
        check_choice("ramp", self.ramp, RAMPS)
        if self.take_up_time is not None and self.take_up_cycles is not None:
            raise InputError(f"take_up_time = {self.take_up_time!r} and take_up_cycles = {self.take_up_cycles!r}: "
                             "give one of them, not both", field="take_up_cycles")


class ReversalOffset(Controller):
    """A motor-side PID whose target takes up the backlash value on each reversal of the commanded direction.

    Parameters
    ----------
    pid : PID
        The position PID (catalog ``pid``); with ``feedback = "load"`` the offset is added the same way.
    backlash : float
        Backlash estimate ``b`` along the line of action [m]; the backlash value is ``2 b / r_b2`` [rad].
    take_up_time : float
        Time a full reversal's offset is spread over [s] (0: in one sample).
    ramp : str
        ``"sin2"``, ``"linear"`` or ``"step"`` (:data:`gearctl.design.deadzone.RAMPS`).
    gain : float
        Factor on the backlash value, ``0 <= gain <= 2``.
    name : str
        Label.

    Raises
    ------
    InputError
        If ``pid`` is not a :class:`~gearctl.design.pid.PID`, or ``backlash``, ``ramp``, ``take_up_time`` or
        ``gain`` is out of range (named).

    Notes
    -----
    The commanded direction is the sign of the reference's increment from the previous sample (what a
    control sees of its position command); a step counts as a move. Increments below ``1e-12`` rad change
    nothing: at rest the last direction, and the offset, are kept.
    """

    def __init__(self, pid: PID, *, backlash: float, take_up_time: float = DEFAULT_TAKE_UP_TIME,
                 ramp: str = "sin2", gain: float = 1.0, name: str = "reversal_offset") -> None:
        super().__init__()
        _check_pid(pid)
        BACKLASH.check("backlash", backlash)
        check_choice("ramp", ramp, RAMPS)
        TAKE_UP_TIME.check("take_up_time", take_up_time)
        if not (0.0 <= gain <= 2.0):
            raise InputError(f"gain = {gain!r} is out of range: expected 0 <= value <= 2", field="gain")
        self.pid, self.backlash, self.take_up_time, self.ramp, self.gain = pid, backlash, take_up_time, ramp, gain
        self.name = name
        self.Ts = pid.Ts
        self.uses_load_encoder = pid.feedback == "load"
        #: the backlash value at the load, times the gain [rad]
        self.value = gain * 2.0 * backlash / pid.info.plant.rb2
        self._ramp = OffsetRamp(ramp if take_up_time > 0.0 else "step", take_up_time, self.value)
        self.reset()

    def reset(self) -> None:
        """Reset the PID, the direction (none yet) and the offset (0, the flanks centred)."""
        self.pid.reset()
        self._dir = 0
        self._r_prev: float | None = None
        self._ramp.reset(0.0)
        self.solve_times, self.fallbacks = [], []

    @property
    def direction(self) -> int:
        """The last commanded direction: +1, -1, or 0 before the first move."""
        return self._dir

    def step(self, t: float, y_motor: float, y_load: float | None, ref: ReferenceLike) -> float:
        r, rd, rdd = ref.at(t)
        check_readings(self, t, y_motor, y_load, (r, rd, rdd))
        if self._r_prev is not None:
            dr = r - self._r_prev
            if abs(dr) > 1e-12:
                d = 1 if dr > 0.0 else -1
                if d != self._dir:  # a reversal (or the first move): take the backlash value up
                    self._dir = d
                    self._ramp.move_to(t, 0.5 * d * self.value)
        self._r_prev = r
        a = self.pid.reference_update(rd, rdd)
        o, do, _ = self._ramp.at(t)
        return offset_torque(self.pid, t, r, rd, a, (o, do, 0.0), y_motor, y_load)

    @property
    def design_notes(self) -> tuple[str, ...]:  # type: ignore[override]
        """The wrapped PID's design notes (:attr:`gearctl.design.pid.PID.design_notes`)."""
        return self.pid.design_notes

    def describe(self) -> dict[str, Any]:
        """Settings of the reversal offset and of the PID."""
        return {**self.pid.describe(), "name": self.name, "kind": KIND, "preview": self.preview,
                "backlash_estimate": self.backlash, "backlash_value": self.value, "take_up_time": self.take_up_time,
                "ramp": self.ramp, "gain": self.gain}


#: The keys of a ``reversal_offset`` controller file and the settings fields they feed.
LAYOUT: Layout = {"": {**LOOP_KEYS, **{f.name: (ReversalSettings, f.name)
                                       for f in dataclasses.fields(ReversalSettings)}}, **PID_TABLES}


#: The deceleration [rad/s^2 at the load] below which the load's friction must stop it for the offset to hold (the
#: catalog move's): a design note names the axis where it does not.
NOTE_DECELERATION = 10.0


def build(path: Path, spec: dict[str, Any], info: LoopInfo, *, name: str,
          backlash: float | None = None) -> ReversalOffset:
    """The reversal offset of a ``kind = "reversal_offset"`` file; ``backlash`` overrides the file's estimate.

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

    Returns
    -------
    ReversalOffset

    Raises
    ------
    InputError
        For an unknown table or key, a value out of range (named with the file and key), or ``take_up_cycles``
        spanning more than 1 s.
    """
    values = spec_values(path, spec, LAYOUT, kind=KIND)
    loop = build_dataclass(path, LoopSettings, values.get(LoopSettings, {}))
    settings = build_dataclass(path, ReversalSettings, values.get(ReversalSettings, {}))
    b = backlash if backlash is not None else (settings.backlash if settings.backlash is not None
                                               else info.plant.backlash)
    if settings.take_up_cycles is not None:
        take_up = settings.take_up_cycles * loop.sample_time
    elif settings.take_up_time is not None:
        take_up = settings.take_up_time
    else:
        take_up = DEFAULT_TAKE_UP_TIME
    if not math.isfinite(take_up) or take_up > 1.0:
        raise InputError(f"{path}: take_up_cycles = {settings.take_up_cycles!r} spans {take_up:g} s: expected at "
                         "most 1 s", field="take_up_cycles")
    pid = pid_from_values(path, values, info, loop, name + "/pid")
    tl, J2 = info.plant.load_torque, info.plant.J2
    if b > 0.0 and settings.gain > 0.0 and abs(tl) > info.plant.tc2:
        # a constant load torque presses the load onto one flank: the command's reversals do not move it across
        pid.design_notes = (*pid.design_notes, f"load_torque: the model's {tl:.3g} N m presses the load onto one "
                            f"flank; it crosses the gap only where a move's acceleration exceeds {abs(tl) / J2:.3g} "
                            f"rad/s^2 at the load, so the offset at each reversal of the command may take up a lost "
                            f"motion the load did not cross (set gain = 0 for such an axis, or use the "
                            f"deadzone_inverse, which sees the torque)")
    elif b > 0.0 and settings.gain > 0.0 and info.plant.tc2 < NOTE_DECELERATION * J2:
        # an inertia-dominated load: friction does not hold it on the driving flank through a move's deceleration
        pid.design_notes = (*pid.design_notes, f"coulomb_friction2: the load's {info.plant.tc2:.3g} N m of friction "
                            f"decelerates it at {info.plant.tc2 / J2:.3g} rad/s^2; a move that decelerates faster "
                            f"(the catalog move: {NOTE_DECELERATION:g} rad/s^2) brings the load onto the braking flank "
                            f"before the command reverses, so the offset at the reversal takes up a lost motion the "
                            f"load has already crossed (worse than no compensation): use the deadzone_inverse, which "
                            f"changes flank on the torque's sign")
    try:
        return ReversalOffset(pid, backlash=b, take_up_time=take_up, ramp=settings.ramp, gain=settings.gain,
                              name=name)
    except InputError as exc:
        raise restate(path, exc, values) from None
