"""Compile-and-cache: C sources gearctl generates or ships, built once per content into a per-user cache.

Every compiled piece of gearctl (the simulation kernel, the MPC's QP, an exported controller's SIL
library) goes through :func:`shared_library`: the sources and the exact command are hashed, the library is
built with the system C compiler the first time that hash is seen, written atomically (parallel workers
may race) and loaded with :mod:`ctypes`. Where there is no compiler, or ``GEARCTL_NO_COMPILE`` is set,
:func:`shared_library` returns None and the caller takes its pure-Python path.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from collections.abc import Sequence
from pathlib import Path

__all__ = ["cache_dir", "c_compiler", "compile_disabled", "shared_library", "prune_cache", "CACHE_KEEP", "CompileError"]


class CompileError(RuntimeError):
    """The C compiler failed (the message holds its output)."""


def cache_dir() -> Path:
    """Per-user folder of gearctl's compiled code (``$XDG_CACHE_HOME/gearctl`` or ``~/.cache/gearctl``)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "gearctl"


def c_compiler() -> str | None:
    """The C compiler to build gearctl's compiled code with, or None where there is none."""
    cc = os.environ.get("CC") or (sysconfig.get_config_var("CC") or "cc").split()[0]
    for cand in (cc, "cc", "gcc", "clang"):
        if shutil.which(cand):
            return cand
    return None


def compile_disabled() -> bool:
    """Whether the user asked for the pure-Python paths (``GEARCTL_NO_COMPILE`` set)."""
    return bool(os.environ.get("GEARCTL_NO_COMPILE"))


_LOADED: dict[Path, ctypes.CDLL] = {}

#: Libraries of one name (one kind of code: an exported controller's kind, the kernel, ...) the cache keeps, the
#: ones used last: each exported controller run in Python builds its own (its parameters are in its sources), and a
#: test run or a study of many exports left 671 files, 268 MB, in the cache, never removed.
CACHE_KEEP = 32


def prune_cache(name: str, *, keep: Path | None = None) -> list[Path]:
    """Remove all but the :data:`CACHE_KEEP` libraries of ``name`` used last from :func:`cache_dir` (never ``keep``,
    the one just built); returns the removed paths.

    A library another process has loaded stays usable (the mapping outlives the file). Files it cannot remove
    (another process pruning at once, permissions) are left.

    Parameters
    ----------
    name : str
        Stem of the cached files (:func:`shared_library`'s ``name``).
    keep : Path, optional
        A library never removed and counted among those kept (the one just built).

    Returns
    -------
    list of Path
        The files removed.
    """
    d = cache_dir()
    suffix = ".dll" if sys.platform == "win32" else ".so"
    entries = []
    for f in d.glob(f"{name}-*{suffix}"):
        stem = f.name[len(name) + 1:-len(suffix)]
        if len(stem) != 16 or any(c not in "0123456789abcdef" for c in stem) or f == keep:
            continue  # another name that begins alike (export_pid against export_pid_load)
        try:
            entries.append((f.stat().st_mtime, f))
        except OSError:
            continue
    entries.sort(reverse=True)
    removed = []
    for _, f in entries[CACHE_KEEP - (keep is not None):]:
        try:
            f.unlink()
            removed.append(f)
        except OSError:
            pass
    return removed


def shared_library(name: str, sources: dict[str, bytes], *, flags: Sequence[str] = ("-O2",),
                   libs: Sequence[str] = ("-lm",), include: Sequence[Path] = (), required: bool = False
                   ) -> ctypes.CDLL | None:
    """Build (once per content) and load a shared library from C sources.

    Parameters
    ----------
    name : str
        Stem of the cached file (the content hash is appended).
    sources : dict of str to bytes
        File name -> content. Files ending in ``.c`` are compiled; the others (headers) are written next
        to them.
    flags, libs : sequence of str
        Compiler flags and libraries (part of the hash).
    include : sequence of Path
        Extra include folders.
    required : bool
        Raise :class:`CompileError` instead of returning None when compilation is impossible or fails.

    Returns
    -------
    ctypes.CDLL or None
        None where there is no compiler, ``GEARCTL_NO_COMPILE`` is set, or the build failed (unless
        ``required``).
    """
    if compile_disabled() and not required:
        return None
    cc = c_compiler()
    if cc is None:
        if required:
            raise CompileError("no C compiler found (set CC, or install gcc or clang)")
        return None
    inc = [f"-I{p}" for p in include]
    cmd_tail = [*flags, "-shared", "-fPIC", *inc]
    h = hashlib.sha256()
    for fname in sorted(sources):
        h.update(fname.encode() + b"\0" + sources[fname] + b"\0")
    h.update(" ".join([cc, *cmd_tail, *libs, sys.version]).encode())
    suffix = ".dll" if sys.platform == "win32" else ".so"
    target = cache_dir() / f"{name}-{h.hexdigest()[:16]}{suffix}"
    if target in _LOADED:
        return _LOADED[target]
    if not target.exists():
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
                for fname, content in sources.items():
                    (Path(tmp) / fname).write_bytes(content)
                out = Path(tmp) / target.name
                c_files = [str(Path(tmp) / f) for f in sorted(sources) if f.endswith(".c")]
                proc = subprocess.run([cc, *cmd_tail, f"-I{tmp}", "-o", str(out), *c_files, *libs],
                                      capture_output=True, timeout=300, text=True)
                if proc.returncode != 0:
                    raise CompileError(f"{cc} failed on {name}: {proc.stderr.strip()[:2000]}")
                os.replace(out, target)  # atomic: parallel processes may race here
        except (OSError, subprocess.SubprocessError, CompileError) as exc:
            if required:
                raise CompileError(str(exc)) from exc
            return None
        prune_cache(name, keep=target)
    else:
        try:  # a use: the pruning keeps the libraries used last
            os.utime(target)
        except OSError:
            pass
    try:
        lib = ctypes.CDLL(str(target))
    except OSError as exc:
        if required:
            raise CompileError(f"cannot load {target}: {exc}") from exc
        return None
    _LOADED[target] = lib
    return lib
