"""Adaptive dead-zone inverse: the backlash inverse whose estimate of ``b`` learns from the encoders.

The inverse itself is :class:`gearctl.design.deadzone.DeadzoneInverse`, used through its public interface
only (``step``, ``reset``, ``describe``, ``set_backlash``, ``backlash``, ``pid``); this module adds the
estimate. It reads both encoders: ``s = r_b1 theta1 - r_b2 theta2`` is the relative displacement along
the line of action up to the encoders' zeros, and the flanks are its two extremes, ``+b`` and ``-b`` (plus
the mesh deflection ``F / k``, removed as ``u / (r_b1 k)`` with the commanded torque ``u``). Whenever the
motor has crossed the gap, a stretch of ``s`` around the crossing holds both extremes, whatever the zeros:

    b_m = (s_hi - s_lo) / 2

over a ``window`` of samples (examined every half window; windows that measure do not overlap), with
``s_hi`` and ``s_lo`` the third largest and smallest values (an impact's penetration is a spike of one or
two samples). The window counts if the inverse changed flank within it (from one flank to the other: the
centred start-up's first flank is no change), the span exceeds ``0.8 b_j`` (one flank's bounces or a
partial crossing span less) and each extreme was visited: the fifth largest (smallest) value lies within
``max(plateau_tolerance, 0.02 b_j)`` of the third. The same rule reads a servo that rests on the flanks
between crossings (the improved plant: flat plateaus), one whose motor keeps bouncing on the driving
flank (the Yang–Sun plant's stiff, lively contact: the flank is the top of the bounces) and one that
rattles across the gap at its reversals (the extremes are the impacts).

Only a flank change makes the motor cross from one flank to the other; without one, a window's extremes
need not be flanks, and two kinds of window passed the span and plateau tests with half the gap or less:

- *the start-up*: the plant starts centred, so the first move spans the half gap from the centre to a flank,
  with a plateau at each end. On ``shing1993_servo_friction`` the first window measured ``0.50 b``, the
  estimate fell to ``0.70 b`` and took 17 s of ISO 230-2 cycles to come back: accuracy A = 257 urad against
  the fixed inverse's 14 (now 14.4);
- *a load coasting off its flank* at rest (no load friction): ``s`` drifts slowly enough that the fifth and
  third extremes lie within the plateau tolerance. On ``shing1993_servo`` three such windows measured
  ``0.29-0.46 b`` in one ISO run and sent the inverse back to its learning crossing for a cycle.

This is a recursive estimate from the gap crossings, in the spirit of Tao & Kokotović's adaptive inverse
(an online estimate of the dead-zone parameter with projection onto known bounds), but driven by the
measured gap rather than by the tracking error, so that the estimate does not absorb the loop's own lag.

The adaptation law (bounded)
----------------------------
At the ``j``-th measurement

    b_(j+1) = clip( b_j + gain (b_m - b_j),  (1 - max_step) b_j,  (1 + max_step) b_j )

projected onto ``[min_backlash, max_backlash]``, and handed to the inverse (``set_backlash``) only when
it differs from the estimate the inverse holds by more than ``apply_threshold`` (1 %): each change moves
the inverse's offset along its crossing ramp, which is a small disturbance of its own.

``gain`` in (0, 1] filters measurement noise (the error
shrinks by ``1 - gain`` per crossing, so from -50 % it is within 5 % after three crossings at the
default 0.6), ``max_step`` bounds any single change (a corrupt measurement moves the estimate by at most
that fraction), and the bounds keep it physical. Between measurements the estimate is held. The steps are
relative, so an initial estimate of 0 (the backlash-free plant of the benchmark) stays 0: the inverse is then
its PID.

The crossing: steps while learning, a ramp once converged
----------------------------------------------------------
A ``sin^2`` crossing (``crossing_time > 0``) tracks far better than a step with the right ``b`` (the
benchmark sine: 21 against 70 urad RMS), but with a wrong one it is the worse of the two: an estimate too
large makes the motor meet the load mid-ramp, one 50 % off leaves the Yang-Sun plant rattling. So the
inverse crosses as its file says (``crossing_time``, a step in the catalog's) while it learns, and with a
ramp of ``converged_crossing_time`` once the estimate has converged:

- *converged*: :data:`CONVERGED_MEASUREMENTS` (2) consecutive measurements each within ``converged_tolerance``
  (2 %) of the estimate they update (the estimate then lies within ``(1 - gain) converged_tolerance``, 0.8 %,
  of the last of them: the measurements scatter by 0.2 % on the improved plant, 1 % on the Yang-Sun one);
- *diverged*: one measurement further than ``diverged_tolerance`` (10 %) from the estimate (a wrong start,
  wear, a changed gear) puts it back to the learning crossing until it has converged again.

The inverse's crossing time is changed (:meth:`DeadzoneInverse.set_crossing_time`) only with its offset at
rest, between crossings: a switch decided during a ramp waits for the ramp's end. ``converged_crossing_time
= 0`` never switches.

References
----------
G. Tao, P. V. Kokotović, *Adaptive Control of Systems with Actuator and Sensor Nonlinearities*, Wiley
(1996), ch. 4-5 (adaptive backlash inverse, parameter projection). M. Nordin, P.-O. Gutman, "Controlling
mechanical systems with backlash - a survey", Automatica 38 (2002) 1633-1649 (the gap between motor and
load positions).
"""

