"""Shared fixtures."""

from __future__ import annotations

from pathlib import Path

import pytest
from examples import IPC_EXAMPLES, REPO_ROOT


@pytest.fixture
def ipc_examples() -> Path:
    if not IPC_EXAMPLES.is_dir():
        pytest.skip("../shared/ipc-examples is not present")
    return IPC_EXAMPLES


@pytest.fixture
def repo_root() -> Path:
    return REPO_ROOT


@pytest.fixture
def pulls_end_by_placement(monkeypatch) -> list:
    """Pulls of prescribed vertices end only in their tail, where ``StepProblem`` places
    the vertices on their targets (never at 99.9 % done); returns what each placement
    attempt gave (the placed x, or None where the move was not free)."""
    from ipcsim.potentials.boundary_pull import PullSchedule
    from ipcsim.potentials.step_problem import StepProblem

    monkeypatch.setattr(PullSchedule, "done", 1.0)
    placed = []
    place = StepProblem._placed

    def placing(self, point):
        got = place(self, point)
        placed.append(None if got is None else got[1].x)
        return got

    monkeypatch.setattr(StepProblem, "_placed", placing)
    return placed
