"""Smoke run of the paper's time-step table: three steps of the h = 0.1 script."""

from __future__ import annotations

import pytest
from examples import IPC_EXAMPLES

from benchmarks.tb1_diffdt import PAPER, STEPS, main


def test_smoke_row_has_ipcsims_and_the_papers_figures(capsys):
    if not IPC_EXAMPLES.is_dir():
        pytest.skip("../shared/ipc-examples is not present")
    assert set(PAPER) == set(STEPS)
    assert main(["--smoke"]) == 0
    row = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("| 0.1 |")]
    assert len(row) == 1
    cells = [c.strip() for c in row[0].strip("|").split("|")]
    assert cells[5] != "0" and float(cells[3]) >= 1.0  # Newton iterations were taken
    assert cells[6] == "clean"  # every frame passed the exact checker
    assert cells[7] == "597 (1.3K)" and cells[9] == "4.75"  # the paper's row for h = 0.1
