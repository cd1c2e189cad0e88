"""The exported controller refuses x87 excess precision (FLT_EVAL_METHOD 2) at compile time.

Where double expressions are evaluated in 80-bit registers (32-bit x86 without ``-mfpmath=sse``, gcc's
``-mfpmath=387``) the torques are no longer the Python controller's: ``make check`` with ``CFLAGS='-O2 -mfpmath=387'``
found 3471 of 4000 steps of ``shing1993_servo``'s dead-zone inverse off by up to 7.8e-6 relative and FAILED, after a
build that said nothing. The library already refuses doubles that are not IEEE binary64; it now refuses this too,
naming FLT_EVAL_METHOD and the flags that fix it. Oracle: the compiler's own FLT_EVAL_METHOD under the flag.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from gearctl.catalog import load_controller, load_model
from gearctl.export import export_controller
from gearctl.plant import build_plant

X87 = ["-std=c99", "-O2", "-mfpmath=387"]
PROBE = "#include <float.h>\n#if FLT_EVAL_METHOD != 2\n#error not x87\n#endif\nint gcx_probe;\n"


def _export(tmp_path: Path, ctrl: str) -> Path:
    m = load_model("shing1993_servo")
    plant = build_plant(m)
    d = tmp_path / ctrl
    export_controller(load_controller(ctrl, plant), d, plant=plant, sensors=m.sensors, model=m.name, vectors=False)
    return d


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
@pytest.mark.parametrize("ctrl", ["pid", "deadzone_inverse", "mpc"])
def test_an_x87_build_is_refused_naming_flt_eval_method(tmp_path: Path, ctrl: str) -> None:
    probe = tmp_path / "probe.c"
    probe.write_text(PROBE)
    if subprocess.run(["gcc", *X87, "-c", str(probe), "-o", str(tmp_path / "probe.o")],
                      capture_output=True, timeout=120).returncode != 0:
        pytest.skip("gcc here has no x87 double arithmetic (-mfpmath=387 with FLT_EVAL_METHOD 2)")
    d = _export(tmp_path, ctrl)
    proc = subprocess.run(["gcc", *X87, f"-I{d}", "-c", str(d / "gearctl_ctrl.c"), "-o", str(tmp_path / "c.o")],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode != 0, "an x87 build compiled: its torques are not the Python controller's"
    assert "FLT_EVAL_METHOD" in proc.stderr and "-mfpmath=sse" in proc.stderr, proc.stderr
    # the same source without the flag builds as before
    ok = subprocess.run(["gcc", "-std=c99", "-O2", f"-I{d}", "-c", str(d / "gearctl_ctrl.c"), "-o",
                         str(tmp_path / "c.o")], capture_output=True, text=True, timeout=600)
    assert ok.returncode == 0, ok.stderr