from __future__ import annotations

import collections
import dataclasses
import math
from pathlib import Path
from typing import Any

from ..controller import READING_LIMIT, ReferenceLike
from ..errors import InputError
from ..files import Layout, build_dataclass, spec_values
from ..params import Sensors
from ..units import BACKLASH, BACKLASH_FLOOR, quantity, validate_fields
from . import deadzone
from .base import Controller, LoopInfo
from .pid import check_readings

__all__ = ["AdaptationSettings", "AdaptiveInverse", "KIND", "LAYOUT", "build", "MAX_HISTORY",
           "CONVERGED_MEASUREMENTS"]

#: The controller-file kind this module builds (:mod:`gearctl.design.registry`).
KIND = "adaptive_inverse"
#: Most estimate updates kept in :attr:`AdaptiveInverse.history` (one per gap crossing).
MAX_HISTORY = 10_000
#: Consecutive measurements within ``converged_tolerance`` of the estimate after which it counts as converged.
CONVERGED_MEASUREMENTS = 2


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class AdaptationSettings:
    """The ``[adaptation]`` table of an ``adaptive_inverse`` file: the bounded update law.

    Parameters
    ----------
    gain : float
        Share of the measured error taken per gap crossing, (0, 1] [1] (default 0.6).
    max_step : float
        Largest relative change of the estimate per crossing, (0, 1] [1] (default 0.5).
    min_backlash : float, optional
        Lower bound of the estimate, 0..0.01 [m] (default: 0.2 x the initial estimate).
    max_backlash : float, optional
        Upper bound of the estimate, 0..0.01 [m] (default: 5 x the initial estimate).
    window : float
        Stretch of ``s = r_b1 theta1 - r_b2 theta2`` examined for both flanks, every half of it, (0, 10] [s]
        (default 0.2).
    plateau_tolerance : float
        How near its extreme a flank's samples of ``s`` lie (about twice the encoders' flicker of ``s``),
        (0, 1e-3] [m] (default 1e-6).
    apply_threshold : float
        Relative change of the estimate that is handed to the inverse, 0..0.5 [1] (default 0.01).
    converged_crossing_time : float
        Crossing time (``sin^2`` ramp) once the estimate has converged, 0 or 1e-6..1 [s] (0: never switch;
        default 0.01).
    converged_tolerance : float
        Relative difference between a measurement and the estimate under which it counts towards convergence,
        (0, 0.5] [1] (default 0.02).
    diverged_tolerance : float
        Relative difference between a measurement and the estimate beyond which the inverse goes back to the
        learning crossing, (0, 10] [1], at least ``converged_tolerance`` (default 0.1).

    Raises
    ------
    InputError
        For a value of wrong type or out of range (named), ``min_backlash`` above ``max_backlash`` or
        ``diverged_tolerance`` below ``converged_tolerance``.
    """

    gain: float = quantity(unit="1", doc="share of the measured error taken per gap crossing", low=0.0,
                           low_open=True, high=1.0, default=0.6)
    max_step: float = quantity(unit="1", doc="largest relative change of the estimate per crossing", low=0.0,
                               low_open=True, high=1.0, default=0.5)
    min_backlash: float | None = BACKLASH.field(default=None, optional=True, doc="lower bound of the estimate "
                                                "(default: 0.2 x the initial estimate)")
    max_backlash: float | None = BACKLASH.field(default=None, optional=True, doc="upper bound of the estimate "
                                                "(default: 5 x the initial estimate)")
    window: float = quantity(unit="s", doc="stretch of s examined for both flanks, every half of it", low=0.0,
                             low_open=True, high=10.0, default=0.2)
    plateau_tolerance: float = quantity(unit="m", doc="how near its extreme a flank's samples lie (about twice "
                                        "the encoders' flicker of s)", low=0.0, low_open=True, high=1e-3,
                                        default=1e-6)
    apply_threshold: float = quantity(unit="1", doc="relative change of the estimate that is handed to the "
                                      "inverse", low=0.0, high=0.5, default=0.01)
    converged_crossing_time: float = deadzone.CROSSING_TIME.field(doc="crossing time (sin^2 ramp) once the estimate "
                                                                  "has converged (0: never switch)", default=0.01)
    converged_tolerance: float = quantity(unit="1", doc="relative difference between a measurement and the "
                                          "estimate under which it counts towards convergence", low=0.0,
                                          low_open=True, high=0.5, default=0.02)
    diverged_tolerance: float = quantity(unit="1", doc="relative difference between a measurement and the "
                                         "estimate beyond which the inverse goes back to the learning crossing",
                                         low=0.0, low_open=True, high=10.0, default=0.1)

    def __post_init__(self) -> None:
        validate_fields(self)
        if self.min_backlash is not None and self.max_backlash is not None and \
                self.min_backlash > self.max_backlash:
            raise InputError(f"min_backlash = {self.min_backlash!r} is out of range: expected at most max_backlash "
                             f"= {self.max_backlash!r} [m]", field="min_backlash")
        if self.diverged_tolerance < self.converged_tolerance:
            raise InputError(f"diverged_tolerance = {self.diverged_tolerance!r} is out of range: expected at least "
                             f"converged_tolerance = {self.converged_tolerance!r}", field="diverged_tolerance")


