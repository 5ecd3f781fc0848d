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
