"""The examples in gearctl's docstrings run and print what they say (a stale example misleads more than none)."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import gearctl


def test_docstring_examples() -> None:
    names = sorted(m.name for m in pkgutil.walk_packages(gearctl.__path__, "gearctl.")
                   if not m.name.startswith("gearctl._"))
    failed, attempted = [], 0
    for name in names:
        result = doctest.testmod(importlib.import_module(name), optionflags=doctest.NORMALIZE_WHITESPACE,
                                 verbose=False, report=False)
        attempted += result.attempted
        if result.failed:
            failed.append(f"{name}: {result.failed} of {result.attempted}")
    assert attempted >= 10, attempted  # the examples are there to be checked
    assert not failed, failed
