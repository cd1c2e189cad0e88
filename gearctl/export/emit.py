"""Writing an exported controller: C99 sources, the header of the fixed API, a Makefile, test vectors.

The folder :func:`export_controller` writes::

    gearctl_ctrl.h          the API (GEARCTL_TS, GEARCTL_PREVIEW, gearctl_ctrl_t, gearctl_ctrl_init/step)
    gearctl_ctrl.c          the controller (the kind's C, mirroring the Python methods)
    gearctl_ctrl_params.h   its parameters: static const tables read off the Python object
    gearctl_qp.c/.h         the QP solver (MPC only): gearctl's own, the one the Python MPC calls
    LICENSE                 gearctl's licence (MIT), which covers every C file here
    Makefile                make: libgearctl_ctrl.a; make check: replay the vectors; make bench: step times
    check.c, bench.c        the programs of make check / make bench (they use stdio; the library does not)
    gearctl_vectors.h       their readers of the test vectors' file
    gearctl_vectors.bin     test vectors recorded from the Python controller in the closed loop
    controller.json         what was exported (kind, settings, Ts, preview, file digests, table sizes)
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.metadata
import json
import math
import re
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from ..controller import Controller
from ..design.mpc import INPUT_LIMIT
from ..errors import InputError
from .cstruct import c_array, c_double
from .kinds import CSRC, KindSpec, defines, kind_spec, kind_structs, source_text
from .rows import VECTORS_FILE, record_cases, write_vectors

__all__ = ["export_controller", "ExportInfo", "license_text", "header_text", "source_files", "FORMAT"]

#: The manifest's format tag.
FORMAT = "gearctl-export/1"
#: Compiler flags the exported code is meant for: ISO C, so no floating-point contraction (the torques
#: then equal the Python controller's bit for bit, which make check verifies).
CFLAGS = "-std=c99 -O2"
#: The prefix of the exported names (``gearctl_ctrl_step``, ``GEARCTL_TS``, the file names).
DEFAULT_PREFIX = "gearctl"


@dataclasses.dataclass(frozen=True)
class ExportInfo:
    """What :func:`export_controller` wrote.

    Attributes
    ----------
    path : Path
        The folder.
    kind : str
        Controller kind.
    files : list of str
        The files written.
    table_bytes : int
        Constant parameter data (struct and tables) [bytes].
    vector_steps : int
        Steps recorded in the test vectors (0 without).
    prefix : str
        Prefix of the exported names.
    warnings : tuple of str
        What was wrong with the recorded closed loops (saturation, a limit cycle, ...): the controller is
        exported as it is, and these say it does not serve this plant well.
    """

    path: Path
    kind: str
    files: list[str]
    table_bytes: int
    vector_steps: int
    prefix: str = DEFAULT_PREFIX
    warnings: tuple[str, ...] = ()


def license_text() -> str:
    """gearctl's licence (a source checkout's LICENSE, or the installed distribution's copy).

    Notes
    -----
    The folder above the package is a gearctl checkout only if its ``pyproject.toml`` names the project
    gearctl: installed, that folder is ``site-packages``, where a ``LICENSE`` (if any) is another package's.
    The text found must be the MIT licence the exported files' SPDX headers name.

    Raises
    ------
    InputError
        If neither can be found, or the one found is not the MIT licence (a broken installation).
    """
    text = None
    root = Path(__file__).resolve().parents[2]
    try:
        project = tomllib.loads((root / "pyproject.toml").read_text()).get("project", {})
    except (OSError, ValueError):
        project = {}
    if project.get("name") == "gearctl" and (root / "LICENSE").is_file():
        text = (root / "LICENSE").read_text()
    else:
        try:
            dist = importlib.metadata.distribution("gearctl")
            for f in dist.files or ():
                if f.name.upper().startswith(("LICENSE", "LICENCE")):
                    text = f.read_text()
                    break
        except importlib.metadata.PackageNotFoundError:
            pass
    if text is None:
        raise InputError("gearctl's LICENSE file is not found (reinstall gearctl): the exported sources must carry it",
                         field="license")
    if "Permission is hereby granted, free of charge" not in text:  # the MIT licence's grant
        raise InputError(f"gearctl's LICENSE file ({text.strip()[:40]!r}...) is not the MIT licence the exported "
                         "sources name (reinstall gearctl)", field="license")
    return text


def _state_type(spec: KindSpec) -> str:
    return f"gcx_{spec.prefix}_s"


#: The MPC header's word on a load reading that no gap explains (:attr:`gearctl.design.mpc.MPC.gap_limit`).
_GAP_RULE = (" * A load reading whose gap from the motor's (rb1 y[0] - rb2 y[1] along the line of action) exceeds\n"
             " * the MPC's gap limit (2.5 b, four mesh deflections under the torque limit, the contact tolerance and\n"
             " * a count and six noise stds of each encoder) is taken as wrong (zeroed off, or broken): the step runs\n"
             " * on the motor encoder alone and returns GEARCTL_STEP_FALLBACK.\n")


#: Where the PID family's kinds keep their PID state (the measurement filter a missed sample leaves behind).
_PID_STATE = {"pid": "c->s", "rev": "c->s.pid", "inv": "c->s.pid", "ada": "c->s.inv.pid"}


def _k_ran_field(spec: KindSpec) -> str:
    """The PID family's clock of the last step that ran (a bad input's step does not): the gap it spans."""
    if spec.prefix not in _PID_STATE:
        return ""
    return ("    int64_t k_ran; /* the clock k of the last step that ran (-1 before the first; a bad input's does"
            " not) */\n")


def _gap_reading_only(spec: KindSpec) -> bool:
    """The adaptive inverse on the motor encoder: it reads the load encoder only to measure the gap."""
    return spec.prefix == "ada" and not spec.values["inv"]["pid"]["feedback_load"]


def header_text(spec: KindSpec) -> str:
    """``gearctl_ctrl.h``: the API of issue 14, with this controller's constants and state.

    Parameters
    ----------
    spec : KindSpec
        What the controller exports (:func:`~gearctl.export.kinds.kind_spec`).

    Returns
    -------
    str
        The header's text.
    """
    from .. import __version__

    state = source_text("gcx_state.h")
    if spec.prefix == "mpc":
        state += source_text("gcx_mpc_state.h")
    load = int(spec.uses_load_encoder)
    returns = ("GEARCTL_STEP_OK, GEARCTL_STEP_BAD_INPUT or GEARCTL_STEP_NOT_INIT\n"
               " * (c never set up by gearctl_ctrl_init); GEARCTL_STEP_FALLBACK and _FAULT are the MPC's")
    if spec.prefix == "mpc":
        returns = ("GEARCTL_STEP_OK, GEARCTL_STEP_FALLBACK, GEARCTL_STEP_BAD_INPUT,\n"
                   " * GEARCTL_STEP_FAULT (the latched fault) or GEARCTL_STEP_NOT_INIT (c never set up by"
                   " gearctl_ctrl_init)")
    statuses = "GEARCTL_STEP_OK, _FALLBACK, _BAD_INPUT, _FAULT or _NOT_INIT" if spec.prefix == "mpc" else \
        "GEARCTL_STEP_OK, _BAD_INPUT or _NOT_INIT"
    if _gap_reading_only(spec):
        returns = ("GEARCTL_STEP_OK, GEARCTL_STEP_FALLBACK (a missing load reading),\n"
                   " * GEARCTL_STEP_BAD_INPUT or GEARCTL_STEP_NOT_INIT (c never set up by gearctl_ctrl_init)")
        statuses = "GEARCTL_STEP_OK, _FALLBACK, _BAD_INPUT or _NOT_INIT"
    if not spec.uses_load_encoder:
        load_rule = ""
    elif _gap_reading_only(spec):
        load_rule = (" (a y[1] not finite or beyond it\n * is a missing load reading: it only measures the gap, so "
                     "the step runs on\n * the motor encoder, learns nothing from it and returns"
                     " GEARCTL_STEP_FALLBACK)")
    elif spec.prefix == "mpc":
        load_rule = (" (a y[1] not finite or beyond it\n * is a missing load reading: the observer predicts over "
                     "it and the step returns\n * GEARCTL_STEP_FALLBACK)")
    else:
        load_rule = ", or such a y[1] (the load\n * encoder is used)"
    wild = (" * as missed: the clock k still advances). A finite reading whose distance from its predicted angle\n"
            " * moves by more than the MPC's gate (one sample of full torque, twice the lost motion and two counts of\n"
            " * the encoder, with its noise) from the last accepted reading's is rejected: the step runs on the\n"
            " * prediction, returns GEARCTL_STEP_FALLBACK;\n"
            " * one that persists 5 samples restarts the estimate.\n"
            + (_GAP_RULE if spec.uses_load_encoder else "")
            if spec.prefix == "mpc" else
            " * as missed: the clock k still advances). A wild reading within the limit is the caller's to\n"
            " * screen: the integral action is bounded (twice the torque limit), but the measurement filter decays\n"
            " * it over samples (one reading of 1e6 rad: 0.11 s on the torque limit; 1e12 rad: about 0.35 s).\n"
            " * The next step that runs spans the missed samples: the derivative takes the measurement's mean speed\n"
            " * over the gap, not its whole displacement in one sample (before, a kick: one missed reading tripled\n"
            " * the torque, 50 missed ones put it on the limit). The inverses' load observer predicts over the\n"
            " * missed samples with the zero torque the step wrote.\n")
    return f"""/* gearctl_ctrl.h -- exported controller "{spec.name}" (kind {spec.kind}),
 * generated by gearctl {__version__}. SPDX-License-Identifier: MIT (see LICENSE)
 *
 *   gearctl_ctrl_t c;                          all state; statically allocatable, any number of instances
 *   gearctl_ctrl_init(&c);                     the state after Controller.reset()
 *   every GEARCTL_TS seconds:
 *       double y[2] = {{motor_angle, load_angle}};     [rad]; y[1] = NAN when the controller uses no load encoder
 *       double ref[3 * GEARCTL_PREVIEW];          rows (r, r', r'') of the load-angle reference at t, t + Ts, ...
 *       double u;                                  the motor torque [N m]
 *       int status = gearctl_ctrl_step(&c, y, ref, &u);   {statuses}
 *
 * Signals. y[0] is the motor shaft's angle (before the gears), y[1] the load shaft's, both in radians from
 * the same zero as the reference, counted positive the way the motor's positive torque turns them (flip an
 * encoder that counts the other way); in contact the motor turns GEARCTL_RATIO times the load's angle. ref
 * holds the load angle's reference: r [rad], r' [rad/s], r'' [rad/s^2] at t, t + Ts, ... The torque u is
 * the motor shaft's, already clipped to +-GEARCTL_TORQUE_LIMIT: a clipped torque is exactly +-the limit, and
 * the status does not report it (compare |u| with the limit to count saturated steps). The angles are
 * multi-turn: a single-turn encoder's wrap (a jump of 2 pi) is not detected but taken as motion (the PIDs
 * then drive the load away with status OK; the MPC faults): unwrap it before the step. Large angles are
 * fine while a double's spacing at the motor angle is well under an encoder count: keep |y[0]| under about
 * 6e14 counts (a zero 1e9 rad away at the load tracked as at 0 with 2^20 counts/rev; 1e11 rad lost 80x).
 * Every interval is taken to be GEARCTL_TS: latch the encoders and apply u on a timer's tick (a call
 * interval varying by +-1 % at random made the inverses 53x worse; the PIDs did not change).
 *
 * Bad input. A y[0] or reference entry not finite or beyond GEARCTL_INPUT_LIMIT{load_rule}: the step returns
 * GEARCTL_STEP_BAD_INPUT, writes u = 0 and leaves the state as it was (the sample counts
{wild} *
 * The step is the Python controller's step at t = k * GEARCTL_TS, k the number of steps since init. No
 * dynamic memory, no I/O, no writable globals; only <math.h>, <string.h>, <stdint.h>, <float.h> (a compile-time
 * check of IEEE doubles, without x87 excess precision). Reentrant: distinct instances may be stepped at once
 * from different threads or interrupts (they share nothing); one instance must not be entered twice at once
 * (there is no lock). RAM: sizeof(gearctl_ctrl_t) per instance, the parameters being static const. No recursion
 * and no variable-length array: the stack is bounded (gcc 12 -O2 -fcallgraph-info=su, x86-64: the PID 16 B, the
 * inverses about 0.5 kB, the MPC about 1.3 kB; measure on the target). Compile as ISO C
 * (e.g. {CFLAGS}, without -ffast-math or -ffp-contract=fast) to get the Python controller's torques
 * bit for bit; `make check` replays the recorded vectors and says whether they are (a compiler that fuses
 * multiply-adds, e.g. -ffp-contract=fast -march=native, gives 1e-13 relative or so, which it accepts up to 1e-9).
 */
