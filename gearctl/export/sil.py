"""Software in the loop: an exported folder's C, compiled and called per sample as a :class:`Controller`.

:func:`load_exported` compiles the folder's own sources (``gearctl_ctrl.c``, and ``gearctl_qp.c`` for an MPC)
through :func:`gearctl.build.shared_library`, with a two-line shim that reports ``sizeof(gearctl_ctrl_t)``,
and returns an :class:`ExportedController`: each :meth:`~ExportedController.step` writes the encoder
readings and points at the reference rows (:class:`~gearctl.export.rows.PreviewRows`, the rows the Python
controller reads), then calls ``gearctl_ctrl_step`` through :mod:`ctypes` on preallocated buffers. So the
closed loop, the metrics and every command that takes a controller run the C itself.
"""

from __future__ import annotations

import ctypes
import json
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..build import CompileError, shared_library
from ..controller import Controller, ReferenceLike
from ..errors import InputError
from .emit import CFLAGS, DEFAULT_PREFIX, FORMAT, prefixed, prefixed_name
from .rows import PreviewRows

__all__ = ["ExportedController", "load_exported", "compile_exported", "execute_exported", "exported_name"]

_SHIM = '#include "gearctl_ctrl.h"\nlong gearctl_sil_state_size(void) { return (long)sizeof(gearctl_ctrl_t); }\n'
_SOURCES = ("gearctl_ctrl.h", "gearctl_ctrl.c", "gearctl_ctrl_params.h", "gearctl_qp.h", "gearctl_qp.c")
_STATUS = {1: "fallback", 2: "bad input (a reading or reference not finite or beyond 1e12: zero torque)",
           3: "fault (latched: the motor braked to rest, then zero torque, until reset)",
           4: "not initialised (gearctl_ctrl_init never ran on the instance: zero torque)"}


def _manifest(folder: Path) -> dict[str, Any]:
    path = folder / "controller.json"
    try:
        man = json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError(f"{folder} holds no exported controller (no controller.json): make one with "
                         f"`gearctl export MODEL CONTROLLER --out {folder}`", field="exported") from None
    except (OSError, ValueError) as exc:
        raise InputError(f"{path} cannot be read: {exc}", field="exported") from None
    if man.get("format") != FORMAT:
        raise InputError(f"{path}: format {man.get('format')!r}: expected {FORMAT!r}", field="exported")
    return man


def compile_exported(folder: str | Path) -> tuple[ctypes.CDLL, dict[str, Any]]:
    """Compile an exported folder's sources into a shared library (cached per content); also its manifest.

    Parameters
    ----------
    folder : str or Path
        A folder :func:`~gearctl.export.emit.export_controller` wrote (its ``manifest.json`` and sources).

    Returns
    -------
    lib : ctypes.CDLL
        The library, with the controller's ``init``, ``step`` and SIL state-size functions typed.
    manifest : dict
        The folder's manifest.

    Raises
    ------
    InputError
        For a folder without an exported controller, or sources that do not compile (the compiler's
        message), or no C compiler.
    """
    folder = Path(folder)
    man = _manifest(folder)
    prefix = str(man.get("prefix", DEFAULT_PREFIX))
    names = [prefixed_name(n, prefix) for n in _SOURCES]
    sources = {name: (folder / name).read_bytes() for name in names if (folder / name).is_file()}
    if names[0] not in sources or names[1] not in sources:
        raise InputError(f"{folder}: {names[1]} or {names[0]} is missing", field="exported")
    sources[prefixed_name("gearctl_sil_shim.c", prefix)] = prefixed(_SHIM, prefix).encode()
    try:
        lib = shared_library(f"export_{man['kind']}", sources, flags=(*CFLAGS.split(), "-Wall"), required=True)
    except CompileError as exc:
        raise InputError(f"cannot build the exported controller in {folder}: {exc}", field="exported") from None
    assert lib is not None
    init, step = getattr(lib, f"{prefix}_ctrl_init"), getattr(lib, f"{prefix}_ctrl_step")
    size = getattr(lib, f"{prefix}_sil_state_size")
    init.restype, init.argtypes = None, [ctypes.c_void_p]
    step.restype, step.argtypes = ctypes.c_int, [ctypes.c_void_p] * 4
    size.restype, size.argtypes = ctypes.c_long, []
    return lib, man


