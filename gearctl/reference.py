"""An independent reference solution: scipy's ``solve_ivp`` with terminal events at ``|s| = b``.

Written from the report's equations directly (not from the kernel's matrices), it is the oracle that the
speed benchmark measures every solver's error against and a second opinion for the tests. It is slow
(about one simulated second per wall second), which is why gearctl does not simulate with it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from .plant import Plant, PlantKind
from .stiffness import yang_sun_damping_factor

__all__ = ["reference_solution"]


def _rhs_factory(p: Plant) -> Callable[..., Callable[[float, NDArray[np.float64]], NDArray[np.float64]]]:
    def make(side: int, u1: float, u2: float, d_ys: float) -> Callable[[float, NDArray[np.float64]], NDArray]:
        def f(t: float, x: NDArray[np.float64]) -> NDArray[np.float64]:
            theta1, theta2, w1, w2 = x
            F = 0.0
            if side != 0:
                if side > 0:  # eqs 3-5
                    delta = p.rb1 * theta1 - p.rb2 * theta2 - p.backlash
                    ddelta = p.rb1 * w1 - p.rb2 * w2
                else:  # eqs 10-12
                    delta = p.rb2 * theta2 - p.rb1 * theta1 - p.backlash
                    ddelta = p.rb2 * w2 - p.rb1 * w1
                if p.kind is PlantKind.YANG_SUN:
                    Fn = (d_ys * ddelta + p.k) * delta
                else:
                    Fn = float(p.stiffness_at(theta1)) * delta + p.c * ddelta
                if p.contact_law.value == "no_pull":
                    Fn = max(Fn, 0.0)
                F = side * Fn
            fr1 = p.d1 * w1 + (p.tc1 * np.tanh(w1 / p.coulomb_velocity) if p.tc1 else 0.0)
            fr2 = p.d2 * w2 + (p.tc2 * np.tanh(w2 / p.coulomb_velocity) if p.tc2 else 0.0)
            # eqs 1-2 (front), 6-7 (separation), 8-9 (back), with F signed as the front flank's
            return np.array([w1, w2, (u1 - p.rb1 * F - fr1) / p.J1, (u2 + p.rb2 * F - fr2) / p.J2])

        return f

    return make


def reference_solution(
    plant: Plant,
    x0: Sequence[float],
    t_eval: NDArray[np.float64],
    *,
    torque: tuple[float, float] | Callable[[int, NDArray[np.float64]], tuple[float, float]] = (0.0, 0.0),
    rtol: float = 1e-12,
    method: str = "DOP853",
) -> tuple[NDArray[np.float64], list[tuple[float, int]]]:
    """States at ``t_eval`` and the impacts ``(t, side)``, integrated segment by segment with events.

    Parameters
    ----------
    plant : Plant
    x0 : sequence of 4 floats
        Initial state.
    t_eval : ndarray
        Increasing output times starting at 0 [s].
    torque : (float, float) or callable
        Constant torques, or ``f(i, x) -> (xi1, xi2)`` held over ``[t_eval[i], t_eval[i+1])`` (a
        sampled controller). The servo's load torque is added to ``xi2``.
    rtol : float
        Relative tolerance; the absolute tolerance is ``1e-6`` of it times the backlash scale.
    method : str
        ``solve_ivp`` method.

    Returns
    -------
    x : ndarray, shape (4, n)
    impacts : list of (float, int)
    """
    p = plant
    make = _rhs_factory(p)
    x = np.asarray(x0, dtype=float).copy()
    out = np.empty((4, t_eval.size))
    out[:, 0] = x
    impacts: list[tuple[float, int]] = []
    s = p.rb1 * x[0] - p.rb2 * x[1]
    side = 1 if s > p.backlash else (-1 if s < -p.backlash else 0)
    d_ys = yang_sun_damping_factor(p.k, 0.0) if side else 0.0
    atol = np.array([1, 1, p.natural_frequency, p.natural_frequency]) * max(p.backlash, 1e-6) * 1e-3 * rtol / p.rb2
    t = float(t_eval[0])
    for i in range(t_eval.size - 1):
        u1, u2 = torque(i, x) if callable(torque) else torque
        u2 = u2 + p.load_torque
        t_next = float(t_eval[i + 1])
        guard = 0
        while t < t_next:
            def g_sep_front(t: float, x: NDArray[np.float64]) -> float:
                return p.rb1 * x[0] - p.rb2 * x[1] - p.backlash

            def g_sep_back(t: float, x: NDArray[np.float64]) -> float:
                return p.rb1 * x[0] - p.rb2 * x[1] + p.backlash

            if side == 0:
                g_sep_front.terminal = True  # type: ignore[attr-defined]
                g_sep_front.direction = 1  # type: ignore[attr-defined]
                g_sep_back.terminal = True  # type: ignore[attr-defined]
                g_sep_back.direction = -1  # type: ignore[attr-defined]
                events = [g_sep_front, g_sep_back]
            elif side > 0:
                g_sep_front.terminal = True  # type: ignore[attr-defined]
                g_sep_front.direction = -1  # type: ignore[attr-defined]
                events = [g_sep_front]
            else:
                g_sep_back.terminal = True  # type: ignore[attr-defined]
                g_sep_back.direction = 1  # type: ignore[attr-defined]
                events = [g_sep_back]
            sol = solve_ivp(make(side, u1, u2, d_ys), (t, t_next), x, method=method, rtol=rtol, atol=atol,
                            events=events)
            if sol.status == 1:  # an event: switch mode
                te = next(float(ev[0]) for ev in sol.t_events if len(ev))
                xe = next(ye[0] for ye in sol.y_events if len(ye))
                v = p.rb1 * xe[2] - p.rb2 * xe[3]
                if side == 0:
                    side = 1 if v > 0 else -1
                    impacts.append((te, side))
                    d_ys = yang_sun_damping_factor(p.k, abs(v))
                else:
                    side = 0 if p.backlash > 0 else -side
                t, x = te, np.array(xe, dtype=float)
                # the next segment watches the crossing in the other direction only, so it does not fire at once
                guard += 1
                if guard > 100000:
                    raise RuntimeError("reference solution: event cascade")
            else:
                t, x = t_next, sol.y[:, -1].copy()
        out[:, i + 1] = x
    return out, impacts
