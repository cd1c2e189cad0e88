"""Backlash and friction identification from encoder logs (gearctl/identify.py, gearctl/excite.py, issue 13).

Oracles:

1. known truth: logs recorded by ``excite`` from the simulated servo (``shing1993_servo_friction``: 0.2 N m
   of Coulomb friction on the load, 2^20-count encoders, plus 2 urad of encoder noise here) with the
   backlash at 0.5x, 1x and 2x the catalog's 50 um, under the designed excitation and under plain
   back-and-forth moves. ``identify`` starts from ``shing1993_servo`` (the right gears, the catalog b, no
   Coulomb friction): b within 5 % with both encoders, 10 % from the motor encoder alone, the truth inside
   the reported 95 % interval (issue 13, "Done when"), the Coulomb friction found;
2. invariants: the estimate does not depend on the encoders' zeros; a log written and read back is the
   same log; the excitation starts and ends at rest with a continuous velocity;
3. the identified model file drives ``track`` and ``precision`` to the figures of the true model (10 %);
4. a corpus of broken logs (tests/data/logs, written by make_corpus.py): one line naming the line or the
   column, exit code 2, no traceback.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from gearctl import InputError, load_model
from gearctl import identify as ident
from gearctl import logs as log_format
from gearctl.cli import main
from gearctl.excite import ExcitationProgram, excitation, record_excitation
from gearctl.identify import EncoderLog, Identification, identify, read_log, write_log

DATA = Path(__file__).resolve().parent / "data" / "logs"
TRUE_MODEL = "shing1993_servo_friction"  # the plant the logs come from
START_MODEL = "shing1993_servo"  # what identify is told: the gears, the catalog b, no Coulomb friction
B_CATALOG = 5e-5
NOISE = 2e-6  # rad, encoder noise on top of the 2^20-count quantisation


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> Callable[[str, float], tuple[Path, float]]:
    """``logs(motion, factor) -> (path, true b)``: a 10 s log written by excite and kept for the module."""
    folder = tmp_path_factory.mktemp("logs")
    made: dict[tuple[str, float], tuple[Path, float]] = {}

    def get(motion: str, factor: float) -> tuple[Path, float]:
        if (motion, factor) not in made:
            model = load_model(TRUE_MODEL, motor_noise=NOISE, load_noise=NOISE)
            ex = record_excitation(model, motion=motion, duration=10.0, backlash=factor * B_CATALOG, seed=7)
            path = folder / f"{motion}_{factor:g}.csv"
            write_log(path, ex.log)
            made[(motion, factor)] = (path, ex.plant.backlash)
        return made[(motion, factor)]

    return get


@pytest.fixture(scope="module")
def results(logs: Callable[[str, float], tuple[Path, float]]) -> Callable[..., tuple[Identification, float]]:
    """``results(motion, factor, encoders) -> (identification, true b)``, each computed once."""
    done: dict[tuple[str, float, str], tuple[Identification, float]] = {}

    def get(motion: str, factor: float, encoders: str) -> tuple[Identification, float]:
        key = (motion, factor, encoders)
        if key not in done:
            path, b = logs(motion, factor)
            done[key] = (identify(path, START_MODEL, encoders=encoders), b)
        return done[key]

    return get


def _check_backlash(res: Identification, b: float, tol: float) -> None:
    lo, hi = res.backlash_ci
    assert abs(res.backlash / b - 1) < tol, (res.backlash, b)
    assert lo <= b <= hi, (lo, b, hi)
    assert hi - lo < 2 * tol * b  # an interval that says something
    assert_allclose(res.lost_motion, 2 * res.backlash / res.base_radius[1], rtol=1e-12)


# --- 1. known truth -----------------------------------------------------------------------------------------
# Measured (this commit): both encoders |error| <= 0.08 %, half-width 0.2-0.8 %; motor alone |error| <= 0.3 %,
# half-width 0.4-2.5 %. The bounds below are the issue's: 5 % and 10 %.

BOTH = [pytest.param(m, f, id=f"{m}-{f:g}b") for m in ("identify", "moves") for f in (0.5, 1.0, 2.0)]
MOTOR = [pytest.param("identify", 1.0, id="identify-1b"), pytest.param("moves", 0.5, id="moves-0.5b")] + [
    pytest.param(m, f, id=f"{m}-{f:g}b", marks=pytest.mark.slow)
    for m, f in (("identify", 0.5), ("identify", 2.0), ("moves", 1.0), ("moves", 2.0))]


@pytest.mark.parametrize(("motion", "factor"), BOTH)
def test_both_encoders_recover_backlash_within_5_percent(results: Callable, motion: str, factor: float) -> None:
    res, b = results(motion, factor, "motor+load")
    assert res.encoders == "motor+load" and res.switches >= 10
    _check_backlash(res, b, 0.05)


@pytest.mark.parametrize(("motion", "factor"), MOTOR)
def test_motor_encoder_alone_recovers_backlash_within_10_percent(results: Callable, motion: str, factor: float) -> None:
    res, b = results(motion, factor, "motor")
    assert res.encoders == "motor" and math.isnan(res.residual_load)
    _check_backlash(res, b, 0.10)


def test_motor_alone_gives_a_wider_interval(results: Callable) -> None:
    both, _ = results("identify", 1.0, "motor+load")
    motor, _ = results("identify", 1.0, "motor")
    w_both = both.backlash_ci[1] - both.backlash_ci[0]
    w_motor = motor.backlash_ci[1] - motor.backlash_ci[0]
    assert w_motor > w_both  # measured 1.6 % against 0.75 % of b


def test_motor_alone_takes_the_models_motor_inertia(results: Callable) -> None:
    # the motor encoder sees J1 + J2/N^2 only: J1 is the model's (its data sheet's) and J2 the rest. The regression's
    # split (its weak prior's pull) was reported instead, on an outside user's log 12 % off the model's J1 with an
    # interval of the 10 % tolerance about it that left the model's value out, and unlike what --write-model writes
    res, _ = results("identify", 1.0, "motor")
    J1, (lo, hi) = res.inertia["J1"], res.inertia_ci["J1"]
    N = 4.0
    assert J1 == pytest.approx(res.nominal["J1"], rel=1e-12)
    assert lo <= res.nominal["J1"] <= hi
    assert res.inertia_sum == pytest.approx(J1 + res.inertia["J2"] / N**2, rel=1e-9)


def test_friction_and_inertia_found(results: Callable) -> None:
    """The model says no Coulomb friction; the log has 0.2 N m on the load and none on the motor."""
    truth = load_model(TRUE_MODEL)
    from gearctl import build_plant

    p = build_plant(truth)
    for enc in ("motor+load", "motor"):
        res, _ = results("identify", 1.0, enc)
        # measured 0.2000 N m (both and motor alone); 2 % allows the encoders' noise
        assert_allclose(res.friction["coulomb2"], p.tc2, rtol=0.02)
        assert res.friction["coulomb1"] < 0.02 * p.tc2
        assert res.friction_ci["coulomb2"][0] <= p.tc2 <= res.friction_ci["coulomb2"][1] + 1e-3
        # the lumped viscous friction and inertia on the motor shaft: measured within 1 %
        N = res.gear_ratio
        assert_allclose(res.inertia["J1"] + res.inertia["J2"] / N**2, p.J1 + p.J2 / N**2, rtol=0.02)
        assert_allclose(res.friction["viscous1"] + res.friction["viscous2"] / N**2, p.d1 + p.d2 / N**2, rtol=0.3)
    both, _ = results("identify", 1.0, "motor+load")
    # with both encoders the split between the shafts is seen (free flights in the gap): measured 0.1 %
    assert_allclose(both.inertia["J1"], p.J1, rtol=0.05)
    assert_allclose(both.inertia["J2"], p.J2, rtol=0.05)


def test_a_2_khz_log_gives_the_same_friction_and_inertia(tmp_path: Path) -> None:
    """A log sampled at 2 kHz (a 0.5 ms PID): its raw second differences are 4x noisier than at 1 kHz, and noise
    in the regressors pulls the free-flight inertia down and shows up as motor friction that is not there. The
    errors-in-variables correction of ``_regress`` removes it: measured J1 within 0.1 %, Coulomb friction on the
    motor 2e-6 N m (truth 0; 1.8e-4 N m uncorrected, 0.8 % low J1)."""
    from gearctl import build_plant

    ctrl = tmp_path / "pid_2khz.toml"
    ctrl.write_text((Path(__file__).resolve().parents[1] / "controllers" / "pid.toml").read_text()
                    .replace("sample_time = 1e-3", "sample_time = 5e-4"))
    truth = load_model(TRUE_MODEL, motor_noise=NOISE, load_noise=NOISE)
    ex = record_excitation(truth, duration=10.0, seed=7, controller=ctrl)
    assert ex.log.t[1] - ex.log.t[0] == pytest.approx(5e-4)
    res = identify(ex.log, START_MODEL, encoders="motor+load")
    p = build_plant(truth)
    assert_allclose(res.backlash, p.backlash, rtol=0.01)
    assert_allclose(res.inertia["J1"], p.J1, rtol=0.01)
    assert_allclose(res.inertia["J2"], p.J2, rtol=0.01)
    assert res.friction["coulomb1"] < 5e-5
    assert_allclose(res.friction["coulomb2"], p.tc2, rtol=0.01)


def test_residual_is_at_the_encoders_level(results: Callable) -> None:
    res, _ = results("identify", 1.0, "motor+load")
    q = 2 * math.pi / 2**20  # one count
    # measured 4e-6 rad (load angle) over 12 crossings: a few counts, against a lost motion of 1.3e-3 rad
    assert res.rms_residual < 5 * q
    # no misfit warning; only the viscous split may be named not identified (the free flights barely show it)
    assert not any("does not fit" in w for w in res.warnings)
    assert set(res.not_identified) <= {"viscous1", "viscous2"}
    assert len(res.windows) == ident.MAX_PLOT_WINDOWS
    assert all(w.theta2 is not None and w.t.size == w.theta1_sim.size for w in res.windows)


# --- 2. invariants ------------------------------------------------------------------------------------------


def test_estimate_does_not_depend_on_the_encoders_zeros(logs: Callable, results: Callable) -> None:
    path, _ = logs("identify", 1.0)
    log = read_log(path)
    shifted = dataclasses.replace(log, theta1=log.theta1 + 1.2345, theta2=log.theta2 - 0.5)
    ref, _ = results("identify", 1.0, "motor+load")
    res = identify(shifted, START_MODEL)
    # the zero moves by r_b1 1.2345 + r_b2 0.5 = 0.061 m along the line of action; rounding at that scale
    # (1e-17 relative) is 1e-11 m in b: rtol 1e-5 of b = 5e-10 m
    assert_allclose(res.backlash, ref.backlash, rtol=1e-5)
    rb1, rb2 = res.base_radius
    assert_allclose(res.offset - ref.offset, rb1 * 1.2345 + rb2 * 0.5, rtol=1e-9)


def test_a_load_encoder_counting_the_other_way_is_turned_round(logs: Callable, results: Callable) -> None:
    """Another simulator's or drive's convention: the load of a spur pair turns against the motor, and its encoder
    may count that way. The same log with -theta2 gives the same b, and says what it did."""
    path, _ = logs("identify", 1.0)
    log = read_log(path)
    ref, _ = results("identify", 1.0, "motor+load")
    res = identify(dataclasses.replace(log, theta2=-log.theta2), START_MODEL)
    assert_allclose(res.backlash, ref.backlash, rtol=1e-9)
    assert any("counts against the motor" in w for w in res.warnings)
    assert not any("counts against the motor" in w for w in ref.warnings)


def test_jittering_time_stamps_are_read_on_the_fixed_period(logs: Callable, results: Callable,
                                                            tmp_path: Path) -> None:
    """A logger that stamps a drive's 1 kHz samples with its own clock: 10 us RMS of jitter (intervals off by up
    to 4 %) is read as the fixed grid, with a warning that gives the figure; the estimate is the one from the
    evenly stamped log to rounding. A sample missing, or stamps that wander off the grid, are refused."""
    path, _ = logs("identify", 1.0)
    log = read_log(path)
    ref, _ = results("identify", 1.0, "motor+load")
    rng = np.random.default_rng(3)
    jittered = tmp_path / "jitter.csv"
    write_log(jittered, dataclasses.replace(log, t=log.t + rng.normal(0.0, 1e-5, log.n)))
    got = read_log(jittered)
    assert got.jitter[0] == pytest.approx(1e-5, rel=0.05) and got.jitter[1] < ident.JITTER_TOLERANCE * got.sample_time
    assert_allclose(got.sample_time, log.sample_time, rtol=1e-6)
    res = identify(jittered, START_MODEL)
    assert_allclose(res.backlash, ref.backlash, rtol=1e-9)
    assert any("time stamps jitter by 10" in w for w in res.warnings), res.warnings
    assert not any("jitter" in w for w in ref.warnings)
    # a clock that runs 20 % slow over the second half: every interval within 25 % of the period, the stamps not
    drift = tmp_path / "drift.csv"
    t = log.t.copy()
    half = log.n // 2
    t[half:] = t[half] + 1.2 * (t[half:] - t[half])
    write_log(drift, dataclasses.replace(log, t=t))
    with pytest.raises(InputError, match="off the grid of the log's period"):
        read_log(drift)


def test_stamps_within_the_jitter_tolerance_are_read_whatever_their_intervals(logs: Callable, results: Callable,
                                                                             tmp_path: Path) -> None:
    """Stamps each up to 20 % of a period off the grid (within the documented 25 %): two neighbours may lie 40 % of
    a period further apart or closer. read_log refused such a file on that interval (the Python API read it); now
    both read it on the grid, with the estimate of the evenly stamped log. A missing sample is still named."""
    path, _ = logs("identify", 1.0)
    log = read_log(path)
    ref, _ = results("identify", 1.0, "motor+load")
    rng = np.random.default_rng(5)
    t = log.t + rng.uniform(-0.2, 0.2, log.n) * log.sample_time
    assert np.max(np.abs(np.diff(t) - log.sample_time)) > ident.JITTER_TOLERANCE * log.sample_time
    jittered = tmp_path / "jitter20.csv"
    write_log(jittered, dataclasses.replace(log, t=t))
    got = read_log(jittered)
    assert got.jitter[1] < ident.JITTER_TOLERANCE * got.sample_time
    assert_allclose(got.sample_time, log.sample_time, rtol=1e-4)
    assert_allclose(identify(jittered, START_MODEL).backlash, ref.backlash, rtol=1e-9)
    assert_allclose(identify(dataclasses.replace(log, t=t), START_MODEL).backlash, ref.backlash, rtol=1e-9)
    gap = tmp_path / "gap.csv"
    keep = np.arange(log.n) != 3000
    write_log(gap, dataclasses.replace(log, t=t[keep], torque=log.torque[keep], theta1=log.theta1[keep],
                                       theta2=log.theta2[keep], extra={}))
    with pytest.raises(InputError, match=r"t = 3\.00\d* is 0\.00[12]\d* s after the previous sample") as exc:
        read_log(gap)
    assert exc.value.field == "t"


def test_log_round_trip(tmp_path: Path) -> None:
    t = np.arange(600) * 1e-3
    log = EncoderLog(t=t, torque=np.sin(t), theta1=0.1 * np.cos(t), theta2=None, extra={"r": t**2},
                     sample_time=1e-3, comments=("made here",))
    write_log(tmp_path / "a.csv", log)
    back = read_log(tmp_path / "a.csv")
    assert back.theta2 is None and back.comments == ("made here",) and set(back.extra) == {"r"}
    assert_allclose(back.sample_time, 1e-3, rtol=1e-9)
    for name in ("t", "torque", "theta1"):
        assert_allclose(getattr(back, name), getattr(log, name), rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("delimiter", [",", ";", "\t"])
def test_other_columns_are_ignored_whatever_they_hold(tmp_path: Path, delimiter: str) -> None:
    """A drive's log: quoted header names, a status text column, an empty trailing column, another delimiter."""
    t = 3.0 + np.arange(600) * 1e-3
    lines = ["# exported by a drive", delimiter.join(['"status"', '"t"', '"torque"', '"theta1"', "axis", ""])]
    lines += [delimiter.join(["ok" if k % 7 else "warn", f"{x:.6f}", f"{np.sin(x):.9g}", f"{0.1 * np.cos(x):.9g}",
                              "2", ""]) for k, x in enumerate(t)]
    path = tmp_path / "drive.csv"
    path.write_text("\n".join(lines) + "\n")
    log = read_log(path)
    assert log.theta2 is None and set(log.extra) == {"axis"}  # numeric throughout: kept; text and empty: dropped
    assert_allclose(log.t, t, rtol=1e-12)
    assert_allclose(log.theta1, 0.1 * np.cos(t), rtol=1e-8)
    assert_allclose(log.sample_time, 1e-3, rtol=1e-6)


