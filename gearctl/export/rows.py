"""The reference rows an exported controller reads, and the test vectors recorded from the Python controller.

The C step reads ``GEARCTL_PREVIEW`` rows ``(r, r', r'')`` of the load-angle reference at ``t, t + Ts, ...``.
:class:`PreviewRows` evaluates them exactly as the Python controller does (a controller of preview 1 calls
``ref.at(t)``; the MPC evaluates the reference in blocks of ``512 + N + 2`` samples from the time a block
starts), so that the C and the Python controller see the same numbers to the last bit.

Test vectors (``gearctl_vectors.bin`` in an exported folder): per case (a 3 s sine, a move) the encoder
readings, the reference rows and the torque the Python controller gave in gearctl's closed loop. Layout,
all little-endian::

    "GCXV"  int32 version (1)  int32 preview  int32 cases
    per case: int32 steps  int32 rows
              float64 table[rows][3]     reference rows (a step reads preview consecutive rows)
              int32   first[steps]       the first row of each step
              float64 y[steps][2]        motor, load encoder [rad] (NaN: not used)
              float64 u[steps]           the Python controller's torque [N m]
"""

from __future__ import annotations

import dataclasses
import math
import struct
from pathlib import Path
from typing import Any

import numpy as np

from ..controller import Controller, ReferenceLike
from ..errors import InputError, SimulationError

__all__ = ["PreviewRows", "Case", "record_cases", "write_vectors", "read_vectors", "VECTORS_FILE"]

VECTORS_FILE = "gearctl_vectors.bin"
_MAGIC = b"GCXV"


class PreviewRows:
    """Reference rows ``(r, r', r'')`` at ``t, t + Ts, ...`` as the Python controller evaluates them.

    Parameters
    ----------
    Ts : float
        Sample period [s].
    preview : int
        Rows per step (1: ``ref.at(t)``; ``N + 1`` for an MPC of horizon ``N``: blocks as
        :meth:`gearctl.design.mpc.MPC._preview` computes them).
    """

    def __init__(self, Ts: float, preview: int) -> None:
        self.Ts, self.preview = Ts, preview
        self._one = np.zeros((1, 3))
        self.reset()

    def reset(self) -> None:
        """Forget the cached block (a new run)."""
        self._ref: Any = None
        self._t0 = 0.0
        self._len = 0
        self._rows = np.zeros((1, 3))
        self.block = 0  # counts the blocks evaluated (the recorder dedupes rows by it)

    def at(self, t: float, ref: ReferenceLike) -> tuple[np.ndarray, int]:
        """The rows array and the index of the row at ``t`` (the step reads ``preview`` rows from there).

        Parameters
        ----------
        t : float
            Sample time [s].
        ref : ReferenceLike
            The load-angle reference.

        Returns
        -------
        rows : ndarray, shape (k, 3)
            ``(r, r', r'')`` rows [rad, rad/s, rad/s^2] (one row for a preview of 1, else the cached block); the
            array is reused by later calls.
        index : int
            The row at ``t``.
        """
        if self.preview == 1:
            r, rd, rdd = ref.at(t)
            one = self._one[0]
            one[0], one[1], one[2] = r, rd, rdd
            self.block += 1
            return self._one, 0
        n = self.preview - 1
        Ts = self.Ts
        if ref is self._ref:  # the MPC's test, word for word
            k = round((t - self._t0) / Ts)
            if 0 <= k <= self._len - n - 2 and abs(self._t0 + k * Ts - t) <= 1e-9 * max(1.0, abs(t)):
                return self._rows, k
        self._ref, self._t0 = ref, t
        self._len = 512 + n + 2
        tt = t + Ts * np.arange(self._len)
        r, rd, rdd = (np.asarray(v, dtype=float) for v in ref.at(tt))
        self._rows = np.ascontiguousarray(np.stack([r, rd, rdd], axis=1))
        self.block += 1
        return self._rows, 0


@dataclasses.dataclass(frozen=True)
class Case:
    """One recorded closed-loop run: what the controller read and what it returned.

    Parameters
    ----------
    name : str
        The case's label (``case<i>`` when read back from a file).
    table : ndarray, shape (rows, 3)
        The reference rows ``(r, r', r'')`` [rad, rad/s, rad/s^2]; a step reads ``preview`` consecutive rows.
    first : ndarray of int, shape (steps,)
        The first row of each step.
    y : ndarray, shape (steps, 2)
        Motor and load encoder readings [rad] (NaN: not used).
    u : ndarray, shape (steps,)
        The Python controller's torque [N m].
    warnings : tuple of str
        What was wrong with the recorded loop (:func:`gearctl.metrics.loop_health`; not stored in the file).
    """

    name: str
    table: np.ndarray  # (rows, 3)
    first: np.ndarray  # (steps,) int
    y: np.ndarray  # (steps, 2)
    u: np.ndarray  # (steps,)
    warnings: tuple[str, ...] = ()  # what was wrong with the recorded loop (gearctl.metrics.loop_health)

    @property
    def steps(self) -> int:
        """Number of steps."""
        return int(self.u.size)