#ifndef GEARCTL_CTRL_H
#define GEARCTL_CTRL_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {{
#endif

#define GEARCTL_TS {c_double(spec.Ts)} /* sample period [s] */
#define GEARCTL_PREVIEW {spec.preview} /* number of reference samples the step reads (>= 1) */
#define GEARCTL_USES_LOAD_ENCODER {load} /* 0: y[1] is not read (pass NAN) */
#define GEARCTL_RATIO {c_double(spec.ratio)} /* motor angle per load angle in contact (the gear ratio) */
#define GEARCTL_TORQUE_LIMIT {c_double(spec.torque_limit)} /* |u| never exceeds it [N m] */

#define GEARCTL_INPUT_LIMIT {INPUT_LIMIT:g} /* |y|, |r|, |r'|, |r''| beyond it (or not finite) are a bad input */

#define GEARCTL_STEP_OK 0        /* a normal step */
#define GEARCTL_STEP_FALLBACK 1  /* the MPC: its solver failed, or a reading was missing or rejected (the step ran on
                                    the prediction); the adaptive inverse: a missing load reading (no gap measured) */
#define GEARCTL_STEP_BAD_INPUT 2 /* an input not finite or beyond GEARCTL_INPUT_LIMIT: u = 0, the state unchanged
                                    but for the clock k, which advances */
