"""The simulation kernel (gearctl/kernel.py and gearctl/_kernel.c): one algorithm, two paths.

Oracles:

1. independent computations: the contact-mode matrices written out from eqs 1-5 (TR 93-28 section 2);
   the backlash-free plant against ``scipy.linalg.expm`` of the contact matrix; the compiled path
   against the pure-Python mirror (``Kernel(..., compiled=False)``) on every plant kind;
2. closed forms of the Zeno rule: a bounce cascade under a small steady torque loses a factor
   ``e = exp(-zeta pi / sqrt(1 - zeta^2))`` of its impact speed per impact (the restitution of the
   linear law, eqs 3 and 10), so it needs about ``log(v0 / ZENO_VELOCITY) / log(1 / e)`` impacts before
   the impact that is made plastic;
3. invariants: the trajectory does not depend on how the run is cut into ``advance`` intervals.

Compiled checks call :func:`require_compiled`, which skips them where no C compiler is available.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from conftest import require_compiled
from numpy.testing import assert_allclose

from gearctl import ContactLaw, GearModel, InputError, Plant, build_plant, load_model
from gearctl.kernel import ZENO_VELOCITY, EventKind, Kernel, contact_matrices
from gearctl.simulate import Event, SimulationResult, simulate

KERNELS = [pytest.param(True, id="compiled"), pytest.param(False, id="python")]
DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def servo() -> Plant:
    """The report's pair with motor and load inertia and viscous friction (shing1993_servo)."""
    return build_plant(load_model("shing1993_servo"))


def free_x0(plant: Plant) -> list[float]:
    """The report's free-vibration start (section 5.1.1): neutral positions, omega1 = 50 rad/s."""
    return [0.0, 0.0, 50.0, 0.0]


def zeta_of(plant: Plant) -> float:
    """Damping ratio of the mesh mode, ``c / (2 sqrt(k m_eq))`` (eq 38, consistent form)."""
    return plant.c / (2.0 * math.sqrt(plant.k * plant.m_eq))


def restitution(plant: Plant) -> float:
    """Restitution of the linear law with no static load: ``exp(-zeta pi / sqrt(1 - zeta^2))``."""
    z = zeta_of(plant)
    return math.exp(-z * math.pi / math.sqrt(1.0 - z * z))


def capped_kernel(cap: int) -> type[Kernel]:
    """A :class:`Kernel` whose ``max_events`` defaults to ``cap`` (simulate() does not pass one)."""

    @dataclasses.dataclass
    class CappedKernel(Kernel):
        max_events: int = cap

    return CappedKernel


# --- contact matrices from the report's equations -------------------------------------------------------


def test_contact_matrices_are_eqs_1_to_12(servo: Plant) -> None:
    # Written out from eqs 1-5 (front contact; eqs 8-12 give the same linear part), plus the viscous
    # friction d1 omega1, d2 omega2 of the servo: F = k (rb1 th1 - rb2 th2 - b) + c (rb1 w1 - rb2 w2);
    # J1 w1' = xi1 - rb1 F - d1 w1; J2 w2' = xi2 + rb2 F - d2 w2.
    p = servo
    assert p.d1 > 0 and p.d2 > 0
    J1, J2, r1, r2, k, c = p.J1, p.J2, p.rb1, p.rb2, p.k, p.c
    A_free = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [0, 0, -p.d1 / J1, 0], [0, 0, 0, -p.d2 / J2]])
    A_contact = A_free + np.array([
        [0, 0, 0, 0],
        [0, 0, 0, 0],
        [-k * r1 * r1 / J1, k * r1 * r2 / J1, -c * r1 * r1 / J1, c * r1 * r2 / J1],
        [k * r1 * r2 / J2, -k * r2 * r2 / J2, c * r1 * r2 / J2, -c * r2 * r2 / J2],
    ])
    B = np.array([[0, 0], [0, 0], [1 / J1, 0], [0, 1 / J2]])
    Ac, Af, Bk = contact_matrices(p)
    # same formulas, different association order: rtol 1e-14
    assert_allclose(Ac, A_contact, rtol=1e-14, atol=0)
    assert_allclose(Af, A_free, rtol=1e-14, atol=0)
    assert_allclose(Bk, B, rtol=1e-14, atol=0)


# --- compiled vs Python ---------------------------------------------------------------------------------


def _plants(shing: GearModel) -> dict[str, Plant]:
    base = build_plant(shing)
    servo_model = load_model("shing1993_servo")
    servo = build_plant(servo_model)
    return {
        "improved-linear": base,
        "improved-no_pull": dataclasses.replace(base, contact_law=ContactLaw.NO_PULL),
        "yang-sun": build_plant(shing, "yang-sun"),
        "tvms": build_plant(shing, "tvms"),
        "servo-viscous": servo,
        # Coulomb friction turns the improved plant nonlinear: the dopri5 path
        "servo-coulomb": dataclasses.replace(servo, tc1=0.01, tc2=0.02),
    }


