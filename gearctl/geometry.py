"""Involute geometry of a spur-gear pair (report section 3.1, eqs 22–28), with profile shift.

A :class:`GearPair` holds the data a designer types (teeth, module, pressure angle, profile shifts,
face width, material, backlash); :func:`pair_geometry` turns it into the radii, the operating centre
distance and pressure angle, the line-of-action points A, B, C, D, E, F, P, the contact ratio, the
tooth thicknesses and the gear inertias.

All lengths are in metres, angles in radians. Profile shift follows ISO 21771 (DIN 3960): the shift
``x m`` moves the generating rack's datum line away from the gear centre.
"""

from __future__ import annotations

import contextvars
import dataclasses
import math
from collections.abc import Callable
from typing import Any

from .errors import InputError, short_repr
from .units import BACKLASH, FACE_WIDTH, MODULE, quantity, validate_fields

__all__ = [
    "GearPair",
    "Geometry",
    "pair_geometry",
    "check_pair",
    "involute",
    "inverse_involute",
    "operating_pressure_angle",
    "undercut_limit",
    "minimum_profile_shift",
]


def involute(phi: float) -> float:
    """Involute function ``inv(phi) = tan(phi) - phi``.

    Parameters
    ----------
    phi : float
        Pressure angle [rad].

    Returns
    -------
    float
        ``inv(phi)`` [rad].

    Examples
    --------
    >>> round(involute(math.radians(20.0)), 6)
    0.014904
    """
    return math.tan(phi) - phi


def inverse_involute(value: float) -> float:
    """Angle ``phi`` in ``(0, pi/2)`` with ``inv(phi) = value`` [rad], by Newton's method.

    Parameters
    ----------
    value : float
        Value of the involute function, > 0.

    Returns
    -------
    float
        The angle [rad], to a few units in the last place.

    Raises
    ------
    ValueError
        If ``value`` is not a positive finite number (no such angle).

    Notes
    -----
    ``inv`` is increasing and convex on ``(0, pi/2)``, so Newton's method started to the right of the
    root converges monotonically without overshooting. Both ``(3 value)^(1/3)`` (since
    ``inv(phi) >= phi^3 / 3``) and ``atan(value + pi/2)`` (since ``tan(phi) = value + phi < value + pi/2``)
    lie right of the root; the smaller of the two starts the iteration.

    Examples
    --------
    >>> round(math.degrees(inverse_involute(0.014904384)), 6)
    20.0
    """
    if not (value > 0.0 and math.isfinite(value)):
        raise ValueError(f"inverse_involute({value!r}): expected a positive finite value")
    phi = min((3.0 * value) ** (1.0 / 3.0), math.atan(value + math.pi / 2))
    for _ in range(100):
        step = (involute(phi) - value) / math.tan(phi) ** 2
        phi -= step
        if abs(step) <= 1e-15 * phi:
            break
    return phi


def operating_pressure_angle(
    pressure_angle: float, teeth1: int, teeth2: int, x1: float = 0.0, x2: float = 0.0
) -> float:
    """Operating pressure angle ``alpha_w`` of an external pair meshing without backlash [rad].

    ``inv(alpha_w) = inv(alpha) + 2 (x1 + x2) tan(alpha) / (z1 + z2)`` (ISO 21771, DIN 3960).

    Parameters
    ----------
    pressure_angle : float
        Pressure angle ``alpha`` of the generating rack [rad].
    teeth1, teeth2 : int
        Numbers of teeth ``z1``, ``z2``.
    x1, x2 : float
        Profile-shift coefficients [1].

    Returns
    -------
    float
        ``alpha_w`` [rad]; exactly ``pressure_angle`` when ``x1 + x2 == 0`` (standard and "V-zero" pairs).

    Raises
    ------
    ValueError
        If the right-hand side is not positive (a negative shift sum too large for the teeth: no angle).

    Examples
    --------
    >>> round(math.degrees(operating_pressure_angle(math.radians(20.0), 12, 24, 0.6, 0.36)), 4)
    26.0886
    """
    shift = x1 + x2
    if shift == 0.0:  # exact, so that unshifted and V-zero pairs keep every result bit for bit
        return pressure_angle
    return inverse_involute(involute(pressure_angle) + 2.0 * shift * math.tan(pressure_angle) / (teeth1 + teeth2))