def _other_simulator_log(path: Path, *, b: float, fs: float = 2000.0, duration: float = 8.0) -> None:
    """A drive log from a simulator that is not gearctl's: fixed-step RK4 at 40 kHz, a tanh load friction, a mesh
    stiffer or softer than gearctl's (1.2e8 N/m, 700 N s/m), a crude PD loop on the motor encoder at ``fs``, the
    clock starting at 12.5 s, a status text column, 2^20-count encoders with 1 urad of noise."""
    J1, J2, d1, d2, tc2 = 2.2e-4, 1.0e-2, 1e-4, 2e-3, 0.2
    rb1, rb2, k, c = 0.018794, 0.075175, 1.2e8, 700.0
    N, sub, Ts = rb2 / rb1, 20, 1.0 / fs
    h = Ts / sub

    def f(x: tuple[float, ...], u: float) -> tuple[float, ...]:
        s = rb1 * x[0] - rb2 * x[1]
        v = rb1 * x[2] - rb2 * x[3]
        F = k * (s - b) + c * v if s > b else (k * (s + b) + c * v if s < -b else 0.0)
        return x[2], x[3], (u - d1 * x[2] - rb1 * F) / J1, (rb2 * F - d2 * x[3] - tc2 * math.tanh(x[3] / 1e-3)) / J2

    rng = np.random.default_rng(3)
    q = 2 * math.pi / 2**20
    x = (0.0, 0.0, 0.0, 0.0)
    lines = ["status,t,torque,theta1,theta2"]
    for n in range(int(duration * fs)):
        tn = n * Ts
        r = 0.2 * math.sin(math.pi * tn) + 0.05 * math.sin(2 * math.pi * 1.7 * tn)
        y1 = q * round((x[0] + 1e-6 * rng.standard_normal()) / q)
        y2 = q * round((x[1] + 1e-6 * rng.standard_normal()) / q)
        u = min(max(30.0 * (r - y1 / N) - 0.4 * x[2] / N, -1.0), 1.0)
        lines.append(f"ok,{12.5 + tn:.6f},{u:.9g},{y1:.12g},{y2:.12g}")
        for _ in range(sub):
            k1 = f(x, u)
            k2 = f(tuple(a + 0.5 * h * d for a, d in zip(x, k1, strict=True)), u)
            k3 = f(tuple(a + 0.5 * h * d for a, d in zip(x, k2, strict=True)), u)
            k4 = f(tuple(a + h * d for a, d in zip(x, k3, strict=True)), u)
            x = tuple(a + h / 6 * (p1 + 2 * p2 + 2 * p3 + p4)
                      for a, p1, p2, p3, p4 in zip(x, k1, k2, k3, k4, strict=True))
    path.write_text("\n".join(lines) + "\n")


