"""The figures of a gear model in one JSON-ready dictionary (``gearctl info``)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from .geometry import pair_geometry
from .plant import build_plant
from .stiffness import damping_coefficient, equivalent_mass, mesh_stiffness, yang_sun_stiffness

if TYPE_CHECKING:
    from .catalog import GearModel

__all__ = ["model_summary"]


def model_summary(model: GearModel) -> dict[str, Any]:
    """Geometry, stiffness, damping and plant figures of a gear model, SI units.

    Parameters
    ----------
    model : GearModel
        The catalog entry.

    Returns
    -------
    dict
        JSON-ready: ``contact_ratio``, ``base_pitch`` [m], ``pitch_radius``, ``base_radius``,
        ``addendum_radius``, ``dedendum_radius`` [m, m], ``line_of_action`` {AB, AC, AD, AE, AF, AP} [m],
        ``tooth_thickness`` {pitch, base, addendum} [m], ``inertia`` [I1, I2] [kg m^2],
        ``equivalent_mass`` [kg], ``mesh_stiffness`` {mean, c1, c2, min, max} [N/m] (eq 21 over the
        mesh cycle), ``mesh_stiffness_per_width`` [N/(mm um)], ``damping_coefficient`` [N s/m] (the
        plant's c: the file's value or eq 38 from the plant's k), ``damping_coefficient_eq38``
        [N s/m] (eq 38 from the computed mean), ``yang_sun_stiffness`` [N/m], ``backlash`` [m],
        ``plant`` {k, c, J1, J2, natural_frequency_hz} for the improved plant.
    """
    pair = model.pair
    geo = pair_geometry(pair)
    ms = mesh_stiffness(pair)
    plant = build_plant(model)
    rb1, rb2 = geo.base_radius
    m_eq = equivalent_mass(*geo.inertia, rb1, rb2)
    return {
        "model": model.name,
        "teeth": [pair.teeth1, pair.teeth2],
        "module": pair.module,
        "pressure_angle_deg": math.degrees(pair.pressure_angle),
        "face_width": pair.face_width,
        "contact_ratio": geo.contact_ratio,
        "base_pitch": geo.base_pitch,
        "pitch_radius": list(geo.pitch_radius),
        "base_radius": list(geo.base_radius),
        "addendum_radius": list(geo.addendum_radius),
        "dedendum_radius": list(geo.dedendum_radius),
        "line_of_action": {
            "AB": geo.AB, "AC": geo.AC, "AD": geo.AD, "AE": geo.AE, "AF": geo.AF, "AP": geo.AP
        },
        "tooth_thickness": {
            "pitch": geo.tooth_thickness_pitch,
            "base": list(geo.tooth_thickness_base),
            "addendum": list(geo.tooth_thickness_addendum),
        },
        "inertia": list(geo.inertia),
        "equivalent_mass": m_eq,
        "mesh_stiffness": {"mean": ms.mean, "c1": ms.c1, "c2": ms.c2, "min": ms.min, "max": ms.max},
        "mesh_stiffness_per_width": ms.mean / pair.face_width * 1e-9,
        "damping_coefficient": plant.c,
        "damping_coefficient_eq38": damping_coefficient(ms.mean, model.dynamics.damping_ratio, m_eq),
        "yang_sun_stiffness": yang_sun_stiffness(pair),
        "backlash": pair.backlash,
        "plant": {
            "k": plant.k,
            "c": plant.c,
            "J1": plant.J1,
            "J2": plant.J2,
            "contact_law": plant.contact_law.value,
            "natural_frequency_hz": plant.natural_frequency / (2 * math.pi),
        },
        "source": dict(model.source),
    }
