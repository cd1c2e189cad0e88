"""Tooth deflection, mesh stiffness and mesh damping (report sections 3–4, eqs 13–21, 29–39).

The improved model's stiffness comes from bending (by ``F cos phi`` and by ``F sin phi``), shear,
foundation flexibility and Hertzian contact of each tooth (eqs 14–18), teeth in series and pairs
in parallel (eq 21), followed over one mesh cycle. Its mean is the plant's mesh stiffness ``k``;
eq 38 (in its dimensionally consistent form) gives the damping coefficient ``c``. The Yang–Sun
values (eqs 36, 37, 39) are here too, for the comparison plant.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InputError, short_repr
from .geometry import GearPair, Geometry, check_pair, involute, pair_geometry
from .units import DAMPING_RATIO, MESH_STIFFNESS, POINTS, Spec

__all__ = [
    "COMPONENTS",
    "ToothDeflections",
    "MeshStiffness",
    "tooth_deflections",
    "mesh_stiffness",
    "mesh_stiffness_at",
    "equivalent_mass",
    "damping_coefficient",
    "yang_sun_stiffness",
    "iso6336_mesh_stiffness",
    "stiffness_note",
    "restitution_coefficient",
    "restitution_note",
    "yang_sun_damping_factor",
]

#: Harmonics returned by :func:`mesh_stiffness`, and its Gauss–Legendre order per segment.
HARMONICS = Spec(unit="1", doc="Fourier harmonics", low=1, high=1000, integer=True)
QUADRATURE_ORDER = Spec(unit="1", doc="Gauss-Legendre order per segment", low=2, high=1000, integer=True)

#: Names of the deflection components of eq 13, in the order of eqs 14–18.
COMPONENTS = ("bending_cos", "bending_sin", "shear", "foundation", "hertz")


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class ToothDeflections:
    """Deflections of one tooth of each gear under a unit normal load, along the path of contact.

    Attributes
    ----------
    theta1 : ndarray, shape (n,)
        Rotation angle of gear 1 from the start of contact C (report's ``vartheta_1``) [rad].
    gear1, gear2 : dict of str to ndarray, shape (n,)
        Deflection per unit load [m/N] of each component of eq 13 (keys :data:`COMPONENTS`)
        and their sum ``"total"``.
    stiffness1, stiffness2 : ndarray, shape (n,)
        Single-tooth stiffness ``k_j = 1 / delta_tj`` (eq 20) [N/m].
    pair_stiffness : ndarray, shape (n,)
        The two teeth in series, ``k1 k2 / (k1 + k2)`` [N/m] (Figure 10).
    """

    theta1: NDArray[np.float64]
    gear1: dict[str, NDArray[np.float64]]
    gear2: dict[str, NDArray[np.float64]]
    stiffness1: NDArray[np.float64]
    stiffness2: NDArray[np.float64]
    pair_stiffness: NDArray[np.float64]


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class MeshStiffness:
    """Mesh stiffness over one mesh cycle and its summary (report Figure 11 and Table 1).

    Attributes
    ----------
    theta1 : ndarray, shape (n,)
        Rotation angle of gear 1 from C, over one mesh cycle ``[0, 2 pi / N1)`` [rad].
    K : ndarray, shape (n,)
        Mesh stiffness (eq 21) [N/m].
    teeth_in_contact : ndarray of int, shape (n,)
        Number of tooth pairs sharing the load.
    mean : float
        Mean over the mesh cycle [N/m] (Table 1 "Mean").
    harmonics : ndarray, shape (m,)
        Magnitudes of the Fourier harmonics 1..m of K over the mesh cycle [N/m] (Table 1 C1, C2).
    min, max : float
        Extremes of K over the mesh cycle [N/m], of the curve (not of the sampled ``K``: they do not change with
        ``points``).
    """

    theta1: NDArray[np.float64]
    K: NDArray[np.float64]
    teeth_in_contact: NDArray[np.int_]
    mean: float
    harmonics: NDArray[np.float64]
    min: float
    max: float

    @property
    def c1(self) -> float:
        """Magnitude of the first harmonic [N/m]."""
        return float(self.harmonics[0])

    @property
    def c2(self) -> float:
        """Magnitude of the second harmonic [N/m]."""
        return float(self.harmonics[1])


def _components(
    pair: GearPair, geo: Geometry, j: int, alpha: NDArray[np.float64]
) -> dict[str, NDArray[np.float64]]:
    """Deflection components of a tooth of gear ``j`` (0 or 1) loaded at roll angle ``alpha``.

    ``alpha = tan(phi_m)`` is the roll angle of the contact point on that gear's involute (eq 29).

    Parameters
    ----------
    pair : GearPair
        The gear data (material, face width, pressure angle of the generating rack).
    geo : Geometry
        Its geometry: per-gear reference tooth thickness, beam heights and trapezoid (eqs 19, 22–28),
        operating pressure angle.
    j : int
        0 for gear 1, 1 for gear 2.
    alpha : ndarray
        Roll angles [rad].

    Returns
    -------
    dict of str to ndarray
        Deflection per unit normal load [m/N] of each component of eq 13 and their sum ``"total"``.

    Notes
    -----
    Eq 30 starts from the reference circle ``(r_j, s_j, alpha)``: radius ``m z_j / 2``, tooth thickness
    ``s_j = m (pi/2 + 2 x_j tan(alpha))`` (``t_p = pi m / 2`` without shift) and the rack's pressure angle.
    The "``cos phi^2``" of eqs 14, 16, 17 (and ``cos phi sin phi`` of eq 15) is read with the
    *operating* pressure angle ``alpha_w``; see :func:`mesh_stiffness`.
    """
    E, nu, f = pair.young_modulus, pair.poisson_ratio, pair.face_width
    G = E / (2 * (1 + nu))
    phi = pair.pressure_angle  # pressure angle at the reference circle, where s_j is given (eq 30)
    phi_w = geo.operating_pressure_angle  # the nominal load angle of eqs 14-17 (== phi without shift sum)
    rb, rp = geo.base_radius[j], geo.pitch_radius[j]
    tb, hb, w = geo.tooth_thickness_base[j], geo.h_b[j], geo.w[j]
    s = geo.tooth_thickness_reference[j]
    phi_m = np.arctan(alpha)
    gamma_m = 0.5 * (s / rp + 2 * (involute(phi) - (np.tan(phi_m) - phi_m)))  # eq 30
    hc = (np.cos(gamma_m) / np.cos(phi_m) - 1) * rb + hb  # eq 31
    cos2 = math.cos(phi_w) ** 2  # "cos phi^2" of eqs 14, 16, 17: the nominal (operating) pressure angle, squared
    ratio = (w - hc) / (w - hb)
    bending_cos = 12 * cos2 * hb / (E * f * tb**3) * (hc**2 + hb**2 / 3 - hc * hb) + 6 * cos2 * (
        w - hb
    ) ** 3 / (E * f * tb**3) * (ratio * (4 - ratio) - 2 * np.log(ratio) - 3)  # eq 14
    bending_sin = (
        3 * math.cos(phi_w) * math.sin(phi_w) / (E * f * tb**2)
        * (hb * (hb - 2 * hc) * (w - hc) / (w - hb) - (hc - hb) ** 2)
    )  # eq 15, sign as printed
    shear = 1.2 * cos2 / (G * f * tb) * (hb + (w - hb) * np.log((w - hb) / (w - hc)))  # eq 16
    foundation = 24 * cos2 * hc**2 / (math.pi * E * f * tb**2)  # eq 17
    hertz = np.full_like(alpha, 4 * (1 - nu**2) / (math.pi * E * f))  # eq 18
    out = {
        "bending_cos": bending_cos,
        "bending_sin": bending_sin,
        "shear": shear,
        "foundation": foundation,
        "hertz": hertz,
    }
    out["total"] = sum(out.values())  # eq 13
    return out


def _roll_angles(geo: Geometry, z: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Roll angles on gears 1 and 2 of a contact point at distance ``z`` from A (eqs 32–33)."""
    return z / geo.base_radius[0], (geo.AB - z) / geo.base_radius[1]


def tooth_deflections(pair: GearPair, theta1: ArrayLike | None = None, *, points: int = 401) -> ToothDeflections:
    """Deflection components of one tooth pair along its whole path of contact (Figures 8–10).

    Parameters
    ----------
    pair : GearPair
        The gear data.
    theta1 : array_like, optional
        Rotation angles of gear 1 measured from the start of contact C [rad]; default ``points``
        values over the path of contact C → D, ``[0, CD / r_b1]``.
    points : int
        Number of default angles, 2 to 1e6 (:data:`gearctl.units.POINTS`, the CLI's ``--points``).

    Returns
    -------
    ToothDeflections
        Per-unit-load deflections [m/N] and the single-tooth and pair stiffnesses [N/m].

    Raises
    ------
    InputError
        If ``points`` is not a whole number in range (checked before any work, also when ``theta1`` is given), or
        ``theta1`` not finite numbers.

    References
    ----------
    TR 93-28, eqs 13–20 and 29–33; Figures 8–10.
    """
    points = int(POINTS.check("points", points))
    geo = pair_geometry(pair)
    if theta1 is None:
        theta1 = np.linspace(0.0, (geo.AD - geo.AC) / geo.base_radius[0], points)
    th = _angles(theta1)
    z = geo.AC + geo.base_radius[0] * th  # eq 32: alpha_11 = vartheta_1 + AC / r_b1
    a1, a2 = _roll_angles(geo, z)
    d1 = _components(pair, geo, 0, a1)
    d2 = _components(pair, geo, 1, a2)
    k1, k2 = 1 / d1["total"], 1 / d2["total"]
    return ToothDeflections(
        theta1=th, gear1=d1, gear2=d2, stiffness1=k1, stiffness2=k2, pair_stiffness=k1 * k2 / (k1 + k2)
    )


def _angles(theta1: ArrayLike) -> NDArray[np.float64]:
    """``theta1`` as a float array, or an InputError naming it if it is not finite numbers."""
    try:
        th = np.asarray(theta1, dtype=float)
    except (TypeError, ValueError):
        th = None
    if th is None or not np.all(np.isfinite(th)):
        raise InputError(f"theta1 = {short_repr(theta1)} is not finite: expected angles of gear 1 from C [rad], "
                         "finite numbers", field="theta1")
    return th


def _pair_compliance(pair: GearPair, geo: Geometry, z: NDArray[np.float64]) -> NDArray[np.float64]:
    a1, a2 = _roll_angles(geo, z)
    return _components(pair, geo, 0, a1)["total"] + _components(pair, geo, 1, a2)["total"]


def mesh_stiffness_at(pair: GearPair, theta1: ArrayLike, geo: Geometry | None = None) -> NDArray[np.float64]:
    """Mesh stiffness ``K`` at rotation angles ``theta1`` of gear 1 from C (eq 21), periodic.

    Parameters
    ----------
    pair : GearPair
        The gear data.
    theta1 : array_like
        Rotation angle of gear 1 measured from the start of contact C [rad]; any real value
        (K is periodic with the mesh period ``2 pi / N1``).
    geo : Geometry, optional
        Precomputed geometry of ``pair``.

    Returns
    -------
    ndarray
        Mesh stiffness [N/m], same shape as ``theta1``.

    Raises
    ------
    InputError
        If ``theta1`` holds a value that is not a finite number (before, NaN gave ``K = 0`` and inf ``0`` with a
        numpy warning: no contact, without a word).

    Notes
    -----
    Every tooth pair whose contact point ``z + i p_b`` lies on the path of contact C → D carries
    load, so the same code covers contact ratios above 2 (three pairs at once) as well as the
    report's double/single-tooth zones. Teeth in series, pairs in parallel (eq 21).
    """
    if geo is not None and not isinstance(geo, Geometry):
        raise InputError(f"geo = {short_repr(geo)} is not a Geometry: expected pair_geometry(pair) or None",
                         field="geo")
    geo = pair_geometry(pair) if geo is None else geo
    th = _angles(theta1)
    period = geo.mesh_period_angle
    phase = np.mod(th, period)
    # a whole number of cycles comes back as (period - rounding), not 0: the start of the cycle, where K jumps
    phase = np.where(phase >= period * (1.0 - 1e-12), 0.0, phase)
    z0 = geo.AC + geo.base_radius[0] * phase
    K = np.zeros_like(z0)
    n_max = int(math.ceil(geo.contact_ratio)) + 1
    for i in range(n_max):
        z = z0 + i * geo.base_pitch
        on = z <= geo.AD * (1 + 1e-14)
        if not np.any(on):
            break
        K = K + np.where(on, 1.0 / _pair_compliance(pair, geo, np.where(on, z, geo.AC)), 0.0)
    return K


def mesh_stiffness(pair: GearPair, *, points: int = 1001, harmonics: int = 4, order: int = 64) -> MeshStiffness:
    """Mesh stiffness over one mesh cycle, its mean and harmonics (Figure 11, Table 1).

    The result depends on the tooth geometry and the material only, not on the backlash or the inertias:
    the last 64 results of up to :data:`CACHED_POINTS` points are kept per process (keyed on those inputs,
    arrays read-only), so that a sweep over backlash, friction or inertias does not integrate the same
    stiffness again for every run.

    Parameters
    ----------
    pair : GearPair
        The gear data.
    points : int
        Number of sample angles returned over the mesh cycle (for plots and CSV), 2 to 1e6
        (:data:`gearctl.units.POINTS`, the CLI's ``--points``).
    harmonics : int
        Number of Fourier harmonics whose magnitudes are returned, 1 to 1000.
    order : int
        Gauss–Legendre order per smooth segment of the cycle for the mean and the harmonics, 2 to 1000.

    Returns
    -------
    MeshStiffness
        ``K(theta1)`` over ``[0, 2 pi / N1)``, the mean, harmonic magnitudes, min and max [N/m].

    Raises
    ------
    InputError
        If ``pair`` is not a GearPair, or ``points``, ``harmonics`` or ``order`` is not a whole number in its
        range (checked before any work).

    Notes
    -----
    The report leaves some readings open; gearctl takes these, which reproduce Table 1's mean and
    C2 within about 0.1 % (see ``tests/test_stiffness.py``):

    - ``cos phi^2`` in eqs 14, 16, 17 is the square of the cosine of the *nominal* pressure angle
      (20 deg), not of the local load angle ``phi_m``; likewise ``cos phi sin phi`` in eq 15.
      With profile shift the nominal angle is the *operating* pressure angle ``alpha_w`` (below).
    - The Hertz term of eq 18 belongs to each gear's compliance, so a tooth pair counts it twice
      (once per flank), as eq 18 is written "for gear j".
    - ``t_p = pi m / 2``, ``delta_bn`` (eq 15) with the sign as printed (it is negative over most of
      the path), and the mesh cycle runs from C to F (section 3.1: a pair "starts their meshing at
      point C and ends at point F").
    - The harmonic magnitude ``C_n`` is ``|c_n|`` of ``K = mean + sum_n |c_n| cos(n 2 pi theta / Theta + psi_n)``
      with ``Theta = 2 pi / N1``.

    With these readings the report's pair gives mean 1.3854e8 N/m (Table 1: 1.3868e8, -0.10 %) and
    C2 1.683e7 N/m (1.684e7, -0.07 %). Table 1's C1 (2.956e7 N/m) does not follow from the report's
    own equations under any reading tried: these give 3.475e7 N/m, +17.6 %. gearctl reports what its
    equations give and does not tune toward that number.

    Profile shift (``x1``, ``x2``) enters through the geometry (:func:`~gearctl.geometry.pair_geometry`):
    the per-gear reference tooth thickness ``s_j`` in eqs 27, 28 and 30, the beam heights ``h_a``, ``h_b``
    of eqs 22–25 from the shifted tip and root radii, and the roll angles of eqs 32–33 on the operating
    line of action ``AB = (r_b1 + r_b2) tan(alpha_w)``. Where the rack's pressure angle ``alpha`` and the
    operating one ``alpha_w`` part (``x1 + x2 != 0``), the report's "``phi``" needs a reading: in eqs 27, 28
    and 30 it is the pressure angle at the circle where ``t_p`` is given (gearctl gives ``s_j`` on the
    reference circle, so ``alpha``); in eqs 14–17 it stands for the direction of the load, the line of
    action, which the report also writes with ``phi`` (``AB = (r_b1 + r_b2) tan phi``) and which is
    inclined at ``alpha_w`` (the local load angle ``phi_m`` at the operating pitch point). gearctl
    therefore uses ``cos^2(alpha_w)`` and ``cos(alpha_w) sin(alpha_w)`` there. Both readings coincide
    without a shift sum, so standard and "V-zero" (``x1 = -x2``) pairs keep the report's numbers exactly.
    Where they part, the choice matters little: against the ``alpha`` reading, ``x1 + x2 = 0.3`` on
    17 + 40 teeth lowers ``cos^2`` by 2 % and raises the mean stiffness by 2 %; KHK's pair (12 + 24 teeth,
    ``x = 0.6 + 0.36``, ``alpha_w = 26.09 deg``) 9 % and 9 %.

    The mean and the harmonics are integrated exactly enough (Gauss–Legendre of ``order`` points on
    each segment between the jumps in the number of teeth in contact), independent of ``points``.

    References
    ----------
    TR 93-28, eqs 13–35, Figures 8–11, Table 1. ISO 21771:2007 (profile shift, operating pressure angle).
    """
    check_pair(pair)
    points = int(POINTS.check("points", points))
    harmonics = int(HARMONICS.check("harmonics", harmonics))
    order = int(QUADRATURE_ORDER.check("order", order))
    if points > CACHED_POINTS:  # a long curve for a plot or a CSV: computed, not kept
        return _mesh_stiffness.__wrapped__(pair, points, harmonics, order)
    key = pair if (pair.backlash == 0.0 and pair.inertia1 is None and pair.inertia2 is None) else \
        dataclasses.replace(pair, backlash=0.0, inertia1=None, inertia2=None)
    return _mesh_stiffness(key, points, harmonics, order)


#: Results of :func:`mesh_stiffness` up to this many points are kept (the last 64: at most 64 x 3 x 10 001
#: doubles, 15 MB); longer curves are computed each time.
CACHED_POINTS = 10_001


@functools.lru_cache(maxsize=64)
def _mesh_stiffness(pair: GearPair, points: int, harmonics: int, order: int) -> MeshStiffness:
    geo = pair_geometry(pair)
    period = geo.mesh_period_angle
    rb1 = geo.base_radius[0]
    # jumps: a pair leaves contact at D, i.e. z0 = AD - i p_b, inside [AC, AF)
    breaks = [0.0, period]
    for i in range(1, int(math.ceil(geo.contact_ratio)) + 1):
        t = (geo.AD - i * geo.base_pitch - geo.AC) / rb1
        if 0.0 < t < period:
            breaks.append(t)
    breaks = sorted(breaks)
    x, wq = np.polynomial.legendre.leggauss(order)
    nodes, weights = [], []
    for a, b in zip(breaks[:-1], breaks[1:], strict=True):
        nodes.append(0.5 * (b - a) * x + 0.5 * (a + b))
        weights.append(0.5 * (b - a) * wq)
    tq, wts = np.concatenate(nodes), np.concatenate(weights)
    Kq = mesh_stiffness_at(pair, tq, geo)
    # the curve's extremes, not the --points samples' (liou1992_28x28_hcr's min read 9.059e7 or 9.06e7 with the
    # sample count): each segment's ends (just inside it, K jumps there) and its inner extremes, refined from the
    # quadrature node nearest to them
    ends = [t for a, b in zip(breaks[:-1], breaks[1:], strict=True) for t in (a + 1e-12 * (b - a), b - 1e-12 * (b - a))]
    ext = [_segment_extreme(pair, geo, a, b, sign) for a, b in zip(breaks[:-1], breaks[1:], strict=True)
           for sign in (1.0, -1.0)]
    Ke = np.concatenate([mesh_stiffness_at(pair, np.array(ends), geo), ext])
    mean = float(np.sum(wts * Kq) / period)
    n = np.arange(1, harmonics + 1)[:, None]
    cn = 2.0 / period * np.sum(wts * Kq * np.exp(-2j * np.pi * n * tq / period), axis=1)
    th = np.linspace(0.0, period, points, endpoint=False)
    K = mesh_stiffness_at(pair, th, geo)
    z0 = geo.AC + rb1 * th
    count = sum(((z0 + i * geo.base_pitch <= geo.AD).astype(np.int_)
                 for i in range(int(math.ceil(geo.contact_ratio)) + 1)), start=np.zeros(th.shape, dtype=np.int_))
    cn = np.abs(cn)
    for arr in (th, K, count, cn):  # shared by every caller of the cache
        arr.flags.writeable = False
    return MeshStiffness(
        theta1=th,
        K=K,
        teeth_in_contact=count,
        mean=mean,
        harmonics=cn,
        min=float(min(Kq.min(), Ke.min())),
        max=float(max(Kq.max(), Ke.max())),
    )


def _segment_extreme(pair: GearPair, geo: Geometry, a: float, b: float, sign: float) -> float:
    """The least (``sign`` 1) or largest (-1) ``K`` inside ``[a, b]``, a segment where it is smooth."""
    from scipy.optimize import minimize_scalar

    t = np.linspace(a, b, 65)[1:-1]
    k = sign * mesh_stiffness_at(pair, t, geo)
    j = int(np.argmin(k))
    lo, hi = t[max(j - 1, 0)], t[min(j + 1, t.size - 1)]
    if hi <= lo:
        return float(sign * k[j])
    res = minimize_scalar(lambda x: sign * float(mesh_stiffness_at(pair, np.array([x]), geo)[0]), bounds=(lo, hi),
                          method="bounded", options={"xatol": 1e-12 * (b - a)})
    return float(sign * min(res.fun, k[j]))


def equivalent_mass(inertia1: float, inertia2: float, rb1: float, rb2: float) -> float:
    """Mass of the mesh mode along the line of action: ``I1 I2 / (I2 r_b1^2 + I1 r_b2^2)`` [kg].

    Parameters
    ----------
    inertia1, inertia2 : float
        Inertias ``I1``, ``I2`` of the pinion's and the gear's shafts [kg m^2].
    rb1, rb2 : float
        Base radii of the pinion and the gear [m].

    Raises
    ------
    InputError
        If an inertia or a base radius is not a positive finite number (named).

    Examples
    --------
    >>> round(equivalent_mass(1.0, 1.0, 1.0, 1.0), 3)
    0.5
    """
    inertia1, inertia2 = _POSITIVE_INERTIA.check("inertia1", inertia1), _POSITIVE_INERTIA.check("inertia2", inertia2)
    rb1, rb2 = _POSITIVE_RADIUS.check("rb1", rb1), _POSITIVE_RADIUS.check("rb2", rb2)
    return inertia1 * inertia2 / (inertia2 * rb1**2 + inertia1 * rb2**2)


def damping_coefficient(k: float, damping_ratio: float, m_eq: float) -> float:
    """Mesh damping coefficient ``c = 2 zeta sqrt(k m_eq)`` [N s/m] (eq 38, consistent form).

    Parameters
    ----------
    k : float
        Mesh stiffness [N/m].
    damping_ratio : float
        Damping ratio zeta of the mesh mode [1].
    m_eq : float
        Equivalent mass along the line of action (:func:`equivalent_mass`) [kg].

    Raises
    ------
    InputError
        If ``k`` is not in (0, 1e13] N/m, ``damping_ratio`` not in 0..2 or ``m_eq`` not a positive finite mass.

    Notes
    -----
    Eq 38 as printed, ``c = 2 zeta sqrt(k (I2 r_b1^2 + I1 r_b2^2) / (I2 I1))``, has the unit
    ``sqrt(N/m * m^2 kg m^2 / (kg m^2)^2) = sqrt(N / (m kg)) = 1/s``, not N s/m: the fraction under
    the root is the *inverse* of the equivalent mass. The mesh mode ``m_eq s'' + c s' + k s = 0`` of eqs 1–5
    gives ``c = 2 zeta sqrt(k m_eq)`` with ``m_eq = I1 I2 / (I2 r_b1^2 + I1 r_b2^2)``, which is the
    dimensionally consistent reading gearctl uses: about 269 N s/m for the report's pair.

    The report's 237.6651 N s/m is what the same consistent form gives when the inertias are taken as
    solid disks of the *base* radius instead of the pitch radius: ``I ~ r^4`` makes ``m_eq`` scale
    with ``cos^4 phi`` and ``c`` with ``cos^2 phi``, and ``269.15 * cos^2(20 deg) = 237.67``. gearctl
    keeps the pitch-radius disks, which reproduce the report's own ``I1`` and ``I2``, and lets a model
    file give ``damping_coefficient = 237.6651`` to run the report's simulations exactly
    (``shing1993_report``).

    References
    ----------
    TR 93-28, eq 38 and section 5.

    Examples
    --------
    >>> round(damping_coefficient(1.0e8, 0.05, 0.05), 1)
    223.6
    """
    k = MESH_STIFFNESS.check("k", k)
    damping_ratio = DAMPING_RATIO.check("damping_ratio", damping_ratio)
    m_eq = _MASS.check("m_eq", m_eq)
    return 2.0 * damping_ratio * math.sqrt(k * m_eq)


#: An equivalent mass along the line of action (:func:`damping_coefficient`'s ``m_eq``), and what
#: :func:`equivalent_mass` takes (positive and finite; no upper bound: a gear's own disk may exceed a shaft's range).
_MASS = Spec(unit="kg", doc="equivalent mass", low=0.0, low_open=True)
_POSITIVE_INERTIA = Spec(unit="kg m^2", doc="inertia", low=0.0, low_open=True)
_POSITIVE_RADIUS = Spec(unit="m", doc="base radius", low=0.0, low_open=True)


#: Below this share of ISO 6336-1's mesh stiffness, the report's beam (eqs 24-25) is taken as too long (see
#: :func:`stiffness_note`). The report's own 20 x 80 pair gives 0.68 of it, pairs of small gears 0.8 to 1.2.
ISO_STIFFNESS_SHARE = 0.5


def iso6336_mesh_stiffness(pair: GearPair) -> float:
    """ISO 6336-1 (method B) mean mesh stiffness ``c_gamma_alpha x face width`` of a spur pair [N/m].

    ``c'_th = 1 / q'`` with ISO 6336-1's polynomial ``q'`` in the teeth and the profile shifts, times the
    correction factor ``C_M = 0.8``, the blank factor ``C_R = 1`` (solid gears), ``C_B`` for the rack's dedendum
    and pressure angle and ``E / 206 GPa`` (the formula is for steel on steel); ``c_gamma_alpha = c' (0.75
    eps_alpha + 0.25)``. (ISO fits ``q'`` for ``x1 >= x2`` and ``-0.5 <= x1 + x2 <= 2``; outside that it is
    extrapolated.) A cross-check of the
    report's model, which is not used for the plant (:func:`stiffness_note`).

    Parameters
    ----------
    pair : GearPair
        The gear pair.

    Returns
    -------
    float
        The mean mesh stiffness [N/m].

    Raises
    ------
    InputError
        If ``pair`` is not a :class:`~gearctl.geometry.GearPair`.

    Examples
    --------
    >>> from gearctl import load_model
    >>> f"{iso6336_mesh_stiffness(load_model('shing1993').pair) / 0.01 * 1e-9:.3g}"  # N/(mm um); the model: 13.9
    '20.4'
    """
    geo = pair_geometry(check_pair(pair))
    z1, z2, x1, x2 = pair.teeth1, pair.teeth2, pair.x1, pair.x2
    q = (0.04723 + 0.15551 / z1 + 0.25791 / z2 - 0.00635 * x1 - 0.11654 * x1 / z1 - 0.00193 * x2
         - 0.24188 * x2 / z2 + 0.00529 * x1**2 + 0.00182 * x2**2)  # mm um / N
    c_b = ((1.0 + 0.5 * (1.2 - pair.dedendum_coefficient))
           * (1.0 - 0.02 * (20.0 - math.degrees(pair.pressure_angle))))
    c_single = 0.8 * c_b / q * pair.young_modulus / 2.06e11  # c' [N/(mm um)]
    return c_single * (0.75 * geo.contact_ratio + 0.25) * 1e9 * pair.face_width


def stiffness_note(pair: GearPair, mean: float) -> str | None:
    """A warning where the report's tooth model makes the mesh far softer than real gears, else None.

    Eqs 24-25 start a tooth's beam at the base circle wherever the dedendum circle lies outside it, so the beam
    of a large gear is longer than its tooth (3 tooth heights at 190 teeth) and the computed mesh stiffness per
    face width falls with the teeth (``mean`` [N/m], :func:`mesh_stiffness`): 13.9 N/(mm um) for 20 x 80 teeth,
    7.0 for 20 x 190, 4.9 for 20 x 300, where ISO 6336-1 gives 20-22. The note is given where such a beam
    leaves the mean under half of :func:`iso6336_mesh_stiffness`.

    Parameters
    ----------
    pair : GearPair
        The gear pair.
    mean : float
        The pair's mean mesh stiffness by the report's model [N/m].

    Returns
    -------
    str or None
        One sentence, or None.

    Raises
    ------
    InputError
        If ``pair`` is not a :class:`~gearctl.geometry.GearPair`.
    """
    geo = pair_geometry(check_pair(pair))
    iso = iso6336_mesh_stiffness(pair)
    # each gear whose beam starts below its root: the beam's length in tooth heights
    beams = {j: geo.h_a[j] / (geo.addendum_radius[j] - geo.dedendum_radius[j])
             for j in range(2) if geo.dedendum_radius[j] > geo.base_radius[j]}
    if not beams or mean >= ISO_STIFFNESS_SHARE * iso:
        return None
    j = max(beams, key=beams.__getitem__)
    teeth, beam = (pair.teeth1, pair.teeth2)[j], beams[j]
    per_width = 1e-9 / pair.face_width
    return (f"the mesh stiffness {mean:.4g} N/m ({mean * per_width:.3g} N/(mm um)) is {mean / iso:.2f} of ISO "
            f"6336-1's {iso:.4g} N/m ({iso * per_width:.3g} N/(mm um)): the report's tooth model starts gear "
            f"{j + 1}'s beam ({teeth} teeth) at the base circle, {beam:.2g} times its tooth height (eqs 24-25), "
            f"so it is too soft for gears this large; give a measured [dynamics] mesh_stiffness (ISO's value if "
            f"none)")


def yang_sun_stiffness(pair: GearPair) -> float:
    """Yang & Sun's Hertz-only mesh stiffness ``pi E f / (4 (1 - nu^2))`` [N/m] (eq 39).

    Parameters
    ----------
    pair : GearPair
        The gear data; only its ``young_modulus``, ``poisson_ratio`` and ``face_width`` enter.

    Raises
    ------
    InputError
        If ``pair`` is not a :class:`~gearctl.geometry.GearPair` (a gear model: ``model.pair``).

    Examples
    --------
    >>> from gearctl.geometry import GearPair
    >>> p = GearPair(teeth1=20, teeth2=80, module=0.002, pressure_angle=math.radians(20), face_width=0.01,
    ...              backlash=5e-5, young_modulus=2.068e11, poisson_ratio=0.3, density=7800.0)
    >>> f"{yang_sun_stiffness(p):.4e}"
    '1.7848e+09'
    """
    pair = check_pair(pair)
    return math.pi * pair.young_modulus * pair.face_width / (4.0 * (1.0 - pair.poisson_ratio**2))


def restitution_coefficient(impact_velocity: float) -> float:
    """Coefficient of restitution ``e = 1 - 0.022 V_i^0.36`` (eq 37) for an impact speed in m/s.

    Parameters
    ----------
    impact_velocity : float
        Relative speed along the line of action at impact [m/s]; its magnitude is used.

    Notes
    -----
    The report (after Yang & Sun 1985 and Goldsmith's 1960 ball-impact data) gives no unit for
    ``V_i``. gearctl reads it in **inches per second**, i.e. ``e = 1 - 0.022 (V / 0.0254 m/s)^0.36``
    ``= 1 - 0.0825 V^0.36`` with ``V`` in m/s, because:

    - Hunt & Crossley (1975), fitting the same Goldsmith data, give ``e ~ 1 - alpha V`` with
      ``alpha = 0.08 ... 0.32 s/m`` for steel, bronze and ivory: ``e ~ 0.92`` at 1 m/s for steel. The
      in/s reading gives 0.917 there; m/s would give 0.978 (a quarter of the loss) and cm/s 0.885.
    - Goldsmith's book and Yang & Sun's journal (ASME, 1985) used US customary units; the example
      pair's ``E = 2.068e11 Pa`` is exactly 30e6 psi.

    This is an assumption, not something the report states. The value is clipped to ``[0.05, 1]``
    so that absurd impact speeds cannot make it negative.

    Examples
    --------
    >>> round(restitution_coefficient(1.0), 3)
    0.917
    """
    v = abs(impact_velocity) / 0.0254  # eq 37 in in/s (see Notes)
    return min(1.0, max(0.05, 1.0 - 0.022 * v**0.36))


#: Young's modulus [Pa] of the steels whose impacts eq 37's restitution fits (Goldsmith's data, see
#: :func:`restitution_coefficient`): a Yang-Sun plant of another material extrapolates it (:func:`restitution_note`).
STEEL_YOUNG_MODULUS = (1.8e11, 2.3e11)


def restitution_note(pair: GearPair) -> str | None:
    """A note where eq 37's restitution, a fit for steel, is applied to a pair of another material.

    Parameters
    ----------
    pair : GearPair
        The gear pair (its ``young_modulus`` [Pa] tells the material).

    Returns
    -------
    str or None
        ``None`` for a steel's modulus (:data:`STEEL_YOUNG_MODULUS`), else one line for the Yang-Sun plant's users:
        its impact damping (eqs 36-37) is extrapolated to this material, where the improved and tvms plants damp the
        mesh by the model's damping ratio.

    Notes
    -----
    Yang & Sun's restitution ``e = 1 - 0.022 V^0.36`` is a fit of Goldsmith's impact data for steel
    (:func:`restitution_coefficient`); Hunt & Crossley's fit of the same data gives bronze up to 4 times steel's loss,
    and polymers (POM, PA) lose far more per impact. No other material's law is in the report, so the plant is
    kept and the user told.

    Examples
    --------
    >>> p = GearPair(teeth1=20, teeth2=80, module=0.002, pressure_angle=math.radians(20), face_width=0.01,
    ...              backlash=5e-5, young_modulus=2.8e9, poisson_ratio=0.35, density=1410.0)
    >>> restitution_note(p)[:37]
    'young_modulus = 2.8e+09 Pa is outside'
    """
    lo, hi = STEEL_YOUNG_MODULUS
    E = pair.young_modulus
    if lo <= E <= hi:
        return None
    return (f"young_modulus = {E:.4g} Pa is outside steel's {lo:.3g} .. {hi:.3g} Pa: the yang-sun plant's restitution "
            "e = 1 - 0.022 V^0.36 (eq 37) is a fit of impacts on steel, so its impact damping is extrapolated to "
            "this material (the improved and tvms plants damp the mesh by the model's damping_ratio)")


def yang_sun_damping_factor(k: float, impact_velocity: float) -> float:
    """Yang & Sun's damping factor ``d = 6 (1 - e) / ((2e - 1)^2 + 3) * k / V_i`` [N s/m^2] (eq 36).

    Parameters
    ----------
    k : float
        Mesh stiffness [N/m].
    impact_velocity : float
        Relative velocity along the line of action at contact onset [m/s]; its magnitude is used.

    Returns
    -------
    float
        ``d`` in the contact law ``F = (d x' + k) x`` [N s/m^2]. With eq 37, ``d ~ V_i^-0.64`` diverges
        as ``V_i -> 0``, so impact speeds below 1 mm/s (grazing contact) are given the factor of a
        1 mm/s impact.

    Raises
    ------
    InputError
        If ``k`` is not in (0, 1e13] N/m or ``impact_velocity`` not a finite number.

    Examples
    --------
    >>> f"{yang_sun_damping_factor(1.0e9, 1.0):.3e}"
    '1.340e+08'
    """
    if not (0.0 < k <= 1e13):  # the per-impact path: comparisons first, the named message only on failure
        k = MESH_STIFFNESS.check("k", k)
    if not abs(impact_velocity) < math.inf:
        raise InputError(f"impact_velocity = {short_repr(impact_velocity)} is not a finite number: expected the "
                         "relative velocity along the line of action at contact onset [m/s]", field="impact_velocity")
    v = max(abs(impact_velocity), 1e-3)
    e = restitution_coefficient(v)
    return 6.0 * (1.0 - e) / ((2.0 * e - 1.0) ** 2 + 3.0) * k / v