#define GEARCTL_STEP_FAULT 3     /* the MPC's latched fault (its estimate restarted 3 times within 1000 samples):
                                    the motor braked to rest from its own reading (the speed its changes give,
                                    damped with a 20 ms time constant, within the torque limit), then u = 0 once
                                    the reading has stood still for 0.1 s, on every step until gearctl_ctrl_init.
                                    A reading that keeps jumping keeps the brake acting on what it reads. A bad
                                    input during the fault returns it too, with u = 0 */
#define GEARCTL_STEP_NOT_INIT 4  /* c was never set up by gearctl_ctrl_init (a static instance holds zeros, which
                                    are no initialised state): u = 0, c unchanged (its clock too) */

/* ---- internal sizes and state types (read them if you like; never write them) ---- */
{defines(spec.dims)}{state}
/* ---- the API ---- */

typedef struct {{
    int64_t k;     /* steps since gearctl_ctrl_init: the step's sample time is k * GEARCTL_TS */
{_k_ran_field(spec)}    uint64_t ready; /* set by gearctl_ctrl_init; a step on an instance without it is refused */
    {_state_type(spec)} s; /* the controller's state */
}} gearctl_ctrl_t;

/* Reset to the state after Controller.reset(). */
void gearctl_ctrl_init(gearctl_ctrl_t *c);