def _within_limit(value: object) -> bool:
    """Whether a reading is a finite number within :data:`~gearctl.controller.READING_LIMIT`."""
    try:
        return abs(float(value)) <= READING_LIMIT  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False


class AdaptiveInverse(Controller):
    """A dead-zone inverse whose backlash estimate updates at every gap crossing (see the module docstring).

    Parameters
    ----------
    inverse : DeadzoneInverse
        The inverse it wraps; its backlash is the initial estimate.
    settings : AdaptationSettings
        The update law.
    name : str
        Label.

    Attributes
    ----------
    history : list of tuple
        ``(t [s], measured b_m [m], estimate after the update [m])`` per crossing, at most
        :data:`MAX_HISTORY`.
    learning_crossing_time : float
        The inverse's crossing time while the estimate learns (the one it was built with) [s].
    switches : list of tuple
        ``(t [s], crossing time handed to the inverse [s])`` per switch, at most :data:`MAX_HISTORY`.
    converged : bool
        Whether the estimate counts as converged (the inverse then crosses with ``converged_crossing_time``
        once its offset is at rest).

    Raises
    ------
    InputError
        If ``inverse`` is not a :class:`~gearctl.design.deadzone.DeadzoneInverse` or ``settings`` not an
        :class:`AdaptationSettings`; if the inverse's backlash (the initial estimate) lies outside
        ``[min_backlash, max_backlash]`` (field ``backlash``).
    """

    def __init__(self, inverse: deadzone.DeadzoneInverse, settings: AdaptationSettings | None = None, *,
                 name: str = "adaptive_inverse") -> None:
        super().__init__()
        if not isinstance(inverse, deadzone.DeadzoneInverse):  # an AttributeError on .Ts before
            from ..errors import short_repr

            raise InputError(f"inverse = {short_repr(inverse)} is not a dead-zone inverse: expected a DeadzoneInverse "
                             "(gearctl.catalog.load_controller('deadzone_inverse', plant))", field="inverse")
        if settings is not None and not isinstance(settings, AdaptationSettings):
            raise InputError(f"settings = {settings!r} is not an AdaptationSettings", field="settings")
        self.inner = inverse
        self.settings = settings or AdaptationSettings()
        self.name = name
        self.Ts = inverse.Ts
        self.preview = inverse.preview
        self.uses_load_encoder = True  # the gap is measured between the two encoders
        self.initial = float(inverse.backlash)
        st = self.settings
        self.min_backlash = st.min_backlash if st.min_backlash is not None else 0.2 * self.initial
        if self.initial > 0.0:  # an estimate is 0 or at least the floor: the law never leaves that range
            self.min_backlash = max(self.min_backlash, BACKLASH_FLOOR)
        self.max_backlash = st.max_backlash if st.max_backlash is not None else min(5.0 * self.initial, 0.0099)
        if not (self.min_backlash <= self.initial <= self.max_backlash):
            raise InputError(f"backlash = {self.initial!r} is out of range: the initial estimate must lie within "
                             f"[min_backlash, max_backlash] = [{self.min_backlash:g}, {self.max_backlash:g}] [m]",
                             field="backlash")
        plant = inverse.pid.info.plant
        self._rb1, self._rb2, self._k = plant.rb1, plant.rb2, plant.k
        self._window = max(10, int(round(st.window / self.Ts)))
        self.learning_crossing_time = float(inverse.crossing_time)
        self.history: list[tuple[float, float, float]] = []
        self.notes: tuple[str, ...] = ()  # the adaptation's design notes (see build)
        self.reset()

    @property
    def backlash(self) -> float:
        """The current estimate ``b`` [m] (the inverse holds it within ``apply_threshold``)."""
        return self._b

    def reset(self) -> None:
        """Back to the initial estimate; the wrapped inverse and the window reset."""
        self._b = self.initial
        self.inner.set_crossing_time(self.learning_crossing_time)
        self.inner.set_backlash(self.initial)
        self.inner.reset()
        self.converged = False
        self._agree = 0  # consecutive measurements within converged_tolerance of the estimate
        self._recent: collections.deque[float] = collections.deque(maxlen=self._window)
        self._count = 0  # samples since the window was last examined
        self._fresh = 0  # samples since the last measurement (measuring windows do not overlap)
        self._flank = 0.0  # the inverse's held flank at the last sample (0: centred, no decision yet)
        self._since_change = self._window  # samples since the inverse changed flank (at most the window)
        self._u = 0.0
        self.history = []
        self.switches: list[tuple[float, float]] = []
        self.solve_times, self.fallbacks = self.inner.solve_times, self.inner.fallbacks

    def update(self, t: float, b_m: float) -> float:
        """Apply one measurement ``b_m`` [m] taken at ``t`` [s] by the bounded law; return the new estimate [m].

        The law of the module docstring: a step of ``gain`` towards ``b_m``, at most ``max_step`` of the
        estimate, projected onto ``[min_backlash, max_backlash]``; the inverse gets it beyond ``apply_threshold``.
        The measurement also counts towards convergence (or divergence), which sets the inverse's crossing.

        Parameters
        ----------
        t : float
            Time of the measurement [s].
        b_m : float
            Measured backlash [m].

        Returns
        -------
        float
            The new estimate [m].
        """
        st = self.settings
        b = self.backlash
        miss = abs(b_m - b)
        self._agree = self._agree + 1 if miss <= st.converged_tolerance * b else 0
        if miss > st.diverged_tolerance * b:
            self.converged = False
        elif self._agree >= CONVERGED_MEASUREMENTS:
            self.converged = True
        self._switch_crossing(t)
        new = b + st.gain * (b_m - b)
        new = min(max(new, (1.0 - st.max_step) * b), (1.0 + st.max_step) * b)
        new = min(max(new, self.min_backlash), self.max_backlash)
        self._b = new
        held = float(self.inner.backlash)
        if abs(new - held) > st.apply_threshold * held:
            self.inner.set_backlash(new)
        if len(self.history) < MAX_HISTORY:
            self.history.append((t, b_m, new))
        return new

    def _switch_crossing(self, t: float) -> None:
        """Give the inverse the crossing time of the state (learning or converged), with its offset at rest."""
        want = self.learning_crossing_time
        if self.converged and self.settings.converged_crossing_time > 0.0:  # 0: never switch
            want = self.settings.converged_crossing_time
        if want != self.inner.crossing_time and not self.inner.offset_moving(t):
            self.inner.set_crossing_time(want)
            if len(self.switches) < MAX_HISTORY:
                self.switches.append((t, want))

    def _observe(self, t: float, s: float) -> None:
        """Add a sample of ``s``; every half window, measure the gap if the window holds both flanks."""
        self._recent.append(s)
        self._count += 1
        self._fresh += 1
        n = self._window
        if self._count < n // 2 or len(self._recent) < n or self._fresh < n:
            return
        self._count = 0
        if self._since_change >= n:  # no flank change in the window: its extremes need not be the flanks
            return
        v = sorted(self._recent)
        hi, lo = v[-3], v[2]
        b = self.backlash
        near = max(self.settings.plateau_tolerance, 0.02 * b)
        if hi - lo > 0.8 * b and hi - v[-5] <= near and v[4] - lo <= near:
            self._fresh = 0
            self.update(t, 0.5 * (hi - lo))

    def _watch_flank(self) -> None:
        """Count the samples since the inverse last changed flank (from one flank to the other)."""
        f = self.inner.held_flank
        changed = f != 0.0 and self._flank != 0.0 and f != self._flank
        self._since_change = 0 if changed else min(self._since_change + 1, self._window)
        self._flank = f

    def step(self, t: float, y_motor: float, y_load: float | None, ref: ReferenceLike) -> float:
        # the inner inverse's checks first (y_load too where it feeds it back), before anything changes; a load
        # reading read only for the gap that is not finite or beyond the limit is a missing one, as in the exported
        # API (GEARCTL_STEP_FALLBACK): no gap measured
        check_readings(self.inner, t, y_motor, y_load, ref.at(t))
        if y_load is not None and not _within_limit(y_load):
            self.fallbacks.append({"t": float(t), "reason": "load reading missing (not finite or beyond 1e12 rad): "
                                                            "no gap measured"})
            y_load = None
        self._watch_flank()
        if y_load is not None:
            self._observe(t, self._rb1 * y_motor - self._rb2 * float(y_load) - self._u / (self._rb1 * self._k))
        self._switch_crossing(t)
        u = self.inner.step(t, y_motor, y_load if self.inner.uses_load_encoder else None, ref)
        self._u = u
        return u

    @property
    def design_notes(self) -> tuple[str, ...]:  # type: ignore[override]
        """The wrapped PID's design notes (:attr:`gearctl.design.pid.PID.design_notes`) and the adaptation's
        (:func:`build`: encoders too coarse for the gap)."""
        return (*self.inner.design_notes, *self.notes)

    def describe(self) -> dict[str, Any]:
        """The inverse's settings, the law's, and the estimate's history."""
        st = self.settings
        return {**self.inner.describe(), "name": self.name, "kind": KIND, "design_notes": list(self.design_notes),
                "backlash_initial": self.initial,
                "backlash_estimate": self.backlash, "backlash_applied": float(self.inner.backlash),
                "gain": st.gain, "max_step": st.max_step,
                "min_backlash": self.min_backlash, "max_backlash": self.max_backlash,
                "window": st.window, "plateau_tolerance": st.plateau_tolerance,
                "apply_threshold": st.apply_threshold, "learning_crossing_time": self.learning_crossing_time,
                "converged_crossing_time": st.converged_crossing_time,
                "converged_tolerance": st.converged_tolerance, "diverged_tolerance": st.diverged_tolerance,
                "converged": self.converged,
                "backlash_history": [list(h) for h in self.history],
                "crossing_switches": [list(w) for w in self.switches]}