def test_a_log_from_another_simulator(tmp_path: Path) -> None:
    """Not gearctl's plant, loop, sample rate or file: measured b 59.98 um (both encoders) and 60.12 um (motor
    alone) for 60, J1 and J2 within 0.6 %, the load's 0.2 N m of friction within 0.2 %."""
    path = tmp_path / "other.csv"
    _other_simulator_log(path, b=6e-5)
    both = identify(path, START_MODEL, encoders="motor+load")
    motor = identify(path, START_MODEL, encoders="motor")
    for res, tol in ((both, 0.01), (motor, 0.05)):
        assert_allclose(res.backlash, 6e-5, rtol=tol)
        assert res.backlash_ci[0] <= 6e-5 <= res.backlash_ci[1]
        assert_allclose(res.friction["coulomb2"], 0.2, rtol=0.02)
    assert_allclose(both.inertia["J1"], 2.2e-4, rtol=0.03)
    assert_allclose(both.inertia["J2"], 1.0e-2, rtol=0.03)


def test_a_short_5_khz_chirp_from_another_simulator() -> None:
    """Half a second of open-loop torque chirp at 5 kHz: the load bangs across the gap and rests some 5 ms on a
    flank, four times. Whether a sample is at rest is judged by its travel over +-1 ms, not per sample (at 5 kHz a
    sample's travel through the gap, 1 um, is within the encoders' flicker, and the bouncing load read as resting),
    and the densest window of the flank's samples slides (fixed bins split the one good rest: 14 samples where 15
    were needed). Before, the log was refused ("no rest on the front flank"); measured b 49.96 um for 50."""
    res = identify(DATA / "other_sim_chirp_5khz.csv", START_MODEL, encoders="motor+load")
    assert res.sample_time == pytest.approx(2e-4)
    assert_allclose(res.backlash, 5e-5, rtol=0.01)
    assert res.backlash_ci[0] <= 5e-5 <= res.backlash_ci[1]


