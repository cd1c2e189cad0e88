"""gearctl: control design for geared servos with backlash.

The plant is the improved spur-gear model of Shing, Tsai & Krishnaprasad (ISR TR 93-28): mesh stiffness
from tooth bending, shear, foundation and Hertzian deflection, three contact modes (front contact,
separation, back contact), beside Yang & Sun's 1985 model.

Data flow, one way: geometry → stiffness → plant → modes → design → simulate → metrics → bench;
plots and the CLI sit on top and are not imported here.

Index
-----
geometry    :class:`GearPair`, :func:`pair_geometry`
stiffness   :func:`mesh_stiffness`, :func:`tooth_deflections`, :func:`damping_coefficient`,
            :func:`yang_sun_stiffness`, :func:`yang_sun_damping_factor`
params      :class:`MeshDynamics`, :class:`Servo`, :class:`Sensors`, :class:`ContactLaw`
plant       :class:`Plant`, :func:`build_plant`, :class:`Mode`, :class:`PlantKind`
catalog     :func:`load_model`, :func:`model_names`, :class:`GearModel`
summary     :func:`model_summary`
errors      :class:`GearctlError`, :class:`InputError`, :class:`SimulationError`
"""

from .catalog import GearModel, load_model, model_names
from .errors import GearctlError, InputError, SimulationError, SolverError
from .geometry import GearPair, Geometry, pair_geometry
from .params import ContactLaw, MeshDynamics, Sensors, Servo
from .plant import Mode, Plant, PlantKind, build_plant
from .stiffness import (
    MeshStiffness,
    ToothDeflections,
    damping_coefficient,
    equivalent_mass,
    mesh_stiffness,
    mesh_stiffness_at,
    tooth_deflections,
    yang_sun_damping_factor,
    yang_sun_stiffness,
)
from .summary import model_summary

__version__ = "0.1.0"

__all__ = [
    "ContactLaw",
    "GearModel",
    "GearPair",
    "GearctlError",
    "Geometry",
    "InputError",
    "MeshDynamics",
    "MeshStiffness",
    "Mode",
    "Plant",
    "PlantKind",
    "Sensors",
    "Servo",
    "SimulationError",
    "SolverError",
    "ToothDeflections",
    "build_plant",
    "damping_coefficient",
    "equivalent_mass",
    "load_model",
    "mesh_stiffness",
    "mesh_stiffness_at",
    "model_names",
    "model_summary",
    "pair_geometry",
    "tooth_deflections",
    "yang_sun_damping_factor",
    "yang_sun_stiffness",
]
