"""Shared fixtures. The original program's example scenes live beside the project, in
``../shared/ipc-examples`` (not copied into it); tests that need them skip without them."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
IPC_EXAMPLES = REPO_ROOT.parent / "shared" / "ipc-examples"


def example_scripts() -> list[Path]:
    """Every scene script of the original program, or [] when the folder is absent."""
    if not IPC_EXAMPLES.is_dir():
        return []
    return sorted(IPC_EXAMPLES.joinpath("input").rglob("*.txt"))


@pytest.fixture
def ipc_examples() -> Path:
    if not IPC_EXAMPLES.is_dir():
        pytest.skip("../shared/ipc-examples is not present")
    return IPC_EXAMPLES


@pytest.fixture
def repo_root() -> Path:
    return REPO_ROOT
