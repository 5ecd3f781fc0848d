"""Boundary extraction: closed, outward, equal to the original's $Surface blocks."""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.model.generate import box_tet_mesh
from ipcsim.model.mesh_io import read_tet_mesh
from ipcsim.model.surface import (boundary_triangles, edge_use_counts, enclosed_volume,
                                  index_set, tet_signed_volumes, unique_edges,
                                  unique_undirected)


def _canonical(tris: np.ndarray) -> np.ndarray:
    """Triangles rotated so the smallest index comes first (orientation kept), sorted."""
    r = np.argmin(tris, axis=1)
    idx = (r[:, None] + np.arange(3)) % 3
    rows = np.take_along_axis(tris, idx, axis=1)
    return rows[np.lexsort(rows.T[::-1])]


def _surface_block(path) -> np.ndarray:
    """The non-standard `$Surface` block of the original's .msh files (0-based)."""
    text = path.read_text()
    body = text.split("$Surface", 1)[1].split("$EndSurface", 1)[0].split()
    k = int(body[0])
    return np.array(body[1:1 + 3 * k], dtype=np.int64).reshape(k, 3) - 1


def test_single_tet_faces_point_outward():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    tris = boundary_triangles(np.array([[0, 1, 2, 3]]))
    assert len(tris) == 4
    centroid = points.mean(axis=0)
    for t in tris:
        x0, x1, x2 = points[t]
        n = np.cross(x1 - x0, x2 - x0)
        assert n @ ((x0 + x1 + x2) / 3 - centroid) > 0
    assert enclosed_volume(points, tris) == pytest.approx(1 / 6)


@pytest.mark.parametrize("dims", [(1, 1, 1), (2, 3, 4), (5, 1, 2), (6, 6, 6)])
def test_box_surface_is_closed_and_outward(dims):
    nx, ny, nz = dims
    points, tets = box_tet_mesh(nx, ny, nz, size=(1.0, 2.0, 0.5), origin=(-1.0, 3.0, 2.0))
    tris = boundary_triangles(tets)
    # a box face of a x b cells has 2ab triangles
    assert len(tris) == 4 * (nx * ny + ny * nz + nz * nx)
    edges, uses = edge_use_counts(tris)
    assert np.all(uses == 2)  # closed 2-manifold
    # divergence theorem: enclosed volume equals the sum of tet volumes (outward normals)
    assert enclosed_volume(points, tris) == pytest.approx(tet_signed_volumes(points, tets).sum())
    assert enclosed_volume(points, tris) == pytest.approx(1.0)
    # Euler characteristic of a sphere: V - E + F = 2
    n_v = len(np.unique(tris))
    assert n_v - len(unique_edges(tris)) + len(tris) == 2
    assert len(edges) == len(unique_edges(tris))


def test_interior_vertices_are_not_on_the_surface():
    points, tets = box_tet_mesh(3, 3, 3)
    on_surface = np.unique(boundary_triangles(tets))
    interior = np.all((points > 0) & (points < 1), axis=1)
    assert set(np.flatnonzero(interior)).isdisjoint(on_surface)
    assert len(on_surface) == len(points) - interior.sum()


def test_two_disjoint_tets_have_eight_faces():
    tets = np.array([[0, 1, 2, 3], [4, 5, 6, 7]])
    assert len(boundary_triangles(tets)) == 8
    assert boundary_triangles(np.zeros((0, 4), np.int64)).shape == (0, 3)


def test_unique_edges_sorted_and_deduplicated():
    tris = np.array([[0, 1, 2], [2, 1, 3]])
    assert unique_edges(tris).tolist() == [[0, 1], [0, 2], [1, 2], [1, 3], [2, 3]]
    assert unique_undirected(np.array([[3, 1], [1, 3], [2, 0]])).tolist() == [[0, 2], [1, 3]]


def test_example_meshes_match_their_surface_block(ipc_examples):
    meshes = sorted(ipc_examples.joinpath("input").rglob("*.msh"))
    assert meshes
    for path in meshes:
        if "$Surface" not in path.read_text():
            continue
        points, tets = read_tet_mesh(path)
        tris = boundary_triangles(tets)
        stored = _surface_block(path)
        # the same set of faces, each with the same orientation up to cyclic rotation
        assert np.array_equal(_canonical(tris), _canonical(stored)), path.name
        assert np.all(edge_use_counts(tris)[1] == 2), path.name
        assert enclosed_volume(points, tris) == pytest.approx(
            tet_signed_volumes(points, tets).sum(), rel=1e-9), path.name


def test_index_set_is_numpys_unique():
    rng = np.random.default_rng(3)
    for a in (rng.integers(0, 50, size=(30, 4)), rng.integers(0, 5, size=200),
              np.zeros((0, 3), np.int64), np.array([7]), np.array([-2, 5, -2, 0])):
        got = index_set(a)
        assert got.dtype == np.int64 and np.array_equal(got, np.unique(a))
