"""Small generated meshes for tests that write their own scenes."""

from __future__ import annotations

from pathlib import Path

from ipcsim.model.generate import box_tet_mesh, write_msh


def write_box_msh(path, cells=(2, 2, 2), size=(0.2, 0.2, 0.2), base_y=0.0) -> Path:
    """Write a box of ``cells`` (6 tets each) and ``size`` metres to ``path`` (.msh),
    centred on the y axis with its base at height ``base_y``; returns the path."""
    sx, sy, sz = size
    points, tets = box_tet_mesh(*cells, size=size, origin=(-sx / 2, base_y, -sz / 2))
    return write_msh(Path(path), points, tets)
