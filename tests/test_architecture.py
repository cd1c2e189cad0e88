"""Import structure of the package, read from the source with ``ast`` (issue 16: layers that show).

The layers, bottom up (each module may import its own layer and the layers below, never above):

0. foundation: errors, units (the parameter schema), files (catalog files), limits, build (compile and cache),
   qp (the embedded QP solver);
1. model: geometry, stiffness, params, model;
2. plant: plant (one plant for a pair and a train; the dynamics as data), modes (linear models), oracle
   (an independent solve_ivp solution);
3. simulation: kernel, simulate, references, controller (the interface the loop calls), closedloop;
4. design: the controllers (``gearctl.design``);
5. analysis: catalog (files to models and controllers), summary, metrics, runs, precision, bench, describe,
   perf and the later tools (logs: the servo log format that identify reads);
6. apps: plots, cli.

Checked here, counting imports inside functions too (a lazy import is still a dependency):

- every module belongs to a layer and imports no module of a higher layer;
- the imports between gearctl's modules form no cycle;
- only ``plots`` and the CLI import matplotlib; nothing below the apps imports them;
- importing the simulation layer (``gearctl.closedloop``) loads neither matplotlib nor python-control, and
  ``import gearctl`` loads no matplotlib.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import gearctl

PKG_DIR = Path(gearctl.__file__).resolve().parent

LAYERS: dict[str, int] = {
    "gearctl.errors": 0, "gearctl.units": 0, "gearctl.files": 0, "gearctl.limits": 0, "gearctl.build": 0,
    "gearctl.qp": 0,
    "gearctl.geometry": 1, "gearctl.stiffness": 1, "gearctl.params": 1, "gearctl.model": 1,
    "gearctl.plant": 2, "gearctl.modes": 2, "gearctl.oracle": 2, "gearctl.overrides": 2,
    "gearctl.kernel": 3, "gearctl.simulate": 3, "gearctl.references": 3, "gearctl.controller": 3,
    "gearctl.closedloop": 3,
    "gearctl.design": 4,
    "gearctl.catalog": 5, "gearctl.summary": 5, "gearctl.metrics": 5, "gearctl.runs": 5, "gearctl.precision": 5,
    "gearctl.bench": 5, "gearctl.describe": 5, "gearctl.perf": 5, "gearctl.identify": 5, "gearctl.sweep": 5,
    "gearctl.excite": 5, "gearctl.parallel": 5, "gearctl._worker_setup": 5, "gearctl.logs": 5,
    "gearctl.export": 5,
    "gearctl.plots": 6, "gearctl.cli": 6,
}
NAMES = {0: "foundation", 1: "model", 2: "plant", 3: "simulation", 4: "design", 5: "analysis", 6: "apps"}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PKG_DIR.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def package_modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PKG_DIR.rglob("*.py")) if "__pycache__" not in p.parts}


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


def layer_of(name: str) -> int | None:
    best = None
    for prefix, layer in LAYERS.items():
        if (name == prefix or name.startswith(prefix + ".")) and (best is None or len(prefix) > len(best[0])):
            best = (prefix, layer)
    return None if best is None else best[1]


MODULES = package_modules()


def _internal(name: str, path: Path) -> set[str]:
    """gearctl modules imported by ``name`` (inside functions too), resolved to modules that exist."""
    out = set()
    for t in imports_of(name, path):
        while t and t not in MODULES:
            t = t.rpartition(".")[0]
        if t and t != name and t != "gearctl":
            out.add(t)
    return out


def test_scan_sees_the_package() -> None:
    # guards the scan itself: it must find the modules we know exist, and see a lazy import
    known = {"gearctl", "gearctl.geometry", "gearctl.kernel", "gearctl.cli", "gearctl.plots", "gearctl.design.mpc"}
    assert known <= set(MODULES)
    assert "gearctl.plots" in _internal("gearctl.cli.loop_cmds", MODULES["gearctl.cli.loop_cmds"])


def test_every_module_has_a_layer() -> None:
    missing = sorted(n for n in MODULES if n != "gearctl" and layer_of(n) is None)
    assert not missing, f"add these modules to LAYERS: {missing}"


def test_no_import_reaches_a_higher_layer() -> None:
    """Lazy imports in functions count: a dependency is a dependency."""
    upward = []
    for name, path in MODULES.items():
        if name == "gearctl":
            continue
        own = layer_of(name)
        for target in _internal(name, path):
            t = layer_of(target)
            if t is not None and own is not None and t > own:
                upward.append(f"{name} ({NAMES[own]}) -> {target} ({NAMES[t]})")
    assert not upward, upward


def test_no_import_cycles() -> None:
    """No cycle between gearctl's modules, counting imports inside functions (packages' __init__ excluded)."""
    graph = {n: {t for t in _internal(n, p) if MODULES[t].name != "__init__.py"}
             for n, p in MODULES.items() if p.name != "__init__.py"}
    state: dict[str, int] = {}  # 1 visiting, 2 done
    stack: list[str] = []

    def dfs(n: str) -> None:
        state[n] = 1
        stack.append(n)
        for t in sorted(graph.get(n, ())):
            if state.get(t) == 1:
                cycle = stack[stack.index(t):] + [t]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if t not in state and t in graph:
                dfs(t)
        stack.pop()
        state[n] = 2

    for n in sorted(graph):
        if n not in state:
            dfs(n)


def test_only_apps_import_matplotlib_and_nothing_imports_the_apps() -> None:
    users = {name for name, path in MODULES.items() if _imports(imports_of(name, path), "matplotlib")}
    assert users and all(layer_of(u) == LAYERS["gearctl.plots"] for u in users), users
    for name, path in MODULES.items():
        if layer_of(name) == LAYERS["gearctl.plots"] or name == "gearctl":
            continue
        deps = _internal(name, path)
        assert not any(_imports({d}, "gearctl.cli") or _imports({d}, "gearctl.plots") for d in deps), name


def _loaded_after(statement: str) -> list[str]:
    code = (
        f"import sys\n{statement}\n"
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('matplotlib', 'control')\n"
        "             or m in ('gearctl.cli', 'gearctl.plots'))\n"
        "print(','.join(bad))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert result.returncode == 0, result.stderr
    return [m for m in result.stdout.strip().split(",") if m]


def test_simulation_layer_loads_no_plotting_and_no_python_control() -> None:
    assert _loaded_after("import gearctl.closedloop, gearctl.simulate, gearctl.kernel") == []


def test_import_gearctl_loads_no_matplotlib() -> None:
    loaded = _loaded_after("import gearctl")
    assert not [m for m in loaded if m.startswith("matplotlib") or m.startswith("gearctl.")], loaded


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
    assert layer_of("gearctl.design.x") == 4 < layer_of("gearctl.plots")
    assert not _imports(imports_of("gearctl.design.x", src, module_level_only=True), "matplotlib")


def test_layer_check_can_fail(tmp_path: Path) -> None:
    """An upward lazy import is what the layer test must catch: the plant importing the CLI."""
    src = tmp_path / "plant.py"
    src.write_text("def f():\n    from .cli import main\n")
    deps = {t for t in imports_of("gearctl.plant", src) if t.startswith("gearctl.")}
    assert any(layer_of(t) > layer_of("gearctl.plant") for t in deps)


def test_every_public_name_resolves_to_one_object() -> None:
    """``gearctl.<name>`` for each name of ``__all__`` imports, and asking twice gives the same object (a lazy
    function named like its submodule would turn into the module once the submodule is imported)."""
    import importlib

    import gearctl

    for name in gearctl.__all__:
        first = getattr(gearctl, name)
        importlib.import_module("gearctl.simulate")  # what closedloop, bench, ... import anyway
        assert getattr(gearctl, name) is first, name
    assert gearctl.export_controller.__module__ == "gearctl.export.emit"
