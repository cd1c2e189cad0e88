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


@pytest.mark.skipif(not Path("/dev/stdout").exists(), reason="needs /dev/stdout")
@pytest.mark.parametrize("shell", ["| cat", ">> {out}"])
def test_dev_stdout_into_a_pipe_or_an_appended_file(tmp_path: Path, shell: str) -> None:
    """``--json /dev/stdout | ...``: /dev/stdout resolves to ``/proc/PID/fd/pipe:[N]``, where no temporary file can be
    made; it failed after the whole run ("No such file or directory"). Into ``>> file`` it is appended to, not
    truncated (opening /dev/stdout for "w" truncates the file the shell opened)."""
    import shlex
    import subprocess
    import sys

    out = tmp_path / "out.txt"
    out.write_text("kept\n")
    code = "from gearctl.files import write_whole; write_whole('/dev/stdout', '{\"a\": 1}\\n')"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    cmd = f"{shlex.quote(sys.executable)} -c {shlex.quote(code)} {shell.format(out=shlex.quote(str(out)))}"
    done = subprocess.run(cmd, shell=True, capture_output=True, text=True, env=env, timeout=60)
    assert done.returncode == 0, done.stderr
    assert list(tmp_path.iterdir()) == [out]  # no temporary left beside it
    if shell.startswith("|"):
        assert done.stdout == '{"a": 1}\n'
    else:
        assert out.read_text() == 'kept\n{"a": 1}\n'


@pytest.mark.skipif(not (os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK)), reason="needs /dev/shm")
def test_a_file_in_dev_shm_is_replaced_whole() -> None:
    """A regular file under /dev (the tmpfs /dev/shm) was taken for a descriptor's link and appended to: writing
    ``{"a": 2}`` over ``{"a": 1}`` left both, not JSON."""
    import tempfile

    with tempfile.TemporaryDirectory(dir="/dev/shm") as d:
        p = Path(d) / "out.json"
        write_whole(p, '{"a": 1}\n')
        write_whole(p, '{"a": 2}\n')
        assert p.read_text() == '{"a": 2}\n' and [q.name for q in Path(d).iterdir()] == ["out.json"]


@pytest.mark.skipif(not Path("/dev/stdout").exists(), reason="needs /dev/stdout")
def test_a_link_to_dev_stdout_into_a_file_is_appended_to(tmp_path: Path) -> None:
    """A link elsewhere to /dev/stdout, whose descriptor the shell opened on a file with >>, is written into."""
    import shlex
    import subprocess
    import sys

    out = tmp_path / "out.txt"
    out.write_text("kept\n")
    link = tmp_path / "link.json"
    link.symlink_to("/dev/stdout")
    code = f"from gearctl.files import write_whole; write_whole({str(link)!r}, 'new\\n')"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    cmd = f"{shlex.quote(sys.executable)} -c {shlex.quote(code)} >> {shlex.quote(str(out))}"
    done = subprocess.run(cmd, shell=True, capture_output=True, text=True, env=env, timeout=60)
    assert done.returncode == 0, done.stderr
    assert out.read_text() == "kept\nnew\n" and link.is_symlink()


def test_a_devices_temporary_file_is_not_a_name_another_could_plant(tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """A device's temporary file went to the shared temporary folder under a fixed name (``.null.PID.tmp``): a link
    planted there was followed, and the file it led to overwritten with the output."""
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    victim = tmp_path / "victim.txt"
    victim.write_text("kept\n")
    (tmp_path / f".null.{os.getpid()}.tmp").symlink_to(victim)
    write_whole(os.devnull, "output\n")
    assert victim.read_text() == "kept\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([f".null.{os.getpid()}.tmp", "victim.txt"])