PLANT_NAMES = ["improved-linear", "improved-no_pull", "yang-sun", "tvms", "servo-viscous", "servo-coulomb"]


@pytest.mark.parametrize("name", PLANT_NAMES)
@pytest.mark.parametrize("torque", [(0.0, 0.0), (1.0, -1.0)], ids=["free", "load"])
def test_compiled_matches_python(shing: GearModel, name: str, torque: tuple[float, float]) -> None:
    require_compiled(True)
    p = _plants(shing)[name]
    runs = [simulate(p, free_x0(p), 5e-3, torque=torque, compiled=c) for c in (True, False)]
    a, b = runs
    assert a.solver.endswith("(compiled)") and b.solver.endswith("(python)")
    assert a.solver.split()[0] == b.solver.split()[0]
    assert len(a.impacts) >= 5  # the comparison covers several contacts
    # one algorithm written twice: s within 1e-9 b (we see <= 1e-12 b)
    assert_allclose(a.s, b.s, rtol=0, atol=1e-9 * p.backlash)
    # the rates agree to the same relative accuracy (1e-9 of the initial 50 rad/s)
    assert_allclose(a.x[2:], b.x[2:], rtol=0, atol=1e-9 * 50.0)
    assert_allclose(a.force, b.force, rtol=0, atol=1e-9 * p.k * p.backlash)
    assert np.array_equal(a.mode, b.mode)
    # same events in the same order; times within 1e-15 s (we see ~1e-16 s)
    assert [(e.kind, e.side) for e in a.events] == [(e.kind, e.side) for e in b.events]
    assert_allclose([e.t for e in a.events], [e.t for e in b.events], rtol=0, atol=1e-15)
    # velocities at the events: 1e-9 of the first impact speed
    assert_allclose([e.velocity for e in a.events], [e.velocity for e in b.events], rtol=0,
                    atol=1e-9 * abs(a.events[0].velocity))
    assert_allclose(a.max_penetration, b.max_penetration, rtol=1e-9)


# --- independence from the output grid ------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["improved", "yang-sun"])
def test_trajectory_independent_of_output_interval(shing: GearModel, kind: str) -> None:
    p = build_plant(shing, kind)
    fine = simulate(p, free_x0(p), 2e-3, dt=1e-6)
    coarse = simulate(p, free_x0(p), 2e-3, dt=1e-4)
    assert_allclose(coarse.t, fine.t[::100], rtol=1e-12, atol=0)
    # events are located, not stepped over: the coarse grid sees the same trajectory.
    # exact solver: s within 1e-9 b (we see 2e-13 b); dopri5 at rtol 1e-9: 1e-6 b
    tol = 1e-9 if kind == "improved" else 1e-6
    assert_allclose(coarse.s, fine.s[::100], rtol=0, atol=tol * p.backlash)
    assert [(e.kind, e.side) for e in coarse.events] == [(e.kind, e.side) for e in fine.events]
    assert_allclose([e.t for e in coarse.events], [e.t for e in fine.events], rtol=0,
                    atol=1e-12 if kind == "improved" else 1e-9)


@pytest.mark.parametrize("compiled", KERNELS)
def test_advance_in_pieces_equals_one_call(improved: Plant, compiled: bool) -> None:
    require_compiled(compiled)
    p = improved
    one = Kernel(p, np.array(free_x0(p)), dt=1e-4, compiled=compiled)
    assert one.advance(0.3, -0.2, 1e-3) == 0
    many = Kernel(p, np.array(free_x0(p)), dt=1e-4, compiled=compiled)
    for _ in range(10):
        assert many.advance(0.3, -0.2, 1e-4) == 0
    assert one.path == many.path == ("compiled" if compiled else "python")
    # time: ten additions of 1e-4 vs one of 1e-3, rtol 1e-14
    assert_allclose(many.t, one.t, rtol=1e-14)
    s1 = p.relative_displacement(one.x)
    s2 = p.relative_displacement(many.x)
    # exact solution either way: 1e-9 b
    assert_allclose(s2, s1, rtol=0, atol=1e-9 * p.backlash)
    assert [e[1:3] for e in many.events] == [e[1:3] for e in one.events]
    assert_allclose([e[0] for e in many.events], [e[0] for e in one.events], rtol=0, atol=1e-15)


