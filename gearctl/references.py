"""Load-angle references: step, ramp, sine and point-to-point moves (trapezoidal or S-curve velocity).

Each reference gives the load angle and its first two derivatives at any time, so controllers can use
feedforward and the dead-zone inverse can tell which flank must carry the load.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .errors import InputError
from .units import quantity, validate_fields

__all__ = ["Reference", "reference", "REFERENCES", "DEFAULT_DURATION", "move_times", "move_point", "pointwise"]

REFERENCES = ("sine", "step", "ramp", "move")

#: Simulated time of a run on each reference when none is given [s].
DEFAULT_DURATION = {"sine": 3.0, "move": 1.0, "step": 2.0, "ramp": 1.5}


#: The velocity profiles of a move.
MOVE_PROFILES = ("s-curve", "trapezoid")


def _refuse_move(velocity: Any, accel: Any, profile: Any) -> None:
    """The :class:`InputError` of :func:`move_times`' first bad argument."""
    for name, v in (("velocity", velocity), ("accel", accel)):
        ok = isinstance(v, int | float | np.floating | np.integer) and not isinstance(v, bool) and 0.0 < v < math.inf
        if not ok:
            raise InputError(f"{name} = {v!r} is out of range: expected a finite number > 0", field=name)
    raise InputError(f"profile = {profile!r}: expected one of {', '.join(MOVE_PROFILES)}", field="profile")


def move_times(distance: float, velocity: float, accel: float, profile: str = "s-curve") -> tuple[float, float, float]:
    """Ramp time, cruise time and cruise velocity of a rest-to-rest move over ``distance >= 0``.

    ``accel`` is the peak acceleration [rad/s^2]; a move too short to reach ``velocity`` never cruises.
    S-curve: acceleration ``(a/2)(1 - cos(2 pi t / t_a))`` over each ramp, so ``t_a = 2 v / a``;
    trapezoid: constant ``a``, ``t_a = v / a``.

    Parameters
    ----------
    distance : float
        Travel [rad]; 0 or less: no move.
    velocity : float
        Cruise velocity [rad/s], > 0 and finite.
    accel : float
        Peak acceleration [rad/s^2], > 0 and finite.
    profile : str
        ``"s-curve"`` (default) or ``"trapezoid"``.

    Returns
    -------
    t_a : float
        Duration of each ramp [s].
    t_c : float
        Duration of the cruise [s] (0 for a move that never reaches ``velocity``).
    v : float
        Velocity reached [rad/s]: ``velocity``, or less for a move that never cruises.

    Raises
    ------
    InputError
        If ``velocity`` or ``accel`` is not a finite number > 0, or ``profile`` is neither profile (a zero was a
        ZeroDivisionError, an unknown profile was timed as a trapezoid and drawn as an S-curve by
        :func:`move_point`).

    Examples
    --------
    >>> move_times(1.0, 1.0, 2.0, "trapezoid")
    (0.5, 0.5, 1.0)
    """
    try:
        ok = 0.0 < velocity < math.inf and 0.0 < accel < math.inf and profile in MOVE_PROFILES
    except TypeError:  # a string or None: named below
        ok = False
    if not ok:
        _refuse_move(velocity, accel, profile)
    if distance <= 0.0:
        return 0.0, 0.0, 0.0
    mean = accel / 2 if profile == "s-curve" else accel  # mean acceleration over a ramp
    ta = velocity / mean
    if velocity * ta > distance:  # triangular: never reaches the cruise velocity
        ta = math.sqrt(distance / mean)
        velocity = mean * ta
        if velocity == 0.0:  # distance / mean underflows (a travel of 5e-324 rad): the move is made at once
            return 0.0, 0.0, 0.0
    return ta, (distance - velocity * ta) / velocity, velocity


