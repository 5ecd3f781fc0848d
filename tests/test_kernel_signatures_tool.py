"""tools/kernel_signatures.py --add keeps every line of the table and adds the new calls."""

from __future__ import annotations

import importlib.util
from pathlib import Path

from ipcsim.compiler import aot

TOOL = Path(__file__).resolve().parents[1] / "tools" / "kernel_signatures.py"


def _tool():
    spec = importlib.util.spec_from_file_location("kernel_signatures", TOOL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_adding_calls_keeps_the_tables_lines_once_each_in_order(tmp_path):
    tool = _tool()
    table = [line for line in aot.TABLE.read_text(encoding="utf-8").splitlines()
             if line and not line.startswith("#")]
    new = "linalg.cholesky_solve(float32[:, ::1], float32[::1], float32[::1])"
    text = tool.merged(table, [new, table[0]])
    lines = [line for line in text.splitlines() if line and not line.startswith("#")]
    assert lines == sorted(set(table) | {new}) and len(lines) == len(table) + 1
    path = tmp_path / "signatures.txt"
    path.write_text(text, encoding="utf-8")
    assert len(aot.read_table(path)) == len(table) + 1  # the file reads back as a table
