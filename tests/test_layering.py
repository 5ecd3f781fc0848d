"""The package's layers: only ipcsim/kernels/ imports numba, and ipcsim/scene/ (reading
and writing scene files) does not depend on ipcsim/io/ (run output)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "ipcsim"


def imported_modules(path: Path) -> set[str]:
    """Absolute names of the modules a file imports (relative imports resolved)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts[:-1])
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                parts = parts[: len(parts) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            names.add(base)
            names.update(f"{base}.{alias.name}" for alias in node.names)
    return names


SOURCES = sorted(PACKAGE.rglob("*.py"))


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.relative_to(PACKAGE).as_posix())
def test_only_kernels_import_numba(path):
    if path.relative_to(PACKAGE).parts[0] == "kernels":
        return
    assert not any(m == "numba" or m.startswith("numba.") for m in imported_modules(path))


@pytest.mark.parametrize("path", sorted((PACKAGE / "scene").rglob("*.py")),
                         ids=lambda p: p.name)
def test_scene_does_not_import_io(path):
    assert not any(m == "ipcsim.io" or m.startswith("ipcsim.io.")
                   for m in imported_modules(path))


def test_the_layering_test_sees_imports():
    scene_init = imported_modules(PACKAGE / "scene" / "__init__.py")
    assert "ipcsim.atomic.atomic_write_text" in scene_init
    assert "numba" in imported_modules(PACKAGE / "kernels" / "distance.py")
