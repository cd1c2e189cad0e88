"""Import structure of the package, read from the source with ``ast`` (STYLE.md, "Layout and one-way flow").

- Only ``plots.py`` and ``cli.py`` import matplotlib, and ``import gearctl`` loads neither matplotlib
  nor the CLI or plotting modules.
- Nothing imports ``gearctl.cli``; only ``gearctl.cli`` imports ``gearctl.plots``.
- Modules named in the STYLE.md data flow import only from modules to their left, and the module-level
  imports between submodules have no cycle.

Every module under ``gearctl/`` is scanned (``design/`` and any future subpackage included), so the
checks cover new modules without editing this file.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import gearctl

PKG_DIR = Path(gearctl.__file__).resolve().parent

# STYLE.md: units/errors -> geometry -> stiffness -> plant -> modes -> design/ -> simulate -> metrics
#           -> bench -> plots -> cli. Modules not listed (params, catalog, summary, ...) are not ranked.
FLOW = [
    "gearctl.errors", "gearctl.units", "gearctl.geometry", "gearctl.stiffness", "gearctl.plant",
    "gearctl.modes", "gearctl.design", "gearctl.simulate", "gearctl.metrics", "gearctl.bench",
    "gearctl.plots", "gearctl.cli",
]


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PKG_DIR.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def package_modules() -> dict[str, Path]:
    return {
        module_name(p): p
        for p in sorted(PKG_DIR.rglob("*.py"))
        if "__pycache__" not in p.parts
    }


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING"
    )


def imports_of(name: str, path: Path, *, module_level_only: bool = False) -> set[str]:
    """Absolute names a module imports (``from . import x`` gives both the package and ``pkg.x``).

    Imports under ``if TYPE_CHECKING:`` are skipped (they never run). With ``module_level_only``,
    imports inside functions and classes are skipped too.
    """
    tree = ast.parse(path.read_text(), filename=str(path))
    is_package = path.name == "__init__.py"
    package = name if is_package else name.rpartition(".")[0]
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child):
                for sub in child.orelse:
                    visit_stmt(sub)
                continue
            if module_level_only and isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                continue
            visit_stmt(child)

    def visit_stmt(node: ast.AST) -> None:
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base_parts = package.split(".")
                base_parts = base_parts[: len(base_parts) - (node.level - 1)]
                base = ".".join(base_parts)
                target = f"{base}.{node.module}" if node.module else base
            else:
                target = node.module or ""
            found.add(target)
            found.update(f"{target}.{alias.name}" for alias in node.names)
        visit(node)

    visit(tree)
    return found


def _imports(names: set[str], target: str) -> bool:
    return any(n == target or n.startswith(target + ".") for n in names)


MODULES = package_modules()


def test_scan_sees_the_package() -> None:
    # guards the scan itself: it must find the modules we know exist
    known = {"gearctl", "gearctl.geometry", "gearctl.stiffness", "gearctl.cli", "gearctl.plots"}
    assert known <= set(MODULES)
    assert "gearctl.plots" in {n for n in imports_of("gearctl.cli", MODULES["gearctl.cli"])}


def test_only_plots_and_cli_import_matplotlib() -> None:
    users = {name for name, path in MODULES.items() if _imports(imports_of(name, path), "matplotlib")}
    assert users <= {"gearctl.plots", "gearctl.cli"}, users
    assert "gearctl.plots" in users


def test_nothing_imports_cli_and_only_cli_imports_plots() -> None:
    for name, path in MODULES.items():
        names = imports_of(name, path)
        if name != "gearctl.cli":
            assert not _imports(names, "gearctl.cli"), f"{name} imports gearctl.cli"
            assert not _imports(names, "gearctl.plots"), f"{name} imports gearctl.plots"


def _rank(name: str) -> int | None:
    for i, prefix in enumerate(FLOW):
        if name == prefix or name.startswith(prefix + "."):
            return i
    return None


def test_one_way_flow() -> None:
    """A ranked module imports no ranked module to its right (lazy imports in functions count)."""
    backward = []
    for name, path in MODULES.items():
        r = _rank(name)
        if r is None:
            continue
        for target in imports_of(name, path):
            t = _rank(target)
            if t is not None and t > r:
                backward.append(f"{name} -> {target}")
    assert not backward, backward


def test_no_import_cycles_between_submodules() -> None:
    """Module-level imports between submodules (packages' ``__init__`` excluded) form no cycle."""
    graph = {
        name: {t for t in imports_of(name, path, module_level_only=True) if t in MODULES and t != name}
        for name, path in MODULES.items()
        if path.name != "__init__.py"
    }
    graph = {n: {t for t in ts if t in graph} for n, ts in graph.items()}
    state: dict[str, int] = {}  # 1 visiting, 2 done
    stack: list[str] = []

    def dfs(n: str) -> None:
        state[n] = 1
        stack.append(n)
        for t in sorted(graph[n]):
            if state.get(t) == 1:
                cycle = stack[stack.index(t):] + [t]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if t not in state:
                dfs(t)
        stack.pop()
        state[n] = 2

    for n in sorted(graph):
        if n not in state:
            dfs(n)


def test_import_gearctl_loads_no_matplotlib() -> None:
    code = (
        "import sys, gearctl\n"
        "bad = sorted(m for m in sys.modules if m == 'matplotlib' or m.startswith('matplotlib.')\n"
        "             or m in ('gearctl.cli', 'gearctl.plots'))\n"
        "print(','.join(bad))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "", result.stdout


def test_scanner_resolves_relative_and_lazy_imports(tmp_path: Path) -> None:
    """The scanner itself: relative imports, ``from . import``, TYPE_CHECKING and lazy imports."""
    src = tmp_path / "x.py"
    src.write_text(
        "from typing import TYPE_CHECKING\n"
        "from ..plots import save\n"
        "from . import pid\n"
        "if TYPE_CHECKING:\n"
        "    from ..cli import main\n"
        "def f():\n"
        "    import matplotlib.pyplot\n"
    )
    found = imports_of("gearctl.design.x", src)
    assert {"gearctl.plots", "gearctl.design.pid", "matplotlib.pyplot"} <= found
    assert not _imports(found, "gearctl.cli")
    assert _rank("gearctl.design.x") is not None and _rank("gearctl.design.x") < _rank("gearctl.plots")
    assert not _imports(imports_of("gearctl.design.x", src, module_level_only=True), "matplotlib")