def test_long_interval_keeps_every_event(improved: Plant) -> None:
    # Undamped free vibration: about 6000 impacts (12 000 events) per second. However the run is cut
    # into intervals, every event must be recorded; the compiled path hands its events back through a
    # buffer (4096 per call), the Python path appends them directly.
    require_compiled(True)
    p = dataclasses.replace(improved, c=0.0)
    x0 = np.array(free_x0(p))
    fine = Kernel(p, x0, dt=1e-3, compiled=True)
    for _ in range(400):
        assert fine.advance(0.0, 0.0, 1e-3) == 0
    assert len(fine.events) > 4096
    one = Kernel(p, x0, dt=1e-3, compiled=True)
    assert one.advance(0.0, 0.0, 0.4) == 0
    # the same state at the end (exact solver, rounding over ~2400 contacts: 1e-6 b, we see 4e-8 b) ...
    assert_allclose(p.relative_displacement(one.x), p.relative_displacement(fine.x), rtol=0,
                    atol=1e-6 * p.backlash)
    # ... so the same events
    n_one, n_fine = len(one.events), len(fine.events)
    assert n_one == n_fine, f"one 0.4 s call recorded {n_one} events, 400 calls of 1 ms recorded {n_fine}"
    # and through simulate(): one output interval of 0.4 s vs 400 of 1 ms
    coarse = simulate(p, x0, 0.4, dt=0.4)
    dense = simulate(p, x0, 0.4, dt=1e-3)
    assert dense.impact_counts()["front"] > 1000
    assert coarse.impact_counts() == dense.impact_counts()


# --- backlash-free plant: linear contact everywhere -----------------------------------------------------


def _affine_expm(A: np.ndarray, a: np.ndarray, x0: np.ndarray, t: np.ndarray) -> np.ndarray:
    """States of ``x' = A x + a`` at times ``t`` via the augmented matrix exponential (scipy)."""
    M = np.zeros((5, 5))
    M[:4, :4] = A
    M[:4, 4] = a
    z0 = np.append(x0, 1.0)
    return np.stack([(scipy.linalg.expm(M * ti) @ z0)[:4] for ti in t], axis=1)


@pytest.mark.parametrize("compiled", KERNELS)
@pytest.mark.parametrize("which", ["bare", "servo"])
@pytest.mark.parametrize("torque", [(0.0, 0.0), (0.05, -0.1)], ids=["free", "torque"])
def test_zero_backlash_is_linear_contact(shing: GearModel, servo: Plant, compiled: bool, which: str,
                                         torque: tuple[float, float]) -> None:
    require_compiled(compiled)
    p = build_plant(shing, backlash=0.0) if which == "bare" else dataclasses.replace(servo, backlash=0.0)
    assert p.backlash == 0.0
    x0 = np.array(free_x0(p))
    res = simulate(p, x0, 2e-3, dt=1e-5, torque=torque, compiled=compiled)
    # with no gap there is nothing to impact: no events at all, never in separation
    assert res.impact_counts() == {"front": 0, "back": 0}
    assert res.events == []
    assert set(np.unique(res.mode).tolist()) <= {-1, 1}
    # s changes sign many times (the mesh vibrates through zero), so both flank laws are used
    assert np.any(res.s > 0) and np.any(res.s < 0)
    Ac, _, B = contact_matrices(p)
    X = _affine_expm(Ac, B @ np.array(torque), x0, res.t)
    # x' = A_contact x + B u everywhere (the +-k b term vanishes with b = 0): each state to 1e-9 of its
    # largest magnitude (we see 3e-14), s to 1e-9 of its amplitude
    for row in range(4):
        assert_allclose(res.x[row], X[row], rtol=0, atol=1e-9 * float(np.max(np.abs(X[row]))))
    s_ref = p.rb1 * X[0] - p.rb2 * X[1]
    assert_allclose(res.s, s_ref, rtol=0, atol=1e-9 * np.max(np.abs(s_ref)))


# --- the Zeno rule ---------------------------------------------------------------------------------------


def _zeno_start(plant: Plant, v0: float, gap: float = 1e-6) -> list[float]:
    """In the gap a hair before front contact, ``s = b (1 - gap)``, closing at v0 along the line of action."""
    return [plant.backlash * (1.0 - gap) / plant.rb1, 0.0, v0 / plant.rb1, 0.0]


# A small steady torque on gear 1 pushes the flanks into front contact. Its static deflection is tiny,
# so after each impact the flanks part again at e times the impact speed and fly back under the
# torque: a geometric cascade of impacts (e = 0.854 at zeta = 0.05), endless in exact arithmetic.
# The relative acceleration is a = rb1 xi1 / J1 ~ 1e-3 m/s^2, and the static deflection in velocity
# units a / omega ~ 2e-8 m/s is far below ZENO_VELOCITY = 1e-6 m/s, so the cascade reaches the Zeno
# rule before the static load could stop it.
ZENO_XI1 = 1e-6  # N m
ZENO_V0 = 1e-5  # m/s


