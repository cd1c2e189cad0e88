"""The command line's files are written whole or not at all (gearctl.files.write_whole).

A full disk under `gearctl sweep --json FILE` left 1 MB of JSON, not valid JSON, after "cannot write FILE: No
space left on device" (a review), and so did runs.csv under --out; a Ctrl-C while writing could too.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest

from gearctl.cli.common import write_whole


def _fails_midway(exc: BaseException):
    def write(fh) -> None:
        fh.write("{\"runs\": [" + "1, " * 1000)
        raise exc

    return write


@pytest.mark.parametrize("exc", [OSError(errno.ENOSPC, "No space left on device"), KeyboardInterrupt()])
def test_a_failed_write_leaves_no_file_and_no_temporary(tmp_path: Path, exc: BaseException) -> None:
    with pytest.raises(type(exc)):
        write_whole(tmp_path / "s.json", _fails_midway(exc))
    assert list(tmp_path.iterdir()) == []


def test_a_failed_write_keeps_the_old_file(tmp_path: Path) -> None:
    old = tmp_path / "s.json"
    old.write_text('{"old": 1}\n')
    with pytest.raises(OSError):
        write_whole(old, _fails_midway(OSError(errno.ENOSPC, "No space left on device")))
    assert old.read_text() == '{"old": 1}\n' and [p.name for p in tmp_path.iterdir()] == ["s.json"]


def test_text_and_writer_and_the_mode_kept(tmp_path: Path) -> None:
    p = tmp_path / "runs.csv"
    write_whole(p, "a,b\n1,2\n")
    assert p.read_bytes() == b"a,b\n1,2\n"
    os.chmod(p, 0o640)
    write_whole(p, lambda fh: fh.write("x\r\n"))  # newline="": written as given
    assert p.read_bytes() == b"x\r\n" and (p.stat().st_mode & 0o777) == 0o640
    assert [q.name for q in tmp_path.iterdir()] == ["runs.csv"]


def test_a_device_is_written_into(tmp_path: Path) -> None:
    write_whole(os.devnull, "{}\n")  # not replaced by a regular file
    assert Path(os.devnull).exists() and not Path(os.devnull).is_file()
