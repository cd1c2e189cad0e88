"""Excitation for identification: a closed-loop motion that makes backlash and friction visible, and its log.

``gearctl excite`` records what a user would record on hardware: the motor torque command and the
encoder readings (quantised, noisy, as the model's ``[sensors]`` say) while a position loop follows a
motion program. The program is built from three pieces, each starting and ending at rest:

- *dwells*, where friction holds the load on the flank that drove it (stick-slip);
- *cosine cycles* ``p0 + A (1 - cos(2 pi f tau)) / 2``, one reversal at the top of each cycle and one
  at its end, at several frequencies so that the reversals happen at several accelerations;
- *S-curve moves* at two cruise speeds, so that viscous and Coulomb friction separate.

Every reversal makes the motor cross the backlash gap (the flank that carries the load changes), which
is what :func:`gearctl.identify.identify` measures. ``--reference-only`` writes the program alone, to
run on a real drive.

A second program, ``moves``, is the plain back-and-forth move a user would record without a special
test (the tests identify from it too, because a user's log will not be the one gearctl designed).
"""

from __future__ import annotations

import bisect
import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .catalog import GearModel, load_controller, load_model
from .closedloop import ClosedLoopResult, simulate_closed_loop
from .controller import Controller, ReferenceLike
from .errors import InputError
from .limits import check_output_size
from .logs import MAX_LOG_SAMPLES, EncoderLog
from .plant import Plant, build_plant
from .references import move_point, move_times, pointwise
from .units import DURATION, SEED, Spec, check_choice

__all__ = ["MOTIONS", "AMPLITUDE", "ExcitationProgram", "excitation", "Excitation", "record_excitation",
           "write_reference", "check_reference_duration"]

#: The motion programs :func:`excitation` builds.
MOTIONS = ("identify", "moves")
#: Scale of a program: the largest excursion of the load from its start [rad].
AMPLITUDE = Spec(unit="rad", doc="excitation amplitude (load angle)", low=0.0, low_open=True, high=10.0)


