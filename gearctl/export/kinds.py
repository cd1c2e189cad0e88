"""What each catalog controller kind exports: its C parameter struct, the values read off the Python object,
its C state, its sources.

One :class:`KindSpec` per controller object (:func:`kind_spec`). The parameters are the Python object's own
numbers (gains, the discretised filter pole, observer matrices, for the MPC its condensed pattern tables and
Hessian factors), read after the design, so that the C runs exactly the controller the object is.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypedDict, cast

from ..controller import Controller
from ..design import deadzone
from ..design import pid as pid_module
from ..design.adaptive import CONVERGED_MEASUREMENTS, AdaptiveInverse
from ..design.deadzone import DeadzoneInverse
from ..design.mpc import MPC
from ..design.pid import PID
from ..design.reversal import ReversalOffset
from ..errors import InputError
from ..plant import MAX_STAGES
from .cstruct import CArray, CStruct

__all__ = ["KindSpec", "kind_spec", "KINDS", "CSRC", "STRUCTS", "kind_structs"]

#: Folder of the C templates.
CSRC = Path(__file__).parent / "csrc"

#: Controller kinds (the ``kind`` of a controller file) and their C prefix; the code of each kind.
KINDS = {"pid": "pid", "reversal_offset": "rev", "deadzone_inverse": "inv", "adaptive_inverse": "ada", "mpc": "mpc"}
#: numeric ids of the kinds in the runtime library (gcx_runtime.c)
KIND_IDS = {"pid": 1, "rev": 2, "inv": 3, "ada": 4, "mpc": 5}
_RAMP_CODES = {"sin2": 0, "linear": 1, "step": 2}

# --- the parameter structs, described once (C declaration, ctypes mirror, initializer) -----------------------

STRUCTS: dict[str, CStruct] = {}


def _struct(name: str, fields: list[tuple[str, str]]) -> CStruct:
    s = CStruct(name, fields, STRUCTS)
    STRUCTS[name] = s
    return s


_struct("gcx_pid_p", [(f, "double") for f in ("kp", "ki", "kd", "a", "Tt", "Ts", "N", "limit", "J_eq",
                                              "d_eq", "load_torque", "friction", "integral_bound")]
        + [("feedforward", "int"), ("feedback_load", "int")])
_struct("gcx_plant_p", [(f, "double") for f in ("J1", "d1", "tc1", "J2", "d2", "load_torque", "tc2", "rb2")])
_struct("gcx_obs_p", [("A", "double[9]"), ("B", "double[3]"), ("L", "double[3]"), ("N", "double"), ("tl", "double")])
_struct("gcx_rev_p", [("pid", "gcx_pid_p"), ("plant", "gcx_plant_p"), ("ramp_shape", "int"),
                      ("ramp_duration", "double"), ("value", "double"), ("uses_load", "int")])
_struct("gcx_inv_p", [("pid", "gcx_pid_p"), ("plant", "gcx_plant_p"), ("obs", "gcx_obs_p"), ("has_observer", "int"),
                      ("rule_velocity", "int"), ("ramp_shape", "int"), ("width", "double"),
                      ("crossing_time", "double"), ("disturbance_threshold", "double"), ("backlash", "double"),
                      ("a_limit", "double"), ("jump_den", "double"), ("jump_floor", "double"),
                      ("rattle_decay", "double"),
                      ("rattle_level", "double"), ("rattle_gain", "double"), ("rattle_max_error", "double"),
                      ("contact_lag", "double"), ("free_load_reach", "double"),
                      ("press_time", "double"), ("press_travel", "double"), ("friction_margin", "double"),
                      ("take_up_acceleration", "double"), ("follow_inertia", "double"), ("n_carried", "int"),
                      ("carried", f"double[{4 * MAX_STAGES}]")])
_struct("gcx_ada_p", [("inv", "gcx_inv_p"), ("rb1", "double"), ("rb2", "double"), ("k", "double"),
                      ("window", "int")] + [(f, "double") for f in (
                          "gain", "max_step", "min_backlash", "max_backlash", "plateau_tolerance", "apply_threshold",
                          "initial", "converged_crossing_time", "converged_tolerance", "diverged_tolerance")]
        + [("converged_measurements", "int")])
_struct("gcx_mpc_p", [
    ("n_pat", "int"), ("n_p", "int"), ("all_contact", "int"), ("rigid", "int"), ("uses_load", "int"),
    ("n_cross", "int"), ("n_lead", "int"), ("bound_landing", "int"), ("gov_on", "int"),
    *[(f, "double") for f in ("Ts", "b", "tol", "umax", "tau_load", "rb1", "rb2", "kappa1", "kappa2", "ratio",
                              "J_eq", "d_eq", "impact_innovation", "flicker_innovation", "flicker_return", "a_max",
                              "v_land", "f_land", "deadband", "cross_share", "learn_below", "tc1", "w_friction", "tc2",
                              "gap_limit", "gate_motor", "gate_load", "c_centre", "a_net", "a_gov", "dp_pass",
                              "dv_pass", "v_gov")],
    ("gap_rows", "double[12]"), ("centre_rows", "double[7]"), ("Lc", "double[3]"), ("Lg_small", "double[2]"),
    ("Lg_big", "double[2]"),
    ("pat_index", "const int16_t *"), ("has_landing", "const int8_t *"), ("land_row", "const int16_t *"),
    ("gap_mask", "const int8_t *"), ("mesh_mask", "const int8_t *"), ("factor", "const double *"),
    ("rows", "const double *"), ("G_ptr", "const int32_t *"), ("G_idx", "const uint16_t *"),
    ("G_val", "const double *"), ("Cr", "const double *"), ("K_ptr", "const int32_t *"),
    ("K_row", "const uint16_t *"), ("K_col", "const uint16_t *"), ("K_val", "const double *"),
])

#: the structs each kind's parameters need, in declaration order
_NEEDS = {"pid": ["gcx_pid_p"], "rev": ["gcx_pid_p", "gcx_plant_p", "gcx_rev_p"],
          "inv": ["gcx_pid_p", "gcx_plant_p", "gcx_obs_p", "gcx_inv_p"],
          "ada": ["gcx_pid_p", "gcx_plant_p", "gcx_obs_p", "gcx_inv_p", "gcx_ada_p"], "mpc": ["gcx_mpc_p"]}


def kind_structs(prefixes: list[str] | tuple[str, ...] = ("pid", "rev", "inv", "ada")) -> str:
    """The C declarations of the parameter structs the kinds ``prefixes`` need.

    Parameters
    ----------
    prefixes : sequence of str
        C prefixes of the kinds: ``pid``, ``rev``, ``inv``, ``ada``, ``mpc`` (default the first four).

    Returns
    -------
    str
        The ``typedef struct`` declarations, each struct once, in the order needed.

    Raises
    ------
    KeyError
        For another prefix.
    """
    names: list[str] = []
    for p in prefixes:
        names += [n for n in _NEEDS[p] if n not in names]
    return "".join(STRUCTS[n].c_decl() for n in names)


@dataclasses.dataclass(frozen=True)
class KindSpec:
    """What one controller object exports.

    Attributes
    ----------
    kind : str
        The controller-file kind (``pid``, ``mpc``, ...).
    prefix : str
        Its C prefix (``gcx_<prefix>_init`` / ``_run``, ``gcx_<prefix>_p`` / ``_s``).
    values : dict
        The parameter struct's values.
    dims : dict
        Compile-time sizes (``#define``; e.g. the MPC's horizon, the adaptive window).
    Ts : float
        Sample period [s].
    preview : int
        Reference rows a step reads.
    uses_load_encoder : bool
    describe : dict
        The Python object's settings (``Controller.describe()``).
    name : str
    ratio : float
        Motor angle per load angle in contact (the gear ratio, > 0: the load angle's positive sense is the
        one the motor's positive torque drives it in).
    torque_limit : float
        The torque the step clips its command to [N m].
    """

    kind: str
    prefix: str
    values: dict[str, Any]
    dims: dict[str, int]
    Ts: float
    preview: int
    uses_load_encoder: bool
    describe: dict[str, Any]
    name: str
    ratio: float
    torque_limit: float

    @property
    def struct(self) -> CStruct:
        """The parameter struct."""
        return STRUCTS[f"gcx_{self.prefix}_p"]

    @property
    def arrays(self) -> list[CArray]:
        """The constant tables (the MPC's)."""
        return self.struct.arrays(self.values)

    @property
    def table_bytes(self) -> int:
        """Bytes of constant data: the parameter struct's scalars and the tables."""
        return int(ctypes_size(self.struct) + sum(a.nbytes for a in self.arrays))


def ctypes_size(s: CStruct) -> int:
    """``sizeof`` of a struct on this machine."""
    import ctypes

    return ctypes.sizeof(s.ctype())


# --- values read off the Python objects ---------------------------------------------------------------------


def _pid_values(pid: PID) -> dict[str, Any]:
    g, info = pid.gains, pid.info
    return {"kp": g.kp, "ki": g.ki, "kd": g.kd, "a": pid._a, "Tt": pid._Tt,
            "Ts": pid.Ts, "N": pid.N, "limit": pid.limit, "J_eq": info.J_eq, "d_eq": info.d_eq,
            "load_torque": info.plant.load_torque, "friction": pid.friction,
            "integral_bound": pid_module.INTEGRAL_BOUND, "feedforward": int(bool(pid.feedforward)),
            "feedback_load": int(pid.feedback == "load")}


def _plant_values(pid: PID) -> dict[str, Any]:
    p = pid.info.plant
    return {"J1": p.J1, "d1": p.d1, "tc1": p.tc1, "J2": p.J2, "d2": p.d2, "load_torque": p.load_torque, "tc2": p.tc2,
            "rb2": p.rb2}


def _inv_values(inv: DeadzoneInverse) -> dict[str, Any]:
    obs = inv._observer
    if obs is not None:
        ov = {"A": [v for row in obs.A for v in row], "B": list(obs.B), "L": list(obs.L), "N": obs.N, "tl": obs._tl}
    else:
        ov = {"A": [0.0] * 9, "B": [0.0] * 3, "L": [0.0] * 3, "N": 0.0, "tl": 0.0}
    return {"pid": _pid_values(inv.pid), "plant": _plant_values(inv.pid), "obs": ov,
            "has_observer": int(obs is not None), "rule_velocity": int(inv.rule == "velocity"),
            "ramp_shape": _RAMP_CODES[inv._ramp.shape], "width": inv.width, "crossing_time": inv.crossing_time,
            "disturbance_threshold": inv.disturbance_threshold, "backlash": inv.backlash, "a_limit": inv._a_limit,
            "jump_den": inv._jump_den, "jump_floor": inv.jump_floor, "rattle_decay": deadzone.RATTLE_DECAY,
            "rattle_level": deadzone.RATTLE_LEVEL, "rattle_gain": deadzone.RATTLE_GAIN,
            "rattle_max_error": deadzone.RATTLE_MAX_ERROR,
            "contact_lag": inv._contact_lag, "free_load_reach": deadzone.FREE_LOAD_REACH,
            "press_time": deadzone.PRESS_TIME, "press_travel": deadzone.PRESS_TRAVEL,
            "friction_margin": deadzone.FRICTION_MARGIN,
            "take_up_acceleration": deadzone.TAKE_UP_ACCELERATION, "follow_inertia": inv._J_follow,
            "n_carried": len(inv._carried),
            "carried": [v for row in inv._carried for v in row] + [0.0] * (4 * (MAX_STAGES - len(inv._carried)))}


class _Common(TypedDict, total=False):
    """The :class:`KindSpec` fields every kind fills alike (``ratio`` and ``torque_limit`` from its PID, if any)."""

    Ts: float
    preview: int
    uses_load_encoder: bool
    describe: dict[str, Any]
    name: str
    ratio: float
    torque_limit: float


def kind_spec(controller: Controller) -> KindSpec:
    """The export description of a controller object.

    Parameters
    ----------
    controller : Controller
        A controller of one of gearctl's kinds, exactly (a subclass is refused: it may change what a method
        does, which the C would not know).

    Returns
    -------
    KindSpec

    Raises
    ------
    InputError
        For a controller that is not one of gearctl's catalog kinds.
    """
    c = controller
    if type(c) not in (PID, ReversalOffset, DeadzoneInverse, AdaptiveInverse, MPC):  # before reading its attributes
        raise _not_exportable(c)
    common: _Common = {"Ts": float(c.Ts), "preview": int(c.preview), "uses_load_encoder": bool(c.uses_load_encoder),
                       "describe": c.describe(), "name": str(c.name)}
    # exact types: a subclass may change what a method does, which the C would not know
    pid = cast("PID | None", {PID: c, ReversalOffset: getattr(c, "pid", None), DeadzoneInverse: getattr(c, "pid", None),
                              AdaptiveInverse: getattr(getattr(c, "inner", None), "pid", None)}.get(type(c)))
    if pid is not None:
        common.update({"ratio": float(pid.N), "torque_limit": float(pid.limit)})
    if type(c) is PID:
        return KindSpec(kind="pid", prefix="pid", values=_pid_values(c), dims={}, **common)
    if type(c) is ReversalOffset:
        vals = {"pid": _pid_values(c.pid), "plant": _plant_values(c.pid), "ramp_shape": _RAMP_CODES[c._ramp.shape],
                "ramp_duration": c._ramp.duration, "value": c.value, "uses_load": int(c.uses_load_encoder)}
        return KindSpec(kind="reversal_offset", prefix="rev", values=vals, dims={}, **common)
    if type(c) is DeadzoneInverse:
        return KindSpec(kind="deadzone_inverse", prefix="inv", values=_inv_values(c), dims={}, **common)
    if type(c) is AdaptiveInverse and type(c.inner) is DeadzoneInverse:
        p = c.inner.pid.info.plant
        st = c.settings
        # the inverse as reset() leaves it: the learning crossing (the object may have switched in a run)
        learning = c.learning_crossing_time
        inv = {**_inv_values(c.inner), "crossing_time": learning,
               "ramp_shape": _RAMP_CODES["sin2" if learning > 0.0 else "step"]}
        vals = {"inv": inv, "rb1": c._rb1, "rb2": c._rb2, "k": c._k, "window": c._window,
                "gain": st.gain, "max_step": st.max_step, "min_backlash": c.min_backlash,
                "max_backlash": c.max_backlash, "plateau_tolerance": st.plateau_tolerance,
                "apply_threshold": st.apply_threshold, "initial": c.initial,
                "converged_crossing_time": st.converged_crossing_time, "converged_tolerance": st.converged_tolerance,
                "diverged_tolerance": st.diverged_tolerance, "converged_measurements": CONVERGED_MEASUREMENTS}
        assert p.rb1 == c._rb1
        return KindSpec(kind="adaptive_inverse", prefix="ada", values=vals, dims={"GCX_ADA_WINDOW": c._window},
                        **common)
    if type(c) is MPC:
        from .mpc_tables import mpc_values

        vals, dims = mpc_values(c)
        common.update({"ratio": float(vals["ratio"]), "torque_limit": float(vals["umax"])})  # (no PID: its tables')
        return KindSpec(kind="mpc", prefix="mpc", values=vals, dims=dims, **common)
    raise _not_exportable(c)


def _not_exportable(c: Any) -> InputError:
    """The error for an object that is none of gearctl's exportable controller kinds."""
    return InputError(f"controller {getattr(c, 'name', c)!r} ({type(c).__name__}) cannot be exported: expected one of "
                      f"gearctl's controller kinds ({', '.join(KINDS)})", field="controller")


def source_text(name: str) -> str:
    """A C template's text."""
    return (CSRC / name).read_text()


def defines(dims: Mapping[str, int]) -> str:
    """``#define`` lines of the compile-time sizes."""
    return "".join(f"#define {k} {int(v)}\n" for k, v in sorted(dims.items()))
