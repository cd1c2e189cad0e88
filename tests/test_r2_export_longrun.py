"""The exported C in long runs and at the edges of its documented API, driven by a harness that knows only the README.

Oracles: an independent C plant (``tests/data/r2_longrun/harness.c``: dead-zone springs, RK4, gearctl's encoder
quantisation) closing the loop on the documented API alone; the same run from a fresh clock and a zero at the origin
(a clock past 2^31 samples, a zero 1e9 rad away must track as well); a freshly initialised instance (init called again,
init after the MPC's latched fault: byte for byte the same torques); the compilers' own warnings.
"""

from __future__ import annotations

import shutil
import subprocess
import textwrap
from pathlib import Path

import pytest

from gearctl.build import c_compiler
from gearctl.catalog import load_controller, load_model
from gearctl.export import export_controller
from gearctl.plant import build_plant

CC = c_compiler()
needs_cc = pytest.mark.skipif(CC is None, reason="needs a C compiler")
SERVO = "shing1993_servo"
HARNESS = Path(__file__).parent / "data" / "r2_longrun" / "harness.c"
STRICT = ["-std=c99", "-pedantic", "-Wall", "-Wextra", "-Wconversion", "-Wshadow", "-Werror"]


def _export(tmp_path: Path, ctrl: str, model: str = SERVO) -> Path:
    m = load_model(model)
    plant = build_plant(m)
    d = tmp_path / f"export_{ctrl}"
    export_controller(load_controller(ctrl, plant), d, plant=plant, sensors=m.sensors, model=m.name, vectors=False)
    return d


def _plant_header(model: str, path: Path) -> None:
    """plant_params.h for the harness, from the model's plant (no value typed again)."""
    m = load_model(model)
    p = build_plant(m)
    wmax = max((s.k * (s.rb1 ** 2 / p.shafts[i].J + s.rb2 ** 2 / p.shafts[i + 1].J)) ** 0.5
               for i, s in enumerate(p.stages))

    def table(name: str, values: list[float]) -> str:
        return f"static const double {name}[] = {{{', '.join(repr(float(v)) for v in values)}}};\n"

    path.write_text(
        f"#define NS {p.n_stages}\n#define WMAX {wmax!r}\n#define LOAD_TORQUE {float(p.load_torque)!r}\n"
        f"#define CPR_M {m.sensors.motor_encoder_cpr or 0}\n#define CPR_L {m.sensors.load_encoder_cpr or 0}\n"
        + table("PJ", [s.J for s in p.shafts]) + table("PD", [s.d for s in p.shafts])
        + "".join(table(f"P_{k}", [getattr(s, k) for s in p.stages]) for k in ("rb1", "rb2", "backlash", "k", "c")))


def _build_harness(tmp_path: Path, d: Path, model: str = SERVO, flags: tuple[str, ...] = ()) -> Path:
    inc = tmp_path / f"inc_{d.name}"
    inc.mkdir(exist_ok=True)
    _plant_header(model, inc / "plant_params.h")
    exe = tmp_path / f"harness_{d.name}"
    sources = [str(p) for p in sorted(d.glob("gearctl_*.c"))]
    proc = subprocess.run([CC, "-std=c99", "-O2", *flags, f"-I{d}", f"-I{inc}", str(HARNESS), *sources, "-lm",
                           "-o", str(exe)], capture_output=True, text=True, timeout=600)
    if proc.returncode != 0 and "sanitize" in proc.stderr:
        pytest.skip(f"{CC} lacks {flags}")
    assert proc.returncode == 0, proc.stderr
    return exe


def _run(exe: Path, *args: object, timeout: float = 600) -> dict[str, float]:
    proc = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, (proc.returncode, proc.stdout, proc.stderr)  # a sanitizer's trap: SIGILL
    words = proc.stdout.split()
    return {words[i]: float(words[i + 1]) for i in range(0, len(words), 2)}


# ---- the bundle's own code under the strict warnings an outside harness builds with ----

def _compilers() -> list[str]:
    return [cc for cc in ("gcc", "clang") if shutil.which(cc)]


