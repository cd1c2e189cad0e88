"""Shared fixtures: the report's example pair and temporary model files built from it.

References
----------
Shing, Tsai & Krishnaprasad, "An Improved Model for the Dynamics of Spur Gear Systems with Backlash
Consideration", ISR TR 93-28 (1993), section 3.2 (the example pair).
"""

from __future__ import annotations

import signal
from collections.abc import Callable, Mapping
from pathlib import Path

import pytest

from gearctl import GearModel, Plant, build_plant, load_model
from gearctl.catalog import resolve
from gearctl.kernel import compiled_available

# A test run started in the background of a non-interactive shell (`cmd &`) inherits SIGINT ignored, and so does every
# process it starts: the Ctrl-C tests then see their command run on (exit 0 for 130). Take Ctrl-C back; a child gets
# the default disposition on exec, and Python's KeyboardInterrupt with it.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_configure(config: pytest.Config) -> None:
    # Narrow ignore, not ours: when a hypothesis test fails, hypothesis's pytest plugin imports libcst
    # (to suggest an @example patch), and libcst's import triggers mypy_extensions' DeprecationWarning.
    # Under filterwarnings = error that warning escapes a plugin hook and aborts the whole session with
    # INTERNALERROR instead of reporting the failing test.
    config.addinivalue_line(
        "filterwarnings", "ignore:mypy_extensions.TypedDict is deprecated:DeprecationWarning"
    )


@pytest.fixture(scope="session")
def shing() -> GearModel:
    """The report's example pair (TR 93-28 section 3.2), loaded from the catalog."""
    return load_model("shing1993")


@pytest.fixture(scope="session")
def shing_toml_text() -> str:
    """Text of the catalog file ``shing1993.toml``, the template of every temporary model file."""
    return resolve("shing1993", "models").read_text()


@pytest.fixture
def write_model(tmp_path: Path, shing_toml_text: str) -> Callable[..., Path]:
    """Return ``write(replace_pairs, name="model.toml") -> Path``.

    Writes ``shing1993.toml`` into ``tmp_path`` after ``text.replace(old, new)`` for each pair (a mapping
    or a sequence of pairs). Every ``old`` must occur in the template, so a test cannot pass because
    its edit silently did nothing after the catalog file changed.
    """

    def write(
        replace_pairs: Mapping[str, str] | list[tuple[str, str]] = (), name: str = "model.toml"
    ) -> Path:
        text = shing_toml_text
        pairs = replace_pairs.items() if isinstance(replace_pairs, Mapping) else replace_pairs
        for old, new in pairs:
            assert old in text, f"template shing1993.toml has no {old!r}"
            text = text.replace(old, new)
        path = tmp_path / name
        path.write_text(text)
        return path

    return write


def require_compiled(compiled: bool | None) -> None:
    """Skip a compiled-path check where the C kernel cannot be built."""
    if compiled and not compiled_available():
        pytest.skip("compiled kernel not available (no C compiler, or GEARCTL_NO_COMPILE set)")


@pytest.fixture(scope="module")
def improved(shing: GearModel) -> Plant:
    """The report's pair, improved plant (computed k, eq 38 damping, linear law)."""
    return build_plant(shing)