def test_a_rattling_loop_widens_the_interval_to_the_truth() -> None:
    """Another simulator's PD loop on the frictionless servo rattles in the gap: the load floats just off its
    flanks, and such samples outnumber those in contact, so each plateau is pulled into the gap (b 1.0 % low).
    The interval now carries that pull (the distance from each plateau up to the top tenth of its samples): before,
    it was [48.97, 49.98] um and missed the true 50; measured [48.80, 50.15]."""
    res = identify(DATA / "other_sim_rattling_pd.csv", START_MODEL, encoders="motor+load")
    assert_allclose(res.backlash, 5e-5, rtol=0.02)
    assert res.backlash_ci[0] <= 5e-5 <= res.backlash_ci[1]


@pytest.mark.parametrize("motion", ["identify", "moves"])
def test_excitation_starts_and_ends_at_rest_and_is_smooth(motion: str) -> None:
    prog = excitation(motion, duration=12.0, amplitude=0.1)
    assert isinstance(prog, ExcitationProgram) and prog.duration >= 12.0
    t = np.arange(0.0, prog.duration, 1e-4)
    r, v, a = prog.at(t)
    assert r[0] == 0.0 and v[0] == 0.0
    assert np.max(np.abs(r)) <= 0.1 * (1 + 1e-12)  # within the amplitude
    # velocity is the derivative of the position (finite differences, 1e-4 s): r is C1
    assert_allclose(np.gradient(r, t), v, atol=2e-3 * np.max(np.abs(v)) + 1e-6)
    # reversals of the velocity: the identification needs many of them
    sv = np.sign(v[np.abs(v) > 1e-9])
    assert np.sum(sv[1:] != sv[:-1]) >= 6