@pytest.mark.parametrize("compiled", KERNELS)
@pytest.mark.parametrize("law", [ContactLaw.LINEAR, ContactLaw.NO_PULL])
def test_zeno_cascade_ends_in_plastic_contact(improved: Plant, compiled: bool, law: ContactLaw,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    require_compiled(compiled)
    import gearctl.simulate as sim

    # The cascade needs ~30 events; cap the kernel at 1000 per interval (default 200000) so that an
    # unresolved cascade fails in a second instead of a minute on the Python path.
    monkeypatch.setattr(sim, "Kernel", capped_kernel(1000))
    p = dataclasses.replace(improved, contact_law=law)
    a = p.rb1 * ZENO_XI1 / p.J1
    assert a / p.natural_frequency < 0.05 * ZENO_VELOCITY  # the premise above
    res = simulate(p, _zeno_start(p, ZENO_V0), 0.3, torque=(ZENO_XI1, 0.0), dt=1e-4, compiled=compiled)
    assert res.success and res.t[-1] == pytest.approx(0.3, rel=1e-12)
    kinds = [e.kind for e in res.events]
    assert kinds.count("plastic") == 1, kinds[-8:]
    i_pl = kinds.index("plastic")
    plastic = res.events[i_pl]
    assert plastic.side == "front"
    assert abs(plastic.velocity) < ZENO_VELOCITY
    # persistent contact: nothing after the plastic impact, front contact to the end
    assert res.events[i_pl + 1:] == []
    after = res.t > plastic.t
    assert np.all(res.mode[after] == 1)
    # the plastic impact removed the relative velocity; the flanks then stay at the static deflection
    v = p.rb1 * res.x[2] - p.rb2 * res.x[3]
    # 1e-3 of ZENO_VELOCITY: only the static-deflection transient a / omega remains
    assert np.max(np.abs(v[after])) < 1e-3 * ZENO_VELOCITY + 2 * a / p.natural_frequency
    # every earlier impact was an ordinary one, each slower than the last, and all above the Zeno speed
    impacts = res.impacts
    assert all(e.kind == "impact" and e.side == "front" for e in impacts[:-1])
    speeds = np.array([abs(e.velocity) for e in impacts])
    assert np.all(np.diff(speeds) < 0)
    assert np.all(speeds[:-1] >= ZENO_VELOCITY)
    # count: speeds v_n = v_1 e^n until the first below ZENO_VELOCITY, so n_impacts <=
    # log(v_1 / Z) / log(1/e) + 2 (the first and the plastic one). The no_pull law's lift dissipates
    # less than the linear law's pull (measured ratio 0.858 vs e = 0.854): slack 3 covers it.
    e = restitution(p)
    estimate = math.log(speeds[0] / ZENO_VELOCITY) / math.log(1.0 / e)
    assert 0.8 * estimate <= len(impacts) <= estimate + 3


@pytest.mark.parametrize("compiled", KERNELS)
@pytest.mark.parametrize("law", [ContactLaw.LINEAR, ContactLaw.NO_PULL])
def test_plastic_impact_is_a_single_event(improved: Plant, compiled: bool, law: ContactLaw) -> None:
    # The last step of every Zeno cascade, isolated: flanks closing slower than ZENO_VELOCITY under a
    # steady torque into contact. The rule makes the impact perfectly plastic (relative velocity
    # removed by an impulse); the torque then holds the flanks in contact. Expected events: exactly one
    # ('plastic', front) and front contact to the end. Seeded sweep over closing speeds, because what
    # happens right after the impulse depends on the last bit of the rounded relative velocity.
    require_compiled(compiled)
    p = dataclasses.replace(improved, contact_law=law)
    rng = np.random.default_rng(20240611)
    failures = []
    for v in rng.uniform(0.01, 0.9, 60) * ZENO_VELOCITY:
        # s = b (1 - 1e-9): contact within the first microsecond
        kn = Kernel(p, np.array(_zeno_start(p, v, gap=1e-9)), dt=1e-5, compiled=compiled, max_events=50)
        status = kn.advance(ZENO_XI1, 0.0, 1e-5)
        kinds = [EventKind.NAMES[k] for _, k, _, _ in kn.events]
        if status != 0 or kinds != ["plastic"] or kn.mode != 1:
            failures.append((float(v), status, kinds[:6], kn.mode))
    hung = [f for f in failures if f[1] != 0]
    assert not failures, (f"{len(failures)} of 60 closing speeds give extra events, {len(hung)} of them never "
                          f"get out (status 3); (v, status, events, mode): {(failures[:2] + hung[:1])}")


# --- failure handling ------------------------------------------------------------------------------------


@pytest.mark.parametrize("compiled", KERNELS)
def test_kernel_gives_up_on_too_many_events(improved: Plant, compiled: bool) -> None:
    require_compiled(compiled)
    p = improved
    # a Zeno cascade of ~60 events in 0.12 s (10 times the torque of the test above)
    kn = Kernel(p, np.array(_zeno_start(p, 1e-4)), dt=0.3, compiled=compiled, max_events=5)
    status = kn.advance(10 * ZENO_XI1, 0.0, 0.3)
    assert status == 3
    assert "too many events" in Kernel.status_message(status)
    assert kn.t < 0.3  # it stopped early
    assert len(kn.events) >= 5


@pytest.mark.parametrize("compiled", KERNELS)
def test_a_steady_event_rate_is_told_from_a_cascade(compiled: bool) -> None:
    require_compiled(compiled)
    # the fuzzer's undamped 717 kHz mesh (damping ratio 2.2e-16) against a load held by stick-slip friction: the
    # mesh turns the load's speed through zero twice a cycle, a stick and a slip each time, 4 events a period
    p = build_plant(load_model(DATA / "fuzz" / "undamped_mesh_stick_slip_chatter.toml"))
    kn = Kernel(p, np.zeros(p.nx), dt=1e-3, compiled=compiled, max_events=300, max_event_rate=1e4)
    status = kn.advance(-p.load_torque / p.stages[0].ratio, p.load_torque, 1e-3)
    assert status == 3 and kn.t < 2e-4  # the budget of 300 + 1e4/s spent in about 0.1 ms
    message = kn.budget_message()
    assert message.startswith("event rate: ") and "stick and slip" in message
    rate = float(message.split("steady ")[1].split(" per s")[0])
    f_mesh = p.natural_frequency / (2 * math.pi)
    assert rate == pytest.approx(4 * f_mesh, rel=0.03)  # measured 2.84e6 against 4 x 717 kHz = 2.87e6
    # a log kept to 100 records (max_records): the run's mean rate, the same
    kn = Kernel(p, np.zeros(p.nx), dt=2e-3, compiled=compiled, max_events=3000, max_event_rate=1e4, max_records=100)
    assert kn.advance(-p.load_torque / p.stages[0].ratio, p.load_torque, 2e-3) == 3 and kn.dropped_events > 0
    message = kn.budget_message()
    assert message.startswith("event rate: ") and "stick and slip" in message
    assert float(message.split("steady ")[1].split(" per s")[0]) == pytest.approx(rate, rel=0.03)


@pytest.mark.parametrize("compiled", KERNELS)
def test_simulate_raises_on_too_many_events(improved: Plant, compiled: bool,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    require_compiled(compiled)
    import gearctl.simulate as sim

    # simulate() has no max_events argument: give its Kernel a tiny one
    monkeypatch.setattr(sim, "Kernel", capped_kernel(5))
    p = improved
    with pytest.raises(sim.SimulationError, match="event cascade: more contact events") as info:
        sim.simulate(p, _zeno_start(p, 1e-4), 0.3, torque=(10 * ZENO_XI1, 0.0), dt=0.3, compiled=compiled)
    res = info.value.result
    assert isinstance(res, SimulationResult)
    assert not res.success
    assert res.message.startswith("event cascade")
    assert all(isinstance(e, Event) for e in res.events) and len(res.events) >= 5


@pytest.mark.parametrize("compiled", KERNELS)
@pytest.mark.parametrize("x0", [[0.0, 0.0, 50.0], [0.0, 0.0, math.nan, 0.0], [0.0, math.inf, 0.0, 0.0],
                                [[0.0, 0.0, 50.0, 0.0]]], ids=["length3", "nan", "inf", "2d"])
def test_kernel_rejects_bad_initial_state(improved: Plant, compiled: bool, x0: list) -> None:
    require_compiled(compiled)
    with pytest.raises(InputError, match="initial state"):
        Kernel(improved, np.array(x0, dtype=float), dt=1e-6, compiled=compiled)


def test_kernel_classify_and_set_state(improved: Plant) -> None:
    p = improved
    kn = Kernel(p, np.array(free_x0(p)), dt=1e-6, compiled=False)
    assert kn.mode == 0 and kn.t == 0.0 and kn.max_penetration == 0.0
    b = p.backlash
    front = np.array([2 * b / p.rb1, 0.0, 0.0, 0.0])  # s = 2 b: front contact, compressed
    back = -front
    assert kn.classify(front) == 1 and kn.classify(back) == -1
    kn.set_state(front)
    assert kn.mode == 1
    assert_allclose(kn.x, front, rtol=0, atol=0)
    # no_pull: overlapping but parting faster than k delta / c carries no load (mode +-2)
    np_kn = Kernel(dataclasses.replace(p, contact_law=ContactLaw.NO_PULL), np.array(free_x0(p)), dt=1e-6,
                   compiled=False)
    delta = 1e-9
    v = -2 * p.k * delta / p.c  # F = k delta + c v = -k delta < 0
    parting = np.array([(b + delta) / p.rb1, 0.0, v / p.rb1, 0.0])
    assert np_kn.classify(parting) == 2
    assert np_kn.classify(-parting) == -2


# --- trains, the force law written once, grazing and bounded cascades (issues 11, 16, 17) ---------------


def _train(kind: str = "improved", *, n: int = 2, law: ContactLaw = ContactLaw.LINEAR, coulomb: float = 0.0,
           friction: str = "stick_slip") -> Plant:
    """A train built from the report's pair: each stage the same pair, the gear of one the pinion's shaft of
    the next (``build_plant`` of a ``[[stage]]`` model does the same from a file)."""
    from gearctl.plant import Shaft

    base = build_plant(load_model("shing1993"), kind)
    st = base.stages[0]
    J = [base.J1] + [base.J2 + base.J1] * (n - 1) + [base.J2]
    shafts = [Shaft(J=j, d=1e-4, tc=coulomb if i == n else 0.0) for i, j in enumerate(J)]
    stages = [dataclasses.replace(st, backlash=st.backlash * (1 + 0.3 * i)) for i in range(n)]
    return Plant(kind=kind, shafts=shafts, stages=stages, contact_law=law, friction_law=friction)


def _train_x0(p: Plant) -> np.ndarray:
    w = len(p.shafts)
    x0 = np.zeros(2 * w)
    x0[w] = 50.0
    for j in range(1, w):  # each shaft slower than its stage's ratio allows: every gap closes
        x0[w + j] = 0.85 * x0[w + j - 1] / p.stages[j - 1].ratio
    return x0


TRAIN_CASES = ["improved", "no_pull", "yang-sun", "tvms", "stick-slip"]


@pytest.mark.parametrize("case", TRAIN_CASES)
def test_train_compiled_matches_python(case: str) -> None:
    require_compiled(True)
    kind = case if case in ("improved", "yang-sun", "tvms") else "improved"
    p = _train(kind, law=ContactLaw.NO_PULL if case == "no_pull" else ContactLaw.LINEAR,
               coulomb=0.02 if case == "stick-slip" else 0.0)
    x0 = _train_x0(p)
    runs = [simulate(p, x0, 3e-3, dt=1e-5, torque=(0.5, -0.3), compiled=c) for c in (True, False)]
    a, b = runs
    assert a.solver.endswith("(compiled)") and b.solver.endswith("(python)")
    assert sum(1 for e in a.events if e.kind in ("impact", "plastic")) >= 4  # several contacts on the stages
    assert {e.stage for e in a.events} == {0, 1}  # both stages have events
    # one algorithm written twice: every stage's gap within 1e-9 of its b (exact path) / 1e-7 (dopri5)
    tol = 1e-9 if a.solver.startswith("exact") else 1e-7
    for i, st in enumerate(p.stages):
        assert_allclose(a.s[i], b.s[i], rtol=0, atol=tol * st.backlash)
    assert [(e.kind, e.side, e.stage) for e in a.events] == [(e.kind, e.side, e.stage) for e in b.events]
    assert np.array_equal(a.mode, b.mode)
    for k in ("impacts_front", "impacts_back", "plastic_front", "plastic_back", "separations"):
        assert np.array_equal(a.counts[k], b.counts[k]), k


@pytest.mark.parametrize("kind", ["improved", "yang-sun", "tvms"])
@pytest.mark.parametrize("law", [ContactLaw.LINEAR, ContactLaw.NO_PULL])
def test_c_and_python_force_laws_agree(kind: str, law: ContactLaw) -> None:
    """The force law is written once per language: the kernel's C ``force()`` and :func:`mesh_force` agree."""
    require_compiled(True)
    from gearctl.plant import mesh_force

    p = _train(kind, law=law)
    kn = Kernel(p, _train_x0(p), dt=1e-5, compiled=True)
    rng = np.random.default_rng(7)
    w = len(p.shafts)
    for _ in range(200):
        x = np.concatenate([rng.normal(0, 2e-3, w), rng.normal(0, 20.0, w)])
        modes = rng.integers(-1, 2, p.n_stages)
        d_ys = rng.uniform(0, 1e8, p.n_stages)
        F = mesh_force(p, x, modes, d_ys)
        for i in range(p.n_stages):
            # same formula, same operation order: equal to rounding (1e-12 of the spring term)
            scale = p.stages[i].k * (abs(p.gaps(x)[i]) + p.stages[i].backlash) + 1.0
            assert abs(kn.c_force(i, int(modes[i]), float(d_ys[i]), x) - F[i]) <= 1e-12 * scale


def test_kernel_structs_come_from_one_description() -> None:
    """The C structs are generated from the field lists the ctypes mirror is built from."""
    from gearctl.kernel import PARAMS_FIELDS, STATE_FIELDS, _Params, _State, c_structs

    text = c_structs()
    for name, _ in PARAMS_FIELDS + STATE_FIELDS:
        assert f"{name};" in text
    assert [f[0] for f in _Params._fields_] == [n for n, _ in PARAMS_FIELDS]
    assert [f[0] for f in _State._fields_] == [n for n, _ in STATE_FIELDS]


@pytest.mark.parametrize("compiled", KERNELS)
def test_grazing_contact_does_not_chatter(compiled: bool) -> None:
    """Issue 11's endless cascade, isolated: flanks touching (s = -b), no relative speed, and a relative
    acceleration at rounding level (an MPC's 1e-16 N m torque). Separation and plastic impact used to
    alternate at one instant without end; the grazing rule keeps the stage where it is."""
    require_compiled(compiled)
    m = load_model("shing1993_servo")
    p = build_plant(m)
    b = p.backlash
    # gear 2 at rest; gear 1 placed so that s = -b exactly, both rolling together (v = 0)
    th2 = 0.0
    th1 = (p.rb2 * th2 - b) / p.rb1
    om2 = 0.3
    om1 = p.rb2 * om2 / p.rb1
    kn = Kernel(p, np.array([th1, th2, om1, om2]), dt=1e-3, compiled=compiled, max_events=1000)
    for u1 in (-1.9e-16, 1.9e-16, 0.0):
        status = kn.advance(u1, 0.0, 1e-3)
        assert status == 0, Kernel.status_message(status)
    assert kn.events_total <= 4


@pytest.mark.parametrize("compiled", KERNELS)
def test_no_pull_force_boundary_does_not_chatter(compiled: bool) -> None:
    """An unseen train's event cascade (the dead-zone inverse's precision run, t = 29.805 s): both stages in
    back contact under the no_pull law, coasting at a mesh force of zero in stage 1. Right after each switch
    the force's rate had the sign of the stiff terms' rounding in both modes, so lift and reload alternated
    at one instant until the event budget ran out (200001 events). The switch back now waits until the force
    is clearly past zero."""
    require_compiled(compiled)
    m = load_model(DATA / "train_steel_alu.toml")
    p = build_plant(m)
    x0 = np.array([4.491235240759591, 1.498198600715453, 0.5005346565291457, -0.00014622063779775788,
                   -4.8740206847427754e-05, -1.624672806931189e-05])
    kn = Kernel(p, x0, dt=1e-3, compiled=compiled, t0=29.805, max_events=2000)
    assert kn.modes == (-1, -1)
    status = kn.advance(-6.870332531810239e-11, 0.0, 1e-3)
    assert status == 0, Kernel.status_message(status)
    assert kn.events_total < 100
    # the force that no mode could agree on stays at zero: the stage never pulls
    s = p.stages[0]
    gap = s.rb1 * kn.x[0] - s.rb2 * kn.x[1]
    assert abs(gap) <= s.backlash + 1e-9


@pytest.mark.parametrize("compiled", KERNELS)
def test_zero_backlash_time_varying_stiffness_rolls_on(compiled: bool) -> None:
    """An unseen case: the report's bare pair with b = 0 on the time-varying stiffness ran out of events at
    t = 10.8 ms, once its vibration had died and the gears rolled together (s and v at rounding level, the
    flank label flipping at s = 0 without end). With no gap and the linear law the flank is a label on the ODE
    path too (the force is k(theta) s + c v on both); the run ends, and the line-of-action momentum
    rb2 J1 omega1 + rb1 J2 omega2 is conserved (no external torque)."""
    require_compiled(compiled)
    p = build_plant(load_model("shing1993", backlash=0.0), kind="tvms")
    x0 = np.array([0.0, 0.0, 50.0, 0.0])
    kn = Kernel(p, x0, dt=1e-5, compiled=compiled, max_events=2000)
    for _ in range(2000):  # the CLI's output steps were 1 us; 10 us hit the same chatter
        status = kn.advance(0.0, 0.0, 1e-5)
        assert status == 0, Kernel.status_message(status)
    s = p.stages[0]
    J1, J2 = p.shafts[0].J, p.shafts[1].J
    h0 = s.rb2 * J1 * 50.0
    h1 = s.rb2 * J1 * kn.x[2] + s.rb1 * J2 * kn.x[3]
    assert h1 == pytest.approx(h0, rel=1e-7)
    assert kn.x[2] * s.rb1 == pytest.approx(kn.x[3] * s.rb2, rel=1e-3)  # rolling together by 20 ms


def test_event_budget_holds_across_buffer_refills(improved: Plant) -> None:
    """The per-call event cap counts every event of the call, also after the buffer was drained (it used to
    restart at each refill, so a cascade ran forever); and the records kept are capped."""
    require_compiled(True)
    p = dataclasses.replace(improved, c=0.0)
    kn = Kernel(p, np.array(free_x0(p)), dt=0.4, compiled=True, max_events=5000, max_records=3000)
    status = kn.advance(0.0, 0.0, 0.4)  # ~4800 events wanted in 0.4 s of undamped vibration
    assert status == 0
    kn2 = Kernel(p, np.array(free_x0(p)), dt=0.4, compiled=True, max_events=4500)
    assert kn2.advance(0.0, 0.0, 0.4) == 3  # more than 4500 (buffer 4096): the cap holds across the refill
    assert kn.events_total > 3000 and len(kn.event_log) == 3000 and kn.dropped_events == kn.events_total - 3000
    c = kn.counts
    assert int(np.sum(c["impacts_front"] + c["impacts_back"])) > 1000  # counts stay exact beyond the records


@pytest.mark.parametrize("compiled", KERNELS)
def test_stick_slip_standstill_is_exact_and_cheap(compiled: bool) -> None:
    """Stick-slip Coulomb friction: a shaft pushed with less than its friction sticks (zero speed, exactly);
    pushed with more, it slips with (torque - T_c) / J; standstill costs no sub-steps beyond the grid."""
    require_compiled(compiled)
    servo = build_plant(load_model("shing1993_servo_friction"), backlash=0.0)
    kn = Kernel(servo, np.zeros(4), dt=1e-3, compiled=compiled)
    assert kn.exact  # stick-slip keeps the improved plant piecewise affine
    for _ in range(100):  # 0.15 N m through the stiff mesh onto 0.2 N m of load friction: stuck
        assert kn.advance(0.15 / servo.gear_ratio, 0.0, 1e-3) == 0
    assert kn.slip[1] == 0 and kn.x[3] == 0.0
    steps_still = kn.steps
    for _ in range(100):  # 0.4 N m: breaks away and accelerates
        assert kn.advance(0.4 / servo.gear_ratio, 0.0, 1e-3) == 0
    assert kn.slip[1] == 1 and kn.x[3] > 0
    kinds = [EventKind.NAMES[k] for k in kn.event_log["kind"].tolist()]
    # the break-away: the elastic mesh rings, so the load may stick again at the first speed zeros; then it slips
    assert kinds[0] == "slip" and kinds[-1] == "slip" and len(kinds) < 20
    # standstill: the same sub-steps per sample as free motion of this plant (no stiff friction law)
    assert steps_still <= 100 * math.ceil(1e-3 * servo.natural_frequency / 0.6 + 1)


def test_tiny_coulomb_friction_does_not_chatter() -> None:
    """A fuzzer's case (issue 11): a motor shaft with a Coulomb friction of 3e-7 N m next to a load held by
    0.2 N m. The stick test and the break-away threshold once disagreed by the rounding of the stiff mesh
    torques (1e-16 of them, above 1e-9 of the tiny friction): the shaft stuck and broke away at one instant
    without end. Both now clear that rounding by the same margin; the precision test runs to its end."""
    from gearctl.precision import precision_test

    m = load_model("shing1993_servo_friction", coulomb_friction1=2.97055e-7, viscous_friction1=8.5508e-5,
                   viscous_friction2=2.23336e-3, motor_inertia=1.99762e-4, load_inertia=5.00515e-3,
                   coulomb_friction2=0.199999, backlash=4.99994e-5)
    p = build_plant(m)
    from gearctl import load_controller

    res = precision_test(p, load_controller("pid", p), sensors=m.sensors, targets=3, cycles=2)
    assert np.isfinite(res.stats["accuracy"]) and res.deviations_up.shape == (3, 2)


@pytest.mark.parametrize("kind", ["tvms", "yang-sun"])
def test_stick_slip_on_the_nonlinear_plants_ends(kind: str) -> None:
    """The fuzzer's hang (issue 11): stick-slip friction on the motor of a pair simulated on the time-varying
    stiffness or Yang-Sun plant. Its zero-speed test took the held torque from the mean-stiffness linear law
    while the motion followed the plant's own law; where they disagreed in sign the shaft reversed without
    stopping, at one instant, forever, and recorded nothing. Now both come from the plant's law, and a reversal
    without sticking is an event (it counts against the budget). The run ends; both kernels agree."""
    require_compiled(True)
    from pathlib import Path

    m = load_model(Path(__file__).parent / "data" / "fuzz" / "stick_slip_tvms.toml")
    p = build_plant(m, kind)
    from gearctl.simulate import report_case

    runs = [report_case(p, "free", 0.01, compiled=c) for c in (True, False)]  # the hanging command
    a, b = runs
    assert a.solver.split()[0] == b.solver.split()[0]
    kinds = [EventKind.NAMES[k] for k in a.event_log["kind"].tolist()]
    assert "slip" in kinds  # the friction acted: the motor broke away (and reversed while slipping)
    assert kinds == [EventKind.NAMES[k] for k in b.event_log["kind"].tolist()]
    assert_allclose(a.x[:, -1], b.x[:, -1], rtol=1e-6, atol=1e-9)
