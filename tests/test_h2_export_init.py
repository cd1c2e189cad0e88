"""The exported C on an instance that ``gearctl_ctrl_init`` never set up (issue 14's API, the order of calls).

A firmware's ``static gearctl_ctrl_t c;`` is all zeros, not initialised. Before, a step on it ran with status OK: the
dead-zone inverse's zero backlash estimate made it a plain PID (a harness's sine: 6.6e-4 rad RMS against 7.2e-6
after init, every step OK), the MPC latched its fault after 5 steps. Now such a step is refused with
``GEARCTL_STEP_NOT_INIT``, ``u = 0`` and the instance left as it was, whether it holds zeros or garbage.

Oracles: the header's own macros and the instance's bytes before and after the refused step, and a run after init
against a second, never-refused instance (the same torques to the bit).
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
needs_cc = pytest.mark.skipif(CC is None or shutil.which("make") is None, reason="needs a C compiler and make")

_MAIN = r"""
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "gearctl_ctrl.h"

static gearctl_ctrl_t zero; /* static storage: zeros, never initialised */

static void sine(long k, double *y, double *ref)
{
    int i;
    for (i = 0; i < GEARCTL_PREVIEW; i++) {
        double t = (double)(k + i) * GEARCTL_TS;
        ref[3 * i] = 0.1 * sin(6.283185307179586 * t);
        ref[3 * i + 1] = 0.6283185307179586 * cos(6.283185307179586 * t);
        ref[3 * i + 2] = -3.947841760435743 * sin(6.283185307179586 * t);
    }
    y[0] = GEARCTL_RATIO * 0.1 * sin(6.283185307179586 * (double)(k - 2) * GEARCTL_TS);
    y[1] = 0.1 * sin(6.283185307179586 * (double)(k - 2) * GEARCTL_TS);
}

int main(void)
{
    static gearctl_ctrl_t junk, a, b, before;
    double y[2], ref[3 * GEARCTL_PREVIEW], u, ub;
    int st, stb, bad = 0;
    long k;
    memset(&junk, 0xA5, sizeof junk); /* what the stack or uncleared RAM may hold */
    sine(0, y, ref);
    /* a zeroed and a garbage instance: refused, u = 0, not a byte changed */
    before = zero;
    u = 7.0;
    st = gearctl_ctrl_step(&zero, y, ref, &u);
    printf("zero %d %d %d\n", st, u == 0.0, memcmp(&before, &zero, sizeof zero) == 0);
    before = junk;
    u = 7.0;
    st = gearctl_ctrl_step(&junk, y, ref, &u);
    printf("junk %d %d %d\n", st, u == 0.0, memcmp(&before, &junk, sizeof junk) == 0);
    /* after init, the refused instance runs as one that was initialised at once */
    gearctl_ctrl_init(&zero);
    gearctl_ctrl_init(&b);
    for (k = 0; k < 500; k++) {
        sine(k, y, ref);
        st = gearctl_ctrl_step(&zero, y, ref, &u);
        stb = gearctl_ctrl_step(&b, y, ref, &ub);
        if (st != stb || st > GEARCTL_STEP_FALLBACK || memcmp(&u, &ub, sizeof u) != 0) bad++;
    }
    /* a copy of an initialised instance is initialised */
    a = b;
    sine(500, y, ref);
    st = gearctl_ctrl_step(&a, y, ref, &u);
    stb = gearctl_ctrl_step(&b, y, ref, &ub);
    printf("init %d copy %d %d\n", bad, st == stb && st <= GEARCTL_STEP_FALLBACK, memcmp(&u, &ub, sizeof u) == 0);
    printf("code %d\n", GEARCTL_STEP_NOT_INIT);
    return 0;
}
"""


@needs_cc
@pytest.mark.parametrize("ctrl", ["pid", "deadzone_inverse", "adaptive_inverse", "mpc"])
def test_a_step_on_an_instance_never_initialised_is_refused(tmp_path: Path, ctrl: str) -> None:
    model = load_model("shing1993_servo")
    plant = build_plant(model)
    d = tmp_path / ctrl
    export_controller(load_controller(ctrl, plant, sensors=model.sensors), d, plant=plant, sensors=model.sensors,
                      model=model.name, vectors=False)
    src = tmp_path / "main.c"
    src.write_text(textwrap.dedent(_MAIN))
    exe = tmp_path / "main"
    sources = [str(p) for p in sorted(d.glob("gearctl_*.c"))]
    proc = subprocess.run([CC, "-std=c99", "-O1", "-Wall", "-Wextra", "-Werror", "-pedantic", f"-I{d}", str(src),
                           *sources, "-lm", "-o", str(exe)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    out = dict((line.split(" ", 1)[0], line.split()[1:]) for line in run.stdout.splitlines())
    code = int(out["code"][0])
    assert code not in (0, 1, 2, 3)  # a status of its own, not one a running controller returns
    assert out["zero"] == [str(code), "1", "1"]
    assert out["junk"] == [str(code), "1", "1"]
    assert out["init"] == ["0", "copy", "1", "1"]
    header = (d / "gearctl_ctrl.h").read_text()
    assert f"#define GEARCTL_STEP_NOT_INIT {code} " in header
    assert "GEARCTL_STEP_NOT_INIT" in (d / "README.md").read_text()


@pytest.mark.parametrize("ctrl", ["pid", "deadzone_inverse", "adaptive_inverse", "reversal_offset", "mpc"])
def test_the_header_promises_only_the_statuses_the_step_returns(ctrl: str) -> None:
    # the PID family's step returns OK, BAD_INPUT or NOT_INIT (its run never flags a fallback): its header listed
    # GEARCTL_STEP_FALLBACK among the returns, which an embedded engineer's harness then handled for nothing
    from gearctl.export.emit import header_text
    from gearctl.export.kinds import kind_spec

    model = load_model("shing1993_servo")
    plant = build_plant(model)
    text = header_text(kind_spec(load_controller(ctrl, plant, sensors=model.sensors)))
    returns = text[text.index("Returns GEARCTL_STEP_OK"):].split("*/")[0]
    if ctrl == "mpc":
        assert "GEARCTL_STEP_FALLBACK" in returns.split(";")[0] and "GEARCTL_STEP_FAULT" in returns
    elif ctrl == "adaptive_inverse":  # a missing load reading (it only measures the gap): test_h5_export_gaps.py
        assert "GEARCTL_STEP_FALLBACK" in returns.split(";")[0] and "GEARCTL_STEP_FAULT" not in returns
    else:
        assert "GEARCTL_STEP_FALLBACK" not in returns.split(";")[0]
        assert "GEARCTL_STEP_BAD_INPUT" in returns and "GEARCTL_STEP_NOT_INIT" in returns