@dataclasses.dataclass(frozen=True, slots=True)
class ExcitationProgram:
    """A load-angle reference made of dwells, cosine cycles and S-curve moves (a :class:`ReferenceLike`).

    Attributes
    ----------
    pieces : tuple
        ``("dwell", T)``, ``("cycles", A, f, n)`` or ``("move", D, v, a)`` [rad, Hz, rad/s, rad/s^2].
    starts : tuple of float
        Start time of each piece [s].
    origins : tuple of float
        Load angle at the start of each piece [rad].
    settle : float
        Start of error statistics [s] (0: the whole program counts).
    """

    pieces: tuple[tuple[Any, ...], ...]
    starts: tuple[float, ...]
    origins: tuple[float, ...]
    settle: float = 0.0

    @staticmethod
    def piece_duration(piece: tuple[Any, ...]) -> float:
        """Duration of one piece [s].

        Parameters
        ----------
        piece : tuple
            ``("dwell", T)``, ``("cycles", A, f, n)`` or ``("move", D, v, a)`` [s; rad, Hz, 1; rad, rad/s,
            rad/s^2].
        """
        if piece[0] == "dwell":
            return float(piece[1])
        if piece[0] == "cycles":
            return piece[3] / piece[2]
        ta, tc, _ = move_times(abs(piece[1]), piece[2], piece[3])
        return 2 * ta + tc

    @staticmethod
    def piece_end(piece: tuple[Any, ...]) -> float:
        """Net displacement of one piece [rad] (cycles return to their start).

        Parameters
        ----------
        piece : tuple
            ``("dwell", T)``, ``("cycles", A, f, n)`` or ``("move", D, v, a)`` [s; rad, Hz, 1; rad, rad/s,
            rad/s^2].
        """
        return float(piece[1]) if piece[0] == "move" else 0.0

    @classmethod
    def from_pieces(cls, pieces: list[tuple[Any, ...]], start: float = 0.0) -> ExcitationProgram:
        """Lay pieces end to end from load angle ``start``.

        Parameters
        ----------
        pieces : list of tuple
            The pieces in order (see :attr:`pieces`).
        start : float
            Load angle the program starts from [rad] (default 0).

        Returns
        -------
        ExcitationProgram
        """
        t, p = 0.0, start
        starts, origins = [], []
        for piece in pieces:
            starts.append(t)
            origins.append(p)
            t += cls.piece_duration(piece)
            p += cls.piece_end(piece)
        return cls(tuple(pieces), tuple(starts), tuple(origins))

    @property
    def duration(self) -> float:
        """Length of the program [s]."""
        return self.starts[-1] + self.piece_duration(self.pieces[-1]) if self.pieces else 0.0

    def _scalar(self, t: float) -> tuple[float, float, float]:
        k = max(0, bisect.bisect_right(self.starts, t) - 1)
        piece, p0, tau = self.pieces[k], self.origins[k], t - self.starts[k]
        kind = piece[0]
        if kind == "dwell" or tau < 0.0:
            return p0, 0.0, 0.0
        if kind == "cycles":
            A, f, n = piece[1], piece[2], piece[3]
            if tau >= n / f:
                return p0, 0.0, 0.0
            w = 2 * math.pi * f
            return p0 + 0.5 * A * (1 - math.cos(w * tau)), 0.5 * A * w * math.sin(w * tau), \
                0.5 * A * w * w * math.cos(w * tau)
        D, v, a = piece[1], piece[2], piece[3]
        sgn = 1.0 if D >= 0 else -1.0
        q, dq, ddq = move_point(tau, abs(D), v, a)
        return p0 + sgn * q, sgn * dq, sgn * ddq

    def at(self, t: Any) -> tuple[Any, Any, Any]:
        """``(r, r', r'')`` of the load angle at time(s) ``t`` [rad, rad/s, rad/s^2].

        Parameters
        ----------
        t : float or array_like
            Time(s) [s].

        Returns
        -------
        tuple
            ``(r, r', r'')``: three floats for a scalar ``t``, else three arrays of ``t``'s shape.
        """
        return pointwise(self._scalar, t)

    def load_disturbance(self, t: float) -> float:
        """No load disturbance during an excitation [N m].

        Parameters
        ----------
        t : float
            Time [s] (unused).

        Returns
        -------
        float
            0.
        """
        return 0.0


def _identify_pattern(A: float) -> list[tuple[Any, ...]]:
    """One period of the identification program (about 10.5 s), scaled by ``A`` [rad]."""
    return [
        ("dwell", 0.3),
        ("cycles", A, 1.0, 2), ("dwell", 0.2),           # slow reversals (0.5 A (2 pi)^2 = 2 rad/s^2 at A = 0.1)
        ("cycles", -0.5 * A, 2.0, 3), ("dwell", 0.2),    # faster, on the other side of the start
        ("cycles", 0.2 * A, 4.0, 4), ("dwell", 0.2),     # fast, small
        ("move", A, 5 * A, 50 * A), ("dwell", 0.3),      # moves at two cruise speeds, with dwells
        ("move", -2 * A, 5 * A, 50 * A), ("dwell", 0.3),
        ("move", 2 * A, 10 * A, 100 * A), ("dwell", 0.3),
        ("move", -A, 10 * A, 100 * A), ("dwell", 0.3),
        ("cycles", -A, 0.5, 1), ("dwell", 0.2),          # one slow, large cycle
    ]


def _moves_pattern(A: float) -> list[tuple[Any, ...]]:
    """One period of the plain back-and-forth program: +A, dwell, -A, dwell at one speed."""
    return [("dwell", 0.2), ("move", A, 5 * A, 50 * A), ("dwell", 0.4), ("move", -A, 5 * A, 50 * A), ("dwell", 0.2)]


