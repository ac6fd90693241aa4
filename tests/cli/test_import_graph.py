"""The import graph of the ncbot packages: no cycle (module-level or inside functions) and imports only downward.

Every `import` statement of every module is read with `ast`, wherever it sits (top of file, inside a function or
a class), so a cycle hidden behind a function-local import is found as well. ``from pkg import name`` counts as an
import of ``pkg`` itself (the statement reads ``name`` off the package, so it needs ``pkg/__init__`` to have run)
and, when ``pkg.name`` is a module, of that module too. Inside a package, siblings are therefore imported by their
full module name (``from ncbot.logs.schemas import X`` or ``import ncbot.logs.schemas as schemas``), never through the package.
The package direction is the one of docs/design.md and docs/architecture.md.
"""
from __future__ import annotations

import ast
from pathlib import Path


ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("fileio", "envs", "modules", "vision", "speech", "logs", "robot_sim", "pipelines")
#: What each package may import (besides itself): pipelines -> robot_sim -> vision/modules/speech/logs -> envs -> fileio.
ALLOWED = {
    "fileio": set(),
    "envs": {"fileio"},
    "vision": {"fileio"},
    "modules": {"envs", "fileio"},
    "speech": {"envs", "fileio"},
    "logs": {"envs", "fileio"},
    "robot_sim": {"envs", "modules", "vision", "speech", "logs", "fileio"},
    "pipelines": {"envs", "modules", "vision", "speech", "logs", "robot_sim", "fileio"},
}


def _module_name(path: Path) -> str:
    parts = ["ncbot", *path.relative_to(ROOT).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for package in PACKAGES for p in sorted((ROOT / package).rglob("*.py"))}


def import_edges() -> dict[str, dict[str, int]]:
    """{module: {imported ncbot module: line of the first such import}} for every ncbot module."""
    modules = _modules()

    def owner(name: str) -> str | None:  # `a.b.c` -> the longest prefix that is an ncbot module
        parts = name.split(".")
        while parts and ".".join(parts) not in modules:
            parts.pop()
        return ".".join(parts) or None

    graph: dict[str, dict[str, int]] = {}
    for name, path in modules.items():
        edges: dict[str, int] = {}
        package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            targets: list[str | None] = []
            if isinstance(node, ast.Import):
                targets = [owner(alias.name) for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = package[: len(package) - node.level + 1] if node.level else []
                source = ".".join(base + ([node.module] if node.module else []))
                targets = [owner(source)] + [f"{source}.{alias.name}" for alias in node.names
                                             if f"{source}.{alias.name}" in modules]
            for target in targets:
                if target is not None and target != name:
                    edges.setdefault(target, node.lineno)
        graph[name] = edges
    return graph


def import_cycles(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for other in graph.get(node, {}):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def _describe(cycle: list[str], graph: dict[str, dict[str, int]]) -> str:
    members = set(cycle)
    edges = [f"{a}:{line} -> {b}" for a in cycle for b, line in sorted(graph[a].items()) if b in members]
    return " <-> ".join(cycle) + " (" + "; ".join(edges) + ")"


def test_the_walker_sees_every_kind_of_import() -> None:
    """The graph must hold module-level and function-local imports, or the cycle test could never fail."""
    graph = import_edges()
    assert {f"ncbot.{p}" for p in PACKAGES} <= set(graph), "every package's __init__ is a node"
    assert "ncbot.logs.reader" in graph["ncbot.logs"]  # logs/__init__ re-exports from ncbot.logs.reader (module level)
    assert "ncbot.pipelines.agents" in graph["ncbot.pipelines.evaluate.games"]  # imported inside evaluate_checkpoint
    assert "ncbot.logs.reader" in graph["ncbot.logs.writer"] and "ncbot.logs.schemas" in graph["ncbot.logs.writer"]  # import a.b as c
    assert import_cycles({"a": {"b": 1}, "b": {"c": 2}, "c": {"a": 3}, "d": {"a": 4}}) == [["a", "b", "c"]]


def test_no_import_cycles() -> None:
    graph = import_edges()
    cycles = [c for c in import_cycles(graph)]
    assert not cycles, "import cycles:\n" + "\n".join(_describe(c, graph) for c in cycles)


def test_packages_import_only_downward() -> None:
    wrong = []
    for name, edges in import_edges().items():
        package = name.split(".")[1]
        for target, line in sorted(edges.items()):
            other = target.split(".")[1]
            if other != package and other not in ALLOWED[package]:
                wrong.append(f"{name}:{line} imports {target} ({package} may import {sorted(ALLOWED[package]) or 'nothing'})")
    assert not wrong, "imports against the package direction:\n" + "\n".join(wrong)


def test_every_package_is_walked_and_installed() -> None:
    """A new top-level package must join the walk (with its place in ALLOWED) and ship (pyproject's package list)."""
    found = {p.parent.name for p in ROOT.glob("*/__init__.py")} - {"tests", "bench", "scripts", "ncbot"}
    assert found <= set(PACKAGES), f"add {sorted(found - set(PACKAGES))} to PACKAGES and ALLOWED"
    import tomllib

    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    folders = {".".join(p.parent.relative_to(ROOT).parts) for package in PACKAGES for p in (ROOT / package).rglob("__init__.py")}
    assert set(setuptools["packages"]) == {"ncbot"} | {f"ncbot.{f}" for f in folders}, "list every package under [tool.setuptools] packages"
    assert setuptools["package-dir"] == {"ncbot": "ncbot"} | {f"ncbot.{p}": p for p in PACKAGES}