def undercut_limit(pressure_angle: float, addendum_coefficient: float = 1.0, profile_shift: float = 0.0) -> float:
    """Fewest teeth a rack-generated gear has without undercut: ``2 (h_a* - x) / sin^2(alpha)``.

    Parameters
    ----------
    pressure_angle : float
        Pressure angle ``alpha`` of the generating rack [rad].
    addendum_coefficient : float
        Addendum of the generating rack (taken equal to the gears' addendum) / module, ``h_a*`` [1].
    profile_shift : float
        Profile-shift coefficient ``x`` of the gear [1].

    Examples
    --------
    >>> round(undercut_limit(math.radians(20.0)), 2)
    17.1
    >>> round(undercut_limit(math.radians(20.0), 1.0, 0.3), 2)
    11.97
    """
    return 2.0 * (addendum_coefficient - profile_shift) / math.sin(pressure_angle) ** 2


def minimum_profile_shift(teeth: int, pressure_angle: float, addendum_coefficient: float = 1.0) -> float:
    """Smallest profile-shift coefficient that keeps a gear of ``teeth`` teeth free of undercut [1].

    ``x_min = h_a* - z sin^2(alpha) / 2``, the inverse of :func:`undercut_limit`.

    Parameters
    ----------
    teeth : int
        Number of teeth ``z``.
    pressure_angle : float
        Pressure angle ``alpha`` [rad].
    addendum_coefficient : float
        Addendum coefficient ``h_a*`` [1] (default 1).

    Returns
    -------
    float
        ``x_min`` [1] (negative: the gear could take a negative shift without undercut).

    Examples
    --------
    >>> round(minimum_profile_shift(12, math.radians(20.0)), 4)
    0.2981
    """
    return addendum_coefficient - teeth * math.sin(pressure_angle) ** 2 / 2.0


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class GearPair:
    """A spur-gear pair, possibly profile-shifted, at its zero-backlash operating centre distance.

    Gear 1 is the driving pinion, gear 2 the driven gear (report Figure 1). With ``x1 = x2 = 0`` this
    is the report's standard pair at standard centre distance. Each field's unit and allowed range are declared
    once, in its metadata (:func:`gearctl.units.quantity`), which validation and error messages read.

    Parameters
    ----------
    teeth1, teeth2 : int
        Numbers of teeth of gear 1 (pinion) and gear 2 [1].
    module : float
        Module, pitch diameter / teeth [m].
    pressure_angle : float
        Pressure angle of the generating rack [rad].
    face_width : float
        Face width [m].
    backlash : float
        Backlash ``b`` along the line of action [m].
    addendum_coefficient : float
        Addendum / module [1] (default 1).
    dedendum_coefficient : float
        Dedendum / module [1] (default 1.25); must exceed ``addendum_coefficient``.
    x1, x2 : float
        Profile-shift coefficients of gear 1 and gear 2, ISO 21771 [1] (default 0).
    young_modulus : float
        Young's modulus ``E`` [Pa].
    poisson_ratio : float
        Poisson's ratio [1].
    density : float
        Density [kg/m^3].
    inertia1, inertia2 : float or None
        Inertias of gear 1 and gear 2 [kg m^2] (default ``None``: a solid disk of pitch radius).

    Raises
    ------
    InputError
        If a field is out of its range, if a gear has fewer teeth than the undercut limit for its
        profile shift (the tooth model of eqs 14–19 does not cover undercut teeth), if the profile
        shifts admit no operating pressure angle, if a tip reaches the mating gear below its generated
        involute (interference), if a tooth tip is pointed, or if the contact ratio is below 1.
    """

    teeth1: int = quantity(unit="1", doc="number of teeth of gear 1 (pinion)", low=3, high=1000, integer=True)
    teeth2: int = quantity(unit="1", doc="number of teeth of gear 2", low=3, high=1000, integer=True)
    module: float = MODULE.field()
    pressure_angle: float = quantity(
        unit="rad", doc="pressure angle", low=math.radians(10.0), high=math.radians(35.0)
    )
    face_width: float = FACE_WIDTH.field()
    backlash: float = BACKLASH.field()
    addendum_coefficient: float = quantity(
        unit="1", doc="addendum / module", low=0.5, high=1.6, default=1.0
    )
    dedendum_coefficient: float = quantity(
        unit="1", doc="dedendum / module", low=0.6, high=2.0, default=1.25
    )
    x1: float = quantity(
        unit="1", doc="profile-shift coefficient of gear 1 (ISO 21771)", low=-1.0, high=1.5, default=0.0
    )
    x2: float = quantity(
        unit="1", doc="profile-shift coefficient of gear 2 (ISO 21771)", low=-1.0, high=1.5, default=0.0
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
        _check_undercut(self)
        if self.dedendum_coefficient <= self.addendum_coefficient:
            rule = f"must exceed addendum_coefficient = {self.addendum_coefficient:g} (tip clearance)"
            raise InputError(
                f"dedendum_coefficient = {self.dedendum_coefficient:g} {rule}", field="dedendum_coefficient", rule=rule
            )
        g = _raw_geometry(self)
        _check_interference(self, g)
        _check_tips(self, g)
        _check_contact_ratio(self, g)


# --- validation (one check per function, each raising a one-line InputError that names the field) ----


def _shift_field(pair: GearPair, j: int | None = None) -> str:
    """Field to name for a shift-dependent rule: gear ``j``'s shift (or the larger one), else the addendum."""
    if j is not None and getattr(pair, f"x{j}") != 0.0:
        return f"x{j}"
    if pair.x1 == 0.0 and pair.x2 == 0.0:
        return "addendum_coefficient"
    return "x1" if abs(pair.x1) >= abs(pair.x2) else "x2"


def _input_error(pair: GearPair, field: str, rule: str) -> InputError:
    """The one-line error ``"<field> = <value> <rule>"`` (the shape the catalog loader restates); for a profile
    shift, with the range that passes when the other keys stay as given (:func:`_shift_limit`)."""
    if field in ("x1", "x2") and not _SEARCHING.get():
        limit = _shift_limit(pair, field)
        if limit is not None:
            side = "at most" if getattr(pair, field) > limit else "at least"
            rule += f" (with the other keys as given: {side} {limit:g})"
    return InputError(f"{field} = {getattr(pair, field):g} {rule}", field=field, rule=rule)


#: True while :func:`_shift_limit` builds its trial pairs (their errors need no range of their own); a context
#: variable, so that threads validating pairs at once do not see each other's search.
_SEARCHING: contextvars.ContextVar[bool] = contextvars.ContextVar("gearctl_shift_search", default=False)


def _shift_limit(pair: GearPair, field: str) -> float | None:
    """The profile shift nearest to the given one at which the pair passes every check with the other keys as given,
    rounded away from the given one to 1e-4: bisection on the whole validation from 0 or, below the undercut limit,
    that limit's shift (None when neither passes)."""
    x = getattr(pair, field)

    def passes(v: float) -> bool:
        token = _SEARCHING.set(True)  # the trial pairs' own errors do not search again
        try:
            changes: dict[str, Any] = {field: v}  # a field named at run time
            dataclasses.replace(pair, **changes)
        except InputError:
            return False
        finally:
            _SEARCHING.reset(token)
        return True

    j = field[1]
    x_min = math.ceil(minimum_profile_shift(getattr(pair, f"teeth{j}"), pair.pressure_angle,
                                            pair.addendum_coefficient) * 1e4) / 1e4  # the undercut limit's shift
    start = next((v for v in (0.0, x_min) if (v - x) * (0.0 - x) >= 0.0 and v != x and passes(v)), None)
    if start is None:
        return None
    lo, hi = start, x  # passes at lo, fails at hi
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if passes(mid):
            lo = mid
        else:
            hi = mid
    return (math.floor(lo * 1e4) if x > lo else math.ceil(lo * 1e4)) / 1e4


def _check_undercut(pair: GearPair) -> None:
    """Each gear at or above the undercut limit for its own profile shift."""
    phi, ha = pair.pressure_angle, pair.addendum_coefficient
    for j, (name, n, x) in enumerate((("teeth1", pair.teeth1, pair.x1), ("teeth2", pair.teeth2, pair.x2)), start=1):
        limit = undercut_limit(phi, ha, x)
        if n < limit:
            tool = f", addendum {ha:g} and profile shift x{j} = {x:g}" if x != 0.0 else f" and addendum {ha:g}"
            x_min = math.ceil(minimum_profile_shift(n, phi, ha) * 1e4) / 1e4  # rounded up: the value shown passes
            rule = (
                f"is below the undercut limit for a pressure angle of {math.degrees(phi):g} deg{tool}: expected "
                f"a whole number >= {math.ceil(limit - 1e-9)} or a profile shift x{j} >= {x_min:g} (the tooth "
                f"model does not cover undercut teeth)"
            )
            raise InputError(f"{name} = {n} {rule}", field=name, rule=rule)


def _check_interference(pair: GearPair, g: dict[str, Any]) -> None:
    """Each tip meets the mating flank on its generated involute (see :func:`pair_geometry`, Notes)."""
    # reach of gear j's tip along the line of action, from gear 1's tangent point A or gear 2's tangent point B,
    # against the start of the mating gear's generated involute (its base-circle tangent point if below it)
    reaches = ((g["AD"], g["l"] - g["g2"]["form"]), (g["l"] - g["AC"], g["l"] - g["g1"]["form"]))
    for j, (reach, room) in enumerate(reaches, start=1):
        if reach > room * (1 + 1e-12):
            rule = (
                f"makes the addendum of gear {j} reach below the mating gear's involute (interference: contact "
                f"length {reach * 1e3:.6g} mm > {room * 1e3:.6g} mm available on the line of action); expected a "
                f"shorter addendum, another profile shift or more teeth on the other gear"
            )
            field = _shift_field(pair, j)
            other = "x2" if field == "x1" else "x1"
            if field in ("x1", "x2") and getattr(pair, other) != 0.0 and not _SEARCHING.get():
                # both shifts move the tips and the involutes' starts: the other key may be the one that changed (a
                # reviewer raised x1 to 1.2 and was told of x2 = -0.1 alone)
                limit = _shift_limit(pair, other)
                if limit is not None:
                    side = "at most" if getattr(pair, other) > limit else "at least"
                    rule += f"; or {other} = {getattr(pair, other):g} {side} {limit:g} with the other keys as given"
            raise _input_error(pair, field, rule)


def _check_tips(pair: GearPair, g: dict[str, Any]) -> None:
    """No pointed tooth tip (eq 28 must give a positive thickness)."""
    for j in (1, 2):
        sa = g[f"g{j}"]["sa"]
        if sa <= 0.0:
            if getattr(pair, f"x{j}") == 0.0:  # an unshifted gear: its few teeth (at this pressure angle) did it
                rule = (
                    f"makes the tip of gear {j} pointed at a pressure angle of {math.degrees(pair.pressure_angle):g} "
                    f"deg and addendum {pair.addendum_coefficient:g} (tooth thickness at the tip {sa * 1e3:.4g} mm "
                    f"<= 0): expected a tip thickness > 0 (ISO 21771 / DIN 3960 recommend >= 0.2 module); use more "
                    f"teeth, a smaller pressure angle or a shorter addendum"
                )
                raise _input_error(pair, f"teeth{j}", rule)
            rule = (
                f"makes the tip of gear {j} pointed (tooth thickness at the tip {sa * 1e3:.4g} mm <= 0): expected "
                f"a tip thickness > 0 (ISO 21771 / DIN 3960 recommend >= 0.2 module); use a smaller profile shift "
                f"or a shorter addendum"
            )
            raise _input_error(pair, _shift_field(pair, j), rule)


def _check_contact_ratio(pair: GearPair, g: dict[str, Any]) -> None:
    """Contact ratio at least 1 (some tooth pair always in contact)."""
    eps = (g["AD"] - g["AC"]) / g["pb"]
    if eps < 1.0:
        shifts = "" if pair.x1 == 0.0 and pair.x2 == 0.0 else f" (profile shifts x1 = {pair.x1:g}, x2 = {pair.x2:g})"
        rule = (
            f"gives a contact ratio of {eps:.4g}{shifts}, below 1: expected a contact ratio >= 1 (the pair would "
            f"lose contact once per mesh); use more teeth, a longer addendum or a smaller profile shift sum"
        )
        raise _input_error(pair, _shift_field(pair), rule)


# --- geometry ----------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class Geometry:
    """Involute geometry of a :class:`GearPair` (report section 3.1 and Figure 4).

    Points on the line of action are given as distances from A (the tangent point on gear 1's
    base circle): ``AB = l``, ``AC``, ``AD``, ``AE``, ``AF``, ``AP``. Per-gear quantities are
    tuples ``(gear 1, gear 2)``. ``pitch_radius`` is the reference radius ``m z / 2``; the pair
    rolls on ``operating_pitch_radius`` at ``centre_distance`` with pressure angle
    ``operating_pressure_angle`` (all equal to the reference ones when ``x1 + x2 = 0``).

    Attributes
    ----------
    pitch_radius : tuple of float
        Reference radii ``r_j = m z_j / 2`` [m].
    operating_pitch_radius : tuple of float
        Operating pitch radii ``r_w = r cos(alpha) / cos(alpha_w)`` [m].
    base_radius : tuple of float
        Base radii ``r_b = r cos(alpha)`` [m].
    addendum_radius : tuple of float
        Tip radii ``r_j + (h_a* + x_j + k*) m``, with ISO 21771's tip alteration ``k*`` [m].
    dedendum_radius : tuple of float
        Root radii ``r_j - (h_f* - x_j) m`` [m].
    profile_shift : tuple of float
        Profile-shift coefficients ``(x1, x2)`` [1].
    operating_pressure_angle : float
        Operating pressure angle ``alpha_w`` [rad].
    reference_centre_distance : float
        ``a = m (z1 + z2) / 2`` [m].
    centre_distance : float
        Operating centre distance ``a_w = a cos(alpha) / cos(alpha_w)`` [m].
    base_pitch : float
        Base pitch ``p_b = pi m cos(alpha)`` [m].
    AB : float
        Length ``l`` of the line of action between the base-circle tangent points A and B [m].
    AC, AD : float
        Start of contact C (gear 2's tip circle) and end of contact D (gear 1's tip circle), from A [m].
    AE, AF : float
        ``AE = AD - p_b`` and ``AF = AC + p_b``: the ends of the single-contact stretch, from A [m].
    AP : float
        Pitch point P, ``r_b1 tan(alpha_w)``, from A [m].
    contact_ratio : float
        ``(AD - AC) / p_b`` [1].
    tooth_thickness_pitch : float
        Unshifted tooth thickness at the reference circle, ``pi m / 2`` [m].
    tooth_thickness_reference : tuple of float
        Reference-circle thicknesses ``s_j = m (pi/2 + 2 x_j tan(alpha))`` [m], where eqs 27, 28 and 30 start.
    tooth_thickness_base : tuple of float
        Tooth thicknesses at the base circle (eq 27) [m].
    tooth_thickness_addendum : tuple of float
        Tooth thicknesses at the tip circle (eq 28) [m].
    h_a, h_b : tuple of float
        Heights of the tooth beam (eqs 22–25) [m].
    w : tuple of float
        Height of the trapezoid of the tooth model (eq 19) [m].
    inertia : tuple of float
        Gear inertias: the pair's ``inertia1``, ``inertia2``, else solid disks of pitch radius [kg m^2].
    gear_ratio : float
        ``N2 / N1`` [1].
    """

    pitch_radius: tuple[float, float]
    operating_pitch_radius: tuple[float, float]
    base_radius: tuple[float, float]
    addendum_radius: tuple[float, float]
    dedendum_radius: tuple[float, float]
    profile_shift: tuple[float, float]
    operating_pressure_angle: float
    reference_centre_distance: float
    centre_distance: float
    base_pitch: float
    AB: float
    AC: float
    AD: float
    AE: float
    AF: float
    AP: float
    contact_ratio: float
    tooth_thickness_pitch: float
    tooth_thickness_reference: tuple[float, float]
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


def _operating_pressure_angle(pair: GearPair) -> float:
    """``alpha_w`` of the pair, or an InputError naming a shift if the shifts admit none."""
    try:
        return operating_pressure_angle(pair.pressure_angle, pair.teeth1, pair.teeth2, pair.x1, pair.x2)
    except ValueError:
        rule = (
            f"gives, with x1 + x2 = {pair.x1 + pair.x2:g} on {pair.teeth1} + {pair.teeth2} teeth, no operating "
            f"pressure angle (inv(alpha_w) = inv(alpha) + 2 (x1 + x2) tan(alpha) / (z1 + z2) <= 0): expected a "
            f"larger profile shift sum"
        )
        raise _input_error(pair, _shift_field(pair), rule) from None


def _tooth_thickness(rb: float, r: float, s: float, phi: float, radius: float) -> float:
    """Tooth thickness at ``radius`` of a tooth ``s`` thick at reference radius ``r`` (eq 26, ISO 21771)."""
    return radius * (s / r + 2 * (involute(phi) - involute(math.acos(rb / radius))))


def _gear_geometry(pair: GearPair, j: int, k: float) -> dict[str, float]:
    """Radii, thicknesses and involute start of gear ``j`` (1 or 2), with the tip alteration ``k*`` [1]."""
    m, phi, ha, hf = pair.module, pair.pressure_angle, pair.addendum_coefficient, pair.dedendum_coefficient
    z, x = (pair.teeth1, pair.x1) if j == 1 else (pair.teeth2, pair.x2)
    r = m * z / 2
    rb = r * math.cos(phi)
    ra = r + (ha + x + k) * m
    tp = math.pi * m / 2
    s = tp + 2 * x * m * math.tan(phi)  # reference-circle thickness (ISO 21771); tp without shift
    if ra <= rb:  # the tip alteration of a large shift sum on few teeth: no involute flank is left (acos(rb / ra))
        rule = (f"with the tip alteration k* = {k:.4g} of the shift sum x1 + x2 = {pair.x1 + pair.x2:g} puts the tip "
                f"circle of gear {j} ({ra * 1e3:.6g} mm) inside its base circle ({rb * 1e3:.6g} mm): no involute "
                f"flank; expected a smaller shift sum or more teeth")
        raise _input_error(pair, _shift_field(pair), rule)
    return {
        "r": r, "rb": rb, "ra": ra, "rd": r - (hf - x) * m, "tp": tp, "s": s,
        "sa": _tooth_thickness(rb, r, s, phi, ra),  # eq 28
        # start of the generated involute, as a tangent length from the base circle: where the generating
        # rack's tip line (h_a* - x below the datum line) leaves the line of action; >= 0 above the undercut limit
        "form": max(0.0, r * math.sin(phi) - (ha - x) * m / math.sin(phi)),
    }


def _raw_geometry(pair: GearPair) -> dict[str, Any]:
    """Centre distances and line-of-action distances, without validation (used by the validation).

    ``g1`` and ``g2`` hold the per-gear quantities of :func:`_gear_geometry`.
    """
    m, phi = pair.module, pair.pressure_angle
    alpha_w = _operating_pressure_angle(pair)
    stretch = math.cos(phi) / math.cos(alpha_w)  # exactly 1.0 without a shift sum
    a = m * (pair.teeth1 + pair.teeth2) / 2
    a_w = a * stretch
    k = min(0.0, (a_w - a) / m - (pair.x1 + pair.x2))  # tip alteration k* (ISO 21771): keeps the tip clearance
    g1, g2 = _gear_geometry(pair, 1, k), _gear_geometry(pair, 2, k)
    ab = (g1["rb"] + g2["rb"]) * math.tan(alpha_w)  # AB = l
    return {
        "g1": g1, "g2": g2, "alpha_w": alpha_w, "a": a, "a_w": a_w, "stretch": stretch,
        "l": ab,
        "AC": ab - math.sqrt(g2["ra"] ** 2 - g2["rb"] ** 2),
        "AD": math.sqrt(g1["ra"] ** 2 - g1["rb"] ** 2),
        "pb": math.pi * m * math.cos(phi),
    }


def _beam_heights(ra: float, rb: float, rd: float) -> tuple[float, float]:
    """Heights ``(h_a, h_b)`` of the tooth beam (eqs 22–25)."""
    if rd > rb:  # eqs 24-25: dedendum circle outside the base circle
        return ra - rb, 0.0
    return ra - rd, rb - rd  # eqs 22-23


def check_pair(pair: Any, *, field: str = "pair") -> GearPair:
    """``pair`` itself if it is a :class:`GearPair`; else an :class:`~gearctl.errors.InputError` naming ``field``.

    A gear model (from :func:`~gearctl.catalog.load_model`) is the usual slip: the message points to its
    ``model.pair``, or for a train to ``model.stages[i].pair``.

    Parameters
    ----------
    pair : object
        What a caller passed as the gear pair.
    field : str
        The name the message gives it (default ``"pair"``).

    Returns
    -------
    GearPair
        ``pair`` itself.

    Raises
    ------
    InputError
        If ``pair`` is not a :class:`GearPair`.
    """
    if isinstance(pair, GearPair):
        return pair
    stages = getattr(pair, "stages", None)
    if stages is not None and hasattr(pair, "servo"):
        hint = (f": a train of {len(stages)} stages, pass one stage's gear pair, model.stages[i].pair"
                if len(stages) > 1 else ": pass its gear pair, model.pair")
        raise InputError(f"{field} = {short_repr(pair)} is not a GearPair{hint}", field=field)
    raise InputError(f"{field} = {short_repr(pair)} is not a GearPair: expected a gear model's pair, "
                     "gearctl.load_model(name).pair", field=field)


def pair_geometry(pair: GearPair) -> Geometry:
    """Compute the involute geometry of a gear pair.

    Parameters
    ----------
    pair : GearPair
        The gear data.

    Returns
    -------
    Geometry
        Radii [m], operating pressure angle [rad] and centre distances [m], line-of-action points [m],
        contact ratio, tooth thicknesses [m] (eqs 26–28), beam heights ``h_a``, ``h_b`` (eqs 22–25) and
        the trapezoid height ``w`` (eq 19) [m], inertias [kg m^2] and the gear ratio ``N2/N1``.

    Notes
    -----
    The tooth thickness at the pitch circle is ``t_p = pi m / 2`` (no backlash thinning: the backlash
    ``b`` enters the dynamics only as the clearance of eqs 4 and 11). Where the dedendum circle lies
    outside the base circle the beam starts at the base circle (eqs 24–25).

    Profile shift (ISO 21771 / DIN 3960). A shift ``x_j`` moves gear j's generating rack out by ``x_j m``:
    the reference tooth thickness becomes ``s_j = m (pi/2 + 2 x_j tan(alpha))``, the dedendum radius
    ``r_j - (h_f* - x_j) m``, and the pair meshes without backlash at the operating pressure angle
    ``inv(alpha_w) = inv(alpha) + 2 (x1 + x2) tan(alpha) / (z1 + z2)`` and centre distance
    ``a_w = a cos(alpha) / cos(alpha_w)``. The report's Figure 4 relations then hold with ``alpha_w`` as
    the inclination of the line of action: ``AB = (r_b1 + r_b2) tan(alpha_w)``, ``AP = r_b1 tan(alpha_w)``.
    Eq 26 may start from any circle of the tooth; gearctl starts eqs 27–28 (and eq 30) from the
    reference circle ``(r_j, s_j, alpha)``, where the shift enters only through ``s_j``.
    ``tooth_thickness_pitch`` keeps its unshifted meaning ``pi m / 2``.

    Tip shortening: the tip radius is ``r_j + (h_a* + x_j + k*) m`` with ISO 21771's tip alteration
    ``k* m = a_w - a - (x1 + x2) m`` (never positive). gearctl applies it, as KHK's and DIN 3960's
    worked examples do, because (i) the pair keeps the tip clearance ``(h_f* - h_a*) m`` that
    ``dedendum_coefficient`` is validated for; without it a pair with ``x1 + x2 > 0`` loses part of
    that clearance (0.13 m of 0.25 m for z = 12 + 24, x = 0.6 + 0.36); (ii) the contact ratio and the
    beam heights then describe gears as they are usually cut. ``k* = 0`` when ``x1 + x2 = 0``.

    Checks (each a one-line InputError naming the field): undercut with each gear's own shift
    (``z >= 2 (h_a* - x) / sin^2 alpha``); interference, i.e. a tip reaching the mating gear below the
    start of its rack-generated involute (the rack's tip line is taken ``h_a* - x`` below the datum line,
    as the undercut limit does; without shift this is never stricter than the base-circle rule of the
    report's Figure 4, since a mating gear's tip reaches at most as deep as the generating rack's);
    pointed tips, ``s_a <= 0``; contact ratio below 1. The tip rule is the model's limit, not ISO's
    strength recommendation ``s_a >= 0.2 m`` (0.4 m case-hardened): unshifted pairs the report's model
    has always accepted go below 0.2 m (12 teeth at 27 deg, ``h_a* = 1.2``: 0.015 m), and eqs 19 and 28
    stay defined down to a pointed tip. Check ``tooth_thickness_addendum`` against ISO's rule when
    designing gears.

    Limitation: eqs 24–25 start the tooth beam at the base circle whenever the dedendum circle lies
    outside it (above ``2 (h_f* - x) / (1 - cos phi)`` teeth: 42 at 20 deg, 27 at 25 deg without shift).
    The report's own 80-tooth gear uses this branch and Table 1 is reproduced with it, but for much larger
    gears the beam grows longer than the real tooth and the mesh stiffness per face width falls below
    ISO 6336-1's band (about 9 N/(mm um) for 100 x 100 teeth at 20 deg, 6 for 150 x 150). gearctl keeps the
    report's model; for gears beyond about 100 teeth give a measured ``[dynamics] mesh_stiffness``.

    Unless the pair gives them, the inertias are those of solid steel disks of the pitch radius and
    the face width, ``I = rho pi f r_p^4 / 2``; this is how the report's ``I1 = 1.9604e-5`` and
    ``I2 = 0.0050 kg m^2`` follow from its data (section 3.2).

    References
    ----------
    Shing, Tsai & Krishnaprasad, TR 93-28, section 3.1, eqs 19, 22–28 and Figure 4.
    ISO 21771:2007, Gears — Cylindrical involute gears and gear pairs — Concepts and geometry.
    """
    check_pair(pair)
    phi, f = pair.pressure_angle, pair.face_width
    g = _raw_geometry(pair)
    gears = (g["g1"], g["g2"])

    def both(key: str) -> tuple[float, float]:
        return (gears[0][key], gears[1][key])

    def per_gear(value: Callable[[int], float]) -> tuple[float, float]:
        return (value(0), value(1))

    rp, rb, ra, rd, s = both("r"), both("rb"), both("ra"), both("rd"), both("s")
    pb, ab, AC, AD = g["pb"], g["l"], g["AC"], g["AD"]
    tb = per_gear(lambda j: rb[j] * (s[j] / rp[j] + 2 * involute(phi)))  # eq 27
    ta = both("sa")  # eq 28
    heights = [_beam_heights(ra[j], rb[j], rd[j]) for j in range(2)]
    h_a, h_b = (heights[0][0], heights[1][0]), (heights[0][1], heights[1][1])
    w = per_gear(lambda j: (h_a[j] * tb[j] - h_b[j] * ta[j]) / (tb[j] - ta[j]))  # eq 19
    disk = tuple(pair.density * math.pi * f * r**4 / 2 for r in rp)
    inertia = (
        pair.inertia1 if pair.inertia1 is not None else disk[0],
        pair.inertia2 if pair.inertia2 is not None else disk[1],
    )
    return Geometry(
        pitch_radius=rp,
        operating_pitch_radius=(rp[0] * g["stretch"], rp[1] * g["stretch"]),
        base_radius=rb,
        addendum_radius=ra,
        dedendum_radius=rd,
        profile_shift=(pair.x1, pair.x2),
        operating_pressure_angle=g["alpha_w"],
        reference_centre_distance=g["a"],
        centre_distance=g["a_w"],
        base_pitch=pb,
        AB=ab,
        AC=AC,
        AD=AD,
        AE=AD - pb,
        AF=AC + pb,
        AP=rb[0] * math.tan(g["alpha_w"]),
        contact_ratio=(AD - AC) / pb,
        tooth_thickness_pitch=gears[0]["tp"],
        tooth_thickness_reference=s,
        tooth_thickness_base=tb,
        tooth_thickness_addendum=ta,
        h_a=h_a,
        h_b=h_b,
        w=w,
        inertia=inertia,
        gear_ratio=pair.teeth2 / pair.teeth1,
    )
