"""Where the original program's example scenes are. They live beside the project, in
``../shared/ipc-examples`` (never copied into it); tests that need them skip without them.
Importable from any test module (``pythonpath = ["tests"]`` in pyproject.toml)."""

from __future__ import annotations

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
IPC_EXAMPLES = REPO_ROOT.parent / "shared" / "ipc-examples"


def example_scripts() -> list[Path]:
    """Every scene script of the original program, or [] when the folder is absent."""
    if not IPC_EXAMPLES.is_dir():
        return []
    return sorted(IPC_EXAMPLES.joinpath("input").rglob("*.txt"))