/* One sample: y[0] motor shaft angle, y[1] load shaft angle (NAN when unused) [rad]; ref: GEARCTL_PREVIEW
 * rows of (r, r', r'') of the load-angle reference at t, t + Ts, ... [rad, rad/s, rad/s^2]; *u: motor torque
 * [N m], |u| <= GEARCTL_TORQUE_LIMIT. Returns {returns}. */
int gearctl_ctrl_step(gearctl_ctrl_t *c, const double y[2], const double *ref, double *u);

#ifdef __cplusplus
}}
#endif

#endif /* GEARCTL_CTRL_H */
"""


def _implementation(spec: KindSpec) -> str:
    """``gearctl_ctrl.c``."""
    mpc = spec.prefix == "mpc"
    # the MPC takes a load reading beyond the limit as missing, and so does the adaptive inverse on the motor encoder,
    # which reads it only to measure the gap (gcx_ada_run)
    check_load = spec.uses_load_encoder and not mpc and not _gap_reading_only(spec)
    load_screen = " || !gcx_finite(y[1]) || fabs(y[1]) > GEARCTL_INPUT_LIMIT" if check_load else ""
    # the MPC's latched fault is reported on every step, a bad input's too (its torque is zero either way)
    bad_status = "c->s.fault ? GEARCTL_STEP_FAULT : GEARCTL_STEP_BAD_INPUT" if mpc else "GEARCTL_STEP_BAD_INPUT"
    # the PID family after missed samples: its measurement filter spans the gap (gcx_pid_torque); the MPC's missed
    # sample is the Python MPC's own (MPC.step), predicted over by its observer
    pid = _PID_STATE.get(spec.prefix)
    init_k_ran = "    c->k_ran = -1;\n" if pid else ""
    gap_in = (f"    if (c->k_ran >= 0 && c->k - c->k_ran > 1) {pid}.gap = (double)(c->k - c->k_ran - 1);\n"
              if pid else "")
    gap_out = f"    {pid}.gap = 0.0;\n    c->k_ran = c->k;\n" if pid else ""
    parts = [
        f"/* gearctl_ctrl.c -- exported controller \"{spec.name}\" (kind {spec.kind}): the kind's C, which mirrors\n"
        " * gearctl's Python methods line by line. SPDX-License-Identifier: MIT (see LICENSE) */\n",
        '#include "gearctl_ctrl.h"\n\n#include <math.h>\n#include <string.h>\n',
        '#include "gearctl_qp.h"\n' if mpc else "",
        "\n/* ---- parameter structs (generated by gearctl/export/kinds.py) ---- */\n",
        kind_structs(["mpc"] if mpc else ["pid", "rev", "inv", "ada"]),  # the family's C needs them all
        "\n",
        source_text("gcx_common.c"),
        source_text("gcx_mpc.c") if mpc else source_text("gcx_pid.c"),
        "\n/* ---- this controller's parameters ---- */\n",
        '#include "gearctl_ctrl_params.h"\n',
        f"""
/* ---- the API ---- */

/* gearctl_ctrl_t.ready of an initialised instance: neither zeros (static storage) nor a repeated byte */
#define GCX_READY 0x6763785f72656479ULL

void gearctl_ctrl_init(gearctl_ctrl_t *c) {{
    memset(c, 0, sizeof *c);
    gcx_{spec.prefix}_init(&GCX_PARAMS, &c->s);
{init_k_ran}    c->ready = GCX_READY;
}}

