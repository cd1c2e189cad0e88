"""The kernel does not depend on how far the axis has turned (a continuously rotating axis after many turns).

The dynamics depend on the gaps ``s_i = rb1_i theta_i - rb2_i theta_{i+1}`` and the speeds only, so a run
whose shafts start turned by ``O`` radians of the load (``O`` times the ratio to each shaft: every gap the
same) is the same run. It used not to be: the stuck shaft's break-away band, ``1e-10`` of the sum of the
magnitudes of the terms of the torque it holds, grew with the absolute angles (``k rb^2 theta``: 0.6 N m
at 1e5 rad on the friction servo, more than its break-away margin), and the friction servo's load never
moved at 3e4 rad. Each kernel call now integrates relative to an origin (the load angle rounded to a whole
radian, carried to every shaft by the ratios: ``gc_step`` in ``_kernel.c``, ``Kernel._origin``).

Oracles:

- **the offset's own rounding, exactly.** What remains of the offset is the storage of the absolute angles
  (the origin is added back after each call, which rounds the angle to its ulp). So the run at offset O
  must equal, *bit for bit*, the run at 0 whose angles are rounded after each call to the precision they
  would have at O (``(theta + O_j) - O_j``). Both paths, the pair with stick-slip friction and impacts,
  the Yang–Sun plant (the ODE path, whose error norm used to carry ``rtol |theta|``) and a three-stage
  train (long steps); the patterns are built beforehand, since the compiled path returns to build one and
  the return adds the origin back too (one more rounding, of the same size, that the emulation would have
  to place identically).
- **the closed loop.** The friction servo's 0.2 rad move and 1 Hz sine (ideal sensors: a 2^20-count
  encoder's counts sit elsewhere relative to the state at a large angle) give the RMS error of the run at 0
  to a relative 1e-6 with the PID (measured: at most 9e-8 at 1e6 rad; the margin covers the rounding's
  growth), and the dead-zone inverse, whose switching makes the RMS sensitive to rounding (measured: up to
  21 % apart at 1e6 rad, as the 0.37 rad offset moves it 2e-5), completes the move: largest error after
  0.5 s below 5e-5 rad (6.9e-6 at 0; before the fix the load stayed put, error 0.2 rad).
- **the time-varying stiffness still follows the absolute angle** (the origin is added back for its
  phase): offset by a whole number of mesh periods, the loaded pair's gap is that of the run at 0 to
  1e-6 of the backlash; offset by half a period more it is not (the stiffness there differs by ~10 %).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest
from conftest import require_compiled

from gearctl import Plant, build_plant, load_model
from gearctl.catalog import load_controller
from gearctl.closedloop import simulate_closed_loop
from gearctl.kernel import Kernel
from gearctl.references import Reference, reference

KERNELS = [pytest.param(True, id="compiled"), pytest.param(False, id="python")]
OFFSETS = (1e4, 1e5, 1e6)


def _ratios(p: Plant) -> list[float]:
    """Shaft j's angle per radian of the load's (every gap unchanged), as the kernel computes it."""
    w = p.nx // 2
    r = [1.0] * w
    for j in range(w - 2, -1, -1):
        r[j] = r[j + 1] * p.stages[j].rb2 / p.stages[j].rb1
    return r


def _run(p: Plant, offset: float, compiled: bool, *, stored_at: float = 0.0, u: float, n: int = 300
         ) -> tuple[np.ndarray, np.ndarray]:
    """``n`` calls of 1 ms: motor torque ``u`` (a sixth of them), then 0, then ``-u`` (a sixth) [N m]; the
    angles start at ``offset`` (load) [rad] and are, with ``stored_at``, rounded after each call to the
    precision they have at that offset. Returns the final state less the offset, and the event log."""
    w = p.nx // 2
    org = [offset * r for r in _ratios(p)]
    emu = [stored_at * r for r in _ratios(p)]
    x0 = np.zeros(p.nx)
    x0[:w] = org
    kn = Kernel(p, x0, dt=1e-3, compiled=compiled)
    for pat in range(kn._slot.size):  # every pattern built beforehand (see the module docstring)
        kn._ensure_pattern(pat)
    for i in range(n):
        assert kn.advance(u if i < n // 6 else (0.0 if i < 5 * n // 6 else -u), 0.0, 1e-3) == 0
        if stored_at:
            for j in range(w):
                kn._x[j] = (kn._x[j] + emu[j]) - emu[j]
    x = kn.x
    x[:w] -= org
    return x, kn.event_log


CASES = {  # plant, motor torque [N m]: every run keeps the load within half a radian (one origin)
    "friction-servo": (lambda: build_plant(load_model("shing1993_servo_friction")), 0.12),
    "friction-servo-yang-sun": (lambda: build_plant(load_model("shing1993_servo_friction"), kind="yang-sun"), 0.12),
    "three-stage": (lambda: build_plant(load_model("servo_3stage_quanser_srv02")), 0.005),
}


@pytest.mark.parametrize("compiled", KERNELS)
@pytest.mark.parametrize("case", list(CASES))
def test_offset_run_is_the_run_at_zero_stored_at_the_offsets_precision(case: str, compiled: bool) -> None:
    require_compiled(compiled)
    make, u = CASES[case]
    p = make()
    w = p.nx // 2
    # calls of 1 ms: shorter where the Python path is slow (the ODE) or the train quick to move
    n = 90 if case == "three-stage" else (300 if compiled or case == "friction-servo" else 150)
    x_ref, log_ref = _run(p, 0.0, compiled, u=u, n=n)
    assert 0.005 < abs(x_ref[w - 1]) < 0.5 and log_ref.size > 10  # it moves, with events, within one origin
    if case.startswith("friction"):
        kinds = set(log_ref["kind"].tolist())
        assert {6, 7} <= kinds, kinds  # the load sticks and breaks away
    for offset in OFFSETS:
        x_emu, log_emu = _run(p, 0.0, compiled, stored_at=offset, u=u, n=n)
        x_off, log_off = _run(p, offset, compiled, u=u, n=n)
        np.testing.assert_array_equal(x_off, x_emu, err_msg=f"offset {offset:g}")
        np.testing.assert_array_equal(log_off, log_emu, err_msg=f"offset {offset:g}")
        # and the physics is that of the run at 0: the load's travel to the rounding's effect
        assert x_off[w - 1] == pytest.approx(x_ref[w - 1], rel=1e-3, abs=1e-6), offset


class _Offset:
    """A catalog reference shifted by a constant angle [rad] (the rest of it as it is)."""

    def __init__(self, ref: Reference, offset: float) -> None:
        self.ref, self.offset = ref, offset

    def at(self, t: float) -> tuple[float, float, float]:
        r, rd, rdd = self.ref.at(t)
        return r + self.offset, rd, rdd

    def __getattr__(self, name: str) -> Any:
        return getattr(self.ref, name)


def _loop(ctrl: str, kind: str, offset: float) -> tuple[float, float]:
    """RMS and largest error after 0.5 s of the friction servo's closed loop at an offset [rad]."""
    m = load_model("shing1993_servo_friction")
    p = build_plant(m)
    sensors = dataclasses.replace(m.sensors, motor_encoder_cpr=None, load_encoder_cpr=None)
    x0 = np.zeros(p.nx)
    x0[: p.nx // 2] = [offset * r for r in _ratios(p)]
    res = simulate_closed_loop(p, load_controller(ctrl, p), _Offset(reference(kind), offset), 3.0,
                               sensors=sensors, x0=x0)
    assert res.success
    k = res.t >= 0.5
    e = res.reference[k] - res.x[p.nx // 2 - 1][k]
    return float(np.sqrt(np.mean(e * e))), float(np.max(np.abs(e)))


@pytest.mark.parametrize("kind", ["move", "sine"])
def test_friction_servo_pid_is_the_same_after_many_turns(kind: str) -> None:
    rms0, _ = _loop("pid", kind, 0.0)
    for offset in (3e4,) + OFFSETS[1:]:
        rms, _ = _loop("pid", kind, offset)
        assert rms == pytest.approx(rms0, rel=1e-6), (offset, rms, rms0)


def test_friction_servo_inverse_completes_the_move_after_many_turns() -> None:
    _, emax0 = _loop("deadzone_inverse", "move", 0.0)
    assert emax0 < 2e-5
    for offset in (3e4,) + OFFSETS[1:]:
        rms, emax = _loop("deadzone_inverse", "move", offset)
        assert emax < 5e-5, (offset, emax)  # the move is 0.2 rad


@pytest.mark.parametrize("compiled", KERNELS)
def test_tvms_stiffness_follows_the_absolute_angle(compiled: bool) -> None:
    require_compiled(compiled)
    p = build_plant(load_model("shing1993_servo"), kind="tvms")
    st = p.stages[0]
    period, b = st.mesh_period, st.backlash
    assert st.kv_table is not None

    def gaps(pinion_turns: float) -> np.ndarray:
        """The gap over 20 ms of a loaded pair whose pinion starts at ``pinion_turns`` mesh periods."""
        th = pinion_turns * period
        r = _ratios(p)
        x0 = np.array([th, th / r[0], 0.0, 0.0])
        x0[0] += (b + 12.0 / (st.rb2 * st.k)) / st.rb1  # in front contact, about the static deflection
        kn = Kernel(p, x0, dt=1e-3, compiled=compiled)
        out = []
        for _ in range(20):
            assert kn.advance(3.0, -12.0, 1e-3) == 0
            out.append(float(p.gaps(kn.x)[0]))
        return np.array(out)

    s0 = gaps(0.0)
    assert np.all(s0 > b)  # stays loaded: a smooth, non-chaotic run
    n = math.floor(4e4 / period)  # ~1e4 rad at the load
    np.testing.assert_allclose(gaps(float(n)), s0, rtol=0, atol=1e-6 * b)
    # the phase is not lost: three quarters of a mesh cycle on, the pinion starts in the single-tooth zone
    # (from the neutral position, in the double-tooth zone FD)
    assert p.stiffness_at(0.75 * period) < 0.8 * p.stiffness_at(0.0)
    assert np.max(np.abs(gaps(n + 0.75) - s0)) > 1e-3 * b