def move_point(tau: float, distance: float, velocity: float, accel: float,
               profile: str = "s-curve") -> tuple[float, float, float]:
    """Position, velocity, acceleration at time ``tau`` after the start of a move over ``distance >= 0``.

    Parameters
    ----------
    tau : float
        Time since the start of the move [s]; at rest at 0 before it, at ``distance`` after its end.
    distance : float
        Travel [rad]; 0 or less: no move.
    velocity : float
        Cruise velocity [rad/s], > 0 and finite.
    accel : float
        Peak acceleration [rad/s^2], > 0 and finite.
    profile : str
        ``"s-curve"`` (default) or ``"trapezoid"``.

    Returns
    -------
    tuple of float
        ``(p, p', p'')`` [rad, rad/s, rad/s^2] (:func:`move_times` gives the ramp and cruise times).

    Raises
    ------
    InputError
        As :func:`move_times`.
    """
    ta, tc, v = move_times(distance, velocity, accel, profile)
    T = 2 * ta + tc
    if tau <= 0.0 or T == 0.0:
        return (0.0 if tau <= 0.0 else distance), 0.0, 0.0
    if tau >= T:
        return distance, 0.0, 0.0
    if profile == "trapezoid":
        a = v / ta

        def ramp(u: float) -> tuple[float, float, float]:
            return 0.5 * a * u * u, a * u, a
    else:
        w = 2 * math.pi / ta

        def ramp(u: float) -> tuple[float, float, float]:
            return ((v / ta) * (u * u / 2 + (math.cos(w * u) - 1) / (w * w)), (v / ta) * (u - math.sin(w * u) / w),
                    (v / ta) * (1 - math.cos(w * u)))

    if tau <= ta:
        return ramp(tau)
    if tau <= ta + tc:
        return v * ta / 2 + v * (tau - ta), v, 0.0
    p, dp, ddp = ramp(T - tau)
    return distance - p, dp, -ddp


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class Reference:
    """A load-angle reference ``r(t)`` [rad] with derivatives.

    Attributes
    ----------
    kind : str
        ``sine``, ``step``, ``ramp`` or ``move``.
    amplitude : float
        Sine amplitude, step height, ramp or move distance [rad].
    frequency : float
        Sine frequency [Hz].
    start : float
        Time the step, ramp or move starts [s].
    rate : float
        Ramp rate [rad/s]; for a move, the cruise velocity [rad/s].
    accel : float
        Peak acceleration of a move [rad/s^2].
    profile : str
        Move velocity profile: ``trapezoid`` or ``s-curve`` (sinusoidal jerk-limited ramps).
    disturbance_time : float
        Time a load-torque step starts [s] (``inf``: none).
    disturbance : float
        Load-torque step on shaft 2 [N m], counter-clockwise positive.
    settle : float
        Start of the interval over which RMS and max error are taken [s] (skips a start-up transient).

    Raises
    ------
    InputError
        For an unknown ``kind`` (field ``reference``) or ``profile``, or a value out of its range (named).
    """

    kind: str
    amplitude: float = quantity(unit="rad", doc="amplitude / distance", low=-100.0, high=100.0, default=0.1)
    frequency: float = quantity(unit="Hz", doc="sine frequency", low=0.0, high=1e3, low_open=True, default=1.0)
    start: float = quantity(unit="s", doc="start time", low=0.0, high=1e5, default=0.0)
    rate: float = quantity(unit="rad/s", doc="ramp rate / cruise velocity", low=0.0, low_open=True, high=1e4,
                           default=0.5)
    accel: float = quantity(unit="rad/s^2", doc="move acceleration", low=0.0, low_open=True, high=1e7, default=5.0)
    profile: str = "s-curve"
    disturbance_time: float = quantity(unit="s", doc="load disturbance start", low=0.0, allow_inf=True,
                                       default=math.inf)
    disturbance: float = quantity(unit="N m", doc="load disturbance", low=-1e4, high=1e4, default=0.0)
    settle: float = quantity(unit="s", doc="start of the interval the error statistics cover", low=0.0, high=1e5,
                             default=0.0)

    def __post_init__(self) -> None:
        if self.kind not in REFERENCES:
            raise InputError(f"reference = {self.kind!r} is not a reference: expected one of "
                             f"{', '.join(REFERENCES)}", field="reference")
        if self.profile not in MOVE_PROFILES:
            raise InputError(f"profile = {self.profile!r}: expected trapezoid or s-curve", field="profile")
        validate_fields(self)

    def at(self, t: ArrayLike) -> tuple[Any, Any, Any]:
        """``(r, r', r'')`` at time(s) ``t`` [rad, rad/s, rad/s^2]; floats for a scalar ``t``.

        Parameters
        ----------
        t : float or array_like
            Time(s) [s].

        Returns
        -------
        tuple
            ``(r, r', r'')``: three floats for a scalar ``t``, else three arrays of ``t``'s shape.
        """
        if isinstance(t, float | int):
            return self._scalar(float(t))
        t = np.asarray(t, dtype=float)
        tau = t - self.start
        on = tau >= 0
        z = np.zeros_like(t)
        if self.kind == "sine":
            w = 2 * math.pi * self.frequency
            a = self.amplitude
            return a * np.sin(w * t), a * w * np.cos(w * t), -a * w**2 * np.sin(w * t)
        if self.kind == "step":
            return np.where(on, self.amplitude, 0.0), z, z
        if self.kind == "ramp":
            sgn = math.copysign(1.0, self.amplitude)
            T = abs(self.amplitude) / self.rate
            r = np.where(on, sgn * self.rate * np.minimum(tau, T), 0.0)
            return r, np.where(on & (tau < T), sgn * self.rate, 0.0), z
        out = np.array([self._scalar(float(x)) for x in t.ravel()]).T  # a move: the scalar path per sample
        return out[0].reshape(t.shape), out[1].reshape(t.shape), out[2].reshape(t.shape)

    def _scalar(self, t: float) -> tuple[float, float, float]:
        """Pure-float path of :meth:`at` (the controllers call it once per sample)."""
        if self.kind == "sine":
            w = 2 * math.pi * self.frequency
            a = self.amplitude
            sn, cs = math.sin(w * t), math.cos(w * t)
            return a * sn, a * w * cs, -a * w * w * sn
        if self.kind == "step":
            return (self.amplitude if t >= self.start else 0.0), 0.0, 0.0
        tau = t - self.start
        sgn = math.copysign(1.0, self.amplitude)
        if tau < 0:
            return 0.0, 0.0, 0.0
        if self.kind == "ramp":
            T = abs(self.amplitude) / self.rate
            return (sgn * self.rate * min(tau, T), sgn * self.rate if tau < T else 0.0, 0.0)
        p, dp, ddp = move_point(tau, abs(self.amplitude), self.rate, self.accel, self.profile)
        return sgn * p, sgn * dp, sgn * ddp

    def load_disturbance(self, t: float) -> float:
        """Load-torque disturbance at time ``t`` [N m].

        Parameters
        ----------
        t : float
            Time [s].

        Returns
        -------
        float
            ``disturbance`` from ``disturbance_time`` on, else 0 [N m].
        """
        return self.disturbance if t >= self.disturbance_time else 0.0


