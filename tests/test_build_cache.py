"""The compiled-code cache stays bounded (s1's review: 671 files, 268 MB, one per exported controller ever run, never
removed): each name keeps the CACHE_KEEP libraries used last."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from gearctl import build
from gearctl.build import CACHE_KEEP, c_compiler, compile_disabled, shared_library

pytestmark = pytest.mark.skipif(c_compiler() is None or compile_disabled(), reason="no C compiler")


def _lib(i: int):  # noqa: ANN202 - a ctypes.CDLL
    return shared_library("cachetest", {"t.c": f"int f(void) {{ return {i}; }}\n".encode()}, required=True)


def test_each_name_keeps_the_libraries_used_last(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(build, "_LOADED", {})  # a fresh process's view: every call finds its file on disk
    files = []
    for i in range(CACHE_KEEP):
        assert _lib(i).f() == i
        files.append(max((tmp_path / "gearctl").glob("cachetest-*.so"), key=os.path.getmtime))
        t = time.time() - 1000 + i  # distinct ages, oldest first
        os.utime(files[-1], (t, t))
    build._LOADED.clear()
    assert _lib(0).f() == 0  # the oldest is used again: now the newest
    build._LOADED.clear()
    for i in range(CACHE_KEEP, CACHE_KEEP + 3):  # three more: the three least recently used go
        assert _lib(i).f() == i
    left = set((tmp_path / "gearctl").glob("cachetest-*.so"))
    assert len(left) == CACHE_KEEP
    assert files[0] in left  # used again, so kept
    assert not {files[1], files[2], files[3]} & left  # the three used least recently
    other = tmp_path / "gearctl" / "cachetest_other-0123456789abcdef.so"
    other.write_bytes(b"")  # another name that begins alike is not counted or removed
    assert _lib(CACHE_KEEP + 3).f() == CACHE_KEEP + 3
    assert other.exists()
