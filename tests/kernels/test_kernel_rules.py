"""House rules of ipcsim/kernels/, read from the source: a kernel that other kernel modules
use is public in its module (no file imports another's underscore names), and no kernel
function is longer than 80 lines."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

KERNELS = Path(__file__).resolve().parents[2] / "ipcsim" / "kernels"
FILES = sorted(KERNELS.rglob("*.py"))


def _tree(path):
    return ast.parse(path.read_text(encoding="utf-8"), filename=str(path))


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.relative_to(KERNELS).as_posix())
def test_no_private_names_imported_across_files(path):
    private = []
    for node in ast.walk(_tree(path)):
        if isinstance(node, ast.ImportFrom) and node.module != "__future__":
            private += [a.name for a in node.names if a.name.startswith("_")]
        elif isinstance(node, ast.Attribute) and node.attr.startswith("_") \
                and not node.attr.startswith("__") and isinstance(node.value, ast.Name) \
                and node.value.id != "self":
            private.append(f"{node.value.id}.{node.attr}")
    assert private == []


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.relative_to(KERNELS).as_posix())
def test_no_kernel_function_is_longer_than_80_lines(path):
    long = [(n.name, n.end_lineno - n.lineno + 1) for n in ast.walk(_tree(path))
            if isinstance(n, ast.FunctionDef) and n.end_lineno - n.lineno + 1 > 80]
    assert long == []