def reference(kind: str, **kwargs: float | str) -> Reference:
    """The benchmark's reference of a kind, with defaults a servo engineer would pick.

    ``sine``: 0.1 rad at 1 Hz (a reversal every 0.5 s; error statistics from 0.5 s, after start-up).
    ``step``: 0.05 rad at 0.1 s with a 0.5 N m load-torque step against the motion at 1.0 s (error
    statistics from 0.6 s: the hold and the disturbance rejection, not the step itself).
    ``ramp``: 0.2 rad at 0.5 rad/s from 0.1 s. ``move``: a
    0.2 rad point-to-point move, S-curve, 1 rad/s, 10 rad/s^2, from 0.1 s.

    Parameters
    ----------
    kind : str
        ``sine``, ``step``, ``ramp`` or ``move``.
    **kwargs
        Settings replacing the kind's defaults: any field of :class:`Reference` (``amplitude``, ``frequency``,
        ``start``, ``rate``, ``accel``, ``profile``, ``disturbance_time``, ``disturbance``, ``settle``), in SI
        units, validated against the ranges the fields state.

    Returns
    -------
    Reference
        ``at(t)`` gives the load angle, speed and acceleration ``(r, r', r'')``; ``load_disturbance(t)`` the
        load torque [N m].

    Raises
    ------
    InputError
        An unknown kind or setting (the message names the close ones), a value out of its range.

    Examples
    --------
    >>> reference("sine", amplitude=0.2).at(0.25)[0]
    0.2
    """
    defaults: dict[str, dict[str, float | str]] = {
        "sine": {"amplitude": 0.1, "frequency": 1.0, "settle": 0.5},
        "step": {"amplitude": 0.05, "start": 0.1, "disturbance_time": 1.0, "disturbance": -0.5, "settle": 0.6},
        "ramp": {"amplitude": 0.2, "rate": 0.5, "start": 0.1},
        "move": {"amplitude": 0.2, "rate": 1.0, "accel": 10.0, "start": 0.1, "profile": "s-curve"},
    }
    if kind not in defaults:
        raise InputError(f"reference = {kind!r} is not a reference: expected one of {', '.join(REFERENCES)}",
                         field="reference")
    keys = [f.name for f in dataclasses.fields(Reference) if f.name != "kind"]
    for key in kwargs:
        if key not in keys:
            import difflib

            close = difflib.get_close_matches(key, keys, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise InputError(f"{key} is not a setting of a reference: expected one of {', '.join(keys)}{hint}",
                             field=key)
    return Reference(kind=kind, **{**defaults[kind], **kwargs})  # type: ignore[arg-type]


def pointwise(scalar: Callable[[float], tuple[float, float, float]], t: Any) -> tuple[Any, Any, Any]:
    """``(r, r', r'')`` of a reference whose ``scalar(t)`` gives them at one time: three floats for a scalar ``t``,
    else ``scalar`` at each element, three arrays of ``t``'s shape (the ``at`` of the excitation and of the ISO
    test's motion program).

    Parameters
    ----------
    scalar : callable
        ``scalar(t)`` -> ``(r, r', r'')`` at one time [s].
    t : float or array_like
        Time(s) [s].

    Returns
    -------
    tuple
        ``(r, r', r'')``.
    """
    if isinstance(t, float | int):
        return scalar(float(t))
    ta = np.asarray(t, dtype=float)
    out = np.array([scalar(float(x)) for x in ta.ravel()]).reshape(-1, 3).T
    return out[0].reshape(ta.shape), out[1].reshape(ta.shape), out[2].reshape(ta.shape)
