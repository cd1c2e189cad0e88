"""Exceptions raised by gearctl.

Every error a user can cause is an :class:`InputError`; the CLI turns any :class:`GearctlError` into one
line on stderr and exit code 2. Anything else escaping gearctl is a bug.
"""

from __future__ import annotations

from typing import Any

__all__ = ["GearctlError", "InputError", "SimulationError", "SolverError", "short_repr"]


class GearctlError(Exception):
    """Base class of the errors gearctl raises on purpose."""


class InputError(GearctlError, ValueError):
    """Bad user input: a missing, unknown, mistyped or out-of-range value.

    Parameters
    ----------
    message : str
        One line naming the field, the value and the allowed range.
    field : str, optional
        Name of the offending field (dataclass field or TOML key), if there is one.
    rule : str, optional
        What was expected, e.g. ``"is out of range: expected a number with 0 < value <= 0.1 [m]"``;
        lets the TOML loader restate the message with the file and key the user typed.
    """

    def __init__(self, message: str, *, field: str | None = None, rule: str | None = None) -> None:
        super().__init__(message)
        self.field = field
        self.rule = rule


class SimulationError(GearctlError, RuntimeError):
    """A simulation that diverged, produced NaN or could not continue.

    Parameters
    ----------
    message : str
        What went wrong, when (simulated time) and where.
    result : object, optional
        The partial result up to the failure, so nothing computed is lost.
    """

    def __init__(self, message: str, *, result: Any = None) -> None:
        super().__init__(message)
        self.result = result


class SolverError(GearctlError, RuntimeError):
    """An optimisation solver could not be built or run at all (not a per-step failure)."""


def short_repr(value: Any, width: int = 80) -> str:
    """``repr(value)`` on one line and at most ``width`` characters, for an :class:`InputError`'s message.

    An array's repr breaks its rows over lines and a model's runs to a page: the message must stay one line.
    A gear model (it has ``servo`` and a ``name``) is shown as ``<GearModel 'name'>``.

    Parameters
    ----------
    value : object
        What to show.
    width : int
        Most characters (default 80); a longer repr is cut and ends in ``...``.

    Returns
    -------
    str

    Examples
    --------
    >>> short_repr("x" * 100, width=10)
    "'xxxxxx..."
    """
    name = getattr(value, "name", None)
    if hasattr(value, "servo") and isinstance(name, str):
        return f"<{type(value).__name__} {name!r}>"
    text = " ".join(repr(value).split())
    return text if len(text) <= width else text[:width - 3] + "..."
