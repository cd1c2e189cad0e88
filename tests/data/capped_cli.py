"""Run ``gearctl`` commands in this process and record how each ended (a helper of the robustness and fuzz tests).

Started by tests/test_robustness.py and tests/test_fuzz.py as a child process under a memory cap
(``RLIMIT_AS``) and a timeout::

    python tests/data/capped_cli.py RESULTS.jsonl < commands.json

or from a test, :func:`run_capped` (which starts it and reads the results back). For many runs,
:class:`ForkServer` keeps one warm process (gearctl and its dependencies imported) and forks a capped child
per job: the same isolation (memory cap, timeout, fresh state) without seconds of imports per job.

``commands.json`` is a JSON list of argv lists. Each command runs through ``gearctl.cli.main(argv)`` with
stdout and stderr captured, and two JSON lines are appended to RESULTS.jsonl: ``{"start": i, "argv": ...}``
before it runs (so a hang or a kill names the command), and after it ends::

    {"i", "argv", "rc", "stdout_bytes", "stdout", "stderr", "wall", "maxrss_mb", "error", "traceback"}

``error`` is the class name of the :class:`gearctl.GearctlError` the command raised (``InputError``,
``SimulationError``, ...; None if it raised none); ``traceback`` is the formatted traceback of any other
exception that escaped ``main`` (a bug: the CLI would have printed it), with ``rc`` None. ``stdout`` keeps
the first STDOUT_KEEP characters (enough for a whole ``--json`` object: a short simulation's ``impact_times``
can run to tens of kB); ``maxrss_mb`` is this process's peak resident memory so far.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import os
import resource
import subprocess
import sys
import time
import traceback
import warnings
from pathlib import Path
from typing import Any

#: Default memory cap of a child [bytes] (address space: numpy, CasADi and the compiled kernels fit in 3 GB).
MEMORY_CAP = 3 * 1024**3
#: Characters of a command's stdout kept in its record (and parsed as its JSON) [1].
STDOUT_KEEP = 2_000_000


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_commands(commands: list[list[str]], out_path: str) -> None:
    """Run each command through ``gearctl.cli.main`` in this process; append the records to ``out_path``."""
    import gearctl.cli as cli
    from gearctl.errors import GearctlError

    raised: list[str] = []
    make_parser = cli._parser

    def recording_parser():  # wrap every command: note the GearctlError it raises, then let main handle it
        ap, cmds = make_parser()

        def wrap(fn):
            def run(args):
                try:
                    return fn(args)
                except GearctlError as exc:
                    raised.append(type(exc).__name__)
                    raise
            return run

        return ap, {name: wrap(fn) for name, fn in cmds.items()}

    cli._parser = recording_parser
    try:
        with open(out_path, "a") as log:
            for i, argv in enumerate(commands):
                log.write(json.dumps({"start": i, "argv": argv}) + "\n")
                log.flush()
                raised.clear()
                out, err = io.StringIO(), io.StringIO()
                rc, tb = None, None
                t0 = time.perf_counter()
                with warnings.catch_warnings():
                    warnings.simplefilter("default")  # as a fresh `gearctl` process shows them (once per place)
                    try:
                        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                            rc = cli.main(argv)
                    except BaseException:  # noqa: BLE001 (a bug in gearctl: record it, go on with the next one)
                        tb = traceback.format_exc()
                wall = time.perf_counter() - t0
                text = out.getvalue()
                rec = {"i": i, "argv": argv, "rc": rc, "stdout_bytes": len(text.encode()), "stdout": text[:STDOUT_KEEP],
                       "stderr": err.getvalue(), "wall": wall, "maxrss_mb": _peak_mb(),
                       "error": raised[-1] if raised else None, "traceback": tb}
                log.write(json.dumps(rec) + "\n")
                log.flush()
    finally:
        cli._parser = make_parser


def main() -> int:
    if sys.argv[1] == "--serve":
        return serve()
    run_commands(json.loads(sys.stdin.read()), sys.argv[1])
    return 0


def serve() -> int:
    """A warm server: import gearctl once, then fork one capped child per job read from stdin.

    Each stdin line is a job ``{"commands", "results", "timeout", "memory", "stderr"}``; the child sets
    ``RLIMIT_AS``, sends its own stdout and stderr to the file ``stderr`` (C-level output, a crash), runs the
    commands and exits; the server kills it past ``timeout`` and answers one line on stdout:
    ``{"returncode", "timed_out", "wall"}``. Forking saves each model the 2-5 s of importing numpy, SciPy,
    python-control and CasADi, which would otherwise dominate a fuzz run of a thousand models.
    """
    import gearctl.cli  # noqa: F401  (warm: every module a command imports lazily)
    for group in gearctl.cli.groups():  # the commands' modules, which main imports when it runs
        assert group.register
    import gearctl.closedloop  # noqa: F401
    import gearctl.design.registry  # noqa: F401
    import gearctl.modes  # noqa: F401
    import gearctl.precision  # noqa: F401
    import gearctl.runs  # noqa: F401
    import gearctl.simulate  # noqa: F401
    import gearctl.summary  # noqa: F401

    for line in sys.stdin:
        job = json.loads(line)
        t0 = time.perf_counter()
        pid = os.fork()
        if pid == 0:  # the child
            code = 0
            try:
                fd = os.open(job["stderr"], os.O_WRONLY | os.O_CREAT | os.O_APPEND)
                os.dup2(fd, 1)
                os.dup2(fd, 2)
                devnull = os.open(os.devnull, os.O_RDONLY)
                os.dup2(devnull, 0)
                resource.setrlimit(resource.RLIMIT_AS, (job["memory"], job["memory"]))
                run_commands(job["commands"], job["results"])
            except BaseException:  # noqa: BLE001
                traceback.print_exc()
                code = 3
            finally:
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(code)
        timed_out = False
        while True:
            done, status = os.waitpid(pid, os.WNOHANG)
            if done:
                break
            if time.perf_counter() - t0 > job["timeout"]:
                os.kill(pid, 9)
                _, status = os.waitpid(pid, 0)
                timed_out = True
                break
            time.sleep(0.01)
        rc = os.waitstatus_to_exitcode(status)
        print(json.dumps({"returncode": rc, "timed_out": timed_out, "wall": time.perf_counter() - t0}), flush=True)
    return 0


@dataclasses.dataclass
class CappedRun:
    """What a child run of :func:`run_capped` gave.

    Attributes
    ----------
    results : list of dict
        One record per command that ended (see the module docstring), in order.
    hung : list or None
        The argv of the command that was running when the child was killed (timeout or crash), else None.
    timed_out : bool
        The child ran past its timeout and was killed.
    returncode : int or None
        The child's exit status (negative: killed by a signal; None after a timeout).
    stderr : str
        What the child wrote to its real stderr outside the captured commands (C-level output, a crash).
    wall : float
        Wall time of the child [s].
    """

    results: list[dict[str, Any]]
    hung: list[str] | None
    timed_out: bool
    returncode: int | None
    stderr: str
    wall: float


def run_capped(commands: list[list[str]], results: Path, *, timeout: float, memory: int = MEMORY_CAP,
               env: dict[str, str] | None = None) -> CappedRun:
    """Run ``commands`` (argv lists) through ``gearctl.cli.main`` in one child process under a memory cap.

    Parameters
    ----------
    commands : list of list of str
        The command lines, without the leading ``gearctl``.
    results : Path
        The JSON-lines file the child writes (appended to; start with a fresh path).
    timeout : float
        Wall-time budget of the whole child [s]; past it the child is killed.
    memory : int
        ``RLIMIT_AS`` of the child [bytes].
    """

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (memory, memory))

    full_env = dict(os.environ)
    full_env.update({"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"})
    if env:
        full_env.update(env)
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), str(results)], stdin=subprocess.PIPE,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, preexec_fn=cap,
                            env=full_env)
    timed_out = False
    try:
        _, err = proc.communicate(json.dumps(commands), timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
        timed_out = True
    wall = time.perf_counter() - t0
    return _read_results(results, timed_out=timed_out, returncode=None if timed_out else proc.returncode,
                         stderr=err or "", wall=wall)


def _read_results(results: Path, *, timed_out: bool, returncode: int | None, stderr: str, wall: float) -> CappedRun:
    done: list[dict[str, Any]] = []
    started: dict[int, list[str]] = {}
    if results.exists():
        for line in results.read_text().splitlines():
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:  # a line cut short by the kill
                continue
            if "start" in rec:
                started[rec["start"]] = rec["argv"]
            else:
                done.append(rec)
    finished = {r["i"] for r in done}
    hung = next((argv for i, argv in sorted(started.items()) if i not in finished), None)
    return CappedRun(results=done, hung=hung, timed_out=timed_out, returncode=returncode, stderr=stderr, wall=wall)


class ForkServer:
    """A warm :func:`serve` process; :meth:`run` is :func:`run_capped` without the start-up cost.

    Use as a context manager; one job at a time per server (start one per worker thread).
    """

    def __init__(self) -> None:
        env = dict(os.environ)
        env.update({"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"})
        self.proc = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), "--serve"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)

    def run(self, commands: list[list[str]], results: Path, *, timeout: float, memory: int = MEMORY_CAP) -> CappedRun:
        """Run ``commands`` in a forked child of the server, under ``memory`` and ``timeout`` (as run_capped)."""
        err_path = results.with_suffix(".stderr")
        job = {"commands": commands, "results": str(results), "timeout": timeout, "memory": memory,
               "stderr": str(err_path)}
        self.proc.stdin.write(json.dumps(job) + "\n")
        self.proc.stdin.flush()
        answer = self.proc.stdout.readline()
        if not answer:
            raise RuntimeError("the fork server died")
        a = json.loads(answer)
        err = err_path.read_text(errors="replace") if err_path.exists() else ""
        return _read_results(results, timed_out=a["timed_out"], returncode=None if a["timed_out"] else a["returncode"],
                             stderr=err, wall=a["wall"])

    def __enter__(self) -> ForkServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.proc.stdin.close()
        try:
            self.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.proc.stdout.close()


if __name__ == "__main__":
    sys.exit(main())