def excitation(motion: str = "identify", *, duration: float = 10.0, amplitude: float = 0.1) -> ExcitationProgram:
    """The motion program of an excitation, repeated or cut to ``duration``.

    Parameters
    ----------
    motion : str
        ``"identify"`` (designed: reversals at several accelerations, dwells, moves at two speeds) or
        ``"moves"`` (plain back-and-forth S-curve moves with dwells).
    duration : float
        Length of the program [s].
    amplitude : float
        Largest excursion of the load angle from the start [rad] (default 0.1; pick it well above the lost
        motion ``2 b / r_b2``, within the axis' travel).

    Returns
    -------
    ExcitationProgram
    """
    check_choice("motion", motion, MOTIONS)
    DURATION.check("duration", duration)
    A = AMPLITUDE.check("amplitude", amplitude)
    pattern = _identify_pattern(A) if motion == "identify" else _moves_pattern(A)
    period = sum(ExcitationProgram.piece_duration(p) for p in pattern)
    reps = max(1, math.ceil(duration / period))
    pieces = pattern * reps
    return ExcitationProgram.from_pieces(pieces)


class _RecordBoth(Controller):
    """Pass-through that makes the loop read the load encoder too (the log records both encoders)."""

    def __init__(self, inner: Controller) -> None:
        super().__init__()
        self.inner = inner
        self.name, self.Ts, self.preview = inner.name, inner.Ts, inner.preview
        self.uses_load_encoder = True
        self.realtime = inner.realtime

    def reset(self) -> None:
        self.inner.reset()
        self.solve_times, self.fallbacks = self.inner.solve_times, self.inner.fallbacks

    def step(self, t: float, y_motor: float, y_load: float | None, ref: ReferenceLike) -> float:
        return self.inner.step(t, y_motor, y_load if self.inner.uses_load_encoder else None, ref)

    def describe(self) -> dict[str, Any]:
        return self.inner.describe()


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class Excitation:
    """A recorded excitation: the log a drive would export and the simulation behind it.

    Attributes
    ----------
    log : EncoderLog
        Time, torque command, encoder readings (quantised, noisy) and the reference.
    run : ClosedLoopResult
        The closed-loop simulation (true states).
    plant : Plant
        The true plant.
    program : ExcitationProgram
    model : GearModel
    """

    log: EncoderLog
    run: ClosedLoopResult
    plant: Plant
    program: ExcitationProgram
    model: GearModel


def record_excitation(model: GearModel | str | Path, *, motion: str = "identify", duration: float = 10.0,
                      amplitude: float = 0.1, seed: int = 0, plant: str = "improved", controller: str | Path = "pid",
                      backlash: float | None = None) -> Excitation:
    """Run an excitation on the simulated plant and record its log.

    Parameters
    ----------
    model : GearModel, str or Path
        The true model (its sensors quantise and add noise to the angles).
    motion : str
        ``"identify"`` or ``"moves"`` (:func:`excitation`).
    duration : float
        Length of the log [s].
    amplitude : float
        Scale of the motion [rad of load angle].
    seed : int
        Seed of the encoder noise.
    plant : str
        True plant kind: ``improved``, ``yang-sun`` or ``tvms``.
    controller : str or Path
        The position loop (catalog name or file; default the catalog ``pid``), designed on the model.
    backlash : float, optional
        Replaces the model's backlash [m] in the true plant and the controller's design.

    Returns
    -------
    Excitation

    Raises
    ------
    InputError
        A train, a motion, amplitude, seed, plant or controller not allowed, or a log longer than
        :data:`~gearctl.logs.MAX_LOG_SAMPLES` samples (which identify would refuse).
    """
    m = model if isinstance(model, GearModel) else load_model(model)
    if m.n_stages != 1:
        raise InputError(f"{m.name}: a train of {m.n_stages} stages; excite and identify handle a gear pair (one "
                         f"stage)", field="model")
    program = excitation(motion, duration=duration, amplitude=amplitude)
    SEED.check("seed", seed)
    true = build_plant(m, plant, backlash=backlash)
    nominal = build_plant(m, backlash=backlash)
    ctrl = load_controller(controller, nominal, sensors=m.sensors)
    n = int(round(duration / ctrl.Ts)) + 1
    if n > MAX_LOG_SAMPLES:
        # checked before the run (about 0.1 s of computing per simulated second: beyond 1000 s, minutes spent on a log
        # that identify then refused)
        raise InputError(f"duration = {duration:g} s is too long for a log: {n:,} samples at the controller's period "
                         f"{ctrl.Ts:g} s, more than identify reads ({MAX_LOG_SAMPLES:,}); expected at most "
                         f"{(MAX_LOG_SAMPLES - 1) * ctrl.Ts:.10g} s", field="duration")
    check_output_size(n, true.nx + 8, field="duration", fix="a shorter --duration")
    # the log records the load encoder too, where the servo has one
    rec = _RecordBoth(ctrl) if m.sensors.load_encoder else ctrl
    run = simulate_closed_loop(true, rec, program, duration, sensors=m.sensors, seed=seed)
    notes = (f"gearctl excite: model {m.name}, {plant} plant, backlash {true.backlash:.6g} m, motion {motion}, "
             f"amplitude {amplitude:g} rad, controller {ctrl.name}, seed {seed}")
    log = EncoderLog(t=run.t, torque=run.torque, theta1=run.y_motor,
                     theta2=run.y_load if m.sensors.load_encoder else None,
                     extra={"reference": run.reference}, sample_time=ctrl.Ts, comments=(notes,))
    return Excitation(log=log, run=run, plant=true, program=program, model=m)