#: The keys of an ``adaptive_inverse`` file: the inverse's (:data:`gearctl.design.deadzone.LAYOUT`) and the
#: ``[adaptation]`` table.
LAYOUT: Layout = {**deadzone.LAYOUT,
                  "adaptation": {f.name: (AdaptationSettings, f.name) for f in dataclasses.fields(AdaptationSettings)}}


def build(path: Path, spec: dict[str, Any], info: LoopInfo, *, name: str,
          backlash: float | None = None, sensors: Sensors | None = None) -> AdaptiveInverse:
    """The adaptive inverse of a ``kind = "adaptive_inverse"`` file; ``backlash`` overrides the initial estimate.

    Every key but the ``[adaptation]`` table is the inverse's, built by :func:`gearctl.design.deadzone.build`
    (so the two kinds read the same keys the same way).

    Parameters
    ----------
    path : Path
        The controller file (named in errors).
    spec : dict
        The parsed file.
    info : LoopInfo
        Design-time plant knowledge.
    name : str
        The controller's label (its inverse's is ``name + "/inverse"``).
    backlash : float, optional
        Initial backlash estimate ``b`` [m], over the file's ``backlash`` and the model's.
    sensors : Sensors, optional
        The model's encoders: the inverse's rattle guard floor, and a design note where they read the gap
        coarser than a tenth of the initial estimate.

    Returns
    -------
    AdaptiveInverse

    Raises
    ------
    InputError
        For an unknown table or key, or a value out of range (named with the file and key).
    """
    values = spec_values(path, spec, LAYOUT, kind=KIND)
    settings = build_dataclass(path, AdaptationSettings, values.get(AdaptationSettings, {}))
    inner_spec = {k: v for k, v in spec.items() if k != "adaptation"}
    inner_spec["kind"] = deadzone.KIND
    inverse = deadzone.build(path, inner_spec, info, name=name + "/inverse", backlash=backlash, sensors=sensors)
    try:
        ctrl = AdaptiveInverse(inverse, settings, name=name)
    except InputError as exc:
        raise InputError(f"{path}: {exc}", field=exc.field, rule=exc.rule) from None
    res = reading_resolution(info, sensors)
    if ctrl.initial > 0.0 and res > READING_SHARE * ctrl.initial:
        ctrl.notes = (f"adaptation: the encoders read s = rb1 theta1 - rb2 theta2 to {res:.2g} m (half a count and "
                      f"three noise stds of each, along the line of action), {res / ctrl.initial:.2g} b: each gap "
                      f"reading may be off by that much, and the estimate settles no closer (coarse encoders read "
                      f"the gap too large); compare it with the pid and a fixed deadzone_inverse on a measured "
                      f"backlash before trusting it (gearctl bench MODEL: on a reviewer's 4096-count servo both "
                      f"inverses positioned worse than the pid)",)
    return ctrl


#: A gap reading whose resolution exceeds this share of the estimate is noted at design (:func:`build`).
READING_SHARE = 0.1


def reading_resolution(info: LoopInfo, sensors: Sensors | None) -> float:
    """How finely the encoders read ``s = r_b1 theta1 - r_b2 theta2`` [m]: half a count and three noise stds of each
    encoder, along the line of action, summed (each extreme of a window may be off by that much). 0 without a load
    encoder (the adaptation then measures nothing)."""
    if sensors is None or not sensors.load_encoder_cpr:
        return 0.0
    p = info.plant
    out = 0.0
    for rb, cpr, noise in ((p.rb1, sensors.motor_encoder_cpr, sensors.motor_noise),
                           (p.rb2, sensors.load_encoder_cpr, sensors.load_noise)):
        count = 2.0 * math.pi / cpr if cpr else 0.0
        out += rb * (0.5 * count + 3.0 * (noise or 0.0))
    return out