class ExportedController(Controller):
    """The compiled C of an exported folder, as a :class:`~gearctl.controller.Controller` (software in the loop).

    Parameters
    ----------
    lib : ctypes.CDLL
        The compiled folder (:func:`compile_exported`).
    manifest : dict
        Its ``controller.json``.
    folder : Path
        Where it came from (for reports).

    Attributes
    ----------
    step_flags : int
        Steps whose C call returned a fallback flag (each also in :attr:`fallbacks`).

    Notes
    -----
    The C keeps its own clock, ``t = k Ts`` with ``k`` the steps since :meth:`reset`: the ``t`` the loop passes
    is used only to evaluate the reference (gearctl's closed loop passes exactly ``k Ts``). For a controller
    that solves an optimisation (the MPC), :attr:`solve_times` holds the wall time of each whole C step (the
    C cannot read a clock), so :attr:`overruns` counts the steps longer than the design's ``max_solve_time`` (the
    sample period if it has none); the C itself has no time budget and does not fall back on an overrun
    (``realtime`` has no effect).
    """

    def __init__(self, lib: ctypes.CDLL, manifest: dict[str, Any], folder: Path) -> None:
        super().__init__()
        self._lib, self.manifest, self.folder = lib, manifest, folder
        self.name = str(manifest["name"])
        self.kind = str(manifest["kind"])
        self.Ts = float(manifest["Ts"])
        self.preview = int(manifest["preview"])
        self.uses_load_encoder = bool(manifest["uses_load_encoder"])
        self._timed = self.kind == "mpc"
        budget = (manifest.get("describe") or {}).get("max_solve_time")
        self._budget = float(budget) if budget is not None else self.Ts
        prefix = str(manifest.get("prefix", DEFAULT_PREFIX))
        self._init, self._fn = getattr(lib, f"{prefix}_ctrl_init"), getattr(lib, f"{prefix}_ctrl_step")
        size = int(getattr(lib, f"{prefix}_sil_state_size")())
        self._state = np.zeros((size + 7) // 8 + 1)  # 8-byte aligned
        self._y = (ctypes.c_double * 2)()
        self._u = ctypes.c_double()
        self._c = self._state.ctypes.data
        self._y_ref, self._u_ref = ctypes.addressof(self._y), ctypes.addressof(self._u)
        self._rows = PreviewRows(self.Ts, self.preview)
        self.step_flags = 0
        self.state_bytes = size
        self.reset()

    def reset(self) -> None:
        """``gearctl_ctrl_init``; forget the reference block and the records."""
        self._init(self._c)
        self._rows.reset()
        self._arr: np.ndarray | None = None
        self._base = 0
        self.solve_times, self.fallbacks = [], []
        self.overruns = 0
        self.step_flags = 0

    def step(self, t: float, y_motor: float, y_load: float | None, ref: ReferenceLike) -> float:
        arr, k = self._rows.at(t, ref)
        if arr is not self._arr:
            self._arr, self._base = arr, arr.ctypes.data
        y = self._y
        y[0] = y_motor
        y[1] = math.nan if y_load is None else y_load
        if self._timed:
            t0 = time.perf_counter()
            flag = self._fn(self._c, self._y_ref, self._base + 24 * k, self._u_ref)
            took = time.perf_counter() - t0
            self.solve_times.append(took)
            if took > self._budget:
                self.overruns += 1
        else:
            flag = self._fn(self._c, self._y_ref, self._base + 24 * k, self._u_ref)
        if flag > 0:
            self.step_flags += 1
            self.fallbacks.append({"t": float(t), "reason": f"exported controller: {_STATUS.get(flag, 'fallback')} "
                                                            f"(status {flag})"})
        return self._u.value

    def describe(self) -> dict[str, Any]:
        """The exported controller's settings (the Python object's at export) and where the C came from."""
        d = dict(self.manifest.get("describe") or {})
        d.update({"name": self.name, "kind": self.kind, "Ts": self.Ts, "preview": self.preview,
                  "implementation": "exported C (software in the loop)", "exported": str(self.folder),
                  "state_bytes": self.state_bytes, "table_bytes": self.manifest.get("table_bytes")})
        if self.kind == "adaptive_inverse":  # what the C learns lives in its state, which is not read back
            d["settings_at_export"] = True
            d["note"] = "backlash_estimate and the adaptation's figures are the exported object's, not the run's"
        return d


def exported_name(folder: str | Path) -> str:
    """The catalog name of the controller an exported folder holds (its kind where the name is no catalog entry).

    Parameters
    ----------
    folder : str or Path
        A folder :func:`~gearctl.export.emit.export_controller` wrote (its ``manifest.json`` and sources).

    Raises
    ------
    InputError
        For a folder without an exported controller.
    """
    from ..catalog import controller_names

    man = _manifest(Path(folder))
    name = str(man.get("name") or "")
    return name if name in controller_names() else str(man.get("kind"))


def exported_notes(folder: str | Path, model: str, backlash: float | None) -> list[str]:
    """What an exported folder keeps that the command asks to change: its model (a folder exported for another model
    of the same ratio runs, on that model's numbers) and its backlash estimate (``--backlash`` changes the plant;
    the C keeps the estimate it was exported with, where plain ``track`` designs on the new value). One note each."""
    man = _manifest(Path(folder))
    notes = []
    theirs = str(man.get("model") or "")
    if theirs and theirs != model:
        notes.append(f"{folder} was exported for model {theirs!r}: its controller keeps that model's numbers on "
                     f"{model!r} (export it for {model!r} to compare with plain `track`)")
    est = (man.get("describe") or {}).get("backlash_estimate")
    if backlash is not None and est is not None and not math.isclose(float(est), backlash, rel_tol=1e-12):
        notes.append(f"--backlash {backlash:g} changes the plant only: the exported controller keeps its backlash "
                     f"estimate {float(est):g} m (plain `track --backlash` designs on the new value; export with "
                     f"`--backlash` or `--estimate` to match)")
    return notes


def load_exported(folder: str | Path) -> ExportedController:
    """Compile an exported folder and return its C as a :class:`~gearctl.controller.Controller` (SIL).

    Parameters
    ----------
    folder : str or Path
        A folder written by :func:`gearctl.export_controller` / ``gearctl export``.

    Returns
    -------
    ExportedController

    Raises
    ------
    InputError
        For a folder without an exported controller, sources that do not compile, or no C compiler.
    """
    lib, man = compile_exported(folder)
    return ExportedController(lib, man, Path(folder))


def execute_exported(run: Any, folder: str | Path, *, keep: bool = False,
                     progress: Callable[[float], Any] | None = None) -> Any:
    """:func:`gearctl.runs.execute` with an exported folder's C in place of the run's Python controller.

    The run's plant, reference, duration, seed and sensors are used; its design names the controller the
    folder must hold (the same kind; the folder's numbers are what runs).

    Parameters
    ----------
    run : Run
    folder : str or Path
        A folder written by ``gearctl export``.
    keep : bool
        Also return the :class:`~gearctl.closedloop.ClosedLoopResult` (None if the run failed before it started).
    progress : callable, optional
        Called with the fraction of the closed loop done.

    Returns
    -------
    RunResult, or (RunResult, ClosedLoopResult or None) with ``keep``

    Raises
    ------
    InputError
        For a folder that holds no exported controller, one of another kind than the run's or for another gear
        ratio, or that does not compile.
    """
    from ..runs import execute_controller

    ctrl = load_exported(folder)
    kind = (run.design.spec or {}).get("kind")
    if kind is not None and kind != ctrl.kind:
        raise InputError(f"{folder} holds an exported {ctrl.kind} controller ({ctrl.name!r}), but the command names "
                         f"a {kind} controller ({run.design.label}): export that one, or name the exported kind",
                         field="exported")
    ratio = ctrl.manifest.get("ratio")
    if ratio is not None and not math.isclose(float(ratio), run.plant.gear_ratio, rel_tol=1e-9):
        # a controller exported for another gear ratio reads the motor encoder through the wrong ratio (a review
        # ran a pair's export on a ratio-5 train: 0.013 rad RMS, no warning)
        raise InputError(f"{folder} holds a controller exported for gear ratio {float(ratio):.10g} (model "
                         f"{ctrl.manifest.get('model')!r}); this plant's ratio is {run.plant.gear_ratio:.10g}: export "
                         f"it for this model", field="exported")
    return execute_controller(run, ctrl, keep=keep, progress=progress)