def check_reference_duration(duration: float, sample_time: float = 1e-3) -> int:
    """The rows of a reference of ``duration`` [s] at ``sample_time`` [s] for a real drive, checked before anything is
    written or run: a drive's log of more than :data:`~gearctl.logs.MAX_LOG_SAMPLES` samples is one identify refuses.

    Parameters
    ----------
    duration : float
        Length of the reference [s].
    sample_time : float
        Sample period of the rows [s] (default 1e-3).

    Returns
    -------
    int
        ``round(duration / sample_time) + 1``.

    Raises
    ------
    InputError
        Naming ``duration`` and the longest allowed, or where the rows would not fit in memory.
    """
    n = int(round(duration / sample_time)) + 1
    if n > MAX_LOG_SAMPLES:
        raise InputError(f"duration = {duration:g} s is too long for a reference: {n:,} samples at {sample_time:g} s, "
                         f"and the drive's log of it more than identify reads ({MAX_LOG_SAMPLES:,}); expected at most "
                         f"{(MAX_LOG_SAMPLES - 1) * sample_time:.10g} s", field="duration")
    check_output_size(n, 4, field="duration", fix="a shorter --duration")
    return n


def write_reference(path: str | Path, program: ExcitationProgram, *, sample_time: float = 1e-3,
                    duration: float | None = None) -> int:
    """Write a program's reference for a real drive: ``t, reference, velocity, acceleration`` per sample.

    Parameters
    ----------
    path : str or Path
        The CSV file to write (its folder is created).
    program : ExcitationProgram
        The program.
    sample_time : float
        Sample period of the rows [s] (default 1e-3).
    duration : float, optional
        Length of the reference [s] (default: the program's).

    Returns
    -------
    int
        The number of rows written.

    Raises
    ------
    InputError
        For a ``duration`` too long (:func:`check_reference_duration`), or a file that cannot be written.
    """
    T = program.duration if duration is None else duration
    n = check_reference_duration(T, sample_time)
    t = np.arange(n, dtype=np.float64) * sample_time
    r, v, a = program.at(t)
    cols: list[NDArray[np.float64]] = [t, r, v, a]
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "w") as fh:
            fh.write("# gearctl excite --reference-only: load-angle reference [rad], velocity [rad/s], acceleration "
                     "[rad/s^2]\n")
            fh.write("t,reference,velocity,acceleration\n")
            np.savetxt(fh, np.column_stack(cols), fmt="%.10g", delimiter=",")
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror}") from None
    return n
