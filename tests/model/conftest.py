"""Fixtures for the model tests: small generated meshes written to a temporary folder."""

from __future__ import annotations

from pathlib import Path

import pytest

from ipcsim.model.generate import box_tet_mesh, write_msh


@pytest.fixture
def mesh_dir(tmp_path) -> Path:
    """A folder with cube1.msh (one cell, 8 vertices, [0,1]^3), cube3.msh (3x3x3 cells),
    bar.msh (4x1x1 cells over [0,4]x[0,1]x[0,1]) and tri.obj (one triangle)."""
    write_msh(tmp_path / "cube1.msh", *box_tet_mesh(1, 1, 1))
    write_msh(tmp_path / "cube3.msh", *box_tet_mesh(3, 3, 3))
    write_msh(tmp_path / "bar.msh", *box_tet_mesh(4, 1, 1, size=(4.0, 1.0, 1.0)))
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 3 2\n")
    return tmp_path
