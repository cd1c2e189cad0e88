"""The ``gearctl`` command line. The only package that prints or exits.

A :class:`~gearctl.errors.GearctlError` becomes one line on stderr and exit code 2; argparse's own usage
errors also exit with 2 (a bad option value in one line, like the others); a closed output pipe (``gearctl models
--json | head``) ends quietly; an output that cannot be written (a full disk: ``gearctl info MODEL --json >
/dev/full``) is one line and exit 2 too. Anything else is a bug and surfaces as a traceback. Each module of this package
registers a group of commands.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import re
import sys
from collections.abc import Callable, Iterable, Sequence
from typing import Any, NoReturn

from .. import __version__
from ..errors import GearctlError, InputError

__all__ = ["main"]

#: What a write to a full or failing output raises: one line on stderr, not a traceback.
_OUTPUT_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO})


def groups() -> tuple[Any, ...]:
    """The command groups, in the order ``gearctl --help`` lists them (imported when the command line runs, not
    when this package is: see :func:`main`)."""
    from . import export_cmds, identify_cmds, loop_cmds, model_cmds, sweep_cmds

    return (model_cmds, loop_cmds, sweep_cmds, identify_cmds, export_cmds)


class _Parser(argparse.ArgumentParser):
    """argparse's parser, reading ``-1e-5`` as a negative number (its own pattern knows ``-1`` and ``-.5`` only, and
    took ``--backlash -1e-5`` for two options: "expected one argument" instead of the value's range). The
    subcommands' parsers are of this class too (``add_subparsers`` makes them of the parent's class)."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        # (a unit typed after it, `--duration -3s`, is a value too: its type then says what is wrong with it, where
        # argparse said "expected one argument")
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?(\s*[^\W\d_][\w/°µ]*)?$")

    def error(self, message: str) -> NoReturn:
        """A bad value of a named option or argument (``argument --duration: -1 is out of range: ...``) is one line
        with a pointer to ``-h``, as every other input error is; the rest (an unknown option, a missing argument)
        keeps argparse's usage above it. Exit status 2 either way. A misspelt choice (``gearctl trak``,
        ``--reference sin``) is told the closest one (Python 3.11's argparse lists them all, without a suggestion)."""
        if message.startswith("argument "):
            m = re.search(r"invalid choice: '(.*)' \(choose from (.*)\)$", message)
            if m is not None:
                import difflib

                choices = re.findall(r"'([^']*)'", m.group(2))
                # the one choice it begins (`--mode sep`), else the closest spelling
                close = [c for c in choices if m.group(1) and c.startswith(m.group(1))]
                close = close if len(close) == 1 else difflib.get_close_matches(m.group(1), choices, n=1,
                                                                                  cutoff=0.6)
                if close:
                    message += f"; did you mean {close[0]!r}?"
            self.exit(2, f"{self.prog}: error: {message} (usage: {self.prog} -h)\n")
        super().error(message)


def _parser() -> tuple[argparse.ArgumentParser, dict[str, Callable[[argparse.Namespace], int]]]:
    ap = _Parser(
        prog="gearctl",
        description="Control design for geared servos with backlash (Shing, Tsai & Krishnaprasad, TR 93-28).",
    )
    ap.add_argument("--version", action="version", version=f"gearctl {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")
    commands: dict[str, Callable[[argparse.Namespace], int]] = {}
    for group in groups():
        commands.update(group.register(sub))
    ap.set_defaults(_subparsers=sub.choices)
    _state_ranges(sub.choices.values())
    return ap, commands


def _state_ranges(parsers: Iterable[argparse.ArgumentParser]) -> None:
    """Append the allowed range to the help of every option parsed against the schema (:func:`common.spec_arg`)
    that does not state one: `gearctl COMMAND --help` gives every option with its unit and range, as the README says
    (a new user found the ranges of --duration, --dt, --travel, --seed ... only in the errors)."""
    for p in parsers:
        for action in p._actions:
            spec = getattr(action.type, "spec", None)
            if spec is None or not action.help or action.help == argparse.SUPPRESS:
                continue
            if "<=" not in action.help and ".." not in action.help:
                action.help = f"{action.help}; {spec.rule()}"


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``gearctl`` command line; return the exit code (0 success, 2 bad input, 130 interrupted).

    The commands' modules (numpy, SciPy ...) are imported here, not with the package: a Ctrl-C while they load
    (the first few tenths of a second) is one line and exit 130 too, not Python's traceback.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments after the program name (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit code.
    """
    try:
        return _main(argv)
    except KeyboardInterrupt:
        print("gearctl: interrupted", file=sys.stderr)
        return 130


def _main(argv: Sequence[str] | None) -> int:
    from . import common
    from .common import check_outputs_writable, refuse_swapped_model_controller, refuse_writing_over_inputs

    parser, commands = _parser()
    try:
        args, extra = parser.parse_known_args(argv)
        if extra:  # said by the subcommand's parser (its usage and name), not the top level's
            args._subparsers[args.command].error(f"unrecognized arguments: {' '.join(extra)}")
    except SystemExit as exc:  # argparse: --help / --version (0) or a usage error (2)
        return int(exc.code or 0)
    try:
        refuse_writing_over_inputs(args)
        refuse_swapped_model_controller(args)
        check_outputs_writable(args)
        if getattr(args, "csv", None) == "-":  # the CSV on standard output, everything else the command says on stderr
            if getattr(args, "json", False):
                raise InputError("--csv - and --json: both would write standard output; give the CSV a file name",
                                 field="csv")
            common.CSV_STDOUT = sys.stdout
            try:
                with contextlib.redirect_stdout(sys.stderr):
                    return commands[args.command](args)
            finally:
                common.CSV_STDOUT = None
        return commands[args.command](args)
    except GearctlError as exc:
        print(f"gearctl {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader went away (`| head`): end quietly, as a Unix tool does
        _stdout_to_devnull()
        return 0
    except OSError as exc:  # a full disk or a failing device under the output (stdout: `> /dev/full`)
        if exc.errno not in _OUTPUT_ERRNOS:
            raise
        print(f"gearctl {args.command}: error: cannot write {exc.filename or 'standard output'}: "
              f"{exc.strerror or exc}", file=sys.stderr)
        _stdout_to_devnull()  # what is still buffered would fail again at exit, as a traceback
        return 2
    except KeyboardInterrupt:  # Ctrl-C: one line, the shell's code for SIGINT (128 + 2), no traceback
        print(f"gearctl {args.command}: interrupted", file=sys.stderr)
        return 130


def _stdout_to_devnull() -> None:
    """Point standard output at the null device, so that the interpreter's flush at exit cannot fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
