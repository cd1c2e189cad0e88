"""Describing-function analysis of the backlash loop: predicted against simulated limit cycles.

The mesh contact law is the only nonlinearity of the improved plant. Cut the loop there: the element maps
the relative displacement ``s = r_b1 theta1 - r_b2 theta2`` to the contact force ``F``; everything else
(two inertias with viscous friction, the sampled PID, the zero-order hold) is linear and gives
``s = -H F``. Harmonic balance ``1 + N(A) H(j omega) = 0`` with the element's describing function
``N(A)`` predicts the limit cycles; :func:`simulate_limit_cycle` runs the event-located closed loop to
check them, and :func:`describe` puts both side by side (``gearctl describe MODEL CONTROLLER``).

Two predictions are offered (``method``):

- ``"describing_function"``: the classical first-harmonic balance with a *sinusoidal* ``s``. Its
  amplitude is reliable here; its frequency is not when the cycle only grazes the flanks (see Notes of
  :func:`predict_limit_cycle`).
- ``"impact"``: the same first-harmonic balance for the motion the simulation shows in that regime, a
  bouncing ``s`` (triangle-like between the flanks, short collisions with restitution ``e``).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from pathlib import Path
from typing import Any

import control as ct
import numpy as np
import scipy.integrate
import scipy.optimize
from numpy.typing import ArrayLike, NDArray

from .catalog import GearModel, load_controller, load_model
from .closedloop import ClosedLoopResult, simulate_closed_loop
from .controller import ReferenceLike
from .design.base import Controller
from .design.pid import PID, PIDGains, gap_loop_pole
from .errors import InputError, short_repr
from .modes import contact_mode_model
from .params import ContactLaw, Sensors
from .plant import Plant, PlantKind, build_plant, check_plant
from .references import Reference

__all__ = [
    "MeshBacklash",
    "dead_zone_factor",
    "sampled_pid",
    "loop_frequency_response",
    "loop_around_backlash",
    "restitution_coefficient",
    "impact_gain",
    "predict_limit_cycle",
    "run_limit_cycle",
    "simulate_limit_cycle",
    "describe",
]


# --- the element ----------------------------------------------------------------------------------------


def dead_zone_factor(A: ArrayLike, b: float) -> Any:
    """Describing-function factor ``eta(A)`` of a dead zone of half-width ``b`` with unit slope.

    ``eta = 1 - (2/pi) (asin(b/A) + (b/A) sqrt(1 - (b/A)^2))`` for ``A > b``, 0 for ``A <= b``.

    Parameters
    ----------
    A : float or array_like
        Amplitude of the sinusoidal input [m], ``A >= 0``.
    b : float
        Half-width of the dead zone (the backlash) [m], ``b >= 0``.

    Returns
    -------
    float or ndarray
        ``eta`` in ``[0, 1)`` [1], the shape of ``A``.

    Raises
    ------
    InputError
        If an amplitude is NaN or negative, or ``b`` is not a finite number >= 0 (before, NaN and negative
        amplitudes read as inside the gap: ``eta = 0``).

    Notes
    -----
    With ``cos phi = b / A``: ``eta = (2 phi - sin 2 phi) / pi``, evaluated with
    ``phi = atan2(sqrt((A - b)(A + b)), b)`` (no cancellation in ``A - b``) and, below ``phi = 0.01``
    where ``2 phi - sin 2 phi`` cancels, its Taylor series ``x^3/6 (1 - x^2/20 + x^4/840)``, ``x = 2 phi``.
    Near the flank, ``A = b (1 + delta)``: ``eta ~ (4 / (3 pi)) (2 delta)^(3/2) = 1.2 delta^(3/2)``.

    Examples
    --------
    >>> round(float(dead_zone_factor(2.0, 1.0)), 6)
    0.391002
    >>> float(dead_zone_factor(0.5, 1.0))
    0.0
    """
    A = np.asarray(A, dtype=float)
    if np.any(np.isnan(A)) or np.any(A < 0):
        raise InputError(f"A = {short_repr(A.tolist())} is out of range: expected amplitudes >= 0 [m] (not NaN)",
                         field="A")
    if isinstance(b, bool) or not isinstance(b, numbers.Real):  # numpy's integers too; True is not a width
        raise InputError(f"b = {b!r} is not a number: expected a finite number >= 0 [m]", field="b")
    if not (math.isfinite(b) and b >= 0):
        raise InputError(f"b = {b!r} is out of range: expected a finite number >= 0 [m]", field="b")
    phi = np.arctan2(np.sqrt(np.maximum((A - b) * (A + b), 0.0)), b)
    x = 2.0 * phi
    closed = (x - np.sin(x)) / np.pi
    series = x**3 / 6.0 * (1.0 - x**2 / 20.0 * (1.0 - x**2 / 42.0)) / np.pi
    eta = np.where(A > b, np.where(phi < 1e-2, series, closed), 0.0)
    return float(eta) if eta.ndim == 0 else eta


class MeshBacklash(ct.DescribingFunctionNonlinearity):
    """The mesh contact law as a python-control describing-function nonlinearity.

    ``F = k (s - b sign s) + c s'`` for ``|s| > b``, ``F = 0`` in the gap: an elastic dead zone with a
    damper that acts only in contact (the improved plant's linear law, report eqs 3 and 10).

    Parameters
    ----------
    k : float
        Mesh stiffness [N/m], > 0.
    b : float
        Half-gap along the line of action [m], >= 0.
    c : float
        Mesh damping [N s/m], >= 0 (used by :meth:`force` and :meth:`describing_function_at` only).

    Raises
    ------
    InputError
        For ``k``, ``b`` or ``c`` not a finite number in its range (named).

    Notes
    -----
    For ``s = A sin(omega t)`` the first harmonic of ``F`` is ``(k + j omega c) eta(A) s``: the spring
    gives ``k eta`` (the dead-zone result) and the gated damper ``j omega c eta`` with the *same* factor:
    over the contact arcs ``theta0 < omega t < pi - theta0`` (and their mirror), ``sin theta0 = b / A``,
    ``(2/pi) int (sin t - sin theta0) sin t dt`` and ``(2/pi) int cos^2 t dt`` both equal
    ``1 - (2/pi)(theta0 + sin theta0 cos theta0) = eta`` (``tests/test_describe.py`` checks both by
    quadrature). python-control's interface has
    ``N(A)`` without frequency, so :meth:`describing_function` is the static spring ``k eta(A)`` and
    :meth:`__call__` the static dead-zone spring; the damper enters the harmonic balance as the factor
    ``(1 + j omega c / k)`` on the linear part (:func:`loop_frequency_response` with
    ``mesh_damping=True``), which is exact for this element.

    Examples
    --------
    >>> el = MeshBacklash(k=1e8, b=5e-5)
    >>> el(1e-4), el(-1e-4), el(1e-5)
    (5000.0, -5000.0, 0.0)
    """

    def __init__(self, k: float, b: float, c: float = 0.0) -> None:
        super().__init__()
        for name, value, low, rule in (("k", k, 0.0, "> 0 [N/m]"), ("b", b, 0.0, ">= 0 [m]"),
                                       ("c", c, 0.0, ">= 0 [N s/m]")):
            number = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
            if not (number and (value > low if name == "k" else value >= low)):
                raise InputError(f"{name} = {value!r} is out of range: expected a finite number {rule}", field=name)
        self.k, self.b, self.c = float(k), float(b), float(c)

    def __call__(self, x: float) -> float:
        """Return the static dead-zone spring force ``k (x - b sign x)`` outside the gap, 0 inside [N]."""
        x = float(np.squeeze(x))
        if x > self.b:
            return self.k * (x - self.b)
        if x < -self.b:
            return self.k * (x + self.b)
        return 0.0

    def _isstatic(self) -> bool:
        return True

    def force(self, s: ArrayLike, v: ArrayLike) -> Any:
        """Return the full contact force ``k (s - b sign s) + c v`` in contact, 0 in the gap [N].

        Parameters
        ----------
        s : float or array_like
            Relative displacement [m].
        v : float or array_like
            Its rate ``s'`` [m/s].
        """
        s, v = np.asarray(s, dtype=float), np.asarray(v, dtype=float)
        contact = np.abs(s) > self.b
        return np.where(contact, self.k * (s - self.b * np.sign(s)) + self.c * v, 0.0)

    def describing_function(self, A: float) -> float:
        """Return the describing function of the static spring, ``k eta(A)`` [N/m] (real).

        Parameters
        ----------
        A : float
            Amplitude of ``s`` [m].

        Raises
        ------
        ValueError
            For ``A < 0`` (python-control's convention).
        """
        if A < 0:
            raise ValueError("cannot evaluate describing function for A < 0")
        return self.k * dead_zone_factor(A, self.b)

    def describing_function_at(self, A: ArrayLike, omega: ArrayLike) -> Any:
        """Return the describing function with the gated damper, ``(k + j omega c) eta(A)`` [N/m].

        Parameters
        ----------
        A : float or array_like
            Amplitude of ``s`` [m].
        omega : float or array_like
            Frequency [rad/s], finite.

        Raises
        ------
        InputError
            If an amplitude is NaN or negative, or a frequency not finite.
        """
        w = np.asarray(omega, dtype=float)
        if not np.all(np.isfinite(w)):
            raise InputError(f"omega = {short_repr(w.tolist())} is not finite: expected frequencies [rad/s]",
                             field="omega")
        return (self.k + 1j * w * self.c) * dead_zone_factor(A, self.b)


# --- the linear part --------------------------------------------------------------------------------------


def _pid_parts(controller: Any, Ts: float | None, feedback: str | None) -> tuple[PIDGains, float, str]:
    if isinstance(controller, PID):
        gains = controller.gains
        Ts = controller.Ts if Ts is None else Ts
        feedback = controller.feedback if feedback is None else feedback
    elif isinstance(controller, PIDGains):
        gains = controller
        Ts = 0.0 if Ts is None else Ts
        feedback = "load" if feedback is None else feedback
    else:
        raise InputError(f"controller = {type(controller).__name__}: the describing-function loop is derived for a "
                         f"PID (kind = 'pid' controller file or PIDGains)", field="controller")
    if not (math.isfinite(Ts) and Ts >= 0.0):
        raise InputError(f"Ts = {Ts!r} is out of range: expected a number >= 0 [s] (0: continuous PID)", field="Ts")
    if feedback not in ("load", "motor"):
        raise InputError(f"feedback = {feedback!r}: expected 'motor' or 'load'", field="feedback")
    return gains, float(Ts), feedback


def _check_coulomb(plant: Plant) -> None:
    """Refuse Coulomb friction (the describing function's linear part has viscous friction only), naming the model's
    keys that hold it: on a train the design pair's motor side lumps the intermediate shafts' (a reviewer was told to
    zero coulomb_friction1/2, both already 0)."""
    sh = plant.shafts
    keys = [k for k, v in (("coulomb_friction1", sh[0].tc), ("coulomb_friction2", sh[-1].tc),
                           ("intermediate_coulomb_friction", any(x.tc for x in sh[1:-1]))) if v]
    if keys:
        tcs = ", ".join(f"{x.tc!r}" for x in sh)
        raise InputError(f"coulomb friction = ({tcs}) N m on the shafts, motor first: the linear part of the loop has "
                         f"viscous friction only; set the model's {', '.join(keys)} to 0", field=keys[0])


def _check_plant(plant: Plant) -> None:
    check_plant(plant)  # a Plant at all (a string was an AttributeError on .kind)
    if plant.kind is not PlantKind.IMPROVED or plant.kv_table is not None:
        raise InputError(f"plant = {plant.kind.value!r}: the describing function is derived for the improved "
                         f"plant's piecewise-linear contact law", field="plant")
    _check_coulomb(plant)
    if plant.load_torque != 0.0:
        raise InputError(f"load_torque = {plant.load_torque!r} N m: a constant load torque preloads one flank and "
                         f"biases s, which the symmetric describing function does not cover; analyse the model "
                         f"with load_torque = 0", field="load_torque")
    if plant.backlash <= 0.0:
        raise InputError("backlash = 0: without a gap there is no describing function to balance; give a "
                         "model with backlash > 0 [m]", field="backlash")


def sampled_pid(gains: PIDGains, Ts: float) -> ct.TransferFunction:
    """The sampled PID of :class:`~gearctl.design.pid.PID` as a discrete transfer function, error to torque.

    :meth:`PIDGains.sampled_tf`, the one statement of the discretisation (see its Notes).

    Parameters
    ----------
    gains : PIDGains
        The PID's gains.
    Ts : float
        Sample period [s].

    Returns
    -------
    control.TransferFunction
        ``C(z)`` with ``dt = Ts``, input ``e``, output ``xi1``.

    Raises
    ------
    InputError
        If ``Ts`` is not a sample period (1e-6..1 s).
    """
    return gains.sampled_tf(Ts)


def _controller_response(gains: PIDGains, Ts: float, omega: NDArray[np.float64]) -> NDArray[np.complex128]:
    """Fundamental of the controller output per unit input phasor.

    ``C(e^{j w Ts}) (1 - e^{-j w Ts}) / (j w Ts)`` for the sampled PID with its zero-order hold,
    ``C(j w)`` for ``Ts = 0``.
    """
    s = 1j * omega
    if Ts == 0.0:
        wf = 2 * math.pi * gains.derivative_filter_hz
        return np.asarray(gains.kp + gains.ki / s + gains.kd * s / (1 + s / wf), dtype=np.complex128)
    kp, kiT, kdT, a = gains.discrete(Ts)
    z = np.exp(s * Ts)
    C = kp + kiT / (z - 1) + kdT * (z - 1) / (z - a)
    return C * (1 - 1 / z) / (s * Ts)


def loop_frequency_response(plant: Plant, controller: PID | PIDGains, omega: ArrayLike, *, Ts: float | None = None,
                            feedback: str | None = None, mesh_damping: bool = False) -> NDArray[np.complex128]:
    """Frequency response of the linear part ``H`` around the backlash element, ``s = -H F``.

    Parameters
    ----------
    plant : Plant
        The improved plant (inertias, base radii, viscous friction; ``k``, ``c`` with ``mesh_damping``).
    controller : PID or PIDGains
        A PID (its ``Ts`` and ``feedback`` are used unless given) or bare gains.
    omega : array_like
        Frequencies [rad/s], > 0.
    Ts : float, optional
        Sample period [s]; 0 for the continuous PID. Default: the controller's, or 0 for gains.
    feedback : str, optional
        ``"load"`` or ``"motor"``. Default: the controller's, or ``"load"`` for gains.
    mesh_damping : bool
        Multiply by ``1 + j omega c / k``, the gated damper's share of the describing function
        (see :class:`MeshBacklash`), so that the balance reads ``1 + k eta(A) H(j omega) = 0``.

    Returns
    -------
    ndarray of complex
        ``H(j omega)`` [m/N].

    Raises
    ------
    InputError
        For a plant the describing function does not cover (not the improved plant, Coulomb friction, a load
        torque, no backlash), a controller that is not a PID or its gains, ``Ts`` or ``feedback`` out of range,
        or an ``omega`` that is not finite and > 0.

    Notes
    -----
    With ``P_i = J_i s^2 + d_i s`` and ``F`` pushing gear 1 back and gear 2 forward,
    ``theta1 = (u - r_b1 F) / P1`` and ``theta2 = r_b2 F / P2``. Load feedback, ``u = -C theta2``:
    ``H = r_b1^2 / P1 + r_b2^2 / P2 + r_b1 r_b2 C / (P1 P2)``. Motor feedback (the PID sees
    ``theta1 / N``), ``u = -C theta1 / N``: ``H = r_b1^2 / (P1 + C / N) + r_b2^2 / P2``.

    Sampling is exact for the fundamental: a sinusoid sampled at ``Ts``, passed through ``C(z)`` and
    held, has at ``omega`` the component ``C(e^{j omega Ts}) (1 - e^{-j omega Ts}) / (j omega Ts)``
    (the hold is the half-sample delay ``e^{-j omega Ts/2}`` times ``sinc(omega Ts / 2)``); its images at
    ``omega + m 2 pi / Ts`` are filtered by the double integrators and neglected, as harmonics are in
    any describing-function balance. Valid below the Nyquist frequency ``pi / Ts``.
    """
    _check_plant(plant)
    gains, Ts, feedback = _pid_parts(controller, Ts, feedback)
    w = np.asarray(omega, dtype=float)
    if np.any(~np.isfinite(w)) or np.any(w <= 0):
        raise InputError("omega must be finite frequencies > 0 [rad/s]", field="omega")
    s = 1j * w
    p = plant
    P1 = p.J1 * s**2 + p.d1 * s
    P2 = p.J2 * s**2 + p.d2 * s
    C = _controller_response(gains, Ts, w)
    if feedback == "load":
        H = p.rb1**2 / P1 + p.rb2**2 / P2 + p.rb1 * p.rb2 * C / (P1 * P2)
    else:
        H = p.rb1**2 / (P1 + C / p.gear_ratio) + p.rb2**2 / P2
    if mesh_damping:
        H = H * (1 + s * p.c / p.k)
    return H


def loop_around_backlash(plant: Plant, gains_or_controller: PID | PIDGains, *, Ts: float | None = None,
                         feedback: str | None = None, pade_order: int = 6,
                         mesh_damping: bool = False) -> ct.TransferFunction:
    """Build the linear part ``H(s)`` around the backlash element as a continuous transfer function.

    Parameters
    ----------
    plant : Plant
        The improved plant.
    gains_or_controller : PID or PIDGains
        The PID (``Ts`` and ``feedback`` taken from it unless given) or its gains.
    Ts : float, optional
        Sample period [s]; 0 gives the continuous PID ``kp + ki/s + kd s/(1 + s/omega_f)``. Default: the
        controller's, or 0 for bare gains.
    feedback : str, optional
        ``"load"`` (default for gains) or ``"motor"``.
    pade_order : int
        Order ``n`` of the diagonal Padé approximant of ``e^{-s Ts}`` used for the sampler and hold.
    mesh_damping : bool
        Include the gated damper's factor ``1 + s c / k`` (see :func:`loop_frequency_response`).

    Returns
    -------
    control.TransferFunction
        ``H(s)`` [m/N], input the contact force ``F``, output ``-s`` (the relative displacement with
        the sign of the loop), named ``H``.

    Raises
    ------
    InputError
        For a controller that is not a PID, a plant other than the improved one without Coulomb friction,
        or ``pade_order`` outside 1..10.

    Notes
    -----
    The formulas are those of :func:`loop_frequency_response`. For ``Ts > 0`` the sampled PID and the
    hold are written with ``z = e^{s Ts}`` replaced by its ``(n, n)`` Padé approximant, so ``C(z)`` and
    ``(1 - z^{-1}) / (s Ts)`` become rational in ``s``: the transfer function converges to the exact
    sampled-data fundamental response below the Nyquist frequency as ``n`` grows (``n = 6``: relative
    error about 1e-9 up to 0.9 of the Nyquist frequency for ``pid_load`` on ``shing1993_servo``, checked
    in the tests). The predictions use the exact response; this transfer function is for
    python-control's tools (``describing_function_response``, Nyquist plots, margins).
    """
    _check_plant(plant)
    gains, Ts, feedback = _pid_parts(gains_or_controller, Ts, feedback)
    if not (isinstance(pade_order, int) and 1 <= pade_order <= 10):
        raise InputError(f"pade_order = {pade_order!r} is out of range: expected an integer in 1..10",
                         field="pade_order")
    P = np.polynomial.polynomial  # coefficient arrays in increasing powers of s (converted at the end)
    p = plant
    P1, P2 = np.array([0.0, p.d1, p.J1]), np.array([0.0, p.d2, p.J2])
    if Ts == 0.0:
        wf = 2 * math.pi * gains.derivative_filter_hz
        # C = (kp s (1 + s/wf) + ki (1 + s/wf) + kd s^2) / (s (1 + s/wf))
        Nc = P.polyadd(P.polyadd(P.polymul([0.0, gains.kp], [1.0, 1 / wf]), P.polymul([gains.ki], [1.0, 1 / wf])),
                       [0.0, 0.0, gains.kd])
        Dc = P.polymul([0.0, 1.0], [1.0, 1 / wf])
    else:
        num, den = ct.pade(Ts, pade_order)  # e^{-s Ts} ~ num/den (decreasing powers)
        Q, R = np.asarray(den, float)[::-1], np.asarray(num, float)[::-1]  # z = e^{s Ts} ~ Q / R
        kp, kiT, kdT, a = gains.discrete(Ts)
        zm1 = P.polysub(Q, R)  # (z - 1) R
        zma = P.polysub(Q, a * R)  # (z - a) R
        # C = kp + kiT R/(Q - R) + kdT (Q - R)/(Q - a R)
        Nc = P.polyadd(P.polyadd(kp * P.polymul(zm1, zma), kiT * P.polymul(R, zma)), kdT * P.polymul(zm1, zm1))
        Dc = P.polymul(zm1, zma)
        # hold: (1 - z^{-1}) / (s Ts) = (Q - R) / (Q s Ts); Q - R is odd in s, so divide out s exactly
        hold_num = zm1[1:] / Ts
        Nc, Dc = P.polymul(Nc, hold_num), P.polymul(Dc, Q)
    if feedback == "load":
        # H = (rb1^2 P2 Dc + rb2^2 P1 Dc + rb1 rb2 Nc) / (P1 P2 Dc)
        num_H = P.polyadd(P.polyadd(p.rb1**2 * P.polymul(P2, Dc), p.rb2**2 * P.polymul(P1, Dc)),
                          p.rb1 * p.rb2 * Nc)
        den_H = P.polymul(P.polymul(P1, P2), Dc)
    else:
        # H = rb1^2 Dc / (P1 Dc + Nc/N) + rb2^2 / P2
        M = P.polyadd(P.polymul(P1, Dc), Nc / p.gear_ratio)
        num_H = P.polyadd(p.rb1**2 * P.polymul(Dc, P2), p.rb2**2 * M)
        den_H = P.polymul(M, P2)
    if mesh_damping:
        num_H = P.polymul(num_H, [1.0, p.c / p.k])
    # the s factor common to numerator and denominator (P1, P2 and the integrator) cancels exactly
    while num_H.size > 1 and den_H.size > 1 and num_H[0] == 0.0 and den_H[0] == 0.0:
        num_H, den_H = num_H[1:], den_H[1:]
    num_H, den_H = np.trim_zeros(num_H[::-1], "f"), np.trim_zeros(den_H[::-1], "f")
    scale = den_H[0]
    return ct.tf(num_H / scale, den_H / scale, inputs="F", outputs="minus_s", name="H")


# --- impacts ----------------------------------------------------------------------------------------------


def restitution_coefficient(plant: Plant) -> float:
    """Coefficient of restitution ``e`` of one tooth collision of the free gear pair.

    A collision lasts about half a mesh period, short against a limit cycle, so the two inertias collide
    as if free: ``m_eq delta'' + c delta' + k delta = 0`` from ``delta = 0``, ``delta' = v``, until the
    flanks part. ``e = |delta'_out| / v``.

    Parameters
    ----------
    plant : Plant
        The improved plant (``k``, ``c``, ``m_eq``, contact law).

    Returns
    -------
    float
        ``e`` in ``[0, 1]`` [1].

    Notes
    -----
    ``zeta = c / (2 sqrt(k m_eq))``. Linear law (the flanks part when ``delta`` returns to 0):
    ``e = exp(-pi zeta / sqrt(1 - zeta^2))``, 0 for ``zeta >= 1`` (no return). No-pull law (they part
    when the force ``k delta + c delta'`` reaches 0, at ``omega_d t = pi - atan2(c omega_d, k - c sigma)``):
    ``e = -delta'(t) / v`` there; for ``zeta >= 1/sqrt(2)`` the force is zero at once and ``e = 1``
    is not physical, so the overdamped case is integrated numerically.
    """
    p = plant
    zeta = p.c / (2 * math.sqrt(p.k * p.m_eq))
    wn = p.natural_frequency
    if p.contact_law is ContactLaw.LINEAR:
        return math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)) if zeta < 1 else 0.0
    if zeta < 1 / math.sqrt(2):
        wd, sig = wn * math.sqrt(1 - zeta**2), zeta * wn
        t = (math.pi - math.atan2(p.c * wd, p.k - p.c * sig)) / wd
        vel = math.exp(-sig * t) * (math.cos(wd * t) - sig / wd * math.sin(wd * t))
        return float(min(max(-vel, 0.0), 1.0))

    def rhs(t: float, y: NDArray[np.float64]) -> list[float]:
        return [y[1], -(p.k * y[0] + p.c * y[1]) / p.m_eq]

    def lift(t: float, y: NDArray[np.float64]) -> float:
        return p.k * y[0] + p.c * y[1] if t > 0 else 1.0

    lift.terminal, lift.direction = True, -1  # type: ignore[attr-defined]
    sol = scipy.integrate.solve_ivp(rhs, (0.0, 50 / wn), [0.0, 1.0], events=lift, rtol=1e-10, atol=1e-14)
    return float(max(-sol.y_events[0][0][1], 0.0)) if sol.t_events[0].size else 0.0


def impact_gain(e: float) -> complex:
    """First-harmonic gain of a bouncing contact, ``N = m_eq omega^2 g(e)``: returns ``g(e)`` [1].

    Parameters
    ----------
    e : float
        Coefficient of restitution, ``0 <= e <= 1``.

    Returns
    -------
    complex
        ``g(e)``; ``g(1) = 1``, and ``arg g`` is the loss angle of the impacts.

    Raises
    ------
    InputError
        For ``e`` outside 0..1.

    Notes
    -----
    Model of the bouncing regime: ``s`` crosses the gap ``2 b`` in half a period, leaving one flank at
    ``e v`` and reaching the other at ``v`` under a constant acceleration (the loop's energy input),
    ``2 b = (1 + e) v T / 4``; each collision is an impulse ``m_eq (1 + e) v`` (alternating sign). With
    ``omega = 1``: ``s`` on ``[0, pi]`` is ``-b + u0 t + a t^2 / 2``, ``u0 = e v``,
    ``a = (1 - e) v / pi``, ``v = 4 b / (pi (1 + e))``, odd about ``pi``; its first harmonic is
    ``s1 = (2/pi)(2 j b + u0 (-2 - j pi) + (a/2)(-2 pi + j (4 - pi^2)))`` and that of the impulses
    ``F1 = -8 m_eq b / pi^2``, so ``g = F1 / (m_eq s1)``. For ``e = 1`` (symmetric triangle wave)
    ``s1 = -8 b / pi^2`` and ``g = 1``: the element then only balances the free-mass compliance.

    Examples
    --------
    >>> impact_gain(1.0)
    (1+0j)
    >>> g = impact_gain(0.8545)
    >>> round(g.real, 4), round(g.imag, 4)
    (0.9975, 0.0498)
    """
    if not (0.0 <= e <= 1.0):
        raise InputError(f"e = {e!r} is out of range: expected 0 <= e <= 1", field="e")
    v = 4.0 / (math.pi * (1.0 + e))
    u0, a = e * v, (1.0 - e) * v / math.pi
    s1 = (2 / math.pi) * (2j + u0 * (-2 - 1j * math.pi) + (a / 2) * (-2 * math.pi + 1j * (4 - math.pi**2)))
    g = (-8 / math.pi**2) / s1
    return complex(round(g.real, 15) + 0.0, round(g.imag, 15) + 0.0)  # +0.0: no negative zero


def _peak_penetration(plant: Plant, v: float) -> float:
    """Largest overlap of a collision at speed ``v`` [m] (damped oscillator from rest at the flank)."""
    p = plant
    zeta = min(p.c / (2 * math.sqrt(p.k * p.m_eq)), 0.999)
    r = math.sqrt(1 - zeta**2)
    return v / p.natural_frequency * math.exp(-zeta / r * math.atan2(r, zeta))


# --- prediction -------------------------------------------------------------------------------------------


def _omega_grid(plant: Plant, Ts: float, n: int = 40000) -> NDArray[np.float64]:
    top = 0.999 * math.pi / Ts if Ts > 0 else 3.0 * plant.natural_frequency
    return np.geomspace(2 * math.pi * 0.1, top, n)


def _crossings(f: Any, w: NDArray[np.float64]) -> list[float]:
    """Frequencies where ``Im f`` changes sign with ``Re f < 0``, refined with brentq."""
    h = f(w)
    out = []
    for i in np.nonzero(np.sign(h.imag[:-1]) * np.sign(h.imag[1:]) < 0)[0]:
        wc = scipy.optimize.brentq(lambda x: float(f(np.array([x]))[0].imag), w[i], w[i + 1], xtol=1e-12,
                                   rtol=1e-13)
        if f(np.array([wc]))[0].real < 0:
            out.append(wc)
    return out


def _amplitude_for(eta: float, b: float) -> float:
    """Inverse of :func:`dead_zone_factor` on ``(b, inf)``."""
    if not (0.0 < eta < 1.0):
        return math.inf
    hi = 2 * b
    while dead_zone_factor(hi, b) < eta:
        hi *= 2
    return scipy.optimize.brentq(lambda A: dead_zone_factor(A, b) - eta, b, hi, xtol=1e-15 * b, rtol=1e-13)


def _dominant_pole(plant: Plant, gains: PIDGains, Ts: float, feedback: str, kappa: float,
                   c_eff: float) -> tuple[float, float]:
    """Growth rate [1/s] and frequency [Hz] of the least damped pole of the linear loop with the element
    replaced by a spring ``kappa`` and damper ``c_eff`` (exact ZOH discretisation for ``Ts > 0``)."""
    sys = contact_mode_model(dataclasses.replace(plant, k=kappa, c=c_eff))  # type: ignore[call-arg]  # Plant(**pair)
    G = sys[1, 0] if feedback == "load" else sys[0, 0] * (1.0 / plant.gear_ratio)
    G = ct.ss(G.A, G.B, G.C, G.D)
    if Ts > 0:
        L = sampled_pid(gains, Ts) * ct.c2d(G, Ts, "zoh")
        poles = np.log(ct.feedback(ct.ss(L), 1).poles().astype(complex)) / Ts
    else:
        poles = ct.feedback(ct.ss(gains.tf()) * G, 1).poles().astype(complex)
    i = int(np.argmax(poles.real))
    return float(poles[i].real), float(abs(poles[i].imag) / (2 * math.pi))


def _spectral_abscissa(plant: Plant, gains: PIDGains, Ts: float, feedback: str, kappa: float, c_eff: float) -> float:
    """Growth rate of the linear loop with the element replaced by a spring ``kappa`` and damper ``c_eff``.

    ``max log|z| / Ts`` (sampled, exact ZOH discretisation) or ``max Re s`` (continuous) [1/s].
    """
    return _dominant_pole(plant, gains, Ts, feedback, kappa, c_eff)[0]


def _torque_amplitude(plant: Plant, gains: PIDGains, Ts: float, feedback: str, w: float, theta2: complex,
                      N: complex) -> float:
    C = complex(_controller_response(gains, Ts, np.array([w]))[0])
    if feedback == "load":
        return abs(C * theta2)
    # motor feedback: theta1 = -rb1 F / (P1 + C/N); F = N s; the torque is -C theta1 / N
    s = 1j * w
    P1 = plant.J1 * s**2 + plant.d1 * s
    P2 = plant.J2 * s**2 + plant.d2 * s
    F = theta2 * P2 / plant.rb2
    return abs(C / plant.gear_ratio * plant.rb1 * F / (P1 + C / plant.gear_ratio))


def predict_limit_cycle(plant: Plant, controller: PID | PIDGains, *, method: str = "describing_function",
                        mesh_damping: bool = True, Ts: float | None = None,
                        feedback: str | None = None) -> list[dict[str, Any]]:
    """Limit cycles of a PID loop around the backlash, by first-harmonic balance.

    Parameters
    ----------
    plant : Plant
        The improved plant.
    controller : PID or PIDGains
        The PID (``Ts``, ``feedback`` from it unless given).
    method : str
        ``"describing_function"``: ``1 + N(A) H(j omega) = 0`` with the sinusoidal-input describing
        function of :class:`MeshBacklash`. ``"impact"``: the bouncing-contact balance
        ``1 + m_eq omega^2 g(e) H(j omega) = 0`` (phase condition; :func:`impact_gain`), one per stable
        describing-function cycle.
    mesh_damping : bool
        Keep the gated damper ``j omega c eta(A)`` in the describing function (``"describing_function"``
        only). See Notes for why it is on by default.
    Ts : float, optional
        Sample period [s] overriding the controller's (0: continuous PID).
    feedback : str, optional
        ``"load"`` or ``"motor"`` overriding the controller's.

    Returns
    -------
    list of dict
        One per solution, by increasing frequency: ``amplitude`` (of ``s``, peak) [m],
        ``frequency_hz`` [Hz], ``stable`` (bool), ``load_amplitude`` (of ``theta2`` from the linear loop)
        [rad], ``torque_amplitude`` [N m] (above the motor's limit the prediction ignores saturation),
        ``eta`` (``N / k``) [1], ``penetration`` (``amplitude / b - 1``) [1], ``damping_ratio``
        (``c omega / k`` at the solution) [1], ``method``; for ``"impact"`` also ``restitution`` [1] and
        ``contact_fraction`` (share of the period in contact) [1]. Empty when no solution exists.

    Raises
    ------
    InputError
        For an unknown ``method``, or a plant or controller outside the analysis (see
        :func:`loop_around_backlash`).

    Notes
    -----
    *Describing function.* With ``-1/N(A)`` on the negative real axis (``N`` real without damper), the
    balance is ``Im H = 0`` (frequency) and ``k eta(A) = -1 / Re H`` (amplitude, needs
    ``-k Re H >= 1``), searched below the Nyquist frequency. With the damper,
    ``N = k eta (1 + j omega c / k)`` and the factor is moved onto ``H``. ``python-control``'s
    ``describing_function_response`` finds the same crossings (``tests/test_describe.py``); the
    balance is solved here with brentq on the exact sampled response because ``H`` is ~1e-6 m/N, below
    the fixed 1e-8 threshold of its segment-intersection test unless rescaled.

    ``c omega / k`` is small (5.5e-3 at the cycle of ``pid_load`` on ``shing1993_servo``), but above the
    loop's bandwidth ``H`` is nearly the free-mass compliance ``-1 / (m_eq omega^2)`` and ``Im H / Re H``
    is of the same small order, so the damper shifts the phase balance while changing ``|N|`` by less
    than 1e-4: the frequency moves by 3 % there (156 -> 151 Hz) and by a factor 2 for the same kind of
    design sampled at 10 kHz. It is kept.

    Stability: the loop with the element replaced by the spring ``k eta(A)`` (and damper ``c eta(A)``) is
    checked just below and above the solution's amplitude (exact ZOH discretisation for ``Ts > 0``); the
    cycle is stable when the loop is unstable below (small oscillations grow) and stable above (large
    ones decay).

    *When it fails.* The describing function assumes ``s`` nearly sinusoidal. When the cycle only grazes
    the flanks (``penetration`` of a few percent, frequency far below the mesh mode), ``s`` is a
    triangle wave between the flanks with short collisions: its first harmonic is about ``8 A / pi^2``,
    the force comes in impulses, and the element's first-harmonic gain measured in the simulated cycle
    of ``pid_load`` is 0.31 ``k eta(A)`` with a loss angle of 0.09 rad, set by the collisions'
    restitution, not by ``c omega / k`` (0.005), while ``H`` itself holds to 1e-4 there (both checked in
    ``tests/test_describe.py``). The amplitude (about ``b``) and the load amplitude (the momentum split
    of that motion) stay right; the frequency comes out 1.3-2.4 times too high on ``shing1993_servo``
    (load-side PIDs sampled at 1-10 kHz), and for a motor-side PID the describing function even predicts
    a cycle (needing a hard excitation) that the simulation does not sustain. ``method="impact"``
    balances the phase with the loss angle of bouncing collisions instead (:func:`impact_gain`) and
    takes the amplitude as ``b`` plus the peak penetration of a collision at the bouncing speed
    ``4 b omega / (pi (1 + e))``; it assumes collisions short against the period (``contact_fraction``
    small) and makes no stability claim of its own (``stable`` is the describing function's).
    """
    _check_plant(plant)
    gains, Ts, feedback = _pid_parts(controller, Ts, feedback)
    if method not in ("describing_function", "impact"):
        raise InputError(f"method = {method!r}: expected 'describing_function' or 'impact'", field="method")
    p = plant
    w = _omega_grid(p, Ts)

    def H(x: NDArray[np.float64], damp: bool = mesh_damping) -> NDArray[np.complex128]:
        return loop_frequency_response(p, gains, x, Ts=Ts, feedback=feedback, mesh_damping=damp)

    def load_amp(wc: float, N: complex, A: float) -> complex:
        # theta2 = rb2 F / P2 and F = N s (first harmonic of s with amplitude A)
        P2 = p.J2 * (1j * wc) ** 2 + p.d2 * 1j * wc
        return p.rb2 * N * A / P2

    out: list[dict[str, Any]] = []
    for wc in _crossings(H, w):
        eta = -1.0 / (p.k * float(H(np.array([wc]))[0].real))
        if not (0.0 < eta < 1.0):
            continue
        A = _amplitude_for(eta, p.backlash)
        lo, hi = p.backlash + 0.95 * (A - p.backlash), p.backlash + 1.05 * (A - p.backlash)
        cf = p.c if mesh_damping else 0.0
        grow_lo = _spectral_abscissa(p, gains, Ts, feedback, p.k * dead_zone_factor(lo, p.backlash),
                                     cf * dead_zone_factor(lo, p.backlash))
        grow_hi = _spectral_abscissa(p, gains, Ts, feedback, p.k * dead_zone_factor(hi, p.backlash),
                                     cf * dead_zone_factor(hi, p.backlash))
        N = (p.k + (1j * wc * p.c if mesh_damping else 0.0)) * eta
        th2 = load_amp(wc, N, A)
        out.append({
            "method": "describing_function", "amplitude": float(A), "frequency_hz": float(wc / (2 * math.pi)),
            "stable": bool(grow_lo > 0 > grow_hi), "load_amplitude": float(abs(th2)),
            "torque_amplitude": _torque_amplitude(p, gains, Ts, feedback, wc, th2, N), "eta": float(eta),
            "penetration": float(A / p.backlash - 1), "damping_ratio": float(wc * p.c / p.k),
        })
    if method == "describing_function":
        return out
    e = restitution_coefficient(p)
    g = impact_gain(e)
    rot = g / abs(g)
    imp: list[dict[str, Any]] = []
    for cyc in (c for c in out if c["stable"]):
        cands = _crossings(lambda x: H(x, False) * rot, w)
        if not cands:
            continue
        w0 = 2 * math.pi * cyc["frequency_hz"]
        wc = min(cands, key=lambda x: abs(math.log(x / w0)))
        v = 4 * p.backlash * wc / (math.pi * (1 + e))
        A = p.backlash + _peak_penetration(p, v)
        N = p.m_eq * wc**2 * g
        th2 = load_amp(wc, N, A)
        imp.append({
            "method": "impact", "amplitude": float(A), "frequency_hz": float(wc / (2 * math.pi)), "stable": True,
            "load_amplitude": float(abs(th2)),
            "torque_amplitude": _torque_amplitude(p, gains, Ts, feedback, wc, th2, N),
            "eta": float(abs(N) / p.k), "penetration": float(A / p.backlash - 1),
            "damping_ratio": float(wc * p.c / p.k), "restitution": float(e),
            "contact_fraction": float(wc / p.natural_frequency),  # two collisions of pi / omega_n per period
        })
    return imp


# --- simulation -------------------------------------------------------------------------------------------


class _Oversampled(Controller):
    """A controller run at its own period inside a loop sampled ``factor`` times faster.

    The plant state is recorded at ``Ts / factor`` while the command is updated every ``factor`` samples
    and held, so the loop is the same sampled-data system.
    """

    def __init__(self, inner: Controller, factor: int) -> None:
        super().__init__()
        self.inner, self.factor = inner, factor
        self.name, self.Ts = inner.name, inner.Ts / factor
        self.uses_load_encoder = inner.uses_load_encoder
        self._i, self._u = 0, 0.0

    def reset(self) -> None:
        self.inner.reset()
        self._i, self._u = 0, 0.0
        self.solve_times, self.fallbacks = [], []

    def step(self, t: float, y_motor: float, y_load: float | None, ref: ReferenceLike) -> float:
        if self._i % self.factor == 0:
            self._u = self.inner.step(t, y_motor, y_load, ref)
        self._i += 1
        return self._u

    def describe(self) -> dict[str, Any]:
        return self.inner.describe()


#: Rows :func:`run_limit_cycle` may record (about 0.3 kB each while the loop runs): its default oversampling is
#: lowered to stay within them, an explicit one beyond them is refused. :func:`simulate_limit_cycle` records
#: at the controller's period only and finds the peaks by re-integrating the contact intervals, one at a time.
MAX_RECORDED_ROWS = 200_000

#: Fine samples per controller sample allowed (``oversample``).
MAX_OVERSAMPLE = 10_000


def _collision_oversample(plant: Plant, Ts: float) -> int:
    """Plant samples per controller sample for eight samples per collision (half a mesh period)."""
    contact = math.pi / plant.natural_frequency
    return max(1, math.ceil(Ts / (contact / 8)))


def _check_oversample(oversample: int) -> None:
    if not (isinstance(oversample, int) and not isinstance(oversample, bool) and 1 <= oversample <= MAX_OVERSAMPLE):
        raise InputError(f"oversample = {oversample!r} is out of range: expected an integer in 1..{MAX_OVERSAMPLE}",
                         field="oversample")


def _default_x0(plant: Plant, controller: Controller) -> NDArray[np.float64]:
    """The measured shaft turned by half the gap (flanks apart, at rest): a disturbance the controller sees."""
    if controller.uses_load_encoder:
        return np.array([0.0, -0.5 * plant.backlash / plant.rb2, 0.0, 0.0])
    return np.array([0.5 * plant.backlash / plant.rb1, 0.0, 0.0, 0.0])


def run_limit_cycle(plant: Plant, controller: Controller, *, duration: float = 2.0, x0: ArrayLike | None = None,
                    sensors: Sensors | None = None, oversample: int | None = None) -> ClosedLoopResult:
    """Run the closed loop behind :func:`simulate_limit_cycle`, recorded finely enough to see the collisions.

    Parameters
    ----------
    plant : Plant
        The plant.
    controller : Controller
        Any gearctl controller (reset before the run), at its own sample period.
    duration : float
        Simulated time [s].
    x0 : array_like, optional
        Initial state ``[theta1, theta2, omega1, omega2]``. Default: the shaft the controller measures turned
        by half the gap (the load, ``theta2 = -b / (2 r_b2)``, for load feedback; the motor,
        ``theta1 = b / (2 r_b1)``, for motor feedback), flanks apart, at rest: the controller sees that error.
    sensors : Sensors, optional
        Encoders (default: ideal, as the describing function assumes).
    oversample : int, optional
        Plant samples per controller sample. Default: enough for eight samples per collision (half a mesh
        period), lowered so that the run records at most :data:`MAX_RECORDED_ROWS` rows.

    Returns
    -------
    ClosedLoopResult
        From :func:`~gearctl.closedloop.simulate_closed_loop`, at ``Ts / oversample``; the controller
        still updates every ``Ts`` and its command is held (the same sampled-data loop).

    Raises
    ------
    InputError
        For a bad ``oversample`` or ``duration``, or an ``oversample`` that would record more than
        :data:`MAX_RECORDED_ROWS` rows.
    SimulationError
        If the loop diverges.

    Notes
    -----
    The recording, not the loop, is what costs: a stiff small pair (a 0.2 mm module watch gear, mesh mode
    83 kHz, 1 ms PID) needs 1325 samples per controller sample to see its collisions, 2.65 million rows for
    2 s. :func:`simulate_limit_cycle` does not record them (it re-integrates only the contact intervals).
    """
    samples = max(1, math.ceil(duration / controller.Ts)) if math.isfinite(duration) and duration > 0 else 1
    if oversample is None:
        oversample = max(1, min(_collision_oversample(plant, controller.Ts), MAX_RECORDED_ROWS // samples))
    _check_oversample(oversample)
    if samples > MAX_RECORDED_ROWS:  # the controller's samples alone: only a shorter run helps
        raise InputError(f"duration = {duration:g} s at Ts = {controller.Ts:g} s would record {samples:,} controller "
                         f"samples (about {samples * 3e-4:.0f} MB): expected at most {MAX_RECORDED_ROWS:,}, "
                         f"{MAX_RECORDED_ROWS * controller.Ts:g} s at this sample time; lower the duration",
                         field="duration")
    if samples * oversample > MAX_RECORDED_ROWS:
        raise InputError(f"oversample = {oversample} over {duration:g} s at Ts = {controller.Ts:g} s would record "
                         f"{samples * oversample:,} rows (about {samples * oversample * 3e-4:.0f} MB): expected at "
                         f"most {MAX_RECORDED_ROWS:,}; lower oversample or duration, or use simulate_limit_cycle, "
                         f"which finds the peaks without recording them", field="oversample")
    x0 = _default_x0(plant, controller) if x0 is None else np.asarray(x0, dtype=float)
    loop = _Oversampled(controller, oversample) if oversample > 1 else controller
    return simulate_closed_loop(plant, loop, Reference(kind="step", amplitude=0.0), duration, sensors=sensors,
                                x0=np.asarray(x0, dtype=float))


def _contact_extremes(res: ClosedLoopResult, first: int, factor: int) -> tuple[float, float, float, float, int]:
    """Largest and smallest ``s`` and ``theta2`` from sample ``first`` on, between the samples too.

    Each interval ``[t_i, t_i+1]`` that starts or ends in contact, holds a located event, or (in the gap) has the
    load's speed change sign, is integrated again from the recorded state with the recorded (held) torque, at
    ``Ts / factor``; the rest stay in the gap with the load moving one way (in the gap ``J2 theta2'' = -d2 theta2'
    + load torque`` is first order in the speed: it changes sign at most once per interval, seen at the samples), so
    their extremes of ``s`` and ``theta2`` are at the samples. Memory: one interval at a time. Returns
    ``(s_max, s_min, theta2_max, theta2_min, n)`` with ``n`` the intervals re-integrated.
    """
    from .kernel import Kernel

    plant = res.plant
    t = res.t
    n = t.size - 1
    mode = np.asarray(res.mode).reshape(-1, t.size)
    touch = np.any(mode[:, first:n] != 0, axis=0) | np.any(mode[:, first + 1:n + 1] != 0, axis=0)
    w2 = res.x[plant.nx // 2 + 1]
    touch |= w2[first:n] * w2[first + 1:n + 1] <= 0.0  # theta2 turns inside the interval
    ev = res.event_log["t"]
    if ev.size:
        k = np.searchsorted(t, ev, side="left") - 1  # the interval holding each event (t_k, t_k+1]
        k = k[(k >= first) & (k < n)] - first
        touch[k] = True
    idx = np.nonzero(touch)[0] + first
    s = np.atleast_2d(res.s)[0]
    th2 = res.x[1]
    hi, lo = float(np.max(s[first:])), float(np.min(s[first:]))
    hi2, lo2 = float(np.max(th2[first:])), float(np.min(th2[first:]))
    if factor <= 1 or idx.size == 0:
        return hi, lo, hi2, lo2, 0
    h = (t[1] - t[0]) / factor
    kn = Kernel(plant, res.x[:, idx[0]], dt=h)
    u2 = plant.load_torque
    for i in idx.tolist():
        kn.set_state(res.x[:, i])
        status, xs, _, _ = kn.run(float(res.torque[i]), u2, h, factor)
        if xs.shape[1]:
            si = np.atleast_2d(plant.relative_displacement(xs))[0]
            hi, lo = max(hi, float(si.max())), min(lo, float(si.min()))
            hi2, lo2 = max(hi2, float(xs[1].max())), min(lo2, float(xs[1].min()))
    return hi, lo, hi2, lo2, int(idx.size)


def simulate_limit_cycle(plant: Plant, controller: Controller, *, duration: float = 2.0,
                         x0: ArrayLike | None = None, window: float = 0.5, sensors: Sensors | None = None,
                         oversample: int | None = None) -> dict[str, Any]:
    """Run the closed loop at zero reference from a small disturbance and measure the cycle it settles to.

    Parameters
    ----------
    plant : Plant
        The plant.
    controller : Controller
        Any gearctl controller (reset before the run).
    duration : float
        Simulated time [s].
    x0 : array_like, optional
        Initial state; default as :func:`run_limit_cycle` (the measured shaft turned by half the gap).
    window : float
        Fraction of the run, at its end, over which the cycle is measured (0 < window <= 1).
    sensors : Sensors, optional
        Encoders (default: ideal, as the describing function assumes).
    oversample : int, optional
        Fine samples per controller sample used to find the peaks of ``s`` inside the window's contact
        intervals (1..10000; 1: the controller's samples only). Default: eight per collision (half a mesh
        period).

    Returns
    -------
    dict
        ``amplitude``: half peak-to-peak of ``s`` [m]; ``frequency_hz``: from the upward zero crossings
        of ``s`` minus its mean at the controller's samples (linearly interpolated; valid below the Nyquist
        frequency ``1 / (2 Ts)``), None without at least three crossings;
        ``load_amplitude``: half peak-to-peak of ``theta2`` [rad], its peaks found between the samples as
        those of ``s`` (at the controller's samples alone it read 3 % low on ``pid_load``); ``impacts_per_second``
        [1/s];
        ``torque_amplitude``: half peak-to-peak of the motor torque [N m]; ``saturated_fraction``: share
        of the window's samples with the torque at its limit [1]; ``limit_cycle``: whether the flanks are
        still being hit at the end (impacts in the window and ``amplitude > b``);
        ``window`` [s, s]: the interval measured.

    Raises
    ------
    InputError
        For a ``duration``, ``window`` or ``oversample`` out of range, or a train (one gap is measured: pass
        :meth:`Plant.equivalent_pair`, as :func:`describe` does).
    SimulationError
        If the loop diverges (from :func:`~gearctl.closedloop.simulate_closed_loop`).

    Notes
    -----
    The run is recorded at the controller's period (``duration / Ts`` rows, what was asked); the peaks of
    ``s``, which last half a mesh period, are found by integrating each interval of the window that touches
    a flank again, from its recorded state with its held torque, on the fine grid (the same exact solver,
    so the same trajectory), one interval at a time. Memory follows from ``duration / Ts``, time from the
    contact intervals times ``oversample``, not from the mesh stiffness.
    """
    if not (0.0 < window <= 1.0):
        raise InputError(f"window = {window!r} is out of range: expected 0 < window <= 1", field="window")
    if getattr(plant, "n_stages", 1) > 1:  # its load angle would be read off the first intermediate shaft
        raise InputError(f"plant: a {plant.n_stages}-stage train; the limit cycle is measured on one gap: pass "
                         "plant.equivalent_pair() (as describe does)", field="plant")
    factor = _collision_oversample(plant, controller.Ts) if oversample is None else oversample
    _check_oversample(min(factor, MAX_OVERSAMPLE) if oversample is None else factor)
    factor = min(factor, MAX_OVERSAMPLE)
    res = run_limit_cycle(plant, controller, duration=duration, x0=x0, sensors=sensors, oversample=1)
    t0 = res.t[-1] * (1.0 - window)
    m = res.t >= t0
    first = int(np.argmax(m))
    t, s, th2, u = res.t[m], np.atleast_2d(res.s)[0][m], res.x[1, m], res.torque[m]
    sc = s - s.mean()
    up = np.nonzero((sc[:-1] < 0) & (sc[1:] >= 0))[0]
    tz = t[up] - sc[up] * (t[up + 1] - t[up]) / (sc[up + 1] - sc[up])
    freq = (tz.size - 1) / (tz[-1] - tz[0]) if tz.size >= 3 else None
    span = t[-1] - t[0]
    n_imp = sum(1 for ev in res.impacts if ev.t >= t0)
    s_hi, s_lo, th2_hi, th2_lo, _ = _contact_extremes(res, first, factor)
    amp = float((s_hi - s_lo) / 2)
    lim = plant.torque_limit
    sat = float(np.mean(np.abs(u[:-1]) >= lim * (1 - 1e-12))) if math.isfinite(lim) and u.size > 1 else 0.0
    return {
        "amplitude": amp, "frequency_hz": None if freq is None else float(freq),
        "load_amplitude": float((th2_hi - th2_lo) / 2), "impacts_per_second": float(n_imp / span),
        "torque_amplitude": float((u.max() - u.min()) / 2), "saturated_fraction": sat,
        "limit_cycle": bool(n_imp > 0 and amp > plant.backlash and freq is not None),
        # the flanks are still hit but the window holds under three periods: no frequency, so no verdict either way
        # (a load swinging off by lost motions is no rattle: the verdict says the loop does not settle)
        "too_short": bool(n_imp > 0 and amp > plant.backlash and freq is None
                          and (th2.max() - th2.min()) / 2 <= UNSETTLED_LOST_MOTIONS * 2 * plant.backlash / plant.rb2),
        "window": [float(t[0]), float(t[-1])],
    }


# --- the report -------------------------------------------------------------------------------------------


def _ratio(a: float | None, b: float | None) -> float | None:
    return None if a is None or b is None or b == 0 else float(a / b)


def describe(model: str | Path | GearModel, controller: str | Path, *, duration: float = 2.0) -> dict[str, Any]:
    """Describing-function prediction and simulation of the limit cycle of a PID loop with backlash.

    What ``gearctl describe MODEL CONTROLLER`` prints (as a table, and with ``--json`` as this dict).

    Parameters
    ----------
    model : str, Path or GearModel
        Catalog name, TOML path or loaded model; its improved plant is used.
    controller : str or Path
        Catalog name or path of a ``kind = "pid"`` controller file.
    duration : float
        Simulated time [s]; the cycle is measured over its second half.

    Returns
    -------
    dict
        JSON-ready (floats, bools, strings, lists, None):

        - ``model``, ``controller`` (names), ``feedback``, ``sample_time`` [s];
        - ``prediction``: list of dicts of :func:`predict_limit_cycle` (describing function);
        - ``impact_prediction``: the same for ``method="impact"``;
        - ``torque_limit``: the servo's [N m] (None without one): a predicted cycle whose ``torque_amplitude``
          exceeds it cannot run as predicted (the prediction is linear in the torque; the text table marks it);
        - ``simulation``: dict of :func:`simulate_limit_cycle`;
        - ``agreement``: prediction / simulation for the first stable describing-function cycle:
          ``amplitude_ratio``, ``frequency_ratio``, ``load_amplitude_ratio``, ``penetration_ratio``
          (``A/b - 1``), and ``impact_amplitude_ratio``, ``impact_frequency_ratio`` (None where
          either side has no cycle);
        - ``verdict``: one or two sentences on what prediction and simulation say together (why they cannot
          be compared when they cannot: saturation, a cycle at the Nyquist frequency, a motor loop unstable
          once the load lets go);
        - ``gap_loop``: for a motor-side PID, ``growth_rate`` [1/s] and ``frequency_hz`` of the least damped
          pole of the motor alone under the PID (the load let go), None for load feedback;
        - ``method_notes``: one paragraph on the method and how far to trust it here, ending with the verdict.

    Raises
    ------
    InputError
        Unknown model or controller, a controller that is not a PID, or a plant outside the analysis.
    """
    gm = model if isinstance(model, GearModel) else load_model(model)
    train = build_plant(gm)
    plant = train.equivalent_pair()  # a train is analysed as its one-gap pair (the controllers' design model)
    ctrl = load_controller(controller, train, sensors=gm.sensors)  # (refused if it reads a missing load encoder)
    if not isinstance(ctrl, PID):
        raise InputError(f"controller {str(controller)!r} is of kind = {ctrl.describe().get('kind')!r}: "
                         f"the describing-function analysis covers kind = 'pid' controllers", field="controller")
    _check_coulomb(train)  # on the train itself: its keys are named (the pair lumps the intermediate shafts')
    pred = predict_limit_cycle(plant, ctrl)
    imp = predict_limit_cycle(plant, ctrl, method="impact")
    sim = simulate_limit_cycle(plant, ctrl, duration=duration)
    stable = next((c for c in pred if c["stable"]), None)
    have = stable is not None and sim["limit_cycle"]
    b = plant.backlash
    cyc: dict[str, Any] = stable if stable is not None else {}  # (have is False without a stable cycle)
    agreement = {
        "amplitude_ratio": _ratio(cyc["amplitude"], sim["amplitude"]) if have else None,
        "frequency_ratio": _ratio(cyc["frequency_hz"], sim["frequency_hz"]) if have else None,
        "load_amplitude_ratio": _ratio(cyc["load_amplitude"], sim["load_amplitude"]) if have else None,
        "penetration_ratio": _ratio(cyc["penetration"], sim["amplitude"] / b - 1) if have else None,
        "impact_amplitude_ratio": _ratio(imp[0]["amplitude"], sim["amplitude"]) if have and imp else None,
        "impact_frequency_ratio": _ratio(imp[0]["frequency_hz"], sim["frequency_hz"]) if have and imp else None,
    }
    gains, Ts, feedback = _pid_parts(ctrl, None, None)
    # the motor alone under a motor-side PID, the load let go: a loop of its own in the gap (the design's own test,
    # free of the rounding a spring of 1e-12 k left: +0.03 /s on a stable loop)
    gap = gap_loop_pole(ctrl.info, gains, Ts) if feedback == "motor" else None
    notes = _notes(plant, ctrl, pred, imp, sim)
    verdict = _verdict(plant, ctrl, pred, sim, gap)
    notes += " " + verdict
    if train.n_stages > 1:
        notes = (f"The {train.n_stages}-stage train is analysed as its equivalent one-gap pair (the whole lost "
                 f"motion in one gap at the output, the stages' series stiffness; Plant.equivalent_pair). " + notes)
    return {
        "model": gm.name, "controller": ctrl.name, "feedback": ctrl.feedback, "sample_time": ctrl.Ts,
        "design_notes": list(ctrl.design_notes),
        "backlash": plant.backlash, "stages": train.n_stages, "prediction": pred, "impact_prediction": imp,
        "torque_limit": train.torque_limit if math.isfinite(train.torque_limit) else None,
        "simulation": sim, "agreement": agreement, "verdict": verdict,
        "gap_loop": None if gap is None else {"growth_rate": gap[0], "frequency_hz": gap[1]},
        "method_notes": notes,
    }


def _verdict(plant: Plant, ctrl: PID, pred: list[dict[str, Any]], sim: dict[str, Any],
             gap: tuple[float, float] | None) -> str:
    """One or two sentences on what the prediction and the simulation say together, true in every case."""
    b = plant.backlash
    stable = next((c for c in pred if c["stable"]), None)
    nyquist = 0.5 / ctrl.Ts
    why = []
    if sim["saturated_fraction"] > 0.2:
        why.append(f"the torque sits on its {plant.torque_limit:g} N m limit {sim['saturated_fraction']:.0%} of the "
                   f"window, which the describing function (no saturation) ignores")
    if sim["frequency_hz"] is not None and sim["frequency_hz"] >= 0.95 * nyquist:
        why.append(f"the cycle is at {sim['frequency_hz'] / nyquist:.0%} of the Nyquist frequency {nyquist:g} Hz (the "
                   f"command changes sign about every sample), which the balance, solved below it, cannot reach")
    if gap is not None and gap[0] > 0:
        why.append(f"with the load let go the motor alone under this PID is unstable (grows at {gap[0]:.3g} /s at "
                   f"{gap[1]:.4g} Hz): the gap does not calm the loop, it destabilises it, so the balance's "
                   f"stability test, which sees that mode on both sides of every solution, calls none stable")
    reason = ("; ".join(why) + ".") if why else ""
    if sim["limit_cycle"] and stable is not None:
        return (f"Verdict: a limit cycle, predicted at {stable['frequency_hz']:.4g} Hz, A = "
                f"{stable['amplitude'] / b:.4f} b and simulated at {sim['frequency_hz']:.4g} Hz, A = "
                f"{sim['amplitude'] / b:.4f} b (ratios in 'agreement'). "
                + (f"Caution: {reason}" if reason else "")).strip()
    if sim["limit_cycle"]:
        what = ("unstable solutions only" if pred else "no solution")
        return (f"Verdict: the simulation settles to a limit cycle ({sim['frequency_hz']:.4g} Hz, A = "
                f"{sim['amplitude'] / b:.4f} b, {sim['impacts_per_second']:.4g} impacts/s) that the describing "
                f"function does not predict ({what}), so there is nothing to compare" +
                (f": {reason}" if reason else "."))
    if sim.get("too_short"):
        w0, w1 = sim["window"]
        pre = (f"a stable cycle is predicted at {stable['frequency_hz']:.4g} Hz, A = {stable['amplitude'] / b:.4f} b; "
               if stable is not None else "")
        return (f"Verdict: {pre}the simulation still hits the flanks at the end ({sim['impacts_per_second']:.4g} "
                f"impacts/s, A = {sim['amplitude'] / b:.4f} b), but its window ({w0:.4g} to {w1:.4g} s) holds fewer "
                f"than three periods, too short to measure a cycle: run a longer duration (--duration; the cycle is "
                f"measured over the second half)" + (f" ({reason})" if reason else "."))
    if stable is not None:
        return (f"Verdict: a stable cycle is predicted at {stable['frequency_hz']:.4g} Hz, A = "
                f"{stable['amplitude'] / b:.4f} b, but the simulation from a half-gap disturbance does not sustain "
                f"one: a cycle that needs a hard excitation, or a false positive of the describing function"
                + (f" ({reason})" if reason else "."))
    lost = 2 * b / plant.rb2
    if lost > 0 and sim["load_amplitude"] > UNSETTLED_LOST_MOTIONS * lost:  # no rattle: a loop that does not hold
        return (f"Verdict: no backlash limit cycle, but the loop does not settle: the load swings "
                f"{sim['load_amplitude']:.4g} rad ({sim['load_amplitude'] / lost:.3g}x the lost motion) in the "
                f"window measured, so this PID does not hold this plant (gearctl track shows the run)"
                + (f": {reason}" if reason else "."))
    return "Verdict: no limit cycle, predicted or simulated" + (f" ({reason})" if reason else ".")


#: A simulated load amplitude beyond this many lost motions is no backlash rattle (the catalog's and reviewers' cycles
#: stay below a quarter of one) but a loop that does not hold the plant: the verdict says so.
UNSETTLED_LOST_MOTIONS = 3.0


def _notes(plant: Plant, ctrl: PID, pred: list[dict[str, Any]], imp: list[dict[str, Any]],
           sim: dict[str, Any]) -> str:
    p = plant
    stable = next((c for c in pred if c["stable"]), None)
    text = (
        f"Element: mesh contact law F = k (s - b sign s) + c s' outside the gap, DF N = (k + j w c) eta(A) "
        f"(k = {p.k:.4g} N/m, b = {p.backlash:.3g} m, c = {p.c:.4g} N s/m). Linear part: s = -H F with "
        f"H = rb1^2/P1 + rb2^2/P2 + rb1 rb2 C/(P1 P2) (load feedback) or rb1^2/(P1 + C/N) + rb2^2/P2 "
        f"(motor), P_i = J_i s^2 + d_i s; the sampled PID C(e^(jwTs)) with its zero-order hold "
        f"(1 - e^(-jwTs))/(jwTs) exactly at the fundamental (Ts = {ctrl.Ts:g} s). "
    )
    if stable is None:
        text += "No stable describing-function solution below the Nyquist frequency: no limit cycle predicted. "
    else:
        text += (
            f"Stable solution at {stable['frequency_hz']:.4g} Hz, A = {stable['amplitude'] / p.backlash:.4f} b "
            f"(c w / k = {stable['damping_ratio']:.2g}; kept, because H is nearly the free-mass compliance "
            f"there and its phase is of that order). "
        )
        below = [c for c in pred if not c["stable"] and c["amplitude"] < stable["amplitude"]]
        if below:
            text += (f"An unstable solution at {below[-1]['frequency_hz']:.4g} Hz, A = "
                     f"{below[-1]['amplitude'] / p.backlash:.4f} b, lies below it: smaller oscillations decay, "
                     f"the cycle needs a hard excitation. ")
        if stable["torque_amplitude"] > p.torque_limit:
            text += (f"Its torque amplitude {stable['torque_amplitude']:.3g} N m exceeds the limit "
                     f"{p.torque_limit:g} N m, which the prediction ignores. ")
        if stable["penetration"] < 0.3:
            text += (
                "The solution only grazes the flanks (penetration {:.1%} of b). In that regime s is a triangle "
                "wave with short collisions, not a sinusoid: the DF amplitude and load amplitude hold better "
                "than its frequency, which comes out too high (1.3-2.4 x on shing1993_servo), and the DF can "
                "predict cycles that collisions cannot sustain (see the impact balance). ".format(stable["penetration"])
            )
        if imp:
            e = imp[0]["restitution"]
            psi = math.atan2(impact_gain(e).imag, impact_gain(e).real)
            text += (f"Impact balance for that motion (restitution e = {e:.3f}, loss angle {psi:.3f} rad, "
                     f"in contact {imp[0]['contact_fraction']:.1%} of the period): "
                     f"{imp[0]['frequency_hz']:.4g} Hz, A = {imp[0]['amplitude'] / p.backlash:.4f} b. ")
        else:
            text += ("Impact balance: the loop's phase nowhere makes up the collisions' loss angle, so no "
                     "bouncing cycle is sustained (the DF solution needs contact over much of the period). ")
    if sim["limit_cycle"]:
        text += (f"Simulation (ideal encoders, zero reference, last {sim['window'][1] - sim['window'][0]:.3g} s): "
                 f"{sim['frequency_hz']:.4g} Hz, A = {sim['amplitude'] / p.backlash:.4f} b, "
                 f"{sim['impacts_per_second']:.4g} impacts/s.")
    else:
        text += "Simulation: no sustained impacts at the end of the run (no limit cycle)."
    return text
