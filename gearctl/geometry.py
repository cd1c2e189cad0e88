"""Involute geometry of a spur-gear pair (report section 3.1, eqs 22–28).

A :class:`GearPair` holds the data a designer types (teeth, module, pressure angle, face width,
material, backlash); :func:`pair_geometry` turns it into the radii, the line-of-action points
A, B, C, D, E, F, P, the contact ratio, the tooth thicknesses and the gear inertias.

All lengths are in metres, angles in radians.
"""

from __future__ import annotations

import dataclasses
import math

from .errors import InputError
from .units import quantity, validate_fields

__all__ = ["GearPair", "Geometry", "pair_geometry", "involute", "undercut_limit"]


def involute(phi: float) -> float:
    """Involute function ``inv(phi) = tan(phi) - phi``.

    Examples
    --------
    >>> round(involute(math.radians(20.0)), 6)
    0.014904
    """
    return math.tan(phi) - phi


def undercut_limit(pressure_angle: float, addendum_coefficient: float = 1.0) -> float:
    """Fewest teeth a rack-generated gear has without undercut: ``2 h_a* / sin^2(phi)``.

    Examples
    --------
    >>> round(undercut_limit(math.radians(20.0)), 2)
    17.1
    """
    return 2.0 * addendum_coefficient / math.sin(pressure_angle) ** 2


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class GearPair:
    """A standard spur-gear pair at standard centre distance, with backlash.

    Gear 1 is the driving pinion, gear 2 the driven gear (report Figure 1).

    Raises
    ------
    InputError
        If a field is out of its range, if a gear has fewer teeth than the undercut limit
        (the tooth model of eqs 14–19 does not cover undercut teeth), if an addendum reaches past
        the mating gear's base circle (interference), or if the contact ratio is below 1.
    """

    teeth1: int = quantity(unit="1", doc="number of teeth of gear 1 (pinion)", low=3, high=1000, integer=True)
    teeth2: int = quantity(unit="1", doc="number of teeth of gear 2", low=3, high=1000, integer=True)
    module: float = quantity(unit="m", doc="module (pitch diameter / teeth)", low=0.0, high=0.1, low_open=True)
    pressure_angle: float = quantity(
        unit="rad", doc="pressure angle", low=math.radians(10.0), high=math.radians(35.0)
    )
    face_width: float = quantity(unit="m", doc="face width", low=0.0, high=1.0, low_open=True)
    backlash: float = quantity(unit="m", doc="backlash b along the line of action", low=0.0, high=0.01)
    addendum_coefficient: float = quantity(
        unit="1", doc="addendum / module", low=0.5, high=1.6, default=1.0
    )
    dedendum_coefficient: float = quantity(
        unit="1", doc="dedendum / module", low=0.6, high=2.0, default=1.25
    )
    young_modulus: float = quantity(unit="Pa", doc="Young's modulus E", low=1e9, high=1e12)
    poisson_ratio: float = quantity(
        unit="1", doc="Poisson's ratio", low=0.0, high=0.5, low_open=True, high_open=True
    )
    density: float = quantity(unit="kg/m^3", doc="density", low=100.0, high=30000.0)
    inertia1: float | None = quantity(
        unit="kg m^2", doc="inertia of gear 1 (default: solid disk of pitch radius)",
        low=0.0, low_open=True, optional=True, default=None,
    )
    inertia2: float | None = quantity(
        unit="kg m^2", doc="inertia of gear 2 (default: solid disk of pitch radius)",
        low=0.0, low_open=True, optional=True, default=None,
    )

    def __post_init__(self) -> None:
        validate_fields(self)
        phi = self.pressure_angle
        limit = undercut_limit(phi, self.addendum_coefficient)
        for name in ("teeth1", "teeth2"):
            n = getattr(self, name)
            if n < limit:
                rule = (
                    f"is below the undercut limit for a pressure angle of {math.degrees(phi):g} deg and "
                    f"addendum {self.addendum_coefficient:g}: expected a whole number >= "
                    f"{math.ceil(limit - 1e-9)} (the tooth model does not cover undercut teeth)"
                )
                raise InputError(f"{name} = {n} {rule}", field=name, rule=rule)
        if self.dedendum_coefficient <= self.addendum_coefficient:
            rule = f"must exceed addendum_coefficient = {self.addendum_coefficient:g} (tip clearance)"
            raise InputError(
                f"dedendum_coefficient = {self.dedendum_coefficient:g} {rule}", field="dedendum_coefficient", rule=rule
            )
        g = _raw_geometry(self)
        for j, reach in enumerate((g["AD"], g["l"] - g["AC"]), start=1):
            if reach > g["l"] * (1 + 1e-12):
                rule = (
                    f"makes the addendum of gear {j} reach past the mating gear's base circle (interference: "
                    f"contact length {reach * 1e3:.4g} mm > line of action {g['l'] * 1e3:.4g} mm); expected a "
                    f"shorter addendum or more teeth on the other gear"
                )
                raise InputError(
                    f"addendum_coefficient = {self.addendum_coefficient:g} {rule}",
                    field="addendum_coefficient", rule=rule,
                )
        eps = (g["AD"] - g["AC"]) / g["pb"]
        if eps < 1.0:
            rule = (
                f"gives a contact ratio of {eps:.4g}, below 1: expected a contact ratio >= 1 (the pair would "
                f"lose contact once per mesh); use more teeth or a longer addendum"
            )
            raise InputError(
                f"addendum_coefficient = {self.addendum_coefficient:g} {rule}", field="addendum_coefficient", rule=rule
            )


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class Geometry:
    """Involute geometry of a :class:`GearPair` (report section 3.1 and Figure 4).

    Points on the line of action are given as distances from A (the tangent point on gear 1's
    base circle): ``AB = l``, ``AC``, ``AD``, ``AE``, ``AF``, ``AP``. Per-gear quantities are
    tuples ``(gear 1, gear 2)``.
    """

    pitch_radius: tuple[float, float]
    base_radius: tuple[float, float]
    addendum_radius: tuple[float, float]
    dedendum_radius: tuple[float, float]
    base_pitch: float
    AB: float
    AC: float
    AD: float
    AE: float
    AF: float
    AP: float
    contact_ratio: float
    tooth_thickness_pitch: float
    tooth_thickness_base: tuple[float, float]
    tooth_thickness_addendum: tuple[float, float]
    h_a: tuple[float, float]
    h_b: tuple[float, float]
    w: tuple[float, float]
    inertia: tuple[float, float]
    gear_ratio: float

    @property
    def mesh_period_angle(self) -> float:
        """Rotation of gear 1 over one mesh cycle, ``p_b / r_b1 = 2 pi / N1`` [rad]."""
        return self.base_pitch / self.base_radius[0]