@pytest.mark.parametrize("cc", _compilers() or [pytest.param("cc", marks=pytest.mark.skip(reason="no gcc or clang"))])
@pytest.mark.parametrize("ctrl", ["pid", "deadzone_inverse", "adaptive_inverse", "reversal_offset", "mpc"])
def test_the_bundle_compiles_without_a_warning_under_strict_flags(tmp_path: Path, cc: str, ctrl: str) -> None:
    # -Wconversion and -Wshadow are not in the Makefile's CFLAGS; a harness that adds them (and -Werror) must still
    # build the controller, its QP solver, and the Makefile's own check and bench programs
    d = _export(tmp_path, ctrl)
    for src in sorted(d.glob("*.c")):
        extra = ["-D_POSIX_C_SOURCE=199309L"] if src.name == "bench.c" else []
        proc = subprocess.run([cc, *STRICT, "-O2", *extra, f"-I{d}", "-c", str(src), "-o", str(tmp_path / "x.o")],
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0 and "warning" not in proc.stderr, (src.name, proc.stderr)


# ---- long runs: the clock past 2^31 samples, a zero far away ----

@needs_cc
@pytest.mark.slow
def test_a_clock_past_2_to_the_31_samples_tracks_as_a_fresh_one(tmp_path: Path) -> None:
    # 2^31 + 7 bad-input steps advance the clock k (an int64) cheaply: 25 days at 1 kHz. The dead-zone inverse keeps
    # absolute times (its ramps, the crossing's end), now near 2.1e6 s; the sine after them must track as from a
    # fresh clock, and no int may overflow on the way (trapped by the sanitizer where the compiler has it)
    d = _export(tmp_path, "deadzone_inverse")
    exe = _build_harness(tmp_path, d, flags=("-fsanitize=signed-integer-overflow",
                                             "-fsanitize-undefined-trap-on-error"))
    fresh = _run(exe, 20000, "sine", 0)
    late = _run(exe, 20000, "sine", 0, 0, 2 ** 31 + 7, timeout=1200)
    assert late["k"] == 2 ** 31 + 7 + 20000
    assert late["ok"] == fresh["ok"] == 20000
    assert late["rms_last"] <= 1.3 * fresh["rms_last"], (late, fresh)
    assert fresh["rms_last"] < 2e-5  # the inverse's figure (the PID's on this sine: 6.5e-4 rad)


@needs_cc
@pytest.mark.parametrize("ctrl", ["deadzone_inverse", "mpc"])
def test_a_zero_1e9_rad_away_tracks_as_at_the_origin(tmp_path: Path, ctrl: str) -> None:
    # README: a zero far away tracks as well as at 0, up to 1e9 rad at the load (4e9 rad at the motor, where a
    # double's spacing is a twelfth of a 2^20-count encoder's count); the readings are quantised in long double
    d = _export(tmp_path, ctrl)
    exe = _build_harness(tmp_path, d)
    at_0 = _run(exe, 20000, "sine", 0)
    far = _run(exe, 20000, "sine", 1e9)
    assert far["ok"] == 20000 and far["beyond"] == 0
    assert far["rms_last"] <= 1.6 * at_0["rms_last"] + 2e-6, (far, at_0)


# ---- the documented API's edges: init again, init after a fault ----

EDGE = r"""
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include "gearctl_ctrl.h"

static void sample(int64_t k, double *y, double *ref) {
    for (int j = 0; j < GEARCTL_PREVIEW; j++) {
        double t = (double)(k + j) * GEARCTL_TS, w = 6.283185307179586;
        ref[3 * j] = 0.1 * sin(w * t), ref[3 * j + 1] = 0.1 * w * cos(w * t);
        ref[3 * j + 2] = -0.1 * w * w * sin(w * t);
    }
    double t = (double)k * GEARCTL_TS;
    y[1] = 0.1 * sin(6.283185307179586 * (t - 0.002)), y[0] = GEARCTL_RATIO * y[1];
}

/* a (init again), b (fresh): the same readings must give the same torques to the bit */
static int same_as_fresh(gearctl_ctrl_t *a, gearctl_ctrl_t *b) {
    double y[2], ref[3 * GEARCTL_PREVIEW], ua, ub;
    gearctl_ctrl_init(a);
    gearctl_ctrl_init(b);
    if (memcmp(a, b, sizeof *a) != 0) return 1;
    for (int64_t k = 0; k < 3000; k++) {
        sample(k, y, ref);
        int sa = gearctl_ctrl_step(a, y, ref, &ua), sb = gearctl_ctrl_step(b, y, ref, &ub);
        if (sa != sb || memcmp(&ua, &ub, sizeof ua) != 0 || sa == GEARCTL_STEP_FAULT) return 2;
    }
    return 0;
}

int main(void) {
    static gearctl_ctrl_t a, b;
    double y[2], ref[3 * GEARCTL_PREVIEW], u;
    int faults = 0;
    gearctl_ctrl_init(&a);
    for (int64_t k = 0; k < 777; k++) sample(k, y, ref), gearctl_ctrl_step(&a, y, ref, &u);
    int again = same_as_fresh(&a, &b);
    /* a motor reading that jumps by 0.05 rad every 50 samples: the MPC latches its fault */
    gearctl_ctrl_init(&a);
    for (int64_t k = 0; k < 5000; k++) {
        double yj[2] = {(k / 50 % 2) ? 0.05 : -0.05, 0.0}, r0[3 * GEARCTL_PREVIEW] = {0};
        faults += gearctl_ctrl_step(&a, yj, r0, &u) == GEARCTL_STEP_FAULT;
    }
    int after_fault = same_as_fresh(&a, &b);
    printf("%d %d %d\n", again, faults, after_fault);
    return 0;
}
"""


@needs_cc
@pytest.mark.parametrize("ctrl", ["pid", "adaptive_inverse", "mpc"])
def test_init_again_and_init_after_a_fault_give_a_fresh_instance(tmp_path: Path, ctrl: str) -> None:
    d = _export(tmp_path, ctrl)
    src = tmp_path / "edge.c"
    src.write_text(textwrap.dedent(EDGE))
    exe = tmp_path / "edge"
    sources = [str(p) for p in sorted(d.glob("gearctl_*.c"))]
    proc = subprocess.run([CC, "-std=c99", "-O2", f"-I{d}", str(src), *sources, "-lm", "-o", str(exe)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    again, faults, after_fault = map(int, run.stdout.split())
    assert again == 0 and after_fault == 0, run.stdout
    if ctrl == "mpc":
        assert faults > 4000  # latched, every step until init
