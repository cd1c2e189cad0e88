"""The figures of a gear model in one JSON-ready dictionary (``gearctl info``)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from .geometry import GearPair, pair_geometry
from .model import GearModel
from .params import MeshDynamics
from .plant import Plant, build_plant
from .stiffness import (
    damping_coefficient,
    equivalent_mass,
    iso6336_mesh_stiffness,
    mesh_stiffness,
    stiffness_note,
    yang_sun_stiffness,
)

__all__ = ["model_summary"]


#: ISO's recommended least tooth thickness at the tip, in modules (0.4 for case-hardened gears)
TIP_THICKNESS_MIN = 0.2


def _tip_note(pair: GearPair, s_a: tuple[float, float]) -> str | None:
    """A note where a tooth tip is thinner than :data:`TIP_THICKNESS_MIN` modules, else None: the model stays defined
    down to a pointed tip (which :func:`~gearctl.geometry.pair_geometry` refuses), but such a tip breaks or wears in
    service (a review's 13-tooth pinion with ``x1 = 0.9`` had 0.059 m)."""
    thin = [(j, sa) for j, sa in enumerate(s_a, start=1) if sa < TIP_THICKNESS_MIN * pair.module]
    if not thin:
        return None
    return "; ".join(f"gear {j}'s tooth tip is {sa / pair.module:.3g} modules thick ({sa * 1e3:.3g} mm), under the "
                     f"{TIP_THICKNESS_MIN:g} m usually asked (0.4 m case-hardened): a smaller profile shift x{j} or "
                     f"addendum_coefficient thickens it" for j, sa in thin)


def _stage_summary(pair: GearPair, dynamics: MeshDynamics, plant: Plant, i: int) -> dict[str, Any]:
    """Geometry, stiffness and damping of one stage (a pair's whole ``info``, a train's ``stages[i]``)."""
    geo = pair_geometry(pair)
    ms = mesh_stiffness(pair)
    rb1, rb2 = geo.base_radius
    m_eq = equivalent_mass(*geo.inertia, rb1, rb2)
    st = plant.stages[i]
    return {
        "teeth": [pair.teeth1, pair.teeth2],
        "module": pair.module,
        "pressure_angle_deg": math.degrees(pair.pressure_angle),
        "face_width": pair.face_width,
        "profile_shift": list(geo.profile_shift),
        "operating_pressure_angle_deg": math.degrees(geo.operating_pressure_angle),
        "centre_distance": geo.centre_distance,
        "contact_ratio": geo.contact_ratio,
        "base_pitch": geo.base_pitch,
        "pitch_radius": list(geo.pitch_radius),
        "base_radius": list(geo.base_radius),
        "addendum_radius": list(geo.addendum_radius),
        "dedendum_radius": list(geo.dedendum_radius),
        "line_of_action": {"AB": geo.AB, "AC": geo.AC, "AD": geo.AD, "AE": geo.AE, "AF": geo.AF, "AP": geo.AP},
        "tooth_thickness": {
            "pitch": geo.tooth_thickness_pitch,
            "reference": list(geo.tooth_thickness_reference),
            "base": list(geo.tooth_thickness_base),
            "addendum": list(geo.tooth_thickness_addendum),
        },
        "inertia": list(geo.inertia),
        "equivalent_mass": m_eq,
        "plant_equivalent_mass": plant.stage_m_eq(i),
        "mesh_stiffness": {"mean": ms.mean, "c1": ms.c1, "c2": ms.c2, "min": ms.min, "max": ms.max},
        "mesh_stiffness_per_width": ms.mean / pair.face_width * 1e-9,
        "mesh_stiffness_iso6336": iso6336_mesh_stiffness(pair),
        # where the plant uses the computed mean: a note if the report's beam makes it far too soft
        "stiffness_note": None if dynamics.mesh_stiffness is not None else stiffness_note(pair, ms.mean),
        "tip_note": _tip_note(pair, geo.tooth_thickness_addendum),
        "damping_coefficient": st.c,
        "damping_coefficient_given": dynamics.damping_coefficient is not None,
        "plant_stiffness": st.k,
        "mesh_stiffness_given": dynamics.mesh_stiffness is not None,
        "damping_coefficient_eq38": damping_coefficient(ms.mean, dynamics.damping_ratio, m_eq),
        "yang_sun_stiffness": yang_sun_stiffness(pair),
        "backlash": pair.backlash,
        "ratio": st.ratio,
    }


def model_summary(model: GearModel) -> dict[str, Any]:
    """Geometry, stiffness, damping and plant figures of a gear model, SI units.

    Parameters
    ----------
    model : GearModel
        The catalog entry (a pair or a train).

    Returns
    -------
    dict
        JSON-ready. For a pair: ``contact_ratio``, ``base_pitch`` [m], ``pitch_radius``, ``base_radius``,
        ``addendum_radius``, ``dedendum_radius`` [m, m], ``line_of_action`` {AB, AC, AD, AE, AF, AP} [m],
        ``tooth_thickness`` {pitch (``pi m / 2``, unshifted), reference (each gear's, with its profile shift:
        ``m (pi/2 + 2 x tan(alpha))``), base, addendum} [m], ``inertia`` [I1, I2] [kg m^2],
        ``equivalent_mass`` [kg] (the gears alone, the report's), ``plant_equivalent_mass`` [kg] (with the
        shafts' inertias: the mesh mode's, which the plant's damping uses), ``mesh_stiffness`` {mean, c1, c2,
        min, max} [N/m] (eq 21 over the mesh cycle), ``mesh_stiffness_per_width`` [N/(mm um)],
        ``mesh_stiffness_iso6336`` [N/m] (ISO 6336-1's estimate, a cross-check), ``stiffness_note`` (a warning
        where the plant's computed stiffness is under half of ISO's for a large gear, else null), ``tip_note`` (a
        note where a tooth tip is under 0.2 modules thick, ISO's usual least, else null),
        ``damping_coefficient`` [N s/m] (the
        plant's c: the file's value or eq 38 from the plant's k; ``damping_coefficient_given`` says which),
        ``plant_stiffness`` [N/m] (the plant's k: the file's ``mesh_stiffness`` if given, which
        ``mesh_stiffness_given`` says, else the computed mean), ``damping_coefficient_eq38``
        [N s/m] (eq 38 from the computed mean), ``yang_sun_stiffness`` [N/m], ``backlash`` [m],
        ``profile_shift``, ``operating_pressure_angle_deg``, ``centre_distance`` [m], and ``plant``
        {k, c, J1, J2, natural_frequency_hz} for the improved plant. For a train: ``stages`` (a list of
        those per-stage keys, each with its ``ratio``), ``plant`` {J (per shaft), k, c (per stage),
        gear_ratio, natural_frequency_hz (the highest resonance of the coupled contact model, `linearize`'s mesh
        mode), resonances_hz (every resonance in contact, lowest first)}, ``lost_motion`` [rad at the output] and
        ``equivalent_stiffness`` [N m/rad at the output], and ``ratio`` (the whole train's, as a pair's ``ratio``).
        Both have ``model``, ``stages_count``,
        ``sensors`` {``motor_encoder_cpr``, ``load_encoder_cpr`` (null: ideal), ``motor_noise``,
        ``load_noise`` [rad], ``load_encoder`` (false: the servo has none)} and ``source``.
    """
    plant = build_plant(model)
    stages = [_stage_summary(s.pair, s.dynamics, plant, i) for i, s in enumerate(model.stages)]
    sensors = dataclasses.asdict(model.sensors)
    common = {"model": model.name, "stages_count": len(stages), "lost_motion": plant.lost_motion,
              "equivalent_stiffness": plant.equivalent_stiffness, "sensors": sensors, "source": dict(model.source)}
    if len(stages) == 1:
        return {"model": model.name, **stages[0], "plant": {
            "k": plant.k, "c": plant.c, "J1": plant.J1, "J2": plant.J2, "contact_law": plant.contact_law.value,
            "natural_frequency_hz": plant.natural_frequency / (2 * math.pi)}, **common}
    from .modes import linearize_modes  # python-control: only for a train's summary

    modes = linearize_modes(plant)  # a train's resonances are the coupled contact model's, as `linearize` gives them
    return {**common, "ratio": plant.gear_ratio, "stages": stages, "plant": {
        "J": [s.J for s in plant.shafts], "k": [s.k for s in plant.stages], "c": [s.c for s in plant.stages],
        "gear_ratio": plant.gear_ratio, "contact_law": plant.contact_law.value,
        "natural_frequency_hz": modes.mesh.natural_frequency_hz, "resonances_hz": list(modes.resonances_hz)}}