int gearctl_ctrl_step(gearctl_ctrl_t *c, const double y[2], const double *ref, double *u) {{
    if (c->ready != GCX_READY) {{ /* never initialised: its state is no controller's */
        *u = 0.0;
        return GEARCTL_STEP_NOT_INIT;
    }}
    /* finiteness first, read off the bits (gcx_finite): no ordered comparison with a NaN (FE_INVALID, a trap where
     * floating-point traps are on), and a check that -ffast-math or -ffinite-math-only cannot remove */
    int i, bad = !gcx_finite(y[0]) || fabs(y[0]) > GEARCTL_INPUT_LIMIT{load_screen};
    for (i = 0; i < 3 * GEARCTL_PREVIEW; i++) bad = bad || !gcx_finite(ref[i]) || fabs(ref[i]) > GEARCTL_INPUT_LIMIT;
    if (bad) {{ /* a missed sample: no update, a zero torque */
        *u = 0.0;
        c->k++;
        return {bad_status};
    }}
{gap_in}    int flag = gcx_{spec.prefix}_run(&GCX_PARAMS, &c->s, c->k, y, ref, u);
{gap_out}    c->k++;
    return flag == 3 ? GEARCTL_STEP_FAULT : flag > 0 ? GEARCTL_STEP_FALLBACK : GEARCTL_STEP_OK;
}}
""",
    ]
    return "".join(parts)


def _readme(spec: KindSpec, vectors: bool) -> str:
    """``README.md`` of the folder: what it is, how to build and call it, the numbers a harness needs."""
    from .. import __version__

    load = "used: pass the load shaft's angle" if spec.uses_load_encoder else "unused: pass NAN"
    vec = ", `gearctl_vectors.bin`" if vectors else ""
    qp = ("- `gearctl_qp.c`, `gearctl_qp.h`: gearctl's dense QP solver (Goldfarb-Idnani), which the Python MPC "
          "calls too\n" if spec.prefix == "mpc" else "")
    check = ("`make check` replays the test vectors recorded from the Python controller in gearctl's closed loop "
             "(a 3 s sine and a move) and prints the largest torque difference: 0 (bit for bit) with the "
             "Makefile's ISO C flags; it accepts 1e-9 of the largest torque (a compiler that fuses multiply-adds "
             "gives about 1e-13). "
             "`make bench` times the step on the same vectors (median and p99).") if vectors else (
             "Exported with `--no-vectors`: there are no test vectors; `make check` and `make bench` say so and exit "
             "with status 2.")
    return f"""# Exported controller `{spec.name}` ({spec.kind})

Generated by gearctl {__version__}. C99, no dynamic memory, no I/O, no writable globals; MIT (see `LICENSE`).

## Build

    make            # libgearctl_ctrl.a; link your program with it and -lm
    make check      # replay the recorded test vectors
    make bench      # time one step

{check}

## Call

```c
#include <math.h> /* NAN, for a load angle the controller does not read */
#include "gearctl_ctrl.h"

static gearctl_ctrl_t ctrl; /* any number of instances; all state is in the struct */

void control_start(void) /* before the first step, and to restart */
{{
    gearctl_ctrl_init(&ctrl);
}}

/* every GEARCTL_TS seconds; ref: (r, r', r'') at t, t + Ts, ..., t + (GEARCTL_PREVIEW - 1) Ts */
double control_step(double motor_angle, double load_angle, const double ref[3 * GEARCTL_PREVIEW], int *status)
{{
    double y[2];
    double u = 0.0;
    y[0] = motor_angle;
    y[1] = load_angle;
    *status = gearctl_ctrl_step(&ctrl, y, ref, &u);
    return u; /* the motor torque [N m], apply it at once */
}}
```

| name | value | meaning |
|---|---|---|
| `GEARCTL_TS` | {spec.Ts:.6g} s | sample period |
| `GEARCTL_PREVIEW` | {spec.preview} | reference rows the step reads |
| `GEARCTL_USES_LOAD_ENCODER` | {int(spec.uses_load_encoder)} | load encoder {load} |
| `GEARCTL_RATIO` | {spec.ratio:.10g} | motor angle per load angle in contact |
| `GEARCTL_TORQUE_LIMIT` | {spec.torque_limit:.6g} N m | the step clips `u` to it |

- `y[0]`: the motor shaft's angle [rad] (before the gears), `y[1]`: the load shaft's [rad], from the zero of
  the reference, positive in the sense the motor's positive torque turns them.
