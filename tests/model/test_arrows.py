"""Arrows downward: model imports numpy and the standard library only, hdl no sim or host, sim no host."""

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

#: For each folder, the top-level packages it may not import (any ``lost`` package but those allowed).
FORBIDDEN = {
    "model": ("lost.hdl", "lost.sim", "lost.host"),
    "hdl": ("lost.sim", "lost.host"),
    "sim": ("lost.host",),
}


def _imports(path: Path) -> list[str]:
    """Every module a file imports, at any depth (lazy imports inside functions count too)."""
    names = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.append(node.module)
    return names


@pytest.mark.parametrize("folder", sorted(FORBIDDEN))
def test_no_import_points_up(folder):
    wrong = [(str(path.relative_to(ROOT)), name) for path in sorted((ROOT / folder).rglob("*.py"))
             for name in _imports(path) if name.startswith(FORBIDDEN[folder])]
    assert wrong == []


def test_model_needs_numpy_only():
    outside = sorted({(str(path.relative_to(ROOT)), name) for path in (ROOT / "model").rglob("*.py")
                      for name in _imports(path)
                      if name.split(".")[0] not in sys.stdlib_module_names | {"numpy", "lost"}})
    assert outside == []


def test_the_check_sees_an_upward_import(tmp_path):
    module = tmp_path / "m.py"
    module.write_text("def f():\n    from lost.host.correlator import driver\n")
    assert _imports(module) == ["lost.host.correlator"]