def _raw_geometry(pair: GearPair) -> dict[str, float]:
    """Line-of-action distances without validation (used by the validation itself)."""
    m, phi = pair.module, pair.pressure_angle
    rp1, rp2 = m * pair.teeth1 / 2, m * pair.teeth2 / 2
    rb1, rb2 = rp1 * math.cos(phi), rp2 * math.cos(phi)
    ra1, ra2 = rp1 + pair.addendum_coefficient * m, rp2 + pair.addendum_coefficient * m
    ab = (rb1 + rb2) * math.tan(phi)  # AB = l
    return {
        "l": ab,
        "AC": ab - math.sqrt(ra2**2 - rb2**2),
        "AD": math.sqrt(ra1**2 - rb1**2),
        "pb": math.pi * m * math.cos(phi),
    }


def pair_geometry(pair: GearPair) -> Geometry:
    """Compute the involute geometry of a gear pair.

    Parameters
    ----------
    pair : GearPair
        The gear data.

    Returns
    -------
    Geometry
        Radii [m], line-of-action points [m], contact ratio, tooth thicknesses [m] (eqs 26–28),
        beam heights ``h_a``, ``h_b`` (eqs 22–25) and the trapezoid height ``w`` (eq 19) [m],
        inertias [kg m^2] and the gear ratio ``N2/N1``.

    Notes
    -----
    The tooth thickness at the pitch circle is ``t_p = pi m / 2`` (no backlash thinning: the backlash
    ``b`` enters the dynamics only as the clearance of eqs 4 and 11). Where the dedendum circle lies
    outside the base circle the beam starts at the base circle (eqs 24–25).

    Limitation: eqs 24–25 start the tooth beam at the base circle whenever the dedendum circle lies
    outside it (above ``2 h_f* / (1 - cos phi)`` teeth: 42 at 20 deg, 27 at 25 deg). The report's own
    80-tooth gear uses this branch and Table 1 is reproduced with it, but for much larger gears the beam
    grows longer than the real tooth and the mesh stiffness per face width falls below ISO 6336-1's
    band (about 9 N/(mm um) for 100 x 100 teeth at 20 deg, 6 for 150 x 150). gearctl keeps the report's
    model; for gears beyond about 100 teeth give a measured ``[dynamics] mesh_stiffness``.

    Unless the pair gives them, the inertias are those of solid steel disks of the pitch radius and
    the face width, ``I = rho pi f r_p^4 / 2``; this is how the report's ``I1 = 1.9604e-5`` and
    ``I2 = 0.0050 kg m^2`` follow from its data (section 3.2).

    References
    ----------
    Shing, Tsai & Krishnaprasad, TR 93-28, section 3.1, eqs 19, 22–28 and Figure 4.
    """
    m, phi, f = pair.module, pair.pressure_angle, pair.face_width
    raw = _raw_geometry(pair)
    teeth = (pair.teeth1, pair.teeth2)
    rp = tuple(m * n / 2 for n in teeth)
    rb = tuple(r * math.cos(phi) for r in rp)
    ra = tuple(r + pair.addendum_coefficient * m for r in rp)
    rd = tuple(r - pair.dedendum_coefficient * m for r in rp)
    pb, ab, AC, AD = raw["pb"], raw["l"], raw["AC"], raw["AD"]
    tp = math.pi * m / 2
    tb = tuple(rb[j] * (tp / rp[j] + 2 * involute(phi)) for j in range(2))  # eq 27
    beta = tuple(math.acos(rb[j] / ra[j]) for j in range(2))
    ta = tuple(ra[j] * (tp / rp[j] + 2 * (involute(phi) - involute(beta[j]))) for j in range(2))  # eq 28
    h_b, h_a = [], []
    for j in range(2):
        if rd[j] > rb[j]:  # eqs 24-25: dedendum circle outside the base circle
            h_b.append(0.0)
            h_a.append(ra[j] - rb[j])
        else:  # eqs 22-23
            h_b.append(rb[j] - rd[j])
            h_a.append(ra[j] - rd[j])
    w = tuple((h_a[j] * tb[j] - h_b[j] * ta[j]) / (tb[j] - ta[j]) for j in range(2))  # eq 19
    disk = tuple(pair.density * math.pi * f * r**4 / 2 for r in rp)
    inertia = (
        pair.inertia1 if pair.inertia1 is not None else disk[0],
        pair.inertia2 if pair.inertia2 is not None else disk[1],
    )
    return Geometry(
        pitch_radius=rp,
        base_radius=rb,
        addendum_radius=ra,
        dedendum_radius=rd,
        base_pitch=pb,
        AB=ab,
        AC=AC,
        AD=AD,
        AE=AD - pb,
        AF=AC + pb,
        AP=rb[0] * math.tan(phi),
        contact_ratio=(AD - AC) / pb,
        tooth_thickness_pitch=tp,
        tooth_thickness_base=tb,
        tooth_thickness_addendum=ta,
        h_a=(h_a[0], h_a[1]),
        h_b=(h_b[0], h_b[1]),
        w=w,
        inertia=inertia,
        gear_ratio=pair.teeth2 / pair.teeth1,
    )
