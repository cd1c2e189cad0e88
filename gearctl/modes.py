"""Linear models of the gear plant per contact mode, as python-control objects.

In contact (front or back) the improved plant is exactly linear about any operating point, and both flanks
share the same dynamics; in separation a stage is two free inertias. These models are built from the
plant's own matrices (:func:`gearctl.plant.mode_matrices`, the ones the exact simulator integrates), not by
finite differences across the backlash kink. A train has a model per mode combination: every stage in
contact, every stage separated, each stage separated alone.

A pair's signals: state ``[theta1, theta2, omega1, omega2]`` (deviations from the operating point); inputs
``xi1`` (motor torque) and ``xi2`` (load torque) [N m]; outputs ``theta1`` (motor angle), ``theta2`` (load
angle) [rad], ``s`` (relative displacement along the line of action) [m] and ``force`` (contact force) [N].
A train's: ``theta0..thetan``, ``omega0..omegan``; ``xi0``, ``xin``; ``theta0``, ``thetan``, ``s1..sn``,
``force1..forcen``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from typing import Any

import control as ct
import numpy as np

from .plant import Mode, Plant, check_plant, input_matrix, mode_matrices, signal_names

__all__ = [
    "ContactModes",
    "MeshMode",
    "contact_mode_model",
    "separation_model",
    "rigid_model",
    "linearize_modes",
    "mesh_mode",
    "mode_model",
    "mode_poles",
    "loop_margins",
    "OUTPUTS",
    "output_names",
    "clean_poles",
    "ZERO_POLE_ROUNDING",
]

OUTPUTS = ("theta1", "theta2", "s", "force")

#: Poles within this share of the largest are the eigenvalue solver's rounding of zero. The free rotation's
#: pole is an exact 0; without viscous friction the rigid body is a double zero (a Jordan block), which the
#: solver splits into a pair of size about sqrt(eps |A|): 2.3e-9 of the mesh pole on a 17 x 43 pair
#: (+5e-12 +/- 1.4e-4j rad/s, read as a 2.2e-5 Hz resonance), 3.2e-9 on a three-stage train.
ZERO_POLE_ROUNDING = 1e-7


def clean_poles(poles: Any) -> np.ndarray:
    """``poles`` (complex) with those within :data:`ZERO_POLE_ROUNDING` of the largest set to the 0 they are.

    Parameters
    ----------
    poles : array_like
        Poles (or zeros) of a linear model [rad/s].

    Returns
    -------
    ndarray
        The same values as complex numbers, the rounding of the rigid body's zero poles replaced by 0.

    Examples
    --------
    >>> clean_poles([-3e3 + 6e4j, -3e3 - 6e4j, 5e-12 + 1.4e-4j, 5e-12 - 1.4e-4j]).tolist()[2:]
    [0j, 0j]
    """
    p = np.atleast_1d(np.asarray(poles, dtype=complex)).copy()
    if p.size:
        p[np.abs(p) <= ZERO_POLE_ROUNDING * np.max(np.abs(p))] = 0.0
    return p


def output_names(plant: Plant) -> list[str]:
    """Output names of the linear models: the pair's :data:`OUTPUTS`, or a train's.

    Parameters
    ----------
    plant : Plant
        A pair or a train of ``n`` stages.

    Returns
    -------
    list of str
        The pair's :data:`OUTPUTS`; for a train ``theta0``, ``theta<n>``, ``s1..s<n>`` and ``force1..force<n>``.
    """
    n = plant.n_stages
    if n == 1:
        return list(OUTPUTS)
    return ["theta0", f"theta{n}"] + [f"s{i + 1}" for i in range(n)] + [f"force{i + 1}" for i in range(n)]


def _outputs(plant: Plant, loaded: list[bool]) -> tuple[np.ndarray, np.ndarray]:
    n, w = plant.n_stages, len(plant.shafts)
    C = np.zeros((2 + 2 * n, 2 * w))
    C[0, 0] = 1.0
    C[1, w - 1] = 1.0
    for i, st in enumerate(plant.stages):
        C[2 + i, [i, i + 1]] = [st.rb1, -st.rb2]
        if loaded[i]:  # F = k (s - b) + c s' about the operating point: k ds + c dv
            C[2 + n + i, [i, i + 1, w + i, w + i + 1]] = [st.k * st.rb1, -st.k * st.rb2, st.c * st.rb1, -st.c * st.rb2]
    return C, np.zeros((2 + 2 * n, 2))


def mode_model(plant: Plant, loaded: Sequence[bool | Mode], *, name: str = "mode") -> ct.StateSpace:
    """Linear model with the stages ``loaded`` in contact (front or back alike) and the others separated.

    Parameters
    ----------
    plant : Plant
        The (improved) plant; motor/load inertias and viscous friction of a ``[servo]`` are included.
    loaded : sequence of bool or Mode
        Per stage, whether it is in contact: ``True`` (or ``Mode.FRONT``, ``Mode.BACK``) or separated:
        ``False`` (or ``Mode.SEPARATION``); the integers -1, 0, 1 read as those modes.
    name : str
        System name.

    Returns
    -------
    control.StateSpace
        Named states, inputs and outputs (see the module docstring); deviations about the operating point
        (the ``+-k b`` offset of the contact law only shifts the operating point).

    Raises
    ------
    InputError
        If ``plant`` is not a Plant, or ``loaded`` has not one entry per stage, each a bool or a mode, or it
        separates a stage without backlash, or ``name`` is not a string.
    """

    plant = check_plant(plant)
    loaded = _loaded_flags(plant, loaded)
    states, inputs = signal_names(plant)
    C, D = _outputs(plant, loaded)
    return ct.ss(mode_matrices(plant, loaded), input_matrix(plant), C, D, states=states, inputs=inputs,
                 outputs=output_names(plant), name=_system_name(name))


def _system_name(name: Any) -> str | None:
    """``name`` for python-control (a string, or None for its generated name), or an InputError naming it
    (python-control raised a TypeError from a regex)."""
    if name is not None and not isinstance(name, str):
        from .errors import InputError, short_repr

        raise InputError(f"name = {short_repr(name)} is not a system name: expected a string (or None)", field="name")
    return name


def _loaded_flags(plant: Plant, loaded: Any) -> list[bool]:
    """``loaded`` checked as :func:`mode_model` takes it, as one bool per stage."""
    from .errors import InputError

    if isinstance(loaded, str | bytes) or not isinstance(loaded, Iterable):
        raise InputError(f"loaded = {loaded!r} is not a sequence: expected one bool or Mode per stage "
                         f"({plant.n_stages}), e.g. [True] * {plant.n_stages}", field="loaded")
    loaded = list(loaded)
    if len(loaded) != plant.n_stages:
        raise InputError(f"loaded = {loaded!r} has {len(loaded)} entries: expected one per stage ({plant.n_stages})",
                         field="loaded")
    flags = []
    for i, v in enumerate(loaded):
        if isinstance(v, bool | np.bool_):
            flags.append(bool(v))
        elif isinstance(v, int | np.integer) and int(v) in (-1, 0, 1):
            flags.append(Mode(int(v)) is not Mode.SEPARATION)
        else:
            raise InputError(f"loaded[{i}] = {v!r} is not a contact mode: expected True (in contact), False "
                             "(separated) or a gearctl.Mode (FRONT, SEPARATION, BACK)", field="loaded")
    for i, (flag, b) in enumerate(zip(flags, plant.backlashes, strict=True)):
        if not flag and b == 0.0:
            where = f"stage {i + 1}" if plant.n_stages > 1 else "the pair"
            raise InputError(f"loaded[{i}] = {loaded[i]!r}: {where} has no backlash (backlash = 0), so it cannot "
                             "separate (its contact law is one spring through s = 0): expected it in contact",
                             field="loaded")
    return flags


def mode_poles(plant: Plant, loaded: Sequence[bool | Mode]) -> np.ndarray:
    """Poles of :func:`mode_model` ``(plant, loaded)`` [rad/s], the rigid bodies' exactly.

    Parameters
    ----------
    plant : Plant
        The plant.
    loaded : sequence of bool or Mode
        Per stage, in contact or separated, as :func:`mode_model` takes it.

    Returns
    -------
    ndarray
        ``2 (n + 1)`` complex poles, fastest first: a 0 per rigid body (a group of shafts joined by stages in
        contact), a second 0 for each such body without viscous friction, and the eigenvalues of the model in gap
        coordinates.

    Raises
    ------
    InputError
        As :func:`mode_model`.

    Notes
    -----
    The angles enter the dynamics through the gaps ``s_i`` of the stages in contact only, so the model in the
    coordinates ``(s_i, omega)`` has the same poles less one exact 0 per rigid body. Its eigenvalues carry the
    rounding ``eps |A|`` (1e-6 rad/s where ``|A|`` is 1e10), where the eigenvalues of the angle model round its
    rigid body's pair ``(0, -d / J)`` by ``sqrt(eps |A|)`` (1e-4 rad/s); :func:`clean_poles` then took both for 0
    when ``d / J`` was below 1e-7 of the mesh pole: ``tests/data/heavy_motor_no_limit.toml``'s -5.8155e-5 rad/s
    (a 4.8 h time constant) came out as 0. Here it is -5.8155e-5 to 1e-11, and a frictionless body's second 0
    (rounded to ~1e-13 rad/s in gap coordinates) is set to the 0 it is by count, not by size.
    """
    plant = check_plant(plant)
    flags = _loaded_flags(plant, loaded)
    w = len(plant.shafts)
    on = [i for i, f in enumerate(flags) if f]
    G = np.zeros((len(on), w))
    for row, i in enumerate(on):
        G[row, [i, i + 1]] = [plant.stages[i].rb1, -plant.stages[i].rb2]
    k = np.diag([plant.stages[i].k for i in on])
    c = np.diag([plant.stages[i].c for i in on])
    Mi = np.diag([1.0 / sh.J for sh in plant.shafts])
    D = np.diag([sh.d for sh in plant.shafts])
    A = np.block([[np.zeros((len(on), len(on))), G], [-Mi @ G.T @ k, -Mi @ (G.T @ c @ G + D)]])
    ev = np.linalg.eigvals(A).astype(complex)
    # the rigid bodies: shafts joined by the stages in contact (a chain: stage i joins shafts i and i + 1)
    bodies, start = [], 0
    for i in range(len(flags) + 1):
        if i == len(flags) or not flags[i]:
            bodies.append(range(start, i + 1))
            start = i + 1
    free = sum(all(plant.shafts[j].d == 0.0 for j in body) for body in bodies)
    if free:
        ev[np.argsort(np.abs(ev))[:free]] = 0.0
    return _ordered(np.concatenate([np.zeros(len(bodies), dtype=complex), ev]))


def _ordered(poles: np.ndarray) -> np.ndarray:
    """Poles fastest first (a conjugate pair: positive imaginary part first), -0.0 written as 0."""
    p = np.asarray(poles, dtype=complex) + 0.0
    return p[np.lexsort((-p.imag, -np.abs(p)))]


def contact_mode_model(plant: Plant, *, name: str = "contact") -> ct.StateSpace:
    """Linear model of the plant with every stage in contact (front or back: the same dynamics), eqs 1–5 and 8–12.

    See :func:`mode_model`.

    Parameters
    ----------
    plant : Plant
        The plant; motor/load inertias and viscous friction of a ``[servo]`` are included.
    name : str
        System name (default ``"contact"``).

    Returns
    -------
    control.StateSpace
        Named states, inputs and outputs, as :func:`mode_model` gives them.

    Raises
    ------
    InputError
        If ``plant`` is not a :class:`~gearctl.plant.Plant`, or ``name`` not a string.
    """
    plant = check_plant(plant)
    return mode_model(plant, [True] * plant.n_stages, name=name)


def separation_model(plant: Plant, *, name: str = "separation") -> ct.StateSpace:
    """Linear model with every stage separated: free inertias with their viscous friction (eqs 6–7).

    Same signals as :func:`contact_mode_model`; the ``force`` outputs of the separated stages are identically
    zero. A stage without backlash (``b = 0``) cannot separate: its contact law is one spring through ``s = 0``,
    so it stays in contact here (a backlash-free pair's separation model is its contact model).

    Parameters
    ----------
    plant : Plant
        The plant; motor/load inertias and viscous friction of a ``[servo]`` are included.
    name : str
        System name (default ``"separation"``).

    Returns
    -------
    control.StateSpace
        Named states, inputs and outputs, as :func:`mode_model` gives them.

    Raises
    ------
    InputError
        If ``plant`` is not a :class:`~gearctl.plant.Plant`, or ``name`` not a string.
    """
    plant = check_plant(plant)
    return mode_model(plant, [b == 0.0 for b in plant.backlashes], name=name)


def rigid_model(plant: Plant, *, name: str = "rigid") -> ct.StateSpace:
    """Infinitely stiff meshes: the limit ``k -> inf`` of the contact model, seen from the motor shaft.

    ``J_eq theta1'' = xi1 + xi2 / N - d_eq theta1'`` with ``N`` the overall ratio, ``J_eq = sum_j J_j / N_j^2``,
    ``d_eq = sum_j d_j / N_j^2`` (``N_j``: ratio from the motor to shaft j); every shaft follows the motor,
    ``s = 0``. States ``theta1, omega1`` (``theta0, omega0`` for a train); the force outputs are the forces the
    stiff meshes transmit.

    Parameters
    ----------
    plant : Plant
        The plant; motor/load inertias and viscous friction of a ``[servo]`` are included.
    name : str
        System name (default ``"rigid"``).

    Returns
    -------
    control.StateSpace
        Two states; the inputs and outputs of :func:`contact_mode_model`.

    Raises
    ------
    InputError
        If ``plant`` is not a :class:`~gearctl.plant.Plant`, or ``name`` not a string.
    """
    p = check_plant(plant)
    n, w = p.n_stages, len(p.shafts)
    ratio_to = [math.prod(s.ratio for s in p.stages[:j]) for j in range(w)]
    N = ratio_to[-1]
    J = sum(p.shafts[j].J / ratio_to[j] ** 2 for j in range(w))
    d = sum(p.shafts[j].d / ratio_to[j] ** 2 for j in range(w))
    A = np.array([[0.0, 1.0], [0.0, -d / J]])
    B = np.array([[0.0, 0.0], [1.0 / J, 1.0 / (N * J)]])
    # shaft j: angle theta1 / N_j, acceleration (acc_row x + acc_in u) / N_j. The force of stage i balances
    # what is downstream of it, from the load back: r_b2 F_i = J_(i+1) theta'' + d omega - u_load + r_b1 F_(i+1)
    acc_row = np.array([0.0, -d / J])
    acc_in = np.array([1.0 / J, 1.0 / (N * J)])
    C = np.zeros((2 + 2 * n, 2))
    D = np.zeros((2 + 2 * n, 2))
    C[0, 0] = 1.0
    C[1, 0] = 1.0 / N
    Fc, Fd = np.zeros(2), np.zeros(2)  # the force of the stage after the current one
    for i in reversed(range(n)):
        j = i + 1
        sh = p.shafts[j]
        rc = sh.J / ratio_to[j] * acc_row + np.array([0.0, sh.d / ratio_to[j]])
        rd = sh.J / ratio_to[j] * acc_in - (np.array([0.0, 1.0]) if j == n else 0.0)
        if j < n:
            rc, rd = rc + p.stages[j].rb1 * Fc, rd + p.stages[j].rb1 * Fd
        Fc, Fd = rc / p.stages[i].rb2, rd / p.stages[i].rb2
        C[2 + n + i], D[2 + n + i] = Fc, Fd
    states = ["theta1", "omega1"] if n == 1 else ["theta0", "omega0"]
    return ct.ss(A, B, C, D, states=states, inputs=signal_names(p)[1], outputs=output_names(p),
                 name=_system_name(name))


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class MeshMode:
    """The mesh (tooth-contact) mode of the contact model.

    Attributes
    ----------
    natural_frequency : float
        Undamped natural frequency ``omega_n`` of the mode [rad/s]: ``sqrt(lambda_a lambda_b)`` of its pole
        pair, i.e. ``|lambda|`` of a complex pair.
    damping_ratio : float
        Its damping ratio ``zeta = -(lambda_a + lambda_b) / (2 omega_n)`` [1]; above 1 for an overdamped mesh.
    antiresonance : float
        Anti-resonance of the motor-torque to motor-angle transfer [rad/s] (the load ringing on the mesh
        spring with the motor held), from the zeros of that transfer function, by the same rule.
    antiresonance_damping : float
        Damping ratio of that zero pair [1].

    Notes
    -----
    A mode is a root pair of ``s^2 + 2 zeta omega_n s + omega_n^2``: ``omega_n^2`` is the roots' product and
    ``-2 zeta omega_n`` their sum. For a complex pair these are the familiar ``omega_n = |lambda|`` and
    ``zeta = -Re(lambda) / |lambda|``; for an overdamped mesh (two real poles
    ``-omega_n (zeta -+ sqrt(zeta^2 - 1))``, ``zeta > 1``) the same two formulas give the frequency the mesh
    would ring at without damping and its damping ratio, the way a control engineer writes an overdamped
    mode. So ``damping_ratio = 1.5`` in a model file is reported as 1.5 (up to the shafts' viscous
    friction), ``natural_frequency`` stays ``sqrt(k / m_eq)``, and :attr:`overdamped` says that nothing rings.
    """

    natural_frequency: float
    damping_ratio: float
    antiresonance: float
    antiresonance_damping: float

    @property
    def natural_frequency_hz(self) -> float:
        """Resonance in Hz."""
        return self.natural_frequency / (2 * math.pi)

    @property
    def antiresonance_hz(self) -> float:
        """Anti-resonance in Hz."""
        return self.antiresonance / (2 * math.pi)

    @property
    def overdamped(self) -> bool:
        """Whether the mode's poles are real (damping ratio of at least 1): the mesh does not ring."""
        return self.damping_ratio >= 1.0


def _siso_tf(sys: ct.StateSpace, out: int, inp: int, poles: np.ndarray) -> ct.TransferFunction:
    """SISO transfer function of ``sys[out, inp]``, from its poles, zeros and high-frequency gain.

    ``poles``: those of ``sys`` (:func:`mode_poles`, the rigid body's exactly); zeros
    the invariant zeros (``control.zeros``), the gain the first nonzero Markov parameter ``C A^(r-1) B`` (``r``:
    the relative degree). ``control.ss2tf`` builds the coefficients directly, and they carry rounding far above
    the physical terms: on a four-stage train its constant term stood where the viscous friction's pole (a
    coefficient 4e-11 of the largest, weighted by the mesh frequency) should be, and cleaning such round-off by
    size dropped that pole with it (the motor-angle response 1.9x off at 0.1 rad/s, the load angle 1.7x at 3e5
    rad/s). Built from its roots, the transfer function matches an exact evaluation of the shaft chain to 5e-6
    from 1e-7 to 1e7 rad/s on every catalog and ``tests/data`` model (``tests/test_h4_mode_tf.py``).
    """
    sub = sys[out, inp]
    zeros = np.atleast_1d(ct.zeros(sub))
    r = poles.size - zeros.size
    gain = float(np.real((sub.C @ np.linalg.matrix_power(sub.A, r - 1) @ sub.B).item())) if r > 0 else \
        float(np.real(sub.D.item()))
    num = gain * np.real(np.poly(zeros)) if zeros.size else np.array([gain])
    return ct.tf(num, np.real(np.poly(poles)))


def _pair_figures(a: complex, b: complex) -> tuple[float, float]:
    """``(omega_n, zeta)`` of the mode with roots ``a``, ``b`` (a conjugate pair, or two real roots)."""
    wn = math.sqrt(abs((a * b).real))
    return wn, float(-(a + b).real / (2 * wn))


def _matchings(items: list[float]) -> Iterable[list[tuple[float, float]]]:
    """Every way of splitting ``items`` (an even number) into pairs."""
    if not items:
        yield []
        return
    first, rest = items[0], items[1:]
    for j, other in enumerate(rest):
        for tail in _matchings(rest[:j] + rest[j + 1:]):
            yield [(first, other), *tail]


def _modes_of(roots: Any, rigid: Sequence[complex], targets: Sequence[float], *,
              exact: bool = False) -> list[tuple[float, float]]:
    """The modes among ``roots`` as ``(omega_n, zeta)``, lowest first (:class:`MeshMode`'s rule per pair).

    ``rigid``: roots of the rigid-body motion, the nearest root to each set aside. ``targets``: the undamped
    natural frequencies [rad/s], one per mode. A complex pair is a mode; the real roots left are the overdamped
    modes, paired so that the pairs' products (``omega_n^2``) come nearest the targets that no complex pair
    took (every pairing is tried: at most 6 such modes, 10395 pairings). ``exact``: the roots' zeros are exact
    (:func:`mode_poles`), so none is rounded to 0 by :func:`clean_poles`: a strongly overdamped mesh's slow root
    ``-k / c`` lies below its rounding (a fuzzed pair with ``damping_coefficient = 1e8``: -2.58 rad/s beside
    -3.4e7; rounded to 0 and set aside as a rigid body, it left no mesh mode and ``linearize`` a traceback).
    """
    roots = np.atleast_1d(np.asarray(roots, dtype=complex)) if exact else clean_poles(roots)
    if roots.size == 0:
        return []
    rest = list(roots)
    tol = 1e-9 * float(np.max(np.abs(roots)))
    for e in rigid:
        # a real rigid-body root (0, -d / J) sets aside the nearest real root: with a viscous friction that moves the
        # coupled roots far from the rigid train's, the nearest could be one of a complex pair, and its lone conjugate
        # then counted as no mode (a fuzzed pair, d1 / J1 = 488 /s beside a 231 rad/s mesh: rigid -168.6, roots
        # -407.6 and -38.5 +- 143.8j: no mesh mode, a ValueError traceback)
        pool = [j for j, r in enumerate(rest) if abs(r.imag) <= tol] if abs(e.imag) <= tol else []
        pool = pool or list(range(len(rest)))
        if pool:
            rest.pop(pool[int(np.argmin([abs(rest[j] - e) for j in pool]))])
    modes = [_pair_figures(r, r.conjugate()) for r in rest if r.imag > tol]
    real = sorted(float(r.real) for r in rest if abs(r.imag) <= tol and r != 0.0)
    free = sorted(float(t) for t in targets if t > 0.0)
    for wn, _ in modes:  # the undamped frequency each complex pair stands for
        if free:
            free.pop(int(np.argmin([abs(math.log(wn / t)) for t in free])))
    m = len(real) // 2
    if m:
        free = (free + [float("nan")] * m)[:m] if len(free) < m else free[-m:]
        known = [t for t in free if math.isfinite(t)]

        def cost(pairs: list[tuple[float, float]]) -> float:
            prods = sorted(math.sqrt(a * b) for a, b in pairs)
            return sum(abs(math.log(p / t)) for p, t in zip(prods[len(prods) - len(known):], known, strict=True))

        best = min(_matchings(real[:2 * m]), key=cost)
        modes += [_pair_figures(complex(a), complex(b)) for a, b in best]
    return sorted(modes)


def _undamped_frequencies(plant: Plant, *, motor_held: bool = False) -> list[float]:
    """Natural frequencies of the undamped contact model [rad/s] (``K phi = omega^2 M phi``), rigid body left
    out; ``motor_held``: with the motor shaft clamped (the anti-resonances of motor torque to motor angle)."""
    w = len(plant.shafts)
    K = np.zeros((w, w))
    for i, st in enumerate(plant.stages):
        g = np.zeros(w)
        g[[i, i + 1]] = [st.rb1, -st.rb2]
        K += st.k * np.outer(g, g)
    M = np.diag([sh.J for sh in plant.shafts])
    if motor_held:
        K, M = K[1:, 1:], M[1:, 1:]
    lam = np.linalg.eigvals(np.linalg.solve(M, K)).real
    lam = np.sort(lam)[(0 if motor_held else 1):]  # the rigid body's zero
    return [math.sqrt(max(v, 0.0)) for v in lam]


def mesh_mode(plant: Plant) -> MeshMode:
    """Resonance and anti-resonance of the mesh mode in contact (poles and zeros of the contact model).

    Parameters
    ----------
    plant : Plant
        The plant (a train: its highest mode).

    Returns
    -------
    MeshMode
        Natural frequency [rad/s] and damping ratio of the pole pair, and the same of the zero pair of motor
        torque to motor angle (``nan`` if that transfer function has no zero pair).

    Notes
    -----
    The contact model's poles are its rigid body (``0`` and about ``-d_eq / J_eq`` of :func:`rigid_model`,
    set aside) and one root pair per stage: a complex pair, or for an overdamped mode (a large
    ``damping_ratio``; the schema allows up to 2) two real roots, paired so that their products come nearest
    the undamped natural frequencies squared. The mesh mode is the pair of the highest natural frequency.
    Either way ``natural_frequency`` and ``damping_ratio`` come from the pair's product and sum
    (:class:`MeshMode`), so an overdamped mesh reports its undamped ``sqrt(k / m_eq)`` and a damping ratio
    above 1 (``MeshMode.overdamped``), not the frequency of one of its real poles. (Before, a train took its
    highest *oscillating* pair: with damping_ratio 0.9 a four-stage train's two upper modes are overdamped,
    and its 7.4 kHz second mode was reported as the mesh mode instead of the 18 kHz one.) The zero pair
    follows the same rule (no rigid-body zeros: the motor is held).
    """
    return _mesh_and_modes(check_plant(plant))[0]


def _mesh_and_modes(plant: Plant) -> tuple[MeshMode, list[tuple[float, float]]]:
    """:func:`mesh_mode` and every contact mode's ``(omega_n, zeta)``, lowest first."""
    sys = contact_mode_model(plant)
    rigid = tuple(complex(r) for r in rigid_model(plant).poles())
    modes = _modes_of(mode_poles(plant, [True] * plant.n_stages), rigid, _undamped_frequencies(plant), exact=True)
    if not modes:  # a contact model has 2 rigid-body poles and 2 per mesh: not reached
        raise ValueError("the contact model has no mesh mode (fewer than two poles besides the rigid body)")
    wn, zeta = modes[-1]
    zmodes = _modes_of(ct.zeros(sys[0, 0]), (), _undamped_frequencies(plant, motor_held=True))
    wz, zz = zmodes[-1] if zmodes else (float("nan"), float("nan"))
    return MeshMode(natural_frequency=wn, damping_ratio=zeta, antiresonance=wz, antiresonance_damping=zz), modes


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class ContactModes:
    """The linear models a designer reaches for, from one plant.

    Attributes
    ----------
    contact, separation, rigid : control.StateSpace
        Models of :func:`contact_mode_model`, :func:`separation_model`, :func:`rigid_model`.
    motor_angle, load_angle : control.TransferFunction
        Contact-mode transfer functions from motor torque ``xi1`` to motor angle and to load angle.
    mesh : MeshMode
        Resonance and anti-resonance of the mesh mode (a train's: its highest resonance).
    plant : Plant
        The plant they come from.
    resonances_hz : tuple of float
        Natural frequencies of every oscillatory mode with all stages in contact [Hz], ``|p| / 2 pi`` of each
        complex pole pair of the damped model (as ``control.damp`` gives them; within a few 1e-4 of the undamped
        eigenfrequencies at the catalog's mesh damping), lowest first: one per stage unless a mode is overdamped
        (real poles: it does not ring, and is left out; :attr:`mesh` may be such a mode).
    stage_separated : tuple of control.StateSpace or None
        For a train, the model with stage ``i`` separated and the others in contact (empty for a pair); None
        for a stage without backlash, which cannot separate.
    """

    contact: ct.StateSpace
    separation: ct.StateSpace
    rigid: ct.StateSpace
    motor_angle: ct.TransferFunction
    load_angle: ct.TransferFunction
    mesh: MeshMode
    plant: Plant
    resonances_hz: tuple[float, ...] = ()
    stage_separated: tuple[ct.StateSpace | None, ...] = ()

    @property
    def lost_motion(self) -> float:
        """Lost motion at the load shaft, ``sum_i 2 b_i / (r_b2,i prod_(j > i) N_j)`` [rad]."""
        return self.plant.lost_motion

    @property
    def equivalent_stiffness(self) -> float:
        """Torsional stiffness of the train in contact at the load shaft [N m/rad]."""
        return self.plant.equivalent_stiffness

    def poles(self, name: str) -> np.ndarray:
        """Poles of :meth:`mode` ``(name)`` [rad/s], the rigid bodies' exactly (:func:`mode_poles`).

        Parameters
        ----------
        name : str
            As :meth:`mode` takes it.

        Raises
        ------
        InputError
            For a name :meth:`mode` refuses.
        """
        sys_ = self.mode(name)
        p, n = self.plant, self.plant.n_stages
        if name == "rigid":
            return _ordered(np.linalg.eigvals(sys_.A))  # triangular: 0 and -d_eq / J_eq exactly
        loaded = {"contact": [True] * n, "separation": [b == 0.0 for b in p.backlashes]}.get(name)
        if loaded is None:  # stageK
            k = int(name[5:])
            loaded = [j != k - 1 for j in range(n)]
        return mode_poles(p, loaded)

    def mode(self, name: str) -> ct.StateSpace:
        """The model of ``"contact"``, ``"separation"``, ``"rigid"`` or, on a train, ``"stageK"`` (stage K separated,
        the others in contact: ``stage_separated[K - 1]``), the names ``gearctl linearize --mode`` takes.

        Parameters
        ----------
        name : str
            ``"contact"``, ``"separation"``, ``"rigid"`` or ``"stageK"``.

        Raises
        ------
        InputError
            For another name, ``"stageK"`` on a pair or with K not a stage of the train, or a stage without backlash
            (it cannot separate).
        """
        from .errors import InputError

        n = self.plant.n_stages
        if isinstance(name, str) and name.startswith("stage"):
            k = int(name[5:]) if name[5:].isdigit() else 0
            if n == 1:
                raise InputError(f"mode = {name!r}: 'stageK' (stage K separated, the others in contact) needs a train; "
                                 "this plant is a pair: its modes are contact, separation and rigid", field="mode")
            if not 1 <= k <= n:
                raise InputError(f"mode = {name!r}: 'stageK' (stage K separated, the others in contact) needs "
                                 f"1 <= K <= {n} (the train's stages)", field="mode")
            sys_ = self.stage_separated[k - 1]
            if sys_ is None:
                raise InputError(f"mode = {name!r}: stage {k} has no backlash (backlash = 0), so it cannot separate: "
                                 "expected a stage with backlash > 0", field="mode")
            return sys_
        if name not in ("contact", "separation", "rigid"):
            more = f", or stage1 to stage{n} (that stage separated)" if n > 1 else ""
            raise InputError(f"mode = {name!r} is not a mode: expected contact, separation or rigid{more}",
                             field="mode")
        return getattr(self, name)


def linearize_modes(plant: Plant) -> ContactModes:
    """All linear models of a plant: contact, separation, rigid, the two transfer functions, the mesh mode.

    Parameters
    ----------
    plant : Plant
        From :func:`~gearctl.plant.build_plant` (a pair or a train).

    Returns
    -------
    ContactModes
        The models, named as in the module docstring (a train's also per stage separated).

    Raises
    ------
    InputError
        If ``plant`` is not a :class:`~gearctl.plant.Plant` (a gear model: build it first).

    Notes
    -----
    The models are the improved plant's linear law ``F = k s + c s'`` in contact, with each stage's ``k`` and
    ``c`` as the plant holds them. A ``tvms`` plant holds the mean mesh stiffness, so its models are the improved
    plant's. A ``yang-sun`` plant holds the Hertz stiffness of eq 39 and the eq 38 damping ``c``, which Yang-Sun's
    law does not use (its damping ``d x x'`` vanishes to first order at the contact onset and grows with the
    load): its models have the Hertz stiffness and a mesh damping that is not Yang-Sun's.

    Examples
    --------
    >>> from gearctl import load_model, build_plant
    >>> m = linearize_modes(build_plant(load_model("shing1993")))
    >>> round(m.mesh.natural_frequency_hz)
    8196
    """
    plant = check_plant(plant)
    contact = contact_mode_model(plant)
    poles = mode_poles(plant, [True] * plant.n_stages)
    tf_motor = _siso_tf(contact, 0, 0, poles)
    tf_load = _siso_tf(contact, 1, 0, poles)
    outs = output_names(plant)
    xi = signal_names(plant)[1][0]
    mesh, modes = _mesh_and_modes(plant)
    n = plant.n_stages
    separated = tuple(mode_model(plant, [j != i for j in range(n)], name=f"stage{i + 1}_separated")
                      if plant.backlashes[i] > 0.0 else None for i in range(n)) if n > 1 else ()
    return ContactModes(
        contact=contact, separation=separation_model(plant), rigid=rigid_model(plant),
        motor_angle=ct.tf(tf_motor.num, tf_motor.den, inputs=xi, outputs=outs[0], name="motor_angle"),
        load_angle=ct.tf(tf_load.num, tf_load.den, inputs=xi, outputs=outs[1], name="load_angle"),
        mesh=mesh, plant=plant, resonances_hz=tuple(wn / (2 * math.pi) for wn, zeta in modes if zeta < 1.0),
        stage_separated=separated,
    )


def loop_margins(loop: Any, omega: Any = None) -> dict[str, float]:
    """Gain and phase margins of an open loop, from its frequency response on a dense grid.

    Parameters
    ----------
    loop : control.LTI
        Open-loop transfer function (controller times plant, SISO), continuous or discrete.
    omega : array_like, optional
        Frequencies [rad/s], increasing, > 0 and, for a sampled loop, below its Nyquist frequency ``pi / dt``;
        default 1e-2 rad/s to the Nyquist frequency (discrete) or 1e6 rad/s.

    Returns
    -------
    dict
        ``phase_margin`` [deg] at the *last* gain crossover (where ``|L|`` falls through 1 for good), in
        (-180, 180] (negative: the phase there is below -180 deg), ``gain_crossover_hz``; ``gain_margin`` [1]
        and ``gain_margin_db``: the smallest distance of ``|L|`` from 1 at the phase crossovers (-180 deg) above
        the gain crossover (``inf`` if none),
        ``phase_crossover_hz``; ``lower_gain_margin_db``: for conditionally stable loops (type 2: phase
        below -180 deg at low frequency), by how much the gain may *drop* before the low-frequency
        crossover turns unstable (``inf`` if none).

    Raises
    ------
    InputError
        If ``loop`` is not a SISO python-control system, or ``omega`` not increasing positive frequencies (below
        the Nyquist frequency of a sampled loop).

    Notes
    -----
    python-control's ``stability_margins`` reports one crossing among several: on these conditionally stable
    type-2 loops with a mesh resonance, the lower crossing as the gain margin. gearctl reads every margin off
    ``frequency_response``. Pass the loop as a state-space product (``ct.ss(C) * G``): a transfer function times
    a many-state mode model (a train's eight) multiplies out into a badly conditioned transfer function whose
    low-frequency response is wrong (a lower gain margin of -64.7 dB for 22.3 on ``servo_3stage_quanser_srv02``).
    """
    from .errors import InputError, short_repr

    if not isinstance(loop, ct.LTI):
        raise InputError(f"loop = {loop!r} is not a python-control LTI system: expected the open loop, e.g. "
                         "ct.ss(C) * G", field="loop")
    if (loop.ninputs, loop.noutputs) != (1, 1):
        raise InputError(f"loop has {loop.ninputs} inputs and {loop.noutputs} outputs: expected a SISO open loop "
                         "(one input, one output), e.g. ct.ss(C) * G[0, 0]", field="loop")
    if omega is None:
        wmax = math.pi / loop.dt if loop.dt else 1e6
        omega = np.logspace(-2, np.log10(wmax * 0.999), 20000)
    else:
        try:
            w = np.asarray(omega, dtype=float)
        except (TypeError, ValueError):
            w = np.empty(0)
        if not (w.ndim == 1 and w.size >= 2 and np.all(np.isfinite(w)) and w[0] > 0 and np.all(np.diff(w) > 0)):
            raise InputError(f"omega = {short_repr(omega)} is not a frequency grid: expected a 1-D array of at least 2 "
                             "increasing frequencies > 0 [rad/s], e.g. np.logspace(-1, 4, 5000)", field="omega")
        if ct.isdtime(loop, strict=True) and loop.dt is not True and w[-1] >= math.pi / loop.dt:
            # beyond the Nyquist frequency a sampled loop's response repeats (aliases): margins read there are
            # not the loop's (python-control only warns, and evaluates)
            raise InputError(f"omega = {short_repr(omega)} reaches {w[-1]:.6g} rad/s: the loop is sampled (dt = "
                             f"{loop.dt:g} s), so expected every frequency below its Nyquist frequency pi / dt = "
                             f"{math.pi / loop.dt:.6g} rad/s", field="omega")
        omega = w
    resp = ct.frequency_response(loop, omega)
    mag = np.squeeze(resp.magnitude)
    ph = np.degrees(np.unwrap(np.squeeze(resp.phase)))
    above = np.nonzero((mag[:-1] >= 1.0) & (mag[1:] < 1.0))[0]
    out = {"phase_margin": float("nan"), "gain_crossover_hz": float("nan"), "gain_margin": float("inf"),
           "gain_margin_db": float("inf"), "phase_crossover_hz": float("nan"), "lower_gain_margin_db": float("inf")}
    if above.size == 0:
        return out
    i = above[-1]
    # bring the phase at the crossover to (-360, 0] deg, so that the phase margin 180 + phase lies in (-180, 180]:
    # a type-2 loop's phase starts at -180 deg, which the response may give as +180 (rounding of round((ph + 180)
    # / 360 - 0.5) left a phase in (0, 180) where it was, and K / (s^2 (s / 10 + 1)) read +354.3 deg, not -5.7)
    ph = ph - 360.0 * np.ceil(ph[i] / 360.0)
    out["phase_margin"] = float(180.0 + ph[i])
    out["gain_crossover_hz"] = float(omega[i] / (2 * math.pi))
    cross = np.nonzero(np.diff(np.sign(ph + 180.0)) != 0)[0]
    hi = [j for j in cross if j > i]
    lo = [j for j in cross if j < i]
    if hi:
        gm = min(1.0 / mag[j] for j in hi)
        out["gain_margin"] = float(gm)
        out["gain_margin_db"] = float(20 * np.log10(gm))
        out["phase_crossover_hz"] = float(omega[min(hi, key=lambda j: 1.0 / mag[j])] / (2 * math.pi))
    if lo:
        out["lower_gain_margin_db"] = float(min(20 * np.log10(mag[j]) for j in lo))
    return out