class _Recorder(Controller):
    """Wraps a controller; records its inputs (as the C would get them) and its torques."""

    def __init__(self, inner: Controller) -> None:
        super().__init__()
        self.inner = inner
        self.name, self.Ts, self.preview = inner.name, inner.Ts, inner.preview
        self.uses_load_encoder = inner.uses_load_encoder
        self.rows = PreviewRows(inner.Ts, inner.preview)
        self.reset()

    def reset(self) -> None:
        self.inner.reset()
        self.rows.reset()
        self.blocks: dict[int, np.ndarray] = {}
        self.used: dict[int, int] = {}
        self.steps: list[tuple[int, int]] = []
        self.ys: list[tuple[float, float]] = []
        self.us: list[float] = []

    @property
    def solve_times(self) -> list[float]:
        return self.inner.solve_times

    @solve_times.setter
    def solve_times(self, v: list[float]) -> None:
        pass

    @property
    def fallbacks(self) -> list[dict[str, Any]]:
        return self.inner.fallbacks

    @fallbacks.setter
    def fallbacks(self, v: list[dict[str, Any]]) -> None:
        pass

    @property
    def overruns(self) -> int:
        return getattr(self.inner, "overruns", 0)

    @overruns.setter
    def overruns(self, v: int) -> None:
        pass

    def step(self, t: float, y_motor: float, y_load: float | None, ref: ReferenceLike) -> float:
        arr, k = self.rows.at(t, ref)
        blk = self.rows.block
        if blk not in self.blocks:
            self.blocks[blk] = arr.copy() if self.preview == 1 else arr
        self.used[blk] = max(self.used.get(blk, 0), k + self.preview)
        self.steps.append((blk, k))
        self.ys.append((float(y_motor), math.nan if y_load is None else float(y_load)))
        u = self.inner.step(t, y_motor, y_load, ref)
        self.us.append(float(u))
        return u

    def describe(self) -> dict[str, Any]:
        return self.inner.describe()

    def case(self, name: str) -> Case:
        base, parts, off = {}, [], 0
        for blk in sorted(self.used):
            base[blk] = off
            parts.append(self.blocks[blk][: self.used[blk]])
            off += self.used[blk]
        table = np.concatenate(parts) if parts else np.zeros((0, 3))
        first = np.array([base[b] + k for b, k in self.steps], dtype=np.int32)
        return Case(name=name, table=np.ascontiguousarray(table, dtype=float), first=first,
                    y=np.array(self.ys, dtype=float).reshape(-1, 2), u=np.array(self.us, dtype=float))


def record_cases(controller: Controller, plant: Any, *, sensors: Any = None,
                 cases: tuple[tuple[str, float], ...] = (("sine", 3.0), ("move", 1.0)), seed: int = 0) -> list[Case]:
    """Run the Python controller in gearctl's closed loop on each reference and record what it read and gave.

    Parameters
    ----------
    controller : Controller
        The Python controller (reset before each run).
    plant : Plant
        The plant the loop runs on (the controller's nominal plant, for the exported vectors).
    sensors : Sensors, optional
        Encoders (default: ideal).
    cases : tuple of (str, float)
        Reference kind (:func:`gearctl.references.reference`) and duration [s] per case.
    seed : int
        Sensor-noise seed.

    Returns
    -------
    list of Case
        A run that fails part-way (divergence, an event cascade) is recorded up to where it stopped.
    """
    from ..closedloop import simulate_closed_loop
    from ..metrics import loop_health
    from ..references import reference

    rec = _Recorder(controller)
    out = []
    for kind, duration in cases:
        try:
            res = simulate_closed_loop(plant, rec, reference(kind), duration, sensors=sensors, seed=seed)
            warnings = loop_health(res).warnings if res.success else (res.message,)
        except SimulationError as exc:  # the steps taken are recorded: they are what the C must reproduce
            warnings = (str(exc),)
        out.append(dataclasses.replace(rec.case(kind), warnings=tuple(warnings)))
    controller.reset()
    return out


def write_vectors(path: Path, preview: int, cases: list[Case]) -> None:
    """Write the cases in the layout of the module docstring.

    Parameters
    ----------
    path : Path
        The file to write (replaced).
    preview : int
        Rows per step.
    cases : list of Case
        The recorded runs (names and warnings are not written).
    """
    with open(path, "wb") as f:
        f.write(_MAGIC + struct.pack("<iii", 1, preview, len(cases)))
        for c in cases:
            f.write(struct.pack("<ii", c.steps, c.table.shape[0]))
            f.write(np.ascontiguousarray(c.table, dtype="<f8").tobytes())
            f.write(np.ascontiguousarray(c.first, dtype="<i4").tobytes())
            f.write(np.ascontiguousarray(c.y, dtype="<f8").tobytes())
            f.write(np.ascontiguousarray(c.u, dtype="<f8").tobytes())


def read_vectors(path: Path) -> tuple[int, list[Case]]:
    """Read a vectors file: ``(preview, cases)``.

    Parameters
    ----------
    path : Path
        A file :func:`write_vectors` wrote.

    Returns
    -------
    preview : int
        Rows per step.
    cases : list of Case
        The runs, named ``case0``, ``case1``, ...

    Raises
    ------
    InputError
        If the file is not a gearctl vectors file.
    """
    data = Path(path).read_bytes()
    if data[:4] != _MAGIC or len(data) < 16:
        raise InputError(f"{path} is not a gearctl test-vector file", field="vectors")
    version, preview, n = struct.unpack_from("<iii", data, 4)
    if version != 1:
        raise InputError(f"{path}: vectors version {version}: expected 1", field="vectors")
    pos, cases = 16, []
    for i in range(n):
        steps, rows = struct.unpack_from("<ii", data, pos)
        pos += 8

        def take(count: int, dtype: str, shape: tuple[int, ...]) -> np.ndarray:
            nonlocal pos
            size = np.dtype(dtype).itemsize * count
            a = np.frombuffer(data, dtype=dtype, count=count, offset=pos).reshape(shape).astype(dtype[1:])
            pos += size
            return a

        table = take(rows * 3, "<f8", (rows, 3))
        first = take(steps, "<i4", (steps,))
        y = take(steps * 2, "<f8", (steps, 2))
        u = take(steps, "<f8", (steps,))
        cases.append(Case(name=f"case{i}", table=table, first=first, y=y, u=u))
    return preview, cases
