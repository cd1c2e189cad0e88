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
simulate    :func:`report_case`, ``gearctl.simulate.simulate`` (open loop, events located exactly)
modes       :func:`linearize_modes`, :func:`contact_mode_model`, :func:`loop_margins` (python-control)
design      :class:`PID`, :func:`design_pid`, :class:`DeadzoneInverse`, MPC (``gearctl.design.mpc``)
closedloop  :func:`simulate_closed_loop`; references :func:`reference`; metrics :func:`tracking_metrics`
precision   :func:`precision_test` (ISO 230-2); bench :func:`run_bench`
runs        :func:`make_run`, :func:`execute` (one closed-loop run as a value)
identify    :func:`read_log`, ``gearctl.identify.identify``, :func:`write_identified_model`; excite
            :func:`record_excitation`
sweep       ``gearctl.sweep.sweep`` (Monte Carlo and grids on Dask.distributed)
export      :func:`export_controller` (C99), :func:`load_exported` (the C in the loop)
errors      :class:`GearctlError`, :class:`InputError`, :class:`SimulationError`

Every name above is imported on first use, so ``import gearctl`` stays light (the command line starts at once).
"""

from .errors import GearctlError, InputError, SimulationError, SolverError

__version__ = "0.1.0"

_LAZY = {
    "GearModel": "gearctl.catalog", "load_model": "gearctl.catalog", "model_names": "gearctl.catalog",
    "GearPair": "gearctl.geometry", "Geometry": "gearctl.geometry", "pair_geometry": "gearctl.geometry",
    "ContactLaw": "gearctl.params", "MeshDynamics": "gearctl.params", "Sensors": "gearctl.params",
    "Servo": "gearctl.params",
    "Mode": "gearctl.plant", "Plant": "gearctl.plant", "PlantKind": "gearctl.plant", "build_plant": "gearctl.plant",
    **{name: "gearctl.stiffness" for name in ("MeshStiffness", "ToothDeflections", "damping_coefficient",
                                              "equivalent_mass", "mesh_stiffness", "mesh_stiffness_at",
                                              "tooth_deflections", "yang_sun_damping_factor", "yang_sun_stiffness")},
    "model_summary": "gearctl.summary",
    "report_case": "gearctl.simulate",
    "linearize_modes": "gearctl.modes", "contact_mode_model": "gearctl.modes", "separation_model": "gearctl.modes",
    "rigid_model": "gearctl.modes", "loop_margins": "gearctl.modes",
    "simulate_closed_loop": "gearctl.closedloop", "reference": "gearctl.references",
    "tracking_metrics": "gearctl.metrics", "precision_test": "gearctl.precision", "run_bench": "gearctl.bench",
    "load_controller": "gearctl.catalog", "plant_nlsys": "gearctl.plant",
    "make_run": "gearctl.runs", "execute": "gearctl.runs",
    "read_log": "gearctl.identify", "write_identified_model": "gearctl.identify",
    "record_excitation": "gearctl.excite",
    "export_controller": "gearctl.export", "load_exported": "gearctl.export",
}


#: Submodules whose main function has the module's name (``gearctl.simulate.simulate``, ``gearctl.identify.identify``,
#: ``gearctl.sweep.sweep``): ``gearctl.<name>`` is always the module (a function of that name would be replaced by
#: the module as soon as anything imports it).
_SUBMODULES = ("simulate", "identify", "sweep")


def __getattr__(name: str) -> object:
    """Import the API on first use (``import gearctl`` imports nothing but the errors, so that the command line
    starts at once and a Ctrl-C while it starts is its own one line); ``gearctl.<submodule>`` imports it too."""
    import importlib

    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    if not name.startswith("_"):
        import importlib.util

        if importlib.util.find_spec(f"{__name__}.{name}") is not None:
            return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module 'gearctl' has no attribute {name!r}")


def __dir__() -> list[str]:
    """The API's names, imported or not yet (tab completion and ``help(gearctl)`` list them, as before)."""
    return sorted({*globals(), *_LAZY, *_SUBMODULES})

__all__ = [
    *_LAZY,
    *_SUBMODULES,
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
