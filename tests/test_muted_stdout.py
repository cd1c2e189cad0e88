"""The MPC's muting of standard output around OSQP's solves (``design/mpc_solvers.py``, ``_MutedStdout``): file
descriptor 1 is the process's, shared by every thread, so muting it must nest across threads (a Dask worker started
with ``--nthreads 2`` runs two MPCs at once) and give descriptor 1 back as it found it."""

from __future__ import annotations

import os
import threading

from gearctl.design.mpc_solvers import _MutedStdout


def _same_file(a: os.stat_result, b: os.stat_result) -> bool:
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


def test_two_threads_muting_at_once_leave_stdout_where_it_was() -> None:
    # thread A mutes, B mutes (saving the null device as "its" stdout), A restores, B restores the null device: the
    # process's standard output stayed on /dev/null for good, every later line of a sweep's worker lost
    before = os.fstat(1)
    keep = os.dup(1)
    a_in, b_in, a_out = threading.Event(), threading.Event(), threading.Event()
    seen: dict[str, os.stat_result] = {}

    def fa() -> str:
        a_in.set()
        assert b_in.wait(10)
        return "a"

    def fb() -> str:
        b_in.set()
        assert a_out.wait(10)
        seen["b"] = os.fstat(1)
        return "b"

    out: dict[str, str] = {}
    ta = threading.Thread(target=lambda: out.__setitem__("a", _MutedStdout().call(fa)))
    tb = threading.Thread(target=lambda: out.__setitem__("b", _MutedStdout().call(fb)))
    try:
        ta.start()
        assert a_in.wait(10)
        tb.start()
        ta.join(10)
        a_out.set()
        tb.join(10)
        after = os.fstat(1)
    finally:
        os.dup2(keep, 1)  # whatever happened, give pytest its descriptor back
        os.close(keep)
    assert out == {"a": "a", "b": "b"}
    assert _same_file(seen["b"], os.stat(os.devnull))  # B's solve still muted after A's ended
    assert _same_file(after, before)


def test_an_exception_in_the_call_restores_stdout_and_leaks_no_descriptor() -> None:
    before = os.fstat(1)
    fds = len(os.listdir("/proc/self/fd"))
    muted = [_MutedStdout() for _ in range(20)]  # one null device for all, not one per QP

    def boom() -> None:
        raise RuntimeError("solver")

    for m in muted:
        try:
            m.call(boom)
        except RuntimeError:
            pass
    assert _same_file(os.fstat(1), before)
    assert len(os.listdir("/proc/self/fd")) <= fds + 1
