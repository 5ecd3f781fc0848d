"""Where the original program's example scenes are. They live beside the project, in
``../shared/ipc-examples`` (the curated set) and ``../shared/ipc-examples-full`` (the
original's whole example tree, a superset; a few of its meshes were never published),
never copied into it; tests that need them skip without them. Importable from any test
module (``pythonpath = ["tests"]`` in pyproject.toml)."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
IPC_EXAMPLES = REPO_ROOT.parent / "shared" / "ipc-examples"
IPC_EXAMPLES_FULL = REPO_ROOT.parent / "shared" / "ipc-examples-full"


def _scripts(root: Path) -> list[Path]:
    return sorted(root.joinpath("input").rglob("*.txt")) if root.is_dir() else []


def example_scripts() -> list[Path]:
    """Every scene script of the curated set, or [] when the folder is absent."""
    return _scripts(IPC_EXAMPLES)


def extra_example_scripts() -> list[Path]:
    """The scripts of the full example tree that the curated set does not hold (all of
    them without the curated set), or [] when the full tree is absent."""
    curated = {p.relative_to(IPC_EXAMPLES) for p in example_scripts()}
    return [p for p in _scripts(IPC_EXAMPLES_FULL)
            if p.relative_to(IPC_EXAMPLES_FULL) not in curated]


@lru_cache(maxsize=1)
def _missing_mesh_scripts() -> dict[Path, str]:
    """The extra scripts that name a mesh the tree lacks, with the reader's message."""
    from ipcsim.errors import SceneError
    from ipcsim.scene import load_scene

    missing = {}
    for path in extra_example_scripts():
        try:
            load_scene(path)
        except SceneError as exc:  # any other error is for the tests themselves to show
            if "not found" in str(exc):
                missing[path] = str(exc)
    return missing


def extra_scripts_with_meshes() -> list[Path]:
    """The extra scripts whose meshes all exist."""
    missing = _missing_mesh_scripts()
    return [p for p in extra_example_scripts() if p not in missing]


def extra_scripts_without_meshes() -> dict[Path, str]:
    """The extra scripts that name an absent mesh -> the error that names it."""
    return dict(_missing_mesh_scripts())
