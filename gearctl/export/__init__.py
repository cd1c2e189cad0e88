"""Embedded export: every catalog controller as self-contained C99, software in the loop, a compiled batch loop.

- :func:`export_controller` writes a folder of C99 sources with the fixed API of ``gearctl_ctrl.h``
  (``gearctl_ctrl_init``, ``gearctl_ctrl_step``), the parameters as ``static const`` tables read off the
  Python object, the QP solver for the MPC (gearctl's own, the one the Python MPC runs), a Makefile
  (``make``, ``make check``, ``make bench``) and test vectors recorded from the Python controller
  (:mod:`gearctl.export.emit`).
- :func:`load_exported` compiles such a folder and returns its C as a :class:`~gearctl.controller.Controller`
  for gearctl's closed loop (:mod:`gearctl.export.sil`).
- :func:`run_compiled` runs a whole closed loop of a linear controller in C, kernel and controller
  together (:mod:`gearctl.export.batch`), equal to :func:`gearctl.runs.execute`.
- :func:`export_timing`: the step times for ``gearctl perf`` (:mod:`gearctl.export.timing`).

Each kind's C (``csrc/gcx_pid.c``, ``csrc/gcx_mpc.c``) mirrors its Python methods line by line, so that the
exported controller gives the Python controller's torques bit for bit: the PID family computes in scalars,
and the MPC forms its QP data with :func:`gearctl.qp.matvec_function` (rows summed in index order, as the C
does) instead of numpy's BLAS.
"""

from __future__ import annotations

from typing import Any

__all__ = ["export_controller", "load_exported", "run_compiled", "export_timing", "ExportedController",
           "ExportInfo", "compiled_kinds"]

_LAZY = {"export_controller": "emit", "ExportInfo": "emit", "load_exported": "sil", "ExportedController": "sil",
         "run_compiled": "batch", "compiled_kinds": "batch", "export_timing": "timing"}


def __getattr__(name: str) -> Any:
    """Import the parts on first use (the batch loop loads the kernel; the rest does not need it)."""
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