def test_excitation_rejects_bad_settings() -> None:
    with pytest.raises(InputError, match="motion"):
        excitation("zigzag")
    with pytest.raises(InputError, match="amplitude"):
        excitation("identify", amplitude=-1.0)
    with pytest.raises(InputError, match="duration"):
        excitation("identify", duration=0.0)


# --- 3. the identified model drives track and precision -------------------------------------------------------


def _figures(capsys: pytest.CaptureFixture[str], argv: list[str]) -> dict:
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_identify_cli_writes_a_model_that_tracks_like_the_true_one(logs: Callable, tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    path, b = logs("identify", 1.0)
    out, plot = tmp_path / "identified.toml", tmp_path / "id.png"
    assert main(["identify", str(path), "--model", START_MODEL, "--json", "--write-model", str(out),
                 "--plot", str(plot)]) == 0
    js = json.loads(capsys.readouterr().out)
    for key in ("backlash", "backlash_ci", "lost_motion", "friction", "encoders", "rms_residual"):
        assert key in js, key
    assert set(js["friction"]) >= {"viscous1", "viscous2", "coulomb1", "coulomb2"}
    assert js["encoders"] == "motor+load" and js["backlash_ci"][0] <= b <= js["backlash_ci"][1]
    assert plot.stat().st_size > 10_000
    m = load_model(out)
    assert "gearctl identify" in m.source["citation"] and "gap-crossing" in m.source["notes"]
    assert_allclose(m.pair.backlash, js["backlash"], rtol=1e-12)
    assert_allclose(m.servo.coulomb_friction2, js["friction"]["coulomb2"], rtol=1e-12)
    # the figures with the identified model against the true model's, within 10 % (or one encoder count, 6 urad,
    # for a figure below it); measured: within 0.2 %. Not the dead-zone inverse's ISO figures: they move by
    # 20-30 % when the true model's load inertia or Coulomb friction moves by 1 % (measured), so no model of
    # the plant could be held to 10 % on them.
    count = 2 * math.pi / 2**20
    prec = ["--json", "--targets", "3", "--cycles", "2"]
    for argv, keys in ((["track", "{m}", "deadzone_inverse", "--json"], ("rms_error",)),
                       (["track", "{m}", "pid", "--json"], ("rms_error",)),
                       (["precision", "{m}", "pid", *prec], ("reversal_value", "repeatability", "accuracy"))):
        true = _figures(capsys, [a.replace("{m}", TRUE_MODEL) for a in argv])
        mine = _figures(capsys, [a.replace("{m}", str(out)) for a in argv])
        for key in keys:
            assert abs(mine[key] - true[key]) <= max(0.10 * abs(true[key]), count), (argv[0], argv[2], key,
                                                                                     mine[key], true[key])


def test_motor_encoder_alone_ignores_a_load_column_it_does_not_use(logs: Callable, tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    # a logger that writes NaN where no load encoder is fitted: `--encoders motor` refused the column it never reads
    # (a reviewer's own logs); with both encoders it is still an error naming the column
    path, b = logs("identify", 1.0)
    lines = path.read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    col = lines[k].split(",").index("theta2")
    rows = [line.split(",") for line in lines[k + 1:]]
    for r in rows:
        r[col] = "nan"
    nan_log = tmp_path / "no_load_encoder.csv"
    nan_log.write_text("\n".join(lines[:k + 1] + [",".join(r) for r in rows]) + "\n")
    js = _figures(capsys, ["identify", str(nan_log), "--model", START_MODEL, "--encoders", "motor", "--json"])
    lo, hi = js["backlash_ci"]
    assert js["encoders"] == "motor" and lo <= b <= hi
    assert main(["identify", str(nan_log), "--model", START_MODEL]) == 2
    assert "column theta2 = nan is not a finite number" in capsys.readouterr().err


@pytest.mark.parametrize(("change", "said"), [
    ("counts", "column theta1: every value is a whole number (up to"),
    ("negated theta1", "a negated torque or theta1 (an encoder counting against the torque)")])
def test_a_log_in_counts_or_with_theta1_negated_is_named(logs: Callable, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str], change: str,
                                                         said: str) -> None:
    # a reviewer's logs: counts were blamed on swapped columns (2^20 / 2^16 counts happen to be the N^2 = 16 of
    # swapped columns), a negated theta1 on the torque alone
    path, _ = logs("identify", 1.0)
    lines = path.read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    head = lines[k].split(",")
    i1, i2 = head.index("theta1"), head.index("theta2")
    rows = [line.split(",") for line in lines[k + 1:]]
    for r in rows:
        if change == "counts":
            r[i1] = str(round(float(r[i1]) * 2**16 / (2 * math.pi)))
            r[i2] = str(round(float(r[i2]) * 2**20 / (2 * math.pi)))
        else:
            r[i1] = repr(-float(r[i1]))
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines[:k + 1] + [",".join(r) for r in rows]) + "\n")
    encoders = ["--encoders", "motor"] if change != "counts" else []
    assert main(["identify", str(bad), "--model", START_MODEL, *encoders]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and said in err, err


def test_design_on_the_identified_model_performs_on_the_true_plant(results: Callable, tmp_path: Path) -> None:
    """The engineering use: design the inverse on the identified model, run it on the true plant."""
    from gearctl import build_plant
    from gearctl.references import reference
    from gearctl.runs import Design, Run, controller_spec, execute

    res, _ = results("identify", 1.0, "motor")  # the harder case: the motor encoder alone
    model_path = ident.write_identified_model(tmp_path / "m.toml", res, START_MODEL)
    # what the log does not identify is written as said in the header and [source]: the fit's best value, but the
    # inertias: the motor's from the model (its data sheet), the load's from the sum J1 + J2/N^2 the log sees
    text = model_path.read_text()
    assert res.not_identified and all(line in text for line in ident._unidentified(res))
    assert all(k in load_model(model_path).source["notes"] for k in res.not_identified)
    written = build_plant(load_model(model_path))
    N2 = res.gear_ratio**2
    assert "J1" in res.not_identified and written.J1 == pytest.approx(res.nominal["J1"], rel=1e-12)
    assert written.J1 + written.J2 / N2 == pytest.approx(res.inertia["J1"] + res.inertia["J2"] / N2, rel=1e-12)
    truth = load_model(TRUE_MODEL)
    true_plant = build_plant(truth)
    spec, label = controller_spec("deadzone_inverse")
    rms = {}
    for name, nominal in (("true", true_plant), ("identified", build_plant(load_model(model_path)))):
        run = Run(plant=true_plant, design=Design(spec=spec, nominal=nominal, label=label), reference=reference("sine"),
                  duration=3.0, sensors=truth.sensors)
        out = execute(run)
        assert out.ok, out.message
        rms[name] = out.metrics.rms_error
    # measured ratio 1.00
    assert_allclose(rms["identified"], rms["true"], rtol=0.10)


def test_excite_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ref = tmp_path / "ref.csv"
    assert main(["excite", TRUE_MODEL, "--reference-only", str(ref), "--duration", "2"]) == 0
    lines = ref.read_text().splitlines()
    assert lines[1] == "t,reference,velocity,acceleration" and len(lines) == 2 + 2001
    log = tmp_path / "log.csv"
    assert main(["excite", TRUE_MODEL, "--out", str(log), "--duration", "3", "--backlash", "2.5e-05",
                 "--motion", "moves"]) == 0
    got = read_log(log)
    assert got.theta2 is not None and "reference" in got.extra and got.n == 3001
    assert any("backlash 2.5e-05" in c for c in got.comments)
    capsys.readouterr()
    assert main(["excite", TRUE_MODEL]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out" in err


# --- 4. bad logs --------------------------------------------------------------------------------------------

CORPUS = [
    ("missing_column.csv", "line 2: missing column 'theta1'"),
    ("duplicate_column.csv", "line 1: column 'theta1' appears twice"),
    ("nonmonotonic.csv", "line 8: t = 0.004 does not increase"),
    ("uneven.csv", "line 7: t = 0.006 is 0.002 s after the previous sample"),
    ("nan.csv", "line 6: column torque = nan is not a finite number"),
    ("inf.csv", "line 6: column theta1 = inf is not a finite number"),
    ("text.csv", "line 4: column theta2 = 'abc' is not a number"),
    ("ragged.csv", "line 7: 3 fields, expected 4"),
    ("short.csv", "100 samples (0.1 s) is too short"),
    ("slow_period.csv", "column t: sample period 2 s is out of range"),
    ("no_header.csv", "has no header row"),
    ("empty.csv", "has no header row"),
    ("binary.csv", "line 3: is binary"),
    ("latin1.csv", "line 1: is not UTF-8"),
    ("flat.csv", "column theta1: the motor does not move"),
    ("no_reversal.csv", "column theta1: the motor turns one way only"),
    ("no_gap_crossing.csv", "column theta2: 0 gap crossing(s) found"),
    ("no_rest.csv", "column theta2: 5 gap crossing(s), but no rest on either flank"),
]


@pytest.mark.parametrize(("name", "fragment"), CORPUS, ids=[c[0] for c in CORPUS])
def test_bad_log_is_one_line_and_exit_2(name: str, fragment: str, capsys: pytest.CaptureFixture[str]) -> None:
    path = DATA / name
    assert path.is_file(), "run tests/data/logs/make_corpus.py"
    assert main(["identify", str(path), "--model", START_MODEL]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"gearctl identify: error: {path}: ") and fragment in err, err


def test_a_log_that_reverses_but_never_rests_says_so(capsys: pytest.CaptureFixture[str]) -> None:
    # an external reviewer's simulator at 500 Hz: the motor reverses 20 times, the load never rests on a flank long
    # enough; the message said "record a motion that reverses"
    path = DATA / "other_sim_hunting_500hz.csv"
    model = Path(__file__).parent / "data" / "small_servo_20x80.toml"
    assert main(["identify", str(path), "--model", str(model)]) == 2
    err = capsys.readouterr().err
    assert "the motor reversed 20 times, but the load never rested on a flank" in err, err


def test_bad_logs_raise_input_error_with_the_column() -> None:
    with pytest.raises(InputError) as exc:
        read_log(DATA / "nan.csv")
    assert exc.value.field == "torque"
    with pytest.raises(InputError) as exc:
        read_log(DATA / "missing_column.csv")
    assert exc.value.field == "theta1"


def test_oversized_log_is_refused_with_the_figure(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = DATA / "short.csv"
    monkeypatch.setattr(log_format, "MAX_LOG_BYTES", 1000)
    with pytest.raises(InputError, match=r"4,3\d\d bytes is too large for a log \(at most 1,000 bytes"):
        read_log(path)
    monkeypatch.setattr(log_format, "MAX_LOG_BYTES", 10**9)
    monkeypatch.setattr(log_format, "MAX_LOG_SAMPLES", 50)
    with pytest.raises(InputError, match="100 samples is more than a log may hold"):
        read_log(path)


def test_load_encoder_asked_for_but_missing(logs: Callable, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path, _ = logs("identify", 1.0)
    log = read_log(path)
    write_log(tmp_path / "motor_only.csv", dataclasses.replace(log, theta2=None, extra={}))
    assert main(["identify", str(tmp_path / "motor_only.csv"), "--model", START_MODEL, "--encoders",
                 "motor+load"]) == 2
    err = capsys.readouterr().err
    assert "missing column 'theta2'" in err and err.count("\n") == 1
    train = load_model(START_MODEL)
    train = dataclasses.replace(train, stages=train.stages * 2)
    with pytest.raises(InputError, match="a train of 2 stages; identify handles a gear pair"):
        identify(log, train)


@pytest.mark.slow
def test_a_plant_unlike_the_model_is_flagged() -> None:
    """A log of the Yang-Sun plant (Hertzian, lively contact) read with the improved model: b from the plateaus
    holds (measured -0.04 %), the re-simulation does not fit and says so (measured 1100 x the noise)."""
    ex = record_excitation(TRUE_MODEL, plant="yang-sun", duration=10.0, seed=2)
    res = identify(ex.log, TRUE_MODEL, encoders="motor+load")
    _check_backlash(res, ex.plant.backlash, 0.05)
    assert sum("does not fit the log" in w for w in res.warnings) == 1
    assert {"J1", "J2", "coulomb1", "coulomb2"} <= set(res.not_identified)  # the friction and inertias are flagged


def _shifted(log: EncoderLog, rows: int) -> EncoderLog:
    """The log with its torque column moved down ``rows`` rows (up for a negative count), the ends repeated."""
    u = np.roll(log.torque, rows)
    if rows > 0:
        u[:rows] = log.torque[0]
    else:
        u[rows:] = log.torque[-1]
    return dataclasses.replace(log, torque=u)


@pytest.mark.parametrize("rows", [1, 2, -1, -2])
def test_a_torque_column_rows_off_is_named_or_left_alone(logs: Callable, rows: int) -> None:
    # a reviewer's log whose torque column was written a row late gave J1 21 % low with a tight interval and no word.
    # A shift is named where the logged torque does not correlate with the motor's acceleration steps and a shifted
    # one clearly does; the torque balances are then widened to the model's range, b from the plateaus kept. Where
    # the signature is not that clear it says nothing, and never names the wrong way. On gearctl's own identify log:
    # moved down one or two rows (written late), named (correlation 0.40 against -0.02 as logged); moved up (a
    # command logged before it acts), the logged row still correlates (0.28) and nothing is named
    path, b = logs("identify", 1.0)
    log = read_log(path)
    assert ident.torque_lag(log)[0] == 0
    bad = _shifted(log, rows)
    lag, corr = ident.torque_lag(bad)
    print(f"\nshifted {rows:+d} rows: lag {lag}, {corr}")
    assert lag in (0, -rows)  # named right, or not at all
    if rows < 0:
        return
    assert lag == -rows  # moved down: each row's torque acted rows earlier
    res = identify(bad, START_MODEL)
    assert any(f"{rows} row" in w and f"up {rows} row" in w for w in res.warnings), res.warnings
    assert {"J1", "J2", "viscous1", "viscous2", "coulomb1", "coulomb2"} <= set(res.not_identified)
    _check_backlash(res, b, 0.05)


def test_no_stored_log_is_read_as_shifted_but_the_late_one() -> None:
    # the stored logs (other simulators, closed loops, hunting, chirps, glitches) as logged: no shift named, but on
    # the reviewer's triangle log whose torque is a row late (0.83 a row up against -0.42 as logged). A second
    # reviewer's 160 logs (excite at 250 Hz to 4 kHz, a 500 Hz PID logged at 1 kHz, load feedback, MPC): none named
    named = {}
    for path in sorted(DATA.glob("*.csv")):
        try:
            log = read_log(path)
        except InputError:
            continue
        lag, corr = ident.torque_lag(log)
        if lag:
            named[path.name] = (lag, corr)
    assert set(named) == {"reviewer_triangle_torque_late.csv"} and named["reviewer_triangle_torque_late.csv"][0] == -1




def test_a_written_model_keeps_the_inertia_sum_when_an_inertia_is_at_its_bound(tmp_path: Path) -> None:
    # a heavy motor (14 kg m^2) beside a 0.013 kg m^2 load: the fit puts the load's inertia at its bound and reports
    # it at the model's value, the motor's holding the whole sum J1 + J2/N^2. The written model once added the two
    # (a reviewer: the load 0.0257 against 0.0126, the sums 26 % and 74 % high on edited results); it keeps the fit's
    # own sum now (measured: 14.06335 kg m^2 both, the truth 14.06098)
    from gearctl import build_plant

    m = load_model(Path(__file__).parent / "data" / "heavy_motor_no_limit.toml")
    ex = record_excitation(m, motion="identify", duration=10.0, seed=0)
    log = tmp_path / "heavy.csv"
    write_log(log, ex.log)
    res = identify(log, m)
    assert {"J1", "J2"} <= set(res.not_identified)
    written = build_plant(load_model(ident.write_identified_model(tmp_path / "out.toml", res, m)))
    N2 = res.gear_ratio**2
    assert written.J1 + written.J2 / N2 == pytest.approx(res.inertia_sum, rel=1e-12)
    true = build_plant(m)
    assert res.inertia_sum == pytest.approx(true.J1 + true.J2 / N2, rel=1e-3)
