"""The host's arrows: the shared floors (settings, errors, the grid, run folders, plots, consistency) import no system, and
no two host modules import each other at module level, directly or round a longer cycle."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

HOST = Path(__file__).resolve().parents[2] / "host"

#: Modules every system builds on: they may import each other, never a system (nav, usbl, track, io, ...).
FLOORS = ("config", "errors", "grid", "runfolder", "plotting", "consistency", "shipped")


def _module(path: Path) -> str:
    parts = path.relative_to(HOST).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _top_level_imports(path: Path) -> set[str]:
    """The host modules ``path`` imports when it is imported (not the lazy imports inside its functions)."""
    package = _module(path).split(".") if path.name == "__init__.py" else _module(path).split(".")[:-1]
    found = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.ImportFrom) and node.level > 0:
            base = package[: len(package) - (node.level - 1)] if node.level > 1 else package
            target = [*base, *(node.module.split(".") if node.module else [])]
            names = [".".join(target)] + [".".join([*target, alias.name]) for alias in node.names]
            found |= {n for n in names if n}
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("lost.host."):
            found.add(node.module.removeprefix("lost.host."))
    return found


def _graph() -> dict[str, set[str]]:
    modules = {_module(p): p for p in HOST.rglob("*.py")}
    return {name: {m for m in _top_level_imports(path) if m in modules and m != name} for name, path in modules.items()}


@pytest.mark.parametrize("floor", FLOORS)
def test_a_shared_floor_imports_no_system(floor):
    wrong = []
    path = HOST / f"{floor}.py"
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level > 0 and node.module:
            if node.module.split(".")[0] not in FLOORS:
                wrong.append(node.module)
    assert wrong == []


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    cycles: list[list[str]] = []

    def visit(node: str, path: list[str], done: set[str]) -> None:
        for nxt in sorted(graph[node]):
            if nxt.startswith(node + "."):
                continue  # a package importing its own submodules (its __init__ re-exporting them) is no cycle
            if nxt in path and not node.startswith(nxt + "."):
                cycles.append(path[path.index(nxt):] + [nxt])
            elif nxt not in done and nxt not in path:
                visit(nxt, [*path, nxt], done)
        done.add(node)

    done: set[str] = set()
    for start in sorted(graph):
        if start not in done:
            visit(start, [start], done)
    return cycles


def test_no_import_cycle_between_host_modules():
    assert _cycles(_graph()) == []


def test_the_checks_see_a_cycle_and_read_relative_imports():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "p": {"p.x"}, "p.x": set()}) == [["a", "b", "c", "a"]]
    assert _top_level_imports(HOST / "cli" / "track.py") >= {"runfolder", "track.tracker", "cli.common"}
