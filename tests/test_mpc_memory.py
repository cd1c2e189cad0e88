"""An MPC design whose condensed QPs would not fit is refused before they are built (a horizon of 200 samples at
0.1 ms, both within their ranges, took 24 GB and the kernel's out-of-memory kill on a 1:1 pair)."""

from __future__ import annotations

import io
import time
from pathlib import Path

import pytest

import gearctl
from gearctl.design.mpc import _pattern_bytes, _pattern_count


def _mpc_file(tmp_path: Path, horizon: int, sample_time: float) -> Path:
    path = tmp_path / f"mpc_h{horizon}.toml"
    path.write_text(f'kind = "mpc"\nsample_time = {sample_time!r}\nhorizon = {horizon}\n[source]\nnotes = "test"\n')
    return path


def test_a_design_that_would_not_fit_is_refused_first(tmp_path: Path) -> None:
    model = gearctl.load_model("shing1993_servo")
    plant = gearctl.build_plant(model)
    start = time.perf_counter()
    with pytest.raises(gearctl.InputError) as exc:
        gearctl.load_controller(_mpc_file(tmp_path, 200, 1e-4), plant, sensors=model.sensors)
    assert time.perf_counter() - start < 30.0  # refused before the patterns are built (they took 17 min)
    msg = str(exc.value)
    assert exc.value.field == "horizon"
    assert "mpc_h200.toml: horizon = 200 samples: the MPC's " in msg and "condensed QPs would take about " in msg
    assert "a horizon of at most " in msg and "samples fits" in msg


def test_the_estimate_counts_the_patterns_built(tmp_path: Path) -> None:
    model = gearctl.load_model("shing1993_servo")
    plant = gearctl.build_plant(model)
    ctrl = gearctl.load_controller(_mpc_file(tmp_path, 20, 1e-3), plant, sensors=model.sensors)
    assert len(ctrl._patterns) == _pattern_count(20, ctrl.n_cross, ctrl._rigid)
    pat = next(iter(ctrl._patterns.values()))
    arrays = pat.H.nbytes + pat.K.nbytes + sum(a.nbytes for a in pat.A.values()) + sum(
        m.nbytes for m in pat.M.values())
    # the pattern's own arrays, plus the solver's Hessian factor and C-order rows: n^2 + 2 (n + 2) n doubles
    assert _pattern_bytes(20) == arrays + 8 * (20 * 20 + 2 * 22 * 20)


def test_available_memory_counts_what_the_kernel_can_reclaim() -> None:
    # SC_AVPHYS_PAGES is the free memory alone (MemFree): with gigabytes in the page cache it was a few hundred MB, and
    # the MPC's cap (half of it) refused designs that fit. On Linux the figure is the kernel's MemAvailable
    import os

    from gearctl.limits import available_memory

    meminfo = Path("/proc/meminfo")
    if not meminfo.exists():
        pytest.skip("no /proc/meminfo")
    fields = dict(line.split(":", 1) for line in meminfo.read_text().splitlines() if ":" in line)
    if "MemAvailable" not in fields:
        pytest.skip("no MemAvailable")
    want = int(fields["MemAvailable"].split()[0]) * 1024
    got = available_memory()
    assert got is not None and abs(got - want) < 256 * 1024**2, (got, want)
    free = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    assert got >= free - 256 * 1024**2


def test_the_design_reports_its_progress(tmp_path: Path) -> None:
    # a long horizon's design takes minutes (80 s at 150 samples on a 1:1 pair): it reports the share of its condensed
    # QPs built, one call each, rising to 1; a PID is designed at once and never calls it
    model = gearctl.load_model("shing1993_servo")
    plant = gearctl.build_plant(model)
    seen: list[float] = []
    ctrl = gearctl.load_controller(_mpc_file(tmp_path, 20, 1e-3), plant, sensors=model.sensors, progress=seen.append)
    assert len(seen) == len(ctrl._patterns)
    assert seen == sorted(seen) and seen[0] > 0.0 and seen[-1] == 1.0
    pid_seen: list[float] = []
    gearctl.load_controller("pid", plant, progress=pid_seen.append)
    assert pid_seen == []


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_design_bar_shows_only_once_the_design_is_slow(monkeypatch: pytest.MonkeyPatch) -> None:
    # the CLI's bar for a duration it cannot tell beforehand (an MPC's design): nothing for a quick one, a bar on the
    # terminal once it has taken the threshold
    from gearctl.cli.common import progress_bar

    for wait, shown in ((0.0, False), (0.3, True)):
        term = _Terminal()
        monkeypatch.setattr("sys.stderr", term)
        with progress_bar("design", expected_s=None, threshold=0.1) as bar:
            time.sleep(wait)
            for k in range(1, 11):
                bar(k / 10)
        assert ("design" in term.getvalue()) is shown, term.getvalue()
