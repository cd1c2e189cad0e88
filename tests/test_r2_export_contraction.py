"""The exported C gives the Python controller's torques bit for bit under clang on a target with FMA.

README: compiled as ISO C (``-std=c99``, no ``-ffast-math`` or ``-ffp-contract=fast``) the C is bit for bit. GCC's ISO
mode turns contraction off, but clang's default is ``-ffp-contract=on`` in every mode: on a target with fused
multiply-add (x86-64 with ``-march=native``, any AArch64: an Apple M1, a Cortex-A) it fused ``a * b + c`` and
``make check`` found 3439 of 4000 steps off by up to 7e-14 relative. Oracle: the recorded vectors, replayed by the
folder's own ``make check`` with ``CC=clang``, and a probe that shows the compiler does contract there.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from gearctl.catalog import load_controller, load_model
from gearctl.export import export_controller
from gearctl.plant import build_plant

NATIVE = "-O2 -march=native"
PROBE = r"""
#include <stdio.h>
int main(void) {
    volatile double a = 1.0 + 0x1p-30, b = 1.0 - 0x1p-30, c = -1.0;
    double x = a, y = b, z = c;
    printf("%d\n", x * y + z != 0.0); /* 1: fused (a * b is 1 - 2^-60 exactly), 0: rounded first */
    return 0;
}
"""


def _clang_contracts(tmp_path: Path) -> bool:
    src, exe = tmp_path / "probe.c", tmp_path / "probe"
    src.write_text(PROBE)
    proc = subprocess.run(["clang", "-std=c99", *NATIVE.split(), str(src), "-o", str(exe)], capture_output=True,
                          text=True, timeout=120)
    if proc.returncode != 0:
        return False
    return subprocess.run([str(exe)], capture_output=True, text=True, timeout=60).stdout.strip() == "1"


@pytest.mark.skipif(shutil.which("clang") is None or shutil.which("make") is None, reason="needs clang and make")
@pytest.mark.parametrize("ctrl", ["deadzone_inverse", "mpc"])
def test_make_check_is_bit_for_bit_under_clang_with_fma(tmp_path: Path, ctrl: str) -> None:
    if not _clang_contracts(tmp_path):
        pytest.skip("clang -march=native does not fuse multiply-adds on this machine")
    m = load_model("shing1993_servo")
    plant = build_plant(m)
    d = tmp_path / ctrl
    export_controller(load_controller(ctrl, plant), d, plant=plant, sensors=m.sensors, model=m.name)
    proc = subprocess.run(["make", "-s", "-C", str(d), "check", "CC=clang", f"CFLAGS={NATIVE}"], capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "ok, bit for bit" in proc.stdout, proc.stdout + proc.stderr
