"""An independent reference solution: scipy's ``solve_ivp`` with terminal events at ``|s| = b``.

Written from the report's equations directly (not from the kernel's matrices), it is the oracle that the
speed benchmark measures every solver's error against and a second opinion for the tests. It is slow
(about one simulated second per wall second), which is why gearctl does not simulate with it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp

from .errors import InputError
from .params import FrictionLaw
from .plant import Plant, PlantKind
from .stiffness import yang_sun_damping_factor

__all__ = ["reference_solution"]


def _rhs_factory(p: Plant) -> Callable[..., Callable[[float, NDArray[np.float64]], NDArray[np.float64]]]:
    w = len(p.shafts)

    def make(sides: Sequence[int], u1: float, u2: float, d_ys: Sequence[float]) -> Callable[[float, NDArray], NDArray]:
        def f(t: float, x: NDArray[np.float64]) -> NDArray[np.float64]:
            theta, omega = x[:w], x[w:]
            T = np.zeros(w)
            T[0] += u1
            T[-1] += u2
            for i, st in enumerate(p.stages):
                side = sides[i]
                if st.backlash == 0.0:  # no gap: the flank is the sign of s, a label on the path (no events)
                    side = 1 if st.rb1 * theta[i] - st.rb2 * theta[i + 1] >= 0.0 else -1
                if side == 0:
                    continue
                if side > 0:  # eqs 3-5
                    delta = st.rb1 * theta[i] - st.rb2 * theta[i + 1] - st.backlash
                    ddelta = st.rb1 * omega[i] - st.rb2 * omega[i + 1]
                else:  # eqs 10-12
                    delta = st.rb2 * theta[i + 1] - st.rb1 * theta[i] - st.backlash
                    ddelta = st.rb2 * omega[i + 1] - st.rb1 * omega[i]
                if p.kind is PlantKind.YANG_SUN:
                    Fn = (d_ys[i] * ddelta + st.k) * delta
                else:
                    Fn = float(p.stiffness_at(theta[i], i, side)) * delta + st.c * ddelta
                if p.contact_law.value == "no_pull":
                    Fn = max(Fn, 0.0)
                F = side * Fn
                T[i] -= st.rb1 * F
                T[i + 1] += st.rb2 * F
            dx = np.empty(2 * w)
            dx[:w] = omega
            for j, sh in enumerate(p.shafts):
                fr = sh.d * omega[j] + (sh.tc * np.tanh(omega[j] / p.coulomb_velocity) if sh.tc else 0.0)
                # eqs 1-2 (front), 6-7 (separation), 8-9 (back) per stage, with F signed as the front flank's
                dx[w + j] = (T[j] - fr) / sh.J
            return dx

        return f

    return make


def reference_solution(
    plant: Plant,
    x0: ArrayLike,
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
        A pair or a train; Coulomb friction only with the smooth law.
    x0 : sequence of float
        Initial state.
    t_eval : ndarray
        Increasing output times starting at 0 [s].
    torque : (float, float) or callable
        Constant torques, or ``f(i, x) -> (xi_motor, xi_load)`` held over ``[t_eval[i], t_eval[i+1])`` (a
        sampled controller). The servo's load torque is added to the load torque.
    rtol : float
        Relative tolerance; the absolute tolerance is ``1e-6`` of it times the backlash scale.
    method : str
        ``solve_ivp`` method.

    Returns
    -------
    x : ndarray, shape (nx, n)
    impacts : list of (float, int)
        Impact time and side (+1 front, -1 back); for a train the side is multiplied by the stage number
        (``+-(i + 1)``), so a pair's are ``+-1`` as always.

    Raises
    ------
    InputError
        For a plant with Coulomb friction under the stick-slip law (field ``friction_law``).
    RuntimeError
        After 100 000 events within one sample (an event cascade).
    """
    p = plant
    if p.has_coulomb and p.friction_law is FrictionLaw.STICK_SLIP:
        raise InputError("the reference solution integrates Coulomb friction with the smooth law only: build the "
                         "plant with friction_law = 'smooth'", field="friction_law")
    make = _rhs_factory(p)
    n = p.n_stages
    x = np.asarray(x0, dtype=float).copy()
    out = np.empty((x.size, t_eval.size))
    out[:, 0] = x
    impacts: list[tuple[float, int]] = []
    s = p.gaps(x)
    sides = [1 if s[i] > st.backlash else (-1 if s[i] < -st.backlash else 0) for i, st in enumerate(p.stages)]
    d_ys = [yang_sun_damping_factor(st.k, 0.0) if sides[i] else 0.0 for i, st in enumerate(p.stages)]
    w = len(p.shafts)
    scale = min(max(st.backlash, 1e-6) / st.rb2 for st in p.stages)
    atol = np.array([1.0] * w + [p.natural_frequency] * w) * scale * 1e-3 * rtol
    t = float(t_eval[0])
    max_step = 0.05 * 2 * math.pi / p.natural_frequency

    def boundary(i: int, sign: float, direction: int) -> Callable[[float, NDArray[np.float64]], float]:
        st = p.stages[i]

        def g(t: float, x: NDArray[np.float64]) -> float:
            return st.rb1 * x[i] - st.rb2 * x[i + 1] + sign * st.backlash

        g.terminal = True  # type: ignore[attr-defined]
        g.direction = direction  # type: ignore[attr-defined]
        return g

    for k in range(t_eval.size - 1):
        u1, u2 = torque(k, x) if callable(torque) else torque
        u2 = u2 + p.load_torque
        t_next = float(t_eval[k + 1])
        guard = 0
        while t < t_next:
            events, owners = [], []
            for i in range(n):
                if p.stages[i].backlash == 0.0:  # its flank follows the sign of s inside the right-hand side
                    continue
                if sides[i] == 0:  # watch both flanks
                    events += [boundary(i, -1.0, 1), boundary(i, 1.0, -1)]
                    owners += [(i, 1), (i, -1)]
                elif sides[i] > 0:
                    events.append(boundary(i, -1.0, -1))
                    owners.append((i, 0))
                else:
                    events.append(boundary(i, 1.0, 1))
                    owners.append((i, 0))
            # steps of at most a twentieth of the fastest mesh period: a step spanning a whole dip of a gap past
            # its flank and back shows no sign change, and the event would be missed
            sol = solve_ivp(make(sides, u1, u2, d_ys), (t, t_next), x, method=method, rtol=rtol, atol=atol,
                            events=events or None, max_step=max_step)
            if sol.status == 1:  # an event: switch that stage's mode
                e = next(j for j, ev in enumerate(sol.t_events) if len(ev))
                te, xe = float(sol.t_events[e][0]), sol.y_events[e][0]
                i, target = owners[e]
                st = p.stages[i]
                v = st.rb1 * xe[w + i] - st.rb2 * xe[w + i + 1]
                if sides[i] == 0:
                    sides[i] = 1 if v > 0 else -1
                    impacts.append((te, sides[i] * (i + 1)))
                    d_ys[i] = yang_sun_damping_factor(st.k, abs(v))
                else:
                    sides[i] = 0 if st.backlash > 0 else -sides[i]
                t, x = te, np.array(xe, dtype=float)
                # the next segment watches the crossing in the other direction only, so it does not fire at once
                guard += 1
                if guard > 100000:
                    raise RuntimeError("reference solution: event cascade")
            else:
                t, x = t_next, sol.y[:, -1].copy()
        out[:, k + 1] = x
    return out, impacts