- `ref`: the load angle's reference, rows of `r` [rad], `r'` [rad/s], `r''` [rad/s^2].
- `u`: the motor torque [N m].
- `status`: `GEARCTL_STEP_OK` (0); `GEARCTL_STEP_FALLBACK` (1, the MPC: its solver failed, or a reading was missing
  or rejected by its gate and the step ran on the prediction; the adaptive inverse: a missing load reading, no gap
  measured); `GEARCTL_STEP_BAD_INPUT` (2, a `y[0]`, a reference
  entry, or a `y[1]` where the load encoder is fed back, not finite or beyond `GEARCTL_INPUT_LIMIT`; the MPC and the
  adaptive inverse on the motor encoder take such a `y[1]` as a missing reading and return
  `GEARCTL_STEP_FALLBACK`): `u = 0`, the state
  unchanged but for the sample clock, which advances;
  `GEARCTL_STEP_FAULT` (3, the MPC's latched fault: its estimate restarted 3 times within 1000 samples, e.g. encoders
  too coarse to follow, or an encoder that keeps jumping; the motor is braked to rest from its own reading, then
  `u = 0` once the reading has stood still for 0.1 s, until `gearctl_ctrl_init`; a reading that keeps jumping keeps
  the brake acting on what it reads, within the torque limit; a bad input during the fault returns it too, with
  `u = 0`); `GEARCTL_STEP_NOT_INIT` (4, `ctrl` was never set up by `gearctl_ctrl_init`: a static instance holds
  zeros, which are no initialised state; `u = 0`, nothing changed).

The step at sample `k` is the Python controller's step at `t = k * GEARCTL_TS`.

## Files

- `gearctl_ctrl.h`: the API above (and the state types, which are internal)
- `gearctl_ctrl.c`: the controller; `gearctl_ctrl_params.h`: its parameters (static const tables)
{qp}- `Makefile`, `check.c`, `bench.c`, `gearctl_vectors.h`{vec}: build, check, time
- `controller.json`: what was exported (settings, sizes, file digests)
"""


def _params(spec: KindSpec) -> str:
    """``gearctl_ctrl_params.h``: the constant tables and the parameter struct."""
    st = spec.struct
    out = [f"/* gearctl_ctrl_params.h -- parameters of \"{spec.name}\" (kind {spec.kind}), read off the Python\n"
           " * object. SPDX-License-Identifier: MIT (see LICENSE)\n"
           " * Included once, by gearctl_ctrl.c (static const definitions). Doubles are written as their shortest\n"
           " * round-trip decimal, so they parse to the Python values exactly. */\n\n"]
    for arr in spec.arrays:
        out.append(c_array(arr))
        out.append("\n")
    out.append(f"static const {st.name} GCX_PARAMS = {st.c_init(spec.values)};\n")
    return "".join(out)


def _makefile(spec: KindSpec, vectors: bool = True) -> str:
    mpc = spec.prefix == "mpc"
    objs = "gearctl_ctrl.o gearctl_qp.o" if mpc else "gearctl_ctrl.o"
    qp_rule = ("gearctl_qp.o: gearctl_qp.c gearctl_qp.h\n\t$(CC) $(STD) $(CFLAGS) -c gearctl_qp.c -o gearctl_qp.o\n\n"
               if mpc else "")
    deps = "gearctl_ctrl.c gearctl_ctrl.h gearctl_ctrl_params.h" + (" gearctl_qp.h" if mpc else "")
    if vectors:
        run_rules = (f"check: check_vectors\n\t./check_vectors {VECTORS_FILE}\n\n"
                     f"bench: bench_vectors\n\t./bench_vectors {VECTORS_FILE}\n")
    else:
        no = "@echo 'exported with --no-vectors: no test vectors to replay (export again without it)' >&2; exit 2"
        run_rules = f"check:\n\t{no}\n\nbench:\n\t{no}\n"
    return f"""# Exported gearctl controller "{spec.name}" ({spec.kind}). SPDX-License-Identifier: MIT (see LICENSE)
#   make         the static library libgearctl_ctrl.a (link it with -lm)
#   make check   replay the recorded test vectors; print the largest |du| relative (0 expected)
#   make bench   time gearctl_ctrl_step: median and p99 per step
# STD is kept apart from CFLAGS: ISO C (no floating-point contraction) is what makes the torques equal the
# Python controller's bit for bit.
CC ?= cc
AR ?= ar
STD = -std=c99
CFLAGS ?= -O2 -Wall -Wextra -pedantic
LIB = libgearctl_ctrl.a
OBJS = {objs}

all: $(LIB)

$(LIB): $(OBJS)
\t$(AR) rcs $(LIB) $(OBJS)

gearctl_ctrl.o: {deps}
\t$(CC) $(STD) $(CFLAGS) -c gearctl_ctrl.c -o gearctl_ctrl.o

{qp_rule}check_vectors: check.c gearctl_ctrl.h gearctl_vectors.h $(LIB)
\t$(CC) $(STD) $(CFLAGS) check.c $(LIB) -lm -o check_vectors

bench_vectors: bench.c gearctl_ctrl.h gearctl_vectors.h $(LIB)
\t$(CC) $(STD) $(CFLAGS) -D_POSIX_C_SOURCE=199309L bench.c $(LIB) -lm -o bench_vectors

{run_rules}
clean:
\trm -f $(OBJS) $(LIB) check_vectors bench_vectors

.PHONY: all check bench clean
"""


def source_files(spec: KindSpec) -> dict[str, str]:
    """The C sources and the header of an exported controller (file name -> text).

    Parameters
    ----------
    spec : KindSpec
        What the controller exports (:func:`~gearctl.export.kinds.kind_spec`).

    Returns
    -------
    dict of str to str
        ``gearctl_ctrl.h``, ``gearctl_ctrl.c``, ``gearctl_ctrl_params.h``; for an MPC also ``gearctl_qp.h`` and
        ``gearctl_qp.c``.
    """
    files = {"gearctl_ctrl.h": header_text(spec), "gearctl_ctrl.c": _implementation(spec),
             "gearctl_ctrl_params.h": _params(spec)}
    if spec.prefix == "mpc":
        from ..qp import SOURCE_DIR

        for f in ("gearctl_qp.h", "gearctl_qp.c"):
            files[f] = (SOURCE_DIR / f).read_text()
    return files


def _jsonable(v: Any) -> Any:
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_jsonable(x) for x in v]
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None if math.isnan(v) else ("inf" if v > 0 else "-inf")
    if isinstance(v, str | int | float | bool) or v is None:
        return v
    return str(v)


#: Files an export owns: written by one, so removed by the next when it does not write them (a stale
#: gearctl_qp.c of an earlier MPC export, or old vectors, would otherwise be built or replayed). Build products
#: of the Makefile are removed too. ``gearctl`` stands for the export's prefix.
OWNED = ("gearctl_ctrl.h", "gearctl_ctrl.c", "gearctl_ctrl_params.h", "gearctl_qp.h", "gearctl_qp.c",
         "gearctl_vectors.h", "gearctl_vectors.bin", "LICENSE", "Makefile", "check.c", "bench.c", "README.md",
         "controller.json", "gearctl_ctrl.o", "gearctl_qp.o", "libgearctl_ctrl.a", "check_vectors", "bench_vectors")
_PREFIX_RE = re.compile(r"[a-z][a-z0-9_]{0,23}")


def check_prefix(prefix: str) -> str:
    """A valid symbol prefix, or an :class:`InputError` naming the rule."""
    if not isinstance(prefix, str) or not _PREFIX_RE.fullmatch(prefix) or prefix.endswith("_") or "__" in prefix:
        raise InputError(f"prefix = {prefix!r} is not a C name prefix: expected 1 to 24 lower-case letters, digits "
                         "and single underscores, starting with a letter (e.g. axis1)", field="prefix")
    return prefix


def check_name(name: str) -> str:
    """A controller name the exported files can quote, or an :class:`InputError` naming the rule.

    The name goes into the first comment of each C file and of the Makefile: a ``*/`` ended the C comment and a
    line break the Makefile's, so the folder did not build; a ``/*`` is a warning (``-Wcomment``) that fails a
    build with ``-Wall -Werror``.
    """
    if "*/" in name or "/*" in name or any((ord(ch) < 32 and ch != "\t") or ord(ch) == 127 for ch in name):
        raise InputError(f"name = {name!r} cannot be quoted in the exported C and Makefile comments: expected a "
                         "name without '*/', '/*', line breaks or other control characters but tabs (rename it in the "
                         "controller's file)", field="name")
    return name


def prefixed(text: str, prefix: str) -> str:
    """``text`` with gearctl's exported names under another prefix: ``gearctl_ctrl_step`` -> ``axis1_ctrl_step``,
    ``GEARCTL_TS`` -> ``AXIS1_TS``, and the internal ``gcx_`` / ``GCX_`` names -> ``axis1_gcx_`` / ``AXIS1_GCX_``, so
    that controllers of several exports link into one program and their headers go into one file."""
    if prefix == DEFAULT_PREFIX:
        return text
    up = prefix.upper()
    # one pass: a prefix that is itself a name's start (``gcx``, ``gcx_a``) must not be renamed again (it made
    # ``gcx_gcx_ctrl_step`` of ``--prefix gcx``)
    new = {"gearctl_": prefix + "_", "libgearctl_ctrl": f"lib{prefix}_ctrl", "GEARCTL_": up + "_",
           "gcx_": prefix + "_gcx_", "GCX_": up + "_GCX_"}
    return _NAMES_RE.sub(lambda m: new[m.group(1)], text)


#: The names :func:`prefixed` renames: gearctl's API (``gearctl_ctrl...``, ``GEARCTL_...``, ``libgearctl_ctrl``) and
#: the internal ``gcx_`` / ``GCX_`` names.
_NAMES_RE = re.compile(r"\b(gearctl_(?=ctrl|qp|vectors|sil)|libgearctl_ctrl|GEARCTL_|gcx_|GCX_)")


def prefixed_name(name: str, prefix: str) -> str:
    """A file name of the export under ``prefix``."""
    return prefixed(name, prefix) if name.startswith(("gearctl_", "libgearctl_")) else name


def _clear_previous(out: Path, prefix: str, keep: set[str]) -> None:
    """Remove what a previous export into ``out`` owned and this one does not write; refuse a folder holding files
    of those names that no gearctl export wrote (they are the user's)."""
    manifest = out / "controller.json"
    old_prefix = None
    if manifest.is_file():
        try:
            man = json.loads(manifest.read_text())
        except (OSError, ValueError):
            man = {}
        if isinstance(man, dict) and man.get("format") == FORMAT:
            old_prefix = str(man.get("prefix", DEFAULT_PREFIX))
    if old_prefix is None:
        clash = sorted(n for n in keep if (out / n).exists())
        if clash:
            raise InputError(f"{out} holds {', '.join(clash[:4])}{' ...' if len(clash) > 4 else ''} and is not a "
                             "gearctl export (no controller.json of one): choose an empty or new folder", field="out")
        return
    for name in {prefixed_name(n, p) for n in OWNED for p in (old_prefix, prefix)} - keep:  # build products too
        path = out / name
        if path.is_file():
            path.unlink()


def export_controller(controller: Controller, out: str | Path, *, plant: Any = None, sensors: Any = None,
                      vectors: bool = True, seed: int = 0, model: str | None = None,
                      prefix: str = DEFAULT_PREFIX) -> ExportInfo:
    """Export a catalog controller as self-contained C99 (see the module docstring for the files).

    Parameters
    ----------
    controller : Controller
        A controller of one of gearctl's kinds (``pid``, ``reversal_offset``, ``deadzone_inverse``,
        ``adaptive_inverse``, ``mpc``), as built from its file (:func:`gearctl.load_controller`). Its present
        numbers are exported (for the dead-zone inverse, its present backlash estimate).
    out : str or Path
        The folder (created; existing files of the same names are replaced).
    plant : Plant, optional
        The plant the test vectors are recorded on (default: the controller's nominal plant).
    sensors : Sensors, optional
        The encoders of that recording (default: ideal).
    vectors : bool
        Record the test vectors (a 3 s sine and a move, in gearctl's closed loop) for ``make check``.
    seed : int
        Sensor-noise seed of the recording.
    model : str, optional
        The model's name, for the manifest.
    prefix : str
        Prefix of every exported name and file (default ``gearctl``: ``gearctl_ctrl.h``,
        ``gearctl_ctrl_step``, ``GEARCTL_TS``); another (``axis1``) lets several exports link into one program.

    Returns
    -------
    ExportInfo

    Raises
    ------
    InputError
        For a controller that is not one of gearctl's kinds, a bad prefix, a name the C comments cannot quote
        (``*/``, ``/*``, a line break), or a folder that cannot be written or
        holds files of the export's names that no gearctl export wrote. Files a previous export into the folder
        wrote and this one does not are removed.
    """
    check_prefix(prefix)
    spec = kind_spec(controller)
    check_name(spec.name)
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create {out}: {exc.strerror}", field="out") from None
    files = source_files(spec)
    files["LICENSE"] = license_text()
    files["Makefile"] = _makefile(spec, vectors)
    files["README.md"] = _readme(spec, vectors)
    files["check.c"] = (CSRC / "check.c").read_text()
    files["bench.c"] = (CSRC / "bench.c").read_text()
    files["gearctl_vectors.h"] = (CSRC / "gearctl_vectors.h").read_text()
    steps = 0
    cases_info: list[dict[str, Any]] = []
    if vectors:
        info = _design_info(controller)
        cases = record_cases(controller, plant if plant is not None else info.nominal, sensors=sensors, seed=seed)
        steps = sum(c.steps for c in cases)
        cases_info = [{"reference": c.name, "steps": c.steps, "warnings": list(c.warnings)} for c in cases]
    files = {prefixed_name(name, prefix): prefixed(text, prefix) for name, text in files.items()}
    vectors_file = prefixed_name(VECTORS_FILE, prefix)
    digests = {name: hashlib.sha256(text.encode()).hexdigest() for name, text in sorted(files.items())}
    from .. import __version__

    manifest = {
        "format": FORMAT, "gearctl": __version__, "kind": spec.kind, "name": spec.name, "model": model,
        "Ts": spec.Ts, "preview": spec.preview, "uses_load_encoder": spec.uses_load_encoder,
        "cflags": CFLAGS, "table_bytes": spec.table_bytes, "dims": spec.dims,
        "qp_solver": "gearctl_qp (dense Goldfarb-Idnani dual active set, C99, MIT; gearctl/csrc/qp)"
        if spec.prefix == "mpc" else None,
        "vectors": {"file": vectors_file, "cases": cases_info, "seed": seed} if vectors else None,
        "prefix": prefix, "ratio": spec.ratio, "torque_limit": spec.torque_limit,
        "sha256": digests, "describe": spec.describe,
    }
    _clear_previous(out, prefix, {*files, "controller.json", *([vectors_file] if vectors else [])})
    try:
        for name, text in files.items():
            (out / name).write_text(text, encoding="utf-8")  # the bytes the digests are of
        if vectors:
            write_vectors(out / vectors_file, spec.preview, cases)
        (out / "controller.json").write_text(json.dumps(_jsonable(manifest), indent=1) + "\n", encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot write into {out}: {exc.strerror}", field="out") from None
    names = sorted([*files, "controller.json", *([vectors_file] if vectors else [])])
    warnings = tuple(f"the recorded {c['reference']} loop: {w}" for c in cases_info for w in c["warnings"])
    return ExportInfo(path=out, kind=spec.kind, files=names, table_bytes=spec.table_bytes, vector_steps=steps,
                      prefix=prefix, warnings=warnings)


def _design_info(controller: Controller) -> Any:
    """The controller's design-time plant knowledge (:class:`gearctl.design.base.LoopInfo`)."""
    for path in ("info", "pid.info", "inner.pid.info"):
        obj: Any = controller
        try:
            for part in path.split("."):
                obj = getattr(obj, part)
        except AttributeError:
            continue
        return obj
    raise InputError(f"controller {controller.name!r} carries no design plant: pass plant=", field="plant")
