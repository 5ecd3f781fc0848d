"""Procedural meshes and the project's generated input meshes."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from ipcsim.model.generate import box_tet_mesh, write_msh
from ipcsim.model.mesh_io import read_tet_mesh
from ipcsim.model.surface import tet_signed_volumes


@pytest.mark.parametrize("dims,size,origin", [((1, 1, 1), (1, 1, 1), (0, 0, 0)),
                                              ((3, 2, 5), (2.0, 0.5, 1.0), (-1, 2, 3))])
def test_box_tet_mesh(dims, size, origin):
    points, tets = box_tet_mesh(*dims, size=size, origin=origin)
    nx, ny, nz = dims
    assert points.shape == ((nx + 1) * (ny + 1) * (nz + 1), 3)
    assert tets.shape == (6 * nx * ny * nz, 4) and tets.dtype == np.int64
    vol = tet_signed_volumes(points, tets)
    assert np.all(vol > 0)
    assert vol.sum() == pytest.approx(np.prod(size))
    assert np.allclose(points.min(axis=0), origin)
    assert np.allclose(points.max(axis=0), np.add(origin, size))
    assert len(np.unique(tets)) == len(points)  # every vertex used
    # vertex (i, j, k) -> i + (nx+1) (j + (ny+1) k)
    i, j, k = 1, 1, 1
    assert np.allclose(points[i + (nx + 1) * (j + (ny + 1) * k)],
                       np.add(origin, np.array([i / nx, j / ny, k / nz]) * size))


def test_box_tet_mesh_rejects_bad_input():
    with pytest.raises(ValueError):
        box_tet_mesh(0, 1, 1)
    with pytest.raises(ValueError):
        box_tet_mesh(1, 1, 1, size=(1, -1, 1))


def test_write_msh_round_trip(tmp_path):
    points, tets = box_tet_mesh(2, 3, 1)
    path = write_msh(tmp_path / "sub" / "box.msh", points, tets)
    mesh = meshio.read(str(path), file_format="gmsh")
    assert np.array_equal(mesh.points, points)
    assert np.array_equal(mesh.cells_dict["tetra"], tets)
    assert "4.1 0 8" in path.read_text().splitlines()[1]


def test_project_cube_is_regenerable(repo_root):
    """input/meshes/cube.msh is box_tet_mesh(5, 5, 5) written by write_msh."""
    points, tets = read_tet_mesh(repo_root / "input/meshes/cube.msh")
    want_p, want_t = box_tet_mesh(5, 5, 5)
    assert np.array_equal(points, want_p) and np.array_equal(tets, want_t)


def test_project_cube_matches_original_extent(repo_root, ipc_examples):
    ours, _ = read_tet_mesh(repo_root / "input/meshes/cube.msh")
    theirs, _ = read_tet_mesh(ipc_examples / "input/tetMeshes/cube.msh")
    assert np.allclose(ours.min(axis=0), theirs.min(axis=0))
    assert np.allclose(ours.max(axis=0), theirs.max(axis=0))
